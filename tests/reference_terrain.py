"""Slow references for height fields held as terrain (docs/static-shapes.md, section 13), used
only by the tests.

Nothing here shares code with ``dua_mujoco/csrc/src/terrain.cc`` (no pyramid, no branch and
bound, no support functions of the kernel's):

* :func:`prism_tops` rebuilds MuJoCo's prisms the way ``mjc_ConvexHField`` walks them (its
  ``addPrismVert`` sliding window written out), so a wrong diagonal or a flipped row would show
  against MuJoCo's own contacts (``test_terrain.py``).
* :func:`point_distance` is the exact distance from a point to the union of the prisms: 0 inside
  one, else the least distance to the faces (two triangles, three quads), each by Ericson's
  closest point on a triangle. :func:`segment_distance` is the distance from a segment (a
  capsule's axis): per prism, the distance from a point moving along the segment to a convex set
  is convex in the segment's parameter, so a golden-section search per prism finds its minimum.
* :func:`first_touch` is the first time the reachable set of the bound model touches the
  terrain: the positions ``c + v t + e`` with ``|e| <= delta t + accel t^2 / 2`` (every one of
  which some feasible trajectory is at, at time ``t``) come within ``eps`` of the terrain at the
  first ``t`` with ``dist(c + v t) <= eps + delta t + accel t^2 / 2``. It is found on a dense
  grid of times and refined by bisection, so it is at or after the true first time: a kernel
  held to it (``tau <= first_touch``) is held to the truth, up to the grid's resolution.
* :func:`cell_bound` is the kernel's bound written over every cell (no pruning): the exhaustive
  minimum the branch and bound must find.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scalar_tau import tau_halfspace

from dua_mujoco import _core


def heights(size, nrow: int, ncol: int, data) -> np.ndarray:
    """``(nrow, ncol)`` heights, row ``r`` at ``y_r``: MuJoCo's ``data * size_z``."""
    return np.asarray(data, dtype=np.float64).reshape(nrow, ncol) * float(size[2])


def vertex(size, nrow: int, ncol: int, h: np.ndarray, r: int, c: int) -> tuple[float, float, float]:
    """Grid point ``(r, c)`` as MuJoCo's ``addPrismVert`` computes it."""
    dx = (2.0 * size[0]) / (ncol - 1)
    dy = (2.0 * size[1]) / (nrow - 1)
    return (dx * c - size[0], dy * r - size[1], float(h[r, c]))


def prism_tops(size, nrow: int, ncol: int, data) -> np.ndarray:
    """``(n, 3, 3)`` top triangles of every prism, in the height field's frame.

    ``mjc_ConvexHField`` keeps the last three vertices it added: for each row ``r`` it adds
    ``(r + 1, c0)``, ``(r, c0)``, then for each next column ``c`` the vertices ``(r + 1, c)`` and
    ``(r, c)``, each time testing the prism of the last three.
    """
    h = heights(size, nrow, ncol, data)
    tops = []
    for r in range(nrow - 1):
        window = [vertex(size, nrow, ncol, h, r + 1, 0), vertex(size, nrow, ncol, h, r, 0)]
        for c in range(1, ncol):
            for rr in (r + 1, r):
                window.append(vertex(size, nrow, ncol, h, rr, c))
                tops.append(window[-3:])
    return np.asarray(tops, dtype=np.float64)


def _closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray):
    """Closest points to ``p`` (``(n, 3)``, one per triangle) on triangles ``(a, b, c)`` (each
    ``(n, 3)``), by Ericson's Voronoi regions (Real-Time Collision Detection, 5.1.5)."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(1), (ac * ap).sum(1)
    bp = p - b
    d3, d4 = (ab * bp).sum(1), (ac * bp).sum(1)
    cp = p - c
    d5, d6 = (ab * cp).sum(1), (ac * cp).sum(1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    out = np.empty_like(a)
    done = np.zeros(a.shape[0], dtype=bool)

    def put(mask, value):
        m = mask & ~done
        out[m] = value[m]
        done[m] = True

    with np.errstate(divide="ignore", invalid="ignore"):
        put((d1 <= 0) & (d2 <= 0), a)
        put((d3 >= 0) & (d4 <= d3), b)
        put((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + (d1 / (d1 - d3))[:, None] * ab)
        put((d6 >= 0) & (d5 <= d6), c)
        put((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + (d2 / (d2 - d6))[:, None] * ac)
        e43, e56 = d4 - d3, d5 - d6
        put((va <= 0) & (e43 >= 0) & (e56 >= 0), b + (e43 / (e43 + e56))[:, None] * (c - b))
        den = 1.0 / (va + vb + vc)
        put(
            np.ones(a.shape[0], dtype=bool), a + ab * (vb * den)[:, None] + ac * (vc * den)[:, None]
        )
    return out


def prism_distances(p, tops: np.ndarray, base: float) -> np.ndarray:
    """``(n,)`` distances from ``p`` to each prism (0 inside); ``p`` one point ``(3,)`` or one
    point per prism ``(n, 3)``."""
    p = np.broadcast_to(np.asarray(p, dtype=np.float64), (tops.shape[0], 3))
    a, b, c = tops[:, 0], tops[:, 1], tops[:, 2]
    e, f = b - a, c - a
    det = e[:, 0] * f[:, 1] - e[:, 1] * f[:, 0]
    qx, qy = p[:, 0] - a[:, 0], p[:, 1] - a[:, 1]
    u = (qx * f[:, 1] - qy * f[:, 0]) / det
    w = (e[:, 0] * qy - e[:, 1] * qx) / det
    top = a[:, 2] + u * e[:, 2] + w * f[:, 2]
    inside = (u >= 0) & (w >= 0) & (u + w <= 1) & (p[:, 2] >= -base) & (p[:, 2] <= top)
    bottom = tops.copy()
    bottom[:, :, 2] = -base
    faces = [(a, b, c), (bottom[:, 0], bottom[:, 1], bottom[:, 2])]
    for i, j in ((0, 1), (1, 2), (2, 0)):
        faces.append((tops[:, i], tops[:, j], bottom[:, j]))
        faces.append((tops[:, i], bottom[:, j], bottom[:, i]))
    best = np.full(tops.shape[0], np.inf)
    for face in faces:
        q = _closest_on_triangles(p, *face)
        best = np.minimum(best, np.sqrt(((q - p) ** 2).sum(1)))
    return np.where(inside, 0.0, best)


def closest_point(p, tops: np.ndarray, base: float) -> np.ndarray:
    """A closest point of the union of the prisms to ``p`` (``p`` itself inside)."""
    p = np.asarray(p, dtype=np.float64)
    k = int(np.argmin(prism_distances(p, tops, base)))
    top = tops[k : k + 1]
    if prism_distances(p, top, base)[0] == 0.0:
        return p.copy()
    bottom = top.copy()
    bottom[:, :, 2] = -base
    faces = [(top[:, 0], top[:, 1], top[:, 2]), (bottom[:, 0], bottom[:, 1], bottom[:, 2])]
    for i, j in ((0, 1), (1, 2), (2, 0)):
        faces.append((top[:, i], top[:, j], bottom[:, j]))
        faces.append((top[:, i], bottom[:, j], bottom[:, i]))
    points = np.concatenate([_closest_on_triangles(p[None], *face) for face in faces])
    return points[int(np.argmin(((points - p) ** 2).sum(1)))]


def _box_distances(points: np.ndarray, tops: np.ndarray, base: float) -> np.ndarray:
    """``(k, n)`` distances from each point to each prism's bounding box: lower bounds of the
    prisms'."""
    lo = np.concatenate([tops[:, :, :2].min(axis=1), np.full((tops.shape[0], 1), -base)], axis=1)
    hi = tops.max(axis=1)
    p = points[:, None, :]
    return np.linalg.norm(np.maximum(np.maximum(lo - p, p - hi), 0.0), axis=2)


def distances(points, tops: np.ndarray, base: float) -> np.ndarray:
    """``(k,)`` distances from the points ``(k, 3)`` (height field frame) to the union of the
    prisms (0 inside).

    Each point is measured to the prism of its nearest bounding box, then to every prism whose
    box is no farther than that (a box's distance is a lower bound of its prism's, so the others
    cannot be nearer): two batched calls of :func:`prism_distances`."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    lower = _box_distances(pts, tops, base)
    first = np.argmin(lower, axis=1)
    best = prism_distances(pts, tops[first], base)
    k, j = np.nonzero(lower <= best[:, None])
    np.minimum.at(best, k, prism_distances(pts[k], tops[j], base))
    return best


def points_distance(points, tops: np.ndarray, base: float) -> float:
    """Least distance from the points ``(k, 3)`` to the union of the prisms."""
    return float(distances(points, tops, base).min())


def point_distance(p, tops: np.ndarray, base: float) -> float:
    """Distance from ``p`` (height field frame) to the union of the prisms (0 inside)."""
    return float(distances(np.asarray(p, dtype=np.float64)[None], tops, base)[0])


def segment_distance(a, b, tops: np.ndarray, base: float, iters: int = 80) -> float:
    """Distance from the segment ``[a, b]`` to the union of the prisms (golden section per prism,
    on a convex function: exact to ``0.618^iters`` of the segment)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    # Every point of the segment is within half its length of its middle: a prism whose
    # distance from the middle exceeds the nearest one's by more than the length is out.
    mid, half = 0.5 * (a + b), 0.5 * float(np.linalg.norm(b - a))
    around = prism_distances(mid, tops, base)
    tops = tops[around <= around.min() + 2.0 * half]
    n = tops.shape[0]
    lo, hi = np.zeros(n), np.ones(n)
    g = (math.sqrt(5.0) - 1.0) / 2.0

    def dist_at(s: np.ndarray) -> np.ndarray:
        return prism_distances(a + s[:, None] * (b - a), tops, base)

    x1, x2 = hi - g * (hi - lo), lo + g * (hi - lo)
    f1, f2 = dist_at(x1), dist_at(x2)
    for _ in range(iters):
        left = f1 <= f2
        hi = np.where(left, x2, hi)
        lo = np.where(left, lo, x1)
        nx1, nx2 = hi - g * (hi - lo), lo + g * (hi - lo)
        x1, x2 = nx1, nx2
        f1, f2 = dist_at(x1), dist_at(x2)
    ends = np.minimum(
        prism_distances(a, tops, base), prism_distances(b, tops, base)
    )  # the ends, should the minimum sit there
    return float(min(np.minimum(f1, f2).min(), ends.min()))


def first_touch(
    dist: Callable[[np.ndarray], np.ndarray],
    eps: float,
    accel: float,
    delta: float,
    t_max: float,
    samples: int = 4000,
) -> float:
    """First ``t`` in ``[0, t_max]`` with ``dist(t) <= eps + delta t + accel t^2 / 2``, on a grid
    of times (denser near 0) refined by bisection; ``inf`` if none on the grid. ``dist`` takes
    an array of times.

    The result is a time at which the inequality holds, so it is at or after the true first
    one; the grid's resolution (``t_max / samples`` at worst) is what a dip between two samples
    could hide.
    """

    def touches(t: np.ndarray) -> np.ndarray:
        return dist(t) <= eps + delta * t + 0.5 * accel * t * t

    if touches(np.zeros(1))[0]:
        return 0.0
    if not t_max > 0.0:
        return math.inf  # nothing on the grid
    grid = np.unique(
        np.concatenate(
            [np.geomspace(t_max * 1e-6, t_max, samples // 2), np.linspace(0.0, t_max, samples // 2)]
        )
    )
    hit = np.flatnonzero(touches(grid))
    if hit.size == 0:
        return math.inf
    lo, hi = float(grid[hit[0] - 1]), float(grid[hit[0]])
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if touches(np.array([mid]))[0]:
            hi = mid
        else:
            lo = mid
    return hi


def cell_bound(
    size,
    nrow: int,
    ncol: int,
    data,
    lo,
    hi,
    lowest: Callable[[np.ndarray], float],
    u,
    spin: float,
    eps: float,
    accel: float,
    delta: float,
) -> float:
    """The kernel's bound over every cell, in the height field's frame (no pyramid, no pruning).

    ``lo``, ``hi``: the object's box; ``lowest(n)``: its least ``n.a``; ``u``: its velocity.
    Per cell, the larger of the time to reach its rectangle and the smaller over its two
    triangles of the larger of the times to come down to the triangle's highest corner and to
    its plane; the least over the cells, and the larger of that and the time to come up to the
    base. Written over arrays of every cell (grids of 201 x 201 in a fraction of a second), with
    the roots of the kernel's ``tau_halfspace``.
    """
    h = heights(size, nrow, ncol, data)
    lo, hi, u = (np.asarray(x, dtype=np.float64) for x in (lo, hi, u))
    w = math.hypot(u[0], u[1]) + spin

    def roots(gap: np.ndarray, vn: np.ndarray | float) -> np.ndarray:
        gap = np.ascontiguousarray(gap, dtype=np.float64).reshape(-1)
        full = [np.ascontiguousarray(np.broadcast_to(x, gap.shape)) for x in (vn, accel, delta)]
        return np.asarray(_core.tau_halfspace_batch(gap, *full))

    # Grid points as MuJoCo's addPrismVert computes them (vertex()), cell (r, c) spanning
    # [x_c, x_{c+1}] x [y_r, y_{r+1}].
    xs = np.array([vertex(size, nrow, ncol, h, 0, c)[0] for c in range(ncol)])
    ys = np.array([vertex(size, nrow, ncol, h, r, 0)[1] for r in range(nrow)])
    x0, x1 = np.meshgrid(xs[:-1], ys[:-1])[0], np.meshgrid(xs[1:], ys[:-1])[0]
    y0, y1 = np.meshgrid(xs[:-1], ys[:-1])[1], np.meshgrid(xs[:-1], ys[1:])[1]
    gx = np.maximum(0.0, np.maximum(x0 - hi[0], lo[0] - x1))
    gy = np.maximum(0.0, np.maximum(y0 - hi[1], lo[1] - y1))
    reach = roots(np.hypot(gx, gy) - eps, -w)
    v00 = np.stack([x0, y0, h[:-1, :-1]], axis=-1).reshape(-1, 3)
    v01 = np.stack([x1, y0, h[:-1, 1:]], axis=-1).reshape(-1, 3)
    v10 = np.stack([x0, y1, h[1:, :-1]], axis=-1).reshape(-1, 3)
    v11 = np.stack([x1, y1, h[1:, 1:]], axis=-1).reshape(-1, 3)
    per = []
    for a, b, c3 in ((v10, v00, v11), (v00, v11, v01)):
        top_z = np.maximum(np.maximum(a[:, 2], b[:, 2]), c3[:, 2])
        down = roots(lo[2] - top_z - eps, u[2] - spin)
        n = np.cross(b - a, c3 - a)
        n = n / np.linalg.norm(n, axis=1)[:, None] * np.where(n[:, 2] > 0, 1.0, -1.0)[:, None]
        top = np.maximum(np.maximum(np.sum(n * a, 1), np.sum(n * b, 1)), np.sum(n * c3, 1))
        low = np.array([lowest(k) for k in n])
        plane = roots(low - top - eps, n @ u - spin)
        per.append(np.maximum(down, plane))
    best = float(np.min(np.maximum(reach, np.minimum(per[0], per[1]))))
    under = tau_halfspace(-float(size[3]) - eps - hi[2], -(u[2] + spin), accel, delta)
    return max(under, best)
