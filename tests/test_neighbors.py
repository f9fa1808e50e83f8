"""The candidate grid and the reach (csrc/src/grid.cc, reach.cc), which choose a pruned
predictor's pairs: the pair set is exact, safe over the horizon, and O(N + K)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from reference_grid import brute_pairs, candidate_pairs, reach

from dua_mujoco import _core
from dua_mujoco.experiments.peers.memory import reset_peak, rss

# ---------------------------------------------------------------------------------------------
# References


def assert_same(c: np.ndarray, r: np.ndarray, margin: float) -> np.ndarray:
    got = candidate_pairs(c, r, margin=margin)
    want = brute_pairs(c, r, margin)
    assert got.dtype == np.int64
    assert got.shape == want.shape, (got.shape, want.shape)
    np.testing.assert_array_equal(got, want)
    return got


@st.composite
def scenes(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, float]:
    n = draw(st.integers(0, 200))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    layout = draw(st.sampled_from(["spread", "clustered", "lattice", "flat", "outlier"]))
    scale = 10.0 ** draw(st.integers(-2, 3))
    offset = draw(st.sampled_from([0.0, 1e6, -3.5e5]))
    if layout == "spread":
        c = rng.uniform(-scale, scale, (n, 3))
    elif layout == "clustered":
        k = draw(st.integers(1, 4))
        hubs = rng.uniform(-scale, scale, (k, 3))
        c = hubs[rng.integers(0, k, n)] + rng.normal(0.0, 0.01 * scale, (n, 3))
    elif layout == "lattice":
        # Exact ties: distances equal to sums of reaches, identical centres.
        c = np.round(rng.uniform(-4, 4, (n, 3))) * 0.25 * scale
    elif layout == "flat":
        c = rng.uniform(-scale, scale, (n, 3))
        c[:, draw(st.integers(0, 2))] = 0.0
    else:
        c = rng.uniform(-1, 1, (n, 3)) * 0.1 * scale
        if n:
            c[rng.integers(0, n)] = 1e5 * scale
    c = c + offset
    r = rng.uniform(0.0, 0.2 * scale, n) * (rng.random(n) < 0.8)
    if layout == "lattice":
        r = np.round(r / (0.125 * scale)) * 0.125 * scale
    if n and draw(st.booleans()):
        # A few spheres of much larger reach (held out of the grid by the cost model).
        big = rng.integers(0, n, draw(st.integers(1, 3)))
        r[big] *= draw(st.sampled_from([10.0, 100.0, 1e4]))
    margin = draw(st.sampled_from([0.0, 0.01 * scale, 0.5 * scale]))
    return c, r, margin


# ---------------------------------------------------------------------------------------------
# candidate_pairs equals the brute force exactly


@settings(max_examples=300, deadline=None)
@given(scenes())
def test_candidate_pairs_equals_brute_force(scene: tuple[np.ndarray, np.ndarray, float]) -> None:
    c, r, margin = scene
    got = assert_same(c, r, margin)
    if got.shape[0]:
        assert (got[:, 0] < got[:, 1]).all()
        keys = got[:, 0] * c.shape[0] + got[:, 1]
        assert (np.diff(keys) > 0).all()


def test_small_and_degenerate_inputs() -> None:
    assert candidate_pairs(np.empty((0, 3)), np.empty(0)).shape == (0, 2)
    assert candidate_pairs(np.zeros((1, 3)), np.ones(1)).shape == (0, 2)
    # Identical centres with zero reach touch (distance 0 <= 0); zero margin, zero reach, N = 3.
    got = candidate_pairs(np.zeros((3, 3)), np.zeros(3))
    np.testing.assert_array_equal(got, [[0, 1], [0, 2], [1, 2]])
    # Distinct centres with zero reach and margin: nothing (the cell edge would be 0).
    assert candidate_pairs(np.eye(3), np.zeros(3)).shape == (0, 2)


def test_huge_coordinates() -> None:
    rng = np.random.default_rng(1)
    c = 1e6 + rng.uniform(0.0, 5.0, (400, 3))
    r = np.full(400, 0.2)
    got = assert_same(c, r, 0.0)
    assert 0 < got.shape[0] < 400 * 399 // 2


def test_all_in_one_cell_returns_all_pairs() -> None:
    rng = np.random.default_rng(2)
    c = rng.uniform(0.0, 0.1, (300, 3))
    got = assert_same(c, np.full(300, 1.0), 0.0)
    assert got.shape[0] == 300 * 299 // 2


def test_exact_boundary_ties_are_in() -> None:
    # Distances exactly equal to reach_i + reach_j + margin, in dyadic (exact) arithmetic.
    c = np.array([[0.0, 0, 0], [1.5, 0, 0], [1.5, 2.0, 0], [0, 0, 3.25]])
    r = np.array([0.5, 0.75, 1.0, 0.5])
    got = candidate_pairs(c, r, margin=0.25)
    # (0,1): 1.5 = 0.5+0.75+0.25; (1,2): 2.0 = 0.75+1.0+0.25; (0,3): 3.25 > 1.25.
    np.testing.assert_array_equal(got, [[0, 1], [1, 2]])


class _Plan:
    """The native grid's plan (``_core.grid_plan``) with its fields as attributes."""

    def __init__(self, fields: dict) -> None:
        self.__dict__.update(fields)


def _plan(c: np.ndarray, r: np.ndarray, margin: float = 0.0):  # type: ignore[no-untyped-def]
    plan = _Plan(_core.grid_plan(r, margin, c.min(axis=0), c.max(axis=0)))
    return plan, plan.held


def test_both_bucket_maps_and_held_out_spheres_are_exercised() -> None:
    rng = np.random.default_rng(3)
    n = 3000
    # Spread with tiny reach: the grid is far larger than the bucket budget, so it wraps.
    c = rng.uniform(0.0, 1000.0, (n, 3))
    r = rng.uniform(0.0, 2.0, n)
    plan, held = _plan(c, r)
    assert any(plan.wrap) and held.size == 0
    # The torus is >= 4 cells wide on every wrapped axis (what lets the scan skip cell checks).
    assert all(mask >= 3 for mask, wraps in zip(plan.mask, plan.wrap, strict=True) if wraps)
    assert plan.nbucket >= 2 * n
    assert_same(c, r, 0.0)
    # Dense: the grid fits, bucket = cell.
    c = rng.uniform(0.0, 10.0, (n, 3))
    r = rng.uniform(0.0, 0.2, n)
    plan, _ = _plan(c, r)
    assert not any(plan.wrap)
    assert plan.h >= 2 * r.max() * (1 + 2**-16)
    assert_same(c, r, 0.0)
    # Two spheres of very large reach: held out, not blowing up the cell.
    r[[5, 17]] = 4.0
    plan, held = _plan(c, r)
    np.testing.assert_array_equal(held, [5, 17])
    assert plan.rcut <= 0.2 and plan.nheld == 2
    got = assert_same(c, r, 0.0)
    assert ((got == 5).any(axis=1)).sum() > 100


@pytest.mark.parametrize("seed", range(5))
def test_rows_across_the_torus_seam(seed: int) -> None:
    # A chain of touching spheres over ~20 cells (h = 3) of a line whose two far outliers make the
    # x axis wrap onto a 128-cell torus: the chain crosses the seam (cells 127 | 128 = 0).
    rng = np.random.default_rng(seed)
    n = 60
    x = 360.3 + np.arange(n) + rng.uniform(-0.05, 0.05, n)
    c = np.zeros((n + 2, 3))
    c[:n, 0] = x
    c[:n, 1:] = rng.uniform(-0.3, 0.3, (n, 2))
    c[n:, 0] = [0.0, 1e4]
    r = np.full(n + 2, 0.75)
    plan, _ = _plan(c, r)
    assert plan.wrap[0] == 1
    cells = np.floor((c[:n, 0] - plan.lo[0]) / plan.h).astype(np.int64)
    assert ((cells & plan.mask[0]) == plan.mask[0]).any(), "no sphere at the seam"
    got = assert_same(c, r, 0.0)
    assert got.shape[0] >= n - 1


# ---------------------------------------------------------------------------------------------
# reach


def test_reach_formula() -> None:
    radius = np.array([0.1, 0.2, 0.3, 0.0])
    speed = np.array([1.0, 0.0, 2.0, 4.0])
    A = np.array([2.0, 4.0, 0.0, 1.0])
    V = np.array([np.inf, 0.5, 1.0, 3.0])
    got = reach(radius, speed, A, 0.5, vel_uncertainty=0.25, speed_bound=V)
    free = (speed + 0.25) * 0.5 + 0.5 * A * 0.25
    want = radius + np.minimum(free, V * 0.5)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)
    assert got[1] == pytest.approx(0.2 + 0.25)  # the speed bound binds
    assert got[0] == pytest.approx(0.1 + 1.25 * 0.5 + 0.25)
    np.testing.assert_allclose(reach(0.1, 1.0, 2.0, 0.5), [0.1 + 0.5 + 0.25])
    # T = 0 with no speed bound: no inf * 0 = NaN.
    np.testing.assert_array_equal(reach(radius, speed, A, 0.0), radius)


# ---------------------------------------------------------------------------------------------
# Safety: a pair left out cannot meet over [0, T]


def trajectories(
    c: np.ndarray,
    v: np.ndarray,
    A: np.ndarray,
    delta: np.ndarray,
    V: np.ndarray,
    T: float,
    times: np.ndarray,
    rng: np.random.Generator,
    segments: int = 8,
) -> np.ndarray:
    """``(len(times), N, 3)`` positions of motions within the bounds, integrated in closed form.

    The true initial velocity is ``v + e`` with ``|e| = delta``; accelerations are piecewise
    constant with norm ``A``. A segment whose end speed would exceed the speed bound coasts
    instead (speed is convex in time under a constant acceleration, so checking the ends keeps
    ``|u| <= V`` throughout). Half of the spheres point ``e`` and every acceleration at a target
    sphere (the extreme motion for that pair), the others pick random directions.
    """
    n = c.shape[0]
    target = c[rng.integers(0, n, n)] - c
    norm = np.linalg.norm(target, axis=1, keepdims=True)
    aim = np.where(norm > 0, target / np.where(norm > 0, norm, 1.0), 0.0)
    aimed = np.asarray(rng.random(n) < 0.5)

    def direction() -> np.ndarray:
        d = rng.normal(size=(n, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return np.where(aimed[:, None], aim, d)

    cuts = np.linspace(0.0, T, segments + 1)
    x = c.copy()
    u = v + delta[:, None] * direction()
    assert (np.linalg.norm(u, axis=1) <= V * (1 + 1e-12)).all(), "the state breaks its bound"
    out = np.empty((times.size, n, 3))
    for k in range(segments):
        t0, t1 = cuts[k], cuts[k + 1]
        a = A[:, None] * direction()
        fast = np.linalg.norm(u + a * (t1 - t0), axis=1) > V
        a[fast] = 0.0
        for ti in np.flatnonzero((times >= t0) & (times <= t1)):
            s = times[ti] - t0
            out[ti] = x + u * s + 0.5 * a * s * s
        s = t1 - t0
        x = x + u * s + 0.5 * a * s * s
        u = u + a * s
    return out


def violations(
    pairs: np.ndarray, positions: np.ndarray, radius: np.ndarray, margin: float
) -> np.ndarray:
    """Pairs left out of ``pairs`` whose spheres touch at some sampled time."""
    n = radius.size
    i, j = np.triu_indices(n, 1)
    kept = np.zeros((n, n), dtype=bool)
    kept[pairs[:, 0], pairs[:, 1]] = True
    out = ~kept[i, j]
    i, j = i[out], j[out]
    d = np.linalg.norm(positions[:, i] - positions[:, j], axis=2)
    touch = (d <= (radius[i] + radius[j] + margin)[None, :]).any(axis=0)
    return np.stack([i[touch], j[touch]], axis=1)


@settings(max_examples=150, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(2, 40),
    T=st.sampled_from([0.05, 0.2, 1.0]),
    margin=st.sampled_from([0.0, 0.02]),
    use_delta=st.booleans(),
    use_speed_bound=st.booleans(),
)
def test_left_out_pairs_cannot_meet(
    seed: int, n: int, T: float, margin: float, use_delta: bool, use_speed_bound: bool
) -> None:
    rng = np.random.default_rng(seed)
    c = rng.uniform(0.0, 2.0, (n, 3))
    radius = rng.uniform(0.0, 0.15, n)
    v = rng.normal(0.0, 0.5, (n, 3))
    A = rng.uniform(0.0, 3.0, n)
    delta = rng.uniform(0.0, 0.3, n) if use_delta else np.zeros(n)
    speed = np.linalg.norm(v, axis=1)
    # Bounds the true initial speed may meet, binding (V T < the free bound) for some spheres.
    V = speed + delta + rng.uniform(0.0, 1.0, n) * A * T
    if not use_speed_bound:
        V[:] = np.inf
    rch = reach(radius, speed, A, T, vel_uncertainty=delta, speed_bound=V)
    pairs = candidate_pairs(c, rch, margin=margin)
    times = np.linspace(0.0, T, 41)
    for _ in range(3):
        pos = trajectories(c, v, A, delta, V, T, times, rng)
        assert violations(pairs, pos, radius, margin).shape[0] == 0


def head_on() -> dict[str, np.ndarray | float]:
    # Two spheres of radius 0.5 on the x axis 2.5 apart, closing at 1 m/s each and braking
    # towards each other at A = 2: over T = 0.5 each covers 0.5 + 0.25 = 0.75, so at t = T the
    # centres are 1.0 = r_i + r_j apart: contact exactly at the horizon (dyadic, so exact).
    return {
        "c": np.array([[0.0, 0.0, 0.0], [2.5, 0.0, 0.0]]),
        "v": np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]),
        "radius": np.array([0.5, 0.5]),
        "A": np.array([2.0, 2.0]),
        "T": 0.5,
    }


def head_on_positions(s: dict[str, np.ndarray | float], times: np.ndarray) -> np.ndarray:
    c = np.asarray(s["c"])
    v = np.asarray(s["v"])
    a = np.array([[2.0, 0.0, 0.0], [-2.0, 0.0, 0.0]])
    t = times[:, None, None]
    return np.asarray(c[None] + v[None] * t + 0.5 * a[None] * t * t)


def test_head_on_at_the_horizon_is_kept() -> None:
    s = head_on()
    T = float(s["T"])
    radius = np.asarray(s["radius"])
    rch = reach(radius, np.linalg.norm(np.asarray(s["v"]), axis=1), np.asarray(s["A"]), T)
    pairs = candidate_pairs(np.asarray(s["c"]), rch)
    np.testing.assert_array_equal(pairs, [[0, 1]])
    pos = head_on_positions(s, np.linspace(0.0, T, 65))
    assert violations(pairs, pos, radius, 0.0).shape[0] == 0


def test_reach_one_step_short_is_caught() -> None:
    """The safety check is not vacuous: a reach over T - dt leaves out a pair that touches."""
    s = head_on()
    T = float(s["T"])
    dt = T / 64
    radius = np.asarray(s["radius"])
    rch = reach(radius, np.linalg.norm(np.asarray(s["v"]), axis=1), np.asarray(s["A"]), T - dt)
    pairs = candidate_pairs(np.asarray(s["c"]), rch)
    assert pairs.shape == (0, 2)
    pos = head_on_positions(s, np.linspace(0.0, T, 65))
    np.testing.assert_array_equal(violations(pairs, pos, radius, 0.0), [[0, 1]])


# ---------------------------------------------------------------------------------------------
# Size: output allocated at its exact size, no O(N^2) anything


def test_large_sparse_input_is_linear() -> None:
    rng = np.random.default_rng(4)
    side = 59  # 59^3 = 205,379 lattice sites, 1 m apart
    g = np.arange(side, dtype=np.float64)
    lattice = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
    n = 200_000
    c = lattice[:n] + rng.uniform(-0.1, 0.1, (n, 3))
    # 40 planted partners 0.05 m from their lattice sphere; everyone else is >= 0.8 m away.
    hosts = np.sort(rng.choice(n - 40, 40, replace=False))
    c[n - 40 :] = c[hosts] + np.array([0.03, 0.0, 0.04])
    r = np.full(n, 0.03)
    candidate_pairs(c[:10], r[:10])  # loaded outside the measurement
    # The growth of the peak resident size over the call (above the earlier peak where Linux
    # refuses the reset: weaker, but still far below an O(N^2) footprint).
    before, _ = reset_peak()
    got = candidate_pairs(c, r)
    peak = max(0, rss("VmHWM") - before)
    want = np.stack([hosts, np.arange(n - 40, n)], axis=1)
    np.testing.assert_array_equal(got, want[np.argsort(want[:, 0])])
    # The work arrays are native allocations, seen in the resident size: ~70 bytes per sphere
    # today, the validation's temporaries ~30 more; O(N^2) anything would be ~1e11 bytes.
    assert peak < 150 * n, peak / n
