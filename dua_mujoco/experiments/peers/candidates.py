"""Broadphase candidate pairs of spheres: sort-and-sweep and a uniform grid, vectorised numpy."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["BROADPHASES", "grid_candidates", "sweep_candidates"]


def _expand(start: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All ``(i, j)`` with ``start[i] <= j < end[i]``, vectorised (the repeat/arange trick)."""
    count = np.maximum(end - start, 0)
    total = int(count.sum())
    owner = np.repeat(np.arange(start.shape[0], dtype=np.int64), count)
    # Position of each output inside its owner's run, added to the owner's start.
    first = np.cumsum(count) - count
    offset = np.arange(total, dtype=np.int64) - np.repeat(first, count)
    return owner, np.repeat(start, count) + offset


def sweep_candidates(centers: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sort-and-sweep on one axis: pairs of spheres whose intervals overlap on that axis.

    The axis is the one of largest spread (fewest overlaps for isotropic boxes). O(N log N)
    for the sort plus the candidates.

    Args:
        centers: ``(n, 3)`` sphere centres.
        radii: ``(n,)`` (inflated) radii.

    Returns:
        ``(a, b)`` int64 sphere indices with ``a != b``, each unordered pair once.
    """
    axis = int(np.argmax(np.ptp(centers, axis=0))) if centers.shape[0] else 0
    lo = centers[:, axis] - radii
    hi = centers[:, axis] + radii
    order = np.argsort(lo, kind="stable")
    lo_s = lo[order]
    hi_s = hi[order]
    # In sorted order, j > i overlaps i iff lo_j <= hi_i: a contiguous run after i.
    end = np.searchsorted(lo_s, hi_s, side="right")
    start = np.arange(1, order.shape[0] + 1, dtype=np.int64)
    a, b = _expand(start, end.astype(np.int64))
    return order[a], order[b]


# Half of the 26 neighbour offsets: each unordered pair of cells is visited once.
_HALF_NEIGHBOURS = np.array(
    [
        (dx, dy, dz)
        for dx in (-1, 0, 1)
        for dy in (-1, 0, 1)
        for dz in (-1, 0, 1)
        if (dx, dy, dz) > (0, 0, 0)
    ],
    dtype=np.int64,
)


def grid_candidates(centers: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Uniform-grid broadphase: pairs of spheres in the same or adjacent cells.

    The cell edge is ``2 max(radii)``, so two overlapping spheres are always in the same or in
    adjacent cells. Spheres are sorted by cell key; each cell's neighbours are found with
    ``searchsorted``, all vectorised.

    Args:
        centers: ``(n, 3)`` sphere centres.
        radii: ``(n,)`` (inflated) radii.

    Returns:
        ``(a, b)`` int64 sphere indices with ``a != b``, each unordered pair once.
    """
    n = centers.shape[0]
    if n < 2:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty
    cell = 2.0 * float(radii.max())
    if not cell > 0:
        cell = 1.0
    low = centers.min(axis=0)
    idx = np.floor((centers - low) / cell).astype(np.int64)
    # One padding cell on each side so that neighbour offsets never wrap around.
    idx += 1
    dims = idx.max(axis=0) + 2
    strides = np.array([dims[1] * dims[2], dims[2], 1], dtype=np.int64)
    key = idx @ strides
    order = np.argsort(key, kind="stable")
    key_s = key[order]
    pos = np.arange(n, dtype=np.int64)
    # Same cell: the later members of the run.
    run_end = np.searchsorted(key_s, key_s, side="right")
    parts_a = []
    parts_b = []
    a, b = _expand(pos + 1, run_end.astype(np.int64))
    parts_a.append(a)
    parts_b.append(b)
    for off in _HALF_NEIGHBOURS:
        nb = key_s + int(off @ strides)
        lo = np.searchsorted(key_s, nb, side="left")
        hi = np.searchsorted(key_s, nb, side="right")
        a, b = _expand(lo.astype(np.int64), hi.astype(np.int64))
        parts_a.append(a)
        parts_b.append(b)
    a = np.concatenate(parts_a)
    b = np.concatenate(parts_b)
    return order[a], order[b]


BROADPHASES: dict[str, Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]] = {
    "sweep": sweep_candidates,
    "grid": grid_candidates,
}
