"""``PairState``: the schedule's per-pair state, indexed by the model's sphere-pair ids.

With ``pairs="all"`` the scheduler holds every active sphere pair and its ids are the model's.
With pruned pairs it holds a subset (``Predictor.held_pairs``, sorted), rebuilt as the spheres
move; a pair it does not hold was shown unable to touch before the next rebuild, so it stands in
no alarm. The exact stage (``Monitor``) reads the state through this view in either case.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from dua_mujoco.core.schedules import Scheduler

__all__ = ["PairState"]


class PairState:
    """The state of every sphere pair of a model (``npairs``), through a scheduler over
    ``held`` of them (``held is None``: all of them, ids equal).

    Args:
        scheduler: The predictor's scheduler.
        npairs: Number of the model's active sphere pairs.
        held: ``(K,)`` sorted pair ids the scheduler holds, or None for all.
        on: ``(npairs,)`` bool, pairs switched on (used when ``held`` is given).
        rebuilds: Rebuilds and renewals of the held set so far (each may change any pair's
            state).
        left_out: Given pair ids not held, the step since which each was shown unable to
            touch (used when ``held`` is given; default 0).
    """

    def __init__(
        self,
        scheduler: Scheduler,
        npairs: int,
        held: np.ndarray | None = None,
        on: np.ndarray | None = None,
        rebuilds: int = 0,
        left_out: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> None:
        self.scheduler = scheduler
        self.npairs = npairs
        self._held = held
        self._on = on
        self.rebuilds = rebuilds
        """Rebuilds and renewals of the held set this view reflects."""
        self._left_out = left_out

    @property
    def step_count(self) -> int:
        """Completed predictor steps."""
        return self.scheduler.step_count

    @property
    def activation_changes(self) -> int:
        """Changes that may alter any pair's state: switches, and rebuilds of the held set."""
        return self.scheduler.activation_changes + self.rebuilds

    @property
    def active(self) -> np.ndarray:
        """``(npairs,)`` bool, pairs switched on."""
        if self._held is None:
            return self.scheduler.active
        assert self._on is not None
        return self._on

    @property
    def last_selected(self) -> np.ndarray:
        """Pair ids whose verdict the latest step renewed."""
        ids = self.scheduler.last_selected
        return ids if self._held is None else self._held[ids]

    def _positions(self, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Scheduler positions of ``ids`` and whether each is held."""
        held = self._held
        assert held is not None
        pos = np.minimum(np.searchsorted(held, ids), max(held.size - 1, 0))
        return pos, (held.size > 0) & (held[pos] == ids)

    def _gather(self, values: np.ndarray, ids: np.ndarray, missing: float | bool) -> np.ndarray:
        pos, found = self._positions(ids)
        out = np.full(ids.shape, missing, dtype=values.dtype)
        out[found] = values[pos[found]]
        return out

    def alarm_state(self, pair: npt.ArrayLike | None = None) -> np.ndarray:
        """Whether each pair stands in alarm (pairs not held never do)."""
        if self._held is None:
            return self.scheduler.alarm_state(pair)
        ids = np.arange(self.npairs) if pair is None else np.asarray(pair, dtype=np.int64)
        if pair is None:
            out = np.zeros(self.npairs, dtype=bool)
            out[self._held] = self.scheduler.alarm_state()
            return out
        return self._gather(self.scheduler.alarm_state(), ids, False)

    def horizon_of(self, pair: np.ndarray) -> np.ndarray:
        """The alarm horizon (seconds) each pair's latest verdict must cover."""
        if self._held is None:
            return self.scheduler.horizon_of(pair)
        pos, found = self._positions(np.asarray(pair, dtype=np.int64))
        out = np.zeros(found.shape)
        out[found] = self.scheduler.horizon_of(pos[found])
        return out

    def last_step_of(self, pair: np.ndarray) -> np.ndarray:
        """Step of each pair's latest evaluation (a pair not held: the step since which it was
        shown unable to touch, by the latest rebuild or a renewal of one of its spheres)."""
        if self._held is None:
            return np.asarray(self.scheduler.last_step[pair])
        ids = np.asarray(pair, dtype=np.int64)
        pos, found = self._positions(ids)
        out = np.zeros(ids.shape, dtype=np.int64)
        out[found] = self.scheduler.last_step[pos[found]]
        if self._left_out is not None and not found.all():
            out[~found] = self._left_out(ids[~found])
        return out

    def last_tau_of(self, pair: np.ndarray) -> np.ndarray:
        """tau of each pair's latest evaluation (a pair not held: ``inf``)."""
        if self._held is None:
            return np.asarray(self.scheduler.last_tau[pair])
        return self._gather(self.scheduler.last_tau, pair, np.inf)
