"""Making flight plans (dua_mujoco/runtime/plans.py): a plan is the simulation under the same
controls bit for bit; the deviation profile matches a slow reference; bad input is named."""

from __future__ import annotations

import copy

import mujoco
import numpy as np
import pytest

import dua_mujoco
from dua_mujoco.exceptions import InvalidInputError, NonFiniteStateError, ShapeError
from dua_mujoco.models.scenes import make_controller
from dua_mujoco.runtime.plans import (
    PilotPlan,
    deviation_profile,
    plan_deviation,
    plan_from_controls,
)
from dua_mujoco.runtime.predictor import Predictor

# Two links on hinges (a PD motor's and a position servo's), a free box that lands on the floor
# and rests there (contacts: the solver's warm start matters), a slider without a control range.
_XML = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="upper" pos="0 0 0.6">
      <joint name="shoulder" type="hinge" axis="0 1 0" range="-2 2" armature="0.02"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04" mass="1"/>
      <body name="fore" pos="0.4 0 0">
        <joint name="elbow" type="hinge" axis="0 1 0" range="-2 2" armature="0.01"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="0.5"/>
        <geom type="box" pos="0.3 0 0" size="0.05 0.04 0.03" mass="0.2"/>
      </body>
    </body>
    <body name="box" pos="0.5 0.3 0.3">
      <freejoint/>
      <geom type="box" size="0.06 0.05 0.04" mass="0.3"/>
    </body>
    <body name="cart" pos="-0.5 0 0.1">
      <joint name="rail" type="slide" axis="1 0 0"/>
      <geom type="sphere" size="0.05" mass="0.4"/>
    </body>
  </worldbody>
  <actuator>
    <motor joint="shoulder" gear="20" ctrlrange="-1 1"/>
    <position joint="elbow" kp="30" ctrlrange="-2 2"/>
    <motor joint="rail" gear="1"/>
  </actuator>
</mujoco>
"""


# The same robot dressed as robot models are: visual geoms (no contacts) between and beside the
# collision ones, on every body, offset and turned or not, and sites; a body that carries only a
# visual geom (a camera), and one without geoms between two links (a mount). A plan reads the
# collision geoms only, and computes their poses on the model without the rest (and without the
# bodies that carry none of them, the mount kept as the forearm's parent).
_VISUAL = (
    _XML.replace(
        '<body name="fore" pos="0.4 0 0">',
        '<body name="camera" pos=".2 0 .05" euler="0 20 0"><geom type="box" size=".02 .02 .02" '
        'contype="0" conaffinity="0" mass="0.01"/></body>'
        '<body name="mount" pos="0.4 0 0" euler="0 0 15"><body name="fore" euler="0 0 -15">',
    )
    .replace(
        '      </body>\n    </body>\n    <body name="box"', '</body></body></body><body name="box"'
    )
    .replace(
        '<geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04" mass="1"/>',
        '<geom type="mesh" mesh="m" contype="0" conaffinity="0" mass="0" pos=".1 .05 0"/>'
        '<geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04" mass="1"/>'
        '<site name="a" pos=".2 0 .05"/>'
        '<geom type="box" size=".1 .02 .02" contype="0" conaffinity="0" mass="0" euler="0 30 10"/>',
    )
    .replace(
        '<geom type="box" pos="0.3 0 0" size="0.05 0.04 0.03" mass="0.2"/>',
        '<geom type="sphere" size=".02" contype="0" conaffinity="0" mass="0"/>'
        '<geom type="box" pos="0.3 0 0" size="0.05 0.04 0.03" mass="0.2" euler="10 0 5"/>'
        '<site name="b"/><geom type="sphere" size=".01" pos=".1 .1 0" contype="0" conaffinity="0" '
        'mass="0"/>',
    )
    .replace(
        '<geom type="box" size="0.06 0.05 0.04" mass="0.3"/>',
        '<geom type="box" size="0.06 0.05 0.04" mass="0.3"/><site name="c" pos=".01 0 0"/>'
        '<geom type="box" size=".07 .01 .01" contype="0" conaffinity="0" mass="0" euler="0 0 45"/>',
    )
    .replace(
        "<worldbody>",
        '<asset><mesh name="m" vertex="0 0 0 .1 0 0 0 .1 0 0 0 .1"/></asset><worldbody>'
        '<geom type="box" size=".1 .1 .1" pos="2 2 -1" contype="0" conaffinity="0"/>',
        1,
    )
)


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(_XML)


def _settled(model: mujoco.MjModel, steps: int = 150, seed: int = 0) -> mujoco.MjData:
    """A state some steps into a smooth drive (the box in contact, warm start non-zero)."""
    d = mujoco.MjData(model)
    mujoco.mj_forward(model, d)
    drive = make_controller(model, "smooth", seed=seed, hold_steps=40)
    for _ in range(steps):
        drive(model, d)
        mujoco.mj_step(model, d)
    return d


def _simulate(model: mujoco.MjModel, d: mujoco.MjData, controls: np.ndarray) -> np.ndarray:
    """The simulation itself under ``controls``: ``(n + 1, nq)``."""
    sim = mujoco.MjData(model)
    mujoco.mj_copyData(sim, model, d)
    rows = [sim.qpos.copy()]
    for u in controls:
        sim.ctrl[:] = u
        mujoco.mj_step(model, sim)
        rows.append(sim.qpos.copy())
    return np.array(rows)


# ----------------------------------------------------------------------------- plans


def test_plan_of_controls_is_the_simulation_bit_for_bit(model: mujoco.MjModel) -> None:
    d = _settled(model)
    assert d.ncon > 0 and np.any(d.qacc_warmstart != 0.0)
    d.qfrc_applied[model.jnt_dofadr[2]] = 0.3  # held through the plan, as the simulation holds it
    rng = np.random.default_rng(1)
    u = rng.uniform(-1.0, 1.0, size=(120, model.nu))
    before = d.qpos.copy(), d.time
    plan = plan_from_controls(model, d, u)
    assert plan.shape == (121, model.nq)
    assert np.array_equal(plan, _simulate(model, d, u))
    assert np.array_equal(d.qpos, before[0]) and d.time == before[1]  # data untouched
    # Without the warm start the same controls give other positions: the test can tell.
    cold = mujoco.MjData(model)
    mujoco.mj_copyData(cold, model, d)
    cold.qacc_warmstart[:] = 0.0
    assert not np.array_equal(_simulate(model, cold, u), plan)


def test_plan_of_a_policy_is_the_simulation_bit_for_bit(model: mujoco.MjModel) -> None:
    d = _settled(model)
    drive = make_controller(model, "smooth", seed=5, hold_steps=40)
    for _ in range(7):  # the drive mid-segment
        drive(model, d)
        mujoco.mj_step(model, d)
    plan = plan_from_controls(model, d, copy.deepcopy(drive), steps=100)
    rows = [d.qpos.copy()]
    for _ in range(100):
        drive(model, d)
        mujoco.mj_step(model, d)
        rows.append(d.qpos.copy())
    assert np.array_equal(plan, np.array(rows))


def test_plan_through_a_mujoco_warning_is_still_the_simulation(model: mujoco.MjModel) -> None:
    # A control of 1e300 makes mj_step warn (bad control) and zero it, and go on; mujoco.rollout
    # stops at a warning and repeats that state to the end. The plan must follow mj_step.
    from mujoco import rollout

    d = _settled(model, steps=20)
    u = np.zeros((30, model.nu))
    u[10:, 2] = 1e300
    plan = plan_from_controls(model, d, u)
    sim = _simulate(model, d, u)
    assert np.array_equal(plan, sim)
    state0 = np.empty(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(model, d, state0, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    scratch = mujoco.MjData(model)
    state, _ = rollout.rollout(
        model, scratch, state0, u[None], initial_warmstart=np.array(d.qacc_warmstart)
    )
    assert not np.array_equal(state[0, :, 1 : 1 + model.nq], sim[1:])  # rollout alone stops


def test_plan_from_controls_names_bad_input(model: mujoco.MjModel) -> None:
    d = _settled(model, steps=2)
    with pytest.raises(ShapeError, match=r"\(5, 2\).*\(n, 3\)"):
        plan_from_controls(model, d, np.zeros((5, 2)))
    bad = np.zeros((4, model.nu))
    bad[2, 1] = np.nan
    with pytest.raises(InvalidInputError, match=r"controls\[2, 1\] = nan"):
        plan_from_controls(model, d, bad)
    with pytest.raises(InvalidInputError, match="steps is missing"):
        plan_from_controls(model, d, lambda m, dd: None)
    with pytest.raises(InvalidInputError, match="steps = 0"):
        plan_from_controls(model, d, lambda m, dd: None, steps=0)
    with pytest.raises(InvalidInputError, match="steps = 3 disagrees with the 4 rows"):
        plan_from_controls(model, d, np.zeros((4, model.nu)), steps=3)
    with pytest.raises(ShapeError, match=r"shape \(2,\) at step 0"):
        plan_from_controls(model, d, lambda m, dd: np.zeros(2), steps=3)
    with pytest.raises(InvalidInputError, match=r"data must be a mujoco\.MjData, got str"):
        plan_from_controls(model, "d", np.zeros((1, model.nu)))  # type: ignore[arg-type]
    other = mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>")
    with pytest.raises(InvalidInputError, match="data was made for another model"):
        plan_from_controls(other, d, np.zeros((1, 0)))


# ----------------------------------------------------------------------------- deviation


def _reference_profile(
    model: mujoco.MjModel,
    actual: np.ndarray,
    plans: list[PilotPlan],
    points: tuple[np.ndarray, np.ndarray, np.ndarray],
    safety: float,
) -> np.ndarray:
    """The profile the slow, obvious way: every plan, knot, body and point one at a time."""
    geom, body, offset = points
    scratch = mujoco.MjData(model)

    def point(q: np.ndarray, i: int) -> np.ndarray:
        scratch.qpos[:] = q
        mujoco.mj_kinematics(model, scratch)
        g = int(geom[i])
        return scratch.geom_xpos[g] + scratch.geom_xmat[g].reshape(3, 3) @ offset[i]

    worst: dict[tuple[int, int], float] = {}
    for plan in plans:
        for j in range(plan.qpos.shape[0]):
            if plan.start + j >= actual.shape[0]:
                break
            age = max(j - plan.origin, 0)
            for i in range(geom.size):
                gap = float(
                    np.linalg.norm(point(actual[plan.start + j], i) - point(plan.qpos[j], i))
                )
                key = (age, int(body[i]))
                worst[key] = max(worst.get(key, 0.0), gap)
    length = max(a for a, _ in worst) + 1
    out = np.zeros((length, model.nbody))
    for (a, b), gap in worst.items():
        out[a, b] = gap
    for a in range(1, length):
        out[a] = np.maximum(out[a], out[a - 1])
    return safety * out


def _pilot(model: mujoco.MjModel) -> tuple[np.ndarray, list[PilotPlan]]:
    """A pilot: the smooth drive, a plan of the drive holding its control every 13 steps,
    waypoints as origins."""
    d = _settled(model, steps=1)
    drive = make_controller(model, "smooth", seed=3, hold_steps=40)
    rows, plans = [d.qpos.copy()], []
    for k in range(1, 160):
        if k % 13 == 0:
            held = np.array(d.ctrl)
            plan = plan_from_controls(model, d, np.tile(held, (30, 1)))
            plans.append(PilotPlan(k - 1, plan, origin=k % 5))
        drive(model, d)
        mujoco.mj_step(model, d)
        rows.append(d.qpos.copy())
    return np.array(rows), plans


def test_deviation_profile_matches_the_slow_reference(model: mujoco.MjModel) -> None:
    actual, plans = _pilot(model)
    points = Predictor(model, accel=1.0).bound_points
    got = deviation_profile(model, actual, plans, points=points, safety=1.5)
    want = _reference_profile(model, actual, plans, points, 1.5)
    assert got.shape == want.shape == (31, model.nbody)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)
    assert np.all(np.diff(got, axis=0) >= 0.0)
    assert got[:, 0].max() == 0.0  # the world never strays
    assert got[-1, model.body("fore").id] > 0.0  # the drive left the held control
    # Plain tuples are plans too; a plan running past the pilot's end is measured where it can.
    tail = [(actual.shape[0] - 5, plans[0].qpos, 0)]
    short = deviation_profile(model, actual, tail, points=points)
    assert short.shape == (5, model.nbody)


def test_deviation_of_an_exact_plan_is_zero(model: mujoco.MjModel) -> None:
    d = _settled(model)
    u = np.random.default_rng(2).uniform(-1.0, 1.0, size=(50, model.nu))
    plan = plan_from_controls(model, d, u)
    points = Predictor(model, accel=1.0).bound_points
    prof = deviation_profile(model, _simulate(model, d, u), [PilotPlan(0, plan)], points=points)
    assert prof.shape == (51, model.nbody) and prof.max() == 0.0


def test_plan_deviation_reads_the_profile_past_the_origin() -> None:
    prof = np.arange(12.0).reshape(6, 2)
    dev = plan_deviation(prof, 8, origin=3)
    assert dev.shape == (8, 2)
    assert np.array_equal(dev[:4], np.tile(prof[0], (4, 1)))
    assert np.array_equal(dev[4:], prof[1:5])
    with pytest.raises(InvalidInputError, match=r"reaches 6 knots past its origin.*only 5"):
        plan_deviation(prof, 8, origin=1)
    with pytest.raises(InvalidInputError, match="origin = 9 is out of range"):
        plan_deviation(prof, 8, origin=9)
    with pytest.raises(InvalidInputError, match="knots = 0"):
        plan_deviation(prof, 0)
    with pytest.raises(ShapeError, match=r"profile has shape \(6,\)"):
        plan_deviation(np.zeros(6), 3)
    # A plain int's fast path and the general checks agree; the rows are a copy, never the
    # profile's own memory.
    rows = plan_deviation(prof, 4)
    assert np.array_equal(rows, prof[:4]) and not np.shares_memory(rows, prof)
    assert np.array_equal(plan_deviation(prof, np.int64(4), origin=np.int64(0)), rows)
    assert np.array_equal(plan_deviation(prof.tolist(), 4), rows)
    for bad in (True, 4.0, -1):
        with pytest.raises(InvalidInputError, match=f"knots = {bad}"):
            plan_deviation(prof, bad)  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match="origin = False"):
        plan_deviation(prof, 4, origin=False)


def test_deviation_profile_names_bad_input(model: mujoco.MjModel) -> None:
    actual, plans = _pilot(model)
    points = Predictor(model, accel=1.0).bound_points
    with pytest.raises(ShapeError, match=r"qpos has shape \(160, 2\)"):
        deviation_profile(model, actual[:, :2], plans, points=points)
    broken = actual.copy()
    broken[7, 1] = np.inf
    with pytest.raises(InvalidInputError, match=r"qpos\[7, 1\] = inf is not finite"):
        deviation_profile(model, broken, plans, points=points)
    with pytest.raises(InvalidInputError, match=r"plans\[0\].start = 160 is out of range"):
        deviation_profile(model, actual, [(160, plans[0].qpos)], points=points)
    with pytest.raises(InvalidInputError, match=r"plans\[1\].origin = -1 is out of range"):
        deviation_profile(model, actual, [plans[0], (0, plans[0].qpos, -1)], points=points)
    with pytest.raises(ShapeError, match=r"plans\[0\].qpos has shape \(31, 1\)"):
        deviation_profile(model, actual, [(0, plans[0].qpos[:, :1])], points=points)
    with pytest.raises(InvalidInputError, match="plans is empty"):
        deviation_profile(model, actual, [], points=points)
    with pytest.raises(InvalidInputError, match=r"safety = 0\.5 is invalid"):
        deviation_profile(model, actual, plans, points=points, safety=0.5)
    with pytest.raises(InvalidInputError, match=r"Predictor\.bound_points"):
        deviation_profile(model, actual, plans, points=None)  # type: ignore[arg-type]
    g, b, o = points
    with pytest.raises(ShapeError, match=r"offset \(\d+, 2\)"):
        deviation_profile(model, actual, plans, points=(g, b, o[:, :2]))
    with pytest.raises(InvalidInputError, match="not their geoms' bodies"):
        deviation_profile(model, actual, plans, points=(g, (b + 1) % model.nbody, o))


def test_plans_are_exported_lazily() -> None:
    assert dua_mujoco.plan_from_controls is plan_from_controls
    assert dua_mujoco.deviation_profile is deviation_profile
    assert dua_mujoco.plan_deviation is plan_deviation
    assert dua_mujoco.PilotPlan is PilotPlan


# ----------------------------------------------------------------------------- with the predictor


@pytest.mark.parametrize("dressed", [False, True])
def test_a_rolled_plan_is_followed_without_a_break(model: mujoco.MjModel, dressed: bool) -> None:
    # The runtime puts the plan's geoms where mj_kinematics puts them for each row of qpos: for a
    # plan rolled under the controls the run then applies, that is where mj_step puts them, so a
    # deviation of 0 holds at every knot, also where the plan's kinematics leaves out the geoms
    # and sites no verdict reads (dressed: a pose off by a bit breaks the plan). A run that
    # leaves the plan breaks it.
    if dressed:
        model = mujoco.MjModel.from_xml_string(_VISUAL)
        assert model.nsite == 3 and int(np.count_nonzero(model.geom_contype == 0)) == 7
    d = _settled(model, steps=3)
    drive = make_controller(model, "smooth", seed=4, hold_steps=40)
    p = Predictor(model, accel=20.0, alarm_horizon=0.05)
    p.reset(d)
    for k in range(1, 201):
        drive(model, d)
        mujoco.mj_step(model, d)
        p.step(d)
        if k % 10 == 0:
            p.set_plan(plan_from_controls(model, d, copy.deepcopy(drive), steps=40), deviation=0.0)
    assert p.has_plan and p.plan_breaks == 0
    d.ctrl[:] = 0.0  # not the plan's controls
    for _ in range(30):
        mujoco.mj_step(model, d)
        p.step(d)
    assert p.plan_breaks > 0


SLIDER = """
<mujoco>
  <option timestep="0.002" gravity="0 0 0"/>
  <worldbody>
    <geom name="wall" type="box" size=".05 .5 .3" pos=".8 0 .3"/>
    <body name="ball" pos="0 0 .3">
      <joint name="x" type="slide" axis="1 0 0"/><geom name="ball" size=".05"/>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.mark.parametrize(("horizon", "first", "last"), [(0.05, 38, 90), (0.2, 168, 178)])
def test_an_exact_plans_alarm_stands_the_whole_horizon_wherever_the_touch_falls(
    horizon: float, first: int, last: int
) -> None:
    """A ball slides at a constant speed into a wall under a plan that is the run: wherever the
    touch falls on the step grid (from ``first`` to ``last`` steps after the plan), the pair
    stands in alarm the whole horizon before it. (A plan's taus are whole steps; before they
    were shaved, the deadline scheduler's rounded test let a pair wait one step too long at
    some touch steps: 43 and 84-87 at 50 ms, 172-175 at 200 ms.)"""
    m = mujoco.MjModel.from_xml_string(SLIDER)
    h = float(m.opt.timestep)
    n = round(horizon / h)
    leads = []
    # 1 m/s: 2 mm a step; start positions 1 mm apart put the touch at every step of the range.
    for x0 in np.arange(0.7 - last * h, 0.7 - first * h, 0.001):
        d = mujoco.MjData(m)
        d.qpos[0], d.qvel[0] = x0, 1.0
        mujoco.mj_forward(m, d)
        p = Predictor(m, accel=10.0, alarm_horizon=horizon)
        p.reset(d)
        p.set_plan(plan_from_controls(m, d, lambda *_: None, steps=last + n), deviation=0.0)
        since = None
        for k in range(last + 4):
            mujoco.mj_step(m, d)
            p.step(d)
            state = p.pair_state()
            standing = bool((state.alarm_state() & state.active).any())
            since = (since if since is not None else k) if standing else None
            if d.ncon:
                leads.append((k - since) * h if since is not None else -1.0)
                break
        assert p.plan_breaks == 0
    assert len(leads) >= last - first  # every touch step of the range, with teeth
    assert min(leads) >= horizon - 1e-9


def test_a_planned_pairs_state_is_checked_though_the_plan_judges_it(model: mujoco.MjModel) -> None:
    # The plan's verdict replaces the bounds' tau of a pair both of whose bodies it plans, so
    # that tau is not computed (PlanCovered); the pair's state is still read and checked: a
    # state that is not finite is named as without a plan (every pair of the forearm is
    # planned here, and all are due at the step after set_plan).
    d = _settled(model, steps=3)
    p = Predictor(model, accel=20.0, alarm_horizon=0.05)
    p.reset(d)
    for _ in range(5):
        mujoco.mj_step(model, d)
        p.step(d)
    p.set_plan(plan_from_controls(model, d, lambda *_: None, steps=40), deviation=0.0)
    mujoco.mj_step(model, d)
    d.cvel[model.body("fore").id] = np.nan
    with pytest.raises(NonFiniteStateError, match=r"geom\(s\) 'geom3', 'geom5' is not finite"):
        p.step(d)
