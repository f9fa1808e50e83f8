"""The urgency tau (docs/theory.md, section 1) against the exact reference in reference_tau.py.

Two kinds of evidence, on purpose independent of each other:

* Reference comparisons: the exact first root (Sturm sequences over the rationals) decides with
  no tolerance whether the fast tau is ever above the true first root; tightness is checked to
  1e-9 relative where the root is well conditioned.
* Physical property tests: feasible trajectories (bounded piecewise-constant accelerations,
  bounded initial-velocity error, bounded speed) integrated exactly in high precision must not
  reach the contact ball before tau; and the worst-case trajectory does reach it at tau.

Failure messages print the inputs with ``repr`` so every failure is an exact reproducer.
"""

from __future__ import annotations

import math
import warnings

import mpmath
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from mpmath import mp, mpf

try:
    from dua_mujoco import distance_urgency, time_to_collision, time_to_halfspace
except ImportError:  # the package __init__ may not re-export yet
    from dua_mujoco.core.urgency import distance_urgency, time_to_collision, time_to_halfspace
import reference_tau as ref
from scalar_tau import tau_speed

from dua_mujoco import _core
from dua_mujoco.exceptions import (
    BoundViolationWarning,
    InvalidBoundError,
    InvalidInputError,
    NonFiniteStateError,
    ShapeError,
)

settings.register_profile(
    "urgency",
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
    print_blob=True,
)
URG = settings.get_profile("urgency")

RTOL_TIGHT = 1e-9
# At an exact double root the float64 inputs only define the root to ~sqrt(2^-52) relative; a
# conservative solver may stop anywhere in that fuzz. 1e-6 still catches a skipped double root.
RTOL_TANGENT = 1e-4


# --------------------------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------------------------


def tau_one(x, v, eps, accel, **kw) -> float:
    """Scalar tau of one pair through the vectorised API."""
    out = np.atleast_1d(
        time_to_collision(np.asarray(x, float)[None], np.asarray(v, float)[None], eps, accel, **kw)
    )
    assert out.shape == (1,)
    return float(out[0])


def case_repr(x, v, eps, accel, delta=0.0, speed=None) -> str:
    """An exact, copy-pasteable reproducer."""
    xs = [float(c) for c in x]
    vs = [float(c) for c in v]
    s = f"time_to_collision({xs!r}, {vs!r}, {float(eps)!r}, {float(accel)!r}"
    if delta:
        s += f", vel_uncertainty={float(delta)!r}"
    if speed is not None:
        s += f", speed={float(speed)!r}"
    return s + ")"


def root_condition(x, v, eps, accel, delta, r: mpf) -> mpf:
    """Estimated relative error of the root r caused by float64 rounding of the inputs.

    h(t) = |x + v t| - R(t); an absolute perturbation of size u * S in h moves the root by
    u * S / |h'(r)|. Below 1e-11 relative the 1e-9 tightness target is fair.
    """
    p = [mpf(x[k]) + mpf(v[k]) * r for k in range(3)]
    npn = mpmath.sqrt(sum(c * c for c in p))
    nv = mpmath.sqrt(sum(mpf(c) ** 2 for c in v))
    S = mpmath.sqrt(sum(mpf(c) ** 2 for c in x)) + nv * r + mpf(eps)
    S += mpf(delta) * r + mpf(accel) * r * r / 2
    if npn == 0:
        return mpf("inf")
    dh = sum(p[k] * mpf(v[k]) for k in range(3)) / npn - (mpf(delta) + mpf(accel) * r)
    if dh == 0 or r == 0:
        return mpf("inf")
    return mpf(2) ** -52 * S / (abs(dh) * r)


def check_against_ref(tau, x, v, eps, accel, delta=0.0, *, tight=True) -> list[str]:
    """Returns a list of problems (empty when tau is a valid and, if asked, tight answer)."""
    r = ref.tau_sphere_ref(x, v, eps, accel, delta)
    rep = case_repr(x, v, eps, accel, delta)
    problems = []
    if not r.is_lower_bound(tau):
        problems.append(f"LATE (missed collision): {rep} = {tau!r} > exact first root {r.value}")
        return problems
    if not tight:
        return problems
    if r.is_zero:
        if tau != 0:
            problems.append(f"{rep} = {tau!r}, expected 0 (already within eps)")
    elif r.is_inf:
        if math.isfinite(tau):
            # Allowed only for a near-miss: the tube must nearly touch at tau.
            h = _h(tau, x, v, eps, accel, delta)
            if h > mpf(10) ** -7 * _scale(tau, x, v, eps, accel, delta):
                problems.append(f"{rep} = {tau!r}, expected inf (h(tau) = {h})")
    else:
        cond = root_condition(x, v, eps, accel, delta, r.value)
        if cond < 1e-11 and r.rel_error(tau) > RTOL_TIGHT:
            problems.append(
                f"LOOSE: {rep} = {tau!r}, exact {r.value}, rel err {float(r.rel_error(tau)):.3g}"
            )
    return problems


def _h(t, x, v, eps, accel, delta):
    t = mpf(t)
    p = [mpf(x[k]) + mpf(v[k]) * t for k in range(3)]
    return mpmath.sqrt(sum(c * c for c in p)) - (mpf(eps) + mpf(delta) * t + mpf(accel) * t * t / 2)


def _scale(t, x, v, eps, accel, delta):
    t = mpf(t)
    nx = mpmath.sqrt(sum(mpf(c) ** 2 for c in x))
    nv = mpmath.sqrt(sum(mpf(c) ** 2 for c in v))
    return nx + nv * t + mpf(eps) + mpf(delta) * t + mpf(accel) * t * t / 2 + mpf(10) ** -300


def assert_all_ok(problems: list[str]) -> None:
    if problems:
        head = "\n".join(problems[:15])
        pytest.fail(f"{len(problems)} problem(s):\n{head}")


def random_cases(rng: np.random.Generator, n: int):
    """Mixed random inputs: log-uniform scales, zeros in A/delta/v, overlaps, separations."""
    scale = 10.0 ** rng.uniform(-4, 4, n)
    tscale = 10.0 ** rng.uniform(-2, 2, n)
    x = rng.normal(size=(n, 3)) * scale[:, None]
    v = rng.normal(size=(n, 3)) * (scale / tscale)[:, None]
    eps = rng.uniform(0, 1.5, n) * np.linalg.norm(x, axis=1)
    A = rng.uniform(0, 2, n) * scale / tscale**2
    delta = rng.uniform(0, 0.5, n) * scale / tscale
    kind = rng.integers(0, 8, n)
    A[kind == 0] = 0.0
    delta[kind <= 3] = 0.0
    v[kind == 1] = 0.0
    A[kind == 2] *= 1e-12
    A[kind == 3] *= 1e8
    # Separating pairs (x.v > 0) that only the acceleration term brings back.
    sep = kind == 4
    v[sep] = np.abs(v[sep]) * np.sign(x[sep])
    return x, v, eps, A, delta


# --------------------------------------------------------------------------------------------
# The reference checks itself (cheap, so a broken reference cannot silently pass everything)
# --------------------------------------------------------------------------------------------


def test_reference_known_values():
    # Exact dyadic tangency at t* = 2: |x+vt|^2 - (1 + t^2/8)^2 has a double root at 2.
    r = ref.tau_sphere_ref([0.5, -2.0, 0.0], [0.5, 1.0, 0.0], 1.0, 0.25)
    assert r.is_lower_bound(2.0) and not r.is_lower_bound(math.nextafter(2.0, 3.0))
    assert ref.first_root_polyroots(ref.sphere_poly([0.5, -2, 0], [0.5, 1, 0], 1, 0.25)) == 2
    # Grazing ray at t = 10.
    r = ref.tau_sphere_ref([-10.0, 1.0, 0.0], [1.0, 0.0, 0.0], 1.0, 0.0)
    assert r.is_lower_bound(10.0) and not r.is_lower_bound(math.nextafter(10.0, 11.0))
    assert ref.tau_sphere_ref([3.0, 0, 0], [0, 0, 0], 1.0, 0.0).is_inf
    assert abs(ref.tau_sphere_ref([3.0, 0, 0], [0, 0, 0], 1.0, 1.0).value - 2) < 1e-25
    assert abs(ref.tau_sphere_ref([3.0, 0, 0], [-1.0, 0, 0], 1.0, 0.0).value - 2) < 1e-25
    assert ref.tau_sphere_ref([0.5, 0, 0], [1.0, 0, 0], 1.0, 0.0).is_zero
    assert ref.tau_sphere_ref([1.0, 0, 0], [1.0, 0, 0], 1.0, 0.0).is_zero  # |x| == eps
    # Half-space: 1 - t^2/2 -> sqrt(2); 1 + 0 t -> inf; (A=0) 1 - t -> 1.
    assert abs(ref.tau_halfspace_ref(1.0, 0.0, 1.0).value - mpmath.sqrt(2)) < 1e-25
    assert ref.tau_halfspace_ref(1.0, 0.0, 0.0).is_inf
    assert ref.tau_halfspace_ref(1.0, -1.0, 0.0).is_lower_bound(1.0)
    assert not ref.tau_halfspace_ref(1.0, -1.0, 0.0).is_lower_bound(math.nextafter(1.0, 2))


def test_reference_agrees_with_polyroots_and_sampling():
    """Sturm reference == polyroots reference; h > 0 before the root, on a dense grid."""
    rng = np.random.default_rng(7)
    x, v, eps, A, delta = random_cases(rng, 120)
    for i in range(len(eps)):
        r = ref.tau_sphere_ref(x[i], v[i], eps[i], A[i], delta[i])
        p = ref.first_root_polyroots(ref.sphere_poly(x[i], v[i], eps[i], A[i], delta[i]))
        if r.is_inf:
            assert mpmath.isinf(p), (i, p)
            continue
        assert abs(r.value - p) <= mpf(10) ** -18 * (1 + r.value), (i, r.value, p)
        if r.value > 0:
            ts = np.linspace(0.0, float(r.value), 64)[:-1]
            assert all(_h(t, x[i], v[i], eps[i], A[i], delta[i]) > 0 for t in ts[::8])


def test_reference_lens_special_cases():
    """Cases where the lens time is known in closed form.

    v = 0, delta = 0: the two balls are concentric, the lens is B(x, min(A t^2/2, V t)), so the
    lens time equals the max formula. A = delta = 0: the lens is the point x + v t (|v| <= V), so
    the lens time is the ray tau.
    """
    x, eps = [3.0, 4.0, 0.0], 1.0
    for A, V in [(1.0, 1.0), (0.01, 10.0), (100.0, 0.5)]:
        lens = ref.lens_time_lower(x, [0.0, 0, 0], eps, A, V)
        mx = ref.tau_speed_max_ref(x, [0.0, 0, 0], eps, A, V)
        assert abs(lens - mx) <= 1e-9 * mx, (A, V, lens, mx)
    v = [-1.0, -1.0, 0.0]  # the ray enters B(0, 1) near t = 3.0
    lens = ref.lens_time_lower(x, v, eps, 0.0, 2.0)
    ray = ref.tau_sphere_ref(x, v, eps, 0.0).value
    assert mpmath.isfinite(ray) and abs(lens - ray) <= 1e-9 * ray, (lens, ray)
    # The max formula is never above the lens time (both balls contain the lens).
    rng = np.random.default_rng(4)
    for _ in range(5):
        xx, vv = rng.normal(size=3) * 3, rng.normal(size=3)
        A, V = rng.uniform(0.1, 2), np.linalg.norm(vv) * rng.uniform(1, 3)
        mx = ref.tau_speed_max_ref(xx, vv, 0.5, A, V)
        chk = ref.check_below_lens(float(mx), xx, vv, 0.5, A, V, rtol=1e-10)
        assert chk.ok or not chk.conclusive, (xx, vv, A, V, mx, chk)


# --------------------------------------------------------------------------------------------
# Reference comparisons
# --------------------------------------------------------------------------------------------


def test_random_against_reference():
    rng = np.random.default_rng(20260501)
    x, v, eps, A, delta = random_cases(rng, 2000)
    tau = np.atleast_1d(time_to_collision(x, v, eps, A, vel_uncertainty=delta))
    assert tau.shape == (len(eps),) and tau.dtype == np.float64
    problems = []
    for i in range(len(eps)):
        problems += check_against_ref(tau[i], x[i], v[i], eps[i], A[i], delta[i])
    assert_all_ok(problems)


def test_settle_bound_is_never_after_the_first_root():
    """The bound that settles a flagged body's pair instead of evaluating it (docs/theory.md,
    section 6, "Settling a made-due pair") never exceeds the exact first root: random cases, and
    head-on approaches, where |x + v t| = |x| - |v| t and the bound is the root but for its
    inflation. Where it does not apply it says so (-inf), never a number."""
    rng = np.random.default_rng(20261202)
    x, v, eps, A, delta = random_cases(rng, 2000)
    # Head-on: v along -x, at speeds that make it, not the acceleration, decide the root.
    on = rng.random(len(eps)) < 0.3
    speed = np.linalg.norm(x, axis=1) * 10.0 ** rng.uniform(-1, 3, len(eps))
    v[on] = -x[on] / np.linalg.norm(x[on], axis=1)[:, None] * speed[on, None]
    problems, bounded = [], 0
    for i in range(len(eps)):
        t = _core.settle_tau(*x[i], *v[i], eps[i], A[i], delta[i])
        assert not math.isnan(t)
        if t == -math.inf:
            continue
        bounded += 1
        problems += check_against_ref(t, x[i], v[i], eps[i], A[i], delta[i], tight=False)
    assert_all_ok(problems)
    assert bounded > 1000
    # Against a wait to cover (the pair's due step): just above it where the bound covers it,
    # found without the root. Covers near the root (the bound's and the root's) test its edge.
    problems, covered = [], 0
    for i in range(len(eps)):
        root = _core.settle_tau(*x[i], *v[i], eps[i], A[i], delta[i])
        if root == -math.inf:
            continue
        for cover in (root * (1 - 1e-9), root * (1 - 1e-13), root * 0.5, root * 1.5):
            t = _core.settle_tau(*x[i], *v[i], eps[i], A[i], delta[i], cover)
            if t == -math.inf or cover <= 0:
                continue
            covered += t > cover
            problems += check_against_ref(t, x[i], v[i], eps[i], A[i], delta[i], tight=False)
    assert_all_ok(problems)
    assert covered > 1000
    # Numbers out of the range its rounding is accounted for: no bound.
    assert _core.settle_tau(1e-300, 0, 0, 0, 0, 0, 0, 1e-300, 0) == -math.inf
    assert _core.settle_tau(1e300, 0, 0, 1e300, 0, 0, 0, 1.0, 0) == -math.inf
    assert _core.settle_tau(1.0, 0, 0, 0, 0, 0, 2.0, 1.0, 0) == -math.inf  # in contact
    # Squares that underflow: |x| of 1.6e-162 came out 41 % above the root (2.2e-32 against
    # 1.6e-32), and a |v| of 1e-170 as 0 let a cover of 1e95 pass a root of 1e90.
    assert _core.settle_tau(1.5718274673686167e-162, 0, 0, -1e-130, 0, 0, 0, 0, 0) == -math.inf
    assert _core.settle_tau(1e-80, 0, 0, -1e-170, 0, 0, 0, 0, 0, 1e95) == -math.inf
    assert _core.settle_tau(1e-80, 0, 0, 0, 0, 0, 0, 0, 0, 1e95) > 1e95  # at rest: it covers


def _scalar_kernel(x, v, eps, A, delta, speed):
    return np.array(
        [tau_speed(*x[i], *v[i], eps[i], A[i], delta[i], speed[i]) for i in range(len(eps))]
    )


@pytest.mark.parametrize("n", [1, 3, 4, 5, 9, 2000, 5003])
def test_batch_lanes_equal_the_scalar_kernel_bit_for_bit(n):
    """time_to_collision runs the kernel four pairs at a time (their common path in lockstep,
    the rest by the scalar kernel): every row must be the scalar kernel's value exactly, in a
    ragged last group, with per-pair and shared bounds, on every path (A = 0, overlap, a tiny
    |v|, the interior minimum, a speed bound, above and below it), serial and threaded."""
    rng = np.random.default_rng(n)
    x, v, eps, A, delta = random_cases(rng, n)
    v[rng.random(n) < 0.05] *= 1e-130  # |v|^2 underflows
    speed = np.where(
        rng.random(n) < 0.5, np.inf, rng.uniform(0.5, 2.0, n) * np.linalg.norm(v, axis=1)
    )
    speed[speed == 0.0] = 1.0
    want = _scalar_kernel(x, v, eps, A, delta, speed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BoundViolationWarning)
        got = time_to_collision(x, v, eps, A, vel_uncertainty=delta, speed=speed)
    np.testing.assert_array_equal(got, want)
    # Shared bounds (one value for every row) take the same path.
    shared = time_to_collision(x, v, eps[0], A[0], vel_uncertainty=delta[0])
    ones = np.ones(n)
    want_shared = _scalar_kernel(x, v, eps[0] * ones, A[0] * ones, delta[0] * ones, np.inf * ones)
    np.testing.assert_array_equal(shared, want_shared)


@URG
@given(
    st.lists(
        st.tuples(*[st.floats(-10.0, 10.0)] * 6, *[st.floats(0.0, 10.0)] * 3),
        min_size=1,
        max_size=11,
    )
)
def test_property_batch_lanes_equal_the_scalar_kernel(rows):
    a = np.array(rows, dtype=np.float64)
    x, v, eps, A, delta = a[:, 0:3], a[:, 3:6], a[:, 6], a[:, 7], a[:, 8]
    got = time_to_collision(x, v, eps, A, vel_uncertainty=delta)
    np.testing.assert_array_equal(
        got, _scalar_kernel(x, v, eps, A, delta, np.full(len(eps), np.inf))
    )


def test_scalar_input_shape():
    out = np.atleast_1d(time_to_collision([3.0, 0, 0], [-1.0, 0, 0], 1.0, 0.0))
    assert out.shape == (1,) and out[0] == pytest.approx(2.0, rel=1e-12)


@pytest.mark.parametrize(
    ("x", "v", "eps", "A", "expected"),
    [
        ([3.0, 0, 0], [-1.0, 0, 0], 1.0, 0.0, 2.0),  # head-on ray
        ([3.0, 0, 0], [0.0, 0, 0], 1.0, 0.0, math.inf),  # v = 0, A = 0
        ([3.0, 0, 0], [0.0, 0, 0], 1.0, 1.0, 2.0),  # v = 0: 1 + t^2/2 = 3
        ([3.0, 0, 0], [1.0, 0, 0], 1.0, 0.0, math.inf),  # separating, no accel
        ([0.5, 0, 0], [1.0, 0, 0], 1.0, 0.0, 0.0),  # overlapping
        ([1.0, 0, 0], [1.0, 0, 0], 1.0, 5.0, 0.0),  # exactly touching, separating
        ([0.0, 0, 0], [0.0, 0, 0], 0.0, 0.0, 0.0),  # degenerate
        ([-10.0, 1, 0], [1.0, 0, 0], 1.0, 0.0, 10.0),  # grazing ray (double root, tangent)
        ([-10.0, 1, 0], [1.0, 0, 0], 0.99999, 0.0, math.inf),  # near-grazing miss
        ([0.5, -2.0, 0], [0.5, 1.0, 0], 1.0, 0.25, 2.0),  # tangency with A > 0 (tangent)
    ],
)
def test_known_cases(x, v, eps, A, expected):
    tau = tau_one(x, v, eps, A)
    assert_all_ok(check_against_ref(tau, x, v, eps, A))
    if math.isinf(expected):
        assert math.isinf(tau)
    else:
        # A double root is ill-conditioned (sqrt of the rounding error): looser target there.
        assert tau == pytest.approx(expected, rel=RTOL_TANGENT if x[1] else 1e-12, abs=0.0)


def _tangent_case(u, n, tstar, eps, A, delta, k):
    """x, v with |x + v t| - R(t) touching zero from above at t* (a double root of g)."""
    R = eps + delta * tstar + A * tstar**2 / 2
    dR = delta + A * tstar
    w = math.sqrt(max(k * A * R, 0.0)) if A > 0 else k * (R + 1.0) / max(tstar, 1.0)
    v = dR * u + w * n
    x = R * u - v * tstar
    return x, v


def _frame(rng):
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    n = rng.normal(size=3)
    n -= n.dot(u) * u
    n /= np.linalg.norm(n)
    return u, n


@pytest.mark.parametrize("check", ["never_late", "tight"])
def test_exact_dyadic_tangency(check):
    """Double roots at exactly representable instants t*: never above t*; within RTOL_TANGENT."""
    rng = np.random.default_rng(3)
    problems = []
    xs, vs, es, As, ds, ts = [], [], [], [], [], []
    for _ in range(300):
        tstar = rng.integers(1, 40) / 4
        A = rng.integers(0, 33) / 16
        delta = rng.integers(0, 9) / 16 * rng.integers(0, 2)
        eps = rng.integers(1, 17) / 8
        R = eps + delta * tstar + A * tstar**2 / 2
        dR = delta + A * tstar
        # w^2 > A R (so |x+vt| - R(t) has a local minimum at t*), w dyadic.
        w = math.ceil(math.sqrt(A * R + 1e-9) * 4 + rng.integers(0, 8)) / 4
        perm = rng.permutation(3)
        su, sn = rng.choice([-1.0, 1.0], 2)
        u, n = np.zeros(3), np.zeros(3)
        u[perm[0]], n[perm[1]] = su, sn
        s = 2.0 ** rng.integers(-14, 14)  # exact rescaling: 6e-5 .. 1.6e4
        v = (dR * u + w * n) * s
        x = R * u * s - v * tstar
        xs.append(x), vs.append(v), es.append(eps * s), As.append(A * s), ds.append(delta * s)
        ts.append(tstar)
    x, v = np.array(xs), np.array(vs)
    eps, A, delta = np.array(es), np.array(As), np.array(ds)
    tau = np.atleast_1d(time_to_collision(x, v, eps, A, vel_uncertainty=delta))
    n_exact = 0
    for i in range(len(ts)):
        r = ref.tau_sphere_ref(x[i], v[i], eps[i], A[i], delta[i])
        rep = case_repr(x[i], v[i], eps[i], A[i], delta[i])
        if not r.is_lower_bound(tau[i]):
            problems.append(f"LATE at tangency: {rep} = {tau[i]!r} > exact {r.value}")
        elif r.is_lower_bound(ts[i]) and not r.is_lower_bound(math.nextafter(ts[i], math.inf)):
            n_exact += 1  # the first root is the touching instant t* itself
            if check == "tight" and tau[i] < ts[i] * (1 - RTOL_TANGENT):
                problems.append(f"LOOSE at tangency: {rep} = {tau[i]!r}, exact {ts[i]!r}")
    assert n_exact > 100, n_exact  # the family really exercises double roots
    assert_all_ok(problems)


def backward_stable(tau, x, v, eps, A, delta, rel=1e-13):
    """tau is the exact first root of a problem whose radius is perturbed by <= rel * S.

    Near a double or triple root the forward error of any conservative solver is amplified
    (a perturbation of size e moves a double root by ~sqrt(e)); the meaningful tightness measure
    there is the backward error: the clearance |x + v tau| - R(tau) must be within rel * S of zero,
    S = |x| + |v| tau + R(tau) (the scale of the rounding errors).
    """
    t = mp.mpf(float(tau))
    xs = [mp.mpf(float(c)) for c in x]
    vs = [mp.mpf(float(c)) for c in v]
    r = mp.mpf(float(eps)) + mp.mpf(float(delta)) * t + mp.mpf(float(A)) * t * t / 2
    y = mp.sqrt(sum((xs[k] + vs[k] * t) ** 2 for k in range(3)))
    scale = mp.sqrt(sum(c * c for c in xs)) + mp.sqrt(sum(c * c for c in vs)) * t + r
    return y - r <= rel * scale


@pytest.mark.parametrize("check", ["never_late", "tight"])
def test_float_near_tangency(check):
    """Tangency built in floats: a tiny crossing, a tiny miss, or exact. Never late; and tight in
    the backward sense (see ``backward_stable``): these roots are ill-conditioned, so a forward
    tolerance would measure the conditioning, not the solver."""
    rng = np.random.default_rng(11)
    rows = []
    for i in range(600):
        u, n = _frame(rng)
        tstar = 10.0 ** rng.uniform(-2, 2)
        eps = 10.0 ** rng.uniform(-3, 1)
        A = [0.0, 10.0 ** rng.uniform(-3, 3)][i % 2]
        delta = [0.0, 10.0 ** rng.uniform(-3, 0)][(i // 2) % 2]
        k = 1.0 + 10.0 ** rng.uniform(-3, 1)
        x, v = _tangent_case(u, n, tstar, eps, A, delta, k)
        rows.append((x, v, eps, A, delta, tstar))
    x = np.array([r[0] for r in rows])
    v = np.array([r[1] for r in rows])
    eps, A, delta, ts = (np.array([r[j] for r in rows]) for j in (2, 3, 4, 5))
    tau = np.atleast_1d(time_to_collision(x, v, eps, A, vel_uncertainty=delta))
    problems = []
    for i in range(len(rows)):
        problems += check_against_ref(tau[i], x[i], v[i], eps[i], A[i], delta[i], tight=False)
        if check == "tight" and not backward_stable(tau[i], x[i], v[i], eps[i], A[i], delta[i]):
            r = ref.tau_sphere_ref(x[i], v[i], eps[i], A[i], delta[i])
            problems.append(
                f"TOO CONSERVATIVE at tangency: {case_repr(x[i], v[i], eps[i], A[i], delta[i])}"
                f" = {tau[i]!r}, touching at {ts[i]!r}, exact {r.value}"
            )
    assert_all_ok(problems)


@pytest.mark.parametrize("log2s", list(range(-14, 15, 2)))
def test_scale_invariance_power_of_two(log2s):
    """(x, eps, v, A) -> s (x, eps, v, A) leaves tau unchanged (exact rescaling by 2^k)."""
    rng = np.random.default_rng(100 + log2s)
    x, v, eps, A, delta = random_cases(rng, 200)
    s = 2.0**log2s
    t0 = np.atleast_1d(time_to_collision(x, v, eps, A, vel_uncertainty=delta))
    t1 = np.atleast_1d(time_to_collision(x * s, v * s, eps * s, A * s, vel_uncertainty=delta * s))
    both_inf = np.isinf(t0) & np.isinf(t1)
    with np.errstate(invalid="ignore"):  # inf - inf where both are inf (handled above)
        rel = np.abs(t1 - t0) / np.maximum(np.abs(t0), 1e-300)
    bad = ~both_inf & ~(rel <= 1e-12) & ~((t0 == 0) & (t1 == 0))
    assert not bad.any(), [
        (case_repr(x[i], v[i], eps[i], A[i], delta[i]), s, t0[i], t1[i])
        for i in np.flatnonzero(bad)[:5]
    ]


@pytest.mark.parametrize("scale", [1e-4, 1e-2, 1.0, 1e2, 1e4])
def test_scale_sweep_against_reference(scale):
    """Decimal (inexact) scales and time scalings, each against the exact reference."""
    rng = np.random.default_rng(int(scale * 1e4) % 2**31)
    x, v, eps, A, delta = random_cases(rng, 150)
    c = 10.0 ** rng.uniform(-3, 3)  # time scaling: v*c, A*c^2, delta*c -> tau/c
    args = (x * scale, v * scale * c, eps * scale, A * scale * c * c, delta * scale * c)
    tau = np.atleast_1d(time_to_collision(*args[:4], vel_uncertainty=args[4]))
    problems = []
    for i in range(len(eps)):
        problems += check_against_ref(tau[i], *(a[i] for a in args))
    assert_all_ok(problems)


def test_tiny_velocity_underflow():
    """|v|^2 underflows to 0 in float64 but the ray still reaches the ball (found by hypothesis)."""
    x, v = [0.0, 0.0, 3.0], [0.0, 0.0, -1.0998993965460972e-257]
    tau = tau_one(x, v, 0.0, 0.0)
    assert_all_ok(check_against_ref(tau, x, v, 0.0, 0.0, tight=False))


def test_extreme_accelerations():
    rng = np.random.default_rng(5)
    n = 200
    x = rng.normal(size=(n, 3))
    v = rng.normal(size=(n, 3))
    eps = np.full(n, 0.1)
    A = np.where(np.arange(n) % 2 == 0, 1e-12, 1e8) * rng.uniform(0.5, 2, n)
    tau = np.atleast_1d(time_to_collision(x, v, eps, A))
    problems = []
    for i in range(n):
        problems += check_against_ref(tau[i], x[i], v[i], eps[i], A[i])
    assert_all_ok(problems)


def test_tiny_accelerations_never_late():
    """Bounds far below any body's (1e-300 to 1e-12 m/s^2), pairs closing head-on among them,
    and head-on speeds far above any body's: G1Root's bracket then spans t_2 / t_a past 2^253,
    which 200 steps did not close (a pair 1 m away closing at 1 m/s got tau = 3.6e76 s under
    A = 5.6e-77, and at 1e24 m/s under 1e-30, 2e54 s; found in this pass)."""
    rng = np.random.default_rng(11)
    n = 120
    x = rng.normal(size=(n, 3))
    v = rng.normal(size=(n, 3))
    head_on = np.arange(n) % 3 == 0
    v[head_on] = -x[head_on] * rng.uniform(0.1, 10.0, (int(head_on.sum()), 1))
    eps = np.where(np.arange(n) % 2 == 0, 0.0, 0.1)
    A = 10.0 ** rng.uniform(-300.0, -12.0, n)
    tau = np.atleast_1d(time_to_collision(x, v, eps, A))
    problems = []
    for i in range(n):
        problems += check_against_ref(tau[i], x[i], v[i], eps[i], A[i], tight=False)
    assert_all_ok(problems)
    # The head-on pairs that start apart close within |x| / |v| s whatever the bound: the exact
    # reference above holds every value; this says the case is in the sample.
    apart = head_on & (np.linalg.norm(x, axis=1) > eps)
    assert apart.sum() >= 30 and np.all(np.isfinite(tau[apart]))
    # At the least bound the kernel solves with (1e-30 m/s^2, below), the ratio comes from the
    # speed: 1e24 m/s head-on puts t_2 / t_a near 2^260.
    for speed in (1e24, 1e26):
        x1, v1 = [0.0, 0.0, 1.0], [0.0, 0.0, -speed]
        t = tau_one(x1, v1, 0.0, 1e-30)
        assert_all_ok(check_against_ref(t, x1, v1, 0.0, 1e-30, tight=False))


def test_settle_bound_stays_below_the_kernel_under_tiny_bounds():
    """The kernel raises a positive bound below 1e-30 m/s^2 to it; the settling bound must
    too, or it settles a pair for longer than an evaluation would (a pair at rest 1 m away under
    1e-40: 1e20 s against the kernel's 1e15 s)."""
    rng = np.random.default_rng(12)
    n = 400
    x = rng.normal(size=(n, 3))
    v = (
        rng.normal(size=(n, 3))
        * np.where(np.arange(n) % 4 == 0, 0.0, 10.0 ** rng.uniform(-9, 1, n))[:, None]
    )
    eps = np.linalg.norm(x, axis=1) * rng.uniform(0.0, 0.9, n)
    accel = 10.0 ** rng.uniform(-300.0, -28.0, n)
    delta = np.where(np.arange(n) % 2 == 0, 0.0, 10.0 ** rng.uniform(-12, -6, n))
    tau = np.atleast_1d(time_to_collision(x, v, eps, accel, vel_uncertainty=delta))
    settled = np.array(
        [_core.settle_tau(*x[i], *v[i], eps[i], accel[i], delta[i]) for i in range(n)]
    )
    finite = np.isfinite(settled)
    assert finite.sum() > n // 2
    assert np.all(settled[finite] <= tau[finite])


@pytest.mark.parametrize("scale", [1.0, 1e-80, 1e-100, 1e-110, 1e-150])
def test_one_problem_at_tiny_scales_never_late(scale):
    """The same pair in units ``scale`` times smaller (the bound too): where ``h^2 |v|^2``
    underflowed, t_2 came out too large, g's interior minimum was missed and the bracket held
    three roots (33.7 s for a first contact before 7.84 s at 1e-100; found by a review in this
    pass). Bounds below 1e-30 m/s^2 are raised to it: earlier, never later."""
    x, v = [10.0 * scale, 0.5 * scale, 0.0], [-scale, 0.0, 0.0]
    eps, accel = scale, 0.04 * scale
    tau = tau_one(x, v, eps, accel)
    assert_all_ok(check_against_ref(tau, x, v, eps, accel, tight=False))
    assert tau <= 7.84


@pytest.mark.parametrize("accel", [1.6e-160, 3e-160, 6e-160])
def test_a_slow_pair_under_a_tiny_bound_never_late(accel):
    """A pair 1 m away closing at 1 mm/s under bounds whose h |v| is below 1e-154 (the kernel
    gave 1e157 s for a contact within 914 s; found by review)."""
    x, v = [1.0, 0.05, 0.0], [-0.001, 0.0, 0.0]
    tau = tau_one(x, v, 0.1, accel)
    assert_all_ok(check_against_ref(tau, x, v, 0.1, accel, tight=False))
    assert tau < 914.0


def test_norms_past_the_squares_range_give_zero():
    """|x| or |x + v t| past 1.3e154 m before the first root: the square overflows and the
    predicate cannot be read, so no time past the bracket's start is certified. The kernel
    said never (inf) here, even for a pair already within eps (found by review)."""
    assert tau_one([1e160, 0.0, 0.0], [0.0, 0.0, 0.0], 2e160, 0.0) == 0.0
    assert tau_one([1e160, 0.0, 0.0], [0.0, 0.0, 0.0], 0.5e160, 1.0) == 0.0
    # A = 0 and delta an ulp below |v|: a first root near 7e153 s, where |x + v t|^2 overflows
    # before the predicate reads it (the kernel said never; found by review).
    x, v = [2.0826947432393332e149, 6.5633509534326387e147, 0.0], [1.0, 0.0, 0.0]
    eps, delta = 2.0826947742739203e149, 0.99999999999999201
    tau = tau_one(x, v, eps, 0.0, vel_uncertainty=delta)
    assert math.isfinite(tau)
    assert_all_ok(check_against_ref(tau, x, v, eps, 0.0, delta, tight=False))


# --------------------------------------------------------------------------------------------
# Exact trajectories (property tests)
# --------------------------------------------------------------------------------------------


def _mpv(a):
    return [mpf(float(c)) for c in a]


def _unit(d):
    nd = mpmath.sqrt(sum(c * c for c in d))
    return [c / nd for c in d] if nd > 0 else [mpf(1), mpf(0), mpf(0)]


def _min_norm_on_piece(p0, u, a, L, eps):
    """min over s in [0, L] of |p0 + u s + a s^2/2| - eps: endpoints, critical points, samples."""

    def f(s):
        q = [p0[k] + u[k] * s + a[k] * s * s / 2 for k in range(3)]
        return mpmath.sqrt(sum(c * c for c in q)) - eps

    # d/ds |p|^2 / 2 = p.u + (p0.a + u.u) s + 1.5 (u.a) s^2 + 0.5 (a.a) s^3
    c3 = float(sum(c * c for c in a) / 2)
    c2 = float(1.5 * sum(u[k] * a[k] for k in range(3)))
    c1 = float(sum(p0[k] * a[k] + u[k] * u[k] for k in range(3)))
    c0 = float(sum(p0[k] * u[k] for k in range(3)))
    coeffs = np.trim_zeros(np.array([c3, c2, c1, c0]), "f")
    cands = [mpf(0), mpf(L)] + [mpf(L) * j / 24 for j in range(1, 24)]
    if len(coeffs) > 1 and np.isfinite(coeffs).all():
        # Normalise first: coefficients spanning 1e-310 .. 1e155 overflow np.roots' companion
        # matrix; the samples above still bound the minimum when roots cannot be had.
        coeffs = np.trim_zeros(coeffs / np.max(np.abs(coeffs)), "f")
        try:
            with np.errstate(all="ignore"):
                roots = np.roots(coeffs)
        except np.linalg.LinAlgError:
            roots = np.zeros(0)
        for r in roots:
            if abs(r.imag) <= 1e-6 * (1 + abs(r)) and 0 <= r.real <= float(L):
                cands.append(mpf(r.real))
    return min(f(s) for s in cands)


def trajectory_min_gap(x, v0, pieces, eps, t_end):
    """min over [0, t_end] of |p(t)| - eps for p(0)=x, p'(0)=v0, piecewise-constant accel.

    Args:
        x, v0: mp 3-vectors.
        pieces: list of (duration, accel mp 3-vector); the last one extends to t_end.
        eps: contact distance.
        t_end: horizon (mpf).

    Returns:
        (min gap, position at t_end, velocity list at piece ends).
    """
    p, u, t = list(x), list(v0), mpf(0)
    best = mpf("inf")
    speeds = [mpmath.sqrt(sum(c * c for c in u))]
    for k, (dur, a) in enumerate(pieces):
        L = t_end - t if k == len(pieces) - 1 else min(dur, t_end - t)
        if L <= 0:
            break
        best = min(best, _min_norm_on_piece(p, u, a, L, eps))
        p = [p[j] + u[j] * L + a[j] * L * L / 2 for j in range(3)]
        u = [u[j] + a[j] * L for j in range(3)]
        speeds.append(mpmath.sqrt(sum(c * c for c in u)))
        t += L
    return best, speeds


@st.composite
def pair_state(draw, *, with_delta=False):
    scale = 10.0 ** draw(st.floats(-3, 3))
    tscale = 10.0 ** draw(st.floats(-1.5, 1.5))
    # Coordinates are 0 or of magnitude >= 1e-6: products of subnormal-range values are a
    # separate, explicit test (test_tiny_velocity_underflow).
    coords = st.one_of(st.just(0.0), st.floats(-1, 1).filter(lambda c: abs(c) >= 1e-6))
    x = np.array([draw(coords) for _ in range(3)]) * 3 * scale
    v = np.array([draw(coords) for _ in range(3)]) * 2 * scale / tscale
    eps = draw(st.floats(0, 1)) * scale
    A = draw(st.sampled_from([0.0, 1.0])) * draw(st.floats(1e-6, 2)) * scale / tscale**2
    delta = draw(st.floats(1e-6, 0.5)) * scale / tscale if with_delta else 0.0
    return x, v, eps, A, delta


@st.composite
def _accel_piece(draw):
    """(fraction of horizon, direction, fraction of A, mode)."""
    frac = draw(st.floats(0.01, 1.0))
    d = [draw(st.floats(-1, 1)) for _ in range(3)]
    mag = draw(st.sampled_from([1.0, 1.0, 0.0])) or draw(st.floats(0, 1))
    mode = draw(st.sampled_from(["free", "toward", "toward", "bang"]))
    return frac, d, mag, mode


@st.composite
def accel_program(draw):
    """Up to 4 pieces (``_accel_piece``) and the initial velocity error's direction, size and
    mode."""
    out = draw(st.lists(_accel_piece(), min_size=1, max_size=4))
    w = [draw(st.floats(-1, 1)) for _ in range(3)]
    wmag = draw(st.sampled_from([1.0, 0.0])) or draw(st.floats(0, 1))
    wmode = draw(st.sampled_from(["free", "toward"]))
    return out, (w, wmag, wmode)


def build_pieces(x, v, A, delta, tau_h, prog, speed=None):
    """Feasible exact trajectory (mp) from a drawn program.

    "toward" points the acceleration at the origin from the predicted position at the piece
    start (the adversarial direction); "bang" uses |a| = A in the drawn direction. With a speed
    bound, each piece is cut where |u + a s| reaches V and followed by cruising.
    """
    progs, (w, wmag, wmode) = prog
    X, Vv = _mpv(x), _mpv(v)
    A, delta = mpf(A), mpf(delta)
    # Initial velocity error |w| <= delta.
    wd = _unit([-c for c in X]) if wmode == "toward" else _unit(_mpv(w))
    w0 = [c * delta * mpf(wmag) for c in wd]
    u0 = [Vv[k] + w0[k] for k in range(3)]
    if speed is not None:
        su = mpmath.sqrt(sum(c * c for c in u0))
        if su > speed:
            u0 = list(Vv)  # |v| <= V is drawn; drop the error rather than break the bound
    total = sum(f for f, *_ in progs)
    p, u = list(X), list(u0)
    pieces = []
    for frac, d, mag, mode in progs:
        dur = tau_h * mpf(frac) / mpf(total)
        if mode == "toward":
            dirn = _unit([-(p[k] + u[k] * dur / 2) for k in range(3)])
            m = A
        else:
            dirn = _unit(_mpv(d))
            m = A if mode == "bang" else A * mpf(mag)
        a = [c * m for c in dirn]
        if speed is not None:
            V = mpf(speed)
            aa = sum(c * c for c in a)
            ua = sum(u[k] * a[k] for k in range(3))
            uu = sum(c * c for c in u)
            if aa > 0:
                disc = ua * ua - aa * (uu - V * V)
                smax = (-ua + mpmath.sqrt(max(disc, mpf(0)))) / aa
                if smax < dur:
                    smax = max(smax * (1 - mpf(10) ** -30), mpf(0))
                    pieces.append((smax, a))
                    p = [p[k] + u[k] * smax + a[k] * smax**2 / 2 for k in range(3)]
                    u = [u[k] + a[k] * smax for k in range(3)]
                    a, dur = [mpf(0)] * 3, dur - smax
        pieces.append((dur, a))
        p = [p[k] + u[k] * dur + a[k] * dur**2 / 2 for k in range(3)]
        u = [u[k] + a[k] * dur for k in range(3)]
    return X, u0, pieces


def _horizon(tau, x, v, eps):
    if math.isfinite(tau):
        return mpf(tau)
    nv = float(np.linalg.norm(v))
    return mpf(10 * (float(np.linalg.norm(x)) + eps + 1e-300) / max(nv, 1e-300)) if nv else mpf(1)


def _check_trajectory(x, v, eps, A, delta, tau, prog, speed=None):
    with mp.workdps(40):
        t_end = _horizon(tau, x, v, eps)
        X, u0, pieces = build_pieces(x, v, A, delta, t_end, prog, speed)
        gap, speeds = trajectory_min_gap(X, u0, pieces, mpf(eps), t_end)
        scale = mpf(float(np.linalg.norm(x))) + mpf(eps) + mpf(10) ** -300
        if speed is not None:
            assert max(speeds) <= mpf(speed) * (1 + mpf(10) ** -25), "generator broke |v| <= V"
        assert gap >= -(mpf(10) ** -25) * scale, (
            f"a feasible trajectory reaches the ball before tau: "
            f"{case_repr(x, v, eps, A, delta, speed)} = {tau!r}; min |p| - eps = {gap}"
        )


@URG
@given(pair_state(), accel_program())
def test_property_accel_only(state, prog):
    x, v, eps, A, _ = state
    assume(np.linalg.norm(x) > eps)
    tau = tau_one(x, v, eps, A)
    _check_trajectory(x, v, eps, A, 0.0, tau, prog)


@URG
@given(pair_state(with_delta=True), accel_program())
def test_property_velocity_uncertainty(state, prog):
    x, v, eps, A, delta = state
    assume(np.linalg.norm(x) > eps)
    tau = tau_one(x, v, eps, A, vel_uncertainty=delta)
    _check_trajectory(x, v, eps, A, delta, tau, prog)


@URG
@given(pair_state(with_delta=True), st.floats(1.0, 5.0), accel_program())
def test_property_speed(state, vfac, prog):
    x, v, eps, A, delta = state
    assume(np.linalg.norm(x) > eps)
    V = float(np.linalg.norm(v)) * vfac + 1e-3 * (float(np.linalg.norm(x)) + 1e-300)
    tau = tau_one(x, v, eps, A, vel_uncertainty=delta, speed=V)
    _check_trajectory(x, v, eps, A, delta, tau, prog, speed=V)


@URG
@given(pair_state(with_delta=True))
def test_tightness_worst_case_trajectory(state):
    """a = -A u, w = -delta u with u the direction of x + v tau reaches |p| = eps at tau."""
    x, v, eps, A, delta = state
    assume(np.linalg.norm(x) > eps)
    tau = tau_one(x, v, eps, A, vel_uncertainty=delta)
    r = ref.tau_sphere_ref(x, v, eps, A, delta)
    assert r.is_lower_bound(tau), f"LATE: {case_repr(x, v, eps, A, delta)} = {tau!r} > {r.value}"
    assume(math.isfinite(tau) and tau > 0)
    assume(root_condition(x, v, eps, A, delta, r.value) < 1e-11)
    with mp.workdps(40):
        t = mpf(tau)
        c = [mpf(x[k]) + mpf(v[k]) * t for k in range(3)]
        nc = mpmath.sqrt(sum(q * q for q in c))
        shrink = mpf(delta) * t + mpf(A) * t * t / 2
        # p(tau) = c - shrink * c/|c|  ->  |p(tau)| = |c| - shrink
        dist = abs(nc - shrink)
        assert dist <= mpf(eps) + mpf(10) ** -8 * _scale(tau, x, v, eps, A, delta), (
            f"tau not tight: {case_repr(x, v, eps, A, delta)} = {tau!r}; the worst case is "
            f"still {dist - mpf(eps)} away at tau (exact root {r.value})"
        )


# --------------------------------------------------------------------------------------------
# Speed bound
# --------------------------------------------------------------------------------------------


def test_speed_between_max_formula_and_lens():
    rng = np.random.default_rng(9)
    n = 25
    x, v, eps, A, delta = random_cases(rng, n)
    V = np.linalg.norm(v, axis=1) * rng.uniform(1.0, 4.0, n) + 1e-3 * np.linalg.norm(x, axis=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error", BoundViolationWarning)
        tau = np.atleast_1d(time_to_collision(x, v, eps, A, vel_uncertainty=delta, speed=V))
    problems = []
    for i in range(n):
        rep = case_repr(x[i], v[i], eps[i], A[i], delta[i], V[i])
        lo = ref.tau_speed_max_ref(x[i], v[i], eps[i], A[i], V[i], delta[i])
        if not mpmath.isinf(lo) and mpf(tau[i]) < lo * (1 - RTOL_TIGHT):
            problems.append(f"LOOSE: {rep} = {tau[i]!r} < max formula {lo}")
        if mpmath.isinf(lo) and math.isfinite(tau[i]):
            problems.append(f"LOOSE: {rep} = {tau[i]!r}, max formula is inf")
        chk = ref.check_below_lens(
            tau[i],
            x[i],
            v[i],
            eps[i],
            A[i],
            V[i],
            delta[i],
            rtol=1e-10,
            max_steps=4000,
            t_cap=float(lo) * 10 if not mpmath.isinf(lo) else None,
        )
        if not chk.ok and chk.conclusive:
            problems.append(f"LATE: {rep} = {tau[i]!r} > lens contact near {chk.reached}")
    assert_all_ok(problems)


def test_speed_violation_warns_and_falls_back():
    x = np.array([[5.0, 0, 0], [5.0, 0, 0]])
    v = np.array([[-1.0, 0.5, 0], [-1.0, 0.5, 0]])
    V = np.array([10.0, 0.5])  # the second pair already moves faster than its bound
    with pytest.warns(BoundViolationWarning):
        tau = np.atleast_1d(time_to_collision(x, v, 1.0, 0.3, speed=V))
    tA = np.atleast_1d(time_to_collision(x, v, 1.0, 0.3))
    assert tau[1] == pytest.approx(tA[1], rel=1e-12)
    assert_all_ok(check_against_ref(tau[1], x[1], v[1], 1.0, 0.3))
    assert tau[0] >= tA[0] * (1 - 1e-12)


def test_speed_inf_is_no_speed_bound():
    rng = np.random.default_rng(12)
    x, v, eps, A, delta = random_cases(rng, 100)
    t0 = np.atleast_1d(time_to_collision(x, v, eps, A, vel_uncertainty=delta))
    t1 = np.atleast_1d(time_to_collision(x, v, eps, A, vel_uncertainty=delta, speed=np.inf))
    np.testing.assert_array_equal(t0, t1)


def test_speed_bound_dominates_when_slow():
    # A huge acceleration bound makes tau_A tiny; the speed bound V = 1 gives (|x| - eps) / V.
    tau = tau_one([10.0, 0, 0], [0.0, 0, 0], 1.0, 1e6, speed=1.0)
    assert tau >= 9.0 * (1 - RTOL_TIGHT)
    chk = ref.check_below_lens(tau, [10.0, 0, 0], [0.0, 0, 0], 1.0, 1e6, 1.0, rtol=1e-10)
    assert chk.ok, chk


# --------------------------------------------------------------------------------------------
# Half-space
# --------------------------------------------------------------------------------------------


def check_halfspace(tau, gap, vn, A, delta, *, tight=True) -> list[str]:
    r = ref.tau_halfspace_ref(gap, vn, A, delta)
    rep = f"time_to_halfspace({gap!r}, {vn!r}, {A!r}, vel_uncertainty={delta!r})"
    if not r.is_lower_bound(tau):
        return [f"LATE: {rep} = {tau!r} > exact {r.value}"]
    if not tight:
        return []
    if r.is_zero and tau != 0:
        return [f"{rep} = {tau!r}, expected 0"]
    if r.is_inf and math.isfinite(tau):
        return [f"{rep} = {tau!r}, expected inf"]
    if not r.is_inf and not r.is_zero and r.rel_error(tau) > RTOL_TIGHT:
        # sensitivity of the root: |f'(r)| vs scale of the terms
        rv = r.value
        df = abs(mpf(vn) - mpf(delta) - mpf(A) * rv)
        S = abs(mpf(gap)) + (abs(mpf(vn)) + mpf(delta)) * rv + mpf(A) * rv * rv / 2
        if df > 0 and mpf(2) ** -52 * S / (df * rv) < 1e-11:
            return [f"LOOSE: {rep} = {tau!r}, exact {rv}"]
    return []


def test_halfspace_random_against_reference():
    rng = np.random.default_rng(21)
    n = 1500
    scale = 10.0 ** rng.uniform(-4, 4, n)
    tsc = 10.0 ** rng.uniform(-2, 2, n)
    gap = rng.uniform(-0.2, 1, n) * scale
    vn = rng.normal(size=n) * scale / tsc
    A = rng.uniform(0, 2, n) * scale / tsc**2
    delta = rng.uniform(0, 0.5, n) * scale / tsc * (rng.integers(0, 2, n))
    kind = rng.integers(0, 6, n)
    A[kind == 0] = 0.0
    A[kind == 1] *= 1e-12  # cancellation in (b + sqrt(b^2 + 2 A gap)) / A when b < 0
    A[kind == 2] *= 1e8
    vn[kind == 3] = delta[kind == 3]  # b = 0 exactly
    gap[kind == 4] = 0.0
    tau = np.atleast_1d(time_to_halfspace(gap, vn, A, vel_uncertainty=delta))
    assert tau.shape == (n,)
    problems = []
    for i in range(n):
        problems += check_halfspace(tau[i], gap[i], vn[i], A[i], delta[i])
    assert_all_ok(problems)


@pytest.mark.parametrize(
    ("gap", "vn", "A", "delta", "expected"),
    [
        (1.0, -1.0, 0.0, 0.0, 1.0),
        (1.0, 0.0, 0.0, 0.0, math.inf),
        (1.0, 2.0, 0.0, 0.0, math.inf),
        (1.0, 0.5, 0.0, 0.5, math.inf),  # b = vn - delta = 0
        (1.0, 0.5, 0.0, 1.5, 1.0),
        (2.0, 0.0, 1.0, 0.0, 2.0),
        (0.0, 1.0, 1.0, 0.0, 0.0),
        (-1.0, 5.0, 0.0, 0.0, 0.0),
        (1.0, -1.0, 1e-12, 0.0, 1.0),  # cancellation
        (1e-4, -1e4, 1e-12, 0.0, 1e-8),
        # |vn|^2 and a * gap underflow (found by hypothesis: the root came out twice too late).
        (1.0, -3.8309705969915786e-215, 0.0, 0.0, 1.0 / 3.8309705969915786e-215),
        (1e-200, 0.0, 1e-200, 0.0, math.sqrt(2.0)),
    ],
)
def test_halfspace_known(gap, vn, A, delta, expected):
    tau = float(np.atleast_1d(time_to_halfspace(gap, vn, A, vel_uncertainty=delta))[0])
    assert_all_ok(check_halfspace(tau, gap, vn, A, delta))
    if math.isinf(expected):
        assert math.isinf(tau)
    else:
        assert tau == pytest.approx(expected, rel=1e-9, abs=0)


@URG
@given(
    st.floats(1e-4, 1e4),
    st.floats(-1, 1),
    st.floats(0, 2),
    st.floats(0, 1),
    st.lists(st.tuples(st.floats(0.01, 1), st.floats(-1, 1)), min_size=1, max_size=4),
    st.floats(-1, 1),
)
def test_halfspace_property(scale, vn, A, delta, prog, w):
    """Normal motion s(t) with |s''| <= A and s'(0) = vn + w, |w| <= delta stays > 0 before tau."""
    gap, vn, A, delta = scale, vn * scale, A * scale, delta * scale
    tau = float(np.atleast_1d(time_to_halfspace(gap, vn, A, vel_uncertainty=delta))[0])
    with mp.workdps(40):
        T = mpf(tau) if math.isfinite(tau) else mpf(100)
        s, u, t = mpf(gap), mpf(vn) + mpf(delta) * mpf(w), mpf(0)
        total = sum(f for f, _ in prog)
        for f, a in prog:
            L = T * mpf(f) / total
            a = mpf(A) * mpf(a)
            ends = [mpf(0), L]
            if a != 0 and 0 < -u / a < L:
                ends.append(-u / a)
            m = min(s + u * e + a * e * e / 2 for e in ends)
            assert m >= -(mpf(10) ** -25) * scale, (gap, vn, A, delta, tau, prog, w)
            s, u, t = s + u * L + a * L * L / 2, u + a * L, t + L
        # Tightness: the worst case a = -A, w = -delta reaches 0 at tau.
        if math.isfinite(tau) and tau > 0:
            T = mpf(tau)
            worst = mpf(gap) + (mpf(vn) - mpf(delta)) * T - mpf(A) * T * T / 2
            terms = abs(mpf(gap)) + (abs(mpf(vn)) + mpf(delta)) * T + mpf(A) * T * T / 2
            assert worst <= mpf(10) ** -8 * terms, ("not tight", gap, vn, A, delta, tau)


# --------------------------------------------------------------------------------------------
# distance urgency and bad input
# --------------------------------------------------------------------------------------------


def test_distance_urgency():
    x = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 0.5]])
    np.testing.assert_allclose(np.atleast_1d(distance_urgency(x, [1.0, 1.0])), [4.0, -0.5])
    np.testing.assert_allclose(np.atleast_1d(distance_urgency([3.0, 4.0, 0.0], 0.0)), [5.0])


X4 = np.arange(12, dtype=float).reshape(4, 3) + 2.0
V4 = -np.ones((4, 3))


@pytest.mark.parametrize("field", ["x", "v"])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_state(field, bad):
    x, v = X4.copy(), V4.copy()
    (x if field == "x" else v)[2, 1] = bad
    with pytest.raises(NonFiniteStateError) as ei:
        time_to_collision(x, v, 1.0, 1.0)
    msg = str(ei.value)
    assert field in msg and "2" in msg, msg


@pytest.mark.parametrize("name", ["eps", "accel", "speed", "vel_uncertainty"])
def test_negative_bound(name):
    kw = {"eps": 1.0, "accel": 1.0, "speed": 100.0, "vel_uncertainty": 0.1}
    kw[name] = np.array([1.0, 1.0, -0.375, 1.0])
    with pytest.raises(InvalidBoundError, match=r"-0\.375"):
        time_to_collision(
            X4, V4, kw["eps"], kw["accel"], speed=kw["speed"], vel_uncertainty=kw["vel_uncertainty"]
        )


@pytest.mark.parametrize("name", ["eps", "accel", "vel_uncertainty"])
def test_nan_bound(name):
    kw = {"eps": 1.0, "accel": 1.0, "vel_uncertainty": 0.1}
    kw[name] = np.nan
    with pytest.raises(InvalidBoundError):
        time_to_collision(X4, V4, kw["eps"], kw["accel"], vel_uncertainty=kw["vel_uncertainty"])


@pytest.mark.parametrize(
    ("x", "v", "eps"),
    [
        (np.zeros((4, 2)), np.zeros((4, 2)), 1.0),
        (X4, np.zeros((3, 3)), 1.0),
        (X4, V4, np.ones(5)),
        (np.zeros((2, 4, 3)), np.zeros((2, 4, 3)), 1.0),
        (np.zeros(4), np.zeros(4), 1.0),
    ],
)
def test_shape_errors(x, v, eps):
    with pytest.raises(ShapeError):
        time_to_collision(x, v, eps, 1.0)


def test_errors_are_invalid_input():
    assert issubclass(ShapeError, InvalidInputError)
    with pytest.raises(InvalidInputError):
        time_to_halfspace([np.nan], [0.0], 1.0)
    with pytest.raises(InvalidBoundError, match=r"-2"):
        time_to_halfspace([1.0], [0.0], -2.0)
    with pytest.raises(ShapeError):
        time_to_halfspace([1.0, 2.0], [0.0, 1.0, 2.0], 1.0)
    with pytest.raises(ShapeError):
        distance_urgency(np.zeros((3, 2)), 1.0)


def test_complex_input_is_refused() -> None:
    """numpy would drop the imaginary part silently: a complex state is a caller's bug."""
    from dua_mujoco.exceptions import InvalidInputError as Invalid

    with pytest.raises(Invalid, match="complex"):
        time_to_collision(np.array([[1.0 + 1j, 0.0, 0.0]]), np.zeros((1, 3)), 0.1, 1.0)
    with pytest.raises(Invalid, match="complex"):
        time_to_collision(np.ones((1, 3)), np.zeros((1, 3)), 0.1 + 0j, 1.0)
