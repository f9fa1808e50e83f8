"""Partial flight plans (docs/theory.md, Lemma 8.3; docs/plans.md): a planned arm next to a
"person", a mocap body the plan does not hold, with a declared speed and acceleration.

* The mixed tau is sound: motions of the person sampled within its bounds (pieces of constant
  acceleration, the speed capped, some aimed at the arm) never bring it within the contact
  distance of the arm's planned geom before tau.
* It is as tight as the reach allows: never above a slow reference (MuJoCo's distance between the
  arm at each knot and the person where it is, less the arm's deviation and the person's reach,
  or where its velocity carries it, less how far it may stray from there), and equal to it for
  most states; a person walking past is judged later than by the reach about where it stands.
* A run: the person walks in and reaches, within its bounds; no onset gets less lead than the
  horizon, far fewer pairs stand than under the motion bounds alone.
* The shield's query (``plan_contact_knots``) gives the knot of the step's own verdict.
"""

from __future__ import annotations

import math
from fractions import Fraction as Q

import mujoco
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mjcf import Capsule, arm, motors

from dua_mujoco import UrgencyOptions, _core
from dua_mujoco._core import LAYOUT
from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.measure.monitor import Monitor
from dua_mujoco.runtime.predictor import Predictor

# An arm of two capsules on hinges about z (the fore at the upper's tip), a person beside it.
UPPER, FORE = Capsule("upper", "swing", ".4", ".04"), Capsule("fore", "elbow", ".3", ".03")
SCENE = f"""<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="3 3 .1"/>
    {arm("0 0 .8", UPPER, FORE, axis="0 0 1", damping=(".5", ".2"))}
    <body name="person" mocap="true" pos="1.6 0 .9">
      <geom name="torso" type="capsule" fromto="0 0 -.5 0 0 .3" size=".15"/>
      <geom name="hand" type="capsule" fromto="0 0 .1 -.35 0 -.05" size=".05"/>
    </body>
  </worldbody>
  {motors("swing", "elbow", gear=("4", "2"), ctrlrange="-1 1")}
</mujoco>"""

# The person's declared bounds (ISO 13855's walking speed), the arm's.
SPEED, ACCEL, ARM_ACCEL = 1.6, 4.0, 30.0
BOUNDS = {"accel": {"*": ARM_ACCEL, "person": ACCEL}, "speed": {"*": math.inf, "person": SPEED}}
ARM = ["upper", "fore"]


def _model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(SCENE)


def _blind(m: mujoco.MjModel) -> mujoco.MjModel:
    """The arm's planner: the same model without the person's collisions (it plans the arm, not
    the person, who stands wherever it stood when the plan was made)."""
    blind = mujoco.MjModel.from_xml_string(SCENE)
    person = np.asarray(blind.geom_bodyid) == m.body("person").id
    blind.geom_contype[person] = 0
    blind.geom_conaffinity[person] = 0
    return blind


def _controls(m: mujoco.MjModel, steps: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    knots = rng.uniform(-1, 1, (steps // 150 + 2, m.nu))
    t = np.arange(steps) / 150.0
    return np.stack([np.interp(t, np.arange(len(knots)), knots[:, i]) for i in range(m.nu)], 1)


def _rollout(blind: mujoco.MjModel, m, d, ctrl: np.ndarray, n: int) -> np.ndarray:
    c = mujoco.MjData(blind)
    mujoco.mj_copyData(c, m, d)
    out = [c.qpos.copy()]
    for j in range(n - 1):
        c.ctrl[:] = ctrl[j]
        mujoco.mj_step(blind, c)
        out.append(c.qpos.copy())
    return np.array(out)


# ------------------------------------------------------------------------------------------------
# one verdict: the mixed tau at the state the first step reads
# ------------------------------------------------------------------------------------------------


class MixedState:
    """The arm planned from a state (deviation ``dev``), the person at ``pos`` moving at ``vel``
    (given to the predictor); ``tau`` per person geom: the mixed verdict of its pair with the
    arm's forearm at the first step."""

    N = 120  # knots

    def __init__(self, p: Predictor, arm_q, ctrl, pos, vel, dev: float) -> None:
        m = p.model
        self.m, self.dev = m, dev
        d = mujoco.MjData(m)
        d.qpos[:] = arm_q
        d.mocap_pos[0] = pos
        mujoco.mj_forward(m, d)
        p.reset(d)
        p.mocap.set_velocity("person", vel)  # type: ignore[union-attr]
        self.plan = _rollout(_blind(m), m, d, ctrl, self.N)
        p.set_plan(self.plan, deviation=dev, bodies=ARM)
        mujoco.mj_step(m, d)  # the step reads the state at time 0: the plan's knot 0
        p.step(d)
        self.pos, self.vel = np.asarray(pos, float), np.asarray(vel, float)
        self.fore = m.geom("fore").id
        state = p.pair_state()
        self.tau = {}
        self.contact = {}
        for name in ("torso", "hand"):
            g = m.geom(name).id
            ids = np.flatnonzero(
                ((p.tables.geom1 == g) & (p.tables.geom2 == self.fore))
                | ((p.tables.geom2 == g) & (p.tables.geom1 == self.fore))
            )
            self.tau[g] = float(state.last_tau_of(ids).min())
            gp = p.geom_pairs
            k = np.flatnonzero((gp.geom1 == min(g, self.fore)) & (gp.geom2 == max(g, self.fore)))
            self.contact[g] = float(gp.contact_distance[k[0]])
        self.scratch = mujoco.MjData(m)
        disc = p.bounds.discrepancy[m.body("person").id]
        self.reach = lambda t: min(
            (np.linalg.norm(self.vel) + disc) * t + ACCEL * t * t / 2, SPEED * t
        )
        # How far the person may stray from where its velocity carries it (it only translates).
        self.stray = lambda t: disc * t + ACCEL * t * t / 2

    def distance(self, j: int, g: int, person_pos) -> float:
        """MuJoCo's distance of the forearm at knot j and geom g with the person at person_pos."""
        self.scratch.qpos[:] = self.plan[j]
        self.scratch.mocap_pos[0] = person_pos
        mujoco.mj_kinematics(self.m, self.scratch)
        return float(mujoco.mj_geomDistance(self.m, self.scratch, self.fore, g, 10.0, None))

    def reference_knot(self, g: int, *, carried: bool = True) -> int:
        """The first knot at which MuJoCo's distance of the planned forearm and the person where it
        is, less the contact distance, is not above the forearm's deviation and the person's
        reach (its own bounds) from the state read, nor (``carried``) its distance to the person
        where its velocity carries it above the deviation and how far it may stray from there:
        the slow reference of the mixed tau."""
        h = float(self.m.opt.timestep)
        for j in range(self.N):
            t = j * h
            if self.distance(j, g, self.pos) - self.contact[g] > self.dev + self.reach(t):
                continue
            ahead = self.pos + t * self.vel
            if carried and (
                self.distance(j, g, ahead) - self.contact[g] > self.dev + self.stray(t)
            ):
                continue
            return j
        return self.N


def person_motion(state: MixedState, g: int, prog, knots: int) -> np.ndarray:
    """Positions of the person at knots 0..knots-1 from a motion within its bounds: semi-implicit
    Euler of piecewise-constant accelerations |a| <= ACCEL, the velocity kept within SPEED (a
    projection: still |dv| <= ACCEL h), from the velocity it was read with; "aimed" pieces
    accelerate at full bound from geom g towards the forearm's planned centre."""
    h = float(state.m.opt.timestep)
    x, v = state.pos.copy(), state.vel.copy()
    state.scratch.mocap_pos[0] = x
    mujoco.mj_kinematics(state.m, state.scratch)
    offset = state.scratch.geom_xpos[g] - x  # the person only translates
    total = sum(f for f, _, _ in prog)
    ends = np.cumsum([f / total for f, _, _ in prog]) * knots
    out = [x.copy()]
    for j in range(1, knots):
        _, direction, aimed = prog[min(int(np.searchsorted(ends, j, side="right")), len(prog) - 1)]
        if aimed:
            state.scratch.qpos[:] = state.plan[j]
            mujoco.mj_kinematics(state.m, state.scratch)
            u = state.scratch.geom_xpos[state.fore] - (x + offset)
            a = ACCEL * u / max(float(np.linalg.norm(u)), 1e-12)
        else:
            a = ACCEL * np.asarray(direction)
        v = v + a * h
        speed = float(np.linalg.norm(v))
        if speed > SPEED:
            v *= SPEED / speed
        x = x + h * v
        out.append(x.copy())
    return np.array(out)


@st.composite
def states(draw):
    """The arm somewhere, the person 0-0.45 m beyond its reach, mostly walking towards it."""
    bearing = draw(st.floats(-0.8, 0.8))
    arm_q = np.array([bearing + draw(st.floats(-0.6, 0.6)), draw(st.floats(-1.5, 1.5))])
    r = 0.75 + 0.15 + draw(st.floats(0.0, 0.45))
    pos = np.array([r * math.cos(bearing), r * math.sin(bearing), 0.9])
    heading = bearing + math.pi + draw(st.sampled_from([0.0, 0.0, 1.0])) * draw(st.floats(-3, 3))
    speed = draw(st.floats(0.0, SPEED))
    vel = speed * np.array([math.cos(heading), math.sin(heading), 0.0])
    dev = draw(st.sampled_from([0.0, 0.01]))
    seed = draw(st.integers(0, 2**16))
    return arm_q, pos, vel, dev, seed


@st.composite
def _piece(draw):
    d = np.array([draw(st.floats(-1, 1)) for _ in range(3)])
    d = d / np.linalg.norm(d) if np.linalg.norm(d) > 1e-6 else np.array([-1.0, 0, 0])
    aimed = draw(st.sampled_from([True, True, True, False]))
    return draw(st.floats(0.1, 1.0)), d * draw(st.floats(0, 1)), aimed


def programs():
    return st.lists(_piece(), min_size=1, max_size=3)


@pytest.fixture(scope="module")
def predictor() -> Predictor:
    return Predictor(_model(), **BOUNDS, alarm_horizon=0.2)  # type: ignore[arg-type]


SETTINGS = settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True
)


@SETTINGS
@given(states(), programs())
def test_no_motion_within_the_persons_bounds_touches_the_planned_arm_before_tau(
    predictor: Predictor, s, prog
) -> None:
    arm_q, pos, vel, dev, seed = s
    ctrl = _controls(predictor.model, MixedState.N + 10, seed)
    state = MixedState(predictor, arm_q, ctrl, pos, vel, dev)
    h = float(state.m.opt.timestep)
    for g, tau in state.tau.items():
        before = min(math.ceil(tau / h - 1e-6), MixedState.N)  # knots strictly before tau
        path = person_motion(state, g, prog, before)
        for j in range(before):
            gap = state.distance(j, g, path[j]) - state.contact[g]
            assert gap > -1e-9, (g, j, tau, gap)


@SETTINGS
@given(states())
def test_the_mixed_tau_is_never_above_the_slow_reference(predictor: Predictor, s) -> None:
    arm_q, pos, vel, dev, seed = s
    ctrl = _controls(predictor.model, MixedState.N + 10, seed)
    state = MixedState(predictor, arm_q, ctrl, pos, vel, dev)
    h = float(state.m.opt.timestep)
    for g, tau in state.tau.items():
        knot = state.reference_knot(g)
        assert tau <= knot * h * (1 + 1e-12), (g, tau, knot)


def test_the_mixed_tau_equals_the_reference_for_most_states(predictor: Predictor) -> None:
    """Tight as the person's reach allows: the knot the runtime finds is the reference's in most
    states (the separating direction at a knot is MuJoCo's witness there), standing or walking
    in, and the verdict depends on the person's velocity (one walking in at 1.5 m/s is judged
    earlier in most states: not in all, it may walk past the forearm's planned sweep)."""
    rng = np.random.default_rng(0)
    m = predictor.model
    equal = fast_equal = total = faster_earlier = 0
    for _ in range(30):
        arm_q = rng.uniform([-1, -1.5], [1, 1.5])
        pos = np.array([rng.uniform(0.7, 1.3), rng.uniform(-0.6, 0.6), 0.9])
        ctrl = _controls(m, MixedState.N + 10, int(rng.integers(1 << 16)))
        slow = MixedState(predictor, arm_q, ctrl, pos, np.zeros(3), 0.0)
        fast = MixedState(predictor, arm_q, ctrl, pos, np.array([-1.5, 0.0, 0.0]), 0.0)
        h = float(m.opt.timestep)
        for g, tau in slow.tau.items():
            knot = slow.reference_knot(g)
            total += 1
            equal += round(tau / h) == knot
            fast_equal += round(fast.tau[g] / h) == fast.reference_knot(g)
            faster_earlier += fast.tau[g] <= tau
    assert equal >= 0.8 * total and fast_equal >= 0.8 * total, (equal, fast_equal, total)
    assert faster_earlier >= 0.9 * total, (faster_earlier, total)


def test_a_person_walking_past_is_judged_where_it_walks(predictor: Predictor) -> None:
    """The reach about where the person heads: one walking past the arm at full speed is judged
    later than by the reach about where it stands alone (a ball of V t) in most states, and as
    the slow reference with both says."""
    rng = np.random.default_rng(1)
    m = predictor.model
    h = float(m.opt.timestep)
    later = equal = total = 0
    for _ in range(16):
        bearing = rng.uniform(-0.6, 0.6)
        arm_q = np.array([bearing + rng.uniform(-0.3, 0.3), rng.uniform(-1.0, 1.0)])
        r = rng.uniform(0.95, 1.3)
        pos = np.array([r * math.cos(bearing), r * math.sin(bearing), 0.9])
        across = bearing + math.pi / 2 * rng.choice([-1.0, 1.0]) + rng.uniform(-0.3, 0.3)
        vel = SPEED * np.array([math.cos(across), math.sin(across), 0.0])
        ctrl = _controls(m, MixedState.N + 10, int(rng.integers(1 << 16)))
        past = MixedState(predictor, arm_q, ctrl, pos, vel, 0.0)
        for g, tau in past.tau.items():
            total += 1
            later += round(tau / h) > past.reference_knot(g, carried=False)
            equal += round(tau / h) == past.reference_knot(g)
    assert later >= total // 2 and equal >= 0.8 * total, (later, equal, total)


# ------------------------------------------------------------------------------------------------
# a run: the person walks in and reaches
# ------------------------------------------------------------------------------------------------


def _person_x(t: float) -> float:
    """In and out twice a run: speed at most 1.08 m/s, acceleration 2.6 m/s^2 (declared 1.6, 4)."""
    d, w = 0.9, 2.4
    return 1.6 - d * (1 - math.cos(w * t)) / 2


def _run(planned: bool, horizon: float = 0.2, steps: int = 2700, every: int = 25) -> Monitor:
    m = _model()
    blind = _blind(m)
    d = mujoco.MjData(m)
    ctrl = _controls(m, steps + 300, seed=5)
    p = Predictor(m, **BOUNDS, alarm_horizon=horizon)  # type: ignore[arg-type]
    monitor = Monitor(p)
    n = round(horizon / m.opt.timestep) + 2 * every
    d.mocap_pos[0, 0] = _person_x(0.0)
    mujoco.mj_forward(m, d)
    mujoco.mj_step(m, d)
    monitor.start(d)
    for k in range(steps):
        if planned and k % every == 0:
            p.set_plan(_rollout(blind, m, d, ctrl[k:], n), deviation=0.0, bodies=ARM)
        d.ctrl[:] = ctrl[k]
        d.mocap_pos[0, 0] = _person_x((k + 1) * m.opt.timestep)
        mujoco.mj_step(m, d)
        monitor.observe(d, p.step(d))
    monitor.finish()
    return monitor


def test_a_planned_arm_and_a_person_on_its_bounds_flag_every_contact_the_horizon_ahead() -> None:
    planned, bounds = _run(True), _run(False)
    assert planned.onsets >= 2 and planned.misses == []
    w = planned.warning
    assert w.short_held == 0 and w.short_after_violation == 0, w.leads
    # The person's bounds held all along (no violation of theirs excuses anything).
    person = planned.model.body("person").id
    assert planned.last_violation[person] == -1
    assert planned.standing_alarm_fraction < 0.5 * bounds.standing_alarm_fraction


# ------------------------------------------------------------------------------------------------
# the bodies a plan holds, and the shield's query
# ------------------------------------------------------------------------------------------------


def test_the_bodies_a_plan_holds_are_named_and_checked(predictor: Predictor) -> None:
    m = predictor.model
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    predictor.reset(d)
    q = np.tile(d.qpos, (20, 1))
    predictor.set_plan(q, deviation=0.0)  # mocap bodies left to their bounds by default
    with pytest.raises(InvalidInputError, match="'person' is in a mocap tree"):
        predictor.set_plan(q, deviation=0.0, bodies=["upper", "person"])
    with pytest.raises(InvalidInputError, match="'arm_\\*' names no body"):
        predictor.set_plan(q, deviation=0.0, bodies="arm_*")
    pos = np.tile(d.mocap_pos, (20, 1, 1))
    quat = np.tile(d.mocap_quat, (20, 1, 1))
    predictor.set_plan(q, deviation=0.0, bodies="*", mocap_pos=pos, mocap_quat=quat)
    assert predictor._rt.plan_ok[m.body("person").id]
    with pytest.raises(InvalidInputError, match="go together"):
        predictor.set_plan(q, deviation=0.0, mocap_pos=pos)


def test_the_shields_query_gives_the_knot_of_the_steps_own_verdict(predictor: Predictor) -> None:
    """plan_contact_knots on a candidate plan (not followed) gives, per geom pair, the knot the
    step's verdict would have under it: the same code. Pairs it plans neither body of: -1; pairs
    MuJoCo's filter rejects: -2."""
    m = predictor.model
    rng = np.random.default_rng(2)
    checked = 0
    for _ in range(10):
        arm_q = rng.uniform([-1, -1.5], [1, 1.5])
        pos = np.array([rng.uniform(0.7, 1.3), rng.uniform(-0.6, 0.6), 0.9])
        ctrl = _controls(m, MixedState.N + 10, int(rng.integers(1 << 16)))
        # The step's verdicts under the plan; then the query, from the same state (time 0).
        state = MixedState(predictor, arm_q, ctrl, pos, np.array([-1.0, 0.0, 0.0]), 0.0)
        pairs = [(m.geom("fore").id, m.geom(g).id) for g in ("torso", "hand", "floor")]
        pairs.append((m.geom("torso").id, m.geom("floor").id))
        knots = predictor.plan_contact_knots(
            state.plan, pairs, deviation=0.0, start=0.0, bodies=ARM
        )
        h = float(m.opt.timestep)
        for (a, b), knot in zip(pairs[:2], knots[:2], strict=True):
            assert knot == round(state.tau[b] / h), (a, b)
            checked += 1
        assert knots[3] == -2  # MuJoCo never collides a mocap body with the world
        upper = predictor.plan_contact_knots(
            state.plan, pairs, deviation=0.0, start=0.0, bodies="upper"
        )
        assert upper[0] == upper[1] == -1  # neither the forearm nor the person is planned
    assert checked == 20


def test_a_plan_keeps_the_replaced_plans_poses_only_where_its_rows_are_the_same() -> None:
    """A plan copies the poses of the plan it replaces at the knots where both have the same
    rows at the same time (Plan::Build: the same joint positions and mocap poses, bit for bit),
    and computes the others: its verdicts are those of a predictor that had no plan before. The
    plan followed keeps the person away; two candidates plan the person walking into the arm,
    one with the plan's own arm (the same joint positions at every knot: a copy that ignored the
    mocap poses would keep the person away), one whose arm leaves the plan's after 30 knots (a
    copy past them would keep the plan's arm)."""
    m = _model()
    blind = _blind(m)
    h = float(m.opt.timestep)
    d = mujoco.MjData(m)
    d.mocap_pos[0, 0] = 1.6
    mujoco.mj_forward(m, d)
    mujoco.mj_step(m, d)
    bounds: dict = BOUNDS
    followed, fresh = Predictor(m, **bounds, alarm_horizon=0.2), Predictor(m, **bounds)
    for p in (followed, fresh):
        p.reset(d)
    n, skip = 160, 10
    ctrl = _controls(m, n + 40, seed=8)
    q = _rollout(blind, m, d, ctrl, n)
    quat = np.tile(d.mocap_quat, (n, 1, 1))
    away = np.tile(d.mocap_pos, (n, 1, 1))
    followed.set_plan(q, deviation=0.0, mocap_pos=away, mocap_quat=quat)
    for k in range(skip):  # the plan followed: the state read moves along its knots
        d.ctrl[:] = ctrl[k]
        mujoco.mj_step(m, d)
        followed.step(d)
        fresh.step(d)
    kept = q[skip - 1 :]
    elsewhere = np.concatenate(
        [kept[:30], _rollout(blind, m, d, -ctrl[skip + 30 :], len(kept) - 30)]
    )
    walking = away[skip - 1 :].copy()
    walking[:, 0, 0] = np.linspace(1.6, 0.2, len(kept))  # the person walks into the arm
    pairs = np.stack([followed.geom_pairs.geom1, followed.geom_pairs.geom2], axis=1)
    args = {"deviation": 0.0, "start": float(d.time) - h, "mocap_quat": quat[: len(kept)]}
    got, want = {}, {}
    for name, rows, pos in (
        ("plan's arm", kept, walking),
        ("arm elsewhere", elsewhere, walking),
        ("plan", kept, away[skip - 1 :]),
    ):
        got[name] = followed.plan_contact_knots(rows, pairs, mocap_pos=pos, **args)
        want[name] = fresh.plan_contact_knots(rows, pairs, mocap_pos=pos, **args)
        assert np.array_equal(got[name], want[name]), name
    # The copies could be wrong: the person's and the arm's motions change the verdicts.
    assert not np.array_equal(got["plan's arm"], got["plan"])
    assert not np.array_equal(got["plan's arm"], got["arm elsewhere"])


# Two spheres on slides about x = 1024 m, where a double's spacing (2.3e-13 m) is far above the
# gap's own rounding allowance (1e-14 of it): the planned one stands still, the free one (no
# acceleration, no discrepancy: its motion is its velocity read) slides at it along x, a tiny
# offset in y making the rounded gaps take every value rather than a grid.
FAR = """<mujoco>
  <option timestep="0.002" gravity="0 0 0"/>
  <worldbody>
    <body name="a" pos="1024 0 0"><joint type="slide" axis="1 0 0"/>
      <geom type="sphere" size=".05"/></body>
    <body name="b" pos="1024.5 .06 0"><joint type="slide" axis="1 0 0"/>
      <joint type="slide" axis="0 1 0"/><geom type="sphere" size=".05"/></body>
  </worldbody>
</mujoco>"""


def test_the_carried_place_keeps_room_for_its_own_rounding() -> None:
    """The mixed tau's carried test (where the free sphere's velocity read takes it, y + t w)
    is never later than the first knot at which, in exact arithmetic, that place touches the
    planned sphere: far from the origin the sum y + t w rounds by up to half a spacing of y,
    which Stray's room (4 eps (|y|_1 + t |w|_1)) covers; without it, some of these states
    (gaps at knot 20 within a spacing of 0) are cleared a knot late."""
    m = mujoco.MjModel.from_xml_string(FAR)
    d, at = mujoco.MjData(m), mujoco.MjData(m)
    p = Predictor(m, accel={"a": 1.0, "b": 0.0}, urgency=UrgencyOptions(exact=False))
    eps = Q(float(p.table_arrays["pairs"].reshape(-1, LAYOUT["PAIR_NCOL"])[0, LAYOUT["PAIR_EPS"]]))
    h, rng, late = m.opt.timestep, np.random.default_rng(5), []
    for _ in range(300):
        w = -0.5 - rng.uniform(0.0, 0.5)  # at knot 20 the gap is within 3e-13 m of 0
        d.qpos[:] = [0.0, 0.08 - 20 * w * h - 0.5 + rng.uniform(-3e-13, 0), rng.uniform(0, 5e-13)]
        d.qvel[:], d.time = [0.0, w, 0.0], 1.0
        mujoco.mj_forward(m, d)
        p.reset(d)
        plan = np.tile(d.qpos, (40, 1))
        knot = p.plan_contact_knots(plan, [[0, 1]], deviation=0.0, bodies=["a"], start=1.0 - h)
        centre, velocity = p.sphere_states(d)
        at.qpos[:] = plan[0]
        mujoco.mj_kinematics(m, at)
        dy, vx = Q(centre[1, 1] - at.geom_xpos[0, 1]), Q(velocity[1, 0])
        dx = [Q(centre[1, 0]) - Q(at.geom_xpos[0, 0]) + vx * j * Q(h) for j in range(40)]
        first = next(j for j in range(40) if dx[j] ** 2 + dy**2 <= eps**2)
        if int(knot[0]) > first:
            late.append((int(knot[0]), first))
    assert not late, late


def _zero_or(top: float) -> st.SearchStrategy[float]:
    """0, or a value from 1e-6 to ``top`` (seconds, m/s, m/s^2: far from the products'
    underflow, which no relative allowance covers)."""
    return st.one_of(st.just(0.0), st.floats(1e-6, top))


@given(t=_zero_or(2.0), accel=_zero_or(100.0), disc=_zero_or(10.0), spin=_zero_or(10.0))
@settings(max_examples=300, deadline=None)
def test_the_stray_is_rounded_up(t: float, accel: float, disc: float, spin: float) -> None:
    """The mixed tau's stray, how far a free point may leave the place its velocity read
    carries it to in t ((spin + disc) t + A t^2 / 2, discrete-time.md section 2), is computed
    in floating point: its roundings (the products and sums, each within half an ulp) are
    covered by Stray's factor (1 + 8 eps), so that it is never below the exact value, held here
    in rational arithmetic with no carried place to round (its room is the test above's). It is
    at most a few ulps above. Without the factor, about half of these draws come out a little
    short. (Through the mixed tau the gaps' own allowance, 1e-14 of the distance, would hide so
    small a shortfall today; the proof of Lemma 8.3 rests on each term being an upper bound.)"""
    got = Q(_core.mixed_stray(t, accel, disc, spin, 0.0, 0.0))
    exact = (Q(spin) + Q(disc)) * Q(t) + Q(accel) * Q(t) * Q(t) / 2
    assert got >= exact, (float(got - exact), float(exact))
    assert got <= exact * (1 + Q(2) ** -48) + Q(2) ** -1074, (float(got - exact), float(exact))
