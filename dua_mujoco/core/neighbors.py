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
cluster plus a far outlier). Every work array is a numpy allocation made here (the compiled
kernels allocate nothing), so ``tracemalloc`` sees the whole footprint (~70 bytes per sphere
plus 20 per pair).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import numpy.typing as npt

from dua_mujoco.exceptions import (
    InvalidBoundError,
    InvalidInputError,
    NonFiniteStateError,
    ShapeError,
)

__all__ = ["ROUNDING_SLACK", "candidate_pairs", "reach"]

ROUNDING_SLACK = 1.0 + 2.0**-44
"""Relative slack of the pair test ``d2 <= s * s * ROUNDING_SLACK`` (covers float64 rounding)."""

# Cells are grown by this factor so that a pair at distance <= s <= cell edge (after rounding of
# d2, s and the slack, all < 1e-13 relative) can never land two cells apart: the rounding of
# floor((x - lo) / h) is below 2^-21 cells as long as there are at most _MAX_CELLS cells an axis.
_GRID_GROW = 1.0 + 2.0**-16
_MAX_CELLS = 2.0**31
# A grid that would need more buckets than the budget may use cells up to this factor larger
# (in _GROW_STEPS geometric steps) instead of wrapping: bucket = cell then, no aliased entries
# to scan. Growing costs at most _GROW_MAX^3 = 8 times the candidates of the same sphere.
_GROW_MAX = 2.0
_GROW_STEPS = 6
# Squares of larger values could overflow to inf, where the test stops meaning anything.
_MAX_MAGNITUDE = 1e150
# Held-out (largest-reach) spheres considered by the cost model; each costs N tests.
_MAX_HELD_OUT = 256
# Cost of visiting one sphere's 14 cells relative to one pair test (a hash lookup each).
_CELL_COST = 14.0


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
    t = float(T)
    r, s, A = arrays["radius"], arrays["speed_now"], arrays["accel"]
    d, V = arrays["vel_uncertainty"], arrays["speed_bound"]
    free = (s + d) * t + 0.5 * A * (t * t)
    # inf * 0 is NaN: with no speed bound (or T = 0) the free-motion bound is the answer.
    capped = np.where(np.isinf(V), free, np.minimum(free, np.where(np.isinf(V), 0.0, V) * t))
    out = np.broadcast_to(r + capped, (1 if n is None else n,)).astype(np.float64)
    if not np.isfinite(out).all():
        idx = int(np.flatnonzero(~np.isfinite(out))[0])
        raise InvalidInputError(
            f"reach[{idx}] overflowed to {out[idx]!r}: the horizon or bounds are too large to "
            "bound anything. Use a shorter horizon."
        )
    return out


Index = int | np.int64
Geometry = tuple[float, float, float, float, int, int, int, int, int, int, int, int]
"""``(lo_x, lo_y, lo_z, h, mask_x, mask_y, mask_z, shift_y, shift_z, wrap_x, wrap_y, wrap_z)``:
cell ``k_a = floor((x_a - lo_a) / h)``, bucket :func:`_bucket`; an axis wraps if its largest
cell index exceeds its mask (the torus is then at least 4 cells wide on it)."""


@nb.njit(cache=True, inline="always")
def _cell(x: float, y: float, z: float, geo: Geometry) -> tuple[np.int64, np.int64, np.int64]:
    h = geo[3]
    return (
        np.int64(math.floor((x - geo[0]) / h)),
        np.int64(math.floor((y - geo[1]) / h)),
        np.int64(math.floor((z - geo[2]) / h)),
    )


@nb.njit(cache=True, inline="always")
def _bucket(kx: Index, ky: Index, kz: Index, geo: Geometry) -> np.int64:
    # The cell index wrapped onto a 2^bx x 2^by x 2^bz torus, x fastest. A locality-preserving
    # hash, unlike a mixing one: a row of neighbour cells is a run of adjacent buckets, and a
    # sweep through the spheres in bucket order reads start and the sorted arrays almost
    # sequentially (with a mixing hash the visit was ~3x slower at N = 1e5, noisy machine).
    return np.int64((kx & geo[4]) | ((ky & geo[5]) << geo[7]) | ((kz & geo[6]) << geo[8]))


@nb.njit(cache=True)
def _build_grid(
    centers: np.ndarray,
    reach: np.ndarray,
    ids: np.ndarray,
    geo: Geometry,
    start: np.ndarray,
    sid: np.ndarray,
    sxyz: np.ndarray,
    sr: np.ndarray,
) -> None:
    """Counting sort of the grid spheres by bucket: bucket ``b`` is ``start[b]:start[b + 1]``."""
    n = ids.size
    nbucket = start.size - 1
    start[:] = 0
    for t in range(n):
        i = ids[t]
        kx, ky, kz = _cell(centers[i, 0], centers[i, 1], centers[i, 2], geo)
        start[_bucket(kx, ky, kz, geo)] += 1
    for u in range(1, nbucket):
        start[u] += start[u - 1]
    start[nbucket] = n
    # start[b] is now the end of bucket b; placing backwards leaves it at the bucket's start (no
    # cursor array needed) and keeps each bucket in id order. The bucket is recomputed rather
    # than stored: the same float expression gives the same cell.
    for t in range(n - 1, -1, -1):
        i = ids[t]
        x = centers[i, 0]
        y = centers[i, 1]
        z = centers[i, 2]
        kx, ky, kz = _cell(x, y, z, geo)
        b = _bucket(kx, ky, kz, geo)
        p = start[b] - 1
        start[b] = p
        sid[p] = i
        sxyz[p, 0] = x
        sxyz[p, 1] = y
        sxyz[p, 2] = z
        sr[p] = reach[i]


@nb.njit(cache=True, inline="always")
def _near(
    xi: float, yi: float, zi: float, ri: float, xj: float, yj: float, zj: float, rj: float, m: float
) -> bool:
    # The contract of the module docstring, operation for operation.
    dx = xi - xj
    dy = yi - yj
    dz = zi - zj
    s = (ri + rj) + m
    return dx * dx + dy * dy + dz * dz <= s * s * ROUNDING_SLACK


@nb.njit(cache=True, inline="always")
def _row(
    kx: np.int64, ny: np.int64, nz: np.int64, geo: Geometry
) -> tuple[np.int64, np.int64, np.int64]:
    """Buckets ``first:stop`` holding cells ``kx - 1 .. kx + 1`` of row ``(ny, nz)``, and a flag.

    Returns ``(first, stop, 1)`` for one run of adjacent buckets: clipped to the grid on an
    axis that does not wrap (no sphere lies outside, and a clipped index must not wrap onto
    another row), empty if the row is outside. Returns flag ``-1`` when a wrapped x axis puts
    the torus seam inside the row: the caller then looks up the three cells' buckets one by one.
    """
    mx = geo[4]
    empty = (np.int64(0), np.int64(0), np.int64(1))
    if not geo[10] and (ny < 0 or ny > geo[5]):
        return empty
    if not geo[11] and nz > geo[6]:
        return empty
    if not geo[9]:
        xa = kx - 1 if kx > 0 else kx
        xb = kx + 1 if kx < mx else kx
        b = _bucket(xa, ny, nz, geo)
        return (b, b + xb - xa + 1, np.int64(1))
    b = _bucket(kx - 1, ny, nz, geo)
    if ((kx - 1) & mx) + 2 == ((kx + 1) & mx):
        return (b, b + 3, np.int64(1))
    return (b, b + 3, np.int64(-1))


@nb.njit(cache=True)
def _visit(
    start: np.ndarray,
    sid: np.ndarray,
    sxyz: np.ndarray,
    sr: np.ndarray,
    geo: Geometry,
    margin: float,
    centers: np.ndarray,
    reach: np.ndarray,
    held: np.ndarray,
    is_held: np.ndarray,
    fill: bool,
    found: np.ndarray,
    cnt_a: np.ndarray,
    cnt_b: np.ndarray,
    tmp: np.ndarray,
    ranges: np.ndarray,
) -> None:
    """Test every candidate pair once; count (``fill=False``) or write (``fill=True``) the hits.

    A grid sphere is tested against the later members of its own bucket and the 13 cells
    ``(dx, dy, dz)`` with ``(dz, dy, dx)`` lexicographically after ``(0, 0, 0)``: every pair of
    adjacent cells from exactly one side. dx varies fastest, as in the bucket map, so the cells
    form five rows of adjacent buckets, each read as one range (``ranges``, ``(16, 2)``, holds a
    sphere's ranges). The count pass stores each sphere's hits in ``found``; the fill pass skips
    the spheres without any (most of them at the densities the predictor is meant for).

    No cell check: an entry of an aliased cell is at least 3 cells away (the torus is >= 4
    wide), so its distance exceeds 2 h > s and the exact test rejects it; and the buckets of the
    27 neighbour cells are distinct, so no true neighbour is scanned twice. The scan is written
    out here rather than in a helper taking arrays: numba's reference counting of arrays passed
    to inlined helpers tripled the cost.
    """
    n = sid.size
    mx = geo[4]
    for p in range(n):
        if fill and found[p] == 0:
            continue
        x = sxyz[p, 0]
        y = sxyz[p, 1]
        z = sxyz[p, 2]
        ri = sr[p]
        i = sid[p]
        kx, ky, kz = _cell(x, y, z, geo)
        b = _bucket(kx, ky, kz, geo)
        # Own row: the rest of the own bucket, then the cell at +x (the next bucket unless the
        # row ends there: at the grid's edge, or the torus seam).
        nr = 1
        ranges[0, 0] = p + 1
        if (kx & mx) != mx:
            ranges[0, 1] = start[b + 2]
        else:
            ranges[0, 1] = start[b + 1]
            if geo[9]:
                bb = _bucket(kx + 1, ky, kz, geo)
                ranges[1, 0] = start[bb]
                ranges[1, 1] = start[bb + 1]
                nr = 2
        for r in range(4):
            ny = ky + 1 if r == 0 else ky + r - 2
            nz = kz if r == 0 else kz + 1
            first, stop, step = _row(kx, ny, nz, geo)
            if step == 1:
                ranges[nr, 0] = start[first]
                ranges[nr, 1] = start[stop]
                nr += 1
            else:
                for nx in range(kx - 1, kx + 2):
                    bb = _bucket(nx, ny, nz, geo)
                    ranges[nr, 0] = start[bb]
                    ranges[nr, 1] = start[bb + 1]
                    nr += 1
        hits = 0
        for t in range(nr):
            for q in range(ranges[t, 0], ranges[t, 1]):
                if _near(x, y, z, ri, sxyz[q, 0], sxyz[q, 1], sxyz[q, 2], sr[q], margin):
                    hits += 1
                    j = sid[q]
                    a, c = (i, j) if i < j else (j, i)
                    # Count: pairs per smaller id (cnt_a) and per larger id (cnt_b). Fill:
                    # cnt_b is each larger id's cursor; the smaller id goes there (first
                    # counting sort, by the larger id).
                    if fill:
                        w = cnt_b[c]
                        tmp[w] = a
                        cnt_b[c] = w + 1
                    else:
                        cnt_a[a] += 1
                        cnt_b[c] += 1
        found[p] = hits
    # Held-out spheres against everyone; a pair of two held-out spheres from the smaller id.
    N = reach.size
    for t in range(held.size):
        if fill and found[n + t] == 0:
            continue
        i = held[t]
        xi = centers[i, 0]
        yi = centers[i, 1]
        zi = centers[i, 2]
        ri = reach[i]
        hits = 0
        # Only j > i, or j < i not held out (that pair is not found from j's side).
        for j in range(N):
            if j == i or (is_held[j] and j < i):
                continue
            if _near(xi, yi, zi, ri, centers[j, 0], centers[j, 1], centers[j, 2], reach[j], margin):
                hits += 1
                a, c = (i, j) if i < j else (j, i)
                if fill:
                    w = cnt_b[c]
                    tmp[w] = a
                    cnt_b[c] = w + 1
                else:
                    cnt_a[a] += 1
                    cnt_b[c] += 1
        found[n + t] = hits


@nb.njit(cache=True)
def _exclusive_prefix(a: np.ndarray) -> int:
    total = 0
    for i in range(a.size):
        c = a[i]
        a[i] = total
        total += c
    return total


@nb.njit(cache=True)
def _scatter(end_b: np.ndarray, tmp: np.ndarray, cur_a: np.ndarray, out: np.ndarray) -> None:
    # Second counting sort, stable, by the smaller id: walking j upwards leaves each i's row
    # block sorted by j. end_b[j] is the end of j's block in tmp (the fill pass's cursor).
    lo = 0
    for j in range(end_b.size):
        hi = end_b[j]
        for q in range(lo, hi):
            i = tmp[q]
            p = cur_a[i]
            out[p, 0] = i
            out[p, 1] = j
            cur_a[i] = p + 1
        lo = hi


@nb.njit(cache=True)
def _box(c: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> int:
    """Bounding box of the rows into ``lo``, ``hi``; the first bad row (NaN, inf, huge) or -1."""
    lo[:] = np.inf
    hi[:] = -np.inf
    for i in range(c.shape[0]):
        for a in range(3):
            x = c[i, a]
            # Written so that NaN fails it too.
            if not abs(x) <= _MAX_MAGNITUDE:
                return i
            lo[a] = min(lo[a], x)
            hi[a] = max(hi[a], x)
    return -1


def _cell_edge(rcut: np.ndarray | float, margin: float, extent: float) -> np.ndarray:
    # >= extent / _MAX_CELLS keeps the cell indices small enough for the rounding argument; a
    # zero edge (all reaches and the margin zero, all centres equal) becomes 1 m, any size works.
    h = np.maximum((2.0 * np.asarray(rcut) + margin) * _GRID_GROW, extent / _MAX_CELLS)
    return np.where(h > 0.0, h, 1.0)


def _geometry(lo: np.ndarray, extent: np.ndarray, h_min: float, n: int) -> tuple[Geometry, int]:
    """Cell edge and bucket map (:data:`Geometry`) and the number of buckets.

    The budget is ``2^b >= 2 n`` buckets. If the grid of cells of edge up to ``_GROW_MAX h_min``
    fits, the smallest such edge is used and bucket = cell; otherwise the edge is
    ``_GROW_MAX h_min`` and the longest axes wrap onto a torus.
    """
    # >= 6 bits: a wrapped axis then keeps >= 2 bits (4 cells), as _visit's scan without cell
    # checks needs.
    budget = max(6, int(n).bit_length() + 1)
    for step in range(_GROW_STEPS + 1):
        h = h_min * _GROW_MAX ** (step / _GROW_STEPS)
        # Bits of the largest cell index on each axis (floor(extent / h) < 2^31 by _cell_edge).
        # extent = max - lo in float64 is the very expression the kernels floor for the max.
        need = [math.floor(e / h).bit_length() for e in extent]
        if sum(need) <= budget:
            break
    bits = list(need)
    while sum(bits) > budget:
        # Wrap the longest axis first, so aliased cells are as far apart as the budget allows.
        bits[bits.index(max(bits))] -= 1
    bx, by, bz = bits
    wraps = [int(b < w) for b, w in zip(bits, need, strict=True)]
    geo = (
        float(lo[0]),
        float(lo[1]),
        float(lo[2]),
        h,
        (1 << bx) - 1,
        (1 << by) - 1,
        (1 << bz) - 1,
        bx,
        bx + by,
        wraps[0],
        wraps[1],
        wraps[2],
    )
    return geo, 1 << (bx + by + bz)


def _hold_out(
    centers: np.ndarray, reach: np.ndarray, margin: float, extent: np.ndarray
) -> tuple[np.ndarray, float]:
    """Ids held out of the grid and the grid's largest reach (cost model of the module docs)."""
    n = reach.shape[0]
    kmax = min(n - 1, _MAX_HELD_OUT)
    if kmax <= 0:
        return np.empty(0, dtype=np.int64), float(reach.max()) if n else 0.0
    part = np.argpartition(reach, n - kmax - 1)[n - kmax - 1 :]
    top = part[np.argsort(-reach[part], kind="stable")]
    h = _cell_edge(reach[top], margin, float(extent.max()))
    vol = np.prod(np.maximum(extent[None, :], h[:, None]), axis=1)
    occupancy = np.minimum(float(n), n * h**3 / vol)
    k = np.arange(kmax + 1, dtype=np.float64)
    cost = k * n + _CELL_COST * (n - k) * (1.0 + occupancy)
    best = int(np.argmin(cost))
    return np.sort(top[:best]).astype(np.int64), float(reach[top[best]])


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
    # One compiled pass: numpy's axis-0 reductions of an (N, 3) array took 7 ms at N = 1e5.
    lo = np.empty(3)
    hi = np.empty(3)
    row = _box(c, lo, hi)
    if row >= 0:
        if not np.isfinite(c[row]).all():
            raise NonFiniteStateError(
                f"centers[{row}] = {c[row].tolist()} is not finite: the state diverged or was "
                "not computed. Pass finite centres."
            )
        raise InvalidInputError(
            f"centers[{row}] = {c[row].tolist()} exceeds {_MAX_MAGNITUDE:g} in magnitude: "
            "squared distances would overflow. Rescale the units."
        )
    for name, a in (("reach", r), ("margin", m)):
        big = a > _MAX_MAGNITUDE
        if big.any():
            where = name if a.ndim == 0 else f"{name}[{int(np.flatnonzero(big)[0])}]"
            raise InvalidInputError(
                f"{where} exceeds {_MAX_MAGNITUDE:g}: its square would overflow. Rescale the units."
            )
    if n < 2:
        return np.empty((0, 2), dtype=np.int64)
    extent = hi - lo
    held, rcut = _hold_out(c, r, float(m), extent)
    is_held = np.zeros(n, dtype=np.bool_)
    is_held[held] = True
    grid_ids = np.flatnonzero(~is_held).astype(np.int64)
    ng = grid_ids.size
    h_min = float(_cell_edge(rcut, float(m), float(extent.max())))
    geo, nbucket = _geometry(lo, extent, h_min, ng)
    # int32 ids and bucket starts: half the cache footprint of the random accesses (N < 2^31).
    start = np.empty(nbucket + 1, dtype=np.int32)
    sid = np.empty(ng, dtype=np.int32)
    sxyz = np.empty((ng, 3), dtype=np.float64)
    sr = np.empty(ng, dtype=np.float64)
    _build_grid(c, r, grid_ids, geo, start, sid, sxyz, sr)
    del grid_ids
    cnt_a = np.zeros(n, dtype=np.int64)
    cnt_b = np.zeros(n, dtype=np.int64)
    tmp = np.empty(0, dtype=np.int32)
    found = np.empty(ng + held.size, dtype=np.int32)
    ranges = np.empty((16, 2), dtype=np.int64)
    args = (start, sid, sxyz, sr, geo, float(m), c, r, held, is_held)
    _visit(*args, False, found, cnt_a, cnt_b, tmp, ranges)
    k = _exclusive_prefix(cnt_a)
    _exclusive_prefix(cnt_b)
    tmp = np.empty(k, dtype=np.int32)
    _visit(*args, True, found, cnt_a, cnt_b, tmp, ranges)
    del args, start, sid, sxyz, sr, found
    out = np.empty((k, 2), dtype=np.int64)
    _scatter(cnt_b, tmp, cnt_a, out)
    return out
