"""Relative deviations of plans (``set_plan(..., relative=...)``; docs/theory.md, Lemma 8.2d).

The relative gap is held to a slow reference on random poses (MuJoCo's distance at the actual
poses is never below the planned distance less the relative deviation that reference measures,
and the runtime's check agrees with it); on a three-link arm whose first and last links lie
side by side, a plan off in the arm's swing leaves their relative pose exact (no break, and the
pair stands no more), a fold of the last link beyond its relative deviation is a plan break the
runtime counts and the monitor sees, and a relative deviation above the sum changes nothing.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from mjcf import link, mjcf, motors
from reference_plan import first_knot_within, last_taus
from reference_relative import relative_deviation

from dua_mujoco import _core
from dua_mujoco.build.events import B_CENTER, B_HALF, NB_REC
from dua_mujoco.exceptions import InvalidInputError, ShapeError
from dua_mujoco.measure.monitor import Monitor
from dua_mujoco.runtime.plans import PilotPlan, deviation_profile, relative_profile
from dua_mujoco.runtime.predictor import Predictor

TWO = """
<mujoco>
  <worldbody>
    <body name="a"><freejoint/><geom name="a" type="capsule" size=".05 .2"/></body>
    <body name="b"><freejoint/><geom name="b" type="box" size=".1 .06 .04"/></body>
  </worldbody>
</mujoco>
"""

# Three links in a plane; the last folds back beside the first, 4 cm apart (surfaces).
_HINGE = {"axis": "0 0 1", "damping": "1"}
_L3 = link("l3", "j3", "0 .1 0", "-.02 0 0 -.25 0 0", **_HINGE)
_L2 = link("l2", "j2", ".3 0 0", "0 0 0 0 .1 0", _L3, **_HINGE)
ARM = mjcf(
    link("l1", "j1", "0 0 .5", ".05 0 0 .3 0 0", _L2, **_HINGE),
    option='timestep="0.002" gravity="0 0 0" integrator="implicitfast"',
    actuator=motors("j1", "j2", "j3", kind="position", kp="50", kv="2"),
)


def _pose(rng_vec: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """A pose from 6 numbers: a position and a rotation vector."""
    pos = np.array(rng_vec[:3])
    rot = np.array(rng_vec[3:])
    angle = float(np.linalg.norm(rot))
    quat = np.array([1.0, 0.0, 0.0, 0.0])
    if angle > 0:
        mujoco.mju_axisAngle2Quat(quat, rot / angle, angle)
    mat = np.empty(9)
    mujoco.mju_quat2Mat(mat, quat)
    return pos, mat


def _distance(m: mujoco.MjModel, d: mujoco.MjData, pa, pb) -> float:  # type: ignore[no-untyped-def]
    d.geom_xpos[0], d.geom_xmat[0] = pa
    d.geom_xpos[1], d.geom_xmat[1] = pb
    return float(mujoco.mj_geomDistance(m, d, 0, 1, 10.0, None))


vec = st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6)


@settings(max_examples=150, deadline=None)
@given(vec, vec, vec, st.lists(st.floats(-0.05, 0.05), min_size=6, max_size=6))
def test_the_actual_distance_is_never_below_the_planned_one_less_the_relative_deviation(
    plan_a: list[float], plan_b: list[float], rigid: list[float], twist: list[float]
) -> None:
    """Random planned poses of two geoms; the actual ones a rigid motion of both (any size) and
    a small relative one: the actual distance is at least the planned one less the reference's
    relative deviation of b's box in a's frame (Lemma 8.2d), and the runtime's check
    (RelativeWithin) passes that deviation and refuses 1 % less. A world-frame measure fails
    the second on large rigid motions."""
    m = mujoco.MjModel.from_xml_string(TWO)
    d = mujoco.MjData(m)
    pa, pb = _pose(plan_a), _pose([2.0 * x for x in plan_b])
    move, turn = _pose(rigid), _pose(twist)

    def moved(pose, by):  # type: ignore[no-untyped-def]
        r = by[1].reshape(3, 3)
        return by[0] + r @ pose[0], (r @ pose[1].reshape(3, 3)).reshape(9)

    aa = moved(pa, move)
    ab = moved(moved(pb, turn), move)
    center, half = np.zeros(3), np.array([0.1, 0.06, 0.04])
    dev = relative_deviation(center, half, aa, ab, pa, pb)
    planned, actual = _distance(m, d, pa, pb), _distance(m, d, aa, ab)
    assume(planned > 0.0)  # a penetration's depth is not a distance
    assert actual >= planned - dev - 1e-9, (actual, planned, dev)
    box = np.zeros(NB_REC)
    box[B_CENTER : B_CENTER + 3], box[B_HALF : B_HALF + 3] = center, half
    within = lambda limit: _core.relative_within(box, *aa, *ab, *pa, *pb, limit)  # noqa: E731
    assert within(dev * (1 + 1e-9) + 1e-9)
    if dev > 1e-6:
        assert not within(dev * 0.99)


# ----------------------------------------------------------------------------- the arm


def _arm() -> tuple[mujoco.MjModel, mujoco.MjData, Predictor]:
    m = mujoco.MjModel.from_xml_string(ARM)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    p = Predictor(m, accel=50.0, alarm_horizon=0.2)
    return m, d, p


def _roll(m: mujoco.MjModel, d: mujoco.MjData, ctrl: np.ndarray, n: int) -> np.ndarray:
    c = mujoco.MjData(m)
    mujoco.mj_copyData(c, m, d)
    out = [c.qpos.copy()]
    for j in range(n - 1):
        c.ctrl[:] = ctrl[min(j, len(ctrl) - 1)]
        mujoco.mj_step(m, c)
        out.append(c.qpos.copy())
    return np.array(out)


def _pair(m: mujoco.MjModel) -> tuple[int, int]:
    return m.body("l1").id, m.body("l3").id


def _stands(p: Predictor, m: mujoco.MjModel) -> bool:
    """Whether a sphere pair of the first and last link stands in alarm."""
    state = p.pair_state()
    stand = np.flatnonzero(state.alarm_state() & state.active)
    g = {m.geom("l1").id, m.geom("l3").id}
    return any({int(p.tables.geom1[i]), int(p.tables.geom2[i])} == g for i in stand)


def test_a_plan_off_in_the_swing_keeps_the_relative_pose_and_frees_the_pair() -> None:
    """The run swings the arm, the plan holds it still: each link strays from its plan by up to
    the swing (15 cm), their relative pose not at all. With the sum of the deviations the pair
    of the first and last link (4 cm apart) stands at every step; with their relative
    deviation (1 cm) it does not, and nothing breaks (a world-frame check would break it)."""
    m, d, p = _arm()
    n = 300  # past the 150 steps run by more than the horizon
    swing = np.tile([0.5, 0.0, 0.0], (n, 1))
    dev = np.full((n, m.nbody), 0.2)
    out = []
    for relative in (None, ([_pair(m)], 0.01)):
        mujoco.mj_resetData(m, d)
        mujoco.mj_forward(m, d)
        p.reset(d)
        p.set_plan(_roll(m, d, np.zeros((1, 3)), n), deviation=dev, relative=relative)
        stood = 0
        for k in range(150):
            d.ctrl[:] = swing[k]
            mujoco.mj_step(m, d)
            p.step(d)
            stood += _stands(p, m)
        out.append((stood, p.plan_breaks))
    assert out[0] == (150, 0), out
    assert out[1] == (0, 0), out


def test_a_run_that_is_the_plan_keeps_a_relative_deviation_of_0() -> None:
    """The plan is the run itself (the arm swinging under the same controls), with a relative
    deviation of 0 between the first and last link: the knots' poses lie within the plan's
    tolerance of MuJoCo's (their hinges by polynomials), and the relative deviation is widened
    by three times it (docs/theory.md, "The knots' hinges"), so nothing breaks."""
    m, d, p = _arm()
    n = 200
    swing = np.tile([0.5, 0.0, 0.4], (n, 1))
    p.reset(d)
    p.set_plan(
        _roll(m, d, swing, n), deviation=np.full((n, m.nbody), 0.2), relative=([_pair(m)], 0.0)
    )
    assert p.plan_tolerance > 0.0
    for k in range(150):
        d.ctrl[:] = swing[k]
        mujoco.mj_step(m, d)
        p.step(d)
    assert p.plan_breaks == 0 and p.beyond_plan_relative().size == 0


def test_a_relative_pairs_rises_are_those_of_its_widened_deviations() -> None:
    """The walk searches a relative pair's knots only where min(D_a + D_b, D_ab) never falls,
    read as widened (each body's D + T, the pair's D_ab + 3T; docs/theory.md, "The knots'
    hinges"). Given 0.5 m a body at knot 0 and 0 after, and D_ab 0 at knot 0 and 0.5 m after, the
    minimum as given is 0 throughout, but as widened it is 3T, then 2T: it falls, and the pair
    is walked knot by knot. With 0.5 m a body at every knot it rises (3T, then 0.5 m + 3T)."""
    m, d, p = _arm()
    p.reset(d)
    n = 10
    rel = np.r_[0.0, np.full(n - 1, 0.5)][:, None]
    falling = np.zeros((n, m.nbody))
    falling[0] = 0.5
    for dev, rises in ((falling, False), (np.full((n, m.nbody), 0.5), True)):
        p.set_plan(np.tile(d.qpos, (n, 1)), deviation=dev, relative=([_pair(m)], rel))
        assert p.plan_tolerance > 0.0
        assert p._rt.plan_relative_rises.tolist() == [rises], dev[:2]


def _fold(monitor: bool = False) -> tuple[Predictor, Monitor | None, mujoco.MjModel]:
    """The plan holds the arm still with deviations of 0.3 m a body (the fold stays within
    them) and 5 mm between the first and last link; the run folds the last link into the first
    within 0.1 s (less than the 0.2 s horizon)."""
    m, d, p = _arm()
    n = 400
    mon = Monitor(p) if monitor else None
    mujoco.mj_step(m, d)
    if mon is not None:
        mon.start(d)
    else:
        p.reset(d)
    p.set_plan(
        _roll(m, d, np.zeros((1, 3)), n),
        deviation=np.full((n, m.nbody), 0.3),
        relative=([_pair(m)], 0.005),
        start=float(d.time) - m.opt.timestep,
    )
    for k in range(250):
        d.ctrl[:] = [0.0, 0.0, 0.6 if k >= 150 else 0.0]  # past the horizon from the start
        mujoco.mj_step(m, d)
        step = p.step(d)
        if mon is not None:
            mon.observe(d, step)
    if mon is not None:
        mon.finish()
    return p, mon, m


def test_a_fold_beyond_the_relative_deviation_is_a_plan_break() -> None:
    """The fold moves the last link 5 mm off its place relative to the first within a few
    steps: the runtime counts a plan break (no body breaks its own deviation), reports the pair
    as beyond its relative deviation, and the pair's verdicts fall back on the sum (it stands).
    Without the relative check nothing breaks."""
    p, _, m = _fold()
    assert p.plan_breaks >= 1
    assert p._rt.plan_ok[list(_pair(m))].all()  # the bodies are within their own deviation
    assert p.beyond_plan_relative().tolist() == [list(_pair(m))]
    assert _stands(p, m)


def test_the_monitor_labels_an_onset_after_a_relative_break_as_not_held() -> None:
    """The fold's contact comes with less lead than the horizon, after the relative bound its
    verdicts rested on broke: the monitor labels it after a break, never as held (a monitor
    that reads only the bodies' breaks labels it held)."""
    _, mon, _ = _fold(monitor=True)
    assert mon is not None and mon.onsets >= 1
    assert mon.warning.short_held == 0, mon.warning.leads
    assert mon.warning.short_after_violation >= 1


def test_a_relative_deviation_above_the_sum_changes_no_verdict() -> None:
    """``min(D_a + D_b, D_ab)``: as the last link folds into the first, a relative deviation of
    1 m, above the 2 cm sum, gives the pair the knot it has without it (the relative term alone
    would give knot 0), and one of 0 a knot no earlier."""
    m, d, p = _arm()
    p.reset(d)
    n = 150
    qpos = _roll(m, d, np.tile([0.0, 0.0, 0.8], (n, 1)), n)
    dev = np.full((n, m.nbody), 0.01)
    pairs = [(m.geom("l1").id, m.geom("l3").id)]
    start = float(d.time) - m.opt.timestep  # the state the data holds
    knots = {
        r: p.plan_contact_knots(
            qpos, pairs, deviation=dev, start=start, relative=None if r is None else ([_pair(m)], r)
        )
        for r in (None, 1.0, 0.0)
    }
    without, above, below = knots[None], knots[1.0], knots[0.0]
    assert without[0] > 0 and (above == without).all(), (without, above)
    assert below[0] >= without[0]


def test_the_pilot_measures_relative_deviations_below_the_sum() -> None:
    """On a pilot that swings the arm against plans that hold it still, the link pairs' own
    deviations grow with the swing while their relative pose stays: relative_profile keeps the
    pair of the first and last link (the only pair of the arm with a geom pair), with a
    deviation far below the sum, and set_plan takes it."""
    m, d, p = _arm()
    p.reset(d)
    rows, plans = [d.qpos.copy()], []
    for k in range(300):
        if k % 20 == 0:
            plans.append(PilotPlan(len(rows) - 1, _roll(m, d, np.zeros((1, 3)), 40)))
        d.ctrl[:] = [0.5 * np.sin(k / 100.0), 0.0, 0.0]
        mujoco.mj_step(m, d)
        rows.append(d.qpos.copy())
    q = np.array(rows)
    profile = deviation_profile(m, q, plans, points=p.bound_points)
    gp = p.geom_pairs
    rel = relative_profile(
        m, q, plans, points=p.bound_points, geom_pairs=(gp.geom1, gp.geom2), profile=profile
    )
    a, b = _pair(m)
    assert rel.pairs.tolist() == [[a, b]]
    assert rel.deviation[-1, 0] < 0.25 * (profile[-1, a] + profile[-1, b])
    # No geom pair, no candidate: an empty table (the numpy twin of RelativePose raised).
    none = relative_profile(
        m, q, plans, points=p.bound_points, geom_pairs=([], []), profile=profile
    )
    assert none.pairs.shape == (0, 2) and none.deviation.shape == (40, 0)
    mujoco.mj_forward(m, d)
    p.reset(d)
    qpos = _roll(m, d, np.zeros((1, 3)), 40)
    p.set_plan(qpos, deviation=profile[:40], relative=rel.relative(40))


def test_bad_relative_deviations_are_refused_by_name() -> None:
    m, d, p = _arm()
    p.reset(d)
    qpos = _roll(m, d, np.zeros((1, 3)), 20)
    a, b = _pair(m)
    with pytest.raises(InvalidInputError, match="not a finite distance"):
        p.set_plan(qpos, deviation=0.1, relative=([(a, b)], np.nan))
    with pytest.raises(InvalidInputError, match="twice"):
        p.set_plan(qpos, deviation=0.1, relative=([(a, b), (b, a)], 0.1))
    with pytest.raises(InvalidInputError, match="bodies the plan holds"):
        p.set_plan(qpos, deviation=0.1, relative=([(0, b)], 0.1))
    with pytest.raises(InvalidInputError, match="bodies the plan holds"):
        p.set_plan(qpos, deviation=0.1, relative=([(a, a)], 0.1))
    # A body id out of range is the runtime's to name (Python does not check it again).
    msg = rf"relative pair 0 \(bodies {a}, 99\), not bodies of the model's {m.nbody}: pass body ids"
    with pytest.raises(InvalidInputError, match=msg):
        p.set_plan(qpos, deviation=0.1, relative=([(a, 99)], 0.1))
    with pytest.raises(ShapeError, match="relative deviation has shape"):
        p.set_plan(qpos, deviation=0.1, relative=([(a, b)], np.zeros((3, 1))))
    with pytest.raises(InvalidInputError, match="relative = "):
        p.set_plan(qpos, deviation=0.1, relative=5)  # type: ignore[arg-type]
    p.set_plan(qpos, deviation=0.1, relative=([("l3", "l1")], 0.1))  # names, either order


def _still_plan(m: mujoco.MjModel, d: mujoco.MjData, p: Predictor, dev: np.ndarray) -> None:
    """A plan that holds the arm still (deviation ``dev``, 2 cm for the pair), 5 steps of it."""
    mujoco.mj_step(m, d)
    p.reset(d)
    p.set_plan(_roll(m, d, np.zeros((1, 3)), len(dev)), deviation=dev, relative=([_pair(m)], 0.02))
    for _ in range(5):
        mujoco.mj_step(m, d)
        p.step(d)


def test_a_replaced_plans_relative_pair_is_checked_from_the_new_plans_departure() -> None:
    """A replan that keeps the arm still for 20 steps and then folds the last link, with a
    tighter relative deviation (5 mm) than the plan it replaces (2 cm): the replaced plan's
    relative pair is nested in the new one until the fold leaves its relative tube, a knot the
    nesting must find. The run follows the new plan: the replaced
    plan's relative pair breaks once, after the fold starts, and the new plan holds."""
    m, d, p = _arm()
    n = 300
    dev = np.full((n, m.nbody), 0.3)  # the fold stays within every body's own deviation
    _still_plan(m, d, p, dev)
    fold = np.array([[0.0, 0.0, 0.0]] * 20 + [[0.0, 0.0, 0.6]])
    p.set_plan(_roll(m, d, fold, n), deviation=dev, relative=([_pair(m)], 0.005))
    breaks = []
    for k in range(100):
        d.ctrl[:] = fold[min(k, len(fold) - 1)]
        mujoco.mj_step(m, d)
        p.step(d)
        breaks.append(p.plan_breaks)
    assert breaks[20] == 0, breaks  # nested while the new plan keeps the old relative pose
    assert breaks[-1] == 1, breaks  # the replaced plan's relative pair, past the fold
    assert p._rt.plan_ok[list(_pair(m))].all()  # no body broke its own deviation


@pytest.mark.parametrize("jump", [False, True], ids=["fold", "jump"])
def test_a_replan_keeps_the_old_walks_cleared_knots_only_within_the_relative_tube(
    jump: bool,
) -> None:
    """The still plan's walk cleared the first and last link to its last knot on their relative
    deviation (2 cm, below the 60 cm sum). A replan with tighter deviations (10 cm a body, 5 mm
    between them) folds the last link into the first from knot 20, or (``jump``) puts it through
    the first from knot 30 on, so that the pair leaves its old relative tube and may touch at
    that very knot: each body stays in its old tube over the span, the pair's relative pose
    leaves its old one. The pair's first walk under the new plan starts no later than that knot
    (docs/theory.md, Lemma 8.2e): its tau is at most the time to the first knot at which
    MuJoCo's distance may touch, which a walk started at the bodies' nesting end, or a knot past
    the relative departure, passes."""
    m, d, p = _arm()
    n = 300
    _still_plan(m, d, p, np.full((n, m.nbody), 0.3))
    if jump:
        qpos = _roll(m, d, np.zeros((1, 3)), n)
        qpos[30:, m.jnt_qposadr[m.joint("j3").id]] = 0.2  # the last link through the first
    else:
        qpos = _roll(m, d, np.array([[0.0, 0.0, 0.0]] * 20 + [[0.0, 0.0, 0.6]]), n)
    departures = p.set_plan(
        qpos, deviation=np.full((n, m.nbody), 0.1), relative=([_pair(m)], 0.005)
    )
    assert np.isinf(departures[list(_pair(m))]).all()  # both bodies nested in their old tubes
    mujoco.mj_step(m, d)
    p.step(d)
    got = last_taus(m, p, "l1", "l3")
    touch = first_knot_within(m, qpos, "l1", "l3", 0.005)
    h = float(m.opt.timestep)
    assert touch is not None and (touch == 30 if jump else 20 < touch < 90), touch
    assert (got <= touch * h + 1e-12).all(), (got, touch)


def _steps_to_break(
    m: mujoco.MjModel, d: mujoco.MjData, p: Predictor, fold: np.ndarray
) -> int | None:
    """The run of ``fold``'s controls: the step of its first plan break, None if none within 60
    steps."""
    for k in range(60):
        d.ctrl[:] = fold[min(k, len(fold) - 1)]
        mujoco.mj_step(m, d)
        p.step(d)
        if p.plan_breaks:
            return k
    return None


def _first_break(fold: np.ndarray, relative: bool) -> int | None:
    """The step of the first plan break when a replan that folds the last link (no relative
    deviation, if ``relative``; else without the pair) replaces a still plan (2 cm) and the run
    is that replan: None if none within 60 steps."""
    m, d, p = _arm()
    n = 300
    dev = np.full((n, m.nbody), 0.3)
    _still_plan(m, d, p, dev)
    p.set_plan(
        _roll(m, d, fold, n), deviation=dev, relative=([_pair(m)], 0.0) if relative else None
    )
    return _steps_to_break(m, d, p, fold)


@pytest.mark.parametrize("start", [20, 21, 22, 23])
def test_a_relative_departure_is_found_at_its_knot_in_every_lane(start: int) -> None:
    """The relative nesting checks four knots at a time (RelativeDeparture's lanes). A replan
    that folds the last link from step ``start`` (four starts: the departure in each lane of a
    block), with no relative deviation of its own, is followed exactly: the replaced plan's
    pair breaks at the very knot the replan leaves its tube, which its shadow checks from the
    departure on. So the break comes at the same step as when the replan lacks the pair (then
    the shadow checks it at every step): a departure found a knot late would come later."""
    fold = np.array([[0.0, 0.0, 0.0]] * start + [[0.0, 0.0, 0.6]])
    step = _first_break(fold, relative=True)
    assert step is not None and step > start
    assert step == _first_break(fold, relative=False)


def _first_body_break(fold: np.ndarray, held: bool) -> int | None:
    """The step of the first plan break when a replan that folds the last link (no deviation;
    without the last link unless ``held``) replaces a still plan (2 cm, no relative pair) and
    the run is that replan: None if none within 60 steps."""
    m, d, p = _arm()
    n = 300
    mujoco.mj_step(m, d)
    p.reset(d)
    p.set_plan(_roll(m, d, np.zeros((1, 3)), n), deviation=0.02)
    for _ in range(5):
        mujoco.mj_step(m, d)
        p.step(d)
    bodies = ["l1", "l2", "l3"] if held else ["l1", "l2"]
    p.set_plan(_roll(m, d, fold, n), deviation=0.0, bodies=bodies)
    return _steps_to_break(m, d, p, fold)


@pytest.mark.parametrize("start", [20, 21, 22, 23])
def test_a_bodys_departure_is_found_at_its_knot_in_every_lane(start: int) -> None:
    """The bodies' nesting checks four knots at a time (BodyDeparture's lanes). A replan that
    folds the last link from step ``start`` (four starts: the departure in each lane of a
    block), with no deviation of its own, is followed exactly: the replaced plan breaks at the
    very knot the replan leaves its tube (``|new - old| > D_old``, the replaced plan's own
    check), which its shadow checks from the departure on. So the break comes at the same step
    as when the replan does not hold the last link (then the shadow checks it at every step): a
    departure found late (a block late, at a block's end, or past a screen that passed a knot
    beyond the tube) would come later."""
    fold = np.array([[0.0, 0.0, 0.0]] * start + [[0.0, 0.0, 0.6]])
    step = _first_body_break(fold, held=True)
    assert step is not None and step > start
    assert step == _first_body_break(fold, held=False)


# A rod 40 cm long (a box along its z axis, 1 cm across) on a hinge about x through its centre,
# beside a block on a hinge about z that stays still: the rod's turn changes its rotation's
# last entry (cos(theta) - 1 of it), which the arm's links, all on hinges about z, never do.
ROD = mjcf(
    '<body name="block" pos="0 0 .5"><joint name="spin" type="hinge" axis="0 0 1"/>'
    '<geom name="block" type="box" size=".05 .05 .05"/></body>',
    '<body name="rod" pos=".6 0 .5"><joint name="tilt" type="hinge" axis="1 0 0"/>'
    '<geom name="rod" type="box" size=".01 .01 .2"/></body>',
    option='timestep="0.002" gravity="0 0 0"',
    actuator=motors("spin", "tilt"),
)


def _first_tilt_break(start: int, held: bool, relative: bool) -> int | None:
    """The step of the first plan break when a replan that turns the rod about x from step
    ``start`` (a torque, so past 90 degrees within 60 steps) replaces a plan that holds both
    bodies still, and the run is that replan: None if none within 60 steps. The replaced plan's
    tube is the rod's (35 cm), or, if ``relative``, the pair's (35 cm; the bodies' own 50 cm,
    which the turn stays within). The replan holds the rod with no deviation, or the pair with
    no relative deviation (the bodies' own as before); or, unless ``held``, not at all."""
    m = mujoco.MjModel.from_xml_string(ROD)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    p = Predictor(m, accel=50.0, alarm_horizon=0.2)
    n = 300
    pair = ([(m.body("block").id, m.body("rod").id)], 0.35)
    mujoco.mj_step(m, d)
    p.reset(d)
    still = _roll(m, d, np.zeros((1, 2)), n)
    if relative:
        p.set_plan(still, deviation=0.5, relative=pair)
    else:
        p.set_plan(still, deviation=0.35)
    for _ in range(5):
        mujoco.mj_step(m, d)
        p.step(d)
    turn = np.array([[0.0, 0.0]] * start + [[0.0, 2.0]])
    plan = _roll(m, d, turn, n)
    if relative:
        p.set_plan(plan, deviation=0.5, relative=(pair[0], 0.0) if held else None)
    else:
        p.set_plan(plan, deviation=0.0, bodies=["block", "rod"] if held else ["block"])
    step = _steps_to_break(m, d, p, turn)
    assert step is None or plan[step + 1, m.joint("tilt").qposadr[0]] > np.pi / 2  # the turn
    return step


@pytest.mark.parametrize("start", [20, 21, 22, 23])
def test_a_bodys_departure_turning_about_x_is_found_at_its_knot_in_every_lane(start: int) -> None:
    """As the arm's fold above, of a body whose turn changes its rotation's last entry (the lanes
    load it knot by knot, apart from the other eight): the rod turns about x past 90 degrees, and
    leaves the replaced plan's 35 cm tube at its knot in every lane of a block, the same step as
    when the replan does not hold the rod. Without the last entry the lanes' screen would take
    the rod's long column of R - R' as |sin(theta)| (0.2 m of reach at most; sqrt(2) |sin(theta)|
    reading the eighth entry for it, 0.28 m), not 2 |sin(theta / 2)|: it would pass every knot of
    the turn, and no break would come."""
    step = _first_tilt_break(start, held=True, relative=False)
    assert step is not None and step > start
    assert step == _first_tilt_break(start, held=False, relative=False)


@pytest.mark.parametrize("start", [20, 21, 22, 23])
def test_a_relative_departure_turning_about_x_is_found_at_its_knot_in_every_lane(
    start: int,
) -> None:
    """As above, of the pair of the block and the rod: the rod's turn about x, in the block's
    frame, changes the relative rotation's last entry (the lanes' last block of four entries),
    and the replan leaves the replaced plan's 35 cm relative tube at its knot in every lane, the
    same step as when the replan does not hold the pair."""
    step = _first_tilt_break(start, held=True, relative=True)
    assert step is not None and step > start
    assert step == _first_tilt_break(start, held=False, relative=True)


def test_a_replan_nested_in_the_newest_shadow_keeps_the_older_shadows_relative_departures() -> None:
    """Three plans in turn (docs/theory.md, Lemma 8.6), with a relative pair. A second that folds
    the last link 20 steps on, then a third that keeps to it (nested in it: its shadow is
    dropped): the first plan's relative pair still departs, and breaks once the run folds. Or a
    second that keeps the arm (only a wider deviation of the middle link: the first stays) and
    a third that folds: it leaves both relative tubes, and the run breaks both."""
    n = 300
    fold = np.array([[0.0, 0.0, 0.0]] * 15 + [[0.0, 0.0, 0.6]])
    for late in (True, False):
        m, d, p = _arm()
        dev = np.full((n, m.nbody), 0.3)
        wide = dev.copy()
        wide[:, m.body("l2").id] = 0.4
        _still_plan(m, d, p, dev)
        ctrl = np.concatenate([np.zeros((5, 3)), fold]) if late else np.zeros((1, 3))
        second = _roll(m, d, ctrl, n)
        p.set_plan(second, deviation=dev if late else wide, relative=([_pair(m)], 0.005))
        for k in range(5):
            d.ctrl[:] = ctrl[min(k, len(ctrl) - 1)]
            mujoco.mj_step(m, d)
            p.step(d)
        if late:
            assert np.array_equal(_roll(m, d, fold, n - 5), second[5:])  # the same plan
        p.set_plan(_roll(m, d, fold, n - 5), deviation=dev[5:], relative=([_pair(m)], 0.005))
        for k in range(100):
            d.ctrl[:] = fold[min(k, len(fold) - 1)]
            mujoco.mj_step(m, d)
            p.step(d)
        assert p.plan_breaks == (1 if late else 2)
        assert p._rt.plan_ok[list(_pair(m))].all()


def test_a_replaced_plans_relative_pair_is_read_at_its_own_place_in_the_new_plan() -> None:
    """The replaced plan has one relative pair, (l1, l3); the new one two, (l1, l2) first, so
    the shadow must read (l1, l3)'s flag at its own place in the new plan. The new plan holds
    the arm still for 40 steps and then folds; the run folds at once. It breaks the new plan's
    (l1, l3) (5 mm) within a few steps and the replaced plan's (2 cm) a few steps later, well
    before the new plan departs from the old: no longer proven by the new plan's pair, the
    shadow is checked and breaks then, not at the departure. (l1, l2) holds throughout: only the
    last joint moves, so a shadow reading its flag would wait for the departure.)"""
    m, d, p = _arm()
    n = 300
    dev = np.full((n, m.nbody), 0.3)
    _still_plan(m, d, p, dev)
    later = np.array([[0.0, 0.0, 0.0]] * 40 + [[0.0, 0.0, 0.6]])
    pairs = [(m.body("l1").id, m.body("l2").id), _pair(m)]
    p.set_plan(_roll(m, d, later, n), deviation=dev, relative=(pairs, 0.005))
    breaks = []
    for _ in range(30):
        d.ctrl[:] = [0.0, 0.0, 0.6]
        mujoco.mj_step(m, d)
        p.step(d)
        breaks.append(p.plan_breaks)
    assert breaks[2] == 0 and breaks[-1] == 2, breaks  # the new plan's (l1, l3), the shadow's
    assert p._rt.plan_ok[list(_pair(m))].all()  # no body broke its own deviation


def _chain(links: int) -> str:
    """``links`` hinge links in a chain, each a capsule and two boxes (many geoms a knot: the
    relative poses are computed a few knots at a time, over many blocks)."""
    body = ""
    for i in reversed(range(links)):
        axis = "0 0 1" if i % 2 == 0 else "0 1 0"
        body = (
            f'<body name="c{i}" pos="{0.0 if i == 0 else 0.25} 0 {0.5 if i == 0 else 0.0}">'
            f'<joint name="h{i}" axis="{axis}" damping=".2"/>'
            f'<geom type="capsule" fromto="0 0 0 .2 0 0" size=".03"/>'
            f'<geom type="box" pos=".1 .06 0" size=".02 .02 .02"/>'
            f'<geom type="box" pos=".1 -.06 0" size=".02 .02 .02"/>{body}</body>'
        )
    return f'<mujoco><option gravity="0 0 0"/><worldbody>{body}</worldbody></mujoco>'


def test_relative_poses_at_every_knot_of_plans_of_changing_sizes_are_the_runs() -> None:
    """Plans that are the run itself, every body at deviation 0 and every pair of links at
    relative deviation 0 (any bit off at any knot is a break), replaced by longer and shorter
    ones (the relative poses computed a block of knots at a time, in buffers recycled from the
    plans replaced): nothing breaks at any step, so each knot's planned relative poses are the
    run's, bit for bit."""
    m = mujoco.MjModel.from_xml_string(_chain(6))
    d = mujoco.MjData(m)
    d.qvel[:] = np.random.default_rng(5).normal(0.0, 2.0, m.nv)
    mujoco.mj_forward(m, d)
    p = Predictor(m, accel=50.0, alarm_horizon=0.05)
    p.reset(d)
    links = [m.body(f"c{i}").id for i in range(6)]
    pairs = [(a, b) for i, a in enumerate(links) for b in links[i + 1 :]]
    for n, steps in ((61, 20), (97, 30), (23, 10), (75, 40)):
        p.set_plan(
            _roll(m, d, np.zeros((1, 0)), n),
            deviation=0.0,
            start=float(d.time),
            relative=(pairs, 0.0),
        )
        for _ in range(steps):
            mujoco.mj_step(m, d)
            p.step(d)
        assert p.plan_breaks == 0, (n, p.plan_breaks)


def _still_pair() -> tuple[mujoco.MjModel, mujoco.MjData, Predictor]:
    """TWO's bodies a and b held still, their surfaces 25 cm apart, and a predictor reset there
    (for ``plan_contact_knots``' walks over plans that hold them still)."""
    m = mujoco.MjModel.from_xml_string(TWO)
    d = mujoco.MjData(m)
    d.qpos[:3] = [0.0, 0.0, 0.0]
    d.qpos[7:10] = [0.4, 0.0, 0.0]
    mujoco.mj_forward(m, d)
    p = Predictor(m, accel=50.0, alarm_horizon=0.2)
    p.reset(d)
    return m, d, p


@pytest.mark.parametrize("relative", [False, True], ids=["body", "relative"])
def test_a_deviation_that_falls_is_not_searched_past(relative: bool) -> None:
    """Two bodies held still 25 cm apart (surfaces): the pair's contact cannot be excluded at
    knot 3 alone, where a's deviation is 0.3 m (0.1 m elsewhere; ``Plan::Finish``'s rises), or
    where their relative deviation is (0 elsewhere, the bodies' 0.5 m each: min(D_a + D_b,
    D_ab); ``Plan::Relative``'s rises). The deviation falls after it, so the walk may not
    search for the end of the knots its carried gap clears (a search from knot 1 goes to 2, 4,
    8: past knot 3)."""
    m, d, p = _still_pair()
    n = 20
    dev = np.full((n, m.nbody), 0.5 if relative else 0.1)
    rel = np.zeros((n, 1))
    if relative:
        rel[3] = 0.3
    else:
        dev[3, m.body("a").id] = 0.3
    pair = (m.body("a").id, m.body("b").id)
    knots = p.plan_contact_knots(
        np.tile(d.qpos, (n, 1)),
        [[m.geom("a").id, m.geom("b").id]],
        deviation=dev,
        relative=([pair], rel) if relative else None,
        start=float(d.time) - m.opt.timestep,  # the state the step reads: the last one
    )
    assert knots.tolist() == [3], knots


def test_a_walks_search_stops_at_the_first_knot_a_rising_deviation_reaches() -> None:
    """The same two bodies held still, a's deviation 0.1 m up to knot ``at`` and 0.3 m from
    it on (rising, so the walk searches: the plan's last knot first, then a gallop and a
    bisection): the pair's first knot that cannot be excluded is ``at`` wherever it stands,
    the plan's last knot and the one before it included (a search that asked any other knot
    than the last before giving up the rest would pass over them)."""
    m, d, p = _still_pair()
    n = 20
    for at in range(n):
        dev = np.full((n, m.nbody), 0.1)
        dev[at:, m.body("a").id] = 0.3
        knots = p.plan_contact_knots(
            np.tile(d.qpos, (n, 1)),
            [[m.geom("a").id, m.geom("b").id]],
            deviation=dev,
            start=float(d.time) - m.opt.timestep,
        )
        assert knots.tolist() == [at], (at, knots)
