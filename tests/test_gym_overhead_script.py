"""benchmarks/gym_overhead.py's paired ratio: each env's times stay its own while the order of
the two steps alternates (a fake clock, no timing)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType, SimpleNamespace
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _script() -> ModuleType:
    """benchmarks/gym_overhead.py, loaded by its path (the benchmarks folder stays off sys.path)."""
    name = "benchmarks_gym_overhead"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, ROOT / "benchmarks" / "gym_overhead.py")
        assert spec is not None and spec.loader is not None
        sys.modules[name] = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(sys.modules[name])
    return sys.modules[name]


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
    script = _script()
    clock = _Clock()
    monkeypatch.setattr(script, "time", SimpleNamespace(perf_counter=clock))
    plain, wrapped = _Env(clock, 1.0), _Env(clock, 3.0)
    assert script._paired(plain, wrapped, 10, 0) == (1.0, 3.0)
    assert plain.steps == wrapped.steps == 10
