"""``DUAScheduler``: the Dynamic Urgency Algorithm's rank buckets (Hayward et al. 1995, sec. 7).

``M`` pairs in ``L = ceil(log2(M + 1))`` buckets, bucket ``k`` of ``2**k`` slots starting at slot
``2**k - 1`` of one flat array (the last bucket partly empty, ``-1``). ``DUAScheduler(tau0,
dt=...)`` is the initial classification; each step hands out ``min(q, 2**k)`` slots of every
bucket (``q`` slots per bucket, a power of two), so bucket ``k`` is revisited every
``I_k = max(1, 2**k / q)`` steps, and a pair landing in bucket ``k`` alarms if
``tau < (I_k + latency) dt``. The setting and the completeness proof: docs/theory.md, section 2.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

import dua_mujoco._core as _core
from dua_mujoco.core.schedules.base import Scheduler, active_mask
from dua_mujoco.core.schedules.state import P_NBUCKETS, P_SLOTS_PER_BUCKET, RANK, WHERE
from dua_mujoco.core.validate import check_int, check_period, check_urgencies

__all__ = ["DUAScheduler", "bucket_layout"]


def bucket_layout(npairs: int) -> tuple[int, int]:
    """Number of buckets ``L`` and of slots ``2**L - 1`` for ``npairs`` pairs."""
    nbuckets = max(1, math.ceil(math.log2(npairs + 1)))
    return nbuckets, (1 << nbuckets) - 1


class DUAScheduler(Scheduler, kind=RANK):
    """The Dynamic Urgency Algorithm: buckets sized by rank, constant work per step.

    Args:
        tau0: ``(M,)`` tau of every pair at time 0 (the initial classification).
        dt: Predictor period ``> 0`` (seconds between steps).
        latency: Periods a verdict takes to act (1: the paper's eq. 26; 0: the predictor
            runs synchronously after each physics step).
        slots_per_bucket: Budget knob ``q`` (a power of two): slots evaluated per bucket per step.
            Revisit intervals shrink ``q``-fold; work grows ``q``-fold.
        active: Optional ``(M,)`` bool mask of pairs initially switched on (default all).

    Attributes:
        interval: ``(L,)`` revisit interval ``I_k`` of each bucket, in steps.
        horizon: ``(L,)`` alarm horizon ``(I_k + latency) dt`` of each bucket.
    """

    def __init__(
        self,
        tau0: npt.ArrayLike,
        *,
        dt: float,
        latency: int = 1,
        slots_per_bucket: int = 1,
        active: npt.ArrayLike | None = None,
    ) -> None:
        tau = check_urgencies("tau0", tau0)
        dt, latency = check_period(dt, latency)
        q = check_int("slots_per_bucket", slots_per_bucket)  # a power of two: the native check
        # The initial classification: a partial sort at the bucket boundaries (paper eq. 23),
        # the pairs standing in alarm marked in their slots (-2 - pair).
        schedule = _core.Schedule(
            RANK, dt, latency, tau, active_mask(active, tau.shape[0]), slots_per_bucket=q
        )
        raw = schedule.slots[: tau.shape[0]]
        self._wrap(schedule, np.sort(-2 - raw[raw < -1]))
        self._derive()

    def _derive(self) -> None:
        params = self.state.params
        self.nbuckets = int(params[P_NBUCKETS])
        self.slots_per_bucket = q = int(params[P_SLOTS_PER_BUCKET])
        self.interval = np.asarray(self.core.intervals)
        self.horizon = self.state.horizon  # the live alarm rule (the kernels read it)
        self._width = int(np.minimum(1 << np.arange(self.nbuckets), q).sum())

    # ----------------------------------------------------------------------- introspection

    @property
    def slots(self) -> np.ndarray:
        """``(2**L - 1,)`` the pair in each slot (-1 empty)."""
        raw = self.state.slots
        return np.where(raw < -1, -2 - raw, raw)

    @property
    def where(self) -> np.ndarray:
        """``(M,)`` the slot of each pair."""
        return self.state.ints[WHERE]

    def most_urgent(self) -> int:
        """The pair DUA believes most urgent: the occupant of bucket 0 (paper sec. 8.1.4).

        If that pair is switched off, the first active pair in slot order (-1 if none).
        """
        active = self.state.active
        first = int(self.slots[0])
        if first >= 0 and active[first]:
            return first
        occupants = self.slots[self.slots >= 0]
        live = occupants[active[occupants]]
        return int(live[0]) if live.size else -1

    @property
    def evaluations_per_step(self) -> int:
        """Slots handed out per step: ``sum_k min(q, 2**k)`` (empty or inactive ones skipped)."""
        return self._width
