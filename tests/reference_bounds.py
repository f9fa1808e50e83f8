"""The BoundMonitor's checks in plain numpy: the slow, obviously-correct reference.

This is the vectorised numpy implementation that ``dua_mujoco.measure.checks.BoundMonitor`` used
before its checks moved into one compiled kernel; the tests hold the kernel to it, value by value.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
from reference_kinematics import reference_states

from dua_mujoco.measure.checks import BoundMonitor, BoundViolation


class ReferenceBoundMonitor(BoundMonitor):
    """``BoundMonitor``'s checks in plain numpy, vectorised over spheres.

    The set-up (spheres, bounds, tolerance, the violation records) is ``BoundMonitor``'s own, so
    that only the checks differ. Update k (k >= 2) checks, for every sphere,
    |u_k - u_{k-1}| <= A h (discrete acceleration), |u_k - w_{k-1}| <= D = delta + A h / 2
    (one-step discrepancy) and |w_k| <= V, with a tolerance for floating-point round-off in the
    second differences. Only ``mocap_period=1``: the discrepancy bound is then the declared one.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        """Take ``BoundMonitor``'s arguments (``mocap_period`` 1 only)."""
        if kwargs.get("mocap_period", 1) != 1:
            raise ValueError("the reference checks every step against the declared bounds")
        super().__init__(*args, **kwargs)
        speed = self._bounds.speed
        # None, not the kernel's empty array, when there is no speed bound.
        self._V = None if speed is None else speed[self._sbody]
        self._prev_c: np.ndarray | None = None
        self._prev_u: np.ndarray | None = None
        self._prev_w: np.ndarray | None = None
        # Its own record, a plain list (the monitor keeps runs of broken updates).
        self._held: list[bool] = []

    @property
    def held(self) -> list[bool]:
        """Per update: True when no bound was broken at that update."""
        return self._held

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
        step = len(self._held)
        for body in sorted(worst):
            self.violations.append(
                BoundViolation(step, t, body, kind, worst[body], float(bound[body]))
            )
        return np.array(sorted(worst), dtype=np.int64)

    def update(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
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
        self._held.append(out.size == 0)
        return out.astype(np.int64)
