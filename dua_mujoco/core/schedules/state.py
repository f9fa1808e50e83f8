"""The typed state every schedule keeps, and the names of its packed rows and parameters.

One ``ScheduleState`` serves DUA's rank buckets, the deadline wheel and select-all, so that one
set of compiled kernels (``kernels.select``, ``kernels.reinsert``, ``kernels.switch``) and one
fused step drive all three: the kernels branch on ``state.kind``. Arrays a schedule does not use
are empty, and nothing outside ``dua_mujoco.core.schedules`` writes them.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from dua_mujoco.exceptions import ShapeError

__all__ = [
    "ALL",
    "DEADLINE",
    "LAST_STEP",
    "NEXT",
    "NPARAMS",
    "PREV",
    "P_BACKOFF",
    "P_CAP",
    "P_COUNT",
    "P_DEFERRED",
    "P_EXTRA",
    "P_MAX_INTERVAL",
    "P_NBUCKETS",
    "P_SLOTS_PER_BUCKET",
    "P_WHEEL",
    "RANK",
    "S_ACTIVE",
    "S_DT",
    "S_HORIZON",
    "S_INTS",
    "S_KIND",
    "S_LAST_TAU",
    "S_LATENCY",
    "S_PARAMS",
    "S_QUEUE",
    "S_SLOTS",
    "S_WORK",
    "S_W_TAU",
    "WHERE",
    "W_ALARMS",
    "W_IDS",
    "W_NEW",
    "W_SLOTS",
    "ScheduleState",
    "empty_state",
]

# Kinds (``ScheduleState.kind``).
RANK = 0
"""DUA: buckets sized by rank (the paper's constant work per step)."""
DEADLINE = 1
"""Each pair revisited at the latest step its own tau allows (a timing wheel)."""
ALL = 2
"""Select-all: every active pair every step."""

# Rows of ``ScheduleState.ints``: one int64 row per pair each.
WHERE = 0
"""Rank: the slot holding the pair. Deadline: the step the pair is due at (-1: not queued)."""
LAST_STEP = 1
"""Step of the pair's latest evaluation."""
NEXT = 2
"""Deadline: next pair in the same wheel slot (-1: last)."""
PREV = 3
"""Deadline: previous pair in the slot, or ``-1 - slot`` for the slot's first pair."""

# Rows of ``ScheduleState.work``.
W_SLOTS = 0
"""Rank: the withdrawn slots, in bucket order, as rank slots hold pairs: ``slot``, or
``-2 - slot`` if its pair stood in alarm (-1 for a pair switched back on)."""
W_IDS = 1
"""The pairs selected this step: evaluated first, then (deadline) deferred ones."""
W_ALARMS = 2
"""The pairs alarmed by this step's verdicts."""
W_NEW = 3
"""1 where the alarm at the same place of ``W_ALARMS`` is new: the pair did not stand in alarm
(or stood only because it was switched back on) before this step."""

# Entries of ``ScheduleState.params`` (int64).
P_NBUCKETS = 0
"""Rank: number of buckets ``L``."""
P_SLOTS_PER_BUCKET = 1
"""Rank: slots handed out per bucket per step (the budget knob ``q``)."""
P_WHEEL = 2
"""Deadline: wheel size (a power of two above the longest revisit interval)."""
P_MAX_INTERVAL = 3
"""Deadline: the longest revisit interval, in steps."""
P_CAP = 4
"""Deadline: evaluations allowed per step (0: no cap)."""
P_COUNT = 5
"""Pairs evaluated by the latest selection."""
P_DEFERRED = 6
"""Deadline: pairs due at the latest selection but left for a later step (over the cap)."""
P_EXTRA = 7
"""Rank: how many of the evaluated pairs were switched back on (evaluated out of their slot)."""
P_BACKOFF = 8
"""Deadline: longest interval (steps) between evaluations of a pair that keeps alarming (1:
every step); it stands in alarm in between."""
NPARAMS = 9


# Positions of the fields in ``tuple(state)``, the form the compiled kernels take: numba
# dispatches a plain tuple about twice as fast as a named one (measured: 1.1 vs 2.3 us).
S_KIND = 0
S_DT = 1
S_LATENCY = 2
S_LAST_TAU = 3
S_ACTIVE = 4
S_INTS = 5
S_SLOTS = 6
S_HORIZON = 7
S_QUEUE = 8
S_PARAMS = 9
S_WORK = 10
S_W_TAU = 11


class ScheduleState(NamedTuple):
    """What a schedule keeps between steps; arrays the kind does not use are empty.

    Attributes:
        kind: ``RANK``, ``DEADLINE`` or ``ALL``.
        dt: Predictor period (seconds).
        latency: Periods a verdict takes to act.
        last_tau: ``(M,)`` urgency at each pair's latest evaluation (``-inf``: switched back on,
            standing in alarm until evaluated).
        active: ``(M,)`` bool, pairs switched on.
        ints: ``(rows, M)`` int64, rows ``WHERE``, ``LAST_STEP`` (and ``NEXT``, ``PREV`` for the
            deadline wheel).
        slots: Rank: ``(2**L - 1,)`` pair of each slot (-1 empty). Deadline: ``(wheel,)`` first
            pair of each wheel slot (-1 empty). Select-all: empty.
        horizon: Rank: ``(L,)`` alarm horizon of each bucket, ``(I_k + latency) dt``. Others:
            ``(1,)`` the alarm threshold on the urgency.
        queue: ``(Q + 1,)`` rank: ``queue[0]`` pairs switched back on wait in ``queue[1:]``.
        params: ``(NPARAMS,)`` int64, the ``P_*`` entries.
        work: ``(4, W)`` int64 rows ``W_SLOTS``, ``W_IDS``, ``W_ALARMS``, ``W_NEW``.
        w_tau: ``(W,)`` urgency of the selected pairs, in selection order.
    """

    kind: int
    dt: float
    latency: int
    last_tau: np.ndarray
    active: np.ndarray
    ints: np.ndarray
    slots: np.ndarray
    horizon: np.ndarray
    queue: np.ndarray
    params: np.ndarray
    work: np.ndarray
    w_tau: np.ndarray


def empty_state(
    kind: int,
    dt: float,
    latency: int,
    urgency: np.ndarray,
    active: npt.ArrayLike | None,
    *,
    rows: int,
    slots: int,
    horizon: np.ndarray,
    queue: int,
    width: int,
) -> ScheduleState:
    """A state with the given sizes: ``last_tau`` a copy of ``urgency``, ``active`` all pairs
    (None) or a ``(M,)`` mask, ``ints`` zero, ``slots`` empty (-1), work buffers unset."""
    m = urgency.shape[0]
    if active is None:
        mask = np.ones(m, dtype=np.bool_)
    else:
        mask = np.array(active, dtype=np.bool_)
        if mask.shape != (m,):
            raise ShapeError(f"active has shape {mask.shape}; expected ({m},).")
    return ScheduleState(
        kind=kind,
        dt=float(dt),
        latency=int(latency),
        last_tau=np.array(urgency, dtype=np.float64),
        active=mask,
        ints=np.zeros((rows, m), dtype=np.int64),
        slots=np.full(slots, -1, dtype=np.int64),
        horizon=np.ascontiguousarray(horizon, dtype=np.float64),
        queue=np.zeros(queue + 1, dtype=np.int64),
        params=np.zeros(NPARAMS, dtype=np.int64),
        work=np.zeros((4, max(width, 1)), dtype=np.int64),
        w_tau=np.zeros(max(width, 1)),
    )
