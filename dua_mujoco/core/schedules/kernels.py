"""The compiled schedule interface: ``select``, ``reinsert``, ``switch`` and ``restore``.

Implemented once, in the native core (``dua_mujoco/csrc/src/schedule.cc``); these are numba's
entry points to it, over the state tuple (:func:`schedule_view` points the C struct at its
arrays).

A fused step is ``count = select(st, n)``, then tau of ``st[S_WORK][W_IDS, :count]`` into
``st[S_W_TAU][:count]`` (whatever the pairs' geometry is), then ``reinsert(st, n, count)``, which
returns the number of alarms written to ``st[S_WORK][W_ALARMS]``. Each entry point branches on
``st[S_KIND]``; the rules and their completeness proofs are in docs/theory.md.

- Rank (DUA): bucket ``k`` of ``2**k`` slots hands out ``min(q, 2**k)`` slots a step, so each of
  its slots is visited every ``I_k = max(1, 2**k / q)`` steps; the i-th most urgent evaluated pair
  goes into the i-th withdrawn slot (bucket order) and alarms if ``tau < (I_k + latency) dt``.
- Deadline: a pair evaluated at step ``n`` with tau is next due at ``n + s``, ``s`` the largest
  interval with ``(s + latency) dt <= tau`` (at least 1, at most ``max_interval``); it alarms iff
  ``s`` had to be raised to 1. Pairs due at a step wait in a timing wheel of linked lists. Over
  the cap, the pairs with the least time left are served and the rest wait a step, alarming if
  their last verdict does not cover the longer interval.
- Select-all: every active pair, alarm iff ``tau < horizon[0]``.

A pair switched back on, or made due by ``make_due`` (its bounds broke), gets
``last_tau = -inf`` (it stands in alarm) and is evaluated at the next selection: rank appends it
to the regular slots (at most the spare width a step, the rest waits in the queue, still
standing in alarm); deadline makes it due at that step.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from dua_mujoco.core.native_kernels import (
    deadline_carry_c,
    deadline_classify_c,
    make_due_c,
    rank_classify_c,
    reinsert_c,
    restore_c,
    select_c,
    switch_c,
)
from dua_mujoco.core.schedules.state import (
    S_ACTIVE,
    S_DT,
    S_HORIZON,
    S_INTS,
    S_KIND,
    S_LAST_TAU,
    S_LATENCY,
    S_PARAMS,
    S_QUEUE,
    S_SLOTS,
    S_W_TAU,
    S_WORK,
)

__all__ = [
    "SCHEDULE_FIELDS",
    "deadline_carry",
    "deadline_classify",
    "make_due",
    "rank_classify",
    "reinsert",
    "restore",
    "schedule_view",
    "select",
    "switch",
]

SCHEDULE_FIELDS = 16
"""Fields of ``dua_schedule`` (``dua/dua.h``), eight bytes each."""


@nb.njit(cache=True)
def schedule_view(st):  # pragma: no cover - jitted
    """A ``dua_schedule`` over the state tuple ``st``'s arrays (C-contiguous; they must outlive
    its use): ``(16,)`` int64, the struct's fields in order."""
    f = np.empty(SCHEDULE_FIELDS, dtype=np.float64)
    v = f.view(np.int64)
    v[0] = st[S_KIND]
    f[1] = st[S_DT]
    v[2] = st[S_LATENCY]
    v[3] = st[S_LAST_TAU].shape[0]
    v[4] = st[S_LAST_TAU].ctypes.data
    v[5] = st[S_ACTIVE].ctypes.data
    v[6] = st[S_INTS].ctypes.data
    v[7] = st[S_SLOTS].ctypes.data
    v[8] = st[S_SLOTS].shape[0]
    v[9] = st[S_HORIZON].ctypes.data
    v[10] = st[S_QUEUE].ctypes.data
    v[11] = st[S_QUEUE].shape[0]
    v[12] = st[S_PARAMS].ctypes.data
    v[13] = st[S_WORK].ctypes.data
    v[14] = st[S_WORK].shape[1]
    v[15] = st[S_W_TAU].ctypes.data
    return v


@nb.njit(cache=True)
def select(st, n):  # pragma: no cover - jitted
    """Select the pairs to evaluate at step ``n`` into the ``W_IDS`` work row; their count."""
    return select_c(schedule_view(st).ctypes, n)


@nb.njit(cache=True)
def reinsert(st, n, count):  # pragma: no cover - jitted
    """Store the verdicts of the ``count`` evaluated pairs (tau in ``st[S_W_TAU]``); #alarms."""
    return reinsert_c(schedule_view(st).ctypes, n, count)


@nb.njit(cache=True)
def restore(st, n, count):  # pragma: no cover - jitted
    """Undo ``select`` of step ``n`` (its evaluation failed): the step can be taken again."""
    restore_c(schedule_view(st).ctypes, n, count)


@nb.njit(cache=True)
def switch(st, ids, on, n_next):  # pragma: no cover - jitted
    """Switch pairs ``ids`` (int64, contiguous) on or off; returns how many changed.
    ``n_next``: the next step to run."""
    return switch_c(schedule_view(st).ctypes, ids.ctypes, ids.shape[0], 1 if on else 0, n_next)


@nb.njit(cache=True)
def make_due(st, p, n):  # pragma: no cover - jitted
    """Withdraw active pair ``p``'s verdict and make it due at step ``n`` (the step about to
    select): it stands in alarm (``last_tau = -inf``) until evaluated, as a pair switched on
    does. Used when the motion it was judged under broke its bounds."""
    make_due_c(schedule_view(st).ctypes, p, n)


@nb.njit(cache=True)
def deadline_classify(st):  # pragma: no cover - jitted
    """Deadline's initial classification: every active pair due ``s`` steps after step 0."""
    deadline_classify_c(schedule_view(st).ctypes)


@nb.njit(cache=True)
def rank_classify(st):  # pragma: no cover - jitted
    """DUA's initial classification from ``last_tau`` (tau0): bucket ``k`` gets the pairs of
    rank ``[2^k - 1, 2^(k+1) - 1)`` (ties by id), each pair's slot in ``WHERE``, and the pairs
    that stand in alarm are marked in their slots."""
    rank_classify_c(schedule_view(st).ctypes)


@nb.njit(cache=True)
def deadline_carry(old, new, src, n):  # pragma: no cover - jitted
    """Fill the deadline state ``new`` (``ints`` and ``slots`` at -1) from ``old`` through ``src``.

    New pair ``p`` is old pair ``src[p]``, whose verdict (tau, last step, due step, switch) is
    carried unchanged, or a pair new to the set (``src[p] < 0``): it stands in alarm
    (``last_tau = -inf``) and is due at step ``n``, as a pair switched back on is. O(len(src)).
    """
    deadline_carry_c(
        schedule_view(old).ctypes, schedule_view(new).ctypes, src.ctypes, src.shape[0], n
    )
