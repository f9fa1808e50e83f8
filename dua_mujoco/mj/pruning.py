"""Pruned sphere pairs for the MuJoCo ``Predictor``: grid candidates within MuJoCo's pair filter.

The filter (``mj/filter.py``) is exact: only sphere pairs of geom pairs MuJoCo could put in
contact are ever held. A pruned predictor holds, of those, the half-space and static-shape
pairs (a plane is infinite; shapes never move) and the sphere pairs among the candidates of
``neighbors.candidate_pairs`` at a horizon ``T``, and renews that set every
``pruned.rebuild_stride(T, dt, latency)`` steps (docs/many-objects.md, which proves this keeps
the guarantee). The intersection is a binary search of the candidates' keys in the sorted keys
of the active sphere pairs, O(K log M) a rebuild.
"""

from __future__ import annotations

import numpy as np

from dua_mujoco.core.neighbors import candidate_pairs, reach
from dua_mujoco.core.pruned import rebuild_stride
from dua_mujoco.core.spheres import AUTO_PRUNED_MIN, DEFAULT_STRIDE, PairMode
from dua_mujoco.exceptions import InvalidChoiceError, InvalidInputError
from dua_mujoco.mj.bounds import MotionBounds
from dua_mujoco.mj.covering import Covering
from dua_mujoco.mj.filter import SpherePairs

__all__ = ["HeldPairs", "held_pairs_for"]


class HeldPairs:
    """Which active sphere pairs a pruned predictor holds, from the spheres' states.

    Args:
        sphere_pairs: The model's active sphere pairs (ids into them are what alarms report).
        radius: ``(nsphere,)`` covering sphere radii.
        accel: ``(nsphere,)`` bound on each sphere centre's acceleration norm.
        vel_uncertainty: ``(nsphere,)`` bound on each sphere's velocity error.
        speed: ``(nsphere,)`` speed bound of each sphere (``inf``: none).
        horizon: The reach's horizon ``T`` (s).
    """

    def __init__(
        self,
        sphere_pairs: SpherePairs,
        radius: np.ndarray,
        accel: np.ndarray,
        vel_uncertainty: np.ndarray,
        speed: np.ndarray,
        horizon: float,
    ) -> None:
        sp = sphere_pairs
        self.nsphere = int(radius.shape[0])
        self.radius, self.accel = radius, accel
        self.vel_uncertainty, self.speed = vel_uncertainty, speed
        self.horizon = float(horizon)
        # Pairs against a plane or a static shape are always held: their second member is no
        # sphere with a reach (a plane is unbounded; shapes are few and never move).
        kind = np.asarray(sp.kind)
        self.always_ids = np.flatnonzero(kind != 0).astype(np.int64)
        ss = np.flatnonzero(kind == 0)
        a = np.asarray(sp.first, dtype=np.int64)[ss]
        b = np.asarray(sp.second, dtype=np.int64)[ss]
        codes = np.minimum(a, b) * self.nsphere + np.maximum(a, b)
        order = np.argsort(codes, kind="stable")
        self.codes = codes[order]
        self.code_ids = ss[order].astype(np.int64)
        # A geom pair's contact distance (margin, gap) beyond the radii: the candidates' margin
        # must cover the largest, so no active pair that could come within it is left out.
        extra = np.asarray(sp.eps)[ss] - radius[a] - radius[b]
        self.margin = float(max(0.0, extra.max(initial=0.0)))

    def select(self, centers: np.ndarray, velocities: np.ndarray) -> np.ndarray:
        """``(K,)`` sorted ids of the sphere pairs to hold from this state."""
        r = reach(
            self.radius,
            np.sqrt(np.einsum("ij,ij->i", velocities, velocities)),
            self.accel,
            self.horizon,
            vel_uncertainty=self.vel_uncertainty,
            speed_bound=self.speed,
        )
        cand = candidate_pairs(centers, r, margin=self.margin)
        key = cand[:, 0] * self.nsphere + cand[:, 1]
        if self.codes.size == 0:
            return self.always_ids.copy()
        pos = np.minimum(np.searchsorted(self.codes, key), self.codes.size - 1)
        found = self.code_ids[pos[self.codes[pos] == key]]
        return np.sort(np.concatenate([self.always_ids, found]))


def held_pairs_for(
    pairs: PairMode | str,
    horizon: float | None,
    *,
    deadline: bool,
    sphere_pairs: SpherePairs,
    covering: Covering,
    bounds: MotionBounds,
    delta: np.ndarray,
    dt: float,
    latency: int,
) -> tuple[HeldPairs | None, int]:
    """What ``Predictor(pairs=..., horizon=...)`` holds: ``(HeldPairs or None, stride)``.

    ``"auto"`` prunes from ``AUTO_PRUNED_MIN`` spheres with the deadline schedule; ``"all"``
    holds every pair (``None``, stride 0). ``delta``: ``(nbody,)`` velocity uncertainties.
    """
    try:
        mode = PairMode(pairs)
    except ValueError:
        raise InvalidChoiceError("pairs", pairs, [m.value for m in PairMode]) from None
    if mode is PairMode.AUTO:
        big = covering.nsphere >= AUTO_PRUNED_MIN
        mode = PairMode.PRUNED if big and deadline else PairMode.ALL
    if mode is PairMode.ALL:
        if horizon is not None:
            raise InvalidInputError(
                f"horizon = {horizon!r} is given but pairs='all': pass pairs='pruned'."
            )
        return None, 0
    if not deadline:
        raise InvalidInputError(
            "pairs='pruned' needs the deadline schedule: pruned pairs are rebuilt into it "
            "only; pass schedule='deadline'."
        )
    T = (DEFAULT_STRIDE + latency) * dt if horizon is None else horizon
    body = np.asarray(covering.sphere_body, dtype=np.int64)
    speed = np.full(body.shape, np.inf) if bounds.speed is None else bounds.speed[body]
    held = HeldPairs(
        sphere_pairs, covering.sphere_radius, bounds.accel[body], delta[body], speed, float(T)
    )
    return held, rebuild_stride(T, dt, latency)
