"""Pruned sphere pairs for the MuJoCo ``Predictor``: grid candidates within MuJoCo's pair filter.

The filter (``mj/filter.py``) is exact: only sphere pairs of geom pairs MuJoCo could put in
contact are ever held. A pruned predictor holds the half-space and static-shape pairs (a plane
is infinite; shapes never move), the ``<pair>`` elements' pairs among the candidates, and the
sphere pairs among the candidates of ``neighbors.candidate_pairs`` at a horizon ``T``; it renews
that set every ``pruned.rebuild_stride(T, dt, latency)`` steps (docs/many-objects.md, which
proves this keeps the guarantee). Candidates the predictor has not met yet are put to MuJoCo's
filter and learnt by its ``PairUniverse``: O(candidates) a rebuild, never O(N^2).
"""

from __future__ import annotations

import numpy as np

from dua_mujoco.core.neighbors import candidate_pairs, reach
from dua_mujoco.core.pruned import rebuild_stride
from dua_mujoco.core.spheres import AUTO_PRUNED_MIN, DEFAULT_STRIDE, PairMode
from dua_mujoco.exceptions import InvalidChoiceError, InvalidInputError
from dua_mujoco.mj.bounds import MotionBounds
from dua_mujoco.mj.covering import Covering
from dua_mujoco.mj.filter import contact_distance_bound
from dua_mujoco.mj.universe import PairUniverse

__all__ = ["HeldPairs", "held_pairs_for", "resolve_pair_mode"]


class HeldPairs:
    """Which sphere pairs a pruned predictor holds, from the spheres' states.

    Args:
        universe: The predictor's known pairs (a lazy one: candidates it lacks are learnt).
        radius: ``(nsphere,)`` covering sphere radii.
        accel: ``(nsphere,)`` bound on each sphere centre's acceleration norm.
        vel_uncertainty: ``(nsphere,)`` bound on each sphere's velocity error.
        speed: ``(nsphere,)`` speed bound of each sphere (``inf``: none).
        horizon: The reach's horizon ``T`` (s).
        margin: The largest contact distance of any geom pair beyond the radii: candidates
            within it of each other are looked at, so no pair that could come within its own
            contact distance is left out.
    """

    def __init__(
        self,
        universe: PairUniverse,
        radius: np.ndarray,
        accel: np.ndarray,
        vel_uncertainty: np.ndarray,
        speed: np.ndarray,
        horizon: float,
        margin: float,
    ) -> None:
        self.universe = universe
        self.nsphere = int(radius.shape[0])
        self.radius, self.accel = radius, accel
        self.vel_uncertainty, self.speed = vel_uncertainty, speed
        self.horizon = float(horizon)
        self.margin = float(margin)
        self.always_ids = np.zeros(0, dtype=np.int64)
        self.codes = np.zeros(0, dtype=np.int64)
        self.code_ids = np.zeros(0, dtype=np.int64)
        self._indexed = 0
        # The state the latest selection assumed: each centre and measured speed.
        self.anchor = np.zeros((self.nsphere, 3))
        self.speed0 = np.zeros(self.nsphere)
        body = np.asarray(universe.covering.sphere_body, dtype=np.int64)
        self._by_body = np.argsort(body, kind="stable")
        nbody = int(universe.model.nbody)
        self._body_start = np.searchsorted(body[self._by_body], np.arange(nbody + 1))

    def _index(self) -> None:
        """Index the pairs the universe learnt since the last call (O(new + known))."""
        sp = self.universe.sphere_pairs
        if self._indexed == sp.npair:
            return
        new = np.arange(self._indexed, sp.npair, dtype=np.int64)
        kind = np.asarray(sp.kind)[new]
        # Pairs against a plane or a static shape are always held: their second member is no
        # sphere with a reach (a plane is unbounded; shapes are few and never move).
        self.always_ids = np.concatenate([self.always_ids, new[kind != 0]])
        ss = new[kind == 0]
        a = np.asarray(sp.first, dtype=np.int64)[ss]
        b = np.asarray(sp.second, dtype=np.int64)[ss]
        codes = np.concatenate([self.codes, np.minimum(a, b) * self.nsphere + np.maximum(a, b)])
        ids = np.concatenate([self.code_ids, ss])
        order = np.argsort(codes, kind="stable")
        self.codes, self.code_ids = codes[order], ids[order]
        self._indexed = sp.npair

    def _lookup(self, key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Ids of the known sphere pairs with codes ``key``, and which keys are unknown."""
        if self.codes.size == 0:
            return np.zeros(0, dtype=np.int64), np.ones(key.shape, dtype=bool)
        pos = np.minimum(np.searchsorted(self.codes, key), self.codes.size - 1)
        hit = self.codes[pos] == key
        return self.code_ids[pos[hit]], ~hit

    def select(self, centers: np.ndarray, velocities: np.ndarray) -> np.ndarray:
        """``(K,)`` sorted ids of the sphere pairs to hold from this state (learning the
        candidates' geom pairs the universe lacks)."""
        self._index()
        self.anchor = np.array(centers, dtype=np.float64)
        self.speed0 = np.sqrt(np.einsum("ij,ij->i", velocities, velocities))
        r = reach(
            self.radius,
            self.speed0,
            self.accel,
            self.horizon,
            vel_uncertainty=self.vel_uncertainty,
            speed_bound=self.speed,
        )
        cand = candidate_pairs(centers, r, margin=self.margin)
        key = cand[:, 0] * self.nsphere + cand[:, 1]
        found, unknown = self._lookup(key)
        if unknown.any():
            geom = np.asarray(self.universe.covering.sphere_geom, dtype=np.int64)
            if self.universe.learn(geom[cand[unknown, 0]], geom[cand[unknown, 1]]):
                self._index()
                found, _ = self._lookup(key)
        return np.sort(np.concatenate([self.always_ids, found]))

    def spheres_of(self, bodies: np.ndarray) -> np.ndarray:
        """``(k,)`` the covering spheres of ``bodies``."""
        lo, hi = self._body_start[bodies], self._body_start[np.asarray(bodies) + 1]
        parts = [self._by_body[a:b] for a, b in zip(lo.tolist(), hi.tolist(), strict=True)]
        return np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)

    def escaped(
        self, spheres: np.ndarray, centers: np.ndarray, velocities: np.ndarray, elapsed: float
    ) -> bool:
        """Whether spheres ``spheres``, ``elapsed`` seconds after the latest selection, may
        leave the reach it assumed (docs/theory.md, section 6): a centre farther from its
        anchor than ``min((s0 + delta) t + A t^2 / 2, V t)``, or a measured speed above
        ``min(s0 + A t, V - delta)``. Neither: whatever broke their bounds before, they stay
        within that reach while the bounds hold from now on, and the pairs left out stay out.

        Args:
            spheres: ``(k,)`` sphere ids.
            centers: ``(k, 3)`` their centres now.
            velocities: ``(k, 3)`` their measured velocities now.
            elapsed: Seconds since the selection.
        """
        t = float(elapsed)
        s0, a = self.speed0[spheres], self.accel[spheres]
        d, v_max = self.vel_uncertainty[spheres], self.speed[spheres]
        allow = (s0 + d) * t + 0.5 * a * t * t
        bounded = np.isfinite(v_max)
        allow = np.where(bounded, np.minimum(allow, np.where(bounded, v_max, 0.0) * t), allow)
        top = np.minimum(s0 + a * t, v_max - d)
        dist = np.linalg.norm(centers - self.anchor[spheres], axis=1)
        speed = np.linalg.norm(velocities, axis=1)
        # Rounding: positions scale with their magnitude, speeds with the bound.
        tol = 1e-9 * (allow + np.abs(top)) + 1e-12 * np.abs(centers).max(axis=1, initial=1.0)
        return bool(np.any(dist > allow + tol) or np.any(speed > top + tol))


def resolve_pair_mode(
    pairs: PairMode | str, horizon: float | None, *, deadline: bool, covering: Covering
) -> PairMode:
    """``Predictor(pairs=..., horizon=...)``'s mode, ``ALL`` or ``PRUNED``: ``"auto"`` prunes
    from ``AUTO_PRUNED_MIN`` spheres with the deadline schedule."""
    try:
        mode = PairMode(pairs)
    except ValueError:
        raise InvalidChoiceError("pairs", pairs, [m.value for m in PairMode]) from None
    if mode is PairMode.AUTO:
        big = covering.nsphere >= AUTO_PRUNED_MIN
        mode = PairMode.PRUNED if big and deadline else PairMode.ALL
    if mode is PairMode.ALL and horizon is not None:
        raise InvalidInputError(
            f"horizon = {horizon!r} is given but pairs='all': pass pairs='pruned'."
        )
    if mode is PairMode.PRUNED and not deadline:
        raise InvalidInputError(
            "pairs='pruned' needs the deadline schedule: pruned pairs are rebuilt into it "
            "only; pass schedule='deadline'."
        )
    return mode


def held_pairs_for(
    universe: PairUniverse,
    horizon: float | None,
    *,
    bounds: MotionBounds,
    delta: np.ndarray,
    dt: float,
    latency: int,
) -> tuple[HeldPairs, int]:
    """A pruned predictor's ``(HeldPairs, stride)``. ``delta``: ``(nbody,)`` velocity
    uncertainties."""
    covering = universe.covering
    T = (DEFAULT_STRIDE + latency) * dt if horizon is None else horizon
    body = np.asarray(covering.sphere_body, dtype=np.int64)
    speed = np.full(body.shape, np.inf) if bounds.speed is None else bounds.speed[body]
    held = HeldPairs(
        universe,
        covering.sphere_radius,
        bounds.accel[body],
        delta[body],
        speed,
        float(T),
        contact_distance_bound(universe.model, universe.explicit),
    )
    return held, rebuild_stride(T, dt, latency)
