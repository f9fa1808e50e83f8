"""The deadline schedule's screen (docs/theory.md, section 3, "The screen").

A pair out of alarm that a reach test clears for the next step leaves the wheel; the test clears
it again at every step until it fails, and then the pair is evaluated. Three kinds of evidence:

* the test itself against the exact first contact of the sphere model (reference_tau.py), on
  random and on boundary draws, in rational arithmetic on the rows the step reads;
* the schedule's invariant after every step of rollouts (every active pair is linked in the
  wheel, due later, or on the screen with a verdict of this step), through switches, pruned
  rebuilds and the shield's watch;
* A/B rollouts against the wheel alone: no onset missed, no more standing alarms, fewer
  evaluations.

The screened verdicts are also held to the independent reference of whole geoms
(``tests/test_reference_step.py``, the stepped cases).
"""

from __future__ import annotations

import math
from fractions import Fraction

import mujoco
import numpy as np
import pytest
import reference_tau as ref
from hypothesis import example, given, settings
from hypothesis import strategies as st
from rollouts import held_control_states
from test_reference_step import _model  # a bundled scene or a robot of benchmarks/robots.py

from dua_mujoco import Predictor, ScheduleOptions, load_scene
from dua_mujoco._core import LAYOUT, screen_clears
from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.measure.report import RunReport
from dua_mujoco.measure.rollout import run
from dua_mujoco.models.scenes import make_controller

WHERE, LAST_STEP, SCREENED = LAYOUT["WHERE"], LAYOUT["LAST_STEP"], LAYOUT["SCREENED"]

coord = st.floats(-2.0, 2.0, allow_nan=False)
velocity = st.floats(-5.0, 5.0, allow_nan=False)
bound = st.one_of(st.just(0.0), st.floats(1e-6, 1e4))
small = st.one_of(st.just(0.0), st.floats(1e-6, 5.0))


def _cleared_verdict_holds(
    first: list[float], second: list[float], eps: float, accel: float, delta: float, h: float
) -> bool:
    """Whether the sphere model (relative velocity ``v_j - v_i``, docs/theory.md, section 1)
    has no contact before the verdict a cleared pair gets, the double above ``h``: exactly, on
    the rows' own numbers (the offset is the difference of two floats, kept as a fraction)."""
    x = [Fraction(b) - Fraction(a) for a, b in zip(first[:3], second[:3], strict=True)]
    v = [Fraction(b) - Fraction(a) for a, b in zip(first[3:], second[3:], strict=True)]
    root = ref.tau_sphere_ref(x, v, eps, accel, delta)
    return root.is_lower_bound(math.nextafter(h, math.inf))


def _check(first: list[float], second: list[float], eps: float, accel: float, delta: float,
           h: float) -> bool:  # fmt: skip
    cleared = screen_clears(first, second, eps, accel, delta, h)
    if cleared:
        assert _cleared_verdict_holds(first, second, eps, accel, delta, h), (
            first,
            second,
            eps,
            accel,
            delta,
            h,
        )
    return cleared


@settings(max_examples=400, deadline=None)
@given(
    first=st.lists(coord, min_size=3, max_size=3),
    offset=st.lists(coord, min_size=3, max_size=3),
    vi=st.lists(velocity, min_size=3, max_size=3),
    vj=st.lists(velocity, min_size=3, max_size=3),
    eps=st.floats(0.0, 0.5),
    accel=bound,
    delta=small,
    h=st.floats(1e-3, 0.5),
)
# Far apart and at rest: cleared (the test is not vacuous).
@example([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0] * 3, [0.0] * 3, 0.1, 1.0, 0.0, 0.01)
def test_the_screen_never_clears_a_pair_that_can_touch_within_h(
    first: list[float], offset: list[float], vi: list[float], vj: list[float], eps: float,
    accel: float, delta: float, h: float,
) -> None:  # fmt: skip
    second = [a + b for a, b in zip(first, offset, strict=True)]
    _check(first + vi, second + vj, eps, accel, delta, h)


@settings(max_examples=400, deadline=None)
@given(
    direction=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).filter(
        lambda u: math.hypot(*u) > 1e-3
    ),
    si=st.floats(0.0, 5.0),
    sj=st.floats(0.0, 5.0),
    eps=st.floats(0.0, 0.5),
    accel=bound,
    delta=small,
    h=st.floats(1e-3, 0.5),
    k=st.integers(-8, 8),
    scale=st.sampled_from([1e-10, 2.0**-52]),
)
def test_the_screen_at_its_boundary_clears_only_what_the_model_keeps_apart(
    direction: list[float], si: float, sj: float, eps: float, accel: float, delta: float,
    h: float, k: int, scale: float,
) -> None:  # fmt: skip
    """Head on (the spheres close at the sum of their speeds, the fastest the test allows), at
    distances within a few units of its margin (1e-9 of the squares) or of the last place around
    the reach: where a margin too small or a speed left out would clear a pair that touches."""
    n = math.hypot(*direction)
    u = [c / n for c in direction]
    reach = eps + (si + sj + delta) * h + 0.5 * accel * h * h
    gap = reach * (1.0 + k * scale)
    first = [0.0, 0.0, 0.0, si * u[0], si * u[1], si * u[2]]
    second = [gap * u[0], gap * u[1], gap * u[2], -sj * u[0], -sj * u[1], -sj * u[2]]
    cleared = _check(first, second, eps, accel, delta, h)
    if k <= -1 and scale == 1e-10 and reach > 1e-90:
        assert not cleared  # inside the reach: must not clear, whatever the rounding


@pytest.mark.parametrize(
    ("first", "second"),
    [
        ([0.0, 0.0, 0.0, math.nan, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        ([0.0, 0.0, 0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, math.inf, 0.0, 0.0]),
        ([0.0, 0.0, 0.0, 2e300, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]),  # not tame
        ([-1e151, 0.0, 0.0, 0.0, 0.0, 0.0], [1e151, 0.0, 0.0, 0.0, 0.0, 0.0]),  # |x|^2 > 1e300
        ([0.0, 0.0, 0.0, 0.0, 0.0, 0.0], [math.nan, 0.0, 0.0, 0.0, 0.0, 0.0]),
    ],
)
def test_the_screen_leaves_what_it_cannot_judge_to_the_kernel(
    first: list[float], second: list[float]
) -> None:
    """Not a number, not tame, or squares past 1e300: not cleared (the step evaluates the pair,
    and the kernel handles each of these)."""
    far = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    assert not screen_clears(first, second, 1e-3, 0.0, 0.0, 0.01)
    assert screen_clears([0.0] * 6, far, 1e-3, 0.0, 0.0, 0.01)
    # A horizon past Lemma 3.9's 1e50 s, or subnormal (the double above it can be twice it).
    for h in (1e50, 5e-324, 1e-310):
        assert not screen_clears([0.0] * 6, far, 1e-3, 0.0, 0.0, h)
    # A reach's bounds part below 1e-100: a cleared |x|^2 need not be normal (Lemma 3.9).
    assert screen_clears([0.0] * 6, far, 1e-100, 0.0, 0.0, 0.01)
    for eps in (0.0, 1e-101, math.nan):
        assert not screen_clears([0.0] * 6, far, eps, 0.0, 0.0, 0.01)


def test_the_screen_names_rows_of_the_wrong_length() -> None:
    with pytest.raises(ValueError, match=r"two sphere rows of 6 numbers .* not 3 and 6"):
        screen_clears([0.0] * 3, [0.0] * 6, 0.0, 0.0, 0.0, 0.01)


def test_the_screen_option_takes_a_bool() -> None:
    with pytest.raises(InvalidInputError, match="screen = 1 is invalid: pass True or False"):
        ScheduleOptions(screen=1)  # type: ignore[arg-type]


def _check_invariant(p: Predictor) -> tuple[int, int]:
    """Every active held pair is linked in the wheel and due after this step, or on the screen
    with a verdict of this step that does not stand; a pair switched off is in neither.
    Returns the pairs on the screen and on the wheel."""
    s = p.pair_state()
    sched = s.scheduler
    where, last = sched.ints[WHERE], sched.ints[LAST_STEP]
    n = s.step_count
    on = np.asarray(sched.active, dtype=bool)
    screened = where == SCREENED
    assert not (screened & ~on).any(), "a pair switched off is on the screen"
    assert (where[~on] == -1).all(), "a pair switched off is linked"
    assert ((where[on] > n) | screened[on]).all(), "an active pair is neither due nor screened"
    assert (last[screened] == n).all(), "a screened pair's verdict is not of this step"
    # Not standing (its verdict covers the next step, when it is tested again).
    ids = np.flatnonzero(screened)
    assert (sched.last_tau[screened] > sched.horizon_of(ids)).all()
    assert (sched.next_due(ids) == n + 1).all()
    # Renewed at this step: the monitor dates the verdicts an alarm replaces by these.
    selected = s.last_selected
    assert np.isin(np.asarray(p.held_pairs)[ids], selected).all()
    # The monitor counts the evaluations: the renewed verdicts less those of no evaluation.
    assert selected.size == p.evaluations_per_step + s.settled + s.cleared + s.deferred
    return int(screened.sum()), int((where > n).sum())


@pytest.mark.parametrize(
    ("scene", "accel", "options"),
    [
        ("two_arms", 200.0, {}),
        ("two_arms", 200.0, {"latency": 1}),  # the test's h is the horizon past the latency
        ("clutter", 30.0, {"schedule": ScheduleOptions(max_evals_per_step=8)}),  # deferrals
        ("bin_pour:30", 5.0, {"pairs": "pruned"}),
        ("robot/dmc_dog", 200.0, {}),
    ],
)
def test_every_active_pair_is_on_the_wheel_or_the_screen(
    scene: str, accel: float, options: dict
) -> None:
    """After every step of a rollout under random controls, with bodies switched off and on
    again now and then (and, pruned, the held set rebuilt and carried; capped, pairs deferred),
    the invariant holds; and the screen holds pairs (not vacuous)."""
    m, d = _model(scene)
    p = Predictor(m, accel=accel, **options)
    ctrl = make_controller(m, "random", seed=3)
    rng = np.random.default_rng(3)
    p.reset(d)
    moving = np.flatnonzero(np.asarray(m.body_dofnum) > 0)
    most = 0
    for k in range(300):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        if k % 37 == 5 and moving.size:
            b = int(rng.choice(moving))
            p.set_active_bodies(b, on=False)
            _check_invariant(p)
            if k % 2:
                p.set_active_bodies(b, on=True)
        p.step(d)
        screened, _ = _check_invariant(p)
        most = max(most, screened)
    assert most > 0
    if options.get("pairs") == "pruned":
        assert p.rebuilds > 0


def _rollout(screen: bool, scene: str) -> RunReport:
    m, d = load_scene(scene)
    p = Predictor(m, accel=200.0, schedule=ScheduleOptions(screen=screen))
    return run(m, d, p, steps=600, progress=False)


@pytest.mark.parametrize("scene", ["two_arms", "clutter", "traffic", "paper_world"])
def test_the_screen_keeps_every_onset_and_stands_no_more(scene: str) -> None:
    """A/B against the wheel alone on the same motion: every onset flagged in both, the share
    of geom pairs standing in alarm no higher, fewer evaluations."""
    wheel, screen = _rollout(False, scene), _rollout(True, scene)
    assert screen.contact_onsets == wheel.contact_onsets > 0
    assert screen.missed_onsets == wheel.missed_onsets == 0
    assert screen.standing_alarm_fraction <= wheel.standing_alarm_fraction
    assert screen.evals_per_step < wheel.evals_per_step


def test_no_pair_is_screened_while_the_runtime_watches_or_off_the_grid() -> None:
    """A watching runtime (the shield's, the gymnasium wrapper's) reads each pair's verdict as
    far as it reaches, so it does not screen, and the pairs a screen held before the watch go
    back to the wheel; with a predictor period of 2 nothing is screened either. The same runs
    at period 1 unwatched screen pairs, so the setup reaches the rule."""
    m, d = load_scene("two_arms")
    p = Predictor(m, accel=200.0)
    ctrl = make_controller(m, "random", seed=1)
    p.reset(d)
    for _ in range(50):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        p.step(d)
    assert p.pair_state().screened > 0
    p._rt.watch(np.zeros(m.ngeom, dtype=np.uint8), np.zeros(0, dtype=np.int64))
    _check_invariant_between_steps(p)
    for _ in range(50):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        p.step(d)
        assert p.pair_state().screened == 0

    m, d = load_scene("two_arms")
    p = Predictor(m, accel=200.0, period=2)
    p.reset(d)
    for k in range(100):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        if k % 2:
            p.step(d)
            assert p.pair_state().screened == 0


def _check_invariant_between_steps(p: Predictor) -> None:
    """Before the next step: no pair on the screen, every active one due at it or later."""
    s = p.pair_state()
    where = s.scheduler.ints[WHERE]
    on = np.asarray(s.scheduler.active, dtype=bool)
    assert s.screened == 0 and (where[on] > s.step_count).all()


def test_no_pair_is_screened_while_a_plan_is_set() -> None:
    """A plan's verdicts rest on the plan, the screen's on the bounds: while a plan is set the
    step screens nothing, and the pairs the screen held go to the wheel at the plan's first
    step."""
    m, d = load_scene("two_arms")
    p = Predictor(m, accel=200.0)
    p.reset(d)
    for _ in range(50):
        mujoco.mj_step(m, d)
        p.step(d)
    assert p.pair_state().screened > 0
    # The plan: the next 200 states under the controls held as they are.
    p.set_plan(held_control_states(m, d, 200), deviation=0.0)
    planned = 0
    for _ in range(150):
        mujoco.mj_step(m, d)
        p.step(d)
        if p.has_plan:
            planned += 1
            assert p.pair_state().screened == 0
    assert planned > 100


def test_no_pair_the_plan_revisits_soon_is_screened() -> None:
    """Under a followed plan (a ball planned to roll at a wall, no controls) the plan's verdicts
    give pairs short waits, out of alarm, that the bounds' test would clear: none is screened,
    since the verdict a screened pair gets rests on the bounds, not on the plan."""
    from test_flightplan import _rollout, _scene  # the suite's plan scene

    m, d = _scene()
    p = Predictor(m, accel=1.0, alarm_horizon=0.05)
    p.reset(d)
    p.set_plan(_rollout(m, d, np.zeros((210, m.nu)), 210), deviation=0.0)
    short = 0
    for _ in range(200):
        d.ctrl[:] = 0.0
        mujoco.mj_step(m, d)
        p.step(d)
        s = p.pair_state()
        assert p.has_plan and s.screened == 0
        sched = s.scheduler
        ids = sched.work[LAYOUT["W_IDS"], : int(sched.params[LAYOUT["P_COUNT"]])]
        wait = sched.ints[WHERE, ids] - s.step_count
        short += int(((wait <= 16) & (sched.last_tau[ids] > sched.horizon[0])).sum())
    assert short > 0  # the plan gives waits the screen would take
