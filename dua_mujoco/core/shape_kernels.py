"""Compiled kernels of the static-shape urgency (proof in docs/static-shapes.md).

Support functions, closest points and ``tau_static`` of a moving sphere against one packed
shape record, implemented once in the native core (``dua_mujoco/csrc/src/shapes.cc``; numba's
entry points to it here); the record layout, packing, validation and the vectorised front are in
``dua_mujoco.core.shapes``, which re-exports everything public here.
"""

from __future__ import annotations

import enum

import numba as nb
import numpy as np

from dua_mujoco.core.native_kernels import (
    closest_point_c,
    static_gap_c,
    support_c,
    tau_static_c,
)

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


@nb.njit(cache=True)
def static_gap(c, rec):  # pragma: no cover - jitted
    """Clearance of a point from a static shape along the chosen direction.

    Args:
        c: Point (sphere centre), shape ``(3,)``, contiguous.
        rec: One shape record, shape ``(16,)``, contiguous.

    Returns:
        ``(gap, nx, ny, nz)``: ``n`` is the unit direction from the closest point of the shape to
        ``c`` and ``gap = n.c - h_S(n)`` (without ``eps``). ``gap <= dist(c, S)`` for every ``c``
        and ``gap <= 0`` inside. Outside, ``gap = dist(c, S)`` up to rounding (for ``MESH_BOX``
        the distance to the box, for the ellipsoid up to the accuracy of the iterated root).
    """
    out = np.empty(4)
    static_gap_c(c.ctypes, rec.ctypes, out.ctypes)
    return out[0], out[1], out[2], out[3]


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
    return support_c(n.ctypes, rec.ctypes)


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
    out = np.empty(3)
    closest_point_c(c.ctypes, rec.ctypes, out.ctypes)
    return out[0], out[1], out[2]


@nb.njit(cache=True)
def tau_static(c0, c1, c2, v0, v1, v2, rec, eps, accel, delta):  # pragma: no cover - jitted
    """Scalar kernel: lower bound on the time before a sphere can touch a static shape.

    The half-space tau of ``H(n)`` (module docstring) with the gap lowered by a rounding slack
    and the velocity uncertainty raised by one, so that rounding cannot make it late. Returns 0
    when the centre is inside the shape or within ``eps`` of it. ``rec`` is contiguous.
    """
    return tau_static_c(c0, c1, c2, v0, v1, v2, rec.ctypes, eps, accel, delta)


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
