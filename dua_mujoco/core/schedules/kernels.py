"""The compiled schedule interface: ``select``, ``reinsert``, ``switch`` and ``restore``.

A fused step is ``count = select(st, n)``, then tau of ``st.work[W_IDS, :count]`` into
``st.w_tau[:count]`` (whatever the pairs' geometry is), then ``reinsert(st, n, count)``, which
returns the number of alarms written to ``st.work[W_ALARMS]``. Each entry point branches on
``st.kind``; the rules and their completeness proofs are in docs/theory.md.

- Rank (DUA): bucket ``k`` of ``2**k`` slots hands out ``min(q, 2**k)`` slots a step, so each of
  its slots is visited every ``I_k = max(1, 2**k / q)`` steps; the i-th most urgent evaluated pair
  goes into the i-th withdrawn slot (bucket order) and alarms if ``tau < (I_k + latency) dt``.
- Deadline: a pair evaluated at step ``n`` with tau is next due at ``n + s``, ``s`` the largest
  interval with ``(s + latency) dt <= tau`` (at least 1, at most ``max_interval``); it alarms iff
  ``s`` had to be raised to 1. Pairs due at a step wait in a timing wheel of linked lists. Over
  the cap, the pairs with the least time left are served and the rest wait a step, alarming if
  their last verdict does not cover the longer interval.
- Select-all: every active pair, alarm iff ``tau < horizon[0]``.

A pair switched back on gets ``last_tau = -inf`` (it stands in alarm) and is evaluated at the
next selection: rank appends it to the regular slots (at most the spare width a step, the rest
waits in the queue, still standing in alarm); deadline makes it due at the next step.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from dua_mujoco.core.schedules.state import (
    DEADLINE,
    LAST_STEP,
    NEXT,
    P_CAP,
    P_COUNT,
    P_DEFERRED,
    P_EXTRA,
    P_MAX_INTERVAL,
    P_NBUCKETS,
    P_SLOTS_PER_BUCKET,
    P_WHEEL,
    PREV,
    RANK,
    W_ALARMS,
    W_IDS,
    W_NEW,
    W_SLOTS,
    WHERE,
)

__all__ = [
    "bucket_of",
    "deadline_carry",
    "deadline_classify",
    "deadline_interval",
    "reinsert",
    "restore",
    "select",
    "switch",
]


# --------------------------------------------------------------------------- rank buckets


@nb.njit(cache=True, inline="always")
def _stood(last_tau, horizon):  # pragma: no cover - jitted
    """Whether a verdict stood in alarm (a pair switched back on, ``-inf``, was never reported)."""
    return last_tau < horizon and last_tau > -math.inf


@nb.njit(cache=True, inline="always")
def bucket_of(slot):  # pragma: no cover - jitted
    """Bucket ``floor(log2(slot + 1))`` of a rank slot."""
    k = 0
    while (2 << k) - 1 <= slot:
        k += 1
    return k


@nb.njit(cache=True)
def _rank_select(st, n):  # pragma: no cover - jitted
    slots, active, params = st.slots, st.active, st.params
    w_slots, w_ids = st.work[W_SLOTS], st.work[W_IDS]
    q = params[P_SLOTS_PER_BUCKET]
    count = 0
    for k in range(params[P_NBUCKETS]):
        size = 1 << k
        base = size - 1
        first = (n * q) % size
        for j in range(min(q, size)):
            slot = base + (first + j) % size
            pid = slots[slot]
            if pid >= 0 and active[pid]:
                w_slots[count] = slot
                w_ids[count] = pid
                count += 1
    # Pairs switched back on, evaluated out of their slots, as many as the spare width holds.
    queue = st.queue
    extra = min(queue[0], w_ids.shape[0] - count)
    for j in range(extra):
        w_slots[count + j] = -1
        w_ids[count + j] = queue[1 + j]
    rest = queue[0] - extra
    for j in range(rest):
        queue[1 + j] = queue[1 + extra + j]
    queue[0] = rest
    params[P_EXTRA] = extra
    return count + extra


@nb.njit(cache=True)
def _rank_reinsert(st, n, count):  # pragma: no cover - jitted
    """Sort the regular pairs by tau into the withdrawn slots; alarm against the bucket."""
    slots, last_tau, horizon = st.slots, st.last_tau, st.horizon
    where, last_step = st.ints[WHERE], st.ints[LAST_STEP]
    w_slots, w_ids, alarms, w_tau = st.work[W_SLOTS], st.work[W_IDS], st.work[W_ALARMS], st.w_tau
    new = st.work[W_NEW]
    regular = count - st.params[P_EXTRA]
    # Stable, so equal tau keep selection order (deterministic across runs).
    order = np.argsort(w_tau[:regular], kind="mergesort")
    nalarm = 0
    for i in range(regular):
        src = order[i]
        pid = w_ids[src]
        slot = w_slots[i]
        tau = w_tau[src]
        before = _stood(last_tau[pid], horizon[bucket_of(where[pid])])
        slots[slot] = pid
        where[pid] = slot
        last_tau[pid] = tau
        last_step[pid] = n
        if tau < horizon[bucket_of(slot)]:
            alarms[nalarm] = pid
            new[nalarm] = not before
            nalarm += 1
    for i in range(regular, count):
        pid = w_ids[i]
        tau = w_tau[i]
        last_tau[pid] = tau
        last_step[pid] = n
        if tau < horizon[bucket_of(where[pid])]:
            alarms[nalarm] = pid
            new[nalarm] = True
            nalarm += 1
    return nalarm


# --------------------------------------------------------------------------- deadline wheel


@nb.njit(cache=True, inline="always")
def _link(st, p, due):  # pragma: no cover - jitted
    slots, nxt, prv = st.slots, st.ints[NEXT], st.ints[PREV]
    slot = due & (st.params[P_WHEEL] - 1)
    head = slots[slot]
    nxt[p] = head
    prv[p] = -1 - slot
    if head >= 0:
        prv[head] = p
    slots[slot] = p
    st.ints[WHERE, p] = due


@nb.njit(cache=True, inline="always")
def _unlink(st, p):  # pragma: no cover - jitted
    nxt, prv = st.ints[NEXT], st.ints[PREV]
    if st.ints[WHERE, p] < 0:
        return
    after = nxt[p]
    before = prv[p]
    if before >= 0:
        nxt[before] = after
    else:
        st.slots[-1 - before] = after
    if after >= 0:
        prv[after] = before
    nxt[p] = -1
    prv[p] = -1
    st.ints[WHERE, p] = -1


@nb.njit(cache=True)
def deadline_interval(tau, dt, latency, max_interval):  # pragma: no cover - jitted
    """The largest ``s`` in ``[1, max_interval]`` with ``(s + latency) dt <= tau`` (1 if none)."""
    if not tau < (max_interval + latency + 1) * dt:
        return max_interval
    s = math.floor(tau / dt) - latency
    # The division rounds; step down until the product, computed as the alarm test computes
    # it, is covered by tau.
    while s >= 1 and (s + latency) * dt > tau:
        s -= 1
    return max(1, min(s, max_interval))


@nb.njit(cache=True)
def _deadline_select(st, n):  # pragma: no cover - jitted
    params, last_tau, last_step = st.params, st.last_tau, st.ints[LAST_STEP]
    w_ids = st.work[W_IDS]
    slot = n & (params[P_WHEEL] - 1)
    p = st.slots[slot]
    st.slots[slot] = -1
    count = 0
    while p >= 0:
        after = st.ints[NEXT, p]
        st.ints[NEXT, p] = -1
        st.ints[PREV, p] = -1
        st.ints[WHERE, p] = -1
        w_ids[count] = p
        count += 1
        p = after
    deferred = 0
    cap = params[P_CAP]
    if cap > 0 and count > cap:
        # The least time left first: a pair left waiting sees its slack shrink every step, so
        # none waits forever under a sustained overload. Ties go to the lower pair id (the
        # wheel's list order is an accident of history).
        w_ids[:count] = np.sort(w_ids[:count])
        slack = np.empty(count)
        for k in range(count):
            q = w_ids[k]
            slack[k] = last_tau[q] - (n - last_step[q]) * st.dt
        order = np.argsort(slack, kind="mergesort")
        chosen = w_ids[:count][order]
        w_ids[:count] = chosen
        deferred = count - cap
        count = cap
        for k in range(count, count + deferred):
            _link(st, w_ids[k], n + 1)
    params[P_COUNT] = count
    params[P_DEFERRED] = deferred
    return count


@nb.njit(cache=True)
def _deadline_reinsert(st, n, count):  # pragma: no cover - jitted
    params, last_tau, last_step = st.params, st.last_tau, st.ints[LAST_STEP]
    w_ids, alarms, w_tau, new = st.work[W_IDS], st.work[W_ALARMS], st.w_tau, st.work[W_NEW]
    dt, latency = st.dt, st.latency
    max_interval = params[P_MAX_INTERVAL]
    nalarm = 0
    for k in range(count):
        p = w_ids[k]
        tau = w_tau[k]
        # Due now: its verdict had to cover until this step (a deferred one, longer: it stood).
        before = _stood(last_tau[p], (n - last_step[p] + latency) * dt)
        last_tau[p] = tau
        last_step[p] = n
        _link(st, p, n + deadline_interval(tau, dt, latency, max_interval))
        if tau < st.horizon[0]:
            alarms[nalarm] = p
            new[nalarm] = not before
            nalarm += 1
    for k in range(count, count + params[P_DEFERRED]):
        p = w_ids[k]
        if last_tau[p] < (st.ints[WHERE, p] - last_step[p] + latency) * dt:
            alarms[nalarm] = p
            new[nalarm] = not _stood(last_tau[p], (n - last_step[p] + latency) * dt)
            nalarm += 1
    return nalarm


# --------------------------------------------------------------------------- select-all


@nb.njit(cache=True)
def _all_select(st):  # pragma: no cover - jitted
    w_ids = st.work[W_IDS]
    count = 0
    for p in range(st.active.shape[0]):
        if st.active[p]:
            w_ids[count] = p
            count += 1
    return count


@nb.njit(cache=True)
def _all_reinsert(st, n, count):  # pragma: no cover - jitted
    w_ids, alarms, w_tau, new = st.work[W_IDS], st.work[W_ALARMS], st.w_tau, st.work[W_NEW]
    nalarm = 0
    for k in range(count):
        p = w_ids[k]
        before = _stood(st.last_tau[p], st.horizon[0])
        st.last_tau[p] = w_tau[k]
        st.ints[LAST_STEP, p] = n
        if w_tau[k] < st.horizon[0]:
            alarms[nalarm] = p
            new[nalarm] = not before
            nalarm += 1
    return nalarm


# --------------------------------------------------------------------------- the interface


@nb.njit(cache=True)
def select(st, n):  # pragma: no cover - jitted
    """Select the pairs to evaluate at step ``n`` into ``st.work[W_IDS]``; returns their count."""
    if st.kind == RANK:
        count = _rank_select(st, n)
    elif st.kind == DEADLINE:
        count = _deadline_select(st, n)
    else:
        count = _all_select(st)
    st.params[P_COUNT] = count
    return count


@nb.njit(cache=True)
def reinsert(st, n, count):  # pragma: no cover - jitted
    """Store the verdicts of the ``count`` evaluated pairs (tau in ``st.w_tau``); #alarms."""
    if st.kind == RANK:
        return _rank_reinsert(st, n, count)
    if st.kind == DEADLINE:
        return _deadline_reinsert(st, n, count)
    return _all_reinsert(st, n, count)


@nb.njit(cache=True)
def restore(st, n, count):  # pragma: no cover - jitted
    """Undo ``select`` of step ``n`` (its evaluation failed): the step can be taken again."""
    w_ids = st.work[W_IDS]
    if st.kind == RANK:
        extra = st.params[P_EXTRA]
        queue = st.queue
        waiting = queue[0]
        for j in range(waiting - 1, -1, -1):
            queue[1 + extra + j] = queue[1 + j]
        for j in range(extra):
            queue[1 + j] = w_ids[count - extra + j]
        queue[0] = waiting + extra
    elif st.kind == DEADLINE:
        for k in range(count + st.params[P_DEFERRED]):
            p = w_ids[k]
            _unlink(st, p)
            _link(st, p, n)
    st.params[P_COUNT] = 0
    st.params[P_DEFERRED] = 0
    st.params[P_EXTRA] = 0


@nb.njit(cache=True)
def switch(st, ids, on, n_next):  # pragma: no cover - jitted
    """Switch pairs on or off; returns how many changed. ``n_next``: the next step to run."""
    changed = 0
    for k in range(ids.shape[0]):
        p = ids[k]
        if st.active[p] == on:
            continue
        changed += 1
        st.active[p] = on
        if on:
            # Nothing is known of its motion while it was off: it stands in alarm until its
            # next evaluation, which comes at the next selection.
            st.last_tau[p] = -math.inf
            if st.kind == RANK:
                st.queue[1 + st.queue[0]] = p
                st.queue[0] += 1
            elif st.kind == DEADLINE:
                _unlink(st, p)
                _link(st, p, n_next)
        elif st.kind == RANK:
            queue = st.queue
            kept = 0
            for j in range(queue[0]):
                if queue[1 + j] != p:
                    queue[1 + kept] = queue[1 + j]
                    kept += 1
            queue[0] = kept
        elif st.kind == DEADLINE:
            _unlink(st, p)
    return changed


@nb.njit(cache=True)
def deadline_classify(st):  # pragma: no cover - jitted
    """Deadline's initial classification: every active pair due ``s`` steps after step 0."""
    max_interval = st.params[P_MAX_INTERVAL]
    for p in range(st.active.shape[0]):
        if st.active[p]:
            _link(st, p, deadline_interval(st.last_tau[p], st.dt, st.latency, max_interval))


@nb.njit(cache=True)
def deadline_carry(old, new, src, n):  # pragma: no cover - jitted
    """Fill the deadline state ``new`` (``ints`` and ``slots`` at -1) from ``old`` through ``src``.

    New pair ``p`` is old pair ``src[p]``, whose verdict (tau, last step, due step, switch) is
    carried unchanged, or a pair new to the set (``src[p] < 0``): it stands in alarm
    (``last_tau = -inf``) and is due at step ``n``, as a pair switched back on is. O(len(src)).
    """
    for p in range(src.shape[0]):
        q = src[p]
        if q >= 0:
            new.last_tau[p] = old.last_tau[q]
            new.active[p] = old.active[q]
            new.ints[LAST_STEP, p] = old.ints[LAST_STEP, q]
            due = old.ints[WHERE, q]
            if due >= 0:
                _link(new, p, due)
        else:
            new.last_tau[p] = -math.inf
            new.active[p] = True
            new.ints[LAST_STEP, p] = n
            _link(new, p, n)
