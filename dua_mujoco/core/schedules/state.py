"""The typed state every schedule keeps, and the names of its packed rows and parameters.

One ``ScheduleState`` serves DUA's rank buckets, the deadline wheel and select-all: the views of
a ``dua_mujoco._core.Schedule``'s buffers, which the native kernels (``csrc/src/schedule.cc``)
read and write, branching on ``state.kind``. Arrays a schedule does not use are empty, and
nothing outside ``dua_mujoco.core.schedules`` writes them. The names of the rows and parameters
are the native core's (``_core.LAYOUT``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

import dua_mujoco._core as _core

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
    "P_SETTLED",
    "P_SLOTS_PER_BUCKET",
    "P_WHEEL",
    "RANK",
    "SCREENED",
    "WHERE",
    "W_ALARMS",
    "W_IDS",
    "W_NEW",
    "W_SLOTS",
    "ScheduleState",
    "state_of",
]

_LAYOUT = _core.LAYOUT

# Kinds (``ScheduleState.kind``).
RANK: int = _LAYOUT["RANK"]
"""DUA: buckets sized by rank (the paper's constant work per step)."""
DEADLINE: int = _LAYOUT["DEADLINE"]
"""Each pair revisited at the latest step its own tau allows (a timing wheel)."""
ALL: int = _LAYOUT["ALL"]
"""Select-all: every active pair every step."""

# Rows of ``ScheduleState.ints``: one int64 row per pair each.
WHERE: int = _LAYOUT["WHERE"]
"""Rank: the slot holding the pair. Deadline: the step the pair is due at (-1: not queued,
``SCREENED``: on the screen)."""
SCREENED: int = _LAYOUT["SCREENED"]
"""Deadline: ``WHERE`` of a pair on the screen, tested at every step instead of linked in the
wheel (docs/theory.md, section 3, "The screen")."""
LAST_STEP: int = _LAYOUT["LAST_STEP"]
"""Step of the pair's latest evaluation."""
NEXT: int = _LAYOUT["NEXT"]
"""Deadline: next pair in the same wheel slot (-1: last)."""
PREV: int = _LAYOUT["PREV"]
"""Deadline: previous pair in the slot, or ``-1 - slot`` for the slot's first pair."""

# Rows of ``ScheduleState.work``.
W_SLOTS: int = _LAYOUT["W_SLOTS"]
"""Rank: the withdrawn slots, in bucket order, as rank slots hold pairs: ``slot``, or
``-2 - slot`` if its pair stood in alarm (-1 for a pair switched back on)."""
W_IDS: int = _LAYOUT["W_IDS"]
"""The pairs selected this step: evaluated first, then (deadline) deferred ones."""
W_ALARMS: int = _LAYOUT["W_ALARMS"]
"""The pairs alarmed by this step's verdicts."""
W_NEW: int = _LAYOUT["W_NEW"]
"""1 where the alarm at the same place of ``W_ALARMS`` is new: the pair did not stand in alarm
(or stood only because it was switched back on) before this step."""

# Entries of ``ScheduleState.params`` (int64).
P_NBUCKETS: int = _LAYOUT["P_NBUCKETS"]
"""Rank: number of buckets ``L``."""
P_SLOTS_PER_BUCKET: int = _LAYOUT["P_SLOTS_PER_BUCKET"]
"""Rank: slots handed out per bucket per step (the budget knob ``q``)."""
P_WHEEL: int = _LAYOUT["P_WHEEL"]
"""Deadline: wheel size (a power of two above the longest revisit interval)."""
P_MAX_INTERVAL: int = _LAYOUT["P_MAX_INTERVAL"]
"""Deadline: the longest revisit interval, in steps."""
P_CAP: int = _LAYOUT["P_CAP"]
"""Deadline: evaluations allowed per step (0: no cap)."""
P_COUNT: int = _LAYOUT["P_COUNT"]
"""Pairs evaluated by the latest selection."""
P_DEFERRED: int = _LAYOUT["P_DEFERRED"]
"""Deadline: pairs due at the latest selection but left for a later step (over the cap)."""
P_EXTRA: int = _LAYOUT["P_EXTRA"]
"""Rank: how many of the evaluated pairs were switched back on (evaluated out of their slot)."""
P_BACKOFF: int = _LAYOUT["P_BACKOFF"]
"""Deadline: longest interval (steps) between evaluations of a pair that keeps alarming (1:
every step); it stands in alarm in between."""
P_SETTLED: int = _LAYOUT["P_SETTLED"]
"""Deadline: pairs of flagged bodies the latest step settled by a bound instead of evaluating
(their ids in ``work[W_SLOTS, :settled]``; docs/theory.md, section 6)."""
NPARAMS: int = _LAYOUT["NPARAMS"]


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


def state_of(schedule: _core.Schedule) -> ScheduleState:
    """The views of ``schedule``'s buffers (owned by it, never reallocated) as a state."""
    views = {name: getattr(schedule, name) for name in ScheduleState._fields[3:]}
    return ScheduleState(int(schedule.kind), float(schedule.dt), int(schedule.latency), **views)
