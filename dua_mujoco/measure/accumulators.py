"""Accumulators of a monitored run that stay small however long it runs."""

from __future__ import annotations

import bisect
import math

import numpy as np

__all__ = ["Durations", "Growing", "Series", "StepMap"]

# Step timings are kept as a histogram of log-durations, not one float per step: bins 0.5 %
# wide from 1 ns to 1000 s put the median within 0.25 % in 41 kB, however long the run.
_LOG_T0 = math.log(1e-9)
_LOG_BIN = 0.005
_NBINS = math.ceil((math.log(1e3) - _LOG_T0) / _LOG_BIN) + 1


class Durations:
    """Median of many durations in constant memory (a log-spaced histogram)."""

    def __init__(self) -> None:
        self.count = 0
        self._hist = np.zeros(_NBINS, dtype=np.int64)

    def add(self, seconds: float) -> None:
        b = int((math.log(max(seconds, 1e-9)) - _LOG_T0) / _LOG_BIN)
        self._hist[min(b, _NBINS - 1)] += 1
        self.count += 1

    def median(self) -> float:
        """The median duration in seconds (the centre of its bin); 0 without durations."""
        if not self.count:
            return 0.0
        b = int(np.searchsorted(np.cumsum(self._hist), (self.count + 1) // 2))
        return math.exp(_LOG_T0 + (b + 0.5) * _LOG_BIN)


class Growing:
    """A 1-D array of ``dtype`` that doubles as it fills (amortised O(1) appends)."""

    def __init__(self, dtype: type = np.float64) -> None:
        self._a: np.ndarray = np.zeros(64, dtype=dtype)
        self.size = 0

    def _reserve(self, n: int) -> None:
        if n > self._a.size:
            self._a = np.concatenate([self._a, np.zeros(max(n, self._a.size), self._a.dtype)])

    def extend(self, values: np.ndarray | list[float]) -> None:
        values = np.asarray(values)
        n = self.size + values.size
        self._reserve(n)
        self._a[self.size : n] = values
        self.size = n

    def append(self, value: float) -> None:
        """One value, without making an array of it (a step's series: a scalar a call)."""
        self._reserve(self.size + 1)
        self._a[self.size] = value
        self.size += 1

    def view(self) -> np.ndarray:
        """The values so far (a view: copy it to keep it past the next append)."""
        return self._a[: self.size]


class Series:
    """Per-predictor-step alarm counts and minimum tau in arrays that double as they fill."""

    def __init__(self) -> None:
        self._alarms, self._tau = Growing(np.int32), Growing(np.float64)

    def append(self, nalarms: int, min_tau: float) -> None:
        self._alarms.append(nalarms)
        self._tau.append(min_tau)

    @property
    def size(self) -> int:
        """Steps recorded."""
        return self._alarms.size

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """Copies trimmed to the steps recorded: ``(alarms int32, min_tau float64)``."""
        return self._alarms.view().copy(), self._tau.view().copy()


class StepMap:
    """Predictor step index -> physics step, stored as runs ``period`` physics steps apart.

    The predictor steps every ``period`` physics steps, so a run needs one entry per reset, not
    one per step; an irregular step (observed by hand, off the period) starts a new run.
    """

    def __init__(self, physics_step: int, period: int) -> None:
        self.period = period
        self._first = [0]
        self._physics = [physics_step]
        self.count = 1

    def append(self, physics_step: int) -> None:
        if physics_step != self[self.count]:
            self._first.append(self.count)
            self._physics.append(physics_step)
        self.count += 1

    def __getitem__(self, j: int) -> int:
        i = bisect.bisect_right(self._first, j) - 1
        return self._physics[i] + (j - self._first[i]) * self.period

    def at(self, j: np.ndarray) -> np.ndarray:
        """``self[j]`` for each predictor step of ``j`` (n,): physics steps (n,)."""
        i = np.searchsorted(self._first, j, side="right") - 1
        return np.asarray(self._physics)[i] + (j - np.asarray(self._first)[i]) * self.period
