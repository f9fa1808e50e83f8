"""The compiled hashed uniform grid behind ``neighbors.candidate_pairs``.

Spheres are counting-sorted into cells by a hash that keeps neighbouring cells next to each other
in memory (rows of three adjacent buckets), then each sphere's row of neighbour cells is scanned:
O(N + K) time and memory (``neighbors`` states the guarantee and its proof).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

__all__ = [
    "MAX_MAGNITUDE",
    "ROUNDING_SLACK",
    "Geometry",
    "bounding_box",
    "bucket",
    "build_grid",
    "cell_of",
    "exclusive_prefix",
    "near",
    "scan_row",
    "scatter",
    "visit",
]


ROUNDING_SLACK = 1.0 + 2.0**-44
"""Relative slack of the pair test ``d2 <= s * s * ROUNDING_SLACK`` (covers float64 rounding)."""

# Squares of larger values could overflow to inf, where the test stops meaning anything.
MAX_MAGNITUDE = 1e150

Index = int | np.int64
Geometry = tuple[float, float, float, float, int, int, int, int, int, int, int, int]
"""``(lo_x, lo_y, lo_z, h, mask_x, mask_y, mask_z, shift_y, shift_z, wrap_x, wrap_y, wrap_z)``:
cell ``k_a = floor((x_a - lo_a) / h)``, bucket :func:`bucket`; an axis wraps if its largest
cell index exceeds its mask (the torus is then at least 4 cells wide on it)."""


@nb.njit(cache=True, inline="always")
def cell_of(x: float, y: float, z: float, geo: Geometry) -> tuple[np.int64, np.int64, np.int64]:
    h = geo[3]
    return (
        np.int64(math.floor((x - geo[0]) / h)),
        np.int64(math.floor((y - geo[1]) / h)),
        np.int64(math.floor((z - geo[2]) / h)),
    )


@nb.njit(cache=True, inline="always")
def bucket(kx: Index, ky: Index, kz: Index, geo: Geometry) -> np.int64:
    # The cell index wrapped onto a 2^bx x 2^by x 2^bz torus, x fastest. A locality-preserving
    # hash, unlike a mixing one: a row of neighbour cells is a run of adjacent buckets, and a
    # sweep through the spheres in bucket order reads start and the sorted arrays almost
    # sequentially (with a mixing hash the visit was ~3x slower at N = 1e5, noisy machine).
    return np.int64((kx & geo[4]) | ((ky & geo[5]) << geo[7]) | ((kz & geo[6]) << geo[8]))


@nb.njit(cache=True)
def build_grid(
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
        kx, ky, kz = cell_of(centers[i, 0], centers[i, 1], centers[i, 2], geo)
        start[bucket(kx, ky, kz, geo)] += 1
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
        kx, ky, kz = cell_of(x, y, z, geo)
        b = bucket(kx, ky, kz, geo)
        p = start[b] - 1
        start[b] = p
        sid[p] = i
        sxyz[p, 0] = x
        sxyz[p, 1] = y
        sxyz[p, 2] = z
        sr[p] = reach[i]


@nb.njit(cache=True, inline="always")
def near(
    xi: float, yi: float, zi: float, ri: float, xj: float, yj: float, zj: float, rj: float, m: float
) -> bool:
    # The contract of the module docstring, operation for operation.
    dx = xi - xj
    dy = yi - yj
    dz = zi - zj
    s = (ri + rj) + m
    return dx * dx + dy * dy + dz * dz <= s * s * ROUNDING_SLACK


@nb.njit(cache=True, inline="always")
def scan_row(
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
        b = bucket(xa, ny, nz, geo)
        return (b, b + xb - xa + 1, np.int64(1))
    b = bucket(kx - 1, ny, nz, geo)
    if ((kx - 1) & mx) + 2 == ((kx + 1) & mx):
        return (b, b + 3, np.int64(1))
    return (b, b + 3, np.int64(-1))


@nb.njit(cache=True)
def visit(
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
        kx, ky, kz = cell_of(x, y, z, geo)
        b = bucket(kx, ky, kz, geo)
        # Own row: the rest of the own bucket, then the cell at +x (the next bucket unless the
        # row ends there: at the grid's edge, or the torus seam).
        nr = 1
        ranges[0, 0] = p + 1
        if (kx & mx) != mx:
            ranges[0, 1] = start[b + 2]
        else:
            ranges[0, 1] = start[b + 1]
            if geo[9]:
                bb = bucket(kx + 1, ky, kz, geo)
                ranges[1, 0] = start[bb]
                ranges[1, 1] = start[bb + 1]
                nr = 2
        for r in range(4):
            ny = ky + 1 if r == 0 else ky + r - 2
            nz = kz if r == 0 else kz + 1
            first, stop, step = scan_row(kx, ny, nz, geo)
            if step == 1:
                ranges[nr, 0] = start[first]
                ranges[nr, 1] = start[stop]
                nr += 1
            else:
                for nx in range(kx - 1, kx + 2):
                    bb = bucket(nx, ny, nz, geo)
                    ranges[nr, 0] = start[bb]
                    ranges[nr, 1] = start[bb + 1]
                    nr += 1
        hits = 0
        for t in range(nr):
            for q in range(ranges[t, 0], ranges[t, 1]):
                if near(x, y, z, ri, sxyz[q, 0], sxyz[q, 1], sxyz[q, 2], sr[q], margin):
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
            if near(xi, yi, zi, ri, centers[j, 0], centers[j, 1], centers[j, 2], reach[j], margin):
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
def exclusive_prefix(a: np.ndarray) -> int:
    total = 0
    for i in range(a.size):
        c = a[i]
        a[i] = total
        total += c
    return total


@nb.njit(cache=True)
def scatter(end_b: np.ndarray, tmp: np.ndarray, cur_a: np.ndarray, out: np.ndarray) -> None:
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
def bounding_box(c: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> int:
    """Bounding box of the rows into ``lo``, ``hi``; the first bad row (NaN, inf, huge) or -1."""
    lo[:] = np.inf
    hi[:] = -np.inf
    for i in range(c.shape[0]):
        for a in range(3):
            x = c[i, a]
            # Written so that NaN fails it too.
            if not abs(x) <= MAX_MAGNITUDE:
                return i
            lo[a] = min(lo[a], x)
            hi[a] = max(hi[a], x)
    return -1
