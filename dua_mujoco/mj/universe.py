"""``PairUniverse``: the sphere pairs a predictor knows, with every table the step reads of them.

An all-pairs predictor knows every active pair from the start (``filter.active_geom_pairs``,
O(ngeom^2), fine for the few hundred geoms it is chosen for). A pruned predictor starts from the
pairs it must always hold (each sphere-covered geom against the planes and static shapes, and
the ``<pair>`` elements) and learns the rest as candidates bring them in: the geom pairs of
candidate sphere pairs it does not know yet are put to MuJoCo's filter (O(candidates),
``pairfilter``) and the ones it lets through are appended, with their sphere pairs, bounds,
packed records and exact-level records. Memory and set-up are then O(N + pairs met), not
O(N^2) (docs/many-objects.md). Appending keeps every id: an alarm's pair id names the same pair
for the predictor's life, and ``version`` counts the appends for those who size arrays by it.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco.core.pairset import PairSet, pack_pairs
from dua_mujoco.mj.bounds import MotionBounds
from dua_mujoco.mj.covering import Covering
from dua_mujoco.mj.exact import (
    X_G1,
    X_G2,
    X_MODE,
    ExactLevel,
    ExactMode,
    build_exact,
    exact_records,
)
from dua_mujoco.mj.filter import (
    GeomPairs,
    SpherePairs,
    active_geom_pairs,
    appended,
    candidate_geom_pairs,
    contacts_enabled,
    explicit_geom_pairs,
    sphere_pairs,
)
from dua_mujoco.mj.mocap import MocapVelocityTracker
from dua_mujoco.mj.pairbounds import bounded_pairs
from dua_mujoco.mj.pairfilter import (
    FilterTables,
    any_dynamic_pair,
    count_dynamic_pairs,
    dynamic_mask,
)
from dua_mujoco.mj.tables import PairTables

__all__ = ["PairUniverse"]


class PairUniverse:
    """The known pairs and their tables (see the module docstring).

    Args:
        model: The model.
        covering: Its covering.
        lazy: Learn pairs from candidates (pruned predictors) instead of knowing all at once.
        exact: ``(exact_below, query_below)`` of the exact level, or None without it.

    Attributes:
        geom_pairs: The known geom pairs (ids stable; sorted only when not lazy).
        sphere_pairs: Their sphere pairs, grouped by geom pair.
        tables: Sphere pair ids to geoms.
        exact: The exact level's tables (None when off).
        on: ``(npair,)`` bool, each pair's switch (intended contact turns it off).
        version: Appends so far.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        covering: Covering,
        *,
        lazy: bool,
        exact: tuple[float, float] | None,
    ) -> None:
        self.model = model
        self.covering = covering
        self.lazy = lazy
        self._exact_params = exact
        self._filter = FilterTables.of(model)
        self._counts: tuple[int, int] | None = None
        self.version = 0
        self.explicit = explicit_geom_pairs(model)
        """The ``<pair>`` elements' geom pairs (known from the start, lazy or not)."""
        if lazy:
            # The pairs held always: every sphere-covered geom against every plane and static
            # shape (O(N x static)), and the <pair> elements.
            explicit = self.explicit
            moving = np.unique(np.asarray(covering.sphere_geom, dtype=np.int64))
            lone = np.concatenate([covering.plane_geom, covering.shape_geom]).astype(np.int64)
            g1 = np.repeat(moving, lone.size)
            g2 = np.tile(lone, moving.size)
            gp = explicit.concat(self._unknown(explicit, g1, g2))
        else:
            gp = active_geom_pairs(model)
        self.geom_pairs = gp
        self.sphere_pairs: SpherePairs = sphere_pairs(covering, gp)
        self.tables = PairTables.build(model, covering, self.sphere_pairs)
        self.exact: ExactLevel | None = (
            None if exact is None else self._build_exact(self.tables, self.sphere_pairs)
        )
        self.on = np.ones(self.npair, dtype=bool)
        self.pair_set: PairSet | None = None
        self.records = np.zeros((0, 0))

    @property
    def npair(self) -> int:
        """Known sphere pairs."""
        return int(self.sphere_pairs.npair)

    def _build_exact(self, tables: PairTables, pairs: SpherePairs) -> ExactLevel:
        """The exact level of sphere pairs ``pairs`` (their geom pairs known) and ``tables``."""
        assert self._exact_params is not None
        below, query = self._exact_params
        dist = np.asarray(self.geom_pairs.contact_distance)
        return build_exact(
            self.model,
            tables.geom1,
            tables.geom2,
            tables.kind,
            dist[np.asarray(pairs.geom_pair, dtype=np.int64)],
            below,
            query,
        )

    def exact_geoms(self) -> np.ndarray:
        """The geoms the exact level may ever read (their corners are bound points): those of
        the known pairs, and in a lazy universe every sphere-covered and static shape geom."""
        assert self.exact is not None
        rec = self.exact.records
        used = rec[rec[:, X_MODE] != ExactMode.NONE]
        geoms = [used[:, X_G1], used[:, X_G2]]
        if self.lazy:
            geoms += [self.covering.sphere_geom, self.covering.shape_geom]
        return np.unique(np.concatenate(geoms).astype(np.int64))

    def bind(
        self,
        bounds: MotionBounds,
        *,
        period: int,
        mocap: MocapVelocityTracker | None,
        shapes: np.ndarray | None,
    ) -> None:
        """Give the pairs their bounds (after the pilot): the pair set and packed records."""
        self._bounds = (bounds, period, mocap)
        self.pair_set = bounded_pairs(
            self.model, self.covering, self.sphere_pairs, bounds, period=period, mocap=mocap
        )
        if shapes is not None and self.covering.nshape:
            self.pair_set.shapes = shapes
        self.records = pack_pairs(self.pair_set, self._plane_geom())

    def _plane_geom(self) -> np.ndarray:
        return np.asarray(self.covering.plane_geom, dtype=np.int64)

    # ------------------------------------------------------------------- growth

    def _unknown(self, known: GeomPairs, g1: np.ndarray, g2: np.ndarray) -> GeomPairs:
        """Of geom pairs ``(g1, g2)``, the ones MuJoCo's filter lets through and ``known``
        lacks, once each."""
        lo, hi = np.minimum(g1, g2), np.maximum(g1, g2)
        keys = np.unique((lo << 32) | hi)
        lo, hi = keys >> 32, keys & 0xFFFFFFFF
        new = known.indices_of(lo, hi) < 0
        return candidate_geom_pairs(self.model, self._filter, lo[new], hi[new])

    def learn(self, g1: npt.ArrayLike, g2: npt.ArrayLike) -> int:
        """Append the geom pairs ``(g1[k], g2[k])`` the filter lets through and the universe
        lacks (a lazy universe; an eager one knows them all). Returns the sphere pairs added."""
        if not self.lazy:
            return 0
        a = np.asarray(g1, dtype=np.int64).reshape(-1)
        b = np.asarray(g2, dtype=np.int64).reshape(-1)
        new = self._unknown(self.geom_pairs, a, b)
        if new.npair == 0:
            return 0
        base = self.geom_pairs.npair
        sp = sphere_pairs(self.covering, new)
        sp = dataclasses.replace(sp, geom_pair=(sp.geom_pair + base).astype(np.int32))
        self.geom_pairs = self.geom_pairs.concat(new)
        self.sphere_pairs = appended(self.sphere_pairs, sp)
        tables = PairTables.build(self.model, self.covering, sp, self.tables.geom_names)
        self.tables = appended(self.tables, tables, shared=("geom_names",))
        if self.exact is not None:
            dist = np.asarray(self.geom_pairs.contact_distance)[sp.geom_pair]
            rec = exact_records(self.exact.geoms, tables.geom1, tables.geom2, tables.kind, dist)
            records = np.concatenate([self.exact.records, rec])
            self.exact = dataclasses.replace(self.exact, records=records)
        self.on = np.concatenate([self.on, np.ones(sp.npair, dtype=bool)])
        if self.pair_set is not None:
            bounds, period, mocap = self._bounds
            added = bounded_pairs(self.model, self.covering, sp, bounds, period=period, mocap=mocap)
            self.pair_set = _concat_pair_sets(self.pair_set, added)
            self.records = np.concatenate([self.records, pack_pairs(added, self._plane_geom())])
        self.version += 1
        return int(sp.npair)

    def between(self, bodies_a: np.ndarray, bodies_b: np.ndarray | None) -> None:
        """Learn every pair with a geom on ``bodies_a`` and the other on ``bodies_b`` (any
        body when None): a switch must reach the pairs not met yet."""
        if not self.lazy:
            return
        gbody = np.asarray(self.model.geom_bodyid, dtype=np.int64)
        ga = np.flatnonzero(np.isin(gbody, bodies_a))
        gb = np.arange(gbody.size) if bodies_b is None else np.flatnonzero(np.isin(gbody, bodies_b))
        self.learn(np.repeat(ga, gb.size), np.tile(gb, ga.size))

    def empty(self) -> bool:
        """Whether no geom pair of the model can ever collide (stops at the first that can)."""
        if self.geom_pairs.npair or not self.lazy:
            return self.geom_pairs.npair == 0
        return not (contacts_enabled(self.model) and any_dynamic_pair(self._filter))

    def counts(self) -> tuple[int, int]:
        """``(geom pairs, sphere pairs)`` MuJoCo's filter lets through in the whole model,
        known or not (a lazy universe counts them once, O(ngeom^2) time, nothing held)."""
        if not self.lazy:
            return self.geom_pairs.npair, self.npair
        if self._counts is None and not contacts_enabled(self.model):
            self._counts = (0, 0)
        if self._counts is None:
            cov = self.covering
            start = np.asarray(cov.geom_sphere_start, dtype=np.int64)
            weight = start[1:] - start[:-1]
            weight[np.asarray(cov.plane_geom, dtype=np.int64)] = 1
            weight[np.asarray(cov.shape_geom, dtype=np.int64)] = 1
            pairs, spheres = count_dynamic_pairs(self._filter, weight)
            # Active = dynamic + explicit - both (a <pair> on geoms the filter lets through).
            explicit = self.explicit
            w = weight[np.asarray(explicit.geom1, dtype=np.int64)]
            w = w * weight[np.asarray(explicit.geom2, dtype=np.int64)]
            both = dynamic_mask(self._filter, explicit.geom1, explicit.geom2)
            pairs += explicit.npair - int(both.sum())
            spheres += int(w.sum()) - int(w[both].sum())
            self._counts = (pairs, spheres)
        return self._counts


def _concat_pair_sets(a: PairSet, b: PairSet) -> PairSet:
    out = PairSet(
        np.concatenate([a.first, b.first]),
        np.concatenate([a.second, b.second]),
        np.concatenate([a.eps, b.eps]),
        np.concatenate([a.accel, b.accel]),
        kind=np.concatenate([a.kind, b.kind]),
        vel_uncertainty=np.concatenate([a.vel_uncertainty, b.vel_uncertainty]),
        speed=np.concatenate([a.speed, b.speed]),
    )
    if a.shapes is not None:
        out.shapes = a.shapes
    return out
