"""What a ``Predictor`` tells about itself: sizes, the held pairs, the static shapes, and the
bodies whose bounds broke. Read-only views, kept apart from the predictor's protocol."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from dua_mujoco.core.pairset import PairSet
from dua_mujoco.core.schedules import Scheduler
from dua_mujoco.exceptions import SchedulerError
from dua_mujoco.mj.covering import Covering
from dua_mujoco.mj.events import EventTable
from dua_mujoco.mj.exact import ExactLevel
from dua_mujoco.mj.filter import GeomPairs, SpherePairs
from dua_mujoco.mj.tables import PairTables
from dua_mujoco.mj.universe import PairUniverse

__all__ = ["PredictorViews"]


class PredictorViews:
    """The introspection half of :class:`~dua_mujoco.mj.predictor.Predictor`."""

    covering: Covering
    universe: PairUniverse
    _held: object | None
    scheduler: Scheduler | None
    events: EventTable | None
    _ids: np.ndarray
    _shapes: np.ndarray
    _spheres: np.ndarray

    @property
    def geom_pairs(self) -> GeomPairs:
        """The known active geom pairs (all of them unless pruned: ``universe``)."""
        return self.universe.geom_pairs

    @property
    def sphere_pairs(self) -> SpherePairs:
        """The known sphere pairs, grouped by geom pair."""
        return self.universe.sphere_pairs

    @property
    def tables(self) -> PairTables:
        """Sphere pair ids to geoms and names."""
        return self.universe.tables

    @property
    def exact(self) -> ExactLevel | None:
        """The exact level's tables (None when off)."""
        return self.universe.exact

    @property
    def pair_set(self) -> PairSet:
        """The known pairs with their bounds."""
        assert self.universe.pair_set is not None
        return self.universe.pair_set

    @property
    def _pair_records(self) -> np.ndarray:
        return self.universe.records

    @property
    def pair_records(self) -> np.ndarray:
        """``(nsphere_pairs, 8)`` packed records of the known sphere pairs (``pack_pairs``)."""
        return self.universe.records

    @property
    def sphere_records(self) -> np.ndarray:
        """``(nsphere, 8)`` packed records of the covering spheres (``pack_spheres``)."""
        return self._spheres

    @property
    def _on(self) -> np.ndarray | None:
        return self.universe.on if self._held is not None else None

    def _require_scheduler(self) -> Scheduler:
        if self.scheduler is None:
            raise SchedulerError("call predictor.reset(data) first.")
        return self.scheduler

    @property
    def held_pairs(self) -> np.ndarray:
        """``(K,)`` id among all active sphere pairs of each of the scheduler's pairs."""
        return self._ids

    @property
    def nsphere(self) -> int:
        """Number of covering spheres."""
        return int(self.covering.nsphere)

    @property
    def nsphere_pairs(self) -> int:
        """Number of sphere pairs (the scheduler's pairs)."""
        return len(self.pair_set)

    @property
    def evaluations_per_step(self) -> int:
        """tau evaluations of the latest step (``dua``: the slots handed out a step)."""
        return self._require_scheduler().evaluations_per_step

    @property
    def shape_records(self) -> np.ndarray:
        """``(nshape, 16)`` records of the static shapes (``core.shapes``), as of ``reset``."""
        return self._shapes

    @property
    def sphere_pair_geoms(self) -> tuple[np.ndarray, np.ndarray]:
        """``(geom1, geom2)``, each ``(nsphere_pairs,)``: the geoms of every sphere pair
        (``geom2`` is the plane geom of half-space pairs, the static geom of shape pairs)."""
        return self.tables.geom1, self.tables.geom2

    def geom_pair_of(self, pairs: npt.ArrayLike) -> np.ndarray:
        """Index into ``geom_pairs`` of sphere pairs."""
        return np.asarray(self.sphere_pairs.geom_pair[np.asarray(pairs, dtype=np.int64)])

    @property
    def violated_bodies(self) -> np.ndarray:
        """``(k,)`` ids of the bodies whose motion broke their bounds over the latest step's
        period: every pair of theirs was evaluated again at that step (empty when
        ``violation_events`` is off)."""
        self._require_scheduler()
        return np.zeros(0, dtype=np.int64) if self.events is None else self.events.violated

    @property
    def violation_events(self) -> int:
        """Body-steps whose bounds broke since the reset, as the step saw them."""
        self._require_scheduler()
        return 0 if self.events is None else self.events.total
