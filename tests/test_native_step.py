"""Tests of the predictor's native step: the alarm log its steps append to."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from dua_mujoco.exceptions import SchedulerError
from dua_mujoco.mj import native_step
from dua_mujoco.mj.alarms import Alarms
from dua_mujoco.mj.options import UrgencyOptions
from dua_mujoco.mj.predictor import Predictor
from dua_mujoco.mj.scenes import load_scene, make_controller


def _rollout(steps: int, **options: object) -> list[tuple[Alarms, tuple[np.ndarray, ...]]]:
    """Each step's ``Alarms`` and a copy of its arrays taken right after the step."""
    m, d = load_scene("two_arms")
    # The sphere urgency: the exact level clears too many alarms for the log to fill up.
    p = Predictor(m, accel=30.0, **options, urgency=UrgencyOptions(exact=False))  # type: ignore[arg-type]
    ctrl = make_controller(m, "random", seed=0)
    mujoco.mj_step(m, d)
    p.reset(d)
    out = []
    for _ in range(steps):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        a = p.step(d)
        out.append((a, (a.pairs.copy(), a.tau.copy(), a.new.copy())))
    return out


@pytest.mark.parametrize("schedule", ["deadline", "dua"])
def test_alarms_outlive_log_replacements(monkeypatch: pytest.MonkeyPatch, schedule: str) -> None:
    """A log with room for one step is replaced at nearly every step: every ``Alarms`` must
    still read what its step raised, and the run must raise what a run whose log never fills
    does."""
    roomy = _rollout(300, schedule=schedule)
    monkeypatch.setattr(native_step, "LOG_STEPS", 1)
    monkeypatch.setattr(native_step, "LOG_MIN", 0)
    tight = _rollout(300, schedule=schedule)
    logs = {id(a.pairs.base) for a, _ in tight if len(a)}
    assert len(logs) > 50  # the log really was replaced, many times
    for (a, copied), (_, expected) in zip(tight, roomy, strict=True):
        for now, then, want in zip((a.pairs, a.tau, a.new), copied, expected, strict=True):
            np.testing.assert_array_equal(now, then)
            np.testing.assert_array_equal(now, want)
    assert sum(len(a) for a, _ in tight) > 300  # the comparison is not of empty steps


def test_alarm_arrays_are_read_only() -> None:
    (a, _), *_ = (s for s in _rollout(50) if len(s[0]))
    for array in (a.pairs, a.tau, a.new):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = array[0]


def test_step_between_select_and_update_is_refused() -> None:
    m, d = load_scene("two_arms")
    p = Predictor(m, accel=30.0)
    mujoco.mj_step(m, d)
    p.reset(d)
    assert p.scheduler is not None
    p.scheduler.select()
    mujoco.mj_step(m, d)
    with pytest.raises(SchedulerError, match="between select"):
        p.step(d)
