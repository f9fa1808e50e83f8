"""Each onset's lead and the oracle: scripted scenes where both are known, and a per-step
reference on a scene with resets."""

from __future__ import annotations

import math
from fractions import Fraction

import mujoco
import numpy as np
import pytest
from mjcf import free, mjcf

from dua_mujoco import _core
from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.measure.accumulators import Durations, StepMap
from dua_mujoco.measure.monitor import Monitor
from dua_mujoco.measure.report import RunReport
from dua_mujoco.measure.rollout import build_report, run
from dua_mujoco.measure.warning_time import WarningTime, alarm_horizon_of
from dua_mujoco.models.scenes import load_scene, make_controller
from dua_mujoco.plugin import attach, standing_pairs
from dua_mujoco.runtime.predictor import Predictor

# Two balls dropped on a plane, 1 m apart: ball_a lands at the 40th physics step and ball_b at
# the 114th (counted from the start state), and both then rest in contact.
_DROP = mjcf(
    '<geom name="floor" type="plane" size="2 2 0.1"/>',
    free("a", "0 0 0.08", 'name="ball_a" type="sphere" size="0.05"'),
    free("b", "1 0 0.3", 'name="ball_b" type="sphere" size="0.05"'),
    option='timestep="0.002"',
)
_TS = 0.002


def _drop(
    predictor_kwargs: dict,
    steps: int,
    *,
    warning_horizon: float | None = None,
    reset_at: int | None = None,
    kick_at: int | None = None,
) -> tuple[Monitor, dict[str, int]]:
    """Roll the drop out under a Monitor; return it and each ball's onset step (the first
    monitored step with the ball in contact). ``kick_at``: push ball_b sideways (100 N) for
    that one step, which breaks any bound under 190 m/s^2 but does not change its landing."""
    m = mujoco.MjModel.from_xml_string(_DROP)
    d = mujoco.MjData(m)
    p = Predictor(m, **predictor_kwargs)
    mon = Monitor(p, warning_horizon=warning_horizon)
    mujoco.mj_step(m, d)
    mon.start(d)
    onset: dict[str, int] = {}
    for k in range(1, steps + 1):
        d.xfrc_applied[m.body("b").id, 0] = 100.0 if k == kick_at else 0.0
        mujoco.mj_step(m, d)
        alarms = p.step(d) if k % p.period == 0 else None
        mon.observe(d, alarms)
        for i in range(int(d.ncon)):
            for g in (int(d.contact.geom1[i]), int(d.contact.geom2[i])):
                onset.setdefault(m.geom(g).name, k)
        if k == reset_at:
            p.reset(d)
    mon.finish()
    onset.pop("floor")
    assert onset == {"ball_a": 39, "ball_b": 113}  # the scene as built
    return mon, onset


def _report(mon: Monitor) -> RunReport:
    return build_report(mon, "drop", False, Durations(), Durations(), interrupted=False)


def test_lead_is_the_standing_run_before_the_onset_cut_at_a_reset() -> None:
    """Bounds so large that every pair stands in alarm from the start: each lead is the time
    since the start, or since the reset in between (the run a reset's classification opens).

    Counted from the episode's start instead, ball_b's lead would be 113 steps, not 113 - 90.
    """
    h = 30 * _TS  # less than ball_a's lead (39 steps), more than ball_b's since the reset (23)
    mon, _ = _drop({"accel": 1e6}, 150, warning_horizon=h, reset_at=90)
    assert mon.onsets == mon.predicted == 2
    np.testing.assert_allclose(np.sort(mon.warning.leads), [23 * _TS, 39 * _TS])
    rep = _report(mon)
    assert rep.lead_min_s == pytest.approx(23 * _TS)
    assert rep.lead_median_s == pytest.approx((23 + 39) / 2 * _TS)
    assert rep.lead_p10_s == pytest.approx(23 * _TS)
    assert rep.warning_horizon_s == h
    # ball_b came 23 steps after the reset, when no alarm could have stood 30.
    assert (rep.short_lead_onsets, rep.short_lead_at_start) == (1, 1)
    assert rep.short_lead_bounds_held == rep.short_lead_after_violation == 0
    # The same run without the reset: both leads from the start, neither short.
    mon, _ = _drop({"accel": 1e6}, 150, warning_horizon=h)
    np.testing.assert_allclose(np.sort(mon.warning.leads), [39 * _TS, 113 * _TS])
    assert mon.warning.short_leads == 0


def test_short_leads_are_told_apart_by_the_bounds() -> None:
    """A horizon longer than the predictor's: with bounds that hold (free fall, 9.81 < 15) the
    alarms come a step or two ahead, so both onsets are short while the bounds held; with
    bounds the fall breaks (0.5 m/s^2) they are short after a violation."""
    h = 30 * _TS  # both onsets come later than this after the start
    mon, _ = _drop({"accel": 15.0}, 130, warning_horizon=h)
    contact_violations = mon.violations  # the landings' impulses, after the onsets
    leads = mon.warning.leads
    assert mon.misses == [] and leads.size == 2
    assert np.all((leads > 0) & (leads < h)), leads
    assert (mon.warning.short_held, mon.warning.short_after_violation) == (2, 0)
    # A violation long before ball_b's landing, after which its pairs were evaluated again:
    # the late alarm still came while the bounds held.
    mon, _ = _drop({"accel": 15.0}, 130, warning_horizon=h, kick_at=5)
    assert mon.violations > contact_violations
    assert (mon.warning.short_held, mon.warning.short_after_violation) == (2, 0)
    mon, _ = _drop({"accel": 0.5}, 130, warning_horizon=h)
    assert mon.violations > 0
    assert np.all(mon.warning.leads < h)
    assert (mon.warning.short_held, mon.warning.short_after_violation) == (0, 2)
    assert mon.warning.short_at_start == 0


def test_a_miss_long_after_a_violation_is_one_with_the_bounds_held() -> None:
    """The monitor's label of a miss: a predictor that never alarms (the paper's schedule with
    its horizons at -1) misses both landings. ball_b is kicked at step 5, long before its
    landing, and its pairs are evaluated again after the kick: its miss came while the bounds
    held since the pair's latest evaluation, as ball_a's did (no violation at all), so both are
    bugs, neither excused by the violation."""
    m = mujoco.MjModel.from_xml_string(_DROP)
    d = mujoco.MjData(m)
    p = Predictor(m, accel=15.0, schedule="dua")
    mon = Monitor(p)
    mujoco.mj_step(m, d)
    mon.start(d)
    assert p.scheduler is not None
    p.scheduler.state.horizon[:] = -1.0  # tau <= -1 never holds: no alarm, ever
    for k in range(1, 131):
        d.xfrc_applied[m.body("b").id, 0] = 100.0 if k == 5 else 0.0
        mujoco.mj_step(m, d)
        mon.observe(d, p.step(d))
    mon.finish()
    assert mon.violations > 0 and mon.predicted == 0
    held = {miss.geom2: miss.bounds_held for miss in mon.misses}
    assert held == {"ball_a": True, "ball_b": True}
    assert not any(miss.in_violation_period for miss in mon.misses)


def test_a_break_before_a_verdict_excuses_no_other_verdicts_short_lead() -> None:
    """Two sphere pairs of one geom pair raise its alarm together; the onset comes 2 steps
    later, short of the 0.1 s horizon. Pair 0's verdict in force was made at step 10 on both
    bodies' bounds, which never broke; pair 1's at step 50 on rod_a's plan, whose break at
    step 30 came before it (the plan it rested on was the one set after). No hypothesis broke
    after the verdict that rested on it: the short lead came while the bounds held, and the
    label must say so. Judged on the union of the two verdicts' hypotheses since the earlier
    evaluation, the plan's break at 30 would excuse it (after a violation). A miss of the same
    two verdicts, current, is judged alike. Not seen in a run: every break makes all the body's
    pairs due, so the two windows differ only for a pair a cap defers across a break and a
    replan."""
    m = mujoco.MjModel.from_xml_string(
        mjcf(
            free("a", "0 0 0.5", 'name="rod_a" type="capsule" size="0.02 0.3" euler="0 90 0"'),
            free("b", "0 0 1.0", 'name="rod_b" type="capsule" size="0.02 0.3" euler="0 90 0"'),
            option='timestep="0.002" gravity="0 0 0"',
        )
    )
    p = Predictor(m, covering="multi")
    assert (p.sphere_pairs.geom_pair[:2] == 0).all()
    w = WarningTime(0.1, 0.002, p)
    hyp, a, b = w.hypotheses, m.body("a").id, m.body("b").id
    none = np.zeros(0, dtype=np.int64)
    hyp.evaluated(np.array([0]), np.array([[0, 0]], dtype=np.uint8))
    w.alarms(none, none, none, np.array([0]), 10, switch=False)
    hyp.last_plan_break[a] = 30
    hyp.evaluated(np.array([1]), np.array([[1, 0]], dtype=np.uint8))
    w.alarms(none, none, none, np.array([1]), 50, switch=False)
    both = np.array([0, 1])
    hyp.evaluated(both, np.array([[0, 0], [1, 1]], dtype=np.uint8))
    w.alarms(np.array([0]), both, np.array([0, 0]), both, 60, switch=False)
    assert hyp.broke(0) == hyp.broke(0, both, [10, 50]) == -1
    w.onset(0, 62, hyp.broke(0))
    assert (w.short_at_start, w.short_held, w.short_after_violation) == (0, 1, 0)
    # Each verdict's own breaks do excuse: rod_b's bounds after pair 0's verdict (at 20, not
    # after pair 1's), then rod_a's plan after pair 1's (at 55).
    hyp.last_violation[b] = 20
    assert hyp.broke(0) == hyp.broke(0, both, [10, 50]) == 20
    assert hyp.broke(0, both, [20, 50]) == -1
    hyp.last_plan_break[a] = 55
    assert hyp.broke(0) == hyp.broke(0, both, [20, 50]) == 55
    w.onset(0, 63, hyp.broke(0))
    assert (w.short_held, w.short_after_violation) == (1, 1)


def test_a_step_map_reads_arrays_as_it_reads_steps() -> None:
    """``StepMap.at`` (each live pair's window on the miss path) gives every predictor step's
    physics step as indexing does, across the runs irregular steps start."""
    steps = StepMap(5, 3)
    for k in (8, 11, 13, 16, 30, 33):
        steps.append(k)
    assert [steps[j] for j in range(steps.count)] == [5, 8, 11, 13, 16, 30, 33]
    j = np.array([6, 0, 3, 4, 2, 5, 1])
    assert steps.at(j).tolist() == [steps[i] for i in j.tolist()]


@pytest.mark.parametrize(("period", "hsteps"), [(1, 0), (1, 10), (3, 10), (2, 200)])
def test_oracle_by_construction(period: int, hsteps: int) -> None:
    """Three active pairs (each ball with the floor, the balls with each other); ball_a touches
    from step 39 to the end, ball_b from 113, the balls never. A predictor step ``k`` counts a
    ball when it touches at some step of ``[k, k + H]``: ``k >= onset - H``."""
    steps = 180
    mon, onset = _drop({"accel": 15.0, "period": period}, steps, warning_horizon=hsteps * _TS)
    sampled = np.arange(period, steps + 1, period)
    expect = sum(np.count_nonzero(sampled >= s - hsteps) for s in onset.values())
    expect /= 3 * sampled.size
    assert mon.predictor_steps == sampled.size
    assert mon.oracle_fraction == pytest.approx(expect, rel=1e-12)
    if hsteps == 0:
        assert mon.oracle_fraction == pytest.approx(mon.contact_pair_fraction, rel=1e-12)


def test_default_horizon_is_the_predictors() -> None:
    m, d = load_scene("traffic")
    p = Predictor(m, accel=4.0, period=3, latency=2)
    assert alarm_horizon_of(p) == pytest.approx(3 * 3 * 0.005)  # (1 + latency) periods
    rep = run(m, d, p, steps=30, progress=False)
    assert rep.warning_horizon_s == alarm_horizon_of(p)
    assert "touching within 45 ms (oracle)" in rep.table()


@pytest.mark.parametrize("bad", [-0.1, math.nan, math.inf, "0.1", True])
def test_a_bad_horizon_names_itself(bad: object) -> None:
    m, _ = load_scene("traffic")
    with pytest.raises(InvalidInputError, match="warning_horizon"):
        Monitor(Predictor(m, accel=4.0), warning_horizon=bad)  # type: ignore[arg-type]


def _reference(
    check: list[np.ndarray],
    state: list[np.ndarray],
    contact: list[np.ndarray],
    onsets: list[tuple[int, int]],
    resets: list[float],
    sampled: list[int],
    nactive: int,
    hsteps: int,
) -> tuple[list[int], float]:
    """Leads (steps) and the oracle, pair by pair in plain Python.

    ``check[k]``: geom pairs standing in alarm when step ``k``'s contacts were checked;
    ``state[k]``: standing after everything done at step ``k`` (a reset's classification);
    ``onsets``: (step, geom pair); ``resets``: steps whose state a reset classified, ``k``
    before step ``k``'s contacts were checked, ``k + 0.5`` after.
    """
    leads = []
    for k, g in onsets:
        if not check[k][g]:
            leads.append(0)
            continue
        s = k
        while s - 1 >= 0 and state[s - 1][g]:
            s -= 1
        cut = max([r for r in resets if r <= k], default=0)
        leads.append(k - max(s, math.floor(cut)))
    last = len(contact) - 1
    total = 0.0
    for k in sampled:
        touching = np.zeros(nactive, dtype=bool)
        for j in range(k, min(k + hsteps, last) + 1):
            touching |= contact[j]
        total += np.count_nonzero(touching) / nactive
    return leads, total / len(sampled)


@pytest.mark.parametrize(("period", "hsteps"), [(1, 8), (3, 20)])
def test_leads_and_oracle_match_a_per_step_reference(period: int, hsteps: int) -> None:
    m, d = load_scene("paper_world:12")
    # Bounds ten times the scene's own: alarms stand from 3 to 40-odd steps before onsets.
    p = Predictor(m, accel=20.0, period=period, latency=2)
    ctrl = make_controller(m, "random", seed=2)
    rng = np.random.default_rng(period)
    mon = Monitor(p, warning_horizon=hsteps * float(m.opt.timestep))
    ngp = p.geom_pairs.npair
    gp_of = p.sphere_pairs.geom_pair

    def standing() -> np.ndarray:
        sched = p.scheduler
        assert sched is not None
        out = np.zeros(ngp, dtype=bool)
        np.logical_or.at(out, gp_of, sched.alarm_state() & sched.active)
        return out

    def touching() -> np.ndarray:
        nc = int(d.ncon)
        out = np.zeros(ngp, dtype=bool)
        gp = p.geom_pairs.indices_of(d.contact.geom1[:nc], d.contact.geom2[:nc])
        out[gp[gp >= 0]] = True
        return out

    mujoco.mj_step(m, d)
    mon.start(d)
    check, state, contact = [standing()], [standing()], [touching()]
    onsets: list[tuple[int, int]] = []
    resets: list[float] = []
    sampled: list[int] = []
    for k in range(1, 900):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        alarms = p.step(d) if k % period == 0 else None
        if alarms is not None and rng.random() < 0.02:
            p.reset(d)  # between step and observe: its classification is of this step
            resets.append(k)
        before = mon.predictor_steps
        mon.observe(d, alarms)
        if mon.predictor_steps > before:
            sampled.append(k)
        now = touching()
        onsets += [(k, int(g)) for g in np.flatnonzero(now & ~contact[-1])]
        check.append(standing())
        contact.append(now)
        if alarms is not None and rng.random() < 0.02:
            p.reset(d)  # after observe: classified at this step, applied at the next
            resets.append(k + 0.5)
        state.append(standing())
    mon.finish()
    leads, oracle = _reference(check, state, contact, onsets, resets, sampled, ngp, hsteps)
    ts = float(m.opt.timestep)
    assert len(resets) >= 3 and len(onsets) >= 10
    assert len(set(leads)) > 5  # leads of many sizes
    np.testing.assert_allclose(np.sort(mon.warning.leads), np.sort(leads) * ts, atol=1e-12)
    assert mon.oracle_fraction == pytest.approx(oracle, rel=1e-12)
    assert mon.contact_pair_fraction < oracle < 1.0
    short = sum(lead < hsteps for lead in leads)
    assert mon.warning.short_leads == short > 0
    assert short < len(leads)


# One ball above a plane: it falls under gravity (9.81 < the bound, 10 m/s^2), so the bounds
# hold until it lands, and the half-space's tau is within a small fraction of a step of the
# landing: a landing between two predictor steps is what section 8 of docs/theory.md rounds for.
_FALL = mjcf(
    '<geom name="floor" type="plane" size="2 2 0.1"/>',
    free("a", "0 0 0.2", 'name="ball" type="sphere" size="0.05"'),
    option='timestep="0.002"',
)


def _fall(period: int, latency: int, v0: float) -> tuple[Monitor, int]:
    """Drop the ball at ``v0`` m/s downward under a Monitor, the predictor stepping every
    ``period`` physics steps; return the Monitor and the landing's physics step."""
    m = mujoco.MjModel.from_xml_string(_FALL)
    d = mujoco.MjData(m)
    d.qvel[2] = -v0
    p = Predictor(m, accel=10.0, period=period, latency=latency)
    mon = Monitor(p)
    mujoco.mj_step(m, d)
    mon.start(d)
    landing = -1
    for k in range(1, 400):
        mujoco.mj_step(m, d)
        mon.observe(d, p.step(d) if k % period == 0 else None)
        if landing < 0 and d.ncon:
            landing = k
            break
    mon.finish()
    return mon, landing


@pytest.mark.parametrize("latency", [0, 1])
@pytest.mark.parametrize("period", [2, 3, 4, 5])
def test_a_landing_between_predictor_steps_is_flagged_the_horizon_ahead(
    period: int, latency: int
) -> None:
    """Theorem 3 at ``period > 1`` on the motion bounds (docs/theory.md, section 8): every tau
    the schedule acts on is counted in whole physics steps (rounded up: the landing's state is a
    step's) and rounded down to the predictor's grid, so a contact between two of its steps is
    flagged at least the alarm horizon (one period) before it, while the bounds hold. The drops'
    speeds put the landing at every phase between two predictor steps.

    Without the rounding, a landing r steps after a predictor step (0 < r < period) is covered
    by the verdict a period before and stands in alarm only r steps ahead: short while the bounds
    held (met on traffic at period 4: 15 ms against 20). With a step counted past the ceiling, a
    landing at the end of a period is covered a period too long."""
    phases = set()
    for v0 in np.linspace(0.0, 1.0, 2 * period + 3):
        mon, landing = _fall(period, latency, float(v0))
        assert landing > 30 and mon.onsets == mon.predicted == 1 and mon.misses == []
        assert mon.violations == 0 or mon.warning.short_after_violation == 0
        lead = mon.warning.leads[0]
        assert mon.warning.short_held == 0, (v0, landing, lead)
        assert lead >= mon.warning.horizon - 1e-12, (v0, landing, lead)
        phases.add(landing % period)
    assert phases == set(range(period)), phases  # the sweep met every phase


def test_the_grid_counts_no_step_past_the_first_state_it_can_touch_at() -> None:
    """Lemma 8.5 in floating point (docs/theory.md, section 8): a tau becomes whole physics steps
    ``s`` of ``h``, the ceiling of ``tau / h``, which the first state in contact cannot be
    nearer than. The step's rounding, held to the exact ceiling (rationals) at taus on, just
    below and just above whole steps, and between them: never a step more (the promise), and
    the ceiling itself unless the correctly rounded quotient fell to the step below (never a
    step less otherwise). The sample holds quotients that a reciprocal, ``tau * (1 / h)``,
    rounds up past a whole step, and taus between steps where the ceiling is a step above the
    floor grid43 took."""
    rng = np.random.default_rng(5)
    shave = 1.0 - 1e-9
    crossed = raised = 0
    for h in [0.002, 0.001, *rng.uniform(1e-4, 1e-2, 300)]:
        for k in rng.integers(1, 100_000, 20):
            t = float(k) * h
            fracs = rng.uniform(0.0, 1.0, 2) * h
            for tau in (
                t,
                math.nextafter(t, 0.0),
                math.nextafter(t, 1.0),
                t + fracs[0],
                t - fracs[1],
            ):
                if not tau > 0.0:
                    continue
                exact = Fraction(tau) / Fraction(h)
                ceil = math.ceil(exact)
                crossed += math.ceil(tau * (1.0 / h)) > ceil
                got = _core.grid_tau(tau, h, 1)
                assert got <= float(ceil) * h * shave, (tau, h, ceil)  # never a step more
                if tau / h > ceil - 1:  # the quotient did not fall to the step below
                    assert got == float(ceil) * h * shave, (tau, h, ceil)
                    raised += not (tau / h).is_integer()  # a step above grid43's floor
                for p in (2, 3):
                    assert _core.grid_tau(tau, h, p) <= float(ceil // p * p) * h * shave
    assert crossed > 0 and raised > 0, (crossed, raised)
    assert [_core.grid_tau(x, 0.002, 2) for x in (0.0, -1.0, math.inf)] == [0.0, -1.0, math.inf]


@pytest.mark.parametrize("period", [2, 3, 4, 5])
def test_the_plugin_flags_a_landing_between_its_steps_the_horizon_ahead(period: int) -> None:
    """The same at the plugin, whose compute runs at every physics step and predicts every
    ``period``-th (its own period attribute; the same native step): the ball-floor pair stands
    in alarm at every physics step of at least the horizon (``period`` steps) before the step
    that finds the ball on the floor, at every phase of the landing. Without the rounding the
    alarm stood only 1 step ahead at some phases, for each period."""
    phases = set()
    for v0 in np.linspace(0.0, 1.0, 2 * period + 3):
        spec = mujoco.MjSpec.from_string(_FALL)
        attach(spec, accel=10.0, period=period)
        m = spec.compile()
        d = mujoco.MjData(m)
        d.qvel[2] = -v0
        stood = []
        while not d.ncon:
            stood.append(standing_pairs(m, d).shape[0] > 0)
            mujoco.mj_step(m, d)
        landing = len(stood)  # the outputs of the steps before it: stood[1:]
        assert landing > 30
        ahead = next((i for i, s in enumerate(reversed(stood)) if not s), len(stood))
        assert ahead >= period, (v0, landing, ahead)
        phases.add(landing % period)
    assert phases == set(range(period)), phases
