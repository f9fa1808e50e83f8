"""``Alarms``: what one predictor step says, with the tables that name its pairs."""

from __future__ import annotations

import numpy as np

from dua_mujoco.mj.tables import PairTables

__all__ = ["Alarms"]


class Alarms:
    """The alarms of one predictor step (read-only).

    A slotted class rather than a frozen dataclass: one is built every predictor step, and a
    frozen dataclass's ``__init__`` (``object.__setattr__`` per field) cost 1.1 us of a step
    budget of a few microseconds (measured; this class: 0.3 us). A step's alarms are a span of
    the predictor's alarm log (``dua_mujoco.mj.native_step``), which the native step appends
    to and nobody overwrites: the arrays are read-only views of that span, made when read.

    Attributes:
        step: Predictor step (0 for the initial classification).
        time: ``data.time`` when read.
        pairs: ``(k,)`` sphere-pair ids that raised an alarm.
        tau: ``(k,)`` their tau (seconds).
        new: ``(k,)`` bool, pairs whose alarm this step raised (not standing from the step
            before): print these to see changes rather than the same standing pairs again.
    """

    __slots__ = (
        "_deferred",
        "_new",
        "_pairs",
        "_start",
        "_step",
        "_stop",
        "_tables",
        "_tau",
        "_time",
    )

    def __init__(
        self,
        step: int,
        time: float,
        pairs: np.ndarray,
        tau: np.ndarray,
        tables: PairTables,
        new: np.ndarray,
        deferred: int = 0,
    ) -> None:
        log = (pairs, tau, np.asarray(new, dtype=bool))
        self._assign(step, time, log, (0, int(pairs.shape[0])), tables, deferred)

    @classmethod
    def from_log(
        cls,
        step: int,
        time: float,
        log: tuple[np.ndarray, np.ndarray, np.ndarray],
        start: int,
        stop: int,
        tables: PairTables,
        deferred: int = 0,
    ) -> Alarms:
        """The alarms at ``[start, stop)`` of an alarm log ``(pairs, tau, new)`` (read-only
        arrays that nothing writes at or before ``stop`` again): no copy is made."""
        # Not through __init__ nor _assign: a class call with its argument parsing cost 0.4 us
        # more, and a method call 0.06 us, in a step whose fixed cost is about 1 us (measured).
        alarms = cls.__new__(cls)
        alarms._step = step
        alarms._time = time
        alarms._pairs, alarms._tau, alarms._new = log
        alarms._start = start
        alarms._stop = stop
        alarms._tables = tables
        alarms._deferred = deferred
        return alarms

    def _assign(
        self, step: int, time: float, log: tuple, span: tuple, tables: PairTables, deferred: int
    ) -> None:
        """Set the fields (``from_log`` sets the same ones inline)."""
        self._step = step
        self._time = time
        self._pairs, self._tau, self._new = log
        self._start, self._stop = span
        self._tables = tables
        self._deferred = deferred

    @property
    def step(self) -> int:
        """Predictor step (0 for the initial classification)."""
        return self._step

    @property
    def time(self) -> float:
        """``data.time`` when read."""
        return self._time

    @property
    def pairs(self) -> np.ndarray:
        """``(k,)`` sphere-pair ids that raised an alarm."""
        return self._pairs[self._start : self._stop]

    @property
    def tau(self) -> np.ndarray:
        """``(k,)`` their tau (seconds)."""
        return self._tau[self._start : self._stop]

    @property
    def new(self) -> np.ndarray:
        """``(k,)`` bool: alarms this step raised, as opposed to ones standing from before."""
        return self._new[self._start : self._stop]

    @property
    def deferred(self) -> int:
        """Pairs due this step but left for a later one (``max_evals_per_step`` reached): the
        predictor could not keep up; those whose last verdict no longer covers the wait are
        among the alarms."""
        return self._deferred

    def __repr__(self) -> str:
        return (
            f"Alarms(step={self._step}, time={self._time!r}, pairs={self.pairs!r}, "
            f"tau={self.tau!r}, new={self.new!r})"
        )

    def __len__(self) -> int:
        return self._stop - self._start

    @property
    def geom1(self) -> np.ndarray:
        """``(k,)`` first geom of each alarmed pair."""
        return np.asarray(self._tables.geom1[self.pairs])

    @property
    def geom2(self) -> np.ndarray:
        """``(k,)`` second geom of each alarmed pair (a plane geom for half-space pairs)."""
        return np.asarray(self._tables.geom2[self.pairs])

    @property
    def sphere1(self) -> np.ndarray:
        """``(k,)`` first sphere of each alarmed pair."""
        return np.asarray(self._tables.first[self.pairs])

    @property
    def sphere2(self) -> np.ndarray:
        """``(k,)`` second sphere, ``-1`` for half-space and static shape pairs."""
        return np.asarray(
            np.where(self._tables.kind[self.pairs] != 0, -1, self._tables.second[self.pairs])
        )

    @property
    def names(self) -> list[tuple[str, str]]:
        """Geom names of each alarmed pair (``geom<id>`` for unnamed geoms)."""
        n = self._tables.geom_names
        return list(zip(n[self.geom1].tolist(), n[self.geom2].tolist(), strict=True))

    @property
    def geom_pairs(self) -> set[tuple[int, int]]:
        """The distinct alarmed geom pairs ``(g1, g2)``, ``g1 < g2``."""
        a, b = self.geom1, self.geom2
        return set(zip(np.minimum(a, b).tolist(), np.maximum(a, b).tolist(), strict=True))
