"""DUAScheduler and the select-all baselines: layout, revisit intervals, alarms, protocol."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dua_mujoco import _core
from dua_mujoco.core.pairset import PairSet
from dua_mujoco.core.schedules import (
    DeadlineScheduler,
    DUAScheduler,
    Scheduler,
    SelectAllScheduler,
    Urgency,
    bucket_layout,
)
from dua_mujoco.core.urgency import PARALLEL_MIN
from dua_mujoco.exceptions import InvalidChoiceError, InvalidInputError, SchedulerError, ShapeError
from dua_mujoco.experiments.paper.world import SphereWorld


def bucket(s: DUAScheduler, pair: object) -> np.ndarray:
    """The bucket each pair's slot is in: slot i in bucket floor(log2(i + 1))."""
    return np.floor(np.log2(s.where[np.asarray(pair)] + 1.0)).astype(np.int64)


def reference_step(
    slots: np.ndarray, n: int, q: int, tau: dict[int, float]
) -> tuple[np.ndarray, list[int]]:
    """Obviously-correct Python version of one step: withdraw, sort, reinsert in bucket order."""
    nb = int(math.log2(len(slots) + 1))
    withdrawn = []
    for k in range(nb):
        size = 1 << k
        for j in range(min(q, size)):
            slot = size - 1 + (n * q + j) % size
            if slots[slot] >= 0:
                withdrawn.append(slot)
    ids = [int(slots[s]) for s in withdrawn]
    ranked = sorted(ids, key=lambda p: tau[p])
    new = slots.copy()
    for slot, pid in zip(withdrawn, ranked, strict=True):
        new[slot] = pid
    return new, ids


@pytest.mark.parametrize("m", [1, 2, 3, 7, 8, 100, 1000, 4097])
def test_layout_and_initial_partial_order(m: int) -> None:
    rng = np.random.default_rng(m)
    tau = rng.exponential(1.0, m)
    s = DUAScheduler(tau, dt=0.01)
    L, nslots = bucket_layout(m)
    assert math.ceil(math.log2(m + 1)) == L and nslots == 2**L - 1
    assert s.slots.shape == (nslots,)
    assert sorted(s.slots[s.slots >= 0].tolist()) == list(range(m))
    assert (s.slots[:m] >= 0).all() and (s.slots[m:] == -1).all()
    # Paper eq. 23: every pair in bucket k has tau <= every pair in bucket k + 1.
    for k in range(L - 1):
        here = s.slots[(1 << k) - 1 : (2 << k) - 1]
        later = s.slots[(2 << k) - 1 :]
        later = later[later >= 0]
        if later.size:
            assert tau[here].max() <= tau[later].min()


@pytest.mark.parametrize("q", [1, 2, 4])
@pytest.mark.parametrize("m", [5, 64, 300])
def test_matches_reference_and_revisits_exactly(q: int, m: int) -> None:
    rng = np.random.default_rng(7)
    s = DUAScheduler(rng.exponential(1.0, m), dt=0.01, slots_per_bucket=q)
    slots = s.slots.copy()
    last_seen: dict[int, int] = {}
    counts = []
    for n in range(1, 200):
        sel = s.select()
        tau = rng.exponential(1.0, sel.size)
        ref_slots, ref_ids = reference_step(slots, n, q, dict(zip(sel.tolist(), tau, strict=True)))
        assert sorted(ref_ids) == sorted(sel.tolist())
        # Each selected pair was placed at its previous visit exactly `interval` steps ago.
        for p in sel.tolist():
            if p in last_seen:
                placed_bucket, step = last_seen[p]
                assert n - step == s.interval[placed_bucket]
        s.update(sel, tau)
        np.testing.assert_array_equal(s.slots, ref_slots)
        slots = ref_slots
        for p in sel.tolist():
            last_seen[p] = (int(bucket(s, p)), n)
            assert s.next_due(np.array([p]))[0] == n + s.interval[bucket(s, p)]
        counts.append(sel.size)
    # Constant work: the same number of slots every step once the last bucket is full or skipped.
    L = s.nbuckets
    full = sum(min(q, 1 << k) for k in range(L - 1))
    assert min(counts) >= full and max(counts) <= s.evaluations_per_step


def test_every_pair_evaluated_within_its_interval() -> None:
    m = 1000
    rng = np.random.default_rng(1)
    s = DUAScheduler(rng.exponential(1.0, m), dt=0.01)
    last = np.zeros(m, dtype=int)
    for n in range(1, 3 * (1 << s.nbuckets)):
        sel = s.select()
        assert (n - last[sel] <= s.interval[-1]).all()
        last[sel] = n
        s.update(sel, rng.exponential(1.0, sel.size))
    assert (last > 0).all()


@settings(max_examples=60, deadline=None)
@given(
    m=st.integers(1, 200),
    latency=st.integers(0, 2),
    dt=st.floats(1e-4, 1.0),
    seed=st.integers(0, 2**31),
)
def test_alarm_rule(m: int, latency: int, dt: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    tau0 = rng.exponential(dt * 20, m)
    s = DUAScheduler(tau0, dt=dt, latency=latency)
    buckets = bucket(s, np.arange(m))
    expect = np.flatnonzero(tau0 < ((1 << buckets) + latency) * dt)
    np.testing.assert_array_equal(np.sort(s.initial_alarms), expect)
    for _ in range(5):
        sel = s.select()
        tau = rng.exponential(dt * 20, sel.size)
        alarms = s.update(sel, tau)
        size = 1 << bucket(s, sel)
        np.testing.assert_array_equal(np.sort(alarms), np.sort(sel[tau < (size + latency) * dt]))
        # The i-th most urgent went to the i-th smallest bucket.
        assert (np.diff(size[np.argsort(tau, kind="stable")]) >= 0).all()


def test_fused_step_equals_select_update() -> None:
    world_a = SphereWorld(30, seed=5, radius=0.05)
    world_b = SphereWorld(30, seed=5, radius=0.05)
    pairs = world_a.pairs()
    ids = np.arange(len(pairs))
    tau0 = pairs.tau(ids, world_a.positions, world_a.velocities)
    a = DUAScheduler(tau0, dt=world_a.dt)
    b = DUAScheduler(tau0, dt=world_b.dt)
    for _ in range(100):
        world_a.step()
        world_b.step()
        sel = a.select()
        alarms_a = a.update(sel, pairs.tau(sel, world_a.positions, world_a.velocities))
        alarms_b = b.step_points(pairs, world_b.positions, world_b.velocities)
        np.testing.assert_array_equal(np.sort(alarms_a), np.sort(alarms_b))
        np.testing.assert_array_equal(a.slots, b.slots)
        np.testing.assert_array_equal(a.last_tau, b.last_tau)


def test_fused_step_takes_new_converted_or_reshaped_inputs() -> None:
    """The fused step remembers the arrays of its latest call; new arrays, lists, float32 and an
    array reshaped in place between calls must give the protocol's alarms all the same."""
    world = SphereWorld(20, seed=7, radius=0.08, accel=2.0, dt=0.01)
    pairs = world.pairs()
    tau0 = pairs.tau(np.arange(len(pairs)), world.positions, world.velocities)
    fused, protocol = DUAScheduler(tau0, dt=world.dt), DUAScheduler(tau0, dt=world.dt)
    flat = np.zeros(world.positions.size)
    for k in range(60):
        world.step()
        c, v = world.positions, world.velocities
        if k % 4 == 1:
            c, v = c.copy(), v.copy()  # new arrays
        elif k % 4 == 2:
            c, v = c.tolist(), v.astype(np.float32)  # converted
        elif k % 4 == 3:
            flat.shape = (flat.size,)  # the same object, reshaped in place each time
            flat[:] = world.positions.ravel()
            flat.shape = world.positions.shape
            c = flat
        ids = protocol.select()
        want = protocol.update(ids, pairs.tau(ids, np.asarray(c, float), np.asarray(v, float)))
        got = fused.step_points(pairs, c, v)
        np.testing.assert_array_equal(np.sort(got), np.sort(want))
        np.testing.assert_array_equal(fused.last_tau, protocol.last_tau)


def test_halfspace_pairs_in_fused_step() -> None:
    # One sphere falling onto the plane z = 0 (normal +z), one far away.
    pairs = PairSet([0, 0, 1], [1, 0, 0], [0.2, 0.1, 0.1], 1.0, halfspace=[False, True, True])
    centers = np.array([[0.0, 0.0, 0.5], [5.0, 0.0, 3.0]])
    vel = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 0.0]])
    normals, offsets = np.array([[0.0, 0.0, 1.0]]), np.array([0.0])
    tau = pairs.tau([0, 1, 2], centers, vel, (normals, offsets))
    # Sphere 0 reaches the plane when 0.5 - t - t^2/2 = 0.1.
    assert tau[1] == pytest.approx(-1 + math.sqrt(1 + 0.8), rel=1e-9)
    assert tau[1] <= -1 + math.sqrt(1 + 0.8)
    assert tau[2] == pytest.approx(math.sqrt(2 * 2.9), rel=1e-9)
    s = DUAScheduler(tau, dt=0.2)  # pair 1 lands in bucket 0: horizon (1 + 1) * 0.2 > 0.34
    np.testing.assert_array_equal(s.initial_alarms, [1])
    alarms = s.step_points(pairs, centers, vel, (normals, offsets))
    # The fused step says what the protocol says; pair 1 (bucket 0, every step) still alarms.
    ref = DUAScheduler(tau, dt=0.2)
    ids = ref.select()
    expected = ref.update(ids, pairs.tau(ids, centers, vel, (normals, offsets)))
    assert sorted(alarms.tolist()) == sorted(expected.tolist())
    assert 1 in alarms.tolist()


def test_switching_pairs_off_and_on() -> None:
    m = 50
    rng = np.random.default_rng(3)
    s = DUAScheduler(rng.exponential(1.0, m), dt=0.01)
    s.set_active([0, 1, 2], False)
    for _ in range(64):
        sel = s.select()
        assert not set(sel.tolist()) & {0, 1, 2}
        s.update(sel, rng.exponential(1.0, sel.size))
    changes = s.activation_changes
    s.set_active([1], True)
    assert s.activation_changes == changes + 1
    # Until its first evaluation the pair stands in alarm (its stale tau says nothing).
    assert s.alarm_state([0, 1, 2]).tolist() == [False, True, False]
    sel = s.select()
    assert 1 in sel.tolist()  # re-activated pairs are evaluated at once
    tau = np.where(sel == 1, 0.0, 1.0)
    assert 1 in s.update(sel, tau).tolist()
    assert s.tau(1) == 0.0
    # Evaluated far from anything, the switched-on pair leaves the alarm.
    s.set_active([2], True)
    sel = s.select()
    s.update(sel, np.full(sel.size, 1e9))
    assert not s.alarm_state([2])[0]


def test_protocol_errors() -> None:
    s = DUAScheduler(np.ones(10), dt=0.01)
    with pytest.raises(SchedulerError, match="select"):
        s.update(np.array([0]), np.array([1.0]))
    sel = s.select()
    with pytest.raises(SchedulerError, match="twice"):
        s.select()
    with pytest.raises(SchedulerError, match="exactly the ids"):
        s.update((sel + 1) % 10, np.ones(sel.size))
    with pytest.raises(InvalidInputError, match="nan"):
        s.update(sel, np.full(sel.size, np.nan))


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"dt": 0.0}, InvalidInputError, "dt = 0.0"),
        ({"dt": -1.0}, InvalidInputError, "seconds > 0"),
        ({"dt": True}, InvalidInputError, "dt = True"),
        ({"dt": float("nan")}, InvalidInputError, "dt = nan"),
        ({"dt": 0.1, "latency": -1}, InvalidInputError, "latency = -1"),
        ({"dt": 0.1, "slots_per_bucket": 3}, InvalidInputError, r"a power of two \(1, 2, 4"),
    ],
)
def test_bad_construction(kwargs: dict, error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        DUAScheduler(np.ones(4), **kwargs)


def test_bad_tau0() -> None:
    with pytest.raises(ShapeError, match=r"\(2, 2\)"):
        DUAScheduler(np.ones((2, 2)), dt=0.1)
    with pytest.raises(InvalidInputError, match=r"tau0\[1\] = -1"):
        DUAScheduler(np.array([1.0, -1.0]), dt=0.1)


def test_select_all_baselines() -> None:
    tau = np.array([0.005, 0.5, 0.015, np.inf])
    sa = SelectAllScheduler(tau, dt=0.01, latency=1)
    np.testing.assert_array_equal(sa.initial_alarms, [0, 2])
    sel = sa.select()
    np.testing.assert_array_equal(sel, [0, 1, 2, 3])
    np.testing.assert_array_equal(sa.update(sel, [1.0, 0.001, 1.0, 1.0]), [1])
    assert sa.most_urgent() == 1
    sad = SelectAllScheduler([0.3, -0.1, 0.2], dt=0.01, urgency="distance")
    assert sad.urgency is Urgency.DISTANCE
    np.testing.assert_array_equal(sad.initial_alarms, [1])
    with pytest.raises(InvalidChoiceError, match="'tau', 'distance'"):
        SelectAllScheduler(tau, dt=0.01, urgency="speed")


def test_most_urgent_is_bucket_zero() -> None:
    tau = np.array([3.0, 1.0, 2.0, 0.5, 9.0])
    s = DUAScheduler(tau, dt=0.01)
    assert s.most_urgent() == 3


# --------------------------------------------------------------------------- deadline schedule


def reference_interval(tau: float, dt: float, latency: int, max_interval: int) -> int:
    """The largest s in [1, max_interval] with (s + latency) dt < tau, by counting up."""
    s = 1
    while s < max_interval and (s + 1 + latency) * dt < tau:
        s += 1
    return s


class ReferenceDeadline:
    """The deadline rule with a dict of due steps: obviously correct, O(M) a step."""

    def __init__(self, tau0, dt, latency, cap, max_interval, backoff):
        self.dt, self.latency, self.cap, self.max_interval = dt, latency, cap, max_interval
        self.backoff = min(backoff, max_interval)
        self.last_tau = np.array(tau0, dtype=float)
        self.last_step = np.zeros(len(tau0), dtype=int)
        self.due = {p: reference_interval(t, dt, latency, max_interval) for p, t in enumerate(tau0)}
        self.n = 0

    def select(self) -> tuple[list[int], list[int]]:
        self.n += 1
        n = self.n
        due = sorted(p for p, d in self.due.items() if d == n)
        deferred: list[int] = []
        if self.cap and len(due) > self.cap:
            slack = {p: self.last_tau[p] - (n - self.last_step[p]) * self.dt for p in due}
            due.sort(key=lambda p: slack[p])
            due, deferred = due[: self.cap], due[self.cap :]
            for p in deferred:
                self.due[p] = n + 1
        return due, deferred

    def update(self, ids, tau, deferred) -> set[int]:
        n, dt, lat = self.n, self.dt, self.latency
        alarms = set()
        for p, t in zip(ids, tau, strict=True):
            waited = n - self.last_step[p]
            old = self.last_tau[p]
            stood = old > -np.inf and old < (waited + lat) * dt
            self.last_tau[p], self.last_step[p] = t, n
            self.due[p] = n + reference_interval(t, dt, lat, self.max_interval)
            if t < (1 + lat) * dt:
                alarms.add(p)
                if stood:  # alarming again: back off
                    self.due[p] = n + min(2 * waited, self.backoff)
        for p in deferred:
            if self.last_tau[p] < (self.due[p] - self.last_step[p] + lat) * dt:
                alarms.add(p)
        return alarms


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    m=st.integers(1, 60),
    latency=st.integers(0, 2),
    cap=st.sampled_from([None, 1, 3, 10]),
    max_interval=st.sampled_from([1, 7, 64]),
    backoff=st.sampled_from([1, 2, 8, 100]),
)
def test_deadline_matches_reference(
    seed: int, m: int, latency: int, cap: int | None, max_interval: int, backoff: int
) -> None:
    rng = np.random.default_rng(seed)
    dt = 0.01

    def draw(k: int) -> np.ndarray:
        # Distinct values (no ties in the slack order), some below one step, some infinite.
        t = rng.exponential(0.05, size=k) + rng.uniform(0, 1e-9, size=k)
        t[rng.uniform(size=k) < 0.1] = np.inf
        return t

    tau0 = draw(m)
    s = DeadlineScheduler(
        tau0,
        dt=dt,
        latency=latency,
        max_evals_per_step=cap,
        max_interval=max_interval,
        alarm_backoff=backoff,
    )
    ref = ReferenceDeadline(tau0, dt, latency, cap, max_interval, backoff)
    assert set(s.initial_alarms.tolist()) == {p for p in range(m) if tau0[p] < (1 + latency) * dt}
    for _ in range(40):
        ids = s.select()
        want, deferred = ref.select()
        assert sorted(ids.tolist()) == sorted(want)
        assert s.state.params[6] == len(deferred)  # P_DEFERRED
        tau = draw(ids.size)
        alarms = s.update(ids, tau)
        assert set(alarms.tolist()) == ref.update(ids.tolist(), tau.tolist(), deferred)
        assert s.deferred == len(deferred)
        # Every pair stands in alarm exactly when its verdict does not cover its next due step.
        due = np.array([ref.due[p] for p in range(m)])
        covered = ref.last_tau >= (due - ref.last_step + latency) * dt
        np.testing.assert_array_equal(s.alarm_state(), ~covered)
        np.testing.assert_array_equal(s.next_due(np.arange(m)), due)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    m=st.integers(1, 40),
    kind=st.sampled_from([0, 1, 2]),
    cap=st.sampled_from([0, 3]),
    max_interval=st.sampled_from([1, 4, 64]),
)
def test_made_due_pairs_are_selected_as_make_due_then_select_selects_them(
    seed: int, m: int, kind: int, cap: int, max_interval: int
) -> None:
    """The native step hands a deadline schedule its flagged bodies' pairs in one pass
    (select_made_due): the same pairs, in the same order (the four-lane kernel's groups follow
    it), and the same state after, as make_due of each group's members in turn, then select.
    The groups overlap (a pair of two flagged bodies), repeat, and hold pairs that are switched
    off or due at this step anyway."""
    rng = np.random.default_rng(seed)
    dt = 0.01
    tau0 = rng.exponential(0.05, size=m)
    a, b = (_core.Schedule(kind, dt, 0, tau0, cap=cap, max_interval=max_interval) for _ in range(2))
    for n in range(1, 25):
        off = rng.choice(m, size=min(m, rng.integers(0, 3)), replace=False).astype(np.int64)
        back = off[: rng.integers(0, off.size + 1)]
        for s in (a, b):
            s.switch(off, False, n)
            s.switch(back, True, n)
        sizes = rng.integers(0, 6, size=rng.integers(1, 6))
        start = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        members = rng.integers(0, m, size=start[-1]).astype(np.int64)
        groups = rng.integers(0, sizes.size, size=rng.integers(0, 4)).astype(np.int64)
        for g in groups:
            for p in members[start[g] : start[g + 1]]:
                a.make_due(int(p), n)
        count = a.select(n)
        assert b.select_made_due(groups, start, members, n) == count
        np.testing.assert_array_equal(a.work[:, :count], b.work[:, :count])
        for field in ("ints", "slots", "last_tau", "params", "queue"):
            np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
        tau = rng.exponential(0.05, size=count)
        a.w_tau[:count] = b.w_tau[:count] = tau
        assert a.reinsert(n, count) == b.reinsert(n, count)
    with pytest.raises(ShapeError, match="groups must lie in"):
        b.select_made_due(np.array([1]), np.array([0, 0]), np.zeros(0, np.int64), 30)


def test_deadline_interval_is_the_latest_safe_step() -> None:
    dt = 0.002
    s = DeadlineScheduler(np.array([0.0, 0.0039, 0.004, 0.0101, np.inf]), dt=dt, latency=1)
    # (s + 1) dt < tau: 0.004 allows no s (it alarms: a verdict must cover the wait strictly);
    # 0.0101 allows s = 4; inf the longest interval.
    np.testing.assert_array_equal(s.next_due(np.arange(5)), [1, 1, 1, 4, 1024])
    np.testing.assert_array_equal(s.initial_alarms, [0, 1, 2])
    # A verdict computed in floating point never allows more than its tau covers, including
    # at the exact multiples of dt where the division rounds.
    taus = np.concatenate([np.linspace(0.0, 0.1, 2001), np.arange(1, 50) * dt])
    t = DeadlineScheduler(taus, dt=dt, latency=1)
    due = t.next_due(np.arange(taus.size))
    assert ((taus <= 2 * dt) | ((due + 1) * dt < taus)).all()
    assert (due == [reference_interval(float(x), dt, 1, 1024) for x in taus]).all()


@pytest.mark.parametrize(
    ("dt", "latency", "horizon", "max_interval"),
    [(0.002, 1, None, 1024), (0.01, 0, None, 7), (1 / 3, 3, 1.0, 1024), (0.005, 0, 0.012, 1)],
)
def test_reinsert_waits_are_the_deadline_interval(
    dt: float, latency: int, horizon: float | None, max_interval: int
) -> None:
    """The reinsertion computes its waits four at a time in lanes (DeadlineIntervals): each
    evaluated pair is linked exactly deadline_interval(tau) steps on (the largest s whose wait
    its tau covers strictly), on the verdicts where the guess from the division is one off
    either way: tau on the grid of waits ((s + latency) dt + extra) and one ulp either side;
    also 0, negative, infinite and NaN taus, and random ones. 203 pairs: whole groups of four,
    a ragged last group and more than one chunk of 64."""
    # Every pair due at step 1, none standing in alarm (-inf: never reported), so an alarming
    # verdict's wait is its interval too, not the backoff.
    sched = _core.Schedule(
        1, dt, latency, np.full(203, -np.inf), max_interval=max_interval, alarm_horizon=horizon
    )
    extra = sched.alarm_horizon - dt
    grid = (np.arange(1, 41) + latency) * dt + extra
    rng = np.random.default_rng(7)
    taus = np.concatenate(
        [
            grid,
            np.nextafter(grid, np.inf),
            np.nextafter(grid, -np.inf),
            [0.0, -1.0, np.inf, -np.inf, np.nan, 1e300, max_interval * dt * 4],
            rng.uniform(0.0, 60 * dt, 76),
        ]
    )
    assert taus.size == 203
    assert sched.select(1) == 203
    ids = sched.work[1, :203].copy()
    sched.w_tau[:203] = taus
    sched.reinsert(1, 203)
    waits = sched.ints[0, ids] - 1
    want = [_core.deadline_interval(float(t), dt, latency, max_interval, extra) for t in taus]
    np.testing.assert_array_equal(waits, want)
    # And by counting up: the largest s in [1, max_interval] whose wait tau covers strictly.
    for t, got in zip(taus, waits, strict=True):
        s = 1
        while s < max_interval and (s + 1 + latency) * dt + extra < t:
            s += 1
        assert got == s


def test_deadline_backs_off_a_pair_that_keeps_alarming() -> None:
    """A pair in contact (tau 0 at every evaluation) is looked at after 1, 2, 4, 8, 8... steps
    and stands in alarm at every step; once clear it is revisited as its tau allows, and its
    next alarm is evaluated again at the very next step."""
    s = DeadlineScheduler(np.array([0.0, np.inf]), dt=0.01, latency=0, alarm_backoff=8)
    evaluated = []
    for n in range(1, 41):
        ids = s.select()
        if ids.size:
            evaluated.append(n)
        s.update(ids, np.zeros(ids.size))
        assert s.alarm_state([0])[0]
    assert evaluated == [1, 3, 7, 15, 23, 31, 39]
    # Clear at its next evaluation (step 47): revisited when its tau runs out, without alarm.
    while not (ids := s.select()).size:
        s.update(ids, np.zeros(0))
    assert s.step_count + 1 == 47
    s.update(ids, [0.051])
    assert not s.alarm_state([0])[0]
    assert s.next_due([0])[0] == 47 + 5
    with pytest.raises(InvalidInputError, match="alarm_backoff"):
        DeadlineScheduler(np.ones(2), dt=0.01, alarm_backoff=0)
    # Without backoff a standing alarm is evaluated every step: select-all's alarms exactly.
    t = DeadlineScheduler(np.array([0.0]), dt=0.01, latency=0, alarm_backoff=1)
    for _ in range(5):
        assert t.select().tolist() == [0]
        t.update([0], [0.0])


def test_deadline_switching_and_errors() -> None:
    s = DeadlineScheduler(np.full(4, np.inf), dt=0.01, latency=0)
    assert s.select().size == 0
    s.update(np.zeros(0, dtype=np.int64), np.zeros(0))
    s.set_active([2], False)
    assert not s.alarm_state([2])[0]
    s.set_active([2], True)
    assert s.alarm_state([2])[0]  # stands in alarm until evaluated
    assert s.next_due(np.array([2]))[0] == 2
    ids = s.select()
    assert ids.tolist() == [2]
    with pytest.raises(SchedulerError, match="between select"):
        s.set_active([1], False)
    assert s.update(ids, [np.inf]).size == 0
    assert not s.alarm_state([2])[0]
    # The schedule names a pair id out of range (Python does not check it again).
    msg = r"pair id {} \(ids\[1\]\) is out of range: the schedule has 4 pairs \(valid ids 0\.\.3\)"
    for bad in (4, -1):
        with pytest.raises(InvalidInputError, match=msg.format(bad)):
            s.set_active([0, bad], False)
    assert s.active.all()  # nothing switched
    for bad in (0, -1, True, 1.5):
        with pytest.raises(InvalidInputError, match="max_evals_per_step"):
            DeadlineScheduler(np.ones(2), dt=0.01, max_evals_per_step=bad)
    with pytest.raises(InvalidInputError, match="max_interval"):
        DeadlineScheduler(np.ones(2), dt=0.01, max_interval=0)


def test_the_alarm_horizon_travels_in_seconds() -> None:
    """The schedule takes the alarm horizon in seconds, one period when not given (no sentinel):
    a verdict covering less than the wait plus the horizon beyond one period alarms. Below one
    period, or not finite, the value is refused by name."""
    from dua_mujoco import _core
    from dua_mujoco.core.schedules.state import DEADLINE

    tau = np.array([0.015, 0.025, 0.035])
    one = _core.Schedule(DEADLINE, 0.01, 0, tau)
    assert one.alarm_horizon == 0.01
    assert _core.stands(one, np.arange(3)).tolist() == [False, False, False]
    three = _core.Schedule(DEADLINE, 0.01, 0, tau, alarm_horizon=0.03)
    assert three.alarm_horizon == 0.03
    assert _core.stands(three, np.arange(3)).tolist() == [True, True, False]
    for bad, shown in ((0.0, "0"), (0.005, "0.005"), (math.inf, "inf"), (math.nan, "nan")):
        with pytest.raises(InvalidInputError, match=rf"alarm_horizon = {shown} .*one period"):
            _core.Schedule(DEADLINE, 0.01, 0, tau, alarm_horizon=bad)


def test_schedules_share_the_fused_step_on_free_spheres() -> None:
    """``step_points`` and the Python protocol give the same alarms for every schedule."""
    world = SphereWorld(12, seed=3, radius=0.08, accel=2.0, dt=0.01)
    pairs = world.pairs()
    tau0 = pairs.tau(np.arange(len(pairs)), world.positions, world.velocities)
    makers = [
        lambda t: DUAScheduler(t, dt=0.01),
        lambda t: DeadlineScheduler(t, dt=0.01, max_evals_per_step=5),
        lambda t: SelectAllScheduler(t, dt=0.01),
    ]
    for make in makers:
        fused, protocol = make(tau0), make(tau0)
        for _ in range(60):
            world.step()
            c, v = world.positions, world.velocities
            a = fused.step_points(pairs, c, v)
            ids = protocol.select()
            b = protocol.update(ids, pairs.tau(ids, c, v))
            assert sorted(a.tolist()) == sorted(b.tolist())
            np.testing.assert_array_equal(fused.last_tau, protocol.last_tau)
            np.testing.assert_array_equal(fused.last_new, protocol.last_new)


def test_of_wraps_a_schedule_without_classifying_again() -> None:
    """``Scheduler.of`` shows an existing ``_core.Schedule`` (the runtime's) as the scheduler of
    its kind: the same buffers and count, options read back, nothing classified again."""
    world = SphereWorld(12, seed=4, radius=0.08, accel=2.0, dt=0.01)
    pairs = world.pairs()
    tau0 = pairs.tau(np.arange(len(pairs)), world.positions, world.velocities)
    for own in (
        DUAScheduler(tau0, dt=0.01, slots_per_bucket=2),
        DeadlineScheduler(tau0, dt=0.01, latency=0, max_evals_per_step=7, alarm_backoff=4),
        SelectAllScheduler(tau0, dt=0.01),
    ):
        for _ in range(5):
            world.step()
            own.step_points(pairs, world.positions, world.velocities)
        seen = Scheduler.of(own.core)
        assert type(seen) is type(own)
        assert seen.step_count == own.step_count == 5
        assert seen.last_tau is not own.last_tau and np.shares_memory(seen.last_tau, own.last_tau)
        np.testing.assert_array_equal(seen.alarm_state(), own.alarm_state())
        np.testing.assert_array_equal(seen.initial_alarms, np.flatnonzero(own.alarm_state()))
        for name in ("interval", "slots_per_bucket", "max_evals_per_step", "max_interval",
                     "alarm_backoff", "urgency", "alarm_distance"):  # fmt: skip
            if hasattr(own, name):
                np.testing.assert_array_equal(getattr(seen, name), getattr(own, name))
        # Steps taken through either are the other's: step_count reads the schedule.
        world.step()
        seen.step_points(pairs, world.positions, world.velocities)
        assert own.step_count == 6
    with pytest.raises(InvalidInputError, match=r"_core\.Schedule"):
        Scheduler.of(tau0)  # type: ignore[arg-type]


def test_pair_bounds_changed_in_place_are_the_ones_evaluated() -> None:
    """A PairSet's bounds are views of the records the native core reads; its indices are
    read-only (the records and the index checks hold them)."""
    world = SphereWorld(8, seed=2, radius=0.05, accel=1.0, dt=0.01)
    pairs = world.pairs()
    ids = np.arange(len(pairs))
    c, v = world.positions, world.velocities
    before = pairs.tau(ids, c, v)
    s = DUAScheduler(before, dt=0.01)
    pairs.accel[:] = 50.0
    after = pairs.tau(ids, c, v)
    assert (after <= before).all() and (after < before).any()
    np.testing.assert_array_equal(pairs.records[:, 4], 50.0)
    s.step_points(pairs, c, v)
    sel = s.last_selected
    np.testing.assert_array_equal(s.last_tau[sel], after[sel])
    with pytest.raises(ValueError, match="read-only"):
        pairs.first[0] = 3
    with pytest.raises(InvalidInputError, match="build a new PairSet"):
        pairs.second = pairs.second.copy()


def test_large_batches_split_over_threads_give_the_same_tau() -> None:
    """From ``PARALLEL_MIN`` rows on a batch runs on two threads: the same values, bit for bit."""
    world = SphereWorld(400, seed=9, radius=0.02, accel=1.0)
    pairs = world.pairs()
    ids = np.arange(len(pairs))
    assert ids.size >= PARALLEL_MIN
    whole = pairs.tau(ids, world.positions, world.velocities)
    parts = [pairs.tau(b, world.positions, world.velocities) for b in np.array_split(ids, 7)]
    np.testing.assert_array_equal(whole, np.concatenate(parts))
