"""The shield's peers, written for MuJoCo as their sources do it, with their default parameters.

* :class:`TtcHalt`, after MoveIt Servo's ``CollisionCheck`` (``moveit_servo/src/
  collision_check.cpp``). Every ``1 / collision_check_rate`` seconds it takes the smallest
  distance ``d`` over the protected pairs (``mj_geomDistance``) and its finite difference ``d'``
  over the check period. ``stop_distance`` mode: the robot halts when ``d <
  min_allowable_collision_distance`` and ``d' <= 0``, or when ``d' < -1e-6`` and ``d / |d'| <
  collision_distance_safety_factor * worst_case_stop_time``, the worst case being
  ``max_j |qdot_j| / a_j`` over the robot's joints (``ServoCalcs``'s, from the joints'
  acceleration limits: here the task's). ``threshold_distance`` mode (MoveIt's default type):
  the intended joint velocity is scaled by ``exp(k (d - threshold))`` below the threshold,
  ``k = -ln(0.001) / threshold``, 0 in contact. Defaults: MoveIt's (``servo_parameters``):
  10 Hz, safety factor 1000, 0.01 m, threshold 0.02 m (scene collisions). A halt here is the
  failsafe brake, a scaled velocity is driven by the same inverse-dynamics law
  (:meth:`dua_mujoco.shield.failsafe.Brake.toward`).
* :class:`VelocityDamper`, after mink's ``CollisionAvoidanceLimit`` (``mink/limits/
  collision_avoidance_limit.py``). Every control period, for each protected pair closer than
  ``collision_detection_distance``, the row ``n . (J2 - J1) dq >= -gain (d - d_min) / dt`` (0 on
  the right when ``d <= d_min``), ``n`` the unit direction between ``mj_geomDistance``'s witness
  points, ``J`` the points' Jacobians over the robot's DOFs (``mj_jac``): the distance at the
  current pose only. The intended joint velocity (the intended controls rolled out over one
  period on a copy) is projected onto those rows (the least change in the Euclidean norm, as
  mink's QP with a unit cost on the velocity; Hildreth's method) and driven by the brake's
  law. Defaults: mink's, gain 0.85, ``d_min`` 0.005 m, detection 0.01 m; ``dt`` the period.

Both read the state at the call (``mj_kinematics`` on a private ``MjData``: after ``mj_step``
the user's holds the poses the step started from).
"""

from __future__ import annotations

import math
from dataclasses import KW_ONLY, dataclass
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco.shield.failsafe import Brake

__all__ = ["Hildreth", "TtcHalt", "VelocityDamper", "intended_velocity"]


def intended_velocity(
    model: mujoco.MjModel,
    scratch: mujoco.MjData,
    data: mujoco.MjData,
    intended: np.ndarray,
    steps: int,
    dofs: np.ndarray,
) -> np.ndarray:
    """The mean joint velocity over ``steps`` steps of ``intended`` held, from ``data``'s state
    (rolled on ``scratch``): ``(len(dofs),)``."""
    mujoco.mj_copyData(scratch, model, data)
    start = np.array(scratch.qpos)
    scratch.ctrl[:] = intended
    for _ in range(steps):
        mujoco.mj_step(model, scratch)
    qvel = np.zeros(model.nv)
    mujoco.mj_differentiatePos(model, qvel, steps * float(model.opt.timestep), start, scratch.qpos)
    return qvel[dofs]


class Hildreth:
    """``argmin |x - x0|^2`` subject to ``G x <= h``: Hildreth's dual coordinate ascent."""

    def __init__(self, sweeps: int = 200, tol: float = 1e-10) -> None:
        self.sweeps = sweeps
        self.tol = tol

    def __call__(self, x0: np.ndarray, g: np.ndarray, h: np.ndarray) -> np.ndarray:
        """The projection of ``x0`` (``(n,)``) onto ``{x : g x <= h}`` (``g`` is ``(k, n)``)."""
        x = x0.copy()
        lam = np.zeros(h.size)
        norms = np.einsum("ij,ij->i", g, g)
        for _ in range(self.sweeps):
            change = 0.0
            for i in range(h.size):
                if norms[i] == 0.0:
                    continue
                new = max(0.0, lam[i] + (g[i] @ x - h[i]) / norms[i])
                x -= (new - lam[i]) * g[i]
                change = max(change, abs(new - lam[i]))
                lam[i] = new
            if change < self.tol:
                break
        return x


@dataclass(eq=False)
class _Peer:
    """What both peers share: the protected pairs, the brake, a private state, counts. Made as
    ``Peer(model, brake=..., pairs=..., period=..., <its own options>)``."""

    model: mujoco.MjModel
    _: KW_ONLY
    brake: Brake
    pairs: Any
    period: int

    def __post_init__(self) -> None:
        model = self.model
        self.pairs = np.asarray(self.pairs, dtype=np.int64).reshape(-1, 2)
        self._scratch = mujoco.MjData(model)
        self._roll = mujoco.MjData(model)
        self.interventions = 0
        self.steps = 0

    def reset(self, data: mujoco.MjData) -> None:
        """Start an episode."""
        self.interventions = 0
        self.steps = 0

    def _at(self, data: mujoco.MjData) -> mujoco.MjData:
        s = self._scratch
        s.qpos[:] = data.qpos
        s.qvel[:] = data.qvel
        if self.model.nmocap:
            s.mocap_pos[:] = data.mocap_pos
            s.mocap_quat[:] = data.mocap_quat
        mujoco.mj_kinematics(self.model, s)
        mujoco.mj_comPos(self.model, s)
        return s

    def _intended(self, data: mujoco.MjData, want: np.ndarray) -> np.ndarray:
        return intended_velocity(self.model, self._roll, data, want, self.period, self.brake.dofs)

    def _override(
        self, data: mujoco.MjData, want: np.ndarray, target: np.ndarray | None
    ) -> np.ndarray:
        """``want`` with the robot's controls driving it to ``target`` (None: braking)."""
        self.interventions += 1
        acts = self.brake.actuators
        out = want.copy()
        drive = self.brake(self.model, data) if target is None else self.brake.toward(data, target)
        out[acts] = drive[acts]
        return out

    def _distances(self, s: mujoco.MjData, distmax: float) -> tuple[np.ndarray, np.ndarray]:
        dist = np.empty(len(self.pairs))
        fromto = np.zeros((len(self.pairs), 6))
        for k, (g1, g2) in enumerate(self.pairs.tolist()):
            dist[k] = mujoco.mj_geomDistance(self.model, s, g1, g2, distmax, fromto[k])
        return dist, fromto


@dataclass(eq=False)
class TtcHalt(_Peer):
    """MoveIt Servo's collision check (module docstring).

    Args:
        model: the model.
        brake: the robot's brake (its halt, and its law to drive a scaled velocity).
        pairs: ``(k, 2)`` protected geom pairs, robot geom first.
        period: physics steps of the control period (intended velocities are rolled over it).
        accel_limits: ``(len(brake.dofs),)`` joint acceleration limits.
        mode: ``"stop_distance"`` or ``"threshold_distance"``.
        rate: checks per second (MoveIt's ``collision_check_rate``).
        safety_factor: ``collision_distance_safety_factor``.
        min_distance: ``min_allowable_collision_distance`` (m).
        threshold: ``scene_collision_proximity_threshold`` (m).
    """

    accel_limits: Any
    mode: str = "stop_distance"
    rate: float = 10.0
    safety_factor: float = 1000.0
    min_distance: float = 0.01
    threshold: float = 0.02

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.mode not in ("stop_distance", "threshold_distance"):
            raise ValueError(f"mode must be stop_distance or threshold_distance: {self.mode!r}")
        h = float(self.model.opt.timestep)
        self.every = max(1, round(1.0 / (self.rate * h)))
        self.check_period = self.every * h
        self.accel_limits = np.asarray(self.accel_limits, dtype=np.float64)
        self.reset(mujoco.MjData(self.model))

    def reset(self, data: mujoco.MjData) -> None:
        """Start an episode."""
        super().reset(data)
        self.previous: float | None = None
        self.scale = 1.0
        self.target: np.ndarray | None = None

    def _check(self, data: mujoco.MjData) -> None:
        s = self._at(data)
        dist, _ = self._distances(s, 10.0)
        d = float(dist.min()) if dist.size else math.inf
        if self.mode == "threshold_distance":
            k = -math.log(0.001) / self.threshold
            below = d < self.threshold
            self.scale = 0.0 if d <= 0 else math.exp(k * (d - self.threshold)) if below else 1.0
            return
        derivative = 0.0 if self.previous is None else (d - self.previous) / self.check_period
        stop_time = float(np.max(np.abs(data.qvel[self.brake.dofs]) / self.accel_limits))
        touching = d < self.min_distance and derivative <= 0
        closing = derivative < -1e-6 and abs(d / derivative) < self.safety_factor * stop_time
        self.scale = 0.0 if touching or closing else 1.0
        self.previous = d

    def __call__(self, data: mujoco.MjData, intended: npt.ArrayLike) -> np.ndarray:
        """The controls to apply at this physics step: ``(nu,)``."""
        want = np.asarray(intended, dtype=np.float64)
        if self.steps % self.every == 0:
            self._check(data)
        if self.steps % self.period == 0 and 0.0 < self.scale < 1.0:
            self.target = self.scale * self._intended(data, want)
        self.steps += 1
        if self.scale >= 1.0:
            return want.copy()
        return self._override(data, want, None if self.scale == 0.0 else self.target)


@dataclass(eq=False)
class VelocityDamper(_Peer):
    """mink's collision-avoidance limit on the intended motion (module docstring).

    Args:
        model: the model.
        brake: the robot's brake (its law drives the projected velocity).
        pairs: ``(k, 2)`` protected geom pairs, robot geom first.
        period: physics steps of the control period (``dt``).
        gain: mink's ``gain``.
        min_distance: ``minimum_distance_from_collisions`` (m).
        detection_distance: ``collision_detection_distance`` (m).
    """

    gain: float = 0.85
    min_distance: float = 0.005
    detection_distance: float = 0.01

    def __post_init__(self) -> None:
        super().__post_init__()
        nv = self.model.nv
        self.dt = self.period * float(self.model.opt.timestep)
        self.project = Hildreth()
        self.target: np.ndarray | None = None
        self._jac1 = np.zeros((3, nv))
        self._jac2 = np.zeros((3, nv))

    def reset(self, data: mujoco.MjData) -> None:
        """Start an episode."""
        super().reset(data)
        self.target = None

    def _rows(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        s = self._at(data)
        dist, fromto = self._distances(s, self.detection_distance)
        rows, bounds = [], []
        dofs = self.brake.dofs
        for k in np.flatnonzero(dist < self.detection_distance).tolist():
            g1, g2 = self.pairs[k]
            if not fromto[k].any():
                continue  # mink's inactive contact
            normal = fromto[k, 3:] - fromto[k, :3]
            normal = normal / (np.linalg.norm(normal) + 1e-9)
            b1, b2 = int(self.model.geom_bodyid[g1]), int(self.model.geom_bodyid[g2])
            mujoco.mj_jac(self.model, s, self._jac1, None, fromto[k, :3], b1)
            mujoco.mj_jac(self.model, s, self._jac2, None, fromto[k, 3:], b2)
            rows.append(-(normal @ (self._jac2 - self._jac1))[dofs])
            gap = dist[k] - self.min_distance
            bounds.append(self.gain * gap / self.dt if gap > 0 else 0.0)
        return np.array(rows).reshape(-1, dofs.size), np.array(bounds)

    def __call__(self, data: mujoco.MjData, intended: npt.ArrayLike) -> np.ndarray:
        """The controls to apply at this physics step: ``(nu,)``."""
        want = np.asarray(intended, dtype=np.float64)
        if self.steps % self.period == 0:
            self.target = None
            g, h = self._rows(data)
            if h.size:
                velocity = self._intended(data, want)
                if np.any(g @ velocity > h + 1e-12):
                    self.target = self.project(velocity, g, h)
        self.steps += 1
        if self.target is None:
            return want.copy()
        return self._override(data, want, self.target)
