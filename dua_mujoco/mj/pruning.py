"""Pruned sphere pairs for the MuJoCo ``Predictor``: grid candidates within MuJoCo's pair filter.

The filter (``mj/filter.py``) is exact: only sphere pairs of geom pairs MuJoCo could put in
contact are ever held. A pruned predictor holds the half-space and static-shape pairs (a plane
is infinite; shapes never move), the ``<pair>`` elements' pairs among the candidates, and the
sphere pairs among the candidates of ``neighbors.candidate_pairs`` at a horizon ``T``; it rebuilds
that set every ``pruned.rebuild_stride(T, dt, latency)`` steps, and in between renews the pairs
of the spheres an impact may have let out of their reach (:meth:`HeldPairs.renew`; the proofs:
docs/many-objects.md and docs/theory.md, Lemmas 6.4 and 6.5). Candidates the predictor has not
met yet are put to MuJoCo's filter and learnt by its ``PairUniverse``: O(candidates) a rebuild,
never O(N^2). The kernels (the grid, the escape check, the renewal) are the native core's,
which the MuJoCo plugin's pruned pairs run too.
"""

from __future__ import annotations

import ctypes
import functools
from typing import Any

import numpy as np
import numpy.typing as npt

from dua_mujoco.core.neighbors import candidate_pairs, reach
from dua_mujoco.core.pruned import rebuild_stride
from dua_mujoco.core.spheres import AUTO_PRUNED_MIN, DEFAULT_STRIDE, PairMode
from dua_mujoco.exceptions import InvalidChoiceError, InvalidInputError
from dua_mujoco.mj.bounds import MotionBounds
from dua_mujoco.mj.covering import Covering
from dua_mujoco.mj.filter import SpherePairs, contact_distance_bound
from dua_mujoco.mj.native_step import NativeStep
from dua_mujoco.mj.universe import PairUniverse
from dua_mujoco.native import declare

__all__ = ["RENEW_MAX", "HeldPairs", "held_pairs_for", "resolve_pair_mode"]

RENEW_MAX = 512
"""Most escaped spheres a step renews alone (``HeldPairs.renew``: ``k N`` pair tests, ~1.1 ns
each); more, and the whole held set is rebuilt (O(N + K), ~1 us a sphere on swarms), so that
a renewal costs at most about half a rebuild at any ``N`` (measured, docs/many-objects.md)."""


class _Reach(ctypes.Structure):
    """``dua_reach`` (dua/dua.h)."""

    _fields_ = [
        ("nsphere", ctypes.c_int64),
        ("radius", ctypes.c_void_p),
        ("body_start", ctypes.c_void_p),
        ("body_spheres", ctypes.c_void_p),
        ("accel", ctypes.c_void_p),
        ("delta", ctypes.c_void_p),
        ("speed", ctypes.c_void_p),
        ("anchor", ctypes.c_void_p),
        ("speed0", ctypes.c_void_p),
        ("reach", ctypes.c_void_p),
        ("built", ctypes.c_void_p),
        ("dt", ctypes.c_double),
        ("horizon", ctypes.c_double),
        ("margin", ctypes.c_double),
    ]


@functools.cache
def _functions() -> Any:
    """The reach's C functions, their signatures declared once."""
    i8, p = ctypes.c_int64, ctypes.c_void_p
    return declare(
        {
            "dua_escapes": (i8, [p, p, i8, p, p, p, p]),
            "dua_escaped_spheres": (i8, [p, p, i8, p]),
            "dua_renew": (i8, [p, p, p, i8, i8, p, i8]),
        }
    )


def _contiguous(a: npt.ArrayLike, dtype: type) -> np.ndarray:
    # An owned copy: the native struct points at it, and no caller's array is aliased.
    return np.ascontiguousarray(np.array(a, dtype=dtype))


class HeldPairs:
    """Which sphere pairs a pruned predictor holds, from the spheres' states.

    Each sphere has an *anchor*: the centre and measured speed its held pairs were chosen from,
    at step ``built[i]`` (the latest rebuild, or a later renewal of that sphere alone), and the
    reach ``r_i + R_i(T)`` from there. The arrays are the native core's (``dua_reach``): write
    into them, never rebind them.

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
        dt: Seconds a predictor step.
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
        dt: float,
    ) -> None:
        self.universe = universe
        n = self.nsphere = int(radius.shape[0])
        self.radius = _contiguous(radius, np.float64)
        self.accel = _contiguous(accel, np.float64)
        self.vel_uncertainty = _contiguous(vel_uncertainty, np.float64)
        self.speed = _contiguous(speed, np.float64)
        self.horizon = float(horizon)
        self.margin = float(margin)
        self.always_ids = np.zeros(0, dtype=np.int64)
        self.codes = np.zeros(0, dtype=np.int64)
        self.code_ids = np.zeros(0, dtype=np.int64)
        self._indexed = 0
        self.anchor = np.zeros((n, 3))
        self.speed0 = np.zeros(n)
        self.reach = np.zeros(n)
        self.built = np.zeros(n, dtype=np.int64)
        body = np.asarray(universe.covering.sphere_body, dtype=np.int64)
        self._by_body = np.argsort(body, kind="stable").astype(np.int64)
        nbody = int(universe.model.nbody)
        self._body_start = np.searchsorted(body[self._by_body], np.arange(nbody + 1)).astype(
            np.int64
        )
        self._out = np.zeros(max(n, 1), dtype=np.int64)
        self._lib = _functions()
        self._state = _Reach(
            n,
            *(
                a.ctypes.data
                for a in (
                    self.radius,
                    self._body_start,
                    self._by_body,
                    self.accel,
                    self.vel_uncertainty,
                    self.speed,
                    self.anchor,
                    self.speed0,
                    self.reach,
                    self.built,
                )
            ),
            float(dt),
            self.horizon,
            self.margin,
        )
        self._ref = ctypes.byref(self._state)

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

    def _known(self, cand: np.ndarray) -> np.ndarray:
        """``(k,)`` ids of the active sphere pairs among candidate sphere pairs ``cand``
        ``(k, 2)``, ``i < j``, learning the geom pairs the universe lacks."""
        self._index()
        key = cand[:, 0] * self.nsphere + cand[:, 1]
        found, unknown = self._lookup(key)
        if unknown.any():
            geom = np.asarray(self.universe.covering.sphere_geom, dtype=np.int64)
            if self.universe.learn(geom[cand[unknown, 0]], geom[cand[unknown, 1]]):
                self._index()
                found, _ = self._lookup(key)
        return found

    def select(self, centers: np.ndarray, velocities: np.ndarray, step: int) -> np.ndarray:
        """``(K,)`` sorted ids of the sphere pairs to hold from this state, step ``step``
        (every sphere anchored anew; the candidates' geom pairs the universe lacks learnt)."""
        self._index()
        self.anchor[:] = centers
        v = velocities
        # Summed as the native renewal sums it (einsum's order differs in the last bit).
        self.speed0[:] = np.sqrt(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1] + v[:, 2] * v[:, 2])
        self.reach[:] = reach(
            self.radius,
            self.speed0,
            self.accel,
            self.horizon,
            vel_uncertainty=self.vel_uncertainty,
            speed_bound=self.speed,
        )
        self.built[:] = step
        cand = candidate_pairs(self.anchor, self.reach, margin=self.margin)
        return np.sort(np.concatenate([self.always_ids, self._known(cand)]))

    def renew(self, native: NativeStep, spheres: np.ndarray, step: int) -> tuple[np.ndarray, int]:
        """Anchor ``spheres`` ``(k,)`` anew at their state on ``native``'s frame, step ``step``,
        and find the pairs their new reach brings in with any sphere as it stands (O(k N),
        compiled; docs/many-objects.md proves it enough).

        Returns:
            ``(ids, bad)``: the sorted ids of those pairs, and -1, or a sphere whose state is not
            finite (nothing anchored then).
        """
        spheres = _contiguous(spheres, np.int64)
        out = np.zeros((max(4 * spheres.size, 16), 2), dtype=np.int64)
        while True:
            count = self._lib.dua_renew(
                native.address, self._ref, spheres.ctypes.data, spheres.size, step,
                out.ctypes.data, out.shape[0],
            )  # fmt: skip
            if count < 0:
                return np.zeros(0, dtype=np.int64), int(spheres[-1 - count])
            if count <= out.shape[0]:
                break
            out = np.zeros((count, 2), dtype=np.int64)
        return np.unique(self._known(out[:count])), -1

    def escaped(
        self,
        spheres: np.ndarray,
        centers: np.ndarray,
        velocities: np.ndarray,
        elapsed: npt.ArrayLike,
    ) -> np.ndarray:
        """Of ``spheres`` ``(k,)``, ``elapsed`` seconds (scalar or ``(k,)``) after their anchors,
        the ones that may have left the reach it assumed (docs/theory.md, Lemma 6.4): a centre
        farther from its anchor than ``min((s0 + delta) t + A t^2 / 2, V t)``, or a measured
        speed above ``min(s0 + A t, V - delta)``. The others, whatever broke their bounds
        before, stay within that reach while the bounds hold from now on.

        Args:
            spheres: ``(k,)`` sphere ids.
            centers: ``(k, 3)`` their centres now.
            velocities: ``(k, 3)`` their measured velocities now.
            elapsed: Seconds since each one's anchor.
        """
        ids = _contiguous(spheres, np.int64)
        c = _contiguous(centers, np.float64)
        v = _contiguous(velocities, np.float64)
        t = _contiguous(np.broadcast_to(np.asarray(elapsed, dtype=np.float64), ids.shape), float)
        out = np.zeros(max(ids.size, 1), dtype=np.int64)
        count = self._lib.dua_escapes(
            self._ref, ids.ctypes.data, ids.size, c.ctypes.data, v.ctypes.data, t.ctypes.data,
            out.ctypes.data,
        )  # fmt: skip
        return out[:count].copy()

    def escapes(self, native: NativeStep, step: int) -> np.ndarray:
        """The escaped spheres (:meth:`escaped`) of the bodies the latest violation pass of
        ``native`` flagged, read on its frame at step ``step`` (O(their spheres), compiled)."""
        out = self._out
        count = self._lib.dua_escaped_spheres(native.address, self._ref, step, out.ctypes.data)
        return self._out[:count].copy()

    def left_out_since(self, pairs: SpherePairs, ids: np.ndarray) -> np.ndarray:
        """Step since which each sphere pair ``ids`` not held was shown unable to touch: the
        later anchor of its two spheres."""
        first = np.asarray(pairs.first, dtype=np.int64)[ids]
        second = np.asarray(pairs.second, dtype=np.int64)[ids]
        sphere = np.asarray(pairs.kind)[ids] == 0
        other = np.where(sphere, self.built[np.where(sphere, second, 0)], 0)
        return np.maximum(self.built[first], other)


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
        dt,
    )
    return held, rebuild_stride(T, dt, latency)
