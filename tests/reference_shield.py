"""The safety shield's check, slowly and plainly: the oracle the native verification is held to.

Written apart from the runtime on purpose (MuJoCo and numpy only, Python loops, MuJoCo's own
``mj_geomDistance`` at every step of the rollout), so that a test holding the runtime to it can
fail.

**The check** (:func:`verify`). From the state in ``data``, roll the robot out on a copy: the
intended controls for one control period, then the failsafe until every robot body is at rest
(every point at most ``rest_speed``). The protected bodies' geoms do not collide in the rollout
(:func:`rollout_model`): the robot's future must not lean on where a body nobody plans is assumed
to stay. Knot ``j`` is the state ``j`` physics steps after the one read. The check fails when,
at some knot ``j`` before the robot is at rest, a protected pair (robot geom ``A``, other geom
``B``) may be in contact:

    mj_geomDistance(A at its knot-j pose, B at its pose at the state read) - contact distance
        <= reach_B(j h) + deviation + slack,

with ``reach_B(t) = min(V t, (|v| + |w| r_B + delta) t + a t^2 / 2)``: ``V``, ``a`` the declared
speed and acceleration bounds of every point of ``B``'s body, ``v`` and ``w`` that body's linear
(at its frame origin) and angular velocity at the state read, ``r_B`` the largest distance from
the body's frame origin to a point of ``B``, ``delta`` the velocity uncertainty of the step
(``a h / 2`` by default: docs/discrete-time.md; a backward difference of a mocap body's pose
is within ``a h / 2`` of its velocity), ``deviation`` how far the robot may stray from its
rollout, ``slack`` 10 um for MuJoCo's distance (GJK converges from above). Static geoms have no
reach. A rollout that does not come to rest within ``max_steps`` fails too.

**The loop** (:class:`ReferenceShield`): at each control period's first step, check the intended
controls; if the check passes, apply them for the period (the rollout is now the plan); if not,
continue the failsafe of the last plan that passed. Every physics step it tracks how far the
robot is from its plan (Lemma 8.1 of docs/theory.md: ``|dp| + |dR|_F r`` for each body).
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

Policy = Callable[[mujoco.MjModel, mujoco.MjData], np.ndarray]

SLACK = 1e-5
"""Metres taken off MuJoCo's distances: GJK's distance converges from above."""


@dataclass(frozen=True)
class OtherBound:
    """Declared bounds on every point of a body nobody plans.

    Attributes:
        speed: speed bound (m/s), inf for none.
        accel: acceleration bound (m/s^2), inf for none.
        delta: velocity uncertainty of the velocity read (m/s); None: ``accel * h / 2``.
    """

    speed: float = np.inf
    accel: float = np.inf
    delta: float | None = None


@dataclass(frozen=True)
class ProtectedPair:
    """A geom pair the robot must not touch while it moves."""

    robot: int
    other: int
    contact_distance: float


@dataclass
class Verdict:
    """What :func:`verify` found.

    Attributes:
        safe: no protected pair may touch while the robot moves (and it comes to rest).
        rest: the first knot at which every robot body is at rest (-1 if none).
        unsafe_knot: the first knot at which a pair may touch (-1 if none).
        unsafe_pair: that pair (None if none).
        body_pos: ``(knots, nrobot, 3)`` the robot bodies' positions at each knot.
        body_mat: ``(knots, nrobot, 9)`` their orientations.
        gaps: ``(knots, npair)`` each pair's distance less contact distance and reach, at
            each knot (inf where a bounding-sphere test already cleared it).
    """

    safe: bool
    rest: int
    unsafe_knot: int
    unsafe_pair: ProtectedPair | None
    body_pos: np.ndarray
    body_mat: np.ndarray
    gaps: np.ndarray = field(repr=False)


def _static(model: mujoco.MjModel, body: int) -> bool:
    weld = int(model.body_weldid[body])
    return int(model.body_dofnum[weld]) == 0 and int(model.body_mocapid[body]) < 0


def _filter_lets_through(model: mujoco.MjModel, g1: int, g2: int) -> bool:
    """MuJoCo 4.0's dynamic pair filter, statement by statement (docs/covering-and-pairs.md)."""
    b1, b2 = int(model.geom_bodyid[g1]), int(model.geom_bodyid[g2])
    if b1 == b2:
        return False
    w1, w2 = int(model.body_weldid[b1]), int(model.body_weldid[b2])
    if w1 == w2:
        return False
    if int(model.body_dofnum[w1]) == 0 and int(model.body_dofnum[w2]) == 0:
        return False
    off = int(model.opt.disableflags) & int(mujoco.mjtDisableBit.mjDSBL_FILTERPARENT)
    p1 = int(model.body_weldid[model.body_parentid[w1]])
    p2 = int(model.body_weldid[model.body_parentid[w2]])
    if not off and w1 != 0 and w2 != 0 and (w1 == p2 or w2 == p1):
        return False
    signature = (min(b1, b2) << 16) + max(b1, b2)
    if signature in set(np.asarray(model.exclude_signature).tolist()):
        return False
    t1, t2 = int(model.geom_contype[g1]), int(model.geom_contype[g2])
    a1, a2 = int(model.geom_conaffinity[g1]), int(model.geom_conaffinity[g2])
    return bool((t1 & a2) or (t2 & a1))


def protected_pairs(
    model: mujoco.MjModel, robot_bodies: Sequence[int], protected_bodies: Sequence[int]
) -> list[ProtectedPair]:
    """Every geom pair between a robot body and a protected body that MuJoCo can collide, with
    its contact distance (margin + gap, summed over the two geoms)."""
    if int(model.npair):
        raise NotImplementedError("the reference shield does not take <pair> elements")
    robot = set(int(b) for b in robot_bodies)
    other = set(int(b) for b in protected_bodies) - robot
    plane = int(mujoco.mjtGeom.mjGEOM_PLANE)
    out = []
    for g1 in range(model.ngeom):
        if int(model.geom_bodyid[g1]) not in robot:
            continue
        for g2 in range(model.ngeom):
            if int(model.geom_bodyid[g2]) not in other or not _filter_lets_through(model, g1, g2):
                continue
            if int(model.geom_type[g1]) == plane:
                continue
            dist = model.geom_margin[g1] + model.geom_margin[g2]
            dist += model.geom_gap[g1] + model.geom_gap[g2]
            out.append(ProtectedPair(g1, g2, float(dist)))
    return out


def rollout_model(model: mujoco.MjModel, protected_bodies: Sequence[int]) -> mujoco.MjModel:
    """A copy of the model in which the protected bodies' geoms collide with nothing."""
    out = copy.deepcopy(model)
    geoms = np.isin(np.asarray(model.geom_bodyid), np.asarray(protected_bodies))
    out.geom_contype[geoms] = 0
    out.geom_conaffinity[geoms] = 0
    return out


def _speeds(
    model: mujoco.MjModel, data: mujoco.MjData, bodies: np.ndarray, radius: np.ndarray
) -> np.ndarray:
    out = np.empty(bodies.size)
    vel = np.empty(6)
    for i, b in enumerate(bodies.tolist()):
        mujoco.mj_objectVelocity(model, data, int(mujoco.mjtObj.mjOBJ_XBODY), b, vel, 0)
        out[i] = np.linalg.norm(vel[3:]) + np.linalg.norm(vel[:3]) * radius[b]
    return out


def body_radius(model: mujoco.MjModel) -> np.ndarray:
    """``(nbody,)`` the largest distance from a body's frame origin to a point of its geoms."""
    out = np.zeros(model.nbody)
    for g in range(model.ngeom):
        if int(model.geom_type[g]) == int(mujoco.mjtGeom.mjGEOM_PLANE):
            continue
        b = int(model.geom_bodyid[g])
        out[b] = max(out[b], float(np.linalg.norm(model.geom_pos[g]) + model.geom_rbound[g]))
    return out


def verify(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    intended: npt.ArrayLike,
    *,
    period: int,
    failsafe: Policy,
    robot_bodies: npt.ArrayLike,
    pairs: Sequence[ProtectedPair],
    bounds: dict[int, OtherBound],
    velocities: dict[int, np.ndarray] | None = None,
    deviation: float = 0.0,
    rest_speed: float = 0.01,
    max_steps: int = 5000,
    rolled: mujoco.MjModel | None = None,
) -> Verdict:
    """Check the intended controls for one period followed by the failsafe (module docstring).

    Args:
        model: the model.
        data: the state read (``qpos``, ``qvel``, ``act``, ``mocap_*``, ``time``); not changed.
        intended: ``(nu,)`` controls held for ``period`` steps.
        period: physics steps of the intended part (0: the failsafe from the start).
        failsafe: ``policy(model, data) -> (nu,)`` after the period.
        robot_bodies: ids of the robot's bodies (what must be at rest).
        pairs: the protected pairs (:func:`protected_pairs`).
        bounds: the declared bounds of each moving body on the other side of a pair, by id.
        velocities: ``[w (3), v (3)]`` of a body at the state read, world frame, at the body's
            frame origin, by id; required for mocap bodies (MuJoCo reports them at rest), read
            from MuJoCo for the others when not given.
        deviation: how far every point of the robot may stray from the rollout (m).
        rest_speed: the speed under which a body is at rest (m/s).
        max_steps: the longest rollout.
        rolled: the model to roll out on (default: :func:`rollout_model` of ``model``).

    Returns:
        The :class:`Verdict`.
    """
    h = float(model.opt.timestep)
    robot = np.asarray(robot_bodies, dtype=np.int64)
    radius = body_radius(model)
    others = sorted({int(model.geom_bodyid[p.other]) for p in pairs})
    if rolled is None:
        rolled = rollout_model(model, others)
    velocities = dict(velocities or {})
    for b in others:
        if not _static(model, b) and b not in bounds:
            raise ValueError(f"body {model.body(b).name!r} moves and has no declared bound")
        if int(model.body_mocapid[b]) >= 0 and b not in velocities:
            raise ValueError(f"mocap body {model.body(b).name!r} needs its velocity")

    roll = mujoco.MjData(rolled)
    roll.qpos[:] = data.qpos
    roll.qvel[:] = data.qvel
    roll.act[:] = data.act
    roll.ctrl[:] = data.ctrl
    roll.mocap_pos[:] = data.mocap_pos
    roll.mocap_quat[:] = data.mocap_quat
    roll.qacc_warmstart[:] = data.qacc_warmstart
    roll.time = data.time
    scratch = mujoco.MjData(model)  # geom poses: the others at knot 0, the robot at knot j

    held = np.asarray(intended, dtype=np.float64)
    # Per pair: the two geoms, the other's body, its bounds (0 for a static body).
    rg = np.array([p.robot for p in pairs], dtype=np.int64)
    og = np.array([p.other for p in pairs], dtype=np.int64)
    ob = np.asarray(model.geom_bodyid)[og]
    contact = np.array([p.contact_distance for p in pairs])
    moves = np.array([not _static(model, int(b)) for b in ob], dtype=bool)
    vmax = np.array([bounds[int(b)].speed if m else 0.0 for b, m in zip(ob, moves, strict=True)])
    amax = np.array([bounds[int(b)].accel if m else 0.0 for b, m in zip(ob, moves, strict=True)])
    delta = np.array(
        [
            (bounds[int(b)].accel * h / 2 if bounds[int(b)].delta is None else bounds[int(b)].delta)
            if m
            else 0.0
            for b, m in zip(ob, moves, strict=True)
        ]
    )
    spheres = model.geom_rbound[rg] + model.geom_rbound[og]
    plane = np.asarray(model.geom_type)[og] == int(mujoco.mjtGeom.mjGEOM_PLANE)
    speed0 = np.zeros(len(pairs))  # each other geom's points' speed bound at the state read
    robot_geoms = np.unique(rg)
    gaps, positions, mats = [], [], []
    rest = unsafe_knot = -1
    unsafe: ProtectedPair | None = None
    for j in range(max_steps):
        roll.ctrl[:] = held if j < period else failsafe(rolled, roll)
        mujoco.mj_step(rolled, roll)  # after it: geom_xpos, cvel of knot j; qpos of knot j + 1
        positions.append(np.array(roll.xpos[robot]))
        mats.append(np.array(roll.xmat[robot]))
        if j == 0:
            scratch.geom_xpos[:] = roll.geom_xpos
            scratch.geom_xmat[:] = roll.geom_xmat
            for k in np.flatnonzero(moves).tolist():
                b = int(ob[k])
                vel = velocities.get(b)
                if vel is None:
                    vel = np.empty(6)
                    mujoco.mj_objectVelocity(
                        rolled, roll, int(mujoco.mjtObj.mjOBJ_XBODY), b, vel, 0
                    )
                r = np.linalg.norm(roll.geom_xpos[og[k]] - roll.xpos[b]) + model.geom_rbound[og[k]]
                speed0[k] = np.linalg.norm(vel[3:]) + np.linalg.norm(vel[:3]) * r
        scratch.geom_xpos[robot_geoms] = roll.geom_xpos[robot_geoms]
        scratch.geom_xmat[robot_geoms] = roll.geom_xmat[robot_geoms]
        moving = bool(np.any(_speeds(rolled, roll, robot, radius) > rest_speed))
        t = j * h
        reach = np.zeros(len(pairs))
        if j > 0:
            by_accel = (speed0 + delta) * t + 0.5 * amax * t * t
            reach = np.where(moves, np.minimum(vmax * t, by_accel), 0.0)
        need = reach + deviation + contact + SLACK
        # Bounding spheres first: a pair whose spheres are that far apart is clear.
        apart = np.linalg.norm(scratch.geom_xpos[rg] - scratch.geom_xpos[og], axis=1) - spheres
        row = np.full(len(pairs), np.inf)
        for k in np.flatnonzero(plane | (apart <= need)).tolist():
            dist = mujoco.mj_geomDistance(
                model, scratch, int(rg[k]), int(og[k]), need[k] + 1.0, None
            )
            row[k] = dist - need[k]
        gaps.append(row)
        if moving and np.any(row <= 0.0):
            unsafe_knot, unsafe = j, pairs[int(np.argmax(row <= 0.0))]
            break
        if j >= period and not moving:
            rest = j
            break
    return Verdict(
        safe=unsafe is None and rest >= 0,
        rest=rest,
        unsafe_knot=unsafe_knot,
        unsafe_pair=unsafe,
        body_pos=np.array(positions),
        body_mat=np.array(mats),
        gaps=np.array(gaps),
    )


def shield_for(setup: Any, bounds: dict[int, OtherBound] | None = None) -> ReferenceShield:
    """The reference shield of a shield scene's setup (``dua_mujoco.experiments.shield.episodes.
    SceneSetup``: its brake, protected bodies, declared bounds and period); ``bounds`` replaces
    the declared ones."""
    if bounds is None:
        bounds = {b: OtherBound(v.speed, v.accel, v.delta) for b, v in setup.bounds.items()}
    return ReferenceShield(
        setup.model,
        robot_actuators=setup.brake.actuators,
        robot_bodies=setup.brake.bodies,
        protected_bodies=setup.protected,
        bounds=bounds,
        period=setup.scene.period,
        failsafe=setup.brake,
    )


class MocapVelocities:
    """Velocities of mocap bodies by backward differences of ``mocap_pos``/``mocap_quat``,
    updated once per physics step before the step (the pose the step will start from)."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.bodies = np.flatnonzero(np.asarray(model.body_mocapid) >= 0)
        self._pos: np.ndarray | None = None
        self._quat: np.ndarray | None = None
        self._time = 0.0
        self.velocity: dict[int, np.ndarray] = {int(b): np.zeros(6) for b in self.bodies}

    def update(self, data: mujoco.MjData) -> None:
        """Difference the poses with the last update's."""
        pos, quat, t = np.array(data.mocap_pos), np.array(data.mocap_quat), float(data.time)
        if self._pos is not None and self._quat is not None and t > self._time:
            dt = t - self._time
            for b in self.bodies.tolist():
                i = int(self.model.body_mocapid[b])
                rot = np.zeros(3)
                mujoco.mju_subQuat(rot, quat[i], self._quat[i])  # in the old frame
                mat = np.zeros(9)
                mujoco.mju_quat2Mat(mat, self._quat[i])
                w = mat.reshape(3, 3) @ rot / dt
                self.velocity[b] = np.concatenate([w, (pos[i] - self._pos[i]) / dt])
        self._pos, self._quat, self._time = pos, quat, t


class ReferenceShield:
    """The shield's loop around :func:`verify`, slowly (a prototype and a test oracle).

    Call it every physics step, after the scripted bodies moved and before ``mj_step``:
    ``ctrl = shield(data, intended)``.

    Args:
        model: the model.
        robot_actuators: the robot's actuator ids (the others' controls pass through).
        robot_bodies: the robot's bodies.
        protected_bodies: the bodies it must not move into.
        bounds: declared bounds of the moving protected bodies, by id.
        period: physics steps per control period.
        failsafe: ``policy(model, data) -> (nu,)``.
        deviation: the robot's declared deviation from its rollout (m).
        rest_speed: at rest below this speed (m/s).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        *,
        robot_actuators: npt.ArrayLike,
        robot_bodies: npt.ArrayLike,
        protected_bodies: npt.ArrayLike,
        bounds: dict[int, OtherBound],
        period: int,
        failsafe: Policy,
        deviation: float = 0.0,
        rest_speed: float = 0.01,
    ) -> None:
        self.model = model
        self.robot_actuators = np.asarray(robot_actuators, dtype=np.int64)
        self.robot_bodies = np.asarray(robot_bodies, dtype=np.int64)
        self.pairs = protected_pairs(model, self.robot_bodies, np.asarray(protected_bodies))
        self.rolled = rollout_model(
            model, sorted({int(model.geom_bodyid[p.other]) for p in self.pairs})
        )
        self.bounds = bounds
        self.period = period
        self.failsafe = failsafe
        self.deviation = deviation
        self.rest_speed = rest_speed
        self.radius = body_radius(model)
        self.mocap = MocapVelocities(model)
        self.reset()

    def reset(self, data: mujoco.MjData | None = None) -> None:
        """Forget the plan and the counts."""
        self.steps = 0
        self.interventions = 0
        self.checks = 0
        self.rejections = 0
        self.plan: Verdict | None = None
        self.knot = 0
        self.held: np.ndarray | None = None
        self.max_deviation = 0.0
        self.mocap = MocapVelocities(self.model)

    def _deviation(self, data: mujoco.MjData) -> float:
        """How far the robot is from its plan's knot (the state the last step started from)."""
        if self.plan is None or self.knot == 0:
            return 0.0
        j = min(self.knot - 1, len(self.plan.body_pos) - 1)
        dp = np.linalg.norm(data.xpos[self.robot_bodies] - self.plan.body_pos[j], axis=1)
        dr = np.linalg.norm(data.xmat[self.robot_bodies] - self.plan.body_mat[j], axis=1)
        return float(np.max(dp + dr * self.radius[self.robot_bodies]))

    def __call__(self, data: mujoco.MjData, intended: npt.ArrayLike) -> np.ndarray:
        """The controls to apply at this physics step: ``(nu,)``."""
        self.mocap.update(data)
        if self.steps > 0:
            self.max_deviation = max(self.max_deviation, self._deviation(data))
        want = np.asarray(intended, dtype=np.float64)
        if self.steps % self.period == 0:
            self.checks += 1
            verdict = verify(
                self.model,
                data,
                want,
                period=self.period,
                failsafe=self.failsafe,
                robot_bodies=self.robot_bodies,
                pairs=self.pairs,
                bounds=self.bounds,
                velocities=self.mocap.velocity,
                deviation=self.deviation,
                rest_speed=self.rest_speed,
                rolled=self.rolled,
            )
            if verdict.safe:
                self.plan, self.knot, self.held = verdict, 0, want.copy()
            else:
                self.rejections += 1
                self.held = None
        self.steps += 1
        self.knot += 1
        if self.held is not None:
            return self.held.copy()
        self.interventions += 1
        ctrl = np.array(want)
        ctrl[self.robot_actuators] = self.failsafe(self.model, data)[self.robot_actuators]
        return ctrl
