"""The alarms a predictor's steps raise: spans of the runtime's alarm log, never copied."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from dua_mujoco._core import LAYOUT
from dua_mujoco.build.options import ScheduleOptions, UrgencyOptions
from dua_mujoco.exceptions import SchedulerError
from dua_mujoco.models.scenes import load_scene, make_controller
from dua_mujoco.runtime import predictor as predictor_module
from dua_mujoco.runtime.alarms import Alarms
from dua_mujoco.runtime.predictor import Predictor


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
    monkeypatch.setattr(predictor_module, "LOG_STEPS", 1)
    monkeypatch.setattr(predictor_module, "LOG_MIN", 0)
    tight = _rollout(300, schedule=schedule)
    # Each step's alarms start a log of their own (every one still held here, so no two share
    # an address): the log really was replaced, many times.
    logs = {a.pairs.ctypes.data for a, _ in tight if len(a)}
    assert len(logs) > 50
    for (a, copied), (_, expected) in zip(tight, roomy, strict=True):
        for now, then, want in zip((a.pairs, a.tau, a.new), copied, expected, strict=True):
            np.testing.assert_array_equal(now, then)
            np.testing.assert_array_equal(now, want)
    assert sum(len(a) for a, _ in tight) > 300  # the comparison is not of empty steps


def test_a_log_no_alarms_holds_is_written_again(monkeypatch: pytest.MonkeyPatch) -> None:
    """A full log that no ``Alarms`` holds any more is written again from its start, not
    replaced (the plugin's case: room for one step, no reader): one log serves the whole run,
    and its alarms are those of a run whose log never fills (the deadline schedule's room is
    every pair: each step that alarms starts the log over)."""
    roomy = _rollout(300)
    monkeypatch.setattr(predictor_module, "LOG_STEPS", 1)
    monkeypatch.setattr(predictor_module, "LOG_MIN", 0)
    m, d = load_scene("two_arms")
    p = Predictor(m, accel=30.0, urgency=UrgencyOptions(exact=False))
    ctrl = make_controller(m, "random", seed=0)
    mujoco.mj_step(m, d)
    p.reset(d)
    logs = set()
    for _, expected in roomy:
        ctrl(m, d)
        mujoco.mj_step(m, d)
        a = p.step(d)
        if len(a):
            logs.add(a.pairs.ctypes.data)
        got = (a.pairs.copy(), a.tau.copy(), a.new.copy())
        del a  # no one holds the log at the next step
        for now, want in zip(got, expected, strict=True):
            np.testing.assert_array_equal(now, want)
    assert len(logs) == 1


def test_alarm_arrays_are_read_only() -> None:
    (a, _), *_ = (s for s in _rollout(50) if len(s[0]))
    for array in (a.pairs, a.tau, a.new):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = array[0]


def test_the_predictors_schedule_is_read_only() -> None:
    """``Predictor.scheduler`` shows the runtime's schedule; stepping it from outside would
    desynchronise the runtime's own bookkeeping: refused."""
    m, d = load_scene("two_arms")
    p = Predictor(m, accel=30.0)
    mujoco.mj_step(m, d)
    p.reset(d)
    assert p.scheduler is not None
    for call in (p.scheduler.select, lambda: p.scheduler.set_active([0], False)):  # type: ignore[union-attr]
        with pytest.raises(SchedulerError, match="read-only"):
            call()
    mujoco.mj_step(m, d)
    p.step(d)  # the runtime steps as before


def test_alarms_name_their_pairs() -> None:
    """geom1/geom2/sphere1/sphere2 and names are the tables' at the step (a pruned predictor's
    learning appends, so they stay right for old alarms too)."""
    steps = [a for a, _ in _rollout(100) if len(a)]
    m, _ = load_scene("two_arms")
    p = Predictor(m, accel=30.0, urgency=UrgencyOptions(exact=False))
    t = p.tables
    for a in steps[:20]:
        np.testing.assert_array_equal(a.geom1, t.geom1[a.pairs])
        np.testing.assert_array_equal(a.geom2, t.geom2[a.pairs])
        np.testing.assert_array_equal(a.sphere1, t.first[a.pairs])
        halfspace_or_shape = t.kind[a.pairs] != 0
        np.testing.assert_array_equal(
            a.sphere2, np.where(halfspace_or_shape, -1, t.second[a.pairs])
        )
        assert a.names == [
            (t.geom_names[g1], t.geom_names[g2]) for g1, g2 in zip(a.geom1, a.geom2, strict=True)
        ]


@pytest.mark.parametrize("options", [{}, {"schedule": ScheduleOptions(max_evals_per_step=4)}])
def test_the_steps_standing_state_is_the_alarm_rule(options: dict) -> None:
    """After every step, the pairs the runtime records as standing (read from the step's alarm
    list, docs/theory.md section 3, "Standing after a step") are those the alarm rule
    (``Schedule::Stands``) puts in alarm: with bodies breaking a tight bound at most steps (their
    pairs all due at once) and, capped, with deferrals."""
    m, d = load_scene("two_arms")
    p = Predictor(m, accel=5.0, **options)
    ctrl = make_controller(m, "random", seed=0)
    mujoco.mj_step(m, d)
    p.reset(d)
    flagged = deferred = standing = 0
    for _ in range(300):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        a = p.step(d)
        rule = np.flatnonzero(p.pair_state().alarm_state())
        np.testing.assert_array_equal(np.asarray(p._rt.standing), rule)
        flagged += p._rt.flagged
        deferred += a.deferred
        standing += rule.size
    assert flagged > 100 and standing > 100  # the check flags, and pairs stand
    assert deferred > 0 or "schedule" not in options


def _standing_reference(p: Predictor) -> np.ndarray:
    """The deadline rule written out slowly (docs/theory.md, section 3): a held pair stands iff
    it is switched on, linked at a due step, and its latest verdict does not cover the wait
    until it plus the latency and the horizon beyond one period, computed as the schedule does.
    Model pair ids, sorted."""
    s = p.pair_state().scheduler
    assert s.kind == LAYOUT["DEADLINE"]
    where, last = s.ints[LAYOUT["WHERE"]], s.ints[LAYOUT["LAST_STEP"]]
    extra = s.alarm_horizon - s.dt
    out = []
    for k in range(where.size):
        if not s.active[k] or where[k] < 0:
            continue
        cover = float(int(where[k]) - int(last[k]) + s.latency) * s.dt + extra
        if s.last_tau[k] <= cover:
            out.append(int(np.asarray(p._rt.ids)[k]))
    return np.asarray(sorted(out), dtype=np.int64)


def test_settled_pairs_neither_stood_nor_stand() -> None:
    """The step tracks no settled pair (docs/theory.md, section 3, "Settled pairs do not
    stand"): on a scene where the check settles thousands of a flagged body's pairs, every
    settled pair stood before its step and stands after it in neither the runtime's standing
    state nor a slow reference of the rule, and the two agree after every step; last, a body
    with a sphere pair standing in alarm is flung 50 m away (flagged, all its pairs far). Fails
    with a standing pair settled, or a settled verdict that does not cover its kept due step
    (benchmarks/mutants.py)."""
    m, d = load_scene("traffic")
    p = Predictor(m, accel=5.0)
    ctrl = make_controller(m, "random", seed=0)
    mujoco.mj_step(m, d)
    p.reset(d)
    before = _standing_reference(p)
    settled = busy = 0
    for _ in range(600):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        p.step(d)
        state = p.pair_state()
        now = _standing_reference(p)
        np.testing.assert_array_equal(np.asarray(p._rt.standing), now)
        k = state.settled
        count = p.evaluations_per_step
        ids = state.last_selected[count : count + k]
        assert not np.isin(ids, before).any() and not np.isin(ids, now).any()
        settled += k
        busy += k > 20
        before = now
    assert settled > 1000 and busy > 10
    body, (g1, g2) = m.geom_bodyid, p.sphere_pair_geoms
    sphere = p.pair_records[:, LAYOUT["PAIR_KIND"]] == 0
    b1, b2 = body[g1[before]], body[g2[before]]
    flung = before[sphere[before] & (b1 != b2) & (b1 > 0) & (b2 > 0)]
    assert flung.size
    b = body[g1[flung[0]]]
    ctrl(m, d)
    mujoco.mj_step(m, d)
    d.geom_xpos[body == b] += [50.0, 0.0, 0.0]
    p.step(d)
    assert b in p.violated_bodies
    np.testing.assert_array_equal(np.asarray(p._rt.standing), _standing_reference(p))
    assert flung[0] not in p._rt.standing
