"""Violations as events (``dua_mujoco.build.events``; docs/theory.md, section 6).

The compiled check is held to ``BoundMonitor``, the point-by-point reference, step by step; the
pairs of a body that broke its bounds must be evaluated at that very step; and a scene where a
collision follows an impulse at once shows that the check, and its timing, are what flag it.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Iterator

import mujoco
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from mjcf import free, mjcf

from dua_mujoco import _core
from dua_mujoco.build.events import body_boxes
from dua_mujoco.build.kinematics import mjdata_frame, pack_spheres, sphere_states
from dua_mujoco.build.options import ScheduleOptions
from dua_mujoco.exceptions import NonFiniteStateError
from dua_mujoco.measure.checks import BoundMonitor
from dua_mujoco.measure.rollout import run
from dua_mujoco.models.scenes import load_scene, make_controller
from dua_mujoco.runtime.pairstate import PairState
from dua_mujoco.runtime.predictor import Predictor

# Three balls in a row, no gravity: the striker hits the middle ball, which rests 0.1 mm from
# the last one. The impulse moves the middle ball into the last one within one physics step,
# so that collision's onset is the step at which the middle ball's bounds break.
THREE_BALLS = mjcf(
    free("striker", "-0.2 0 0", 'name="striker" size="0.05"'),
    free("middle", "0 0 0", 'name="middle" size="0.05"'),
    free("last", "0.1001 0 0", 'name="last" size="0.05"'),
    option='gravity="0 0 0" timestep="0.002"',
)


def _three_balls() -> tuple[mujoco.MjModel, mujoco.MjData]:
    m = mujoco.MjModel.from_xml_string(THREE_BALLS)
    d = mujoco.MjData(m)
    d.qvel[0] = 2.0  # the striker, towards the middle ball
    mujoco.mj_forward(m, d)
    return m, d


@settings(max_examples=300, deadline=None)
@given(arrays(np.float64, 12, elements=st.floats(-10, 10)), st.floats(0, 40))
# Squares of 1.25e-162 underflow to 0: the box then read as a point and passed a bound of 0.
@example(np.full(12, 1.25e-162), 0.0)
@example(np.full(12, 1e-200), 1e-190)
@example(np.zeros(12), 0.0)
def test_exceeds_is_the_largest_corner(q: np.ndarray, bound: float) -> None:
    """``exceeds12`` (the check's screen) uses the triangle inequality: it must agree with the
    corners, at any scale."""
    corners = [  # math.hypot scales: no square underflows in the reference either
        math.hypot(*(q[:3] + s[0] * q[3:6] + s[1] * q[6:9] + s[2] * q[9:12]))
        for s in itertools.product((-1.0, 1.0), repeat=3)
    ]
    assert _core.exceeds12(q, bound) == (max(corners) > bound)


@pytest.mark.parametrize("scene", ["two_arms", "clutter"])
def test_body_boxes_hold_every_bound_point(scene: str) -> None:
    """Each point the bounds limit lies in its body's box, at every state: a bound checked at
    the box's corners holds for it."""
    m, d = load_scene(scene)
    p = Predictor(m, accel=5.0)
    # The covering's centres and the exact level's corners, as the predictor gathered them.
    sgeom, sbody, soff = p.covering.sphere_geom, p.covering.sphere_body, p.covering.sphere_offset
    assert p.exact is not None
    points = p.exact.with_corners(m, (sgeom, sbody, soff))
    boxes = body_boxes(m, points)
    ctrl = make_controller(m, "random", seed=3)
    twist = np.zeros((m.nbody, 6))
    for _ in range(50):
        ctrl(m, d)
        mujoco.mj_step(m, d)
    frame = mjdata_frame(d, twist)
    c, _ = sphere_states(pack_spheres(*points, m.body_rootid), frame)
    row = {int(b): i for i, b in enumerate(boxes.body)}
    for k, b in enumerate(np.asarray(points[1]).tolist()):
        i = row[b]
        g = int(boxes.frame[i])
        local = d.geom_xmat[g].reshape(3, 3).T @ (c[k] - d.geom_xpos[g])
        assert np.all(np.abs(local - boxes.center[i]) <= boxes.half[i] + 1e-9)


@pytest.mark.parametrize(("scene", "accel"), [("two_arms", 20.0), ("traffic", 5.0)])
def test_step_flags_the_bodies_the_bound_monitor_flags(scene: str, accel: float) -> None:
    """Period 1: the step's O(bodies) check and ``BoundMonitor``'s point-by-point check of the
    same corners flag the same bodies at every step."""
    m, d = load_scene(scene)
    p = Predictor(m, accel=accel)
    flagged = _flags_as_the_bound_monitor(p, m, d, steps=600)
    assert flagged > 20  # the bounds broke often enough to mean something
    assert p.violation_events == flagged


def _flags_as_the_bound_monitor(
    p: Predictor, m: mujoco.MjModel, d: mujoco.MjData, steps: int
) -> int:
    """Steps ``p`` under random controls, asserting at each step that it flags the bodies
    ``BoundMonitor`` flags; returns how many it flagged."""
    bm = BoundMonitor(m, p.bounds, p.bound_points, mocap=p.mocap)
    ctrl = make_controller(m, "random", seed=1)
    ctrl(m, d)
    mujoco.mj_step(m, d)
    p.reset(d)
    bm.update(m, d)
    flagged = 0
    for _ in range(steps):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        p.step(d)
        expected = bm.update(m, d)
        assert p.violated_bodies.tolist() == sorted(expected.tolist())
        flagged += expected.size
    return flagged


def test_a_body_that_breaks_its_acceleration_bound_alone_is_flagged() -> None:
    """The check's common path passes a group of four when every screen's first test passes on
    every lane: the acceleration's too. Here the discrepancy bound is loose (1000 m/s) and there
    is no speed bound, so only the acceleration can flag a body, as ``BoundMonitor`` says."""
    m, d = load_scene("two_arms")
    bounds = Predictor(m, accel=20.0).bounds
    loose = dataclasses.replace(
        bounds, speed=None, vel_uncertainty=np.where(bounds.accel > 0, 1e3, bounds.vel_uncertainty)
    )
    p = Predictor(m, accel=loose)
    flagged = _flags_as_the_bound_monitor(p, m, d, steps=300)
    assert flagged > 20  # the acceleration bound broke often enough to mean something


@pytest.mark.parametrize(
    ("scene", "accel"),
    [("two_arms", 20.0), ("swarm:30", 2.0), ("swarm:31", 2.0), ("traffic", 5.0)],
)
def test_the_checks_lanes_equal_one_body_at_a_time(scene: str, accel: float) -> None:
    """The step checks four bodies at a time (lanes.h): at every step, from the same state, it
    flags the bodies and writes the states that checking one body at a time does, bit for bit
    (a NaN's sign aside: the compiler may swap the operands of + and *; numpy compares NaNs
    equal). The scenes have 4k, 4k + 1, 4k + 2 and 4k + 3 bodies: every ragged last group."""
    m, d = load_scene(scene)
    p = Predictor(m, accel=accel)
    assert p.events is not None
    nbody, group, width = p.events.nbody, 4, _core.LAYOUT["NB_STATE"]
    ctrl = make_controller(m, "random", seed=2)
    ctrl(m, d)
    mujoco.mj_step(m, d)
    p.reset(d)
    flagged = 0
    for k in range(300):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        results = []
        for lanes in (False, True):
            rows, flat = p._rt.check_bodies_copy(lanes)
            state = flat.reshape(-1, width, group)
            # Body by body (the lanes also write the last group's padding; one at a time not).
            by_body = state.transpose(0, 2, 1).reshape(-1, width)[:nbody]
            results.append((rows.tolist(), by_body))
            if lanes and nbody % group:
                # The padding runs as the last body (so its spare lanes take that body's paths).
                last = state[-1, :, nbody % group - 1]
                for j in range(nbody % group, group):
                    np.testing.assert_array_equal(state[-1, :, j], last)
        assert results[0][0] == results[1][0], f"step {k}"
        np.testing.assert_array_equal(results[1][1], results[0][1], err_msg=f"step {k}")
        flagged += len(results[0][0])
        p.step(d)
    assert flagged > 0  # the bounds broke: the check's every branch ran


def test_the_checks_lanes_judge_bounds_below_their_squares_underflow() -> None:
    """A bound below 1e-139 sends its lane of the four-body check to ``Exceeds12``'s rescan
    (step.cc): numbers whose squares underflow would read as 0 and pass it. Seven bodies shrunk
    2^-560 times (their frames' matrices scaled: the check's arithmetic takes any matrix), every
    other one with a bound of 1e-170, move by chords of up to 1.1e-162 (their squares 0 in
    doubles): each step's flags must be the declared hypotheses' at the corners, with
    ``math.hypot`` (which scales, so nothing underflows in the reference), and the lanes' flags and
    states those of one body at a time, bit for bit. Groups of four mix small and large bounds,
    and the last group is ragged. Fails with the rescan written to a wrong lane or skipped
    (benchmarks/mutants.py)."""
    n, h = 7, 2.0**-9  # 1 / h exact: the chords are the position steps times 512, exactly
    m = mujoco.MjModel.from_xml_string(
        mjcf(
            *(free(f"b{i}", f"{i} 0 0", 'size="0.0625"') for i in range(n)),
            option=f'gravity="0 0 0" timestep="{h!r}"',
        )
    )
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    accel = {f"b{i}": 1e-170 if i % 2 == 0 else 1.0 for i in range(n)}
    p = Predictor(m, accel=accel)
    assert p.events is not None and p.bounds.speed is None
    body = np.asarray(m.geom_bodyid)
    A, D = p.bounds.accel[body], p.bounds.discrepancy[body]  # by geom (one a body)
    assert np.all((D < 1e-139) == (A < 1e-139)) and (D < 1e-139).sum() == 4
    rng = np.random.default_rng(5)
    pos = np.zeros((m.ngeom, 3))
    width = _core.LAYOUT["NB_STATE"]

    def put(pos: np.ndarray) -> None:
        """The frames: the geoms at ``pos``, turned by 2^-560 I, no velocity."""
        d.geom_xpos[:] = pos
        d.geom_xmat[:] = np.ldexp(np.eye(3), -560).ravel()
        d.xpos[:] = d.subtree_com[:] = d.cvel[:] = 0.0

    put(pos)
    p.reset(d)
    chord = np.zeros((m.ngeom, 3))
    flagged = small_flagged = 0
    for k in range(1, 13):
        still = rng.random(m.ngeom) < 0.3
        steps = np.ldexp(rng.integers(-4, 5, (m.ngeom, 3)).astype(float), -549)
        pos = pos + np.where(still[:, None], 0.0, steps)
        last, chord = chord, np.where(still[:, None], 0.0, steps) / h
        put(pos)
        # The declared hypotheses at the box's corners: its axes keep still, so every corner's
        # chord is the centre's; no velocity, so the discrepancy is the chord.
        expected = []
        for g in range(m.ngeom):
            speed, change = math.hypot(*chord[g]), math.hypot(*(chord[g] - last[g])) / h
            # Far from the bounds either way: the round-off allowances play no part.
            assert speed == 0 or not 1e-3 < speed / D[g] < 1e3
            if speed > D[g] or (k >= 2 and change > A[g]):
                expected.append(g)
        results = []
        for lanes in (False, True):
            rows, flat = p._rt.check_bodies_copy(lanes)
            by_body = flat.reshape(-1, width, 4).transpose(0, 2, 1).reshape(-1, width)[:n]
            results.append((rows.tolist(), by_body))
        assert results[0][0] == results[1][0], f"step {k}"
        np.testing.assert_array_equal(results[1][1], results[0][1], err_msg=f"step {k}")
        d.time += h
        p.step(d)
        assert p.violated_bodies.tolist() == body[expected].tolist(), f"step {k}"
        flagged += len(expected)
        small_flagged += int((A[expected] < 1e-139).sum())
    assert small_flagged == flagged > 10  # the small bounds' lanes flagged, the others never


def _random_run(
    m: mujoco.MjModel, d: mujoco.MjData, p: Predictor, steps: int
) -> Iterator[PairState]:
    """``p`` reset one step into random controls (seed 2), then followed ``steps`` steps: the
    schedule's state after each."""
    ctrl = make_controller(m, "random", seed=2)
    ctrl(m, d)
    mujoco.mj_step(m, d)
    p.reset(d)
    for _ in range(steps):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        p.step(d)
        yield p.pair_state()


@pytest.mark.parametrize("cap", [None, 3])
def test_pairs_of_a_violated_body_are_renewed_at_that_step(cap: int | None) -> None:
    """Every held pair of a body that broke its bounds is evaluated at that step, or (over a
    cap) stands in alarm until it is."""
    m, d = load_scene("traffic")
    p = Predictor(m, accel=5.0, schedule=ScheduleOptions(max_evals_per_step=cap))
    body1 = m.geom_bodyid[p.tables.geom1]
    body2 = np.where(p.tables.geom2 >= 0, m.geom_bodyid[np.maximum(p.tables.geom2, 0)], 0)
    renewed = 0
    for sched in _random_run(m, d, p, 1500):
        broke = p.violated_bodies
        if broke.size == 0:
            continue
        pairs = np.flatnonzero(np.isin(body1, broke) | np.isin(body2, broke))
        now = sched.last_step_of(pairs) == sched.step_count
        assert np.all(now | sched.alarm_state(pairs))
        renewed += int(now.sum())
    assert renewed > 100


def test_settled_pairs_get_a_verdict_of_that_step_below_the_sphere_kernels() -> None:
    """A flagged body's pair the step settles instead of evaluating (docs/theory.md, section 6,
    "Settling a made-due pair") gets a verdict of that step, which does not alarm and is at most
    the sphere kernel's tau on the same state (so it bounds the first root as the evaluation
    would). Fails with the bound's speed or acceleration term dropped (benchmarks/mutants.py)."""
    m, d = load_scene("traffic")
    p = Predictor(m, accel=5.0)
    rec = p.pair_records
    settled = 0
    for state in _random_run(m, d, p, 600):
        k = state.settled
        if k == 0:
            continue
        count = p.evaluations_per_step
        ids = state.last_selected[count : count + k]
        assert np.all(state.last_step_of(ids) == state.step_count)
        assert not state.alarm_state(ids).any()
        c, v = p.sphere_states(d)
        i, j = rec[ids, 0].astype(np.int64), rec[ids, 1].astype(np.int64)
        tau = _core.tau_speed_batch(
            c[j] - c[i], v[j] - v[i], rec[ids, 3], rec[ids, 4], rec[ids, 5], rec[ids, 6]
        )
        lower = state.last_tau_of(ids)
        assert np.all(lower <= tau), (lower[lower > tau], tau[lower > tau])
        settled += k
    assert settled > 1000


def test_settled_pairs_wait_on_the_predictor_grid_at_period_above_one() -> None:
    """With ``period > 1`` every tau the schedule acts on is floored onto the predictor's grid
    (docs/theory.md, section 8; a verdict off it lets a contact between two predictor steps
    stand in alarm less than the horizon ahead): a settled pair's verdict too, a whole number of
    periods (shaved by 1e-9). Fails with SettleBound's grid dropped (benchmarks/mutants.py)."""
    m, d = load_scene("traffic")
    period = 3
    p = Predictor(m, accel=5.0, period=period)
    grid = period * m.opt.timestep * (1.0 - 1e-9)
    ctrl = make_controller(m, "random", seed=2)
    ctrl(m, d)
    mujoco.mj_step(m, d)
    p.reset(d)
    settled = 0
    for k in range(1, 1800):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        if k % period:
            continue
        p.step(d)
        state = p.pair_state()
        if state.settled == 0:
            continue
        count = p.evaluations_per_step
        tau = state.last_tau_of(state.last_selected[count : count + state.settled])
        finite = tau[np.isfinite(tau) & (tau > 0.0)]
        np.testing.assert_allclose(finite / grid, np.round(finite / grid), rtol=0, atol=1e-6)
        settled += finite.size
    assert settled > 100


def test_a_step_retried_after_it_failed_judges_the_pairs_it_had_settled_again() -> None:
    """A step that fails (a non-finite state) leaves the pairs it settled made due, as the ones
    it evaluated: retried on a repaired state at the same time, a pair whose body was flung 50 m
    away (and so settled) and is now put onto the other body alarms. Kept as the failed step's
    verdict, it would not be looked at again until its due step."""
    m, d = load_scene("traffic")
    p = Predictor(m, accel=5.0)
    for _ in _random_run(m, d, p, 100):
        pass
    mujoco.mj_step(m, d)
    rec, body = p.pair_records, m.geom_bodyid
    g1, g2 = (np.asarray(a) for a in p.sphere_pair_geoms)
    c, v = p.sphere_states(d)
    i, j = rec[:, 0].astype(np.int64), rec[:, 1].astype(np.int64)
    tau = _core.tau_speed_batch(
        c[j] - c[i], v[j] - v[i], rec[:, 3], rec[:, 4], rec[:, 5], rec[:, 6]
    )
    between = np.flatnonzero((body[g1] != body[g2]) & (body[g1] > 0) & (body[g2] > 0))
    k = between[np.argmin(tau[between])]
    b, other = body[g1[k]], body[g2[k]]
    third = next(x for x in range(1, m.nbody) if x not in (b, other) and np.any(body == x))
    repaired = d.geom_xpos.copy()
    d.geom_xpos[body == b] += [50.0, 0.0, 0.0]
    d.geom_xpos[np.flatnonzero(body == third)[0]] = np.nan
    with pytest.raises(NonFiniteStateError):
        p.step(d)
    assert p.pair_state().last_tau_of(np.array([k]))[0] == -math.inf
    d.geom_xpos[:] = repaired
    d.geom_xpos[body == b] += d.geom_xpos[g2[k]] - d.geom_xpos[g1[k]]
    alarms = p.step(d)
    assert p.pair_state().alarm_state(np.array([k]))[0] and len(alarms) > 0


def test_a_collision_right_after_an_impulse_is_flagged_only_with_events() -> None:
    """The middle ball's bounds break at the step it touches the last ball. Evaluated again at
    that step, the pair alarms; one step late, or never, it is missed. Off the screen (which
    tests a screened pair on every step's state, so that it would catch this pair without the
    events), as on the wheel alone."""
    m, d = _three_balls()
    on_time = run(m, d, Predictor(m, accel=1.0), steps=200, progress=False)
    assert on_time.contact_onsets >= 2 and on_time.bound_violations > 0
    assert on_time.missed_onsets == 0

    m, d = _three_balls()
    wheel = ScheduleOptions(violation_events=False, screen=False)
    never = Predictor(m, accel=1.0, schedule=wheel)
    report = run(m, d, never, steps=200, progress=False)
    assert report.missed_onsets_outside_violations >= 1

    # One step late: the pairs of the bodies that broke their bounds are made due at the next
    # step (switched off and on again, which withdraws their verdict) instead of this one.
    m, d = _three_balls()
    late = Predictor(m, accel=1.0, schedule=wheel)
    checks = BoundMonitor(m, late.bounds, late.bound_points)

    def renew_next_step(k: int, data: mujoco.MjData, alarms: object, monitor: object) -> None:
        for b in checks.update(m, data).tolist():
            late.set_active_bodies(b, on=False)
            late.set_active_bodies(b, on=True)

    report = run(m, d, late, steps=200, progress=False, on_step=renew_next_step)
    assert report.missed_onsets_outside_violations >= 1


# The middle ball rests 15 cm from the last one: far enough that a pruned predictor with a slow
# bound leaves that pair out, near enough that once struck it hits the last ball (about step
# 80) before the next regular rebuild (a horizon of 0.2 s: every 100 steps).
SPREAD_BALLS = THREE_BALLS.replace('pos="0.1001 0 0"', 'pos="0.25 0 0"')


@pytest.mark.parametrize("renew", [True, False], ids=["renewal", "rebuild"])
def test_a_pruned_predictor_renews_its_pairs_when_a_struck_body_leaves_their_reach(
    monkeypatch: pytest.MonkeyPatch, renew: bool
) -> None:
    """After the impulse the middle ball is faster than the reach that left out its pair with
    the last ball assumed: the escape check renews its pairs at the next step (alone, or by a
    rebuild of the whole held set when too many spheres escaped) and the collision is flagged.
    Without the check (never escaped) the pair is not held until the next regular rebuild, and
    the collision is missed outside a violation's period."""
    from dua_mujoco.build.options import PairOptions
    from dua_mujoco.runtime import table_arrays

    if not renew:
        monkeypatch.setattr(table_arrays, "RENEW_MAX", 0)

    def balls() -> tuple[mujoco.MjModel, mujoco.MjData]:
        m = mujoco.MjModel.from_xml_string(SPREAD_BALLS)
        d = mujoco.MjData(m)
        d.qvel[0] = 2.0
        mujoco.mj_forward(m, d)
        return m, d

    pruned = PairOptions(mode="pruned", horizon=0.2)
    m, d = balls()
    p = Predictor(m, accel=0.1, pairs=pruned)
    report = run(m, d, p, steps=100, progress=False)
    assert report.contact_onsets >= 2 and report.bound_violations > 0
    assert report.missed_onsets_outside_violations == 0
    # At the step after the strike; the regular rebuild is at step 100.
    assert (p.renewals >= 1) if renew else (p.renewals == 0 and p.rebuilds >= 1)

    m, d = balls()
    blind_predictor = Predictor(m, accel=0.1, pairs=pruned)
    blind_predictor._rt.set_escape_check(False)
    blind = run(m, d, blind_predictor, steps=100, progress=False)
    assert blind.missed_onsets_outside_violations >= 1


@pytest.mark.parametrize("seed", range(3))
def test_held_pairs_are_indexed_by_body_as_a_stable_sort_would(seed: int) -> None:
    """The runtime's index of held pairs by the violation check's rows (a counting sort): for
    each checked body, the held pairs with a geom on it, by first geom then second, each in
    increasing position, as a stable argsort of the rows does it; geoms of unchecked bodies and
    -1 left out."""
    from dua_mujoco.build.events import B_BODY

    m, _ = load_scene("two_arms")
    events = Predictor(m, accel=30.0).events
    assert events is not None
    rng = np.random.default_rng(seed)
    g1, g2 = rng.integers(-1, m.ngeom, (2, 500))
    row_of_body = np.full(m.nbody, -1)
    row_of_body[events.records[:, B_BODY].astype(int)] = np.arange(events.nbody)
    start, members = _core.index_by_row(row_of_body[m.geom_bodyid], g1, g2, events.nbody)
    rows = np.concatenate([row_of_body[m.geom_bodyid[g]] * (g >= 0) - (g < 0) for g in (g1, g2)])
    pos = np.concatenate([np.arange(500), np.arange(500)])
    keep = rows >= 0
    order = np.argsort(rows[keep], kind="stable")
    np.testing.assert_array_equal(members, pos[keep][order])
    np.testing.assert_array_equal(
        start, np.searchsorted(rows[keep][order], np.arange(events.nbody + 1))
    )
    assert 0 < members.size < 1000
