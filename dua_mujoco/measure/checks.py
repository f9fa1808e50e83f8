"""Checks, every physics step, that the motion bounds the guarantee assumes actually held.

``BoundMonitor`` runs one native pass over the covering spheres through the kinematics kernel
(``dua_check_points``, ``csrc/src/checks.cc``) and records each broken bound as a
``BoundViolation``: a miss after a violation is not covered
by the guarantee (docs/discrete-time.md derives each check).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco.build.bounds import MotionBounds, default_spheres
from dua_mujoco.build.kinematics import PointMotion, pack_spheres
from dua_mujoco.build.mocap import PredictorMocap
from dua_mujoco.core.validate import check_int
from dua_mujoco.exceptions import InvalidInputError

__all__ = ["BoundMonitor", "BoundViolation"]


@dataclass(frozen=True)
class BoundViolation:
    """One broken bound.

    Attributes:
        step: index of the :meth:`BoundMonitor.update` call that detected it (0-based).
        time: ``d.time`` at that call.
        body: body id.
        kind: ``"accel"``, ``"discrepancy"`` or ``"speed"``.
        value: the largest measured value over the body's spheres.
        bound: the bound it exceeded.
    """

    step: int
    time: float
    body: int
    kind: str
    value: float
    bound: float


class BoundMonitor:
    """Checks, once per physics step, whether the hypotheses of the guarantee held.

    Call :meth:`update` after every ``mj_step``. From the second update on it checks, for every
    sphere (the acceleration from the third),
    |u_k - u_{k-1}| <= A h (discrete acceleration), |u_k - w_{k-1}| <= D = delta + A h / 2
    (one-step discrepancy) and |u_k| <= V (chord speed, fresh every step for mocap trees too),
    with a tolerance for floating-point round-off in the
    second differences. One native pass over the spheres (the checks run every physics step of
    a monitored run; as numpy calls they took ten times as long as ``mj_step`` on traffic).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        bounds: MotionBounds,
        spheres: tuple[npt.ArrayLike, npt.ArrayLike, npt.ArrayLike] | None = None,
        *,
        mocap: PredictorMocap | None = None,
        mocap_period: int = 1,
        rtol: float = 1e-9,
        max_violations: int = 10_000,
        screen: bool = True,
    ) -> None:
        """Create a monitor.

        Args:
            bounds: the bounds to hold the run to.
            spheres: ``(sphere_geom, sphere_body, sphere_offset)``; None for
                :func:`default_spheres`.
            mocap: tracker for mocap velocities (the caller updates it before :meth:`update`,
                every step or every ``mocap_period`` steps).
            mocap_period: physics steps between the tracker's updates (a predictor's period).
                Its velocities are then backward differences over the period, off by up to
                ``A h (period + 1) / 2`` from the next step's discrete velocity, the allowance
                the predictor makes (``Predictor``): for spheres of mocap trees the
                discrepancy bound is ``D + A h (period - 1) / 2``, and it is checked only at
                the step after a tracker update (the hypothesis at a prediction instant; in
                between the tracker's velocities are stale by design).
            rtol: relative tolerance on every comparison.
            max_violations: how many violations :attr:`violations` keeps (the first ones);
                :attr:`nviolations` counts them all and :attr:`worst` keeps the largest of each
                body and kind, so that a long run whose bounds break every step (a driven mocap
                body, say) holds O(bodies) memory, not O(steps).
            screen: Measure only the spheres of bodies that a screen in O(1) a body cannot
                clear (``PointMotion``'s ``screen``): the same violations, a fraction of the
                work when most bodies keep well inside their bounds.
        """
        if bounds.accel.shape != (model.nbody,):
            raise InvalidInputError("bounds were made for a model with a different nbody.")
        sgeom, sbody, soff = default_spheres(model) if spheres is None else spheres
        self._sgeom = np.asarray(sgeom, dtype=np.int64)
        self._sbody = np.asarray(sbody, dtype=np.int64)
        self._soff = np.asarray(soff, dtype=np.float64).reshape(-1, 3)
        n = self._sgeom.shape[0]
        if self._sbody.shape != (n,) or self._soff.shape != (n, 3):
            raise InvalidInputError(
                f"spheres: sphere_geom {self._sgeom.shape}, sphere_body {self._sbody.shape} and "
                f"sphere_offset {self._soff.shape} must have shapes (n,), (n,), (n, 3)."
            )
        if n and not (
            0 <= self._sgeom.min() <= self._sgeom.max() < model.ngeom
            and 0 <= self._sbody.min() <= self._sbody.max() < model.nbody
        ):
            raise InvalidInputError(
                f"spheres: geom ids must lie in [0, {model.ngeom}) and body ids in "
                f"[0, {model.nbody}); got geoms [{self._sgeom.min()}, {self._sgeom.max()}] and "
                f"bodies [{self._sbody.min()}, {self._sbody.max()}]."
            )
        self._bounds = bounds
        self._mocap = mocap
        self._rtol = rtol
        self._nbody = model.nbody
        self._ngeom = model.ngeom
        mocap_period = check_int("mocap_period", mocap_period)
        in_tree = np.zeros(model.nbody, dtype=bool)
        if mocap is not None:
            in_tree[mocap.mocap_bodies] = True
        mocap_sphere = in_tree[np.asarray(model.body_rootid)][self._sbody]
        # A tracker updated every period lags by up to A h (period - 1) / 2 (see above).
        self._A = bounds.accel[self._sbody]
        lag = self._A * float(model.opt.timestep) * (mocap_period - 1) / 2
        self._D = bounds.discrepancy[self._sbody] + np.where(mocap_sphere, lag, 0)
        self._points = PointMotion(
            pack_spheres(self._sgeom, self._sbody, self._soff, model.body_rootid),
            self._A,
            self._D,
            None if bounds.speed is None else bounds.speed[self._sbody],
            rtol,
            screen=screen,
        )
        # Which spheres' discrepancy to check: all, or (after a step without a tracker update)
        # all but the mocap trees'.
        self._check_all = np.ones(n, dtype=np.bool_)
        self._check_fresh = ~mocap_sphere
        self._mocap_updates = -1
        self._prev_fresh = True
        self._twist = np.zeros((model.nbody, 6))  # no mocap tracker: no twist
        self._prev_t = 0.0
        self.violations: list[BoundViolation] = []
        """The first ``max_violations`` violations, in order."""
        self.nviolations = 0
        """Every violation so far (body-updates)."""
        self.worst: dict[tuple[int, str], BoundViolation] = {}
        """The largest violation of each ``(body, kind)`` so far."""
        self.nupdates = 0
        """Updates so far."""
        self._max_violations = int(max_violations)
        # Runs [start, stop) of consecutive updates that broke a bound: O(runs), not O(steps).
        self._broken_runs: list[list[int]] = []

    def _flag(self, kind: str, mask: np.ndarray, values: np.ndarray, t: float) -> np.ndarray:
        """Record violations of ``kind`` for spheres in ``mask``; return the body ids."""
        if not mask.any():
            return np.zeros(0, dtype=np.int64)
        bodies = self._sbody[mask]
        worst = np.full(self._nbody, -np.inf)
        np.maximum.at(worst, bodies, values[mask])
        ub = np.unique(bodies)
        bound = getattr(self._bounds, kind)
        for b in ub.tolist():
            v = BoundViolation(self.nupdates, t, b, kind, float(worst[b]), float(bound[b]))
            if len(self.violations) < self._max_violations:
                self.violations.append(v)
            top = self.worst.get((b, kind))
            if top is None or v.value > top.value:
                self.worst[(b, kind)] = v
        self.nviolations += int(ub.size)
        return ub

    def update(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """Check the step that produced ``data`` (right after ``mj_step``); return the ``(k,)``
        sorted ids of the bodies that broke a bound at it (empty if none)."""
        if data.geom_xpos.shape[0] != self._ngeom or data.cvel.shape[0] != self._nbody:
            raise InvalidInputError(
                f"data has {data.geom_xpos.shape[0]} geoms and {data.cvel.shape[0]} bodies but "
                f"the monitor was made for {self._ngeom} and {self._nbody}: pass the MjData of "
                "its model."
            )
        # The discrepancy compares this step's discrete velocity with the velocities read at the
        # previous update: for mocap trees those are fresh only if the tracker had just updated.
        check = self._check_all if self._prev_fresh else self._check_fresh
        twist = self._twist
        if self._mocap is not None and self._mocap.mocap_bodies.size:
            twist = self._mocap.twist
            self._prev_fresh = self._mocap.nupdates != self._mocap_updates
            self._mocap_updates = self._mocap.nupdates
        t = float(data.time)
        h = t - self._prev_t
        if h <= 0:
            h = float(model.opt.timestep)
        nbroken = self._points.update(data, twist, h, check)
        self._prev_t = t
        if nbroken == 0:
            self.nupdates += 1
            return np.zeros(0, dtype=np.int64)
        p = self._points
        found = [
            self._flag(kind, p.broken[:, col], p.values[:, col], t)
            for kind, col in (
                ("speed", p.SPEED),
                ("discrepancy", p.DISCREPANCY),
                ("accel", p.ACCEL),
            )
        ]
        out = np.unique(np.concatenate(found))
        runs = self._broken_runs
        if runs and runs[-1][1] == self.nupdates:
            runs[-1][1] += 1
        else:
            runs.append([self.nupdates, self.nupdates + 1])
        self.nupdates += 1
        return out.astype(np.int64)

    @property
    def held(self) -> list[bool]:
        """Per update: True when no bound was broken at that update (built when read)."""
        held = [True] * self.nupdates
        for start, stop in self._broken_runs:
            held[start:stop] = [False] * (stop - start)
        return held

    def bounds_held(self, start: int = 0, stop: int | None = None) -> bool:
        """Whether no bound was broken at updates ``start`` .. ``stop - 1`` (O(log runs))."""
        stop = self.nupdates if stop is None else min(stop, self.nupdates)
        if start >= stop:
            return True
        # The last run starting before ``stop`` is the only one that can reach into the window.
        k = bisect.bisect_left(self._broken_runs, [stop]) - 1
        return k < 0 or self._broken_runs[k][1] <= start
