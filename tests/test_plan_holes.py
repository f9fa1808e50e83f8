"""The holes issue 39 found in the promise under flight plans, each a run that failed before
(docs/theory.md, section 8): a short lead labelled *held* where a verdict rested on a broken
bound (terrain pairs, pairs a pruned predictor does not hold), a replan never checked against
the plan it replaced, a plan outliving ``reset``, and an excursion off the plan between two
steps with ``period > 1``. Each test asserts the promise's reading: the lead is the horizon, or
the short onset is labelled after a violation or a plan break; never held."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from reference_plan import first_knot_within, last_taus

from dua_mujoco.measure.monitor import Monitor
from dua_mujoco.plugin import attach, set_plan, standing_pairs
from dua_mujoco.runtime.predictor import Predictor


def _rollout(m: mujoco.MjModel, d: mujoco.MjData, n: int, ctrl: float = 0.0) -> np.ndarray:
    """``(n, nq)``: d's qpos and the n - 1 states after it under a constant control."""
    c = mujoco.MjData(m)
    mujoco.mj_copyData(c, m, d)
    out = [c.qpos.copy()]
    for _ in range(n - 1):
        c.ctrl[:] = ctrl
        mujoco.mj_step(m, c)
        out.append(c.qpos.copy())
    return np.array(out)


def _planned_run(m, d, p, steps, *, every=25, horizon=0.1, ctrl=lambda k: 0.0, settle=0):
    """Exact plans every ``every`` steps (deviation 0), a monitor over the run."""
    n = round(horizon / m.opt.timestep) + 2 * every
    monitor = Monitor(p)
    for _ in range(settle):
        mujoco.mj_step(m, d)
    mujoco.mj_step(m, d)
    monitor.start(d)
    for k in range(steps):
        if k % every == 0:
            p.set_plan(_rollout(m, d, n, ctrl(k)), deviation=0.0)
        d.ctrl[:] = ctrl(k)
        mujoco.mj_step(m, d)
        monitor.observe(d, p.step(d))
    monitor.finish()
    return monitor


def _never_held(monitor: Monitor, horizon: float) -> None:
    w = monitor.warning
    assert monitor.onsets >= 1 and monitor.misses == []
    assert w.short_held == 0, w.leads


# ------------------------------------------------------------------------------------------------
# 1. labels per pair, not per body
# ------------------------------------------------------------------------------------------------

TERRAIN = """<mujoco><option timestep="0.002"/>
<asset><hfield name="h" nrow="5" ncol="5" size="1 1 .2 .1"
  elevation="0 .1 .2 .1 0 .1 .3 .2 .1 0 .2 .1 0 .1 .2 0 .1 .2 .3 .1 .1 0 .1 .2 0"/></asset>
<worldbody><geom name="t" type="hfield" hfield="h"/>
<body name="ball" pos=".1 .05 .6"><freejoint/><geom name="ball" size=".05"/></body>
</worldbody></mujoco>"""


def test_a_ball_planned_onto_terrain_is_flagged_the_horizon_ahead() -> None:
    """A free ball dropped onto a height field, exact plans every 25 steps, accel=1 (below
    gravity): the ball-terrain pair follows the plan (its gap at each knot from the terrain's
    own bound), so the onset gets the whole horizon; before, the pair was left to a bound the
    ball broke at every step, and the monitor excused it for a planned body: 86 ms, held."""
    m = mujoco.MjModel.from_xml_string(TERRAIN)
    d = mujoco.MjData(m)
    p = Predictor(m, accel=1.0, alarm_horizon=0.1)
    monitor = _planned_run(m, d, p, 300)
    _never_held(monitor, 0.1)
    assert monitor.warning.leads.min() >= 0.1 - 1e-9
    assert monitor.violations > 0 and p.plan_breaks == 0  # the bounds broke, the plan held


BLOCK = """<mujoco><option timestep="0.002"/>
<worldbody><geom name="floor" type="plane" size="2 2 .1"/>
<body name="block" pos="0 0 .2"><joint name="hinge" type="hinge" axis="0 1 0" damping="1"/>
  <geom name="block" type="box" size=".05 .05 .05"/></body>
<body name="ball" pos=".05 0 .7"><freejoint/><geom name="ball" size=".05"/></body>
</worldbody></mujoco>"""


@pytest.mark.parametrize("pairs", ["pruned", "all"])
def test_a_pair_a_pruned_predictor_left_out_rests_on_the_bounds(pairs: str) -> None:
    """A ball falling onto a hinged block under exact plans, 200 ms horizon, accel=1: pruned,
    the ball-block pair is not held until the ball's reach (from its bounds, broken by gravity)
    meets the block's, and then stands 186 ms before the contact; that exclusion rested on the
    ball's bounds, so the onset is labelled after a violation (before: held). Every pair held:
    the whole horizon."""
    m = mujoco.MjModel.from_xml_string(BLOCK)
    d = mujoco.MjData(m)
    p = Predictor(m, accel=1.0, alarm_horizon=0.2, pairs=pairs)
    monitor = _planned_run(m, d, p, 250, horizon=0.2)
    _never_held(monitor, 0.2)
    if pairs == "all":
        assert monitor.warning.leads.min() >= 0.2 - 1e-9
    else:
        assert monitor.warning.short_after_violation == 1  # the hole's onset, labelled


# ------------------------------------------------------------------------------------------------
# 2. a new plan checked against the one it replaces
# ------------------------------------------------------------------------------------------------

ARM = """<mujoco><option timestep="0.002"/>
<worldbody><geom name="floor" type="plane" size="2 2 .1"/>
<body name="arm" pos="0 0 .1"><joint name="swing" type="hinge" axis="0 0 1" damping=".05"/>
  <geom name="link" type="capsule" fromto="0 0 0 .4 0 0" size=".03"/></body>
<body name="ball" pos=".12 .26 .05"><freejoint/><geom name="ball" size=".05"/></body>
</worldbody><actuator><motor joint="swing" gear="20" ctrlrange="-1 1"/></actuator></mujoco>"""


def _replan_run(swing_from: int, *, known: bool):
    """Plans every 25 steps of what will be commanded: the swing from step swing_from, which the
    plans made before it know (known) or not (each holds the control of its own step)."""
    m = mujoco.MjModel.from_xml_string(ARM)
    d = mujoco.MjData(m)
    p = Predictor(m, accel=1.0, alarm_horizon=0.2)
    departures: dict[int, np.ndarray] = {}
    n = 100 + 50
    monitor = Monitor(p)
    for _ in range(50):  # the ball settles
        mujoco.mj_step(m, d)
    monitor.start(d)
    for k in range(400):
        if k % 25 == 0:
            c = mujoco.MjData(m)
            mujoco.mj_copyData(c, m, d)
            q = [c.qpos.copy()]
            for j in range(n - 1):
                c.ctrl[:] = 1.0 if (k + j if known else k) >= swing_from else 0.0
                mujoco.mj_step(m, c)
                q.append(c.qpos.copy())
            departures[k] = p.set_plan(np.array(q), deviation=0.0)
        d.ctrl[:] = 1.0 if k >= swing_from else 0.0
        mujoco.mj_step(m, d)
        monitor.observe(d, p.step(d))
    monitor.finish()
    return m, p, monitor, departures


def test_a_replan_that_departs_the_old_plan_within_its_span_is_a_plan_break() -> None:
    """A still arm planned exactly every 25 steps, then at step 150 an exact plan that swings it
    into a resting ball: the verdicts of the plan of step 125 said the arm stays still for the
    horizon, and the arm leaves it at once. The old plan is checked as a shadow: the arm's
    departure is a plan break (counted), the onset (82 ms of lead at 200 ms) is labelled after it,
    never held; set_plan said so up front (the arm's departure time, the next state's)."""
    m, p, monitor, departures = _replan_run(swing_from=150, known=False)
    arm = m.body("arm").id
    _never_held(monitor, 0.2)
    assert monitor.warning.short_after_violation == 1
    assert p.plan_breaks >= 1
    h = float(m.opt.timestep)
    assert departures[150][arm] <= 51 * h + 150 * h + 1e-9  # the first step under the new plan
    assert np.isinf(departures[125]).all()  # replans that keep to the old plan: none


def test_a_replan_that_commits_the_old_plans_horizon_keeps_the_lead() -> None:
    """The pattern an MPC should follow (docs/plans.md): each plan commits what it commands over
    its first H, so the plans made before step 150 already hold the swing there and no replan
    departs from the plan it replaces; the onset gets the whole horizon and nothing breaks."""
    _, p, monitor, departures = _replan_run(swing_from=150, known=True)
    _never_held(monitor, 0.2)
    assert monitor.warning.leads.min() >= 0.2 - 1e-9
    assert p.plan_breaks == 0
    assert all(np.isinf(v).all() for v in departures.values())


def _arm_plan(m: mujoco.MjModel, d: mujoco.MjData, n: int, swing_at: int | None) -> np.ndarray:
    """The arm's plan from d: still, then swinging from knot ``swing_at`` (None: never)."""
    c = mujoco.MjData(m)
    mujoco.mj_copyData(c, m, d)
    q = [c.qpos.copy()]
    for j in range(n - 1):
        c.ctrl[:] = 0.0 if swing_at is None or j < swing_at else 1.0
        mujoco.mj_step(m, c)
        q.append(c.qpos.copy())
    return np.array(q)


def test_a_replaced_plan_is_checked_from_the_departure_set_plan_reports() -> None:
    """A replan that keeps to the plan it replaces for 20 steps and then swings the arm: set_plan
    reports the arm's departure 20 steps on, and the arm, following the new plan, breaks the old
    one there (not before); a body that leaves both plans breaks both, the replaced one as soon
    as the new one no longer proves it within; a replaced plan the new one is nested in is
    dropped."""
    m = mujoco.MjModel.from_xml_string(ARM)
    d = mujoco.MjData(m)
    p = Predictor(m, accel=1.0, alarm_horizon=0.2)
    for _ in range(50):
        mujoco.mj_step(m, d)
    p.reset(d)
    h, arm = float(m.opt.timestep), m.body("arm").id
    p.set_plan(_arm_plan(m, d, 200, None), deviation=0.005)
    for _ in range(5):
        mujoco.mj_step(m, d)
        p.step(d)
    departures = p.set_plan(_arm_plan(m, d, 200, 20), deviation=0.005)
    assert float(d.time) + 10 * h < departures[arm] < float(d.time) + 30 * h
    breaks = []
    for k in range(40):
        d.ctrl[:] = 1.0 if k >= 20 else 0.0
        mujoco.mj_step(m, d)
        p.step(d)
        breaks.append(p.plan_breaks)
    assert breaks[15] == 0 and breaks[-1] == 1  # the old plan, at the departure
    assert p._rt.plan_ok[arm]  # the new plan holds
    # The ball, which the new plan keeps where the old one had it (no departure: the old plan's
    # check of it waits on the new plan's), pushed off: the new plan breaks, and the old one
    # too, now that the new one no longer proves the ball within it.
    ball = m.jnt_qposadr[m.body("ball").jntadr[0]]
    d.qpos[ball] += 0.2
    mujoco.mj_forward(m, d)
    mujoco.mj_step(m, d)
    p.step(d)
    assert p.plan_breaks == 1 + 2
    # A replan that keeps to the plan it replaces leaves no shadow (it is nested in it): a push
    # off both is one break, of the plan in force, which proves the other's tube.
    p.reset(d)
    p.set_plan(_arm_plan(m, d, 200, 0), deviation=0.005)
    assert np.isinf(p.set_plan(_arm_plan(m, d, 200, 0), deviation=0.005)).all()
    d.qpos[0] += 0.2
    mujoco.mj_forward(m, d)
    mujoco.mj_step(m, d)
    p.step(d)
    assert p.plan_breaks == 3 + 1


def test_a_replan_keeps_the_old_walks_cleared_knots_only_where_it_nests() -> None:
    """A replan's first walk of a pair starts where the replaced plan's walk of it ended, as
    far as the new plan stays in the old one's tubes (docs/theory.md, Lemma 8.2e): the still
    arm's plan cleared the arm and the ball to its last knot; a replan that keeps the arm still
    to knot 20 and then swings it into the ball leaves the old tube there, and the pair's tau
    right after it is at most the time to the first knot at which MuJoCo's distance under the
    new plan may touch (a walk started at the old walk's end, past the departure, passes it).
    A replan that keeps to the old plan walks on from the carried knots to its own last one."""
    m = mujoco.MjModel.from_xml_string(ARM)
    d = mujoco.MjData(m)
    for _ in range(50):
        mujoco.mj_step(m, d)
    h, dev = float(m.opt.timestep), 0.005
    # Swinging within the old plan's span (the next state plus the horizon: 101 knots), past it
    # (the old walk's cleared knots reach further, but no nesting was checked there), never, and
    # a plan that puts the arm through the ball at knot 30 (it departs and touches at that knot).
    for leave, jump in ((20, False), (120, False), (None, False), (30, True)):
        p = Predictor(m, accel=1.0, alarm_horizon=0.2)
        c = mujoco.MjData(m)
        mujoco.mj_copyData(c, m, d)
        p.reset(c)
        p.set_plan(_arm_plan(m, c, 200, None), deviation=dev)
        for _ in range(5):
            mujoco.mj_step(m, c)
            p.step(c)
        assert (last_taus(m, p, "link", "ball") >= 190 * h).all()  # cleared to the last knot
        new = _arm_plan(m, c, 200, None if jump else leave)
        if jump:
            new[leave:, m.jnt_qposadr[m.joint("swing").id]] = 1.13  # the link through the ball
        p.set_plan(new, deviation=dev)
        mujoco.mj_step(m, c)
        p.step(c)
        got = last_taus(m, p, "link", "ball")
        if leave is None:  # cleared past the carried knots, to the new plan's last
            assert np.allclose(got, 200 * h)
            continue
        touch = first_knot_within(m, new, "link", "ball", 2 * dev)
        assert touch is not None and leave <= touch < 190
        assert (got <= touch * h + 1e-12).all(), (got, touch)


def test_a_body_that_broke_the_replaced_plan_carries_no_walk() -> None:
    """A walk's cleared knots carry over only for bodies the nesting checked: the still arm's
    plan cleared the arm and the ball to its last knot, then the arm, pushed off, broke it (its
    pairs follow the bounds, its walk's end still recorded). A replan from there that swings the
    arm into the ball walks the pair from the step's knot: its tau is at most the time to the
    first knot at which MuJoCo's distance may touch (a broken body taken as nested over the
    span starts the walk past it)."""
    m = mujoco.MjModel.from_xml_string(ARM)
    d = mujoco.MjData(m)
    for _ in range(50):
        mujoco.mj_step(m, d)
    h, dev, arm = float(m.opt.timestep), 0.005, m.body("arm").id
    p = Predictor(m, accel=1.0, alarm_horizon=0.2)
    p.reset(d)
    p.set_plan(_arm_plan(m, d, 200, None), deviation=dev)
    for _ in range(5):
        mujoco.mj_step(m, d)
        p.step(d)
    assert (last_taus(m, p, "link", "ball") >= 190 * h).all()
    d.qpos[m.jnt_qposadr[m.joint("swing").id]] -= 0.05  # away from the ball, past the deviation
    mujoco.mj_forward(m, d)
    mujoco.mj_step(m, d)
    p.step(d)
    assert p.plan_breaks == 1 and not p._rt.plan_ok[arm]
    new = _arm_plan(m, d, 200, 10)
    # A tighter deviation, so that the ball stays in its old tube until the arm reaches it: the
    # arm is the only body whose nesting could cut the carry before the touch.
    start = float(d.time)
    departures = p.set_plan(new, deviation=0.8 * dev)
    mujoco.mj_step(m, d)
    p.step(d)
    touch = first_knot_within(m, new, "link", "ball", 1.6 * dev)
    assert touch is not None and 10 <= touch < 100, touch
    assert departures[m.body("ball").id] > start + touch * h
    got = last_taus(m, p, "link", "ball")
    assert (got <= touch * h + 1e-12).all(), (got, touch)


def test_a_replan_is_checked_to_the_last_knot_of_the_replaced_plans_span() -> None:
    """The replaced plan's verdicts cover the next state plus the alarm horizon (latency 0), so
    a replan that leaves its tube at any knot up to that one departs there, and one that leaves
    it a knot later departs never (docs/theory.md, Lemma 8.4). A span one knot short would let
    a replan leave the old tube at its last covered knot unseen."""
    m = mujoco.MjModel.from_xml_string(ARM)
    d = mujoco.MjData(m)
    horizon = 0.02
    p = Predictor(m, accel=1.0, alarm_horizon=horizon)
    for _ in range(50):
        mujoco.mj_step(m, d)
    h, arm = float(m.opt.timestep), m.body("arm").id
    swing = m.jnt_qposadr[m.joint("swing").id]
    still = _arm_plan(m, d, 100, None)

    def departure(leave_at: int) -> float:
        p.reset(d)
        p.set_plan(still, deviation=0.005)
        moved = still.copy()
        moved[leave_at:, swing] += 0.5
        return float(p.set_plan(moved, deviation=0.005)[arm])

    start = departure(0)  # the first knot checked: the state the next step reads
    assert float(d.time) <= start <= float(d.time) + h + 1e-12
    first = round((start - float(d.time)) / h)
    last = first + round(horizon / h)
    for j in (first + 1, last - 1, last):
        assert departure(j) == pytest.approx(float(d.time) + j * h, abs=1e-12)
    assert np.isinf(departure(last + 1))


def test_a_replan_nested_in_the_newest_shadow_keeps_the_older_shadows_departures() -> None:
    """Three plans in turn (docs/theory.md, Lemma 8.6: nesting passes on). The second keeps the
    arm where the first has it and lifts the ball 20 steps on: the first stays, a shadow the
    ball departs. A third that keeps to the second is nested in it: the arm is nested in the
    first without a check, and the ball's departure from the first is still found. A third that
    frees the arm (a wide deviation) leaves both: an arm pushed within it breaks both."""
    m = mujoco.MjModel.from_xml_string(ARM)
    settled = mujoco.MjData(m)
    for _ in range(50):
        mujoco.mj_step(m, settled)
    h, arm, ball = float(m.opt.timestep), m.body("arm").id, m.body("ball").id
    z = m.jnt_qposadr[m.body("ball").jntadr[0]] + 2
    for free in (False, True):
        d = mujoco.MjData(m)
        mujoco.mj_copyData(d, m, settled)
        p = Predictor(m, accel=1.0, alarm_horizon=0.2)
        p.reset(d)
        p.set_plan(np.tile(d.qpos, (300, 1)), deviation=0.006)
        for _ in range(5):
            mujoco.mj_step(m, d)
            p.step(d)
        second = np.tile(d.qpos, (300, 1))
        second[20:, z] += 0.1
        departures = p.set_plan(second, deviation=0.005)
        assert np.isinf(departures[arm])
        assert float(d.time) + 15 * h < departures[ball] < float(d.time) + 25 * h
        for _ in range(5):
            mujoco.mj_step(m, d)
            p.step(d)
        deviation = np.full((295, m.nbody), 0.004)  # nested while the plans agree
        deviation[:, arm] = 1.0 if free else 0.004
        departures = p.set_plan(second[5:], deviation=deviation)
        assert float(d.time) + 10 * h < departures[ball] < float(d.time) + 20 * h
        if not free:
            assert np.isinf(departures[arm])
            continue
        assert departures[arm] <= float(d.time) + 2 * h + 1e-9
        d.qpos[0] += 0.3  # within the third plan, beyond the first two
        mujoco.mj_forward(m, d)
        mujoco.mj_step(m, d)
        p.step(d)
        assert p.plan_breaks == 2  # the second plan and the first


# ------------------------------------------------------------------------------------------------
# 3. reset drops the plan
# ------------------------------------------------------------------------------------------------


def test_reset_drops_the_plan_even_on_its_knots() -> None:
    """mj_resetData + predictor.reset brings the clock back onto the plan's knots: the plan is
    dropped all the same (a classification judges from the state alone)."""
    m = mujoco.MjModel.from_xml_string(ARM)
    d = mujoco.MjData(m)
    p = Predictor(m, accel=1.0, alarm_horizon=0.1)
    mujoco.mj_step(m, d)
    p.reset(d)
    p.set_plan(_rollout(m, d, 100), deviation=0.0)
    for _ in range(5):
        mujoco.mj_step(m, d)
        p.step(d)
    assert p.has_plan
    mujoco.mj_resetData(m, d)
    mujoco.mj_step(m, d)
    mujoco.mj_step(m, d)  # the state read is the plan's knot 0 again
    p.reset(d)
    assert not p.has_plan


def test_the_plugin_drops_the_plan_at_a_reset() -> None:
    """The plugin's reset (mj_resetData) classifies at the next compute: its standing pairs are
    a plugin's without a plan, on the knots of the plan it had (under which every pair stood)."""
    spec = mujoco.MjSpec.from_string(BLOCK)
    attach(spec, accel=1.0, alarm_horizon=0.2, pairs="all")
    m = spec.compile()
    d, fresh = mujoco.MjData(m), mujoco.MjData(m)
    plan = _rollout(m, d, 300)  # from the initial state: after a reset the clock is on its knots
    mujoco.mj_step(m, d)
    # A plan that allows a metre everywhere: every pair stands under it.
    set_plan(m, d, plan, deviation=1.0, start=0.0)
    for _ in range(100):
        mujoco.mj_step(m, d)
    planned = {tuple(g) for g in standing_pairs(m, d)}
    assert len(planned) == len(standing_pairs(m, d)) == 3
    mujoco.mj_resetData(m, d)
    for _ in range(101):  # both from the initial state, on the same clock
        mujoco.mj_step(m, d)
        mujoco.mj_step(m, fresh)
    unplanned = {tuple(g) for g in standing_pairs(m, fresh)}
    assert planned != unplanned  # the plan changes what stands here: the test can tell
    assert {tuple(g) for g in standing_pairs(m, d)} == unplanned


# ------------------------------------------------------------------------------------------------
# 4. period > 1: an excursion between two predictor steps
# ------------------------------------------------------------------------------------------------


def _drive(m: mujoco.MjModel, d: mujoco.MjData, push: bool, then) -> None:
    """Twelve physics steps of d along a clean copy of its motion (its state set from the copy's,
    then mj_forward), the ball pushed 5 cm off at step 6 (within the second period of 4) and back
    on the clean motion at step 7; then(k) after each."""
    clean = mujoco.MjData(m)
    mujoco.mj_copyData(clean, m, d)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(m, spec))
    ball = m.jnt_qposadr[m.body("ball").jntadr[0]]
    for k in range(1, 13):
        mujoco.mj_step(m, clean)
        mujoco.mj_getState(m, clean, state, spec)
        mujoco.mj_setState(m, d, state, spec)
        if push and k == 6:
            d.qpos[ball] += 0.05
        mujoco.mj_forward(m, d)
        then(k)


def test_an_excursion_between_predictor_steps_is_a_break_seen_by_the_plugin() -> None:
    """With period 4 the plugin checks the plan at every physics step: a ball pushed off its
    exact plan for one physics step between two predictor steps is a break, and its pairs are
    evaluated at the next step (before: nothing, at the predictor's steps it was on plan)."""

    def evaluated(push: bool) -> float:
        spec = mujoco.MjSpec.from_string(BLOCK)
        attach(spec, accel=50.0, alarm_horizon=0.1, pairs="all", period=4)
        m = spec.compile()
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)  # the plugin classifies here (time 0)
        set_plan(m, d, _rollout(m, d, 300), deviation=0.0)
        out: list[float] = []
        _drive(m, d, push, lambda k: out.append(float(d.sensordata[2])) if k == 8 else None)
        return out[0]

    assert evaluated(True) > evaluated(False)


def test_the_predictor_sees_an_excursion_between_its_steps_when_asked() -> None:
    """Python's Predictor with period 4 is stepped every 4 physics steps: check_plan in between
    sees the same excursion (a break, counted; the ball follows its bounds from the next step)."""
    m = mujoco.MjModel.from_xml_string(BLOCK)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    p = Predictor(m, accel=50.0, alarm_horizon=0.1, period=4)
    p.reset(d)
    # The kinematics of time t are read as the state of t - h (as after mj_step): knot j is t.
    p.set_plan(_rollout(m, d, 300), deviation=0.0, start=-float(m.opt.timestep))
    ball = m.body("ball").id
    found: list[list[int]] = []
    _drive(
        m, d, True, lambda k: p.step(d) if k % 4 == 0 else found.append(p.check_plan(d).tolist())
    )
    assert [ball] in found and p.plan_breaks == 1
    assert not p._rt.plan_ok[ball]
