"""The BoundMonitor's checks in plain numpy: the slow, obviously-correct reference.

This is the vectorised numpy implementation that ``dua_mujoco.mj.checks.BoundMonitor`` used before
its checks moved into one compiled kernel; the tests hold the kernel to it, value by value.
"""

from __future__ import annotations

import mujoco
import numpy as np
import numpy.typing as npt
from reference_kinematics import reference_states

from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.mj.bounds import MotionBounds, default_spheres
from dua_mujoco.mj.checks import BoundViolation
from dua_mujoco.mj.mocap import MocapVelocityTracker


class ReferenceBoundMonitor:
    """Checks, once per physics step, whether the hypotheses of the guarantee held.

    Call :meth:`update` after every ``mj_step``. Update k (k >= 2) checks, for every sphere,
    |u_k - u_{k-1}| <= A h (discrete acceleration), |u_k - w_{k-1}| <= D = delta + A h / 2
    (one-step discrepancy) and |w_k| <= V, with a tolerance for floating-point round-off in the
    second differences. Vectorised over spheres.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        bounds: MotionBounds,
        spheres: tuple[npt.ArrayLike, npt.ArrayLike, npt.ArrayLike] | None = None,
        *,
        mocap: MocapVelocityTracker | None = None,
        rtol: float = 1e-9,
    ) -> None:
        """Create a monitor.

        Args:
            model: the MuJoCo model.
            bounds: the bounds to hold the run to.
            spheres: ``(sphere_geom, sphere_body, sphere_offset)``; None for
                :func:`default_spheres`.
            mocap: tracker for mocap velocities (the caller updates it each step, before
                :meth:`update`).
            rtol: relative tolerance on every comparison.
        """
        if bounds.accel.shape != (model.nbody,):
            raise InvalidInputError("bounds were made for a model with a different nbody.")
        sgeom, sbody, soff = default_spheres(model) if spheres is None else spheres
        self._sgeom = np.asarray(sgeom, dtype=np.int64)
        self._sbody = np.asarray(sbody, dtype=np.int64)
        self._soff = np.asarray(soff, dtype=np.float64).reshape(-1, 3)
        self._bounds = bounds
        self._mocap = mocap
        self._rtol = rtol
        self._nbody = model.nbody
        self._A = bounds.accel[self._sbody]
        self._D = bounds.discrepancy[self._sbody]
        self._V = None if bounds.speed is None else bounds.speed[self._sbody]
        self._prev_c: np.ndarray | None = None
        self._prev_u: np.ndarray | None = None
        self._prev_w: np.ndarray | None = None
        self._prev_t = 0.0
        self.violations: list[BoundViolation] = []
        """Every violation so far, in order."""
        self.held: list[bool] = []
        """Per update: True when no bound was broken at that update."""

    def _flag(self, kind: str, mask: np.ndarray, values: np.ndarray, t: float) -> np.ndarray:
        """Record violations of ``kind`` for spheres in ``mask`` (the worst value per body)."""
        worst: dict[int, float] = {}
        for i in np.flatnonzero(mask).tolist():
            body = int(self._sbody[i])
            worst[body] = max(worst.get(body, -np.inf), float(values[i]))
        bound = {
            "accel": self._bounds.accel,
            "discrepancy": self._bounds.discrepancy,
            "speed": self._bounds.speed,
        }[kind]
        assert bound is not None
        step = len(self.held)
        for body in sorted(worst):
            self.violations.append(
                BoundViolation(step, t, body, kind, worst[body], float(bound[body]))
            )
        return np.array(sorted(worst), dtype=np.int64)

    def update(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """Check the step that produced ``data``.

        Args:
            model: the MuJoCo model.
            data: the data right after ``mj_step``.

        Returns:
            ``(k,)`` sorted ids of bodies that broke a bound at this step (empty if none).
        """
        c, w = reference_states(model, data, self._sgeom, self._soff, self._mocap)
        t = float(data.time)
        found: list[np.ndarray] = []
        u = None
        if self._prev_c is not None:
            h = t - self._prev_t
            if h <= 0:
                h = float(model.opt.timestep)
            u = (c - self._prev_c) / h
            # Round-off of a second difference of positions of size |c|: ~ 4 eps |c| / h^2.
            scale = np.max(np.abs(c), axis=1) + np.max(np.abs(self._prev_c), axis=1)
            tol_a = 8 * np.finfo(float).eps * scale / h**2
            if self._V is not None:
                speed = np.linalg.norm(u, axis=1)  # the chord (discrete velocity)
                over = speed > self._V * (1 + self._rtol) + 0.5 * tol_a * h
                found.append(self._flag("speed", over, speed, t))
            assert self._prev_w is not None
            disc = np.linalg.norm(u - self._prev_w, axis=1)
            tol_d = tol_a * h + 8 * np.finfo(float).eps * np.linalg.norm(self._prev_w, axis=1)
            found.append(
                self._flag("discrepancy", disc > self._D * (1 + self._rtol) + tol_d, disc, t)
            )
            if self._prev_u is not None:
                acc = np.linalg.norm(u - self._prev_u, axis=1) / h
                found.append(self._flag("accel", acc > self._A * (1 + self._rtol) + tol_a, acc, t))
        self._prev_c, self._prev_u, self._prev_w, self._prev_t = c, u, w, t
        out = np.unique(np.concatenate(found)) if found else np.zeros(0, dtype=np.int64)
        self.held.append(out.size == 0)
        return out.astype(np.int64)
