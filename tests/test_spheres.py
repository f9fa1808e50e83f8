"""``SpherePredictor`` (the native runtime on free spheres) and its pruned pair sets: completeness
in ghost worlds, the slow reference, the rebuild's carried state, the horizon's off-by-one, the
escape test and its renewals, validation and ``pairs="auto"``."""

from __future__ import annotations

import copy
import dataclasses
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dua_mujoco import _core
from dua_mujoco.core.pairset import PairSet
from dua_mujoco.core.schedules import DeadlineScheduler
from dua_mujoco.core.spheres import AUTO_PRUNED_MIN, PairMode, SpherePredictor, rebuild_stride
from dua_mujoco.exceptions import (
    BoundViolationWarning,
    InvalidBoundError,
    InvalidChoiceError,
    InvalidInputError,
    NonFiniteStateError,
    SchedulerError,
    ShapeError,
)
from dua_mujoco.experiments.paper.world import AccelProfile, SphereWorld


@dataclasses.dataclass
class Outcome:
    onsets: int
    missed: list[tuple[int, int, float]]
    reference_misses: int
    held_max: int
    rebuilds: int
    renewals: int


def _key_set(pairs: np.ndarray, n: int) -> set[int]:
    return set((pairs[:, 0] * n + pairs[:, 1]).tolist())


def run_predictor(
    world: SphereWorld,
    pred: SpherePredictor,
    *,
    steps: int,
    substeps: int = 8,
    reference: bool = False,
    noise: float = 0.0,
) -> Outcome:
    """Drive ``pred`` on ``world``; every onset must meet an alarm of the verdict acting then.

    The verdict acting at time ``t`` is the latest one made at a step ``q`` with
    ``(q + latency) dt <= t`` (the reset's before that). Onsets are found over all pairs on a
    grid of ``substeps`` times a step (any grid onset is a real one). With ``reference``, each
    step also checks the slow reference: every pair whose tau over all pairs is below
    ``(1 + latency) dt`` stands in alarm. ``noise``: the predictor is given velocities off by up
    to that much (its ``vel_uncertainty`` must cover it), the reference the true ones.
    """
    n, lat, S = world.n, pred.latency, substeps
    every = PairSet.all_pairs(world.radius, world.accel_bound, margin=pred.margin)
    ids = np.arange(len(every))
    i, j = every.first, every.second
    rng = np.random.default_rng(n)

    def measured(v: np.ndarray) -> np.ndarray:
        d = rng.normal(size=v.shape)
        return v + d * (noise * rng.uniform(0, 1, (n, 1)) / np.linalg.norm(d, axis=1)[:, None])

    history = [_key_set(pred.reset(world.positions, measured(world.velocities)), n)]
    held_max = pred.npairs

    def touching(pos: np.ndarray) -> np.ndarray:
        return np.linalg.norm(pos[j] - pos[i], axis=1) <= every.eps

    in_contact = touching(world.positions)
    onsets, missed, ref_misses = 0, [], 0
    for m in range(steps):
        pending = []
        for k in range(1, S + 1):
            if k == S:
                world.step()
                out = pred.step(world.positions, measured(world.velocities))
                history.append(_key_set(out, n))
                held_max = max(held_max, pred.npairs)
                if reference:
                    tau = every.tau(ids, world.positions, world.velocities)
                    urgent = np.flatnonzero(tau < (1 + lat) * pred.dt - 1e-9)
                    ref_misses += len(
                        _key_set(np.stack([i[urgent], j[urgent]], 1), n) - history[-1]
                    )
                now = touching(world.positions)
            else:
                now = touching(world.positions_at(world.dt * k / S))
            pending.append((m * S + k, now & ~in_contact))
            in_contact = now
        for u, new in pending:
            q = max(0, u // S - lat)
            for p in np.flatnonzero(new):
                onsets += 1
                if int(i[p]) * n + int(j[p]) not in history[q]:
                    missed.append((int(i[p]), int(j[p]), u / S * world.dt))
    return Outcome(onsets, missed, ref_misses, held_max, pred.rebuilds, pred.renewals)


def dense_world(seed: int, n: int = 40) -> SphereWorld:
    return SphereWorld(
        n,
        seed=seed,
        box=1.0,
        radius=0.05,
        accel=2.0,
        speed=0.5,
        dt=0.01,
        profile=AccelProfile.BANG_BANG,
    )


@pytest.mark.parametrize("latency", [0, 1])
@pytest.mark.parametrize("mode", ["pruned", "all"])
def test_every_onset_is_flagged(latency: int, mode: str) -> None:
    for seed in (0, 1):
        world = dense_world(seed)
        # A short horizon: rebuilds every 4 (latency 1) or 5 steps, pairs come and go.
        horizon = 0.05 if mode == "pruned" else None
        pred = SpherePredictor(
            world.radius, 2.0, dt=0.01, latency=latency, pairs=mode, horizon=horizon
        )
        out = run_predictor(world, pred, steps=150, reference=(seed == 0))
        assert out.onsets >= 5, "the world must be dense enough for collisions to happen"
        assert out.missed == []
        assert out.reference_misses == 0
        if mode == "pruned":
            assert out.rebuilds >= 150 // (5 - latency) - 1
            assert out.held_max < 40 * 39 // 2 / 3, "pruning must leave most pairs out"


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**16),
    n=st.integers(2, 50),
    latency=st.integers(0, 2),
    stride=st.integers(1, 8),
    noise=st.sampled_from([0.0, 0.05, 0.3]),
    margin=st.sampled_from([0.0, 0.02]),
    cap=st.sampled_from([None, 2]),
    bang_bang=st.booleans(),
)
def test_sampled_feasible_trajectories_miss_nothing(
    seed: int,
    n: int,
    latency: int,
    stride: int,
    noise: float,
    margin: float,
    cap: int | None,
    bang_bang: bool,
) -> None:
    """Ghost worlds whose bounds hold, velocities measured within ``vel_uncertainty`` of the
    true ones (in doubt, the escape test renews such spheres): no onset missed, pruned or all
    pairs, and every pair select-all's rule alarms stands in alarm."""
    world = SphereWorld(
        n,
        seed=seed,
        box=0.6 + 0.02 * n,
        radius=0.05,
        accel=2.0,
        speed=0.5,
        dt=0.01,
        profile=AccelProfile.BANG_BANG if bang_bang else AccelProfile.UNIFORM,
    )
    for mode in ("pruned", "all"):
        pred = SpherePredictor(
            world.radius,
            2.0,
            dt=0.01,
            latency=latency,
            margin=margin,
            pairs=mode,
            vel_uncertainty=noise,
            max_evals_per_step=cap,
            horizon=(stride + latency) * 0.01 if mode == "pruned" else None,
        )
        out = run_predictor(
            copy.deepcopy(world), pred, steps=40, reference=cap is None, noise=noise
        )
        assert out.missed == []
        assert out.reference_misses == 0


def test_pairs_met_long_ago_are_forgotten_and_nothing_is_missed() -> None:
    """Spheres that wander meet ever new pairs; the runtime forgets those no rebuild has held
    for a while (as the plugin does: docs/theory.md, Lemma 7.1), so the pairs it knows stay
    bounded, and no onset is missed meanwhile."""
    world = SphereWorld(
        150, seed=3, box=2.0, radius=0.05, accel=2.0, speed=0.8, dt=0.01,
        profile=AccelProfile.BANG_BANG,
    )  # fmt: skip
    pred = SpherePredictor(world.radius, 2.0, dt=0.01, latency=1, pairs="pruned", horizon=0.05)
    known: list[int] = []
    step = pred.step

    def counted(c: np.ndarray, v: np.ndarray) -> np.ndarray:
        out = step(c, v)
        known.append(int(pred._rt.npair))
        return out

    pred.step = counted  # type: ignore[method-assign]
    out = run_predictor(world, pred, steps=500, substeps=2, reference=True)
    assert out.onsets > 100
    assert out.missed == [] and out.reference_misses == 0
    assert (np.diff(known) < 0).sum() >= 3, "no compaction"
    assert max(known) < 4 * out.held_max


def test_capped_pruned_predictor_is_complete() -> None:
    """Over the cap, new pairs of a rebuild wait standing in alarm like any deferred pair."""
    world = dense_world(2)
    pred = SpherePredictor(
        world.radius, 2.0, dt=0.01, latency=1, pairs="pruned", horizon=0.05, max_evals_per_step=3
    )
    out = run_predictor(world, pred, steps=150)
    assert out.onsets >= 5
    assert out.missed == []
    assert pred.evaluations <= 3


def _head_on(latency: int, shorten: bool) -> Outcome:
    """Two spheres driven head-on just inside the acceleration bound, placed just outside the
    reach of the horizon shortened by one step: only that shortening could leave the pair out
    too long (and did, before the tables' check refused it)."""
    dt, T, r, A, v = 0.01, 0.1, 0.05, 1.0, 0.5
    Ts = T - dt
    gap = 2 * (r + v * Ts + 0.5 * A * Ts * Ts) + 1e-6
    # 1e-4 inside the bound: a motion at the bound itself is, to rounding, on the escape test's
    # edge, which renews it (in doubt) and so would hide the shortening.
    a = A * (1 - 1e-4)

    class HeadOn(SphereWorld):
        def step(self) -> None:
            super().step()
            self.accelerations[:] = [[a, 0, 0], [-a, 0, 0], [0, 0, 0], [0, 0, 0]]

    world = HeadOn(4, radius=r, accel=A, dt=dt, box=4.0)
    world.positions = np.array([[-gap / 2, 0, 0], [gap / 2, 0, 0], [1.5, 1.5, 1.5], [-1, 1, 1]])
    world.velocities = np.array([[v, 0, 0], [-v, 0, 0], [0, 0, 0], [0, 0, 0]], dtype=float)
    world.accelerations = np.array([[a, 0, 0], [-a, 0, 0], [0, 0, 0], [0, 0, 0]], dtype=float)
    pred = SpherePredictor(world.radius, A, dt=dt, latency=latency, pairs="pruned", horizon=T)
    if shorten:
        pred._rt = pred._runtime(Ts)  # the reach's horizon alone, the stride kept
    with warnings.catch_warnings():
        # Motion within the bounds must not count as breaking them.
        warnings.simplefilter("error", BoundViolationWarning)
        out = run_predictor(world, pred, steps=14, substeps=16, reference=True)
    # Nor as escaping the reach: the only rebuilds are the stride's, and nothing is renewed.
    assert out.rebuilds == 14 // pred.stride
    assert out.renewals == 0
    return out


@pytest.mark.parametrize("latency", [0, 1])
def test_a_horizon_shortened_by_one_step_is_refused(latency: int) -> None:
    """The head-on pair at the horizon's reach: with the stride's horizon, flagged; with the
    reach over one step less and the stride kept, the tables are refused, naming the stride and
    the largest the horizon covers. (Accepted, the pair was left out until a step after it
    touched: the run missed its onset, and the slow reference found tau urgent meanwhile.)"""
    good = _head_on(latency, shorten=False)
    assert good.onsets == 1
    assert good.missed == []
    assert good.reference_misses == 0
    most = 9 - latency
    with pytest.raises(InvalidInputError, match=rf"stride of {most + 1} steps past the reach's "
                       rf"horizon \(0\.09 s\).*lower the stride to {most} or less"):  # fmt: skip
        _head_on(latency, shorten=True)


def test_rebuild_stride_is_the_largest_covered() -> None:
    for dt in (0.01, 0.002, 0.1, 1 / 3):
        for latency in (0, 1, 3):
            for steps in range(1 + latency, 40):
                T = steps * dt
                R = rebuild_stride(T, dt, latency)
                assert (R + latency) * dt <= T
                assert (R + 1 + latency) * dt > T
                # Period 3: the reach covers dt - h more (docs/many-objects.md), one stride less.
                grid = dt - dt / 3
                if (1 + latency) * dt + grid <= T:
                    Rg = rebuild_stride(T, dt, latency, grid=grid)
                    assert (Rg + latency) * dt + grid <= T < (Rg + 1 + latency) * dt + grid
                    assert Rg == R - 1
    with pytest.raises(InvalidInputError, match="horizon"):
        rebuild_stride(0.015, 0.01, 1)


@pytest.mark.parametrize(
    "options",
    [
        {"pairs": "pruned", "horizon": 0.06},
        {"pairs": "pruned", "horizon": 0.06, "max_evals_per_step": 2},
        {"pairs": "all", "alarm_backoff": 4},
        {"pairs": "all", "schedule": "dua"},
    ],
)
def test_carry_keeps_state_and_output_matches_alarm_state(options: dict) -> None:
    """The runtime's standing list (its output) is the schedule's alarm rule over the held pairs
    after every step, and a rebuild carries every kept pair's verdict: tau, last step, due step."""
    world = dense_world(3)
    pred = SpherePredictor(world.radius, 2.0, dt=0.01, latency=1, **options)
    pred.reset(world.positions, world.velocities)
    kept_checked = 0
    for step in range(1, 40):
        sched = pred.scheduler
        assert sched is not None
        old = {(int(a), int(b)): q for q, (a, b) in enumerate(pred.keys)}
        before = (sched.tau(np.arange(pred.npairs)), sched.last_step.copy())
        due = (
            sched.next_due(np.arange(pred.npairs)) if isinstance(sched, DeadlineScheduler) else None
        )
        world.step()
        out = pred.step(world.positions, world.velocities)
        sched = pred.scheduler
        assert sched is not None
        want = pred.keys[np.flatnonzero(sched.alarm_state())]
        np.testing.assert_array_equal(out, want[np.lexsort((want[:, 1], want[:, 0]))])
        if options["pairs"] == "pruned" and step % 5 == 0:
            assert pred.rebuilds == step // 5
            assert isinstance(sched, DeadlineScheduler) and due is not None
            src = np.array([old.get((int(a), int(b)), -1) for a, b in pred.keys])
            kept = np.flatnonzero(src >= 0)
            # Not due at the rebuild step itself (those were evaluated again there).
            later = kept[due[src[kept]] > step]
            np.testing.assert_array_equal(sched.next_due(later), due[src[later]])
            np.testing.assert_array_equal(sched.tau(later), before[0][src[later]])
            np.testing.assert_array_equal(sched.last_step[later], before[1][src[later]])
            # New pairs were due at once: evaluated there, or deferred standing in alarm.
            new = np.flatnonzero(src < 0)
            assert ((sched.last_step[new] == step) | sched.alarm_state(new)).all()
            kept_checked += later.size
    assert options["pairs"] == "all" or kept_checked > 20


def test_escaped_sphere_is_renewed_and_warns() -> None:
    """A teleported sphere is anchored anew at once (its new neighbours held, due now), the
    others keep theirs; the state proves a violation, so it warns."""
    world = dense_world(4)
    pred = SpherePredictor(world.radius, 2.0, dt=0.01, pairs="pruned", horizon=0.2)
    pred.reset(world.positions, world.velocities)
    world.step()
    pred.step(world.positions, world.velocities)
    assert (pred.rebuilds, pred.renewals) == (0, 0)
    c = world.positions.copy()
    far = np.linalg.norm(c - c[7], axis=1).argmax()
    c[7] = c[far] + 0.01  # a teleport onto another sphere, far beyond its acceleration bound
    with pytest.warns(BoundViolationWarning, match="sphere 7"):
        out = pred.step(c, world.velocities)
    assert (pred.rebuilds, pred.renewals) == (0, 1)
    pair = (min(7, far), max(7, far))
    assert pair in set(map(tuple, pred.keys.tolist()))
    assert pair in set(map(tuple, out.tolist()))


def test_validation() -> None:
    r = np.full(5, 0.1)
    c = np.zeros((5, 3))
    with pytest.raises(InvalidBoundError, match=r"accel\[2\]"):
        SpherePredictor(r, [1, 1, -1, 1, 1], dt=0.01)
    with pytest.raises(ShapeError):
        SpherePredictor(r, np.ones(4), dt=0.01)
    with pytest.raises(ShapeError, match="radii"):
        SpherePredictor(np.ones((2, 2)), 1.0, dt=0.01)
    with pytest.raises(InvalidInputError, match="dt"):
        SpherePredictor(r, 1.0, dt=0.0)
    with pytest.raises(InvalidChoiceError, match="pruned"):
        SpherePredictor(r, 1.0, dt=0.01, pairs="some")
    with pytest.raises(InvalidChoiceError, match="deadline"):
        SpherePredictor(r, 1.0, dt=0.01, schedule="fast")
    with pytest.raises(InvalidInputError, match="schedule='deadline'"):
        SpherePredictor(r, 1.0, dt=0.01, pairs="pruned", schedule="dua")
    with pytest.raises(InvalidInputError, match="horizon"):
        SpherePredictor(r, 1.0, dt=0.01, pairs="pruned", horizon=0.01)
    with pytest.raises(InvalidInputError, match="horizon"):
        SpherePredictor(r, 1.0, dt=0.01, pairs="all", horizon=0.5)
    with pytest.raises(InvalidInputError, match="speed"):
        SpherePredictor(r, 1.0, dt=0.01, speed=0.0)
    with pytest.raises(InvalidInputError, match="max_evals_per_step"):
        SpherePredictor(r, 1.0, dt=0.01, max_evals_per_step=0)
    for mode in ("all", "pruned"):
        pred = SpherePredictor(r, 1.0, dt=0.01, pairs=mode)
        with pytest.raises(SchedulerError, match="reset"):
            pred.step(c, c)
        bad = c.copy()
        bad[3, 1] = np.nan
        with pytest.raises(NonFiniteStateError, match=r"centers\[3\]"):
            pred.reset(bad, c)
        pred.reset(np.arange(15.0).reshape(5, 3), c)
        with pytest.raises(NonFiniteStateError, match="velocities"):
            pred.step(c, bad)
        with pytest.raises(ShapeError, match="5 spheres"):
            pred.step(np.zeros((6, 3)), np.zeros((6, 3)))
        with pytest.raises(ShapeError, match="velocities"):
            pred.step(c, np.zeros((5, 2)))


def test_auto_chooses_by_size_and_schedule() -> None:
    small = SpherePredictor(np.full(AUTO_PRUNED_MIN - 1, 0.1), 1.0, dt=0.01)
    large = SpherePredictor(np.full(AUTO_PRUNED_MIN, 0.1), 1.0, dt=0.01)
    dua = SpherePredictor(np.full(AUTO_PRUNED_MIN, 0.1), 1.0, dt=0.01, schedule="dua")
    assert small.mode is PairMode.ALL and small.stride is None
    assert large.mode is PairMode.PRUNED and large.stride == 32
    assert dua.mode is PairMode.ALL


def test_other_schedules_over_all_pairs_are_complete() -> None:
    for schedule in ("dua", "select-all"):
        world = dense_world(5)
        pred = SpherePredictor(world.radius, 2.0, dt=0.01, pairs="all", schedule=schedule)
        out = run_predictor(world, pred, steps=100)
        assert out.onsets >= 3
        assert out.missed == []


# ---------------------------------------------------------------------------------------------
# The escape test (docs/theory.md, "The escape test, once")


def _old_escape_passes(d: float, w: float, s0: float, delta: float, A: float, V: float, t: float):
    """The unsound test SpherePredictor ran before (``core/pruned.py:escaped``): a measured
    speed up to ``s0 + 2 delta + A t`` let through, its rounding allowance added."""
    allow = min((s0 + delta) * t + 0.5 * A * t * t, V * t)
    top = min(s0 + 2 * delta + A * t, V + delta)
    tol = 1e-9 * (allow + top) + 2e-12
    return d <= allow + tol and w <= top + tol


def _leaves_reach(d: float, w: float, s0: float, delta: float, A: float, V: float, t: float,
                  T: float) -> bool:  # fmt: skip
    """Whether the farthest motion within the bounds from time ``t`` on (true speed ``w +
    delta``, capped at ``V``, straight out, speeding up at ``A`` to ``V``) leaves the reach
    ``min((s0 + delta) u + A u^2 / 2, V u)`` of the anchor at some ``u`` in ``[t, T]``."""
    u = np.linspace(t, T, 2001)
    u0 = min(w + delta, V)
    s = u - t
    travelled = u0 * s + 0.5 * A * s * s
    if np.isfinite(V):
        k = (V - u0) / A  # when it reaches V
        travelled = np.where(s <= k, travelled, u0 * k + 0.5 * A * k * k + V * (s - k))
    reach = np.minimum((s0 + delta) * u + 0.5 * A * u * u, V * u)
    return bool((d + travelled > reach * (1 + 1e-12) + 1e-15).any())


def test_escape_after_a_hidden_violation_renews_before_the_collision() -> None:
    """Two spheres at rest at the rebuild, their pair left out; one step later, still where
    they were, they move towards each other at 3 m/s, measured as 2 m/s (delta = 1). Nothing
    tells whether a violation happened, but from there on the motion keeps its bounds and
    leaves the reach (1 m/s) before the horizon, colliding before the next rebuild. The sound
    test renews both at once and the pair alarms; the old test let the state through."""
    dt, delta, A, r = 0.01, 1.0, 1e-3, 0.05
    pred = SpherePredictor(
        np.full(2, r), A, dt=dt, latency=0, pairs="pruned", horizon=2 * dt, vel_uncertainty=delta
    )
    assert pred.stride == 2
    c = np.array([[-0.075, 0.0, 0.0], [0.075, 0.0, 0.0]])
    assert pred.reset(c, np.zeros((2, 3))).shape == (0, 2)
    assert pred.npairs == 0  # left out: 0.15 > 2 r + 2 (delta T + A T^2 / 2)
    measured = np.array([[2.0, 0.0, 0.0], [-2.0, 0.0, 0.0]])
    with warnings.catch_warnings():
        # The state proves nothing broken (a true speed of 1 m/s is within delta): no warning.
        warnings.simplefilter("error", BoundViolationWarning)
        out = pred.step(c, measured)
    assert (pred.rebuilds, pred.renewals) == (0, 1)
    np.testing.assert_array_equal(out, [[0, 1]])
    # Why it matters: the old test passed this state, and the true motion (3 m/s each, within
    # its bounds from now on) touches at 1/120 s after this step, before the next one, having
    # left its reach (1 m/s from the anchor) before the horizon.
    assert _old_escape_passes(0.0, 2.0, 0.0, delta, A, np.inf, dt)
    touch = dt + (0.15 - 2 * r) / 6.0
    assert touch < 2 * dt
    assert 3.0 * (touch - dt) > delta * touch + 0.5 * A * touch**2


def test_escape_test_keeps_passing_spheres_inside_their_reach() -> None:
    """States sampled on both sides of the test's edges: every one the native test passes stays
    within its reach until the horizon under the farthest motion its bounds allow from then on;
    the old test passes some that leave (so the check has teeth)."""
    rng = np.random.default_rng(7)
    passed = old_leaks = 0
    for _ in range(400):
        s0, A = rng.uniform(0, 2), rng.uniform(0.1, 10)
        delta = rng.choice([0.0, rng.uniform(0, 0.5)])
        V = np.inf if rng.random() < 0.5 else s0 + delta + rng.uniform(0.1, 2)
        T = rng.uniform(0.02, 0.5)
        t = rng.uniform(0.001, 0.9) * T
        allow = min((s0 + delta) * t + 0.5 * A * t * t, V * t)
        edge_w = rng.choice([min(s0 + A * t, V - delta), min(s0 + 2 * delta + A * t, V + delta)])
        w = max(0.0, edge_w * (1 + rng.choice([-1e-6, -1e-10, 0.0, 1e-10])))
        d = allow * rng.uniform(0.0, 1.0 + 1e-9)
        esc = _core.escapes(
            np.zeros((1, 3)), np.array([s0]), np.array([A]), np.array([delta]), np.array([V]),
            np.zeros(1, dtype=np.int64), np.array([[d, 0.0, 0.0]]), np.array([[w, 0.0, 0.0]]),
            np.array([t]),
        )  # fmt: skip
        leaves = _leaves_reach(d, w, s0, delta, A, V, t, T)
        if esc.size == 0:
            passed += 1
            assert not leaves, (s0, delta, A, V, t, T, d, w)
        elif _old_escape_passes(d, w, s0, delta, A, V, t) and leaves:
            old_leaks += 1
    assert passed > 50, passed
    assert old_leaks > 10, old_leaks
