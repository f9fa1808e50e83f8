"""Urgency of a moving sphere against a static convex shape (proof in docs/static-shapes.md).

A static geom ``S`` (a body welded to the world) is held as its own shape instead of a bounding
sphere. Any half-space ``{p : n.p <= h_S(n)}`` (``h_S`` the support function) holds ``S``, so
the half-space tau (``dua_mujoco.core.urgency.time_to_halfspace``) of ``gap = n.c - h_S(n) - eps``
and normal velocity ``n.v`` is a lower bound on the time to contact for *any* unit ``n``; the
kernels take ``n`` from the closest point of ``S`` and evaluate the support at that very ``n``, so
an inaccurate closest point costs tightness, never safety.

Shape records are ``(nshape, 16)`` float64 rows: ``SHAPE_KIND`` (a ``ShapeKind``: MuJoCo's
``mjtGeom`` code, ``MESH_BOX`` for a mesh held as the box of its hull, ``HFIELD`` for terrain,
``dua_mujoco.core.terrain``), ``SHAPE_SIZE`` (MuJoCo's ``geom_size``), ``SHAPE_POS`` and
``SHAPE_MAT`` (``geom_xmat``, row-major); docs/static-shapes.md, section 7, has the table. Planes
are half-spaces already; SDFs are not convex and are refused. The one-shape kernels below take a
record, or a table and the row of one of its records (a terrain record needs its table).
"""

from __future__ import annotations

import enum

import numpy as np
import numpy.typing as npt

import dua_mujoco._core as _core
from dua_mujoco.core.terrain import first_bad_row, record_count
from dua_mujoco.core.validate import as_ids, as_vectors, per_pair
from dua_mujoco.exceptions import InvalidInputError, ShapeError

__all__ = [
    "SHAPE_KIND",
    "SHAPE_MAT",
    "SHAPE_NCOL",
    "SHAPE_POS",
    "SHAPE_SIZE",
    "ShapeKind",
    "closest_point",
    "mesh_box",
    "one_point",
    "pack_shapes",
    "shape_table",
    "time_to_static",
]

_LAYOUT = _core.LAYOUT


class ShapeKind(enum.IntEnum):
    """Static shape types; the values are MuJoCo's ``mjtGeom`` codes."""

    SPHERE = _LAYOUT["ShapeKind.SPHERE"]
    CAPSULE = _LAYOUT["ShapeKind.CAPSULE"]
    ELLIPSOID = _LAYOUT["ShapeKind.ELLIPSOID"]
    CYLINDER = _LAYOUT["ShapeKind.CYLINDER"]
    BOX = _LAYOUT["ShapeKind.BOX"]
    MESH_BOX = _LAYOUT["ShapeKind.MESH_BOX"]  # a mesh, held as the box geom_aabb around its hull
    HFIELD = _LAYOUT["ShapeKind.HFIELD"]  # a static height field, its grid's prisms (core/terrain)


SHAPE_KIND: int = _LAYOUT["SHAPE_KIND"]
SHAPE_SIZE: int = _LAYOUT["SHAPE_SIZE"]
SHAPE_POS: int = _LAYOUT["SHAPE_POS"]
SHAPE_MAT: int = _LAYOUT["SHAPE_MAT"]
SHAPE_NCOL: int = _LAYOUT["SHAPE_NCOL"]


def one_point(
    point: npt.ArrayLike, rec: npt.ArrayLike, row: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A point ``(1, 3)``, a table ``(k, 16)`` and the id ``(1,)`` of its row ``row`` for the
    native kernels' batches (a terrain record reads the rows after it: its table is passed)."""
    p = np.asarray(point, dtype=np.float64).reshape(1, 3)
    r = np.ascontiguousarray(np.asarray(rec, dtype=np.float64).reshape(-1, SHAPE_NCOL))
    return p, r, np.array([row], dtype=np.int64)


def closest_point(c: npt.ArrayLike, rec: npt.ArrayLike, row: int = 0) -> tuple[float, float, float]:
    """Closest point of a static shape to ``c`` (``c`` itself when inside).

    Args:
        c: Point, shape ``(3,)``.
        rec: One shape record, shape ``(16,)``, or a table ``(k, 16)``.
        row: The record's row in ``rec`` when it is a table.

    Returns:
        ``(q0, q1, q2)`` in world coordinates; ``|c - q|`` is the distance to the shape (to the
        box for ``MESH_BOX``; for the ellipsoid to the iterated root, accurate to rounding).
    """
    out = _core.closest_point(*one_point(c, rec, row))[0]
    return float(out[0]), float(out[1]), float(out[2])


# How far from orthonormal a rotation may be (MuJoCo's geom_xmat is orthonormal to ~1e-15).
_ORTHO_TOL = 1e-6


# ------------------------------------------------------------------------------------------------
# Packing and validation
# ------------------------------------------------------------------------------------------------

_KIND_CODES = np.array([int(k) for k in ShapeKind], dtype=np.float64)
# Size columns a kind uses; the others are ignored (MuJoCo leaves them 0 for spheres).
_USED = {
    ShapeKind.HFIELD: 0,  # its size columns locate its block (dua_mujoco.core.terrain)
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
            "Planes are half-spaces (use time_to_halfspace); SDFs are not convex (cover them "
            "with spheres instead)."
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
    if (k == int(ShapeKind.HFIELD)).any():
        i = _first_bad_row(k == int(ShapeKind.HFIELD))
        raise InvalidInputError(
            f"kind[{i}] is HFIELD: a height field's record points to its grid; build it with "
            "dua_mujoco.core.terrain.pack_terrain and shape_table."
        )
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


def shape_table(shapes: npt.ArrayLike) -> np.ndarray:
    """``shapes`` checked as a shape table: ``(m, 16)`` finite records of known kinds and sizes
    (``pack_shapes``), and the blocks its terrain records point to (``core/terrain``).

    Raises:
        ShapeError: It is not ``(m, 16)`` with ``m >= 1``.
        InvalidInputError: A value is not finite, a record's kind or size is invalid, or a
            terrain record's block does not fit the table.
    """
    recs = np.asarray(shapes, dtype=np.float64)
    if recs.ndim != 2 or recs.shape[1] != SHAPE_NCOL or recs.shape[0] == 0:
        raise ShapeError(
            f"shapes has shape {recs.shape}; expected (m, {SHAPE_NCOL}) records from pack_shapes."
        )
    if not np.isfinite(recs).all():
        i = _first_bad_row(~np.isfinite(recs).all(axis=1))
        raise InvalidInputError(f"shapes[{i}] is not finite; rebuild it with pack_shapes.")
    # Terrain records point to blocks after the records (dua_mujoco.core.terrain).
    recs = np.ascontiguousarray(recs)
    nrec = record_count(recs)
    _check_kinds("shapes[:, SHAPE_KIND]", recs[:nrec, SHAPE_KIND])
    _check_sizes(
        "shapes[:, SHAPE_SIZE:SHAPE_POS]",
        recs[:nrec, SHAPE_KIND],
        recs[:nrec, SHAPE_SIZE:SHAPE_POS],
    )
    bad = first_bad_row(recs)
    if bad >= 0:
        raise InvalidInputError(
            f"shapes[{bad}] is a terrain record whose block does not fit the table (its offset, "
            "length, header or grid): rebuild the table with dua_mujoco.build.tables.static_shapes "
            "or dua_mujoco.core.terrain.shape_table."
        )
    return recs


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
    c = as_vectors("centers", centers)
    n = c.shape[0]
    v = as_vectors("velocities", velocities, n)
    recs = shape_table(shapes)
    ids64 = as_ids("shape_ids", shape_ids, n)  # each in range: the native call says
    e = per_pair("eps", eps, n)
    a = per_pair("accel", accel, n)
    dl = per_pair("vel_uncertainty", vel_uncertainty, n)
    return np.asarray(_core.tau_static_batch(c, v, np.ascontiguousarray(recs), ids64, e, a, dl))
