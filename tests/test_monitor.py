"""The Monitor's episode accounting against a slow, step-by-step reference."""

from __future__ import annotations

import tracemalloc
import warnings

import mujoco
import numpy as np
import pytest

import dua_mujoco.measure.rollout as rollout
from dua_mujoco.build.options import ScheduleOptions, UrgencyOptions
from dua_mujoco.exceptions import DeadlineOverrunWarning, InvalidInputError
from dua_mujoco.measure.monitor import Monitor
from dua_mujoco.measure.report import RunReport
from dua_mujoco.measure.rollout import run
from dua_mujoco.models.scenes import load_scene, make_controller
from dua_mujoco.runtime.predictor import Predictor


def _reference_episodes(
    times: list[float],
    standing: list[np.ndarray],
    contact: list[np.ndarray],
    opened_horizon: list[dict[int, float]],
) -> tuple[int, int]:
    """Alarm episodes and false ones, pair by pair, in plain Python.

    An episode of a geom pair is a maximal run of physics steps with a standing alarm; it is
    false when the pair is in contact at none of its steps nor at any step up to ``horizon``
    seconds after the step that withdrew the alarm, whether or not a new episode of the pair
    starts meanwhile (``horizon``: the longest revisit horizon among the alarms that opened
    it). Episodes still open, or whose window is still running, at the end count as false if
    no contact was seen.
    """
    npair = standing[0].size
    episodes = false = 0
    for g in range(npair):
        k = 0
        n = len(times)
        while k < n:
            if not standing[k][g]:
                k += 1
                continue
            episodes += 1
            horizon = opened_horizon[k].get(g, 0.0)
            touched = False
            while k < n and standing[k][g]:
                touched |= bool(contact[k][g])
                k += 1
            if k < n:  # withdrawn at step k: watch until the deadline, through later episodes
                deadline = times[k] + horizon
                for j in range(k, n):
                    touched |= bool(contact[j][g])
                    if times[j] >= deadline:
                        break
            false += not touched
    return episodes, false


@pytest.mark.parametrize(("scene", "period"), [("traffic", 1), ("two_arms", 1), ("traffic", 3)])
def test_episode_accounting_matches_reference(scene: str, period: int) -> None:
    m, d = load_scene(scene)
    # The sphere urgency alone: the exact level leaves traffic no false alarm to count.
    p = Predictor(m, accel=4.0, period=period, urgency=UrgencyOptions(exact=False))
    ctrl = make_controller(m, "random", seed=1)
    mon = Monitor(p, check_bounds=False)
    ngp = p.geom_pairs.npair
    gp_of = p.sphere_pairs.geom_pair
    times: list[float] = []
    standing: list[np.ndarray] = []
    contact: list[np.ndarray] = []
    opened: list[dict[int, float]] = []

    def record(alarms: object | None) -> None:
        sched = p.pair_state()
        assert sched is not None
        alarmed = sched.alarm_state() & sched.active
        now = np.zeros(ngp, dtype=bool)
        np.logical_or.at(now, gp_of[alarmed], True)
        hits = np.zeros(ngp, dtype=bool)
        nc = int(d.ncon)
        if nc:
            idx = p.geom_pairs.indices_of(d.contact.geom1[:nc], d.contact.geom2[:nc])
            hits[idx[idx >= 0]] = True
        horizon: dict[int, float] = {}
        if alarms is not None:
            for pair in alarms.pairs.tolist():  # type: ignore[attr-defined]
                g = int(gp_of[pair])
                h = float(sched.horizon_of(np.array([pair]))[0])
                horizon[g] = max(horizon.get(g, 0.0), h)
        times.append(float(d.time))
        standing.append(now)
        contact.append(hits)
        opened.append(horizon)

    ctrl(m, d)
    mujoco.mj_step(m, d)
    record(mon.start(d))
    for k in range(1, 901):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        alarms = p.step(d) if k % period == 0 else None
        mon.observe(d, alarms)
        record(alarms)
    mon.finish()
    episodes, false = _reference_episodes(times, standing, contact, opened)
    assert mon.episodes > 10 and 0 < mon.false_episodes < mon.episodes  # a test with teeth
    assert (mon.episodes, mon.false_episodes) == (episodes, false)


def _standing_reference(predictor: Predictor) -> np.ndarray:
    """Geom pairs with a standing alarm, straight from the scheduler (the Monitor's invariant)."""
    sched = predictor.scheduler
    assert sched is not None
    out = np.zeros(predictor.geom_pairs.npair, dtype=bool)
    np.logical_or.at(out, predictor.sphere_pairs.geom_pair, sched.alarm_state() & sched.active)
    return out


@pytest.mark.parametrize("period", [1, 3, 8])
def test_standing_alarms_follow_switches_and_resets(period: int) -> None:
    """Random switches between physics steps (off, on, off and on again at once) and resets.

    After every ``observe`` the Monitor's standing alarms must be the scheduler's, geom pair by
    geom pair. An off-and-on-again left no trace in the active mask and was missed; a reset's
    new initial classification was never applied, and a contact it alarmed counted as a miss
    with the bounds held.
    """
    m, d = load_scene("paper_world:12")
    p = Predictor(m, accel=2.0, period=period)
    ctrl = make_controller(m, "random", seed=0)
    rng = np.random.default_rng(period)
    mon = Monitor(p)
    mujoco.mj_step(m, d)
    mon.start(d)
    kinds = {"off": 0, "on": 0, "off_on": 0, "reset": 0, "reset_mid": 0, "switch_mid": 0}
    steps_of = [0]  # physics step of each predictor step since the last reset
    for k in range(1, 800):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        stepped = k % period == 0
        alarms = p.step(d) if stepped else None
        steps_of += [k] if stepped else []
        # Between predictor.step and observe: a reset (its alarms then belong to the old
        # scheduler) or a switch.
        if stepped and rng.random() < 0.03:
            p.reset(d)
            steps_of = [k]
            kinds["reset_mid"] += 1
        elif rng.random() < 0.05:
            sched = p.pair_state()
            assert sched is not None
            mid = rng.choice(len(p.pair_set), size=3, replace=False)
            sched.set_active(mid, False)
            sched.set_active(mid, True)
            kinds["switch_mid"] += 1
        mon.observe(d, alarms)
        np.testing.assert_array_equal(mon._standing > 0, _standing_reference(p), f"step {k}")
        steps = mon._pred_steps
        assert [steps[j] for j in range(steps.count)] == steps_of, f"step {k}"  # a miss's window
        sched = p.pair_state()
        assert sched is not None
        ids = rng.choice(len(p.pair_set), size=3, replace=False)
        r = rng.random()
        if r < 0.02:
            # A switch that changes nothing must not look like one.
            changes = sched.activation_changes
            sched.set_active(ids[sched.active[ids]], True)
            assert sched.activation_changes == changes
        elif r < 0.05:
            sched.set_active(ids, False)
            sched.set_active(ids, True)
            kinds["off_on"] += 1
        elif r < 0.10:
            sched.set_active(ids, False)
            kinds["off"] += 1
        elif r < 0.15:
            sched.set_active(ids, True)
            kinds["on"] += 1
        elif r < 0.25 and stepped:
            p.reset(d)
            steps_of = [k]
            kinds["reset"] += 1
    mon.finish()
    assert min(kinds.values()) > 0, kinds
    assert not [miss for miss in mon.misses if miss.bounds_held]


@pytest.mark.parametrize("period", [1, 3])
def test_alarm_and_contact_fractions_match_a_per_step_reference(period: int) -> None:
    """``standing_alarm_fraction`` and ``contact_pair_fraction`` against plain per-step sums.

    Pairs are switched off and on between steps, so the count of active geom pairs changes.
    """
    m, d = load_scene("paper_world:12")
    p = Predictor(m, accel=2.0, period=period)
    ctrl = make_controller(m, "random", seed=3)
    rng = np.random.default_rng(period)
    mon = Monitor(p)
    gp_of = p.sphere_pairs.geom_pair
    alarm_fractions: list[float] = []
    contact_fractions: list[float] = []
    mujoco.mj_step(m, d)
    mon.start(d)
    for k in range(1, 600):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        alarms = p.step(d) if k % period == 0 else None
        mon.observe(d, alarms)
        sched = p.pair_state()
        assert sched is not None
        if alarms is not None:
            active = {int(g) for g in gp_of[sched.active]}
            alarmed = {int(g) for g in gp_of[sched.alarm_state() & sched.active]}
            touching = set()
            for i in range(int(d.ncon)):
                g = int(
                    p.geom_pairs.indices_of(d.contact.geom1[i : i + 1], d.contact.geom2[i : i + 1])[
                        0
                    ]
                )
                if g in active:
                    touching.add(g)
            if active:
                alarm_fractions.append(len(alarmed) / len(active))
                contact_fractions.append(len(touching) / len(active))
            else:
                alarm_fractions.append(0.0)
                contact_fractions.append(0.0)
        if rng.random() < 0.1:
            sched.set_active(rng.choice(len(p.pair_set), size=5, replace=False), rng.random() < 0.5)
    mon.finish()
    assert mon.predictor_steps == len(alarm_fractions)
    assert 0.0 < np.mean(contact_fractions) < np.mean(alarm_fractions) < 1.0  # a test with teeth
    assert mon.standing_alarm_fraction == pytest.approx(np.mean(alarm_fractions), rel=1e-12)
    assert mon.contact_pair_fraction == pytest.approx(np.mean(contact_fractions), rel=1e-12)


def _run_memory(steps: int, series: bool) -> tuple[int, RunReport]:
    """Bytes held at the last step of a run, and its report (``bounds.py`` excluded)."""
    m, d = load_scene("two_arms")
    p = Predictor(m, accel=200.0)
    ctrl = make_controller(m, "random", seed=0)
    held: list[int] = []
    # BoundMonitor keeps a flag per step and a record per violation (bounds.py, not the run's
    # own accounting): left out of the measurement.
    skip = [tracemalloc.Filter(False, "*bounds.py")]

    def measure(k: int, d: mujoco.MjData, alarms: object, monitor: Monitor) -> None:
        if k == steps:
            snap = tracemalloc.take_snapshot().filter_traces(skip)
            held.append(sum(stat.size for stat in snap.statistics("filename")))

    tracemalloc.start()
    try:
        report = run(
            m, d, p, steps=steps, controller=ctrl, progress=False, series=series, on_step=measure
        )
    finally:
        tracemalloc.stop()
    return held[0], report


def test_run_memory_does_not_grow_with_steps_without_series() -> None:
    """Without series the report holds no per-step data and a 4x longer run holds no more.

    The old run kept six per-step Python lists (about 240 bytes a step: +700 kB here).
    """
    _run_memory(100, False)  # load the compiled code outside the measurement
    short, _ = _run_memory(1000, False)
    long, report = _run_memory(4000, False)
    assert report.alarms_per_step is None and report.min_tau_per_step is None
    assert "alarms_per_step" not in report.to_dict()
    assert long - short < 40_000, (short, long)
    with pytest.raises(InvalidInputError, match="series=True"):
        report.to_dict(series=True)
    _, with_series = _run_memory(500, True)
    assert with_series.alarms_per_step is not None and with_series.min_tau_per_step is not None
    assert with_series.alarms_per_step.dtype == np.int32
    assert with_series.alarms_per_step.shape == (with_series.predictor_steps + 1,)
    out = with_series.to_dict(series=True)
    assert len(out["min_tau_per_step"]) == 501
    assert all(t is None or isinstance(t, float) for t in out["min_tau_per_step"])


def test_capped_runs_count_evaluations_not_deferrals() -> None:
    """With a cap that binds, the report's evaluations per step stay within the cap: deferred
    pairs have their verdict renewed, not evaluated."""
    m, d = load_scene("two_arms")
    p = Predictor(m, accel=30.0, schedule=ScheduleOptions(max_evals_per_step=4))
    report = run(
        m, d, p, steps=200, controller=make_controller(m, "random", seed=0), progress=False
    )
    assert report.evals_per_step <= 4.0
    assert report.missed_onsets_valid_bounds == 0


def test_a_deferral_opens_no_window_for_the_onsets_labels() -> None:
    """A short lead is "after a violation" when a hypothesis broke after the evaluation whose
    verdict was in force (measure/warning_time.py); a pair a capped schedule
    deferred keeps its latest evaluation's verdict, so its window stays at that evaluation.
    Every step, each pair's window (the step the labels compare breaks with) is the physics
    step of its schedule's last_step, as the miss rule's, deferred pairs included: counted from
    the deferral, a violation between the verdict and its last deferral made an onset that
    pair raised one "with the bounds held"."""
    m, d = load_scene("two_arms")
    p = Predictor(m, accel=5.0, schedule=ScheduleOptions(max_evals_per_step=4))
    mon = Monitor(p)
    ctrl = make_controller(m, "random", seed=0)
    mujoco.mj_step(m, d)
    mon.start(d)
    pairs = np.arange(p.nsphere_pairs)
    deferred = 0
    for _ in range(60):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        alarms = p.step(d)
        mon.observe(d, alarms)
        deferred += alarms.deferred
        steps = mon._pred_steps
        made = [steps[int(j)] for j in p.pair_state().last_step_of(pairs)]
        np.testing.assert_array_equal(mon.warning._last_eval, made)
    assert deferred > 100  # the cap binds


def test_monitored_run_with_pruned_pairs() -> None:
    """Pruned pairs (the default from 256 spheres) hold a fraction of the pairs, rebuilt as the
    spheres move, and the exact stage still finds every onset alarmed while the bounds held."""
    m, d = load_scene("swarm:300")
    p = Predictor(m, accel=2.0)
    report = run(
        m, d, p, steps=300, controller=make_controller(m, "random", seed=0), progress=False
    )
    total = p.universe.counts()[1]  # the model's active sphere pairs
    assert report.pairs == total and report.geom_pairs == p.universe.counts()[0]
    assert p.held_pairs.size < total // 10
    assert p.nsphere_pairs < total // 5  # it knows only the pairs its candidates brought in
    assert p.rebuilds >= 5
    assert report.contact_onsets > 0
    assert report.missed_onsets_valid_bounds == 0
    assert report.unfiltered_contacts == 0


@pytest.mark.parametrize(
    "options",
    [
        {},
        {"urgency": UrgencyOptions(exact=False)},
        {"schedule": ScheduleOptions(max_evals_per_step=16)},
    ],
)
def test_pruned_pairs_keep_the_static_shapes(options: dict) -> None:
    """Pairs against static shapes are always held: their second member is a shape, not a sphere
    with a reach (an earlier merge read it as a sphere id and dropped table contacts)."""
    m, d = load_scene("two_arms")
    p = Predictor(m, accel=80.0, pairs="pruned", **options)
    report = run(
        m, d, p, steps=600, controller=make_controller(m, "random", seed=0), progress=False
    )
    assert report.contact_onsets >= 10
    assert report.missed_onsets_valid_bounds == 0
    kinds = p.sphere_pairs.kind
    assert set(np.flatnonzero(kinds != 0).tolist()) <= set(p.held_pairs.tolist())


@pytest.mark.parametrize("realtime", [False, True])
def test_run_counts_the_predictor_steps_slower_than_its_period_when_realtime(
    realtime: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``run(realtime=True)`` times each predictor step and counts those slower than
    ``predictor.dt`` (``monitor.overruns``, the report's ``deadline_overruns``), warning once;
    without it nothing is counted. A clock that advances 1 s a reading makes every step slow
    (no timing)."""
    ticks = iter(range(10**6))
    monkeypatch.setattr(rollout.time, "perf_counter", lambda: float(next(ticks)))
    m, d = load_scene("two_arms")
    p = Predictor(m, accel=5.0, period=2)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        report = run(m, d, p, steps=20, realtime=realtime, progress=False)
    overrun = [w for w in caught if issubclass(w.category, DeadlineOverrunWarning)]
    assert report.deadline_overruns == (10 if realtime else 0)
    assert len(overrun) == (1 if realtime else 0)


def test_monitor_realtime_is_deprecated_and_does_nothing() -> None:
    """``Monitor(realtime=...)`` never had an effect (the monitor does not time the predictor):
    given, it warns that it is deprecated; left out, nothing is said."""
    m, _ = load_scene("two_arms")
    p = Predictor(m, accel=5.0)
    with pytest.warns(DeprecationWarning, match=r"Monitor\(realtime=\.\.\.\) has no effect"):
        Monitor(p, realtime=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Monitor(p)
