"""``PairState``: the schedule's per-pair state, indexed by the model's sphere-pair ids.

With ``pairs="all"`` the runtime holds every active sphere pair and its ids are the model's.
With pruned pairs it holds a subset (``Predictor.held_pairs``, sorted), rebuilt as the spheres
move; a pair it does not hold was shown unable to touch before the next rebuild, so it stands in
no alarm. The exact stage (``Monitor``) reads the state through this view in either case; it is
read from the runtime when asked (O(pairs) a call), never kept.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from dua_mujoco import _core
from dua_mujoco._core import LAYOUT
from dua_mujoco.build.universe import PairUniverse
from dua_mujoco.core.pairset import PairKind

__all__ = ["PairState"]

_P_COUNT, _P_DEFERRED = LAYOUT["P_COUNT"], LAYOUT["P_DEFERRED"]
_P_SETTLED, _W_SLOTS = LAYOUT["P_SETTLED"], LAYOUT["W_SLOTS"]
_W_IDS, _LAST_STEP = LAYOUT["W_IDS"], LAYOUT["LAST_STEP"]
_WHERE, _SCREENED = LAYOUT["WHERE"], LAYOUT["SCREENED"]


class PairState:
    """The state of every sphere pair of a predictor's runtime.

    Args:
        runtime: The predictor's ``dua_mujoco._core.Runtime``.
        universe: Its pairs (to name the pairs not held).
        held: ``(nheld,)`` the runtime's held ids (``runtime.ids``) if the caller has them.
    """

    def __init__(
        self, runtime: Any, universe: PairUniverse, *, held: np.ndarray | None = None
    ) -> None:
        self._rt = runtime
        self._universe = universe
        self.scheduler = runtime.schedule
        """The runtime's ``_core.Schedule`` (its ``deferred`` and ``params``)."""
        self.npairs = int(runtime.npair)
        self._held = np.asarray(runtime.ids) if held is None else held
        self._all = self._held.size == self.npairs

    @property
    def step_count(self) -> int:
        """Completed predictor steps since the reset."""
        return int(self._rt.step_count)

    @property
    def activation_changes(self) -> int:
        """Changes that may alter any pair's state: switches, classifications and, with pruned
        pairs, changes of the held set."""
        return int(self.scheduler.activation_changes)

    @property
    def deferred(self) -> int:
        """Pairs due at the latest step but left for a later one (a capped schedule)."""
        return int(self.scheduler.params[_P_DEFERRED]) if self.step_count else 0

    @property
    def settled(self) -> int:
        """Pairs of flagged bodies the latest step settled by a bound from their state instead
        of evaluating them (docs/theory.md, section 6, "Settling a made-due pair")."""
        return int(self.scheduler.params[_P_SETTLED]) if self.step_count else 0

    @property
    def screened(self) -> int:
        """Held pairs on the deadline schedule's screen after the latest step: its reach test
        cleared them (:attr:`cleared`), or they joined it after their evaluation there
        (docs/theory.md, section 3, "The screen")."""
        s = self.scheduler
        return int(np.count_nonzero(s.ints[_WHERE] == _SCREENED)) if s.last_tau.size else 0

    @property
    def active(self) -> np.ndarray:
        """``(npairs,)`` bool, pairs switched on."""
        return np.asarray(self._rt.on)

    def set_active(self, pairs: npt.ArrayLike, on: bool) -> None:
        """Switch model pairs ``pairs`` off or back on (:meth:`Predictor.set_active_bodies` does
        it for a body's pairs). A pair switched back on stands in alarm until the next step
        evaluates it; a pruned pair not held now stays switched for when it is.

        Raises:
            InvalidInputError: A pair id is out of range (the runtime names it).
        """
        self._rt.switch(np.atleast_1d(np.asarray(pairs, dtype=np.int64)).reshape(-1), bool(on))

    @property
    def last_selected(self) -> np.ndarray:
        """Pair ids whose verdict the latest step renewed: the evaluated ones, the ones it
        settled (:attr:`settled`; a verdict from a bound), the ones its screen cleared
        (:attr:`screened`, less those that joined it after their evaluation at this step), then
        the deferred ones (last)."""
        s = self.scheduler
        if self.step_count == 0:
            return np.zeros(0, dtype=np.int64)
        params = s.params
        renewed = int(params[_P_COUNT] + params[_P_DEFERRED])
        ids = s.work[_W_IDS, :renewed]
        count = int(params[_P_COUNT])
        settled = s.work[_W_SLOTS, : int(params[_P_SETTLED])]
        cleared = self._cleared()
        if settled.size or cleared.size:
            ids = np.concatenate([ids[:count], settled, cleared, ids[count:]])
        return np.asarray(self._held[ids])

    @property
    def cleared(self) -> int:
        """Pairs the screen's test cleared at the latest step (a verdict renewed without an
        evaluation; :attr:`screened` less the pairs that joined the screen at that step)."""
        return int(self._cleared().size) if self.step_count else 0

    def _cleared(self) -> np.ndarray:
        """Schedule positions of the pairs the screen's test cleared at the latest step."""
        s = self.scheduler
        if s.last_tau.size == 0:  # no pairs held (the rows are then empty)
            return np.zeros(0, dtype=np.int64)
        on = np.flatnonzero(s.ints[_WHERE] == _SCREENED)
        if on.size == 0:
            return on
        return on[~np.isin(on, s.work[_W_IDS, : int(s.params[_P_COUNT])])]

    def _positions(self, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Schedule positions of model pairs ``ids`` and whether each is held."""
        held = self._held
        if self._all:
            return ids, np.ones(ids.shape, dtype=bool)
        pos = np.minimum(np.searchsorted(held, ids), max(held.size - 1, 0))
        return pos, (held.size > 0) & (held[pos] == ids)

    def _gather(self, values: np.ndarray, ids: np.ndarray, missing: float | bool) -> np.ndarray:
        pos, found = self._positions(ids)
        out = np.full(ids.shape, missing, dtype=values.dtype)
        out[found] = values[pos[found]]
        return out

    def alarm_state(self, pair: npt.ArrayLike | None = None) -> np.ndarray:
        """Whether each pair stands in alarm (pairs not held never do)."""
        s = self.scheduler
        state = np.asarray(_core.stands(s, np.arange(s.last_tau.shape[0], dtype=np.int64)))
        if pair is None:
            if self._all:
                return state
            out = np.zeros(self.npairs, dtype=bool)
            out[self._held] = state
            return out
        return self._gather(state, np.asarray(pair, dtype=np.int64), False)

    def horizon_of(self, pair: npt.ArrayLike) -> np.ndarray:
        """The alarm horizon (seconds) each pair's latest verdict must cover."""
        pos, found = self._positions(np.asarray(pair, dtype=np.int64))
        out = np.zeros(found.shape)
        out[found] = self.scheduler.horizon_of(pos[found])
        return out

    def last_step_of(self, pair: npt.ArrayLike) -> np.ndarray:
        """Step of each pair's latest verdict: its evaluation, or the screen's test (a pair not
        held: the step since which it was shown unable to touch, the later anchor of its two
        spheres at the latest rebuild or renewal)."""
        ids = np.asarray(pair, dtype=np.int64)
        pos, found = self._positions(ids)
        out = np.zeros(ids.shape, dtype=np.int64)
        out[found] = self.scheduler.ints[_LAST_STEP, pos[found]]
        if not found.all():
            built = np.asarray(self._rt.anchor_steps)
            sp = self._universe.sphere_pairs
            rest = ids[~found]
            first = np.asarray(sp.first, dtype=np.int64)[rest]
            second = np.asarray(sp.second, dtype=np.int64)[rest]
            sphere = np.asarray(sp.kind)[rest] == int(PairKind.SPHERE)
            other = np.where(sphere, built[np.where(sphere, second, 0)], 0)
            out[~found] = np.maximum(built[first], other)
        return out

    def last_tau_of(self, pair: npt.ArrayLike) -> np.ndarray:
        """tau of each pair's latest evaluation (a pair not held: ``inf``)."""
        return self._gather(np.asarray(self.scheduler.last_tau), np.asarray(pair, np.int64), np.inf)
