"""The completeness theorem (docs/theory.md) exercised in ghost-sphere worlds.

In a ``SphereWorld`` the declared bounds hold exactly, so the theorem applies: every collision onset
of a pair must be flagged by that pair's latest evaluation at or before the onset. Onsets are found
on a fine grid of sub-step times from the closed-form trajectories (any grid onset is a real
collision, so the check can only under-count onsets, never invent them). The same check fails
when the alarm rule is weakened, which shows it has teeth.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from dua_mujoco.core.schedules import (
    DeadlineScheduler,
    DUAScheduler,
    Schedule,
    Scheduler,
    SelectAllScheduler,
)
from dua_mujoco.experiments.paper.world import AccelProfile, SphereWorld


@dataclasses.dataclass
class Outcome:
    onsets: int
    missed: list[tuple[int, float]]
    late: list[tuple[int, float]]
    evaluations: int


def run_world(
    world: SphereWorld,
    *,
    steps: int,
    latency: int,
    substeps: int = 8,
    make: Callable[[np.ndarray], Scheduler] | None = None,
    weaken=None,
    switch_every: int = 0,
) -> Outcome:
    """Drive a scheduler on ``world`` and check every onset against the theorem.

    ``make(tau0)`` builds the scheduler (default DUA at the world's step and ``latency``;
    :func:`_scheduler` makes one), ``weaken(sched)`` replaces a DUA scheduler's horizons; with
    ``switch_every`` a random tenth of the pairs is switched off and as many back on every that
    many steps, and onsets of pairs switched off are not counted (contact is intended there).
    """
    pairs = world.pairs()
    ids = np.arange(len(pairs))
    tau0 = pairs.tau(ids, world.positions, world.velocities)
    rng = np.random.default_rng(12345)
    sched = DUAScheduler(tau0, dt=world.dt, latency=latency) if make is None else make(tau0)
    if weaken is not None:
        sched.horizon[:] = weaken(sched)
    # Latest evaluation of every pair: its time, whether it alarmed, and whether the one before did.
    eval_time = np.zeros(len(pairs))
    alarmed = np.zeros(len(pairs), dtype=bool)
    alarmed[sched.initial_alarms] = True
    prev_alarmed = np.ones(len(pairs), dtype=bool)  # nothing is known before time 0
    i, j = pairs.first, pairs.second
    eps = pairs.eps

    def touching(pos: np.ndarray) -> np.ndarray:
        return np.linalg.norm(pos[j] - pos[i], axis=1) <= eps

    in_contact = touching(world.positions)
    onsets, missed, late, evaluations = 0, [], [], 0

    def check(new: np.ndarray, t: float) -> None:
        nonlocal onsets
        for p in np.flatnonzero(new & sched.active):
            onsets += 1
            if not alarmed[p]:
                missed.append((int(p), t))
            elif not prev_alarmed[p] and t < eval_time[p] + latency * world.dt - 1e-12:
                late.append((int(p), t))

    for step in range(steps):
        if switch_every and step % switch_every == 0:
            off = rng.choice(len(pairs), size=len(pairs) // 10, replace=False)
            on = rng.choice(len(pairs), size=len(pairs) // 10, replace=False)
            sched.set_active(off, False)
            sched.set_active(on, True)
            changed = np.union1d(off, on)
            # A pair switched on stands in alarm until it is evaluated (the scheduler says so).
            alarmed[changed] = sched.alarm_state(changed) & sched.active[changed]
            prev_alarmed[changed] = True
        for k in range(1, substeps):
            now = touching(world.positions_at(world.dt * k / substeps))
            check(now & ~in_contact, world.time + world.dt * k / substeps)
            in_contact = now
        world.step()
        sel = sched.select()
        tau = pairs.tau(sel, world.positions, world.velocities)
        out = sched.update(sel, tau)
        evaluations += sel.size
        prev_alarmed[sel] = alarmed[sel]
        alarmed[sel] = False
        alarmed[out] = True
        eval_time[sel] = world.time
        now = touching(world.positions)
        check(now & ~in_contact, world.time)
        in_contact = now
    return Outcome(onsets, missed, late, evaluations)


def dense_world(seed: int, profile: AccelProfile = AccelProfile.UNIFORM) -> SphereWorld:
    return SphereWorld(
        24, seed=seed, box=1.0, radius=0.07, accel=2.0, speed=0.5, dt=0.01, profile=profile
    )


def _scheduler(
    schedule: Schedule, latency: int, **options: Any
) -> Callable[[np.ndarray], Scheduler]:
    """``run_world``'s ``make``: the library's scheduler of ``schedule`` at ``dense_world``'s
    step (0.01 s), with its ``options``."""
    kind = {Schedule.DUA: DUAScheduler, Schedule.DEADLINE: DeadlineScheduler}
    make = kind.get(schedule, SelectAllScheduler)
    return lambda tau0: make(tau0, dt=0.01, latency=latency, **options)


@pytest.mark.parametrize("latency", [0, 1])
@pytest.mark.parametrize("profile", list(AccelProfile))
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_onset_is_flagged(latency: int, profile: AccelProfile, seed: int) -> None:
    out = run_world(dense_world(seed, profile), steps=300, latency=latency)
    assert out.onsets >= 5, "the world must be dense enough for collisions to happen"
    assert out.missed == []
    assert out.late == []


@pytest.mark.parametrize("q", [2, 4])
def test_budget_knob_keeps_completeness(q: int) -> None:
    out = run_world(
        dense_world(3), steps=200, latency=1, make=_scheduler(Schedule.DUA, 1, slots_per_bucket=q)
    )
    assert out.onsets >= 5
    assert out.missed == []


def test_select_all_is_complete() -> None:
    out = run_world(dense_world(4), steps=200, latency=1, make=_scheduler(Schedule.SELECT_ALL, 1))
    assert out.onsets >= 5
    assert out.missed == []


def test_weakened_alarm_rule_misses_collisions() -> None:
    """The paper's off-by-one (bucket i revisited after 2^(i-1) steps) and dropped latency miss."""

    def half_interval(s: DUAScheduler) -> np.ndarray:
        return (s.interval / 2 + s.latency) * s.dt

    def no_latency(s: DUAScheduler) -> np.ndarray:
        return s.interval * s.dt

    def failures(weaken) -> int:
        outcomes = [
            run_world(
                dense_world(seed, AccelProfile.BANG_BANG), steps=300, latency=1, weaken=weaken
            )
            for seed in range(4)
        ]
        return sum(len(o.missed) + len(o.late) for o in outcomes)

    assert failures(half_interval) > 0
    assert failures(no_latency) > 0


def _deadline(latency: int, cap: int | None = None, *, backoff: int = 8):
    return _scheduler(Schedule.DEADLINE, latency, max_evals_per_step=cap, alarm_backoff=backoff)


@pytest.mark.parametrize("backoff", [1, 8])
@pytest.mark.parametrize("latency", [0, 1])
@pytest.mark.parametrize("profile", list(AccelProfile))
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_deadline_flags_every_onset(
    latency: int, profile: AccelProfile, seed: int, backoff: int
) -> None:
    """With or without backing off the revisits of pairs that keep alarming."""
    make = _deadline(latency, backoff=backoff)
    out = run_world(dense_world(seed, profile), steps=300, latency=latency, make=make)
    assert out.onsets >= 5
    assert out.missed == []
    assert out.late == []
    # Each pair when its tau runs out: fewer evaluations than select-all's 276 a step.
    assert out.evaluations < 0.6 * 276 * 300


@pytest.mark.parametrize("cap", [1, 4, 16])
@pytest.mark.parametrize("latency", [0, 1])
def test_deadline_with_a_cap_flags_every_onset(cap: int, latency: int) -> None:
    """Over the cap the most urgent are served; the rest stand in alarm until they are."""
    out = run_world(
        dense_world(5, AccelProfile.BANG_BANG),
        steps=300,
        latency=latency,
        make=_deadline(latency, cap),
    )
    assert out.onsets >= 5
    assert out.missed == []
    assert out.late == []
    assert out.evaluations <= cap * 300


@pytest.mark.parametrize("latency", [0, 1])
def test_deadline_with_switches_flags_every_onset(latency: int) -> None:
    for seed in (6, 7):
        out = run_world(
            dense_world(seed, AccelProfile.BANG_BANG),
            steps=300,
            latency=latency,
            make=_deadline(latency, 8),
            switch_every=7,
        )
        assert out.onsets >= 5
        assert out.missed == []
        assert out.late == []


def test_deadline_revisiting_one_step_late_misses_collisions() -> None:
    """Scheduling with latency 0 a world whose verdicts act one period late revisits every pair
    one step later than its tau allows (and alarms one step too rarely): the same check that
    passes above must then find misses or late alarms."""
    outcomes = [
        run_world(
            dense_world(seed, AccelProfile.BANG_BANG), steps=300, latency=1, make=_deadline(0)
        )
        for seed in range(4)
    ]
    assert sum(len(o.missed) + len(o.late) for o in outcomes) > 0
