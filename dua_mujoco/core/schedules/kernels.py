"""The compiled schedule interface: ``select``, ``reinsert``, ``switch`` and ``restore``.

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

import math

import numba as nb
import numpy as np

from dua_mujoco.core.schedules.state import (
    DEADLINE,
    LAST_STEP,
    NEXT,
    P_BACKOFF,
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
    "make_due",
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
def _occupant(raw, alarmed):  # pragma: no cover - jitted
    """A rank slot's entry for pair ``raw``: the pair, or ``-2 - pair`` if it stands in alarm."""
    return -2 - raw if alarmed else raw


@nb.njit(cache=True, inline="always")
def bucket_of(slot):  # pragma: no cover - jitted
    """Bucket ``floor(log2(slot + 1))`` of a rank slot."""
    k = 0
    while (2 << k) - 1 <= slot:
        k += 1
    return k


@nb.njit(cache=True)
def _rank_select(st, n):  # pragma: no cover - jitted
    slots, active, params = st[S_SLOTS], st[S_ACTIVE], st[S_PARAMS]
    w_slots, w_ids = st[S_WORK][W_SLOTS], st[S_WORK][W_IDS]
    # Whether each selected pair stood in alarm (for reinsert's new-alarm flags) comes with the
    # slot's entry (``_occupant``) rather than from last_tau: with millions of pairs that read
    # misses the cache (measured: 1.6 us of a 10 us step at M = 1e6). It travels to reinsert
    # in the withdrawn slot's entry, the same way.
    q = params[P_SLOTS_PER_BUCKET]
    count = 0
    for k in range(params[P_NBUCKETS]):
        size = 1 << k
        base = size - 1
        first = (n * q) % size
        for j in range(min(q, size)):
            slot = base + (first + j) % size
            raw = slots[slot]
            pid = raw if raw >= 0 else -2 - raw
            if raw != -1 and active[pid]:
                w_slots[count] = _occupant(slot, raw < -1)
                w_ids[count] = pid
                count += 1
    # Pairs switched back on, evaluated out of their slots, as many as the spare width holds.
    queue = st[S_QUEUE]
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
    slots, last_tau, horizon = st[S_SLOTS], st[S_LAST_TAU], st[S_HORIZON]
    where, last_step = st[S_INTS][WHERE], st[S_INTS][LAST_STEP]
    w_slots, w_ids, alarms, w_tau = (
        st[S_WORK][W_SLOTS],
        st[S_WORK][W_IDS],
        st[S_WORK][W_ALARMS],
        st[S_W_TAU],
    )
    new = st[S_WORK][W_NEW]
    regular = count - st[S_PARAMS][P_EXTRA]
    # Stable, so equal tau keep selection order (deterministic across runs).
    order = np.argsort(w_tau[:regular], kind="mergesort")
    nalarm = 0
    for i in range(regular):
        src = order[i]
        pid = w_ids[src]
        slot = w_slots[i]
        slot = slot if slot >= 0 else -2 - slot  # _rank_select's entry: slot and stood flag
        tau = w_tau[src]
        alarmed = tau < horizon[bucket_of(slot)]
        slots[slot] = _occupant(pid, alarmed)
        where[pid] = slot
        last_tau[pid] = tau
        last_step[pid] = n
        if alarmed:
            alarms[nalarm] = pid
            new[nalarm] = w_slots[src] >= 0  # it did not stand in alarm
            nalarm += 1
    for i in range(regular, count):
        pid = w_ids[i]
        tau = w_tau[i]
        last_tau[pid] = tau
        last_step[pid] = n
        alarmed = tau < horizon[bucket_of(where[pid])]
        slots[where[pid]] = _occupant(pid, alarmed)
        if alarmed:
            alarms[nalarm] = pid
            new[nalarm] = True
            nalarm += 1
    return nalarm


# --------------------------------------------------------------------------- deadline wheel


@nb.njit(cache=True, inline="always")
def _link_into(slots, ints, wheel, p, due):  # pragma: no cover - jitted
    """Link pair ``p`` at the head of its due step's slot (``ints``: the NEXT, PREV and WHERE
    rows). Loops over many pairs pass the arrays once: each view taken of the state tuple
    costs reference counting (about 100 ns a link when taken per pair, measured)."""
    slot = due & (wheel - 1)
    head = slots[slot]
    ints[NEXT, p] = head
    ints[PREV, p] = -1 - slot
    if head >= 0:
        ints[PREV, head] = p
    slots[slot] = p
    ints[WHERE, p] = due


@nb.njit(cache=True, inline="always")
def _link(st, p, due):  # pragma: no cover - jitted
    _link_into(st[S_SLOTS], st[S_INTS], st[S_PARAMS][P_WHEEL], p, due)


@nb.njit(cache=True, inline="always")
def _unlink(st, p):  # pragma: no cover - jitted
    nxt, prv = st[S_INTS][NEXT], st[S_INTS][PREV]
    if st[S_INTS][WHERE, p] < 0:
        return
    after = nxt[p]
    before = prv[p]
    if before >= 0:
        nxt[before] = after
    else:
        st[S_SLOTS][-1 - before] = after
    if after >= 0:
        prv[after] = before
    nxt[p] = -1
    prv[p] = -1
    st[S_INTS][WHERE, p] = -1


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
    params, last_tau, last_step = st[S_PARAMS], st[S_LAST_TAU], st[S_INTS][LAST_STEP]
    w_ids = st[S_WORK][W_IDS]
    slot = n & (params[P_WHEEL] - 1)
    p = st[S_SLOTS][slot]
    st[S_SLOTS][slot] = -1
    count = 0
    while p >= 0:
        after = st[S_INTS][NEXT, p]
        st[S_INTS][NEXT, p] = -1
        st[S_INTS][PREV, p] = -1
        st[S_INTS][WHERE, p] = -1
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
            slack[k] = last_tau[q] - (n - last_step[q]) * st[S_DT]
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
    params, last_tau, last_step = st[S_PARAMS], st[S_LAST_TAU], st[S_INTS][LAST_STEP]
    w_ids, alarms, w_tau, new = (
        st[S_WORK][W_IDS],
        st[S_WORK][W_ALARMS],
        st[S_W_TAU],
        st[S_WORK][W_NEW],
    )
    dt, latency = st[S_DT], st[S_LATENCY]
    max_interval = params[P_MAX_INTERVAL]
    backoff = params[P_BACKOFF]
    nalarm = 0
    for k in range(count):
        p = w_ids[k]
        tau = w_tau[k]
        waited = n - last_step[p]
        # Due now: its verdict had to cover until this step (a deferred one, longer: it stood).
        before = _stood(last_tau[p], (waited + latency) * dt)
        last_tau[p] = tau
        last_step[p] = n
        interval = deadline_interval(tau, dt, latency, max_interval)
        if tau < st[S_HORIZON][0]:
            if before:
                # It keeps alarming (resting contact, mostly): look again after twice the last
                # wait, up to the backoff. It stands in alarm until then, which covers it.
                interval = max(1, min(2 * waited, backoff))
            alarms[nalarm] = p
            new[nalarm] = not before
            nalarm += 1
        _link(st, p, n + interval)
    for k in range(count, count + params[P_DEFERRED]):
        p = w_ids[k]
        if last_tau[p] < (st[S_INTS][WHERE, p] - last_step[p] + latency) * dt:
            alarms[nalarm] = p
            new[nalarm] = not _stood(last_tau[p], (n - last_step[p] + latency) * dt)
            nalarm += 1
    return nalarm


# --------------------------------------------------------------------------- select-all


@nb.njit(cache=True)
def _all_select(st):  # pragma: no cover - jitted
    w_ids = st[S_WORK][W_IDS]
    count = 0
    for p in range(st[S_ACTIVE].shape[0]):
        if st[S_ACTIVE][p]:
            w_ids[count] = p
            count += 1
    return count


@nb.njit(cache=True)
def _all_reinsert(st, n, count):  # pragma: no cover - jitted
    w_ids, alarms, w_tau, new = (
        st[S_WORK][W_IDS],
        st[S_WORK][W_ALARMS],
        st[S_W_TAU],
        st[S_WORK][W_NEW],
    )
    nalarm = 0
    for k in range(count):
        p = w_ids[k]
        before = _stood(st[S_LAST_TAU][p], st[S_HORIZON][0])
        st[S_LAST_TAU][p] = w_tau[k]
        st[S_INTS][LAST_STEP, p] = n
        if w_tau[k] < st[S_HORIZON][0]:
            alarms[nalarm] = p
            new[nalarm] = not before
            nalarm += 1
    return nalarm


# --------------------------------------------------------------------------- the interface


@nb.njit(cache=True)
def select(st, n):  # pragma: no cover - jitted
    """Select the pairs to evaluate at step ``n`` into the ``W_IDS`` work row; their count."""
    if st[S_KIND] == RANK:
        count = _rank_select(st, n)
    elif st[S_KIND] == DEADLINE:
        count = _deadline_select(st, n)
    else:
        count = _all_select(st)
    st[S_PARAMS][P_COUNT] = count
    return count


@nb.njit(cache=True)
def reinsert(st, n, count):  # pragma: no cover - jitted
    """Store the verdicts of the ``count`` evaluated pairs (tau in ``st[S_W_TAU]``); #alarms."""
    if st[S_KIND] == RANK:
        return _rank_reinsert(st, n, count)
    if st[S_KIND] == DEADLINE:
        return _deadline_reinsert(st, n, count)
    return _all_reinsert(st, n, count)


@nb.njit(cache=True)
def restore(st, n, count):  # pragma: no cover - jitted
    """Undo ``select`` of step ``n`` (its evaluation failed): the step can be taken again."""
    w_ids = st[S_WORK][W_IDS]
    if st[S_KIND] == RANK:
        extra = st[S_PARAMS][P_EXTRA]
        queue = st[S_QUEUE]
        waiting = queue[0]
        for j in range(waiting - 1, -1, -1):
            queue[1 + extra + j] = queue[1 + j]
        for j in range(extra):
            queue[1 + j] = w_ids[count - extra + j]
        queue[0] = waiting + extra
    elif st[S_KIND] == DEADLINE:
        for k in range(count + st[S_PARAMS][P_DEFERRED]):
            p = w_ids[k]
            _unlink(st, p)
            _link(st, p, n)
    st[S_PARAMS][P_COUNT] = 0
    st[S_PARAMS][P_DEFERRED] = 0
    st[S_PARAMS][P_EXTRA] = 0


@nb.njit(cache=True)
def switch(st, ids, on, n_next):  # pragma: no cover - jitted
    """Switch pairs on or off; returns how many changed. ``n_next``: the next step to run."""
    changed = 0
    for k in range(ids.shape[0]):
        p = ids[k]
        if st[S_ACTIVE][p] == on:
            continue
        changed += 1
        st[S_ACTIVE][p] = on
        if on:
            # Nothing is known of its motion while it was off: it stands in alarm until its
            # next evaluation, which comes at the next selection.
            st[S_LAST_TAU][p] = -math.inf
            if st[S_KIND] == RANK:
                # Not reported as standing in alarm (see _stood) until evaluated.
                st[S_SLOTS][st[S_INTS][WHERE, p]] = p
                st[S_QUEUE][1 + st[S_QUEUE][0]] = p
                st[S_QUEUE][0] += 1
            elif st[S_KIND] == DEADLINE:
                _unlink(st, p)
                _link(st, p, n_next)
        elif st[S_KIND] == RANK:
            queue = st[S_QUEUE]
            kept = 0
            for j in range(queue[0]):
                if queue[1 + j] != p:
                    queue[1 + kept] = queue[1 + j]
                    kept += 1
            queue[0] = kept
        elif st[S_KIND] == DEADLINE:
            _unlink(st, p)
    return changed


@nb.njit(cache=True)
def make_due(st, p, n):  # pragma: no cover - jitted
    """Withdraw active pair ``p``'s verdict and make it due at step ``n`` (the step about to
    select): it stands in alarm (``last_tau = -inf``) until evaluated, as a pair switched on
    does. Used when the motion it was judged under broke its bounds."""
    if not st[S_ACTIVE][p]:
        return
    if st[S_KIND] == RANK:
        if st[S_LAST_TAU][p] == -math.inf:
            return  # already waiting in the queue
        st[S_LAST_TAU][p] = -math.inf
        st[S_SLOTS][st[S_INTS][WHERE, p]] = p
        st[S_QUEUE][1 + st[S_QUEUE][0]] = p
        st[S_QUEUE][0] += 1
    elif st[S_KIND] == DEADLINE:
        st[S_LAST_TAU][p] = -math.inf
        _unlink(st, p)
        _link(st, p, n)
    else:
        st[S_LAST_TAU][p] = -math.inf


@nb.njit(cache=True)
def deadline_classify(st):  # pragma: no cover - jitted
    """Deadline's initial classification: every active pair due ``s`` steps after step 0."""
    max_interval = st[S_PARAMS][P_MAX_INTERVAL]
    for p in range(st[S_ACTIVE].shape[0]):
        if st[S_ACTIVE][p]:
            _link(
                st, p, deadline_interval(st[S_LAST_TAU][p], st[S_DT], st[S_LATENCY], max_interval)
            )


@nb.njit(cache=True)
def deadline_carry(old, new, src, n):  # pragma: no cover - jitted
    """Fill the deadline state ``new`` (``ints`` and ``slots`` at -1) from ``old`` through ``src``.

    New pair ``p`` is old pair ``src[p]``, whose verdict (tau, last step, due step, switch) is
    carried unchanged, or a pair new to the set (``src[p] < 0``): it stands in alarm
    (``last_tau = -inf``) and is due at step ``n``, as a pair switched back on is. O(len(src)).
    """
    old_tau, old_active, old_ints = old[S_LAST_TAU], old[S_ACTIVE], old[S_INTS]
    tau, active, ints, slots = new[S_LAST_TAU], new[S_ACTIVE], new[S_INTS], new[S_SLOTS]
    wheel = new[S_PARAMS][P_WHEEL]
    for p in range(src.shape[0]):
        q = src[p]
        if q >= 0:
            tau[p] = old_tau[q]
            active[p] = old_active[q]
            ints[LAST_STEP, p] = old_ints[LAST_STEP, q]
            due = old_ints[WHERE, q]
            if due >= 0:
                _link_into(slots, ints, wheel, p, due)
        else:
            tau[p] = -math.inf
            active[p] = True
            ints[LAST_STEP, p] = n
            _link_into(slots, ints, wheel, p, n)
