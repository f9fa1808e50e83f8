"""Flight plans (``Predictor.set_plan``; docs/theory.md, section 8).

A plan's verdicts are held to a slow reference (MuJoCo's distance at every knot of the plan,
less both bodies' deviations), and rollouts hold the promise: a plan that is the simulation
itself flags every onset the whole alarm horizon ahead, impacts included; motion that strays
from its plan within the declared deviation is flagged as early; motion beyond it falls back to
the motion bounds.
"""

from __future__ import annotations

from collections.abc import Iterator

import mujoco
import numpy as np
import pytest
from mjcf import free, motors

from dua_mujoco.exceptions import InvalidInputError, SchedulerError, ShapeError
from dua_mujoco.measure.monitor import Monitor
from dua_mujoco.models.scenes import load_scene
from dua_mujoco.runtime.flightplan import plan_arrays
from dua_mujoco.runtime.pairstate import PairState
from dua_mujoco.runtime.plans import PilotPlan, deviation_profile
from dua_mujoco.runtime.predictor import Predictor

# A ball rolled towards a wall, a box dropped on the floor, an arm swinging through both.
SCENE = f"""
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 .1"/>
    <geom name="wall" type="box" size=".05 .5 .3" pos=".8 0 .3"/>
    {free("ball", "0 0 .3", 'name="ball" size=".05"')}
    {free("box", ".3 .3 .4", 'name="box" type="box" size=".05 .04 .03"')}
    <body name="arm" pos=".4 -.3 .2">
      <joint name="swing" type="hinge" axis="0 0 1" damping=".1"/>
      <geom name="link" type="capsule" fromto="0 0 0 .35 0 0" size=".03"/>
      <body name="hand" pos=".35 0 0">
        <joint name="bend" type="hinge" axis="0 1 0" damping=".1"/>
        <geom name="hand" type="box" size=".04 .04 .04" pos=".05 0 0"/>
      </body>
    </body>
  </worldbody>
  {motors("swing", "bend", gear=("2", "1"), ctrlrange="-1 1")}
</mujoco>
"""

ACCEL = 60.0


# The scene with a cloth (a flex: its contacts have no geom, out of the predictor's scope) that
# falls onto the box and the floor.
FLEX = SCENE.replace(
    "  </worldbody>",
    '    <flexcomp name="cloth" type="grid" count="4 4 1" spacing=".04 .04 .04" pos=".3 .3 .6" '
    'dim="2" radius=".01" mass=".05"><edge equality="true"/></flexcomp>\n  </worldbody>',
)
# The scene with MuJoCo 4's sleep: the box starts asleep on the floor in the ball's path, is woken
# when the ball strikes it, and falls asleep again where it comes to rest.
SLEEP = SCENE.replace(
    '<option timestep="0.002"/>', '<option timestep="0.002"><flag sleep="enable"/></option>'
).replace('<body name="box" pos=".3 .3 .4">', '<body name="box" pos=".5 0 .03" sleep="init">')


def _scene(xml: str = SCENE) -> tuple[mujoco.MjModel, mujoco.MjData]:
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qvel[0] = 1.5  # the ball, towards the wall
    mujoco.mj_forward(m, d)
    return m, d


def _controls(m: mujoco.MjModel, steps: int, seed: int) -> np.ndarray:
    """Controls linear between random targets 100 steps apart (a robot's commands)."""
    rng = np.random.default_rng(seed)
    knots = rng.uniform(-1, 1, (steps // 100 + 2, m.nu))
    t = np.arange(steps) / 100.0
    return np.stack([np.interp(t, np.arange(len(knots)), knots[:, i]) for i in range(m.nu)], 1)


def _rollout(m: mujoco.MjModel, d: mujoco.MjData, ctrl: np.ndarray, n: int) -> np.ndarray:
    """``(n, nq)``: d's qpos and the n - 1 states after it under ctrl[0], ctrl[1], ..."""
    c = mujoco.MjData(m)
    mujoco.mj_copyData(c, m, d)
    out = [c.qpos.copy()]
    for j in range(n - 1):
        if m.nu:
            c.ctrl[:] = ctrl[min(j, len(ctrl) - 1)]
        mujoco.mj_step(m, c)
        out.append(c.qpos.copy())
    return np.array(out)


def _geom_poses(m: mujoco.MjModel, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = mujoco.MjData(m)
    pos, mat = [], []
    for q in qpos:
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        pos.append(d.geom_xpos.copy())
        mat.append(d.geom_xmat.copy())
    return np.array(pos), np.array(mat)


def _deviation(m: mujoco.MjModel, plan: np.ndarray, actual: np.ndarray) -> np.ndarray:
    """``(n, nbody)``: a bound on how far each body's geoms are from the plan at each knot, by
    the definition (the origin's distance plus ``|dR|_F`` times the bounding radius)."""
    p0, r0 = _geom_poses(m, plan)
    p1, r1 = _geom_poses(m, actual)
    per_geom = np.linalg.norm(p1 - p0, axis=2) + np.linalg.norm(r1 - r0, axis=2) * m.geom_rbound
    out = np.zeros((len(plan), m.nbody))
    for g in range(m.ngeom):
        b = int(m.geom_bodyid[g])
        out[:, b] = np.maximum(out[:, b], per_geom[:, g])
    return out


def _drive(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    p: Predictor,
    ctrl: np.ndarray,
    steps: int,
    *,
    every: int,
    plan_of,  # (k, d) -> (qpos, deviation) or None
) -> list[tuple[tuple[int, int], int, float]]:
    """Run, giving plans every ``every`` steps; each onset as (geom pair, step, lead in s)."""
    h = m.opt.timestep
    since: dict[tuple[int, int], int] = {}
    touching: set[tuple[int, int]] = set()
    onsets = []
    g1, g2 = p.tables.geom1, p.tables.geom2
    for k in range(steps):
        if k % every == 0:
            plan = plan_of(k, d)
            if plan is not None:
                p.set_plan(plan[0], deviation=plan[1])
        if m.nu:
            d.ctrl[:] = ctrl[k]
        mujoco.mj_step(m, d)
        p.step(d)
        state = p.pair_state()
        stand = np.flatnonzero(state.alarm_state() & state.active)
        now = {(min(int(g1[i]), int(g2[i])), max(int(g1[i]), int(g2[i]))) for i in stand}
        since = {g: since.get(g, k) for g in now}
        contacts = {
            (min(int(c.geom1), int(c.geom2)), max(int(c.geom1), int(c.geom2)))
            for c in d.contact[: d.ncon]
        }
        for g in contacts - touching:
            onsets.append((g, k, (k - since[g]) * h if g in since else -1.0))
        touching = contacts
    return onsets


def _monitored(
    horizon: float,
    plan_of,  # (k, data) -> (qpos, deviation) or None, every `every` steps
    *,
    ctrl: np.ndarray,
    period: int = 1,
    latency: int = 0,
    pairs: str = "all",
    steps: int = 600,
    every: int = 25,
    d0: mujoco.MjData | None = None,
    xml: str = SCENE,
) -> tuple[Predictor, Monitor]:
    """A run of the scene (``xml``) under the run monitor, accel=1 (below gravity: every falling
    body breaks its bounds at every step, so the bounds alone give onsets less lead than the
    horizon), a plan every ``every`` steps."""
    m, d = _scene(xml)
    if d0 is not None:
        mujoco.mj_copyData(d, m, d0)
    p = Predictor(m, accel=1.0, alarm_horizon=horizon, period=period, latency=latency, pairs=pairs)
    monitor = Monitor(p)
    mujoco.mj_step(m, d)
    monitor.start(d)
    for k in range(steps):
        plan = plan_of(k, d) if k % every == 0 else None
        if plan is not None:
            p.set_plan(plan[0], deviation=plan[1])
        d.ctrl[:] = ctrl[k]
        mujoco.mj_step(m, d)
        monitor.observe(d, p.step(d) if (k + 1) % period == 0 else None)
    monitor.finish()
    return p, monitor


def _late(monitor: Monitor) -> int:
    """Onsets with less lead than the horizon past the start (held or after a violation)."""
    return monitor.warning.short_held + monitor.warning.short_after_violation


@pytest.mark.parametrize(
    ("horizon", "period", "latency", "pairs"),
    [(0.05, 1, 0, "all"), (0.2, 1, 0, "all"), (0.1, 2, 1, "all"), (0.1, 1, 0, "pruned")],
)
def test_a_plan_that_is_the_simulation_flags_every_onset_the_horizon_ahead(
    horizon: float, period: int, latency: int, pairs: str
) -> None:
    """The plan is the rollout of the controls that will be applied (bit for bit the run):
    every onset past the start stood in alarm at least the horizon (and the latency), impacts
    and all, no body strays, and the pairs standing are the oracle's (the plan knows which
    touch). Under accel=1 the same run without plans has onsets with less lead: the plans, not
    the bounds, give the lead here (with period > 1, only because a plan's tau is rounded down
    to the predictor's grid, docs/theory.md, section 8)."""
    m, _ = _scene()
    every = 25
    ctrl = _controls(m, 1000, seed=1)
    n = round(horizon / m.opt.timestep) + 2 * every + period * (latency + 2)
    config = {"period": period, "latency": latency, "pairs": pairs, "ctrl": ctrl}
    p, planned = _monitored(
        horizon, lambda k, data: (_rollout(m, data, ctrl[k:], n), 0.0), **config
    )
    assert planned.onsets >= 3 and planned.misses == []
    assert _late(planned) == 0, planned.warning.leads
    assert p.plan_breaks == 0 and p.has_plan
    assert planned.standing_alarm_fraction <= 1.02 * planned.oracle_fraction + 1e-12
    _, bounds = _monitored(horizon, lambda k, data: None, **config)
    assert _late(bounds) >= 1  # the same run without plans: the test can fail


@pytest.mark.parametrize("xml", [FLEX, SLEEP], ids=["flex", "sleep"])
def test_a_plan_on_a_model_with_a_flex_or_sleeping_trees_flags_every_onset(xml: str) -> None:
    """Plans on models whose knots' poses come from ``mj_kinematics`` on the whole model (a flex,
    or sleep enabled: plan.cc): a plan that is the simulation is followed without a break and
    every onset stands in alarm the horizon ahead. With a flex, the cloth's contacts (geom -1)
    are counted apart (out of scope), not looked up as a geom pair (the monitor stopped there).
    With sleep, the box is asleep when the first plans are made (so in the plans' own data from
    the start), awake at later ones and asleep again where it came to rest: a stale pose in any
    knot breaks a plan of deviation 0. Without the plans the same run has onsets with less lead."""
    m, _ = _scene(xml)
    every, horizon = 25, 0.05
    ctrl = _controls(m, 1000, seed=1)
    n = round(horizon / m.opt.timestep) + 2 * every + 2
    box = int(m.body_treeid[m.body("box").id])
    asleep: list[bool] = []  # the box's tree at each plan

    def plan_of(k: int, data: mujoco.MjData) -> tuple[np.ndarray, float]:
        asleep.append(bool(data.tree_asleep[box] >= 0))
        return _rollout(m, data, ctrl[k:], n), 0.0

    p, planned = _monitored(horizon, plan_of, ctrl=ctrl, every=every, xml=xml)
    assert planned.onsets >= 3 and planned.misses == []
    assert _late(planned) == 0, planned.warning.leads
    assert p.plan_breaks == 0 and p.has_plan
    if xml is FLEX:
        assert m.nflex == 1 and planned.flex_contacts > 0 and planned.unfiltered_contacts == 0
    else:
        # Asleep, woken, asleep again (the plans at steps 0, 150 and 275 see each).
        woken = asleep.index(False)
        assert asleep[0] and True in asleep[woken:], asleep
    _, bounds = _monitored(horizon, lambda k, data: None, ctrl=ctrl, every=every, xml=xml)
    assert _late(bounds) >= 1


def test_motion_within_its_deviation_is_flagged_the_horizon_ahead() -> None:
    """Plans of the commanded controls, a run whose controls stray from them: each plan is
    given the deviation the run will show (measured on a first pass by the runtime's own
    measure, deviation_profile at safety 1), and the second pass, the same run, breaks no plan
    (nor the plans it replaced, checked over their spans) and flags every onset the horizon
    ahead; without plans (accel=1) it does not."""
    m, d0 = _scene()
    horizon, steps, every = 0.1, 600, 20
    n = round(horizon / m.opt.timestep) + 2 * every
    planned = _controls(m, steps + n, seed=2)
    applied = planned + np.random.default_rng(3).normal(0, 0.3, planned.shape)
    # First pass: the plans and what the run did (as _monitored runs it: one step, then the run).
    d = mujoco.MjData(m)
    mujoco.mj_copyData(d, m, d0)
    mujoco.mj_step(m, d)
    plans: dict[int, np.ndarray] = {}
    qpos = [d.qpos.copy()]
    for k in range(steps):
        if k % every == 0:
            plans[k] = _rollout(m, d, planned[k:], n)
        d.ctrl[:] = applied[k]
        mujoco.mj_step(m, d)
        qpos.append(d.qpos.copy())
    actual = np.array(qpos + [qpos[-1]] * n)
    points = Predictor(m, accel=1.0).bound_points
    dev = {
        k: deviation_profile(m, actual, [PilotPlan(k, q)], points=points, safety=1.0)
        for k, q in plans.items()
    }
    assert max(float(v.max()) for v in dev.values()) > 1e-3  # the run does stray
    p, monitor = _monitored(
        horizon, lambda k, data: (plans[k], dev[k]), ctrl=applied, every=every, d0=d0
    )
    assert monitor.onsets >= 3 and monitor.misses == []
    assert _late(monitor) == 0, monitor.warning.leads
    assert p.plan_breaks == 0
    _, bounds = _monitored(horizon, lambda k, data: None, ctrl=applied, every=every, d0=d0)
    assert _late(bounds) >= 1


def _reference_tau(
    m: mujoco.MjModel, p: Predictor, qpos: np.ndarray, dev: np.ndarray, knot: int
) -> np.ndarray:
    """Each pair's time from ``knot`` to the first knot at which MuJoCo's distance of its two
    geoms, less the pair's contact distance, is not above both bodies' deviations (0 for a
    static body, which a plan holds exactly)."""
    h = m.opt.timestep
    d = mujoco.MjData(m)
    gp = p.geom_pairs
    contact = gp.contact_distance[p.sphere_pairs.geom_pair]
    g1, g2 = p.tables.geom1, p.tables.geom2
    b1, b2 = m.geom_bodyid[g1], m.geom_bodyid[g2]
    out = np.full(len(g1), (len(qpos) - knot) * h)
    dev = np.where(m.body_weldid == 0, 0.0, dev)  # a static body never strays
    for j in range(len(qpos) - 1, knot - 1, -1):  # backwards: the last hit written is the first
        d.qpos[:] = qpos[j]
        mujoco.mj_kinematics(m, d)
        for i in range(len(g1)):
            dist = mujoco.mj_geomDistance(m, d, int(g1[i]), int(g2[i]), 10.0, None)
            if dist - contact[i] <= dev[j, b1[i]] + dev[j, b2[i]]:
                out[i] = (j - knot) * h
    return out


@pytest.mark.parametrize("deviation", [0.0, 0.01, 0.05, "rising", "wobbling"])
def test_the_plans_tau_is_never_above_the_reference_and_is_mostly_equal(
    deviation: float | str,
) -> None:
    """Right after a plan every pair is evaluated under it: its tau is never later than the
    first knot at which MuJoCo's distance says it may touch (a tau that dropped the deviation,
    the sweep between knots or a knot would be), and equal to it for most pairs. Deviations
    that rise with the knots (constant ones too) let the knot walk search for the end of the
    knots a carried gap clears; a wobbling one walks them one by one: both are held here (a
    search that overshot would pass the knot the reference stops at)."""
    m, d = _scene()
    horizon, n = 0.2, 200
    ctrl = _controls(m, 2 * n, seed=4)
    p = Predictor(m, accel=ACCEL, alarm_horizon=horizon)
    p.reset(d)
    qpos = _rollout(m, d, ctrl, n)
    knots = np.arange(n)[:, None]
    dev = {
        "rising": np.broadcast_to(0.05 * knots / n, (n, m.nbody)),
        "wobbling": np.broadcast_to(0.02 + 0.015 * np.sin(knots / 3.0), (n, m.nbody)),
    }.get(str(deviation), np.full((n, m.nbody), deviation))
    p.set_plan(qpos, deviation=dev)
    d.ctrl[:] = ctrl[0]
    mujoco.mj_step(m, d)
    p.step(d)
    got = p.pair_state().last_tau_of(np.arange(p.nsphere_pairs))
    want = _reference_tau(m, p, qpos, dev, knot=0)
    assert (got <= want + 1e-12).all(), np.flatnonzero(got > want)
    assert np.mean(np.isclose(got, want)) >= 0.8
    assert 0 < np.mean(want < horizon) < 1  # some pairs may touch within the horizon, some not


def _first_touch(m: mujoco.MjModel, p: Predictor, qpos: np.ndarray, dev: np.ndarray) -> np.ndarray:
    """``(n + 1, npair)``: from each knot, the time to the first knot at which the pair may
    touch by :func:`_reference_tau`'s rule (row ``n``: none left)."""
    h, n = m.opt.timestep, len(qpos)
    out = np.zeros((n + 1, p.nsphere_pairs))
    may = [_reference_tau(m, p, qpos[j : j + 1], dev[j : j + 1], knot=0) == 0 for j in range(n)]
    for j in range(n - 1, -1, -1):
        out[j] = np.where(may[j], 0.0, out[j + 1] + h)
    return out


def _followed_plans(
    m: mujoco.MjModel, d: mujoco.MjData, p: Predictor, dev: np.ndarray, n: int, every: int
) -> Iterator[tuple[int, int, np.ndarray, PairState, np.ndarray]]:
    """Three plans of ``n`` knots rolled from random controls, each followed for ``every``
    steps: after each step, ``(plan, k, qpos, state, ids)``, ``ids`` the pairs evaluated."""
    for plan in range(3):
        ctrl = _controls(m, n, seed=10 + plan)
        qpos = _rollout(m, d, ctrl, n)
        p.set_plan(qpos, deviation=dev)
        for k in range(every):
            d.ctrl[:] = ctrl[k]
            mujoco.mj_step(m, d)
            p.step(d)
            state = p.pair_state()
            ids = np.flatnonzero(state.last_step_of(np.arange(p.nsphere_pairs)) == state.step_count)
            yield plan, k, qpos, state, ids


def test_a_pairs_later_verdicts_under_one_plan_are_never_above_the_reference() -> None:
    """A pair evaluated again under the same plan takes the knot its last walk ended at
    without walking (Lemma 8.2c) until the step passes it: at every step of a run that follows
    its plans, the pairs evaluated have a tau never later than the reference's from that
    step's knot, and a new plan forgets the old one's walks (a walk's end carried past its
    knot, or past a new plan, fails it)."""
    m, d = _scene()
    horizon, n, every = 0.2, 160, 40
    p = Predictor(m, accel=ACCEL, alarm_horizon=horizon)
    p.reset(d)
    h = m.opt.timestep
    dev = np.broadcast_to(0.02 * np.arange(n)[:, None] / n, (n, m.nbody)).copy()
    checked = standing = 0
    for plan, k, qpos, state, ids in _followed_plans(m, d, p, dev, n, every):
        if k == 0:
            want = _first_touch(m, p, qpos, dev)
        got = state.last_tau_of(ids)
        bound = np.minimum(want[k, ids], (n - k) * h)
        assert (got <= bound + 1e-12).all(), (plan, k, ids[got > bound + 1e-12])
        checked += ids.size
        standing += int(np.count_nonzero(got < horizon) if k else 0)
    assert p.plan_breaks == 0
    assert standing >= 20 and checked >= 200  # pairs were evaluated again under each plan


def _clearable(
    m: mujoco.MjModel, p: Predictor, qpos: np.ndarray, dev: np.ndarray, slack: float
) -> np.ndarray:
    """``(n, npair)``: whether MuJoCo's distance of the pair's two geoms at each knot, less the
    pair's contact distance, is above both bodies' deviations there by more than ``slack``: a
    knot some direction clears (:func:`_reference_tau`'s test, the other way round)."""
    d = mujoco.MjData(m)
    contact = p.geom_pairs.contact_distance[p.sphere_pairs.geom_pair]
    g1, g2 = p.tables.geom1, p.tables.geom2
    b1, b2 = m.geom_bodyid[g1], m.geom_bodyid[g2]
    dev = np.where(m.body_weldid == 0, 0.0, dev)
    out = np.zeros((len(qpos), len(g1)), dtype=bool)
    for j, q in enumerate(qpos):
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        for i in range(len(g1)):
            dist = mujoco.mj_geomDistance(m, d, int(g1[i]), int(g2[i]), 10.0, None)
            out[j, i] = dist - contact[i] > dev[j, b1[i]] + dev[j, b2[i]] + slack
    return out


@pytest.mark.parametrize("deviation", ["rising", 0.15])
def test_no_walk_stops_at_a_knot_mujocos_distance_clears(deviation: float | str) -> None:
    """The exact level at a knot asks MuJoCo for a direction only where one could clear the knot
    (docs/theory.md, section 8, "Queries that cannot clear, at the knots"): over three plans
    followed step by step, every knot a pair's walk stops at (its tau short of the plan's end)
    has MuJoCo's distance, less the contact distance, within both deviations (0.1 mm of room
    for GJK's own tolerance). A screen that skipped a query whose direction clears would stop a
    walk at such a knot; a large deviation makes the kept direction fail where others clear."""
    m, d = _scene()
    horizon, n, every = 0.2, 160, 40
    p = Predictor(m, accel=ACCEL, alarm_horizon=horizon)
    p.reset(d)
    h = m.opt.timestep
    if deviation == "rising":
        dev = np.broadcast_to(0.02 * np.arange(n)[:, None] / n, (n, m.nbody)).copy()
    else:
        dev = np.full((n, m.nbody), float(deviation))
    stops = 0
    for plan, k, qpos, state, ids in _followed_plans(m, d, p, dev, n, every):
        if k == 0:
            clears = _clearable(m, p, qpos, dev, slack=1e-4)
        steps = np.rint(state.last_tau_of(ids) / h).astype(int)
        stop = steps < n - k
        knot, ids = k + steps[stop], ids[stop]
        assert not clears[knot, ids].any(), (plan, k, ids[clears[knot, ids]])
        stops += ids.size
    assert p.plan_breaks == 0
    assert stops >= 100


def test_a_body_beyond_its_deviation_falls_back_to_the_bounds() -> None:
    """A plan of held controls with no deviation allowed, a run that moves the arm: the arm's
    bodies break the plan (their pairs follow the motion bounds from then on), the ball's and
    the box's do not, and nothing is missed while the bounds hold."""
    m, d = _scene()
    steps = 300
    ctrl = _controls(m, steps, seed=5)
    p = Predictor(m, accel=ACCEL, alarm_horizon=0.05)
    p.reset(d)
    held = np.zeros_like(ctrl)
    onsets = _drive(
        m, d, p, ctrl, steps, every=steps,
        plan_of=lambda k, data: (_rollout(m, data, held, steps + 10), 0.0),
    )  # fmt: skip
    ok = p._rt.plan_ok
    assert p.plan_breaks >= 1
    assert not ok[m.body("arm").id] and ok[m.body("ball").id]
    assert [o for o in onsets if o[2] < 0] == []  # every onset alarmed before it


@pytest.mark.parametrize("planned", [True, False])
def test_no_pair_is_settled_while_a_plan_is_set(planned: bool) -> None:
    """Settling (docs/theory.md, section 6) judges a flagged body's pair by the motion bounds'
    norms, so it stays off while a plan is set, whose verdicts rest on the plan: under a plan of
    held controls the run breaks (its bodies flagged), nothing is settled; the same run with no
    plan settles pairs, so the setup reaches the rule."""
    m, d = _scene()
    steps = 200
    ctrl = _controls(m, steps, seed=5)
    p = Predictor(m, accel=1.0, alarm_horizon=0.05)
    p.reset(d)
    if planned:
        p.set_plan(_rollout(m, d, np.zeros_like(ctrl), steps + 10), deviation=0.0)
    flagged = settled = 0
    for k in range(steps):
        d.ctrl[:] = ctrl[k]
        mujoco.mj_step(m, d)
        p.step(d)
        assert p.has_plan == planned
        flagged += p.violated_bodies.size
        settled += p.pair_state().settled
    assert flagged > 0
    assert (settled == 0) if planned else (settled > 0)


def test_settling_resumes_once_a_plan_runs_out() -> None:
    """What a verdict rested on is remembered for two evaluations (the monitor's "held" label),
    so settling waits for them after a plan; it must not stay off for good."""
    m, d = _scene()
    ctrl = _controls(m, 200, seed=5)
    p = Predictor(m, accel=1.0, alarm_horizon=0.05)
    p.reset(d)
    p.set_plan(_rollout(m, d, np.zeros((1, m.nu)), 20), deviation=0.0)
    settled = []
    for k in range(200):
        d.ctrl[:] = ctrl[k]
        mujoco.mj_step(m, d)
        p.step(d)
        settled.append(p.pair_state().settled)
    assert not any(settled[:20])
    assert any(settled[20:40])


def test_past_its_last_knot_the_plan_is_dropped() -> None:
    """Knot j is the state j steps on, which the step after it reads (MuJoCo's step reads the
    state it started from): 30 knots cover 30 steps, and the 31st drops the plan."""
    m, d = _scene()
    p = Predictor(m, accel=ACCEL, alarm_horizon=0.05)
    p.reset(d)
    p.set_plan(_rollout(m, d, np.zeros((1, m.nu)), 30), deviation=0.0)
    for _ in range(30):
        mujoco.mj_step(m, d)
        p.step(d)
        assert p.has_plan
    mujoco.mj_step(m, d)
    p.step(d)
    assert not p.has_plan
    p.set_plan(_rollout(m, d, np.zeros((1, m.nu)), 30), deviation=0.0)
    p.clear_plan()
    assert not p.has_plan


def test_bad_plans_are_refused_by_name() -> None:
    m, d = _scene()
    p = Predictor(m, accel=ACCEL)
    q = _rollout(m, d, np.zeros((1, m.nu)), 10)
    with pytest.raises(SchedulerError, match="reset"):
        p.set_plan(q, deviation=0.0)
    p.reset(d)
    with pytest.raises(ShapeError, match=r"\(n, nq\) = \(n, 16\)"):
        p.set_plan(q[:, :-1], deviation=0.0)
    with pytest.raises(ShapeError, match="deviation has shape"):
        p.set_plan(q, deviation=np.zeros(3))
    bad = q.copy()
    bad[4, 2] = np.nan
    with pytest.raises(InvalidInputError, match=r"knot 4, qpos\[2\]: nan"):
        p.set_plan(bad, deviation=0.0)
    with pytest.raises(InvalidInputError, match=r"knot 3, body 2: -1\) for body 'box'"):
        dev = np.zeros((10, m.nbody))
        dev[3, 2] = -1.0
        p.set_plan(q, deviation=dev)
    with pytest.raises(InvalidInputError, match="does not cover the state the next step reads"):
        p.set_plan(q, deviation=0.0, start=float(d.time) + 0.1)
    with pytest.raises(InvalidInputError, match="does not cover"):
        p.set_plan(q, deviation=0.0, start=float(d.time) + 0.0005)  # not on a step


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf, -1.0, -5e-324])
def test_set_plan_refuses_a_value_out_of_range_wherever_it_stands(value: float) -> None:
    """The runtime scans a plan's numbers two at a time before it searches for the one its
    message names (``Plan::Build``): a bad deviation or joint position at any entry, in either
    lane or in the odd one out at the end, is refused, and the message names the first bad
    one; a deviation of -0.0 is a distance >= 0, and a joint position of any sign is fine."""
    m, d = _scene()
    p = Predictor(m, accel=ACCEL)
    p.reset(d)
    q = _rollout(m, d, np.zeros((1, m.nu)), 7)  # 7 knots of 5 bodies: 35 deviations, one odd
    n, nbody, nq = q.shape[0], m.nbody, m.nq
    for i in range(n * nbody):
        dev = np.zeros(n * nbody)
        dev[i] = value
        if i + 2 < n * nbody - 1:
            dev[i + 2] = -1.0  # a second bad one after it, in the lanes (not the odd one out)
        knot, body = divmod(i, nbody)
        with pytest.raises(InvalidInputError, match=rf"\(knot {knot}, body {body}: "):
            p.set_plan(q, deviation=dev.reshape(n, nbody))
    for i in range(n * nq):
        bad = q.copy().reshape(-1)
        bad[i] = value
        knot, entry = divmod(i, nq)
        if np.isfinite(value):
            p.set_plan(bad.reshape(n, nq), deviation=0.0)  # any finite joint position
            continue
        if i + 2 < n * nq:
            bad[i + 2] = np.nan
        with pytest.raises(InvalidInputError, match=rf"knot {knot}, qpos\[{entry}\]: "):
            p.set_plan(bad.reshape(n, nq), deviation=0.0)
    p.set_plan(q, deviation=np.full((n, nbody), -0.0))


def test_set_plan_reads_the_callers_arrays_without_copies_or_writes() -> None:
    """The arrays a plan's arguments already are (float64, C-contiguous; int64 relative ids) go
    to the runtime as they are: no copy of them and no write to them; the empty arrays of what
    is not planned are one of each, shared by every call; ``set_plan`` returns the
    runtime's departures, a new ``(nbody,)`` array each call."""
    m, d = _scene()
    p = Predictor(m, accel=ACCEL)
    p.reset(d)
    q = _rollout(m, d, np.zeros((1, m.nu)), 10)
    dev = np.full((10, m.nbody), 0.01)
    arm, hand = (mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in ("arm", "hand"))
    pairs, rel = np.array([[arm, hand]], dtype=np.int64), np.full((10, 1), 0.005)
    kept = [a.copy() for a in (q, dev, pairs, rel)]
    args = plan_arrays(m, q, dev, d.time, relative=(pairs, rel))
    assert args.qpos is q and args.deviation is dev
    assert args.rel_bodies is pairs and args.rel_deviation is rel
    other = plan_arrays(m, q, 0.01, d.time)
    assert other.mocap_pos is args.mocap_pos and other.mocap_quat is args.mocap_pos
    assert other.bodies is args.bodies and other.rel_bodies is plan_arrays(m, q, 0.0, 0).rel_bodies
    assert other.mocap_pos.size == other.bodies.size == other.rel_bodies.size == 0
    assert np.array_equal(other.deviation, dev)  # one number broadcast, a new array
    first = p.set_plan(q, deviation=dev, relative=(pairs, rel))
    again = p.set_plan(q, deviation=dev, relative=(pairs, rel))
    for a, b in zip((q, dev, pairs, rel), kept, strict=True):
        assert np.array_equal(a, b) and a.flags.writeable
    assert type(first) is np.ndarray and first.shape == (m.nbody,) and first.dtype == np.float64
    assert np.all(first == np.inf) and np.all(again == np.inf)  # a plan replaced by itself
    assert first is not again and not np.shares_memory(first, again)
    # Other layouts and dtypes are converted, as before: the same plan; a deviation of one
    # number a knot is a row, a relative deviation of one number a pair a column.
    ball, box = (mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in ("ball", "box"))
    two = np.array([[arm, hand], [ball, box]], dtype=np.int32)
    knot = np.arange(10.0) / 100
    conv = plan_arrays(
        m, np.asfortranarray(q), knot.astype(np.float32), d.time, relative=(two.tolist(), [1, 2])
    )
    assert conv.qpos.flags.c_contiguous and np.array_equal(conv.qpos, q)
    assert conv.deviation.dtype == np.float64 and conv.deviation.flags.c_contiguous
    assert np.allclose(conv.deviation, np.repeat(knot[:, None], m.nbody, axis=1))
    assert conv.rel_bodies.dtype == np.int64 and np.array_equal(conv.rel_bodies, two)
    assert np.array_equal(conv.rel_deviation, np.tile([1.0, 2.0], (10, 1)))
    rows = plan_arrays(m, q, knot, 0.0).deviation  # float64 already: broadcast, not converted
    assert np.array_equal(rows, np.repeat(knot[:, None], m.nbody, axis=1))


def test_a_model_with_mocap_bodies_takes_a_plan_of_its_other_bodies() -> None:
    """A plan of qpos holds every moving body outside mocap trees; the mocap bodies follow their
    bounds, unless their poses are planned too."""
    m, d = load_scene("clutter")
    p = Predictor(m, accel=50.0)
    mujoco.mj_step(m, d)
    p.reset(d)
    mocap = int(p.mocap.mocap_bodies[0])  # type: ignore[union-attr]
    p.set_plan(np.tile(d.qpos, (5, 1)), deviation=0.0)
    ok = np.asarray(p._rt.plan_ok)
    assert not ok[mocap] and ok[np.asarray(m.body_weldid) != 0].sum() > 1
    pos, quat = np.tile(d.mocap_pos, (5, 1, 1)), np.tile(d.mocap_quat, (5, 1, 1))
    p.set_plan(np.tile(d.qpos, (5, 1)), deviation=0.0, mocap_pos=pos, mocap_quat=quat)
    assert p._rt.plan_ok[mocap]


def test_each_verdict_says_what_it_rested_on() -> None:
    """The runtime records, per verdict and side, the plan or the bounds (what the monitor
    labels onsets by): under a plan every pair rests on it on both sides (a static body is
    planned with deviation 0); a pair with a body beyond its deviation rests on that body's
    bounds, and the other's plan; without a plan, on both bodies' bounds."""
    m, d = _scene()
    p = Predictor(m, accel=ACCEL, alarm_horizon=0.05)
    mujoco.mj_step(m, d)
    p.reset(d)
    everything = np.arange(p.nsphere_pairs)
    assert (p.verdict_basis(everything) == 0).all()
    dev = np.zeros((30, m.nbody))
    p.set_plan(_rollout(m, d, np.ones((1, m.nu)), 30), deviation=dev)
    d.ctrl[:] = 1.0  # the arm moves as planned
    mujoco.mj_step(m, d)
    p.step(d)
    basis = p.verdict_basis(everything)
    assert (basis[:, 0] == 3).all() and (basis[:, 1] == 0).all()
    arm = {m.body("arm").id, m.body("hand").id}
    for _ in range(3):
        mujoco.mj_step(m, d)
        p.step(d)
    assert p.plan_breaks == 0
    p.set_plan(_rollout(m, d, np.zeros((1, m.nu)), 30), deviation=dev)  # held still: it breaks
    for _ in range(5):
        d.ctrl[:] = 1.0
        mujoco.mj_step(m, d)
        p.step(d)
    assert p.plan_breaks >= 1
    g1, g2 = p.tables.geom1, p.tables.geom2
    b1, b2 = m.geom_bodyid[g1], m.geom_bodyid[g2]
    basis = p.verdict_basis(everything)[:, 0]
    ok = np.asarray(p._rt.plan_ok)
    broken = {b for b in arm if not ok[b]}
    assert broken
    off1, off2 = np.isin(b1, list(broken)), np.isin(b2, list(broken))
    static = (m.body_weldid[b1] == 0) | (m.body_weldid[b2] == 0)
    # A planned body against a broken one: the mixed tau (the plan on one side); against a
    # static body, or two broken ones: the bounds alone.
    mixed = (off1 ^ off2) & ~static
    want = np.where(mixed, np.where(off1, 2, 1), 0)
    assert (basis[off1 | off2] == want[off1 | off2]).all()
    assert (basis[mixed] > 0).sum() >= 2


def _strays(shift: float, turn: float, dev: float) -> bool:
    """Whether the box (a free body) breaks an exact plan of deviation ``dev`` when the state the
    step reads has it shifted by ``shift`` metres along x and turned by ``turn`` radians about
    its own z axis (its origin, the geom's centre, kept)."""
    m, d = _scene()
    p = Predictor(m, accel=ACCEL, alarm_horizon=0.05)
    mujoco.mj_step(m, d)
    p.reset(d)
    box = m.body("box").id
    deviation = np.zeros((20, m.nbody))
    deviation[:, box] = dev
    p.set_plan(_rollout(m, d, np.zeros((1, m.nu)), 20), deviation=deviation)
    adr = m.jnt_qposadr[m.body("box").jntadr[0]]
    d.qpos[adr] += shift
    q = np.empty(4)
    mujoco.mju_mulQuat(
        q, d.qpos[adr + 3 : adr + 7].copy(), [np.cos(turn / 2), 0, 0, np.sin(turn / 2)]
    )
    d.qpos[adr + 3 : adr + 7] = q
    mujoco.mj_forward(m, d)
    mujoco.mj_step(m, d)  # reads the state set: the plan's knot 0, strayed
    p.step(d)
    return not p._rt.plan_ok[box]


def test_a_body_strayed_past_its_deviation_breaks_its_plan() -> None:
    """The check is exact at the box's corners: 1.5 times a 1 cm deviation breaks, half of it
    does not (a check allowing twice the deviation fails the first, one scaled up the second)."""
    assert _strays(0.015, 0.0, 0.01)
    assert not _strays(0.005, 0.0, 0.01)


def test_a_turn_alone_past_the_deviation_breaks_its_plan() -> None:
    """A turn about the box's own centre moves no origin, only its corners: by 2 sin(a / 2) r,
    r the corners' distance from the axis (0.064 m). 1.5 times the deviation there breaks, half
    of it does not (a check without the rotation term fails the first)."""
    r = np.hypot(0.05, 0.04)

    def angle(distance: float) -> float:
        return 2 * np.arcsin(distance / (2 * r))

    assert _strays(0.0, angle(0.015), 0.01)
    assert not _strays(0.0, angle(0.005), 0.01)


def test_the_monitor_counts_a_planned_bodys_bound_violations_and_labels_by_the_basis() -> None:
    """Bounds far too small for gravity (every falling body breaks them every step) and exact
    plans: the run monitor counts every violation (a plan excuses none), yet no onset is
    labelled by them, for no verdict in force rested on the bounds they broke: none comes short
    of the horizon, none is missed. Without the plans the onsets come short, after violations."""
    m, _ = _scene()
    horizon, every = 0.1, 25
    n = round(horizon / 0.002) + 2 * every
    ctrl = _controls(m, 1000, seed=6)
    p, planned = _monitored(
        horizon, lambda k, data: (_rollout(m, data, ctrl[k:], n), 0.0), ctrl=ctrl
    )
    assert p.plan_breaks == 0 and planned.violations > 100
    assert planned.onsets >= 3 and planned.misses == []
    assert planned.warning.short_leads == planned.warning.short_at_start == 0
    _, bounds = _monitored(horizon, lambda k, data: None, ctrl=ctrl)
    assert bounds.warning.short_after_violation >= 1 and bounds.warning.short_held == 0


def test_the_plugin_follows_a_plan_as_the_predictor_does() -> None:
    """The plugin (inside mj_step, reading the state before time advances) and the Python
    predictor (after it) given the same plans stand the same pairs after every step: the plan's
    knots are placed by the state each reads."""
    from dua_mujoco.plugin import attach, clear_plan, set_plan, standing_pairs

    spec = mujoco.MjSpec.from_string(SCENE)
    p = attach(spec, accel=ACCEL, alarm_horizon=0.1)
    m = spec.compile()
    d = mujoco.MjData(m)
    d.qvel[0] = 1.5
    steps, every, n = 300, 20, 100
    ctrl = _controls(m, steps + n, seed=7)
    busy = 0
    for k in range(steps):
        if k % every == 0 and k:
            plan = _rollout(m, d, ctrl[k:], n)
            set_plan(m, d, plan, deviation=0.002)
            p.set_plan(plan, deviation=0.002)
        if k == 250:
            clear_plan(m, d)
            p.clear_plan()
        d.ctrl[:] = ctrl[k]
        mujoco.mj_step(m, d)
        if k == 0:
            p.reset(d)
            continue
        p.step(d)
        state = p.pair_state()
        stand = np.flatnonzero(state.alarm_state() & state.active)
        want = {tuple(sorted((int(p.tables.geom1[i]), int(p.tables.geom2[i])))) for i in stand}
        got = {tuple(int(g) for g in row) for row in standing_pairs(m, d)}
        assert got == want, f"step {k}"
        busy += bool(want)
    assert busy > 20 and p.plan_breaks == 0


def test_verdicts_after_a_plan_is_cleared_rest_on_the_bounds() -> None:
    """Once the plan is cleared, each pair's next verdicts rest on the bounds on both sides: the
    runtime stops shifting the bases only when none is the plan's any more (a basis left stale
    would have the monitor label onsets by a plan that no longer stands)."""
    m, d = _scene()
    p = Predictor(m, accel=ACCEL, alarm_horizon=0.05)
    mujoco.mj_step(m, d)
    p.reset(d)
    everything = np.arange(p.nsphere_pairs)
    p.set_plan(_rollout(m, d, np.ones((1, m.nu)), 30), deviation=np.zeros((30, m.nbody)))
    d.ctrl[:] = 1.0
    for _ in range(3):
        mujoco.mj_step(m, d)
        p.step(d)
    assert (p.verdict_basis(everything)[:, 0] == 3).all()
    p.clear_plan()
    # Long enough for every pair of this scene to be evaluated twice (else a pair would keep its
    # plan-based verdict, rightly, and the assertion below fail).
    for _ in range(200):
        mujoco.mj_step(m, d)
        p.step(d)
    assert (p.verdict_basis(everything) == 0).all()
