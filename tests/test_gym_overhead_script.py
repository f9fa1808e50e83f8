"""benchmarks/gym_overhead.py's paired ratio: each env's times stay its own while the order of
the two steps alternates (a fake clock, no timing)."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest
from benchmark_scripts import script


class _Clock:
    now = 0.0

    def __call__(self) -> float:
        return self.now


class _Space:
    def seed(self, seed: int) -> None:
        pass

    def sample(self) -> int:
        return 0


class _Env:
    """A step that takes ``cost`` seconds of the fake clock."""

    def __init__(self, clock: _Clock, cost: float) -> None:
        self.clock, self.cost, self.action_space = clock, cost, _Space()
        self.steps = 0

    def reset(self, *, seed: int) -> None:
        self.steps = 0

    def step(self, action: Any) -> None:
        self.steps += 1
        self.clock.now += self.cost


def test_paired_keeps_each_envs_times_its_own(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fails if a step's time goes to the other env when the order flips (both would read 2)."""
    overhead = script("gym_overhead")
    clock = _Clock()
    monkeypatch.setattr(overhead, "time", SimpleNamespace(perf_counter=clock))
    plain, wrapped = _Env(clock, 1.0), _Env(clock, 3.0)
    assert overhead._paired(plain, wrapped, 10, 0) == (1.0, 3.0)
    assert plain.steps == wrapped.steps == 10
