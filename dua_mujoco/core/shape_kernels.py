"""Compiled kernels of the static-shape urgency (proof in docs/static-shapes.md).

Support functions, closest points and ``tau_static`` of a moving sphere against one packed
shape record; the record layout, packing, validation and the vectorised front are in
``dua_mujoco.core.shapes``, which re-exports everything public here.
"""

from __future__ import annotations

import enum
import math

import numba as nb

from dua_mujoco.core.urgency import tau_halfspace

__all__ = [
    "SHAPE_KIND",
    "SHAPE_MAT",
    "SHAPE_NCOL",
    "SHAPE_POS",
    "SHAPE_SIZE",
    "ShapeKind",
    "closest_point",
    "static_batch",
    "static_gap",
    "support",
    "support_local",
    "tau_static",
]


class ShapeKind(enum.IntEnum):
    """Static shape types; the values are MuJoCo's ``mjtGeom`` codes."""

    SPHERE = 2
    CAPSULE = 3
    ELLIPSOID = 4
    CYLINDER = 5
    BOX = 6
    MESH_BOX = 7  # a mesh, held as the box geom_aabb around its convex hull


SHAPE_KIND = 0
SHAPE_SIZE = 1
SHAPE_POS = 4
SHAPE_MAT = 7
SHAPE_NCOL = 16

# Plain ints for the kernels (numba folds module-level ints into constants).
_SPHERE = 2
_CAPSULE = 3
_ELLIPSOID = 4
_CYLINDER = 5
_BOX = 6
_MESH_BOX = 7

# The computed gap n.(c - p) - h_local(R^T n) - eps carries a rounding error of a few units of
# 2**-53 times |c| + |p| + h_local + eps (three-term dot products, the norm of n, sums of
# products); 1e-14 is ~45 units. Subtracting it makes the gap handed to tau_halfspace a lower
# bound of the exact one for the float n actually used (docs/static-shapes.md, "Rounding").
_GAP_SLACK = 1e-14
# n.v is off by a few units times |v| for the same reasons; tau_halfspace treats it as extra
# velocity uncertainty, which is exactly what a bounded error of the normal velocity is.
_VEL_SLACK = 1e-14
# Newton iterations of the ellipsoid's closest-point root (monotone, so any count is safe).
_ELLIPSOID_ITER = 60


@nb.njit(cache=True, inline="always")
def support_local(kind, s0, s1, s2, m0, m1, m2):  # pragma: no cover - jitted
    """h of the shape in its own frame, in direction m (any length: every form is homogeneous).

    ``kind`` is a ``ShapeKind`` code and ``s0, s1, s2`` its sizes (MuJoCo's ``geom_size``; a
    ``MESH_BOX``'s half-sizes). Scalars in and out: no array view, so callers in hot loops pay
    no reference counting."""
    if kind == _SPHERE:
        return s0 * math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
    if kind == _CAPSULE:
        return abs(m2) * s1 + s0 * math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
    if kind == _CYLINDER:
        # r |m_xy| rather than r sqrt(1 - m_z^2): no cancellation, and exact for |m| != 1.
        return abs(m2) * s1 + s0 * math.hypot(m0, m1)
    if kind == _ELLIPSOID:
        return math.sqrt((s0 * m0) ** 2 + (s1 * m1) ** 2 + (s2 * m2) ** 2)
    # _BOX and _MESH_BOX (a mesh's hull lies in its box, so this bounds the hull's support).
    return abs(m0) * s0 + abs(m1) * s1 + abs(m2) * s2


@nb.njit(cache=True, inline="always")
def _ellipsoid_t(e0, e1, e2, y0, y1, y2):  # pragma: no cover - jitted
    """Root t > 0 of F(t) = sum (e_i y_i / (t + e_i^2))^2 - 1, for y outside the ellipsoid.

    F is convex and decreasing on t >= 0, so Newton's method started below the root climbs to it
    monotonically and never overshoots. The start uses |y| e_min / (t + e_max^2) <= each term's
    root bound: F(t) > 0 for t < e_min |y| - e_max^2.
    """
    emin = min(e0, e1, e2)
    emax = max(e0, e1, e2)
    ny = math.sqrt(y0 * y0 + y1 * y1 + y2 * y2)
    t = max(0.0, emin * ny - emax * emax)
    for _ in range(_ELLIPSOID_ITER):
        q0 = e0 * y0 / (t + e0 * e0)
        q1 = e1 * y1 / (t + e1 * e1)
        q2 = e2 * y2 / (t + e2 * e2)
        f = q0 * q0 + q1 * q1 + q2 * q2 - 1.0
        if f <= 0.0:
            break
        df = -2.0 * (q0 * q0 / (t + e0 * e0) + q1 * q1 / (t + e1 * e1) + q2 * q2 / (t + e2 * e2))
        step = -f / df
        if step <= 1e-16 * (t + emin * emin):
            break
        t += step
    return t


@nb.njit(cache=True, inline="always")
def _closest_local(kind, s0, s1, s2, d0, d1, d2):  # pragma: no cover - jitted
    """Closest point q of the shape to d (local frame) and an outward direction m at it.

    m is along d - q when d is outside; inside (q = d) it points out of the nearest face, or
    anywhere sensible: every direction gives gap <= -eps there, so the choice only has to exist.
    Returns (q0, q1, q2, m0, m1, m2), m not normalised.
    """
    if kind == _SPHERE:
        nd = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if nd > s0:
            k = s0 / nd
            return d0 * k, d1 * k, d2 * k, d0, d1, d2
        if nd > 0.0:
            return d0, d1, d2, d0, d1, d2
        return d0, d1, d2, 0.0, 0.0, 1.0
    if kind == _CAPSULE:
        zc = min(max(d2, -s1), s1)
        w2 = d2 - zc
        nw = math.sqrt(d0 * d0 + d1 * d1 + w2 * w2)
        if nw > s0:
            k = s0 / nw
            return d0 * k, d1 * k, zc + w2 * k, d0, d1, w2
        if nw > 0.0:
            return d0, d1, d2, d0, d1, w2
        return d0, d1, d2, 1.0, 0.0, 0.0
    if kind == _CYLINDER:
        rho = math.hypot(d0, d1)
        zc = min(max(d2, -s1), s1)
        if rho > s0:
            k = s0 / rho
            q0 = d0 * k
            q1 = d1 * k
        else:
            q0 = d0
            q1 = d1
        if rho > s0 or abs(d2) > s1:
            return q0, q1, zc, d0 - q0, d1 - q1, d2 - zc
        # Inside: leave through the nearer of the side wall and the cap.
        if s0 - rho <= s1 - abs(d2):
            if rho > 0.0:
                return d0, d1, d2, d0, d1, 0.0
            return d0, d1, d2, 1.0, 0.0, 0.0
        return d0, d1, d2, 0.0, 0.0, 1.0 if d2 >= 0.0 else -1.0
    if kind == _ELLIPSOID:
        y0 = abs(d0)
        y1 = abs(d1)
        y2 = abs(d2)
        if (y0 / s0) ** 2 + (y1 / s1) ** 2 + (y2 / s2) ** 2 > 1.0:
            t = _ellipsoid_t(s0, s1, s2, y0, y1, y2)
            # q_i = e_i^2 d_i / (t + e_i^2) and d - q = t d_i / (t + e_i^2): the normal is taken
            # in that closed form, free of the cancellation of d - q near the surface.
            k0 = 1.0 / (t + s0 * s0)
            k1 = 1.0 / (t + s1 * s1)
            k2 = 1.0 / (t + s2 * s2)
            return (
                s0 * s0 * d0 * k0,
                s1 * s1 * d1 * k1,
                s2 * s2 * d2 * k2,
                d0 * k0,
                d1 * k1,
                d2 * k2,
            )
        m0 = d0 / (s0 * s0)
        m1 = d1 / (s1 * s1)
        m2 = d2 / (s2 * s2)
        if m0 == 0.0 and m1 == 0.0 and m2 == 0.0:
            # The centre: leave along the shortest semi-axis.
            if s0 <= s1 and s0 <= s2:
                return d0, d1, d2, 1.0, 0.0, 0.0
            if s1 <= s2:
                return d0, d1, d2, 0.0, 1.0, 0.0
            return d0, d1, d2, 0.0, 0.0, 1.0
        return d0, d1, d2, m0, m1, m2
    # _BOX and _MESH_BOX
    q0 = min(max(d0, -s0), s0)
    q1 = min(max(d1, -s1), s1)
    q2 = min(max(d2, -s2), s2)
    if q0 != d0 or q1 != d1 or q2 != d2:
        return q0, q1, q2, d0 - q0, d1 - q1, d2 - q2
    # Inside: leave through the nearest face.
    p0 = s0 - abs(d0)
    p1 = s1 - abs(d1)
    p2 = s2 - abs(d2)
    if p0 <= p1 and p0 <= p2:
        return d0, d1, d2, 1.0 if d0 >= 0.0 else -1.0, 0.0, 0.0
    if p1 <= p2:
        return d0, d1, d2, 0.0, 1.0 if d1 >= 0.0 else -1.0, 0.0
    return d0, d1, d2, 0.0, 0.0, 1.0 if d2 >= 0.0 else -1.0


@nb.njit(cache=True, inline="always")
def _rotate(rec, x0, x1, x2, row, col):  # pragma: no cover - jitted
    """``y_i = sum_j rec[SHAPE_MAT + row i + col j] x_j``: R x with ``(row, col) = (3, 1)``,
    R^T x with ``(1, 3)``, R = rec's rotation (row-major). Callers pass constants, which
    numba folds once the call is inlined."""
    m = SHAPE_MAT
    return (
        rec[m] * x0 + rec[m + col] * x1 + rec[m + 2 * col] * x2,
        rec[m + row] * x0 + rec[m + row + col] * x1 + rec[m + row + 2 * col] * x2,
        rec[m + 2 * row] * x0 + rec[m + 2 * row + col] * x1 + rec[m + 2 * row + 2 * col] * x2,
    )


@nb.njit(cache=True, inline="always")
def _to_local(rec, x0, x1, x2):  # pragma: no cover - jitted
    """R^T x with R = rec's rotation."""
    return _rotate(rec, x0, x1, x2, 1, 3)


@nb.njit(cache=True, inline="always")
def _to_world(rec, x0, x1, x2):  # pragma: no cover - jitted
    """R x with R = rec's rotation."""
    return _rotate(rec, x0, x1, x2, 3, 1)


@nb.njit(cache=True, inline="always")
def _gap(c0, c1, c2, rec):  # pragma: no cover - jitted
    """(n.c - h_S(n), n, |c| + |p| + h_local) with n the closest-point direction, unit."""
    kind = int(rec[SHAPE_KIND])
    s0 = rec[SHAPE_SIZE]
    s1 = rec[SHAPE_SIZE + 1]
    s2 = rec[SHAPE_SIZE + 2]
    p0 = rec[SHAPE_POS]
    p1 = rec[SHAPE_POS + 1]
    p2 = rec[SHAPE_POS + 2]
    d0 = c0 - p0
    d1 = c1 - p1
    d2 = c2 - p2
    l0, l1, l2 = _to_local(rec, d0, d1, d2)
    _, _, _, m0, m1, m2 = _closest_local(kind, s0, s1, s2, l0, l1, l2)
    n0, n1, n2 = _to_world(rec, m0, m1, m2)
    nn = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if not nn > 0.0:  # m underflowed (d - q subnormal): any direction is valid
        n0, n1, n2, nn = 0.0, 0.0, 1.0, 1.0
    n0 /= nn
    n1 /= nn
    n2 /= nn
    # The support is evaluated at R^T of this very n: the half-space is then exactly H(n) for
    # the n whose n.v is used, whatever the closest-point routine got wrong.
    k0, k1, k2 = _to_local(rec, n0, n1, n2)
    h = support_local(kind, s0, s1, s2, k0, k1, k2)
    gap = n0 * d0 + n1 * d1 + n2 * d2 - h
    scale = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2) + math.sqrt(p0 * p0 + p1 * p1 + p2 * p2) + abs(h)
    return gap, n0, n1, n2, scale


@nb.njit(cache=True)
def static_gap(c, rec):  # pragma: no cover - jitted
    """Clearance of a point from a static shape along the chosen direction.

    Args:
        c: Point (sphere centre), shape ``(3,)``.
        rec: One shape record, shape ``(16,)``.

    Returns:
        ``(gap, nx, ny, nz)``: ``n`` is the unit direction from the closest point of the shape to
        ``c`` and ``gap = n.c - h_S(n)`` (without ``eps``). ``gap <= dist(c, S)`` for every ``c``
        and ``gap <= 0`` inside. Outside, ``gap = dist(c, S)`` up to rounding (for ``MESH_BOX``
        the distance to the box, for the ellipsoid up to the accuracy of the iterated root).
    """
    gap, n0, n1, n2, _ = _gap(c[0], c[1], c[2], rec)
    return gap, n0, n1, n2


@nb.njit(cache=True)
def support(n, rec):  # pragma: no cover - jitted
    """Support function ``h_S(n) = n.p + h_local(R^T n)`` of one shape.

    Args:
        n: Direction, shape ``(3,)``, any length (the support function is positively
            homogeneous).
        rec: One shape record, shape ``(16,)``.

    Returns:
        ``max_{q in S} n.q`` (for ``MESH_BOX``, that of the box around the hull: an upper bound).
    """
    k0, k1, k2 = _to_local(rec, n[0], n[1], n[2])
    h = support_local(
        int(rec[SHAPE_KIND]), rec[SHAPE_SIZE], rec[SHAPE_SIZE + 1], rec[SHAPE_SIZE + 2], k0, k1, k2
    )
    return n[0] * rec[SHAPE_POS] + n[1] * rec[SHAPE_POS + 1] + n[2] * rec[SHAPE_POS + 2] + h


@nb.njit(cache=True)
def closest_point(c, rec):  # pragma: no cover - jitted
    """Closest point of a static shape to ``c`` (``c`` itself when inside).

    Args:
        c: Point, shape ``(3,)``.
        rec: One shape record, shape ``(16,)``.

    Returns:
        ``(q0, q1, q2)`` in world coordinates; ``|c - q|`` is the distance to the shape (to the
        box for ``MESH_BOX``; for the ellipsoid to the iterated root, accurate to rounding).
    """
    p0 = rec[SHAPE_POS]
    p1 = rec[SHAPE_POS + 1]
    p2 = rec[SHAPE_POS + 2]
    l0, l1, l2 = _to_local(rec, c[0] - p0, c[1] - p1, c[2] - p2)
    q0, q1, q2, _, _, _ = _closest_local(
        int(rec[SHAPE_KIND]), rec[SHAPE_SIZE], rec[SHAPE_SIZE + 1], rec[SHAPE_SIZE + 2], l0, l1, l2
    )
    w0, w1, w2 = _to_world(rec, q0, q1, q2)
    return w0 + p0, w1 + p1, w2 + p2


@nb.njit(cache=True)  # not inlined: the fused steps stay small for the common pairs
def tau_static(c0, c1, c2, v0, v1, v2, rec, eps, accel, delta):  # pragma: no cover - jitted
    """Scalar kernel: lower bound on the time before a sphere can touch a static shape.

    The half-space tau of ``H(n)`` (module docstring) with the gap lowered by ``_GAP_SLACK`` and
    the velocity uncertainty raised by ``_VEL_SLACK |v|`` so that rounding cannot make it late.
    Returns 0 when the centre is inside the shape or within ``eps`` of it.
    """
    gap, n0, n1, n2, scale = _gap(c0, c1, c2, rec)
    g = gap - eps - _GAP_SLACK * (scale + eps)
    if g <= 0.0:
        return 0.0
    vn = n0 * v0 + n1 * v1 + n2 * v2
    nv = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    return tau_halfspace(g, vn, accel, delta + _VEL_SLACK * nv)


@nb.njit(cache=True, inline="always")
def _at(arr, i):  # pragma: no cover - jitted
    return arr[i] if arr.shape[0] > 1 else arr[0]


@nb.njit(cache=True)
def static_batch(c, v, shapes, ids, eps, accel, delta, out):  # pragma: no cover - jitted
    # Serial: a few dozen flops per sphere is cheaper than waking a thread pool.
    for i in range(c.shape[0]):
        out[i] = tau_static(
            c[i, 0],
            c[i, 1],
            c[i, 2],
            v[i, 0],
            v[i, 1],
            v[i, 2],
            shapes[ids[i]],
            _at(eps, i),
            _at(accel, i),
            _at(delta, i),
        )
