"""``PairUniverse``: the sphere pairs a predictor knows, with every table the step reads of them.

An all-pairs predictor knows every active pair from the start (``filter.active_geom_pairs``,
O(ngeom^2), fine for the few hundred geoms it is chosen for). A pruned predictor starts from the
pairs it must always hold (each sphere-covered geom against the planes and static shapes, and
the ``<pair>`` elements); its native runtime learns the rest as candidates bring them in: the
geom pairs of candidate sphere pairs it does not know yet are put to MuJoCo's filter, and the
ones it lets through are appended with their sphere pairs, bounds and exact-level records
(``csrc/src/universe.cc``). Memory and set-up are then O(N + pairs met), not O(N^2)
(docs/many-objects.md). This object builds the first set, and shows the runtime's as it grows:
its tables are then the runtime's arrays, read after each growth, never computed again here.
Appending keeps every id: an alarm's pair id names the same pair for the predictor's life,
and ``version`` counts the appends for those who size arrays by it.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import mujoco
import numpy as np

from dua_mujoco.build.bounds import MotionBounds
from dua_mujoco.build.covering import Covering
from dua_mujoco.build.exact import X_G1, X_G2, X_MODE, ExactLevel, ExactMode, build_exact
from dua_mujoco.build.filter import (
    GeomPairs,
    SpherePairs,
    active_geom_pairs,
    candidate_geom_pairs,
    contacts_enabled,
    explicit_geom_pairs,
    sphere_pairs,
)
from dua_mujoco.build.pairbounds import bounded_pairs
from dua_mujoco.build.pairfilter import (
    FilterTables,
    any_dynamic_pair,
    count_dynamic_pairs,
    dynamic_mask,
)
from dua_mujoco.build.tables import PairTables
from dua_mujoco.core.pairset import (
    PAIR_ACCEL,
    PAIR_DELTA,
    PAIR_EPS,
    PAIR_FIRST,
    PAIR_KIND,
    PAIR_SECOND,
    PAIR_SPEED,
    PairKind,
    PairSet,
    pack_pairs,
)

__all__ = ["PairUniverse"]


class PairUniverse:
    """The known pairs and their tables (see the module docstring).

    Args:
        lazy: Learn pairs from candidates (pruned predictors) instead of knowing all at once.
        exact: ``(exact_below, query_below)`` of the exact level, or None without it.
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
        self._filter = FilterTables.of(model)
        self._counts: tuple[int, int] | None = None
        self.explicit = explicit_geom_pairs(model)
        """The ``<pair>`` elements' geom pairs (known from the start, lazy or not)."""
        if lazy:
            # The pairs held always: every sphere-covered geom against every plane and static
            # shape (O(N x static)), and the <pair> elements.
            moving = np.unique(np.asarray(covering.sphere_geom, dtype=np.int64))
            lone = np.concatenate([covering.plane_geom, covering.shape_geom]).astype(np.int64)
            g1, g2 = np.repeat(moving, lone.size), np.tile(lone, moving.size)
            lo, hi = np.minimum(g1, g2), np.maximum(g1, g2)
            keys = np.unique((lo << 32) | hi)
            lo, hi = keys >> 32, keys & 0xFFFFFFFF
            new = self.explicit.indices_of(lo, hi) < 0
            gp = self.explicit.concat(candidate_geom_pairs(model, self._filter, lo[new], hi[new]))
        else:
            gp = active_geom_pairs(model)
        self._geom_pairs = gp
        self._sphere_pairs: SpherePairs = sphere_pairs(covering, gp)
        self._tables = PairTables.build(model, covering, self._sphere_pairs)
        self._exact: ExactLevel | None = None
        if exact is not None:
            dist = np.asarray(gp.contact_distance)[self._sphere_pairs.geom_pair]
            t = self._tables
            self._exact = build_exact(model, t.geom1, t.geom2, t.kind, dist, *exact)
        self._pair_set: PairSet | None = None
        self._records = np.zeros((0, 0))
        self._runtime: Any = None  # the native runtime that grows these pairs (attach)
        self._version = 0

    # ------------------------------------------------------------------- the first set

    def bind(
        self, bounds: MotionBounds, *, period: int, mocap: Any, shapes: np.ndarray | None
    ) -> None:
        """Give the pairs their bounds (after the pilot): the pair set and packed records."""
        self._pair_set = bounded_pairs(
            self.model, self.covering, self._sphere_pairs, bounds, period=period, mocap=mocap
        )
        if shapes is not None and self.covering.nshape:
            self._pair_set.shapes = shapes
        self._records = pack_pairs(self._pair_set, np.asarray(self.covering.plane_geom))

    def attach(self, runtime: Any) -> None:
        """Follow the pairs ``runtime`` (a ``dua_mujoco._core.Runtime`` made from these
        tables) learns."""
        self._runtime = runtime

    # ------------------------------------------------------------------- the runtime's growth

    def _sync(self) -> None:
        """The tables of the pairs the runtime knows, read from its arrays (one copy a growth)
        when it has learnt pairs since the last look: the records' columns, never computed
        again here. Ids only grow (this runtime never forgets), so the first geom pairs keep
        their ``explicit`` flags."""
        rt = self._runtime
        if rt is None or rt.universe_version == self._version:
            return
        self._version = rt.universe_version
        u = rt.universe()
        rec, gp, contact = u["pairs"], u["geom_pairs"], u["geom_pair_contact"]
        kind = rec[:, PAIR_KIND].astype(np.int8)
        first, second = (rec[:, c].astype(np.int64) for c in (PAIR_FIRST, PAIR_SECOND))
        halfspace, eps = kind == int(PairKind.HALFSPACE), rec[:, PAIR_EPS]
        explicit = np.zeros(gp.shape[0], dtype=bool)
        explicit[: self._geom_pairs.npair] = self._geom_pairs.explicit
        margin, gap = contact[:, 0], contact[:, 1]
        self._geom_pairs = GeomPairs(
            gp[:, 0].astype(np.int32),
            gp[:, 1].astype(np.int32),
            explicit,
            margin,
            gap,
            margin + gap,
        )
        self._sphere_pairs = SpherePairs(
            first.astype(np.int32),
            second.astype(np.int32),
            halfspace,
            u["pair_geom"].astype(np.int32),
            eps,
            kind == int(PairKind.SHAPE),
        )
        names = self._tables.geom_names
        self._tables = PairTables(first, second, halfspace, u["geom1"], u["geom2"], names, kind)
        if self._exact is not None:
            self._exact = dataclasses.replace(self._exact, records=u["exact"])
        self._records = rec
        if self._pair_set is not None:
            self._pair_set = PairSet(
                first,
                second,
                eps,
                rec[:, PAIR_ACCEL],
                kind=kind,
                vel_uncertainty=rec[:, PAIR_DELTA],
                speed=rec[:, PAIR_SPEED],
                shapes=self._pair_set.shapes,
            )

    @property
    def version(self) -> int:
        """Appends so far (the runtime's count)."""
        return 0 if self._runtime is None else int(self._runtime.universe_version)

    @property
    def geom_pairs(self) -> GeomPairs:
        """The known geom pairs (ids stable; sorted only when not lazy)."""
        self._sync()
        return self._geom_pairs

    @property
    def sphere_pairs(self) -> SpherePairs:
        """Their sphere pairs, grouped by geom pair."""
        self._sync()
        return self._sphere_pairs

    @property
    def tables(self) -> PairTables:
        """Sphere pair ids to geoms."""
        self._sync()
        return self._tables

    @property
    def exact(self) -> ExactLevel | None:
        """The exact level's tables (None when off), its records as built (the runtime keeps
        the directions it learns in its own copy)."""
        self._sync()
        return self._exact

    @property
    def pair_set(self) -> PairSet | None:
        """The known pairs with their bounds (after :meth:`bind`)."""
        self._sync()
        return self._pair_set

    @property
    def records(self) -> np.ndarray:
        """``(npair, 8)`` packed records of the known pairs (``pack_pairs``)."""
        self._sync()
        return self._records

    @property
    def npair(self) -> int:
        """Known sphere pairs."""
        return int(self.sphere_pairs.npair)

    def exact_geoms(self) -> np.ndarray:
        """The geoms the exact level may ever read (their corners are bound points): those of
        the known pairs, and in a lazy universe every sphere-covered and static shape geom."""
        assert self._exact is not None
        rec = self._exact.records
        used = rec[rec[:, X_MODE] != ExactMode.NONE]
        geoms = [used[:, X_G1], used[:, X_G2]]
        if self.lazy:
            geoms += [self.covering.sphere_geom, self.covering.shape_geom]
        return np.unique(np.concatenate(geoms).astype(np.int64))

    # ------------------------------------------------------------------- counts

    def empty(self) -> bool:
        """Whether no geom pair of the model can ever collide (stops at the first that can)."""
        if self._geom_pairs.npair or not self.lazy:
            return self._geom_pairs.npair == 0
        return not (contacts_enabled(self.model) and any_dynamic_pair(self._filter))

    def counts(self) -> tuple[int, int]:
        """``(geom pairs, sphere pairs)`` MuJoCo's filter lets through in the whole model,
        known or not (a lazy universe counts them once, O(ngeom^2) time, nothing held)."""
        if not self.lazy:
            return self._geom_pairs.npair, self._sphere_pairs.npair
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
