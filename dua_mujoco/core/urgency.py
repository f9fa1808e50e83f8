"""Urgency: conservative lower bounds on the time to collision (docs/theory.md, section 1).

For a pair of spheres with relative centre position ``x``, relative velocity ``v``, contact
distance ``eps`` (radii plus margin), bound ``A`` on the norm of the relative acceleration and
velocity uncertainty ``delta``, the relative position at time ``t`` lies in the ball
``B(x + v t, delta t + A t^2 / 2)``. A collision at ``t`` needs that ball to reach ``B(0, eps)``, so

    tau = min { t >= 0 : |x + v t| <= eps + delta t + A t^2 / 2 }       (+inf if none)

is a lower bound on the time to collision (paper eq. 13, extended by ``delta``).

The kernels below never return more than the exact first root. How (proof in docs/theory.md,
section 1):

* The problem is solved for slightly inflated parameters (``eps``, ``delta`` and ``A`` grown by
  ``_KAPPA`` relative, plus ``_KAPPA (|x| + |v| t)`` on the radius). The inflation is larger than
  any rounding error of the predicate, so at the exact first root of the original problem the
  computed predicate of the inflated one is strictly negative, even at a tangency (double root).
* ``g(t) = |x + v t|^2 - R(t)^2`` has ``g''`` decreasing on ``[0, inf)``, so ``g'`` is increasing
  then decreasing there and ``g`` has at most two critical points: at most one interior local
  minimum, which is the only place a first root can hide without a sign change of ``g'``. It is
  located by safeguarded Newton and the predicate is evaluated there in vector form (no expanded
  polynomial, so no cancellation).
* The root is refined inside a bracket ``[lo, hi]`` on which ``g`` is monotone, with the computed
  predicate positive at ``lo`` and non-positive at ``hi``; ``lo`` is returned, so an early stop
  still gives a lower bound.
"""

from __future__ import annotations

import math
import warnings

import numba as nb
import numpy as np
import numpy.typing as npt

from dua_mujoco.core.validate import as_vectors, per_pair
from dua_mujoco.exceptions import BoundViolationWarning, InvalidBoundError, ShapeError

__all__ = [
    "PARALLEL_MIN",
    "distance_urgency",
    "tau_accel",
    "tau_between",
    "tau_halfspace",
    "tau_speed",
    "time_to_collision",
    "time_to_halfspace",
]

# Relative inflation of the problem. It must dominate the rounding error of the predicate, which
# is at most ~4.5 u (|x| + |v| t + R(t)) with u = 2**-53 (docs/theory.md); 4e-15 leaves ~8x.
_KAPPA = 4e-15
# Relative bracket width at which refinement stops (the result is the bracket's lower end).
_RTOL = 2e-13
_MAX_ITER = 200
_INF = math.inf


@nb.njit(cache=True, inline="always")
def _predicate(x0, x1, x2, v0, v1, v2, e, d, h, t):  # pragma: no cover - jitted
    """|x + v t| - (e + d t + h t^2): positive while the reachable ball misses B(0, e)."""
    y0 = x0 + v0 * t
    y1 = x1 + v1 * t
    y2 = x2 + v2 * t
    return math.sqrt(y0 * y0 + y1 * y1 + y2 * y2) - (e + t * (d + h * t))


@nb.njit(cache=True, inline="always")
def _predicate_and_slopes(x0, x1, x2, v0, v1, v2, a, e, d, h, t):  # pragma: no cover - jitted
    """The predicate (same expression as ``_predicate``, so the same sign), f' and f''.

    ``a = |v|^2``. With ``p = (y . v) / |y|``: ``|y|' = p`` and ``|y|'' = (|v|^2 - p^2) / |y|``.
    """
    y0 = x0 + v0 * t
    y1 = x1 + v1 * t
    y2 = x2 + v2 * t
    ny = math.sqrt(y0 * y0 + y1 * y1 + y2 * y2)
    f = ny - (e + t * (d + h * t))
    if ny > 0.0:
        p = (y0 * v0 + y1 * v1 + y2 * v2) / ny
        f2 = (a - p * p) / ny - 2.0 * h
    else:
        p = 0.0
        f2 = -2.0 * h
    return f, p - (d + 2.0 * h * t), f2


@nb.njit(cache=True)
def _refine(x0, x1, x2, v0, v1, v2, e, d, h, lo, hi):  # pragma: no cover - jitted
    """Lower end of a tight bracket of the single root of the predicate in ``[lo, hi]``.

    Fast path: Halley's method on the expanded quartic ``g`` (no square roots), then the
    bracket ``[t (1 - RTOL/2), t (1 + RTOL/2)]`` is *certified* with the vector-form predicate
    (positive at its lower end, non-positive at its upper end, inside ``[lo, hi]``). The expanded
    polynomial only steers: if cancellation made its root inaccurate, certification fails and
    the safe iteration (``_refine_safe``) runs instead, so correctness rests on the predicate.
    """
    a = v0 * v0 + v1 * v1 + v2 * v2
    b = x0 * v0 + x1 * v1 + x2 * v2
    c = x0 * x0 + x1 * x1 + x2 * x2
    # g(t) = a t^2 + 2 b t + c - (e + d t + h t^2)^2
    c4 = -h * h
    c3 = -2.0 * h * d
    c2 = a - d * d - 2.0 * e * h
    c1 = 2.0 * (b - e * d)
    c0 = c - e * e
    blo = lo
    bhi = hi
    t = hi
    for _ in range(16):
        g = (((c4 * t + c3) * t + c2) * t + c1) * t + c0
        g1 = ((4.0 * c4 * t + 3.0 * c3) * t + 2.0 * c2) * t + c1
        g2 = (12.0 * c4 * t + 6.0 * c3) * t + 2.0 * c2
        if g > 0.0:
            blo = max(blo, t)
        else:
            bhi = min(bhi, t)
        den = 2.0 * g1 * g1 - g * g2
        tn = t - 2.0 * g * g1 / den if (g1 < 0.0 and den > 0.0) else -1.0
        if not (blo <= tn <= bhi):
            tn = 0.5 * (blo + bhi)
        if abs(tn - t) <= 1e-15 * t:
            t = tn
            break
        t = tn
    tl = t * (1.0 - 0.5 * _RTOL)
    th = t * (1.0 + 0.5 * _RTOL)
    if (
        lo <= tl
        and th <= hi
        and _predicate(x0, x1, x2, v0, v1, v2, e, d, h, tl) > 0.0
        and _predicate(x0, x1, x2, v0, v1, v2, e, d, h, th) <= 0.0
    ):
        return tl
    return _refine_safe(x0, x1, x2, v0, v1, v2, e, d, h, lo, hi)


@nb.njit(cache=True)
def _refine_safe(x0, x1, x2, v0, v1, v2, e, d, h, lo, hi):  # pragma: no cover - jitted
    """Lower end of a tight bracket of the single root of the predicate in ``[lo, hi]``.

    Requires: predicate(lo) > 0, predicate(hi) <= 0 and exactly one root in ``[lo, hi]`` (g
    monotone or unimodal there). Halley's method (cubic convergence; f'' is nearly free) from
    ``hi``, safeguarded by bisection; every iterate tightens the bracket, so stopping early still
    returns a lower bound.
    """
    a = v0 * v0 + v1 * v1 + v2 * v2
    t = hi
    f, df, d2 = _predicate_and_slopes(x0, x1, x2, v0, v1, v2, a, e, d, h, t)
    probe = False  # the previous iterate was a probe past a converged point
    for _ in range(_MAX_ITER):
        tol = _RTOL * hi
        if hi - lo <= tol:
            break
        den = 2.0 * df * df - f * d2
        tn = t - 2.0 * f * df / den if (df < 0.0 and den > 0.0) else -1.0
        side = f > 0.0
        if abs(tn - t) <= tol:
            if probe:
                # A probe did not close the bracket: Halley is creeping towards a minimum of
                # the predicate (near a tangency), not a root. Bisect instead.
                tn = 0.5 * (lo + hi)
                probe = False
            else:
                # Converged from one side; step just past it to close the bracket.
                tn = t + tol if side else t - tol
                probe = True
        else:
            probe = False
        if not (lo < tn < hi):
            tn = 0.5 * (lo + hi)
        f, df, d2 = _predicate_and_slopes(x0, x1, x2, v0, v1, v2, a, e, d, h, tn)
        if f > 0.0:
            lo = tn
        else:
            hi = tn
        if probe and (f > 0.0) != side:
            probe = False
        t = tn
    return lo


@nb.njit(cache=True)
def _g1_root(p3, p2, p1, p0, lo, hi, increasing):  # pragma: no cover - jitted
    """Root of the cubic G1(t) = p3 t^3 + p2 t^2 + p1 t + p0, monotone on [lo, hi] (sign change)."""
    t = 0.5 * (lo + hi)
    for _ in range(_MAX_ITER):
        val = ((p3 * t + p2) * t + p1) * t + p0
        if (val > 0.0) == increasing:
            hi = t
        else:
            lo = t
        if hi - lo <= 1e-15 * hi:
            break
        der = (3.0 * p3 * t + 2.0 * p2) * t + p1
        tn = t - val / der if der != 0.0 else 0.5 * (lo + hi)
        if not (lo < tn < hi):
            tn = 0.5 * (lo + hi)
        if tn == t:
            break
        t = tn
    return t


@nb.njit(cache=True)
def _upper(x0, x1, x2, v0, v1, v2, e, d, h, start, nx, nv):  # pragma: no cover - jitted
    """A time >= start where the predicate is <= 0, on a final piece where g decreases to -inf."""
    # |x + v t| <= |x| + |v| t, so the predicate is <= 0 once |x| + |v| t <= e + d t + h t^2.
    bq = nv - d
    cq = nx - e
    if h > 0.0:
        t = (bq + math.sqrt(bq * bq + 4.0 * h * max(cq, 0.0))) / (2.0 * h)
    else:  # d > |v| on this branch
        t = max(cq, 0.0) / (d - nv)
    t = max(t, start, 1e-300)
    for _ in range(2100):
        if _predicate(x0, x1, x2, v0, v1, v2, e, d, h, t) <= 0.0:
            return t
        t *= 2.0
    return _INF


@nb.njit(cache=True)
def tau_accel(x0, x1, x2, v0, v1, v2, eps, accel, delta):  # pragma: no cover - jitted
    """Scalar kernel: min {t >= 0 : |x + v t| <= eps + delta t + accel t^2 / 2} (lower bound)."""
    nx = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    nv = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    vmax = max(abs(v0), abs(v1), abs(v2))
    if 0.0 < vmax < 1e-120:
        # |v|^2 would underflow: solve in the time unit s (a power of two, so exactly), where the
        # velocity is O(1): x + v t = x + (v s) (t / s).
        s = 2.0 ** round(-math.log2(vmax))
        if math.isfinite(accel * s * s) and math.isfinite(delta * s):
            return s * tau_accel(x0, x1, x2, v0 * s, v1 * s, v2 * s, eps, accel * s * s, delta * s)
    # Inflated problem (see module docstring): radius e + d t + h t^2.
    e = eps * (1.0 + _KAPPA) + _KAPPA * nx
    d = delta * (1.0 + _KAPPA) + _KAPPA * nv
    h = 0.5 * accel * (1.0 + _KAPPA)
    if nx - e <= 0.0:
        return 0.0
    a = nv * nv
    b = x0 * v0 + x1 * v1 + x2 * v2
    # g(t) = |x + v t|^2 - (e + d t + h t^2)^2; G1 = g'/2 and G2 = g''/2:
    #   G1(t) = -2h^2 t^3 - 3hd t^2 + q t + (b - e d),  G2(t) = -6h^2 t^2 - 6hd t + q.
    q = a - d * d - 2.0 * e * h
    p0 = b - e * d
    if h == 0.0:
        if q > 0.0:
            # g is convex: decreasing until its vertex, then increasing. Only the vertex can touch.
            if p0 >= 0.0:
                return _INF
            tv = -p0 / q
            if _predicate(x0, x1, x2, v0, v1, v2, e, d, h, tv) > 0.0:
                return _INF
            return _refine(x0, x1, x2, v0, v1, v2, e, d, h, 0.0, tv)
        if q == 0.0 and p0 >= 0.0:
            return _INF
        # q < 0 (or linear and decreasing): g goes to -inf past its vertex (if any).
        start = max(-p0 / q, 0.0) if q < 0.0 else 0.0
        if start > 0.0 and _predicate(x0, x1, x2, v0, v1, v2, e, d, h, start) <= 0.0:
            return _refine(x0, x1, x2, v0, v1, v2, e, d, h, 0.0, start)
        if d <= nv:  # linear g with |v| = d: the closed-form upper bound does not apply
            t = max(start, 1.0)
            for _ in range(2100):
                if _predicate(x0, x1, x2, v0, v1, v2, e, d, h, t) <= 0.0:
                    return _refine(x0, x1, x2, v0, v1, v2, e, d, h, start, t)
                t *= 2.0
            return _INF
        hi = _upper(x0, x1, x2, v0, v1, v2, e, d, h, start, nx, nv)
        return _refine(x0, x1, x2, v0, v1, v2, e, d, h, start, hi)

    # start: a time before the first root with g > 0 on [0, start] and g unimodal (rising then
    # falling) on [start, inf), so the bracket [start, hi] holds exactly one root.
    start = 0.0
    if q > 0.0 and p0 < 0.0:
        # G2's positive root: 6h^2 t^2 + 6hd t - q = 0, in the cancellation-free form. G1 = g'/2
        # rises on [0, t2] and falls after, so with G1(0) < 0 < G1(t2), g decreases on [0, ta],
        # rises to a local maximum and falls: the local minimum ta is the only place a first root
        # can touch without a sign change of g'.
        t2 = 2.0 * q / (6.0 * h * d + math.sqrt(36.0 * h * h * d * d + 24.0 * h * h * q))
        p3 = -2.0 * h * h
        p2 = -3.0 * h * d
        if ((p3 * t2 + p2) * t2 + q) * t2 + p0 > 0.0:
            ta = _g1_root(p3, p2, q, p0, 0.0, t2, True)
            if _predicate(x0, x1, x2, v0, v1, v2, e, d, h, ta) <= 0.0:
                return _refine(x0, x1, x2, v0, v1, v2, e, d, h, 0.0, ta)
            start = ta
    hi = _upper(x0, x1, x2, v0, v1, v2, e, d, h, start, nx, nv)
    return _refine(x0, x1, x2, v0, v1, v2, e, d, h, start, hi)


@nb.njit(cache=True)
def tau_speed(x0, x1, x2, v0, v1, v2, eps, accel, delta, speed):  # pragma: no cover - jitted
    """Scalar kernel with a relative speed bound ``speed`` (``inf`` for none).

    The relative position also stays in ``B(x, V t)``, so no collision before
    ``(|x| - eps) / V``; the larger of that and ``tau_accel`` is still a lower bound. A measured
    ``|v| > V`` means the declared bound is broken: the speed term is then dropped.
    """
    tau = tau_accel(x0, x1, x2, v0, v1, v2, eps, accel, delta)
    if speed < _INF and tau > 0.0:
        nv = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        if nv <= speed:
            nx = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
            ts = (nx - eps * (1.0 + _KAPPA) - _KAPPA * nx) / speed * (1.0 - _KAPPA)
            tau = max(tau, ts)
    return tau


@nb.njit(cache=True, inline="always")
def tau_between(ci, vi, cj, vj, eps, accel, delta, speed):  # pragma: no cover - jitted
    """:func:`tau_speed` of two spheres from their centres ``ci``, ``cj`` and velocities ``vi``,
    ``vj`` (3-vectors each; the relative state is ``j`` minus ``i``)."""
    return tau_speed(
        cj[0] - ci[0],
        cj[1] - ci[1],
        cj[2] - ci[2],
        vj[0] - vi[0],
        vj[1] - vi[1],
        vj[2] - vi[2],
        eps,
        accel,
        delta,
        speed,
    )


@nb.njit(cache=True)
def tau_halfspace(gap, normal_velocity, accel, delta):  # pragma: no cover - jitted
    """Scalar kernel: min {t >= 0 : gap + (n.v) t - delta t - accel t^2 / 2 <= 0} (lower bound)."""
    if gap <= 0.0:
        return 0.0
    # Exact where it matters: x - y is exact when y / 2 <= x <= 2 y (Sterbenz), so w is exactly 0
    # when the velocity uncertainty cancels the approach speed; elsewhere its rounding is relative.
    w = normal_velocity - delta
    a = accel * (1.0 + _KAPPA)
    # sqrt(w^2 + 2 a gap), without squaring: w * w underflows to 0 below |w| ~ 1e-154, and then
    # 2 gap / (s - w) below was twice the root (1 / |w| instead of 1 / (2 |w|) for a = 0).
    s = math.hypot(w, math.sqrt(2.0 * a) * math.sqrt(gap))
    # Positive root of (a/2) t^2 - w t - gap, in the form without cancellation for either sign of w.
    if w > 0.0:
        if a == 0.0:
            return _INF
        t = (w + s) / a
    else:
        den = s - w
        if den == 0.0:
            return _INF
        t = 2.0 * gap / den
    return t * (1.0 - _KAPPA)


# The batch kernels take per-pair parameters of length M or 1 (a broadcast scalar), so scalars
# cost no (M,) temporaries.
@nb.njit(cache=True, inline="always")
def _at(arr, i):  # pragma: no cover - jitted
    return arr[i] if arr.shape[0] > 1 else arr[0]


# Below this many pairs the batch kernels run serially: waking the thread pool costs more than
# the work (and can cost milliseconds on a loaded machine).
PARALLEL_MIN = 4096


@nb.njit(cache=True)
def _tau_row(x, v, eps, accel, delta, speed, out, i):  # pragma: no cover - jitted
    out[i] = tau_speed(
        x[i, 0],
        x[i, 1],
        x[i, 2],
        v[i, 0],
        v[i, 1],
        v[i, 2],
        _at(eps, i),
        _at(accel, i),
        _at(delta, i),
        _at(speed, i),
    )


@nb.njit(cache=True)
def _tau_serial(x, v, eps, accel, delta, speed, out):  # pragma: no cover - jitted
    for i in range(x.shape[0]):
        _tau_row(x, v, eps, accel, delta, speed, out, i)


@nb.njit(cache=True, parallel=True)
def _tau_parallel(x, v, eps, accel, delta, speed, out):  # pragma: no cover - jitted
    for i in nb.prange(x.shape[0]):
        _tau_row(x, v, eps, accel, delta, speed, out, i)


def _tau_batch(x, v, eps, accel, delta, speed, out):
    """tau of every row into ``out``: threads for large batches, serial for small ones."""
    kernel = _tau_parallel if x.shape[0] >= PARALLEL_MIN else _tau_serial
    kernel(x, v, eps, accel, delta, speed, out)


@nb.njit(cache=True)
def _halfspace_batch(gap, vn, accel, delta, out):  # pragma: no cover - jitted
    # Serial: a closed form is cheaper than waking threads for any realistic batch.
    for i in range(gap.shape[0]):
        out[i] = tau_halfspace(_at(gap, i), _at(vn, i), _at(accel, i), _at(delta, i))


def time_to_collision(
    x: npt.ArrayLike,
    v: npt.ArrayLike,
    eps: npt.ArrayLike,
    accel: npt.ArrayLike,
    *,
    speed: npt.ArrayLike | None = None,
    vel_uncertainty: npt.ArrayLike = 0.0,
) -> np.ndarray:
    """Conservative time to collision of sphere pairs (docs/theory.md, section 1).

    Args:
        x: Relative centre positions ``c_j - c_i``, shape ``(M, 3)`` or ``(3,)``.
        v: Relative centre velocities, same shape as ``x``.
        eps: Contact distance (radii plus margin), scalar or ``(M,)``, ``>= 0``.
        accel: Bound ``A`` on the norm of the relative acceleration, scalar or ``(M,)``, ``>= 0``.
        speed: Optional bound ``V`` on the relative speed, scalar or ``(M,)``, ``> 0`` (``inf``
            for none). Rows whose measured ``|v|`` exceeds it break the declared bound: they fall
            back to the acceleration-only value and a ``BoundViolationWarning`` is issued.
        vel_uncertainty: Bound ``delta`` on the error of ``v``, scalar or ``(M,)``, ``>= 0``.

    Returns:
        ``(M,)`` float64 lower bounds on the time to collision: never above the exact first root
        of ``|x + v t| = eps + delta t + A t^2 / 2``, ``0`` where already within ``eps`` and
        ``+inf`` where no collision is possible.

    Raises:
        ShapeError: Shapes do not match.
        NonFiniteStateError: ``x`` or ``v`` holds NaN or inf.
        InvalidBoundError: A bound is negative or NaN.
    """
    xa = as_vectors("x", x)
    m = xa.shape[0]
    va = as_vectors("v", v, m)
    eps_a = per_pair("eps", eps, m)
    acc_a = per_pair("accel", accel, m)
    del_a = per_pair("vel_uncertainty", vel_uncertainty, m)
    if speed is None:
        spd_a = np.full(1, np.inf)
    else:
        spd_a = per_pair("speed", speed, m, allow_inf=True)
        if (spd_a == 0.0).any():
            i = int(np.flatnonzero(spd_a == 0.0)[0])
            raise InvalidBoundError(
                f"speed[{i}] = 0 is invalid: a speed bound must be positive (use inf for none)."
            )
        broken = np.einsum("ij,ij->i", va, va) > spd_a * spd_a
        if broken.any():
            i = int(np.flatnonzero(broken)[0])
            warnings.warn(
                f"{int(broken.sum())} pair(s) move faster than their speed bound (e.g. pair {i}: "
                f"|v| = {np.linalg.norm(va[i]):.6g} > V = {spd_a[min(i, spd_a.size - 1)]:.6g}); "
                "the bound is broken "
                "there and those pairs fall back to the acceleration-only tau.",
                BoundViolationWarning,
                stacklevel=2,
            )
    out = np.empty(m)
    _tau_batch(xa, va, eps_a, acc_a, del_a, spd_a, out)
    return out


def time_to_halfspace(
    gap: npt.ArrayLike,
    normal_velocity: npt.ArrayLike,
    accel: npt.ArrayLike,
    *,
    vel_uncertainty: npt.ArrayLike = 0.0,
) -> np.ndarray:
    """Conservative time until spheres reach half-spaces (MuJoCo planes).

    Args:
        gap: ``n . c - r - contact_distance`` (signed clearance), scalar or ``(M,)``.
        normal_velocity: ``n . v``, the clearance rate, scalar or ``(M,)``.
        accel: Bound on the acceleration norm of the sphere centre, scalar or ``(M,)``, ``>= 0``.
        vel_uncertainty: Bound on the error of the velocity, scalar or ``(M,)``, ``>= 0``.

    Returns:
        ``(M,)`` float64: the first ``t >= 0`` with
        ``gap + normal_velocity t - vel_uncertainty t - accel t^2 / 2 <= 0`` (a lower bound), ``0``
        where ``gap <= 0`` and ``+inf`` where never.
    """
    g = np.atleast_1d(np.asarray(gap, dtype=np.float64))
    if g.ndim != 1:
        raise ShapeError(f"gap has shape {g.shape}; expected a scalar or (M,).")
    m = g.shape[0]
    g = per_pair("gap", g, m, state=True)
    vn = per_pair("normal_velocity", normal_velocity, m, state=True)
    acc = per_pair("accel", accel, m)
    dl = per_pair("vel_uncertainty", vel_uncertainty, m)
    out = np.empty(m)
    _halfspace_batch(g, vn, acc, dl, out)
    return out


def distance_urgency(x: npt.ArrayLike, eps: npt.ArrayLike) -> np.ndarray:
    """Distance urgency ``|x| - eps`` (the paper's SA(d) ranking), shape ``(M,)``.

    Args:
        x: Relative centre positions, ``(M, 3)`` or ``(3,)``.
        eps: Contact distance, scalar or ``(M,)``, ``>= 0``.
    """
    xa = as_vectors("x", x)
    return np.asarray(np.linalg.norm(xa, axis=1) - per_pair("eps", eps, xa.shape[0]))
