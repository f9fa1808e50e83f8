"""Slow, exact reference for the urgency tau (docs/theory.md, section 1), used only by the tests.

Nothing here shares code or method with ``dua_mujoco.core.urgency``: the fast implementation uses
floating point and safeguarded Newton; this module uses exact rational arithmetic where a decision
is made and high-precision mpmath only to print or approximate numbers.

Method for the sphere tau (acceleration bound, optional velocity uncertainty)
----------------------------------------------------------------------------
Every float64 input is an exact dyadic rational, so ``fractions.Fraction(float)`` is exact and

    g(t) = |x + v t|^2 - (eps + delta t + A t^2 / 2)^2

has exact rational coefficients. For t >= 0 the radius R(t) = eps + delta t + A t^2/2 is >= 0, so
g has the sign of |x + v t| - R(t): tau is 0 if g(0) <= 0, otherwise the smallest positive real
root of g (whatever its multiplicity: at a tangency the double root is the touching instant and
is the answer). No floating-point root finder is trusted:

1. ``q = g / gcd(g, g')`` is the square-free part of g (exact polynomial gcd over Q); it has the
   same distinct real roots as g, all simple, so q changes sign at each of them, including at the
   double roots of g that a complex-pair-discarding solver would skip.
2. The Sturm sequence of q counts its distinct real roots in any (a, b] exactly (Sturm's theorem,
   evaluated with Fractions). A Cauchy bound gives an interval (0, B] that holds every root.
3. Bisection on Sturm counts isolates the first root in (lo, hi]; then bisection on the exact sign
   of q refines the bracket to a relative width of 2**-100.
4. ``FirstRoot.is_lower_bound(t)`` decides *exactly* whether a float t is <= the first root (no
   root of g in [0, t)): this is the check that a fast tau never exceeds the exact root, with no
   tolerance at all, so a tangency at an exactly representable instant (t* = 2.0) still passes
   when the implementation returns 2.0 and fails when it returns 2.0000000000000004.

The half-space tau is the same procedure on p(t) = gap + (n.v - delta) t - A t^2/2.

A second, independent method (``first_root_polyroots``) uses mpmath.polyroots at 60 digits, keeps
real roots and the real parts of nearly-real complex pairs (tangency), and verifies them by the
sign of g; the tests cross-check the two on every family.

Speed bound (lens)
------------------
The position must lie in B1(t) = B(x + v t, delta t + A t^2/2), B2(t) = B(x, V t) and reach
B3 = B(0, eps). The exact lens time is the first root of

    F(t) = min_p max_i (|p - c_i(t)| - r_i(t)),

which is <= 0 exactly when the three balls share a point. F is computed exactly (up to mpmath
rounding) as the minimum over a finite candidate set of max_i(|p - c_i| - r_i): the three centres,
the three pairwise "balanced" points on the segments between centres, and the (at most two)
points equidistant in the shifted sense |p - c_i| = r_i + s in the plane of the centres (an
Apollonius problem: two linear equations and a quadratic in s). The optimum of this convex
minimax problem always has an active set of size 1, 2 or 3 and is one of those points (argued in
``lens_gap``), and any other point only gives an upper value, so the minimum over candidates is F.
F(t) is Lipschitz in t with constant max(|v| + delta + A t, V), which makes conservative
advancement (t += F / L) a root search that can never step over the first root: that proves
``tau <= lens`` up to a stated relative tolerance.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from fractions import Fraction

import mpmath
from mpmath import mp, mpf

mp.dps = 60

Poly = list[Fraction]  # coefficients, lowest degree first

# Relative width of the final bracket of a reference root.
_REFINE_BITS = 100


# --------------------------------------------------------------------------------------------
# Exact polynomial arithmetic over Q
# --------------------------------------------------------------------------------------------


def _trim(p: Poly) -> Poly:
    p = list(p)
    while p and p[-1] == 0:
        p.pop()
    return p


def poly_eval(p: Poly, t: Fraction) -> Fraction:
    """Evaluates ``p`` at ``t`` exactly (Horner)."""
    acc = Fraction(0)
    for c in reversed(p):
        acc = acc * t + c
    return acc


def poly_deriv(p: Poly) -> Poly:
    """Returns the exact derivative of ``p``."""
    return _trim([c * k for k, c in enumerate(p)][1:])


def poly_divmod(n: Poly, d: Poly) -> tuple[Poly, Poly]:
    """Exact polynomial long division ``n = q d + r`` with deg r < deg d."""
    n, d = _trim(n), _trim(d)
    if not d:
        raise ZeroDivisionError("polynomial division by zero")
    q = [Fraction(0)] * max(len(n) - len(d) + 1, 1)
    r = list(n)
    while len(r) >= len(d) and r:
        k = len(r) - len(d)
        c = r[-1] / d[-1]
        q[k] = c
        for i, dc in enumerate(d):
            r[i + k] -= c * dc
        r = _trim(r[:-1]) if r[-1] == 0 else _trim(r)
    return _trim(q), r


def poly_gcd(a: Poly, b: Poly) -> Poly:
    """Monic gcd of two polynomials (Euclid over Q)."""
    a, b = _trim(a), _trim(b)
    while b:
        a, b = b, poly_divmod(a, b)[1]
    return [c / a[-1] for c in a] if a else a


def square_free(p: Poly) -> Poly:
    """Square-free part ``p / gcd(p, p')``: same distinct roots, all simple."""
    p = _trim(p)
    if len(p) <= 2:
        return p
    g = poly_gcd(p, poly_deriv(p))
    return poly_divmod(p, g)[0] if len(g) > 1 else p


def sturm_sequence(q: Poly) -> list[Poly]:
    """Sturm sequence q, q', -rem(...), ... of a square-free polynomial."""
    seq = [_trim(q), poly_deriv(q)]
    while seq[-1]:
        r = poly_divmod(seq[-2], seq[-1])[1]
        if not r:
            break
        seq.append([-c for c in r])
    return [s for s in seq if s]


IntPoly = list[int]


def to_int_poly(p: Poly) -> IntPoly:
    """Positive integer multiple of ``p`` (same signs everywhere, much faster to evaluate)."""
    den = 1
    for c in p:
        den = den * c.denominator // math.gcd(den, c.denominator)
    return [int(c * den) for c in p]


def int_poly_sign_value(p: IntPoly, t: Fraction) -> int:
    """den**deg * p(t) as an exact integer (homogeneous Horner), which has the sign of p(t)."""
    num, den = t.numerator, t.denominator
    acc = 0
    dpow = 1
    for c in reversed(p):
        acc = acc * num + c * dpow
        dpow *= den
    # The loop above gives sum c_i num^i den^(n-i) scaled by a positive power of den.
    return acc


def _sign_changes(seq: list[IntPoly], t: Fraction) -> int:
    signs = [s for s in (int_poly_sign_value(p, t) for p in seq) if s != 0]
    return sum(1 for a, b in itertools.pairwise(signs) if (a > 0) != (b > 0))


def count_roots(seq: list[IntPoly], a: Fraction, b: Fraction) -> int:
    """Number of distinct real roots of ``seq[0]`` in (a, b] (Sturm's theorem)."""
    return _sign_changes(seq, a) - _sign_changes(seq, b)


def cauchy_bound(p: Poly) -> Fraction:
    """Every real root of ``p`` has absolute value below this bound."""
    p = _trim(p)
    lead = abs(p[-1])
    return 1 + max((abs(c) / lead for c in p[:-1]), default=Fraction(0))


def to_frac(value: float | Fraction) -> Fraction:
    """Exact rational value of a float (float64 inputs are dyadic rationals), or the fraction
    itself (a difference of two floats, kept exact)."""
    if isinstance(value, Fraction):
        return value
    f = float(value)
    if not math.isfinite(f):
        raise ValueError(f"reference needs finite inputs, got {value!r}")
    return Fraction(f)


# --------------------------------------------------------------------------------------------
# First non-negative root, exactly
# --------------------------------------------------------------------------------------------


@dataclass
class FirstRoot:
    """The first t >= 0 with p(t) <= 0, for a polynomial p with rational coefficients.

    Attributes:
        poly: the polynomial (lowest degree first).
        lo: lower end of a bracket of the root (exact), or None when the root is 0 or +inf.
        hi: upper end (exact); the root r satisfies lo < r <= hi. ``inf`` when there is no root.
    """

    poly: Poly
    lo: Fraction | None = None
    hi: Fraction | float | None = None
    _seq: list[list[int]] = field(default_factory=list, repr=False)

    @property
    def is_zero(self) -> bool:
        """True when p(0) <= 0 (already in contact)."""
        return self.hi == 0

    @property
    def is_inf(self) -> bool:
        """True when p stays positive for all t >= 0."""
        return self.hi == math.inf

    @property
    def value(self) -> mpf:
        """The root to about 30 digits, as an mpmath number (``mpf('inf')`` when none)."""
        if self.is_inf:
            return mpf("inf")
        if self.is_zero:
            return mpf(0)
        return (
            mpf(self.lo.numerator) / self.lo.denominator
            + mpf(self.hi.numerator) / self.hi.denominator
        ) / 2

    def as_float(self) -> float:
        """Nearest float to the root."""
        return float(self.value)

    def is_lower_bound(self, t: float) -> bool:
        """Exactly decides whether ``t`` <= the first root, i.e. p > 0 on [0, t).

        Args:
            t: a candidate tau (any float, inf allowed).

        Returns:
            True when no collision of the reference model happens strictly before ``t``.
        """
        if t < 0 or math.isnan(t):
            return False
        if self.is_zero:
            return t == 0
        if self.is_inf:
            return True
        if math.isinf(t):
            return False
        ft = Fraction(t)
        if ft <= self.lo:
            return True
        if ft > self.hi:
            return False
        # Roots in (0, ft]; a root exactly at ft is allowed (touching at tau itself).
        n = count_roots(self._seq, Fraction(0), ft)
        if n == 0:
            return True
        return n == 1 and int_poly_sign_value(self._seq[0], ft) == 0

    def rel_error(self, t: float) -> mpf:
        """Relative distance |t - r| / r (0 if both are 0, inf if exactly one is inf/0)."""
        r = self.value
        if self.is_inf or math.isinf(t):
            return mpf(0) if (self.is_inf and math.isinf(t)) else mpf("inf")
        if r == 0:
            return mpf(0) if t == 0 else mpf("inf")
        return abs(mpf(t) - r) / r


def first_nonpositive(poly: Poly) -> FirstRoot:
    """Exact reference for ``min{t >= 0 : p(t) <= 0}`` (see the module docstring).

    Args:
        poly: polynomial with rational coefficients, lowest degree first.

    Returns:
        A ``FirstRoot`` with an exact bracket of relative width 2**-100.
    """
    p = _trim(poly)
    if not p or p[0] <= 0:
        return FirstRoot(p, None, Fraction(0))
    q = square_free(p)
    if len(q) <= 1:  # nonzero constant: never changes sign
        return FirstRoot(p, None, math.inf)
    seq = [to_int_poly(s) for s in sturm_sequence(q)]
    qi = seq[0]
    zero = Fraction(0)
    # A power of two above the Cauchy bound keeps every bisection point dyadic (cheap integers).
    cb = cauchy_bound(q)
    # Bit lengths, not float log2: the bound can exceed the float range (|v| ~ 1e-257).
    bound = Fraction(1 << max(cb.numerator.bit_length() - cb.denominator.bit_length() + 2, 0))
    assert bound >= cb
    if count_roots(seq, zero, bound) == 0:
        return FirstRoot(p, None, math.inf, seq)
    # Isolate: keep the first root in (lo, hi] (Sturm counts are exact, so it cannot be lost)
    # until it is the only root there and the bracket is relatively narrow.
    lo, hi = zero, bound
    while count_roots(seq, lo, hi) > 1 or (hi - lo) > hi / 4:
        mid = (lo + hi) / 2
        if count_roots(seq, lo, mid) >= 1:
            hi = mid
        else:
            lo = mid
    # One simple root r of q in (lo, hi]; q changes sign there, so bisect on its exact sign.
    target = hi / (1 << _REFINE_BITS)
    if int_poly_sign_value(qi, hi) == 0:  # hi is the root itself; (lo, hi) holds no other
        lo = max(lo, hi - target)
    else:
        s_lo = int_poly_sign_value(qi, lo) > 0
        while hi - lo > target:
            mid = (lo + hi) / 2
            val = int_poly_sign_value(qi, mid)
            if val == 0:
                lo, hi = mid - target / 4, mid
                break
            if (val > 0) == s_lo:
                lo = mid
            else:
                hi = mid
    return FirstRoot(p, lo, hi, seq)


def _vec(a) -> list[Fraction]:
    return [to_frac(c) for c in a]


def sphere_poly(x, v, eps, accel, delta=0.0) -> Poly:
    """Exact coefficients of g(t) = |x + v t|^2 - (eps + delta t + A t^2/2)^2."""
    X, Vv = _vec(x), _vec(v)
    e, d, a = to_frac(eps), to_frac(delta), to_frac(accel) / 2
    xx = sum(c * c for c in X)
    xv = sum(p * q for p, q in zip(X, Vv, strict=True))
    vv = sum(c * c for c in Vv)
    # (e + d t + a t^2)^2 = e^2 + 2ed t + (d^2 + 2ea) t^2 + 2da t^3 + a^2 t^4
    return [xx - e * e, 2 * xv - 2 * e * d, vv - d * d - 2 * e * a, -2 * d * a, -a * a]


def tau_sphere_ref(x, v, eps, accel, delta=0.0) -> FirstRoot:
    """Exact reference for ``time_to_collision`` without a speed bound (one pair).

    Args:
        x: relative position (3,).
        v: relative velocity (3,).
        eps: contact distance (>= 0).
        accel: acceleration bound A (>= 0).
        delta: velocity uncertainty (>= 0).

    Returns:
        The first root of g as a ``FirstRoot``.
    """
    return first_nonpositive(sphere_poly(x, v, eps, accel, delta))


def tau_halfspace_ref(gap, normal_velocity, accel, delta=0.0) -> FirstRoot:
    """Exact reference for ``time_to_halfspace``.

    The first t >= 0 with gap + (vn - delta) t - A t^2/2 <= 0.
    """
    g, vn, d, a = to_frac(gap), to_frac(normal_velocity), to_frac(delta), to_frac(accel)
    return first_nonpositive([g, vn - d, -a / 2])


# --------------------------------------------------------------------------------------------
# Independent cross-check: mpmath polyroots
# --------------------------------------------------------------------------------------------


def first_root_polyroots(poly: Poly, dps: int = 60) -> mpf:
    """First t >= 0 with p(t) <= 0 from mpmath.polyroots (second, independent method).

    Keeps real roots and the real parts of complex pairs with a relatively tiny imaginary part
    (a double root comes back as such a pair), then keeps only the candidates where p really
    vanishes (|p| tiny relative to its terms) or that bracket a sign change.

    Args:
        poly: coefficients, lowest degree first (Fractions or floats).
        dps: working precision in decimal digits.

    Returns:
        The first root as ``mpf``; ``mpf('inf')`` if none; 0 if p(0) <= 0.
    """
    with mp.workdps(dps):
        c = [mpf(f.numerator) / f.denominator if isinstance(f, Fraction) else mpf(f) for f in poly]
        while c and c[-1] == 0:
            c.pop()
        if not c or c[0] <= 0:
            return mpf(0)
        if len(c) == 1:
            return mpf("inf")
        roots = mpmath.polyroots(c[::-1], maxsteps=500, extraprec=4 * dps)
        scale_tol = mpf(10) ** (-dps // 3)

        def pval(t):
            return mpmath.polyval(c[::-1], t)

        def pscale(t):
            return sum(abs(ci) * abs(t) ** k for k, ci in enumerate(c))

        cands = []
        for r in roots:
            re, im = mpmath.re(r), mpmath.im(r)
            if re < 0 and abs(re) > scale_tol * (1 + abs(r)):
                continue
            if abs(im) <= scale_tol * (1 + abs(r)):
                re = max(re, mpf(0))
                if abs(pval(re)) <= scale_tol * pscale(re):
                    cands.append(re)
        return min(cands) if cands else mpf("inf")


# --------------------------------------------------------------------------------------------
# Speed bound: max formula and the exact lens
# --------------------------------------------------------------------------------------------


def tau_speed_max_ref(x, v, eps, accel, speed, delta=0.0) -> mpf:
    """The cheap valid bound max(tau_A, (|x| - eps) / V) at 60 digits (0 if |x| <= eps)."""
    tA = tau_sphere_ref(x, v, eps, accel, delta)
    if tA.is_zero:
        return mpf(0)
    nx = mpmath.sqrt(sum(mpf(c) ** 2 for c in x))
    dV = (nx - mpf(eps)) / mpf(speed) if speed > 0 else mpf("inf")
    return max(tA.value, dV)


def _sub(a, b):
    return [p - q for p, q in zip(a, b, strict=True)]


def _dot(a, b):
    return sum(p * q for p, q in zip(a, b, strict=True))


def _norm(a):
    return mpmath.sqrt(_dot(a, a))


def lens_gap(t, x, v, eps, accel, speed, delta=0.0, grow=(0, 0)) -> mpf:
    """F(t) = min_p max_i (|p - c_i| - r_i) over the three balls of the speed lens.

    F(t) <= 0 exactly when B(x + v t, delta t + A t^2/2), B(x, V t) and B(0, eps) share a point.
    The optimum p* has 1, 2 or 3 active terms. One: p* is a local, hence global, minimiser of a
    single |p - c_i| - r_i, i.e. a centre. Two: p* minimises the max of two, which is the centre of
    the larger-containing ball or the unique balanced point on the segment (f_i + f_j >= d - r_i -
    r_j with equality only on the segment). Three: by symmetry the optimal set contains a point
    of the centres' plane where all three shifted distances are equal; for collinear centres the
    1-D problem reduces to a pair. Every candidate p only gives an upper value, so the minimum over
    the candidates is F.

    Args:
        t: time (mpf or float).
        x, v: relative position and velocity (3,).
        eps, accel, speed, delta: the bounds.
        grow: extra radius added to the first two balls (used to cover a whole time step).

    Returns:
        F(t) as ``mpf``.
    """
    t = mpf(t)
    X = [mpf(c) for c in x]
    C = [[X[k] + mpf(v[k]) * t for k in range(3)], X, [mpf(0)] * 3]
    R = [
        mpf(delta) * t + mpf(accel) * t * t / 2 + grow[0],
        mpf(speed) * t + grow[1],
        mpf(eps),
    ]
    return balls_gap(C, R)


def balls_gap(C, R) -> mpf:
    """min_p max_i (|p - C[i]| - R[i]) for three balls (see ``lens_gap`` for why it is exact)."""

    def fmax(p):
        return max(_norm(_sub(p, C[i])) - R[i] for i in range(3))

    cands = [list(c) for c in C]
    for i, j in ((0, 1), (0, 2), (1, 2)):
        e = _sub(C[j], C[i])
        d = _norm(e)
        if d > 0:
            w = (d - R[i] - R[j]) / 2
            s = min(max((R[i] + w) / d, mpf(0)), mpf(1))
            cands.append([C[i][k] + s * e[k] for k in range(3)])
    # Three active: q = p - c0 in span(e1, e2) with q.e_k = k_k + m_k s and |q| = r0 + s.
    e1, e2 = _sub(C[1], C[0]), _sub(C[2], C[0])
    g11, g12, g22 = _dot(e1, e1), _dot(e1, e2), _dot(e2, e2)
    det = g11 * g22 - g12 * g12
    if det > mpf(10) ** (-40) * (g11 * g22 + mpf(10) ** (-300)):
        k1 = (g11 - (R[1] ** 2 - R[0] ** 2)) / 2
        m1 = -(R[1] - R[0])
        k2 = (g22 - (R[2] ** 2 - R[0] ** 2)) / 2
        m2 = -(R[2] - R[0])
        a0 = (g22 * k1 - g12 * k2) / det
        b0 = (-g12 * k1 + g11 * k2) / det
        a1 = (g22 * m1 - g12 * m2) / det
        b1 = (-g12 * m1 + g11 * m2) / det
        Q0 = [a0 * e1[k] + b0 * e2[k] for k in range(3)]
        Q1 = [a1 * e1[k] + b1 * e2[k] for k in range(3)]
        qa = _dot(Q1, Q1) - 1
        qb = 2 * (_dot(Q0, Q1) - R[0])
        qc = _dot(Q0, Q0) - R[0] ** 2
        sols = []
        if abs(qa) > mpf(10) ** (-40) * (abs(qb) + abs(qc) + 1):
            disc = qb * qb - 4 * qa * qc
            if disc >= 0:
                sq = mpmath.sqrt(disc)
                sols = [(-qb - sq) / (2 * qa), (-qb + sq) / (2 * qa)]
        elif qb != 0:
            sols = [-qc / qb]
        for s in sols:
            cands.append([C[0][k] + Q0[k] + Q1[k] * s for k in range(3)])
    return min(fmax(p) for p in cands)


@dataclass
class LensCheck:
    """Outcome of ``check_below_lens``.

    Attributes:
        ok: True if tau is (within the tolerance) no later than the first lens contact.
        reached: the time conservative advancement reached (>= tau * (1 - rtol) when ok).
        gap: F at ``reached``.
        steps: number of advancement steps.
        conclusive: False when the step budget ran out before a verdict.
    """

    ok: bool
    reached: mpf
    gap: mpf
    steps: int
    conclusive: bool = True


def check_below_lens(
    tau,
    x,
    v,
    eps,
    accel,
    speed,
    delta=0.0,
    *,
    rtol=1e-12,
    max_steps=20000,
    t_cap=None,
    contact_tol=1e-20,
) -> LensCheck:
    """Proves F > 0 on [0, tau * (1 - rtol)) by conservative advancement, or finds contact.

    F is Lipschitz in t with constant L(t) = max(|v| + delta + A t, V); a step of length h with
    h * max(V, |v| + delta + A (t + h)) <= F(t) cannot cross a zero of F, so the walk never
    passes the first lens contact. It stops when it reaches tau (pass), when F becomes tiny
    relative to the scale before tau (fail: the lens reaches the ball earlier), or when the budget
    is exhausted (inconclusive).

    Args:
        tau: the implementation's value (float; inf is checked up to ``t_cap``).
        x, v, eps, accel, speed, delta: the inputs.
        rtol: relative slack allowed above the lens contact (the walk converges only linearly).
        max_steps: step budget.
        t_cap: horizon used when ``tau`` is inf.
        contact_tol: F below ``contact_tol * scale`` counts as contact.

    Returns:
        A ``LensCheck``.
    """
    with mp.workdps(30):
        nv = _norm([mpf(c) for c in v])
        scale = _norm([mpf(c) for c in x]) + mpf(eps) + mpf(10) ** (-300)
        target = mpf(tau)
        if mpmath.isinf(target):
            target = mpf(t_cap) if t_cap is not None else mpf("inf")
        goal = target * (1 - mpf(rtol))
        t = mpf(0)
        A, V, d = mpf(accel), mpf(speed), mpf(delta)
        F = lens_gap(t, x, v, eps, accel, speed, delta)
        for k in range(max_steps):
            if t >= goal:
                return LensCheck(True, t, F, k)
            if mpf(contact_tol) * scale >= F:
                return LensCheck(False, t, F, k)
            b = nv + d + A * t
            h_acc = 2 * F / (b + mpmath.sqrt(b * b + 4 * A * F)) if (b > 0 or A > 0) else mpf("inf")
            h_vel = F / V if V > 0 else mpf("inf")
            h = min(h_acc, h_vel)
            if mpmath.isinf(h):
                return LensCheck(True, mpf("inf"), F, k)  # nothing moves: F constant > 0
            # Longer certified step: over [t, t + h] ball 1 stays inside B(c1(t), r1(t) + b h +
            # A h^2/2) and ball 2 inside B(x, V (t + h)); if those inflated balls are disjoint
            # from each other's common part, no contact happens in the step. Doubling search.
            for _ in range(60):
                h2 = 2 * h
                grow = (b * h2 + A * h2 * h2 / 2, V * h2)
                if lens_gap(t, x, v, eps, accel, speed, delta, grow) <= 0:
                    break
                h = h2
            t = t + h * (1 - mpf(10) ** (-25))
            F = lens_gap(t, x, v, eps, accel, speed, delta)
        return LensCheck(t >= goal, t, F, max_steps, conclusive=False)


def lens_time_lower(x, v, eps, accel, speed, delta=0.0, *, max_steps=20000) -> mpf:
    """A value <= the first lens contact, where F has fallen below 1e-14 of the scale."""
    res = check_below_lens(
        math.inf, x, v, eps, accel, speed, delta, rtol=0, max_steps=max_steps, contact_tol=1e-14
    )
    return res.reached
