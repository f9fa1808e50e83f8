"""Urgency of a moving sphere against a static convex shape (proof in docs/static-shapes.md).

A static geom ``S`` (a body welded to the world) is held as its own shape instead of a bounding
sphere. For every unit vector ``n`` the half-space ``H(n) = {p : n.p <= h_S(n)}``, with the support
function ``h_S(n) = max_{q in S} n.q``, contains ``S``; a sphere of contact distance ``eps`` (radius
plus margin) can touch ``S`` only after its centre comes within ``eps`` of ``H(n)``. So the
half-space tau (``dua_mujoco.urgency.tau_halfspace``) with

    gap = n.c - h_S(n) - eps,    normal velocity = n.v

is a lower bound on the time to contact for *any* ``n``: the direction only decides how tight it
is. The kernels take ``n`` along ``c - q*`` with ``q*`` the closest point of ``S`` to the centre
``c``, which maximises the gap (it is then ``dist(c, S) - eps``), and evaluate the gap with the
support function at that very ``n``, so an inaccurate closest point costs tightness, never safety.

Shape records are ``(nshape, 16)`` float64 rows; the size columns follow MuJoCo's ``geom_size``:

======  ===========  =========================================================================
column  name         content
======  ===========  =========================================================================
0       SHAPE_KIND   ``ShapeKind`` code (float-coded integer)
1..3    SHAPE_SIZE   sphere ``(r, -, -)``; capsule ``(r, L, -)``; ellipsoid ``(a, b, c)``;
                     cylinder ``(r, L, -)``; box and mesh box ``(a, b, c)`` half-sizes
4..6    SHAPE_POS    centre of the shape's frame, world coordinates
7..15   SHAPE_MAT    rotation geom-to-world, 3x3 row-major (MuJoCo's ``geom_xmat``)
======  ===========  =========================================================================

``ShapeKind`` codes equal MuJoCo's ``mjtGeom`` (this module does not import MuJoCo):
``mjGEOM_SPHERE = 2``, ``CAPSULE = 3``, ``ELLIPSOID = 4``, ``CYLINDER = 5``, ``BOX = 6``; a
``mjGEOM_MESH = 7`` is held as ``MESH_BOX``, the box ``geom_aabb`` of its convex hull (build the
record with ``mesh_box``). Planes (``0``) are half-spaces already (``time_to_halfspace``); height
fields (``1``) and SDFs (``8``) are not convex and are refused.
"""

from __future__ import annotations

import enum
import math

import numba as nb
import numpy as np
import numpy.typing as npt

from dua_mujoco.core.urgency import tau_halfspace
from dua_mujoco.exceptions import (
    InvalidBoundError,
    InvalidInputError,
    NonFiniteStateError,
    ShapeError,
)

__all__ = [
    "SHAPE_KIND",
    "SHAPE_MAT",
    "SHAPE_NCOL",
    "SHAPE_POS",
    "SHAPE_SIZE",
    "ShapeKind",
    "closest_point",
    "mesh_box",
    "pack_shapes",
    "static_gap",
    "support",
    "tau_static",
    "time_to_static",
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
# How far from orthonormal a rotation may be (MuJoCo's geom_xmat is orthonormal to ~1e-15).
_ORTHO_TOL = 1e-6


@nb.njit(cache=True, inline="always")
def _support_local(kind, s0, s1, s2, m0, m1, m2):  # pragma: no cover - jitted
    """h of the shape in its own frame, in direction m (any length: every form is homogeneous)."""
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
def _to_local(rec, x0, x1, x2):  # pragma: no cover - jitted
    """R^T x with R = rec's rotation (row-major)."""
    m = SHAPE_MAT
    return (
        rec[m + 0] * x0 + rec[m + 3] * x1 + rec[m + 6] * x2,
        rec[m + 1] * x0 + rec[m + 4] * x1 + rec[m + 7] * x2,
        rec[m + 2] * x0 + rec[m + 5] * x1 + rec[m + 8] * x2,
    )


@nb.njit(cache=True, inline="always")
def _to_world(rec, x0, x1, x2):  # pragma: no cover - jitted
    """R x with R = rec's rotation (row-major)."""
    m = SHAPE_MAT
    return (
        rec[m + 0] * x0 + rec[m + 1] * x1 + rec[m + 2] * x2,
        rec[m + 3] * x0 + rec[m + 4] * x1 + rec[m + 5] * x2,
        rec[m + 6] * x0 + rec[m + 7] * x1 + rec[m + 8] * x2,
    )


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
    h = _support_local(kind, s0, s1, s2, k0, k1, k2)
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
    h = _support_local(
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


@nb.njit(cache=True, inline="always")
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
def _static_batch(c, v, shapes, ids, eps, accel, delta, out):  # pragma: no cover - jitted
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


# ------------------------------------------------------------------------------------------------
# Packing and validation
# ------------------------------------------------------------------------------------------------

_KIND_CODES = np.array([int(k) for k in ShapeKind], dtype=np.float64)
# Size columns a kind uses; the others are ignored (MuJoCo leaves them 0 for spheres).
_USED = {
    ShapeKind.SPHERE: 1,
    ShapeKind.CAPSULE: 2,
    ShapeKind.ELLIPSOID: 3,
    ShapeKind.CYLINDER: 2,
    ShapeKind.BOX: 3,
    ShapeKind.MESH_BOX: 3,
}
# Radii and semi-axes that the closest-point formulas divide by; other lengths may be 0.
_POSITIVE = (ShapeKind.SPHERE, ShapeKind.ELLIPSOID)


def _rows(name: str, value: npt.ArrayLike, ncol: int, n: int | None = None) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 1 and arr.shape[0] == ncol and n is None:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != ncol or (n is not None and arr.shape[0] != n):
        want = f"({n}, {ncol})" if n is not None else f"(N, {ncol})"
        raise ShapeError(f"{name} has shape {np.shape(value)}; expected {want}.")
    return arr


def _first_bad_row(bad: npt.ArrayLike) -> int:
    return int(np.flatnonzero(bad)[0])


def _check_kinds(name: str, kind: np.ndarray) -> None:
    ok = np.isin(kind, _KIND_CODES)
    if not ok.all():
        i = _first_bad_row(~ok)
        valid = ", ".join(f"{k.name}={int(k)}" for k in ShapeKind)
        raise InvalidInputError(
            f"{name}[{i}] = {float(kind[i]):g} is not a static shape kind. Valid kinds: {valid}. "
            "Planes are half-spaces (use time_to_halfspace); height fields and SDFs are not "
            "convex (cover them with spheres instead)."
        )


def _check_sizes(name: str, kind: np.ndarray, size: np.ndarray) -> None:
    """Used size columns >= 0 (> 0 for sphere radii and ellipsoid semi-axes)."""
    codes = kind.astype(np.int64)
    ncol = np.zeros(max(int(k) for k in ShapeKind) + 1, dtype=np.int64)
    for k, count in _USED.items():
        ncol[int(k)] = count
    used = np.arange(3) < ncol[codes][:, None]
    strict = np.isin(kind, [int(k) for k in _POSITIVE])[:, None]
    bad = (used & (size < 0.0)) | (used & strict & (size <= 0.0))
    if bad.any():
        j = _first_bad_row(bad.any(axis=1))
        kj = ShapeKind(int(kind[j]))
        need = "positive" if kj in _POSITIVE else "non-negative"
        raise InvalidInputError(
            f"{name}[{j}] = {size[j].tolist()} is invalid for {kj.name}: its first "
            f"{_USED[kj]} entries must be {need} (MuJoCo's geom_size convention)."
        )


def pack_shapes(
    kind: npt.ArrayLike, size: npt.ArrayLike, pos: npt.ArrayLike, mat: npt.ArrayLike
) -> np.ndarray:
    """Pack static shapes into records for ``tau_static`` and ``time_to_static``.

    Args:
        kind: ``ShapeKind`` codes (MuJoCo ``mjtGeom`` values), shape ``(m,)`` or a scalar.
        size: MuJoCo ``geom_size`` rows, shape ``(m, 3)`` (for ``MESH_BOX`` the half-sizes from
            ``mesh_box``).
        pos: Frame centres in world coordinates, shape ``(m, 3)``.
        mat: Rotations geom-to-world, shape ``(m, 9)`` row-major or ``(m, 3, 3)``.

    Returns:
        ``(m, 16)`` float64 records: ``[kind, size(3), pos(3), mat(9)]`` (columns ``SHAPE_KIND``,
        ``SHAPE_SIZE``, ``SHAPE_POS``, ``SHAPE_MAT``).

    Raises:
        ShapeError: An argument does not have the documented shape.
        InvalidInputError: An unknown kind, a non-finite value, a negative size, a zero radius
            or semi-axis, or a matrix that is not a rotation.
    """
    k = np.atleast_1d(np.asarray(kind))
    if k.ndim != 1:
        raise ShapeError(f"kind has shape {k.shape}; expected (m,).")
    if not (np.issubdtype(k.dtype, np.integer) or k.dtype == object):
        raise InvalidInputError(
            f"kind has dtype {k.dtype}; pass integer ShapeKind codes (e.g. int(model.geom_type))."
        )
    k = k.astype(np.int64)
    m = k.shape[0]
    _check_kinds("kind", k.astype(np.float64))
    sz = _rows("size", size, 3, m)
    ps = _rows("pos", pos, 3, m)
    mt = np.asarray(mat, dtype=np.float64)
    if mt.shape == (m, 3, 3):
        mt = mt.reshape(m, 9)
    mt = _rows("mat", mt, 9, m)
    for name, arr in (("size", sz), ("pos", ps), ("mat", mt)):
        if not np.isfinite(arr).all():
            i = _first_bad_row(~np.isfinite(arr).all(axis=1))
            raise InvalidInputError(f"{name}[{i}] = {arr[i].tolist()} is not finite.")
    _check_sizes("size", k, sz)
    rots = mt.reshape(m, 3, 3)
    err = np.abs(np.einsum("mij,mkj->mik", rots, rots) - np.eye(3)).max(axis=(1, 2))
    bad = (err > _ORTHO_TOL) | (np.linalg.det(rots) <= 0.0)
    if bad.any():
        i = _first_bad_row(bad)
        raise InvalidInputError(
            f"mat[{i}] = {mt[i].tolist()} is not a rotation (|R R^T - I| = {err[i]:.3g}, "
            f"det = {np.linalg.det(rots[i]):.6g}); pass geom_xmat rows (3x3, row-major)."
        )
    out = np.empty((m, SHAPE_NCOL))
    out[:, SHAPE_KIND] = k
    out[:, SHAPE_SIZE : SHAPE_SIZE + 3] = sz
    out[:, SHAPE_POS : SHAPE_POS + 3] = ps
    out[:, SHAPE_MAT : SHAPE_MAT + 9] = mt
    return out


def mesh_box(
    aabb: npt.ArrayLike, pos: npt.ArrayLike, mat: npt.ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """Size and world centre of the box that holds a mesh geom's convex hull.

    MuJoCo's ``geom_aabb`` is ``(centre offset, half-sizes)`` in the geom frame; the offset is
    folded into the world centre so that the record is a plain box.

    Args:
        aabb: ``geom_aabb`` rows, shape ``(m, 6)``.
        pos: ``geom_xpos``, shape ``(m, 3)``.
        mat: ``geom_xmat``, shape ``(m, 9)`` or ``(m, 3, 3)``.

    Returns:
        ``(size, centre)``, each ``(m, 3)``: pass them to ``pack_shapes`` with
        ``ShapeKind.MESH_BOX`` and the same ``mat``.
    """
    ab = _rows("aabb", aabb, 6)
    m = ab.shape[0]
    ps = _rows("pos", pos, 3, m)
    mt = np.asarray(mat, dtype=np.float64).reshape(m, 3, 3) if np.size(mat) == 9 * m else None
    if mt is None:
        raise ShapeError(f"mat has shape {np.shape(mat)}; expected ({m}, 9) or ({m}, 3, 3).")
    centre = ps + np.einsum("mij,mj->mi", mt, ab[:, :3])
    return ab[:, 3:].copy(), centre


def _per_sphere(name: str, value: npt.ArrayLike, n: int) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 0:
        arr = arr.reshape(1)
    elif arr.shape != (n,):
        raise ShapeError(f"{name} has shape {arr.shape}; expected a scalar or ({n},).")
    ok = np.isfinite(arr) & (arr >= 0.0)
    if not ok.all():
        i = _first_bad_row(~ok)
        raise InvalidBoundError(
            f"{name}[{i}] = {arr[i]} is invalid: it must be a finite non-negative number."
        )
    return np.ascontiguousarray(arr)


def _state(name: str, value: npt.ArrayLike, n: int | None) -> np.ndarray:
    arr = _rows(name, value, 3, n)
    if not np.isfinite(arr).all():
        bad = ~np.isfinite(arr).all(axis=1)
        i = _first_bad_row(bad)
        raise NonFiniteStateError(
            f"{name}[{i}] = {arr[i].tolist()} is not finite ({int(bad.sum())} rows): "
            "the state is NaN or inf; check that the simulation has not diverged."
        )
    return np.ascontiguousarray(arr)


def time_to_static(
    centers: npt.ArrayLike,
    velocities: npt.ArrayLike,
    shapes: npt.ArrayLike,
    shape_ids: npt.ArrayLike,
    eps: npt.ArrayLike,
    accel: npt.ArrayLike,
    *,
    vel_uncertainty: npt.ArrayLike = 0.0,
) -> np.ndarray:
    """Conservative time until moving spheres can touch static convex shapes.

    Args:
        centers: Sphere centres, shape ``(n, 3)`` or ``(3,)``.
        velocities: Centre velocities, same shape as ``centers``.
        shapes: Shape records from ``pack_shapes``, shape ``(m, 16)``.
        shape_ids: Row of ``shapes`` each sphere is tested against, integers, shape ``(n,)``.
        eps: Contact distance (sphere radius plus margin), scalar or ``(n,)``, ``>= 0``.
        accel: Bound on the acceleration norm of the centre, scalar or ``(n,)``, ``>= 0``.
        vel_uncertainty: Bound on the error of the velocity, scalar or ``(n,)``, ``>= 0``.

    Returns:
        ``(n,)`` float64 lower bounds on the time before the sphere comes within ``eps`` of its
        shape: ``0`` where it already is (or the centre is inside), ``+inf`` where never.

    Raises:
        ShapeError: An argument does not have the documented shape.
        NonFiniteStateError: A centre or velocity is NaN or inf.
        InvalidInputError: A record is not finite or has an unknown kind, or an id is out of range
            or not an integer.
        InvalidBoundError: ``eps``, ``accel`` or ``vel_uncertainty`` is negative, NaN or inf.
    """
    c = _state("centers", centers, None)
    n = c.shape[0]
    v = _state("velocities", velocities, n)
    recs = np.asarray(shapes, dtype=np.float64)
    if recs.ndim != 2 or recs.shape[1] != SHAPE_NCOL or recs.shape[0] == 0:
        raise ShapeError(
            f"shapes has shape {recs.shape}; expected (m, {SHAPE_NCOL}) records from pack_shapes."
        )
    if not np.isfinite(recs).all():
        i = _first_bad_row(~np.isfinite(recs).all(axis=1))
        raise InvalidInputError(f"shapes[{i}] is not finite; rebuild it with pack_shapes.")
    _check_kinds("shapes[:, SHAPE_KIND]", recs[:, SHAPE_KIND])
    _check_sizes(
        "shapes[:, SHAPE_SIZE:SHAPE_POS]", recs[:, SHAPE_KIND], recs[:, SHAPE_SIZE:SHAPE_POS]
    )
    ids = np.asarray(shape_ids)
    if ids.shape != (n,):
        raise ShapeError(f"shape_ids has shape {ids.shape}; expected ({n},).")
    if not np.issubdtype(ids.dtype, np.integer):
        raise InvalidInputError(
            f"shape_ids has dtype {ids.dtype}; pass integer row indices into shapes."
        )
    out_of_range = (ids < 0) | (ids >= recs.shape[0])
    if out_of_range.any():
        i = _first_bad_row(out_of_range)
        raise InvalidInputError(
            f"shape_ids[{i}] = {int(ids[i])} is out of range: shapes has {recs.shape[0]} rows "
            f"(valid ids 0..{recs.shape[0] - 1})."
        )
    e = _per_sphere("eps", eps, n)
    a = _per_sphere("accel", accel, n)
    dl = _per_sphere("vel_uncertainty", vel_uncertainty, n)
    out = np.empty(n)
    _static_batch(
        c, v, np.ascontiguousarray(recs), np.ascontiguousarray(ids, dtype=np.int64), e, a, dl, out
    )
    return out
