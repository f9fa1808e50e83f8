"""Pruned sphere pairs: the pairs whose reachable balls over a horizon can meet.

Motion model of sphere ``i``: centre ``c_i``, velocity ``v_i``, radius ``r_i``, a bound ``A_i`` on
the norm of the centre's acceleration, an optional bound ``delta_i`` on the error of the measured
velocity and an optional speed bound ``V_i``. :func:`reach` returns ``reach_i = r_i + R_i(T)`` with
``R_i(T) = min(|v_i| T + delta_i T + A_i T^2 / 2, V_i T)``; :func:`candidate_pairs` returns every
pair ``i < j`` with ``|c_i - c_j| <= reach_i + reach_j + margin`` and no other.

Guarantee: a pair that :func:`candidate_pairs` leaves out cannot come within ``r_i + r_j + margin``
(centre distance) at any time in ``[0, T]``, whatever its motion within the bounds.
Proof: the true velocity ``u_i(s)`` satisfies ``|u_i(0)| <= |v_i| + delta_i`` and
``|u_i(s) - u_i(0)| <= A_i s``, so ``|x_i(t) - c_i| <= (|v_i| + delta_i) t + A_i t^2 / 2``; a speed
bound gives ``|x_i(t) - c_i| <= V_i t`` as well, so ``|x_i(t) - c_i| <= R_i(t) <= R_i(T)`` since
every term is non-decreasing in ``t``. By the triangle inequality
``|x_i(t) - x_j(t)| >= |c_i - c_j| - R_i(T) - R_j(T) > r_i + r_j + margin`` for every left-out
pair. Floating point: the test is evaluated as ``d2 <= s * s * ROUNDING_SLACK`` with
``d2 = dx*dx + dy*dy + dz*dz`` and ``s = (reach_i + reach_j) + margin`` in float64 (this exact
expression is the contract; the tests compare against it). ``ROUNDING_SLACK = 1 + 2**-44`` exceeds
the at most ~12 ulp of relative error of ``d2`` and ``s * s``, so every pair meeting the test in
exact arithmetic is returned; the extra pairs lie within a relative ``3e-14`` of the boundary.

Algorithm: a uniform grid of cubic cells of edge ``h >= 2 rcut + margin`` (``rcut``: the largest
reach in the grid), so every pair to report lies in the same or adjacent cells. Cells map to
``2^b >= 2 N`` buckets by wrapping the cell index onto a power-of-two torus (x fastest): a
locality-preserving hash, so a row of three neighbour cells is a run of adjacent buckets, and
sweeping the spheres in bucket order reads memory almost sequentially (a mixing hash made every
probe a cache miss). If the grid has at most ``2^b`` cells with ``h`` up to twice the minimum,
the smallest such ``h`` is used and nothing wraps. Spheres are counting-sorted by bucket (no
comparison sort, no dict); each is tested against the rest of its bucket and the 13 cells after
its own in (z, y, x) order, five runs of buckets, so each pair is tested once. The ``k``
spheres of largest reach may be held out of the grid and tested against every sphere instead
(``k N`` tests), ``k`` minimising a cost model ``k N + 14 N (1 + occupancy)`` with the
occupancy estimated from the bounding box: one 2 m sphere among 1 cm ones then costs ``N``
tests instead of growing every cell 200 times (8e6 times the volume). Pairs are counted in a
first pass and written in a second into arrays allocated at their exact size; two counting sorts
(by ``j``, then stably by ``i``) order them. Time and memory are ``O(N + K)``, plus ``N k`` tests
for held-out spheres, and the tests in the grid are at most a constant times ``N + K`` unless
the extent of the centres exceeds ``2^31 h`` (cells are then grown to keep indices exact: a
cluster plus a far outlier). Cells are grown by ``1 + 2^-16`` beyond ``2 rcut + margin`` so
that a pair at distance ``<= s <=`` the edge (after rounding, ``< 1e-13`` relative) never lands
two cells apart: the rounding of ``floor((x - lo) / h)`` stays below ``2^-21`` cells with at
most ``2^31`` cells an axis. The grid is the native core's (``csrc/src/grid.cc``, which the
MuJoCo plugin runs too, called through ``dua_mujoco._core``; ``_core.grid_plan`` shows its
plan); its work arrays (~70 bytes per sphere plus 20 per pair) are native allocations, which
``tracemalloc`` does not see (the process's resident size does).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

import dua_mujoco._core as _core
from dua_mujoco.exceptions import (
    InvalidBoundError,
    InvalidInputError,
    NonFiniteStateError,
    ShapeError,
)

__all__ = ["ROUNDING_SLACK", "candidate_pairs", "reach"]


ROUNDING_SLACK = 1.0 + 2.0**-44
"""Relative slack of the pair test ``d2 <= s * s * ROUNDING_SLACK`` (covers float64 rounding)."""

# Squares of larger values could overflow to inf, where the test stops meaning anything.
MAX_MAGNITUDE = 1e150


def _as_1d(name: str, value: npt.ArrayLike, first: tuple[str, int] | None) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64)
    if a.ndim == 0:
        return a
    if a.ndim != 1:
        raise ShapeError(
            f"{name} has shape {a.shape}; expected a scalar or shape (N,), one entry per "
            "sphere. Pass one value per sphere or a single scalar for all."
        )
    if first is not None and a.shape[0] != first[1]:
        raise ShapeError(
            f"{name} has shape {a.shape} but {first[0]} has {first[1]} entries: every array "
            "argument has one entry per sphere. Pass arrays of the same length (or scalars)."
        )
    return a


def _check_values(
    name: str,
    a: np.ndarray,
    *,
    allow_inf: bool = False,
    error: type[InvalidInputError] = InvalidInputError,
) -> None:
    bad = np.isnan(a) | (a < 0) | (np.isinf(a) & (not allow_inf))
    if not bad.any():
        return
    if a.ndim == 0:
        where, value = name, float(a)
    else:
        idx = int(np.flatnonzero(bad)[0])
        where, value = f"{name}[{idx}]", float(a[idx])
    allowed = "finite or inf, and >= 0" if allow_inf else "finite and >= 0"
    raise error(f"{where} = {value!r} is invalid: it must be {allowed}. Fix the value passed.")


def reach(
    radius: npt.ArrayLike,
    speed_now: npt.ArrayLike,
    accel: npt.ArrayLike,
    horizon: float,
    *,
    vel_uncertainty: npt.ArrayLike = 0.0,
    speed_bound: npt.ArrayLike = np.inf,
) -> np.ndarray:
    """Radius plus the farthest a sphere's centre can travel within ``horizon``.

    ``reach_i = r_i + min(|v_i| T + delta_i T + A_i T^2 / 2, V_i T)`` (see the module docstring
    for why the centre stays within that distance of ``c_i`` over all of ``[0, T]``).

    Args:
        radius: ``(N,)`` or scalar sphere radii ``r_i`` (m), finite, ``>= 0``.
        speed_now: ``(N,)`` or scalar measured speeds ``|v_i|`` (m/s), finite, ``>= 0``.
        accel: ``(N,)`` or scalar bounds ``A_i`` on the centre's acceleration norm (m/s^2),
            finite, ``>= 0``.
        horizon: The horizon ``T`` (s), finite, ``>= 0``.
        vel_uncertainty: ``(N,)`` or scalar bound ``delta_i`` on ``|v_true - v_measured|``
            (m/s), finite, ``>= 0``.
        speed_bound: ``(N,)`` or scalar bounds ``V_i`` on the speed (m/s), ``>= 0``; ``inf``
            (the default) for none.

    Returns:
        ``(N,)`` float64 reaches; ``N`` is the length of the array arguments (``1`` if all are
        scalars).

    Raises:
        ShapeError: an argument is neither a scalar nor ``(N,)``, or the lengths differ.
        NonFiniteStateError: a speed is NaN, infinite or negative.
        InvalidBoundError: an acceleration, uncertainty or speed bound is NaN or negative
            (or infinite, except the speed bound).
        InvalidInputError: a radius or the horizon is NaN, infinite or negative, or the reach
            overflows.
    """
    args = {
        "radius": radius,
        "speed_now": speed_now,
        "accel": accel,
        "vel_uncertainty": vel_uncertainty,
        "speed_bound": speed_bound,
    }
    first: tuple[str, int] | None = None
    arrays: dict[str, np.ndarray] = {}
    for name, value in args.items():
        a = _as_1d(name, value, first)
        if a.ndim == 1 and first is None:
            first = (name, a.shape[0])
        arrays[name] = a
    n = None if first is None else first[1]
    T = np.asarray(horizon, dtype=np.float64)
    if T.ndim != 0:
        raise ShapeError(f"horizon has shape {T.shape}; expected a scalar (seconds).")
    _check_values("horizon", T)
    _check_values("radius", arrays["radius"])
    _check_values("speed_now", arrays["speed_now"], error=NonFiniteStateError)
    _check_values("accel", arrays["accel"], error=InvalidBoundError)
    _check_values("vel_uncertainty", arrays["vel_uncertainty"], error=InvalidBoundError)
    _check_values("speed_bound", arrays["speed_bound"], allow_inf=True, error=InvalidBoundError)
    shape = (1 if n is None else n,)
    r, s, A, d, V = (
        np.ascontiguousarray(np.broadcast_to(arrays[k], shape))
        for k in ("radius", "speed_now", "accel", "vel_uncertainty", "speed_bound")
    )
    # The native core's kernel: the MuJoCo predictor renews reaches with it inside its step.
    out = np.asarray(_core.reaches(r, s, A, d, V, float(T)))
    if not np.isfinite(out).all():
        idx = int(np.flatnonzero(~np.isfinite(out))[0])
        raise InvalidInputError(
            f"reach[{idx}] overflowed to {out[idx]!r}: the horizon or bounds are too large to "
            "bound anything. Use a shorter horizon."
        )
    return out


def candidate_pairs(
    centers: npt.ArrayLike, reach: npt.ArrayLike, *, margin: float = 0.0
) -> np.ndarray:
    """Every pair ``i < j`` whose reachable balls come within ``margin`` of each other.

    Exactly the pairs with ``|c_i - c_j| <= reach_i + reach_j + margin``, evaluated as the module
    docstring states (a relative ``3e-14`` of slack for rounding, never less than the exact set).

    Args:
        centers: ``(N, 3)`` sphere centres (m), finite, magnitude below ``1e150``.
        reach: ``(N,)`` reaches (m), finite, ``>= 0``, below ``1e150``; usually :func:`reach`.
        margin: Extra distance (m) under which two spheres count as touching, finite, ``>= 0``.

    Returns:
        ``(K, 2)`` int64 array of pairs ``(i, j)``, ``i < j``, sorted lexicographically;
        ``(0, 2)`` when there are none.

    Raises:
        ShapeError: ``centers`` is not ``(N, 3)`` or ``reach`` not ``(N,)``.
        NonFiniteStateError: a centre is NaN or infinite.
        InvalidInputError: a reach or the margin is NaN, infinite or negative, or a value is
            above ``1e150``.
    """
    c = np.asarray(centers, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] != 3:
        raise ShapeError(f"centers has shape {c.shape}; expected (N, 3), one row per sphere.")
    n = c.shape[0]
    if n >= 2**31:
        raise InvalidInputError(
            f"{n} spheres: ids are stored as int32, so at most 2^31 - 1. Split the scene."
        )
    r = np.asarray(reach, dtype=np.float64)
    if r.shape != (n,):
        raise ShapeError(
            f"reach has shape {r.shape}; expected ({n},), one entry per row of centers."
        )
    m = np.asarray(margin, dtype=np.float64)
    if m.ndim != 0:
        raise ShapeError(f"margin has shape {m.shape}; expected a scalar (m).")
    _check_values("margin", m)
    _check_values("reach", r)
    c = np.ascontiguousarray(c)
    r = np.ascontiguousarray(r)
    bad = ~(np.abs(c) <= MAX_MAGNITUDE).all(axis=1)  # NaN fails the comparison too
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        if not np.isfinite(c[row]).all():
            raise NonFiniteStateError(
                f"centers[{row}] = {c[row].tolist()} is not finite: the state diverged or was "
                "not computed. Pass finite centres."
            )
        raise InvalidInputError(
            f"centers[{row}] = {c[row].tolist()} exceeds {MAX_MAGNITUDE:g} in magnitude: "
            "squared distances would overflow. Rescale the units."
        )
    for name, a in (("reach", r), ("margin", m)):
        big = a > MAX_MAGNITUDE
        if big.any():
            where = name if a.ndim == 0 else f"{name}[{int(np.flatnonzero(big)[0])}]"
            raise InvalidInputError(
                f"{where} exceeds {MAX_MAGNITUDE:g}: its square would overflow. Rescale the units."
            )
    return np.asarray(_core.candidate_pairs(c, r, float(m)))
