"""The exact level of the urgency: a conservative tau from the geoms themselves, not their balls.

A pair whose sphere tau is below ``exact_below`` is looked at again through its two geoms:
MuJoCo's narrowphase (``mj_geomDistance``, called from compiled code through ``libmujoco``'s C
entry point) gives a witness direction ``n`` from the first geom to the second, and the
separation of the two geoms along ``n`` is bounded below, over time, by

    d(t) >= d_n + (n . (v_B - v_A) - |w_A| r_A - |w_B| r_B) t - delta t - A t^2 / 2,

where ``d_n = min_B n.b - max_A n.a`` is computed from this package's own support functions
(never from MuJoCo's distance, whose numerical tolerance could make it too large), ``v`` the
velocities of the geom origins, ``w`` the bodies' angular velocities, ``r`` the geoms' radii
about their origins, and ``A``, ``delta`` the pair's bounds, which hold for every point of the two
geoms (their boxes' corners are among the points the bounds are estimated and checked at). Its
first root is :func:`~dua_mujoco.core.urgency.tau_halfspace`'s, and the pair's tau is the larger
of the two lower bounds. Proof, and what the distance means for each geom type, in
docs/theory.md (section 6). A plane needs no query: its normal is the direction.

Height fields and SDF geoms are not convex and keep their sphere tau; so do pairs whose witness
is degenerate (touching, or no witness within the query's reach).
"""

from __future__ import annotations

import ctypes
import dataclasses
import enum
import math
import os

import mujoco
import numba as nb
import numpy as np
import numpy.typing as npt
from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

from dua_mujoco.core.pairset import KIND_HALFSPACE, KIND_SHAPE, PAIR_ACCEL, PAIR_DELTA, PAIR_OTHER
from dua_mujoco.core.shape_kernels import support_local
from dua_mujoco.core.shapes import (
    SHAPE_KIND,
    SHAPE_MAT,
    SHAPE_POS,
    SHAPE_SIZE,
    ShapeKind,
)
from dua_mujoco.core.urgency import tau_halfspace
from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.mj.kinematics import SPHERE_BODY, SPHERE_ROOT, pack_spheres, rigid_point_at

__all__ = [
    "EXACT_PERIODS",
    "EXACT_TYPES",
    "QUERY_PERIODS",
    "ExactLevel",
    "ExactMode",
    "build_exact",
    "corner_points",
    "exact_buffer",
    "exact_pass",
    "exact_taus",
    "geom_distance_address",
    "no_exact",
]

EXACT_PERIODS = 2
"""Pairs whose sphere tau is below this many predictor periods past the latency are looked at
through their geoms: one period past the alarm horizon. Measured on six scenes
(docs/benchmarks.md): 1 to 32 periods clear the same alarms, and the cost grows with it."""
QUERY_PERIODS = 4
"""MuJoCo is asked for a new direction when the pair's tau along its last one is below this
many predictor periods (1 to 16 cost within the machine's noise of each other, measured)."""

EXACT_TYPES = frozenset(
    int(t)
    for t in (
        mujoco.mjtGeom.mjGEOM_SPHERE,
        mujoco.mjtGeom.mjGEOM_CAPSULE,
        mujoco.mjtGeom.mjGEOM_ELLIPSOID,
        mujoco.mjtGeom.mjGEOM_CYLINDER,
        mujoco.mjtGeom.mjGEOM_BOX,
        mujoco.mjtGeom.mjGEOM_MESH,
    )
)
"""Geom types the exact level reads (convex, with a support function here); planes too, as the
second member of a half-space pair."""


class ExactMode(enum.IntEnum):
    """What the exact level does for a pair (``X_MODE``)."""

    NONE = 0
    """Keep the sphere tau (a height field, an SDF, or the level is off)."""
    GEOMS = 1
    """Two geoms that may both move: ``mj_geomDistance`` gives the direction."""
    PLANE = 2
    """A geom and a plane: the plane's normal is the direction."""
    SHAPE = 3
    """A geom and a static shape (its record in the shape table): ``mj_geomDistance``."""


# Plain ints for the kernels (numba folds module-level ints into constants).
_NONE, _GEOMS, _PLANE, _SHAPE = (int(m) for m in ExactMode)


# Columns of the per-geom records: the first eight are ``pack_spheres``' (a "sphere" at the geom
# origin, which ``rigid_point`` reads for the origin's velocity), then the support shape.
GX_KIND = 8  # ShapeKind code, or -1 where the level does not apply
GX_SIZE = 9  # 3 columns
GX_CENTRE = 12  # 3 columns: the support shape's centre in the geom frame (a mesh's box centre)
GX_RADIUS = 15  # max |p - origin| over the geom's points
GX_NCOL = 16
# Columns of the per-pair records: the last direction that served the pair starts at X_N.
X_MODE, X_G1, X_G2, X_DIST, X_N = 0, 1, 2, 3, 4
X_NCOL = 8

# The gap is a sum of dot products and supports of size ``scale``; 1e-14 is ~45 units of
# rounding (as in core/shape_kernels.py).
_GAP_SLACK = 1e-14
_VEL_SLACK = 1e-14
# A witness shorter than this (relative to the geoms' size) has no usable direction.
_MIN_WITNESS = 1e-9


def geom_distance_address() -> int:
    """Address of ``mj_geomDistance`` in the ``libmujoco`` the ``mujoco`` package loaded."""
    folder = os.path.dirname(mujoco.__file__)
    names = sorted(n for n in os.listdir(folder) if n.startswith("libmujoco.so"))
    if not names:  # pragma: no cover - every Linux wheel ships it
        raise InvalidInputError(
            f"no libmujoco.so in {folder}: the exact level calls MuJoCo's C library; reinstall "
            "mujoco, or build the Predictor with UrgencyOptions(exact=False)."
        )
    lib = ctypes.CDLL(os.path.join(folder, names[-1]))
    return int(ctypes.cast(lib.mj_geomDistance, ctypes.c_void_p).value or 0)


@intrinsic
def _geom_distance(typingctx, fn, m, d, g1, g2, distmax, fromto):  # pragma: no cover - compile
    """``mj_geomDistance(m, d, g1, g2, distmax, fromto)`` through the function pointer ``fn``.

    The addresses are run-time integers, so the compiled step stays cacheable (a ctypes
    function object would bake this process's address into the cache)."""
    sig = types.float64(fn, m, d, g1, g2, distmax, fromto)

    def codegen(context, builder, signature, args):
        i8p = ir.IntType(8).as_pointer()
        f64 = ir.DoubleType()
        i32 = ir.IntType(32)
        fnty = ir.FunctionType(f64, [i8p, i8p, i32, i32, f64, f64.as_pointer()])
        ints = [
            context.cast(builder, v, t, types.int64)
            for v, t in zip(args[:5], signature.args[:5], strict=True)
        ]
        out = context.make_array(signature.args[6])(context, builder, args[6])
        return builder.call(
            builder.inttoptr(ints[0], fnty.as_pointer()),
            [
                builder.inttoptr(ints[1], i8p),
                builder.inttoptr(ints[2], i8p),
                builder.trunc(ints[3], i32),
                builder.trunc(ints[4], i32),
                context.cast(builder, args[5], signature.args[5], types.float64),
                out.data,
            ],
        )

    return sig, codegen


@nb.njit(cache=True, inline="always")
def _spin(g, geoms, twist, root_twist):  # pragma: no cover - jitted
    """``|w| r`` of geom ``g``: how fast rotation can move its points away from translation."""
    b = int(geoms[g, SPHERE_BODY])
    r = int(geoms[g, SPHERE_ROOT])
    w0 = twist[b, 0] + root_twist[r, 0]
    w1 = twist[b, 1] + root_twist[r, 1]
    w2 = twist[b, 2] + root_twist[r, 2]
    return math.sqrt(w0 * w0 + w1 * w1 + w2 * w2) * geoms[g, GX_RADIUS]


@nb.njit(cache=True, inline="always")
def _support(kind, s0, s1, s2, mat, row, col, p0, p1, p2, n0, n1, n2):  # pragma: no cover
    """``max n.x`` over a shape of ``kind`` and sizes ``s`` centred at ``p``, rotated by the
    row-major ``mat[row, col:col + 9]`` (scalars in and out: no array view)."""
    m0 = mat[row, col] * n0 + mat[row, col + 3] * n1 + mat[row, col + 6] * n2
    m1 = mat[row, col + 1] * n0 + mat[row, col + 4] * n1 + mat[row, col + 7] * n2
    m2 = mat[row, col + 2] * n0 + mat[row, col + 5] * n1 + mat[row, col + 8] * n2
    return n0 * p0 + n1 * p1 + n2 * p2 + support_local(kind, s0, s1, s2, m0, m1, m2)


@nb.njit(cache=True, inline="always")
def _geom_support(g, geoms, frame_pos, frame_mat, n0, n1, n2):  # pragma: no cover - jitted
    """Support of geom ``g``'s support shape at its current pose along ``n``: ``max n.p``."""
    # The support shape's centre: the origin plus R c (c: a mesh box's centre, else 0).
    c0 = geoms[g, GX_CENTRE]
    c1 = geoms[g, GX_CENTRE + 1]
    c2 = geoms[g, GX_CENTRE + 2]
    m = frame_mat
    p0 = frame_pos[g, 0] + m[g, 0] * c0 + m[g, 1] * c1 + m[g, 2] * c2
    p1 = frame_pos[g, 1] + m[g, 3] * c0 + m[g, 4] * c1 + m[g, 5] * c2
    p2 = frame_pos[g, 2] + m[g, 6] * c0 + m[g, 7] * c1 + m[g, 8] * c2
    kind = int(geoms[g, GX_KIND])
    s0, s1, s2 = geoms[g, GX_SIZE], geoms[g, GX_SIZE + 1], geoms[g, GX_SIZE + 2]
    return _support(kind, s0, s1, s2, m, g, 0, p0, p1, p2, n0, n1, n2)


@nb.njit(cache=True, inline="always")
def _record_support(shapes, row, n0, n1, n2):  # pragma: no cover - jitted
    """Support of static shape record ``row`` along ``n`` (``core.shapes.support``, scalars)."""
    sz = SHAPE_SIZE
    ps = SHAPE_POS
    # Indexed, not s = shapes[row]: a row view is reference-counted (exact_pass).
    return _support(
        int(shapes[row, SHAPE_KIND]),
        shapes[row, sz],
        shapes[row, sz + 1],
        shapes[row, sz + 2],
        shapes,
        row,
        SHAPE_MAT,
        shapes[row, ps],
        shapes[row, ps + 1],
        shapes[row, ps + 2],
        n0,
        n1,
        n2,
    )


@nb.njit(cache=True)
def exact_pass(tau, ids, count, pairs, frame, shapes, exact, buf):  # pragma: no cover - jitted
    """Raise ``tau[k]`` of pairs ``ids[k]`` (``k < count``) to their exact level where it is
    below ``exact_below``: ``max(tau, exact)`` (module docstring).

    One call a step, not one a pair: numba reference-counts every array a call unpacks, and
    that cost 0.3 us a pair (measured), more than the arithmetic.

    Args:
        tau: ``(>= count,)`` sphere taus, overwritten.
        ids: ``(>= count,)`` pair ids: rows of ``pairs`` and of the exact records.
        count: How many to look at.
        pairs: ``pack_pairs`` records (the bounds; ``PAIR_OTHER`` is a shape row).
        frame: ``mjdata_frame``'s tuple.
        shapes: Static shape records.
        exact: :meth:`ExactLevel.args`; its records' directions are written.
        buf: ``(2, 6)`` scratch (:func:`exact_buffer`).
    """
    geoms, records, below, call, query_below = exact
    # Unpacked once: an array taken out of a tuple is reference-counted each time.
    fp, fm, tw, tr, rt, ro = frame
    sa = buf[0]
    sb = buf[1]
    for k in range(count):
        if tau[k] < below:
            p = ids[k]
            tau[k] = _exact_tau(
                pairs,
                p,
                records,
                tau[k],
                fp,
                fm,
                tw,
                tr,
                rt,
                ro,
                shapes,
                geoms,
                call,
                query_below,
                sa,
                sb,
            )


@nb.njit(cache=True, inline="always")
def _exact_tau(
    pairs, p, records, coarse, fp, fm, tw, tr, rt, ro, shapes, geoms, call, query_below, sa, sb
):  # pragma: no cover
    """One pair's ``max(coarse, exact)``.

    Any unit direction gives a lower bound, so the direction that served the pair last time
    (kept in its record) is tried first, and MuJoCo is asked for a new one only when the pair is
    still urgent along it (below ``query_below``, a few predictor periods).
    """
    # Rows are indexed, never viewed: a view is reference-counted (exact_pass).
    mode = int(records[p, X_MODE])
    if mode == _NONE:
        return coarse
    g1 = int(records[p, X_G1])
    g2 = int(records[p, X_G2])
    rigid_point_at(g1, geoms, fp, fm, tw, tr, rt, ro, sa)
    spin = _spin(g1, geoms, tw, rt)
    # Relative velocity of the origins, second minus first.
    r0 = -sa[3]
    r1 = -sa[4]
    r2 = -sa[5]
    if mode == _GEOMS:
        rigid_point_at(g2, geoms, fp, fm, tw, tr, rt, ro, sb)
        spin += _spin(g2, geoms, tw, rt)
        r0 += sb[3]
        r1 += sb[4]
        r2 += sb[5]
    if mode == _PLANE:
        # From the geom towards the plane: against the plane's outward normal (its z axis).
        n0 = -fm[g2, 2]
        n1 = -fm[g2, 5]
        n2 = -fm[g2, 8]
        t = _axis_tau(n0, n1, n2, mode, r0, r1, r2, spin, pairs, records, p, fp, fm, shapes, geoms)
        return max(coarse, t)
    best = coarse
    n0 = records[p, X_N]
    n1 = records[p, X_N + 1]
    n2 = records[p, X_N + 2]
    if n0 != 0.0 or n1 != 0.0 or n2 != 0.0:
        t = _axis_tau(n0, n1, n2, mode, r0, r1, r2, spin, pairs, records, p, fp, fm, shapes, geoms)
        best = max(best, t)
        if best >= query_below:
            return best
    fromto = sb  # its state has been read
    c0 = fp[g2, 0] - fp[g1, 0]
    c1 = fp[g2, 1] - fp[g1, 1]
    c2 = fp[g2, 2] - fp[g1, 2]
    # Both origins lie inside their geoms, so the distance is at most theirs: a witness.
    reach = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2) + records[p, X_DIST] + 1.0
    dist: float = _geom_distance(call[0], call[1], call[2], g1, g2, reach, fromto)  # type: ignore[call-arg]
    if not dist > records[p, X_DIST]:
        return best  # in contact, or no witness
    n0 = fromto[3] - fromto[0]
    n1 = fromto[4] - fromto[1]
    n2 = fromto[5] - fromto[2]
    length = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if not length > _MIN_WITNESS * (geoms[g1, GX_RADIUS] + geoms[g2, GX_RADIUS]):
        return best
    n0 /= length
    n1 /= length
    n2 /= length
    # MuJoCo's direction is the best guess for the next look, whether or not it helps now.
    records[p, X_N] = n0
    records[p, X_N + 1] = n1
    records[p, X_N + 2] = n2
    t = _axis_tau(n0, n1, n2, mode, r0, r1, r2, spin, pairs, records, p, fp, fm, shapes, geoms)
    return max(best, t)


@nb.njit(cache=True, inline="always")
def _axis_tau(
    n0, n1, n2, mode, r0, r1, r2, spin, pairs, records, p, fp, fm, shapes, geoms
):  # pragma: no cover
    """tau of the pair's separation along the unit direction ``n`` (first geom to second):
    ``d_n + (n.r - spin) t - delta t - A t^2 / 2`` with ``d_n = min_B n.b - max_A n.a`` from the
    supports and ``r`` the relative velocity of the origins."""
    g2 = int(records[p, X_G2])
    if mode == _PLANE:
        low_b = n0 * fp[g2, 0] + n1 * fp[g2, 1] + n2 * fp[g2, 2]
    elif mode == _SHAPE:
        low_b = -_record_support(shapes, int(pairs[p, PAIR_OTHER]), -n0, -n1, -n2)
    else:
        low_b = -_geom_support(g2, geoms, fp, fm, -n0, -n1, -n2)
    h_a = _geom_support(int(records[p, X_G1]), geoms, fp, fm, n0, n1, n2)
    scale = abs(h_a) + abs(low_b) + records[p, X_DIST]
    gap = low_b - h_a - records[p, X_DIST] - _GAP_SLACK * scale
    if gap <= 0.0:
        return 0.0
    vn = n0 * r0 + n1 * r1 + n2 * r2 - spin
    speed = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2) + spin
    return tau_halfspace(gap, vn, pairs[p, PAIR_ACCEL], pairs[p, PAIR_DELTA] + _VEL_SLACK * speed)


@nb.njit(cache=True)
def exact_buffer():  # pragma: no cover - jitted
    """:func:`exact_pass`'s scratch: two rows of six (the origins' states, the witness)."""
    return np.empty((2, 6))


@dataclasses.dataclass(frozen=True)
class ExactLevel:
    """The tables the exact level reads.

    Attributes:
        geoms: ``(ngeom, 16)`` per-geom records (``pack_spheres`` columns for the origin, then
            the support shape: kind, size, centre, radius).
        records: ``(npair, 8)`` per sphere pair ``[mode, g1, g2, contact distance, n (3), 0]``
            (``n``: the last witness direction that served the pair, zero before the first;
            written by the step).
        exact_below: Pairs whose sphere tau is below this (seconds) are looked at exactly.
        query_below: MuJoCo is asked for a new direction when the pair's tau along its last
            one is below this (seconds).
    """

    geoms: np.ndarray
    records: np.ndarray
    exact_below: float
    query_below: float

    def with_corners(
        self, model: mujoco.MjModel, points: tuple[np.ndarray, np.ndarray, np.ndarray]
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``points`` (``(geom, body, offset)``, the covering's centres) and the box corners of
        every moving geom the level reads: the bounds hold for every point of those geoms
        when they hold at the corners (:func:`corner_points`)."""
        used = self.records[self.records[:, X_MODE] != ExactMode.NONE]
        geoms = np.unique(np.concatenate([used[:, X_G1], used[:, X_G2]]).astype(np.int64))
        geoms = geoms[self.geoms[geoms, GX_KIND] >= 0]  # planes are read by their normal only
        corners = corner_points(model, geoms)
        return tuple(  # type: ignore[return-value]
            np.concatenate([a, b]) for a, b in zip(points, corners, strict=True)
        )

    def args(self, model: mujoco.MjModel, data: mujoco.MjData, records: np.ndarray) -> tuple:
        """The ``exact`` tuple of the compiled step for ``data`` and the held pairs' ``records``.

        The addresses are ``model``'s and ``data``'s: the tuple lives no longer than they do
        (the predictor holds both).
        """
        call = np.array([_ADDRESS.get(), model._address, data._address], dtype=np.int64)
        return (self.geoms, records, float(self.exact_below), call, float(self.query_below))


class _Address:
    """``mj_geomDistance``'s address, looked up once per process."""

    value = 0

    def get(self) -> int:
        if not self.value:
            self.value = geom_distance_address()
        return self.value


_ADDRESS = _Address()


def no_exact() -> tuple:
    """The ``exact`` tuple that never runs (placeholder rows; the threshold is below any tau)."""
    return (np.zeros((1, GX_NCOL)), np.zeros((1, X_NCOL)), -1.0, np.zeros(3, dtype=np.int64), 0.0)


def _geom_records(model: mujoco.MjModel) -> np.ndarray:
    """``(ngeom, 16)`` records of every geom (``GX_KIND`` -1 for types the level skips)."""
    ngeom = model.ngeom
    gtype = np.asarray(model.geom_type, dtype=np.int64)
    rec = np.zeros((ngeom, GX_NCOL))
    rec[:, :8] = pack_spheres(
        np.arange(ngeom), model.geom_bodyid, np.zeros((ngeom, 3)), model.body_rootid
    )
    usable = np.isin(gtype, sorted(EXACT_TYPES))
    rec[:, GX_KIND] = np.where(usable, gtype, -1)
    size = np.asarray(model.geom_size, dtype=np.float64)
    aabb = np.asarray(model.geom_aabb, dtype=np.float64)
    mesh = gtype == int(mujoco.mjtGeom.mjGEOM_MESH)
    # A mesh is held as the box geom_aabb around it (MuJoCo collides its convex hull, which
    # lies in the box): the support is an upper bound of the hull's.
    rec[:, GX_SIZE : GX_SIZE + 3] = np.where(mesh[:, None], aabb[:, 3:], size)
    rec[:, GX_CENTRE : GX_CENTRE + 3] = np.where(mesh[:, None], aabb[:, :3], 0.0)
    rec[mesh, GX_KIND] = int(ShapeKind.MESH_BOX)
    # The radius about the origin: MuJoCo's rbound, and for a mesh the farthest corner of its
    # box, whichever is smaller (both hold every point of the geom).
    corner = np.linalg.norm(np.abs(aabb[:, :3]) + aabb[:, 3:], axis=1)
    rbound = np.asarray(model.geom_rbound, dtype=np.float64)
    rec[:, GX_RADIUS] = np.where(mesh, np.minimum(rbound, corner), rbound)
    return rec


def build_exact(
    model: mujoco.MjModel,
    geom1: npt.ArrayLike,
    geom2: npt.ArrayLike,
    kind: npt.ArrayLike,
    contact_distance: npt.ArrayLike,
    exact_below: float,
    query_below: float = 0.0,
) -> ExactLevel:
    """The exact level's tables for sphere pairs with geoms ``geom1``, ``geom2``.

    Args:
        model: The model.
        geom1: ``(n,)`` geom of each pair's first sphere.
        geom2: ``(n,)`` geom of the second member (a plane geom for half-space pairs, the static
            geom for shape pairs).
        kind: ``(n,)`` ``PairKind`` codes.
        contact_distance: ``(n,)`` the geom pair's contact distance (MuJoCo reports a contact
            below it).
        exact_below: Seconds (``> 0``; ``inf`` looks at every evaluated pair exactly).
        query_below: Seconds: ask MuJoCo for a new direction when the last one leaves the pair
            below this (0: only for a pair without one; ``inf``: at every exact look).

    Raises:
        InvalidInputError: ``exact_below`` is not a positive number.
    """
    if (
        isinstance(exact_below, bool)
        or not isinstance(exact_below, float | int)
        or not (exact_below > 0.0)
    ):
        raise InvalidInputError(
            f"exact_below = {exact_below!r} is invalid: pass a positive number of seconds "
            "(inf to look at every evaluated pair through its geoms)."
        )
    geoms = _geom_records(model)
    g1 = np.asarray(geom1, dtype=np.int64)
    g2 = np.asarray(geom2, dtype=np.int64)
    k = np.asarray(kind)
    ok1 = geoms[g1, GX_KIND] >= 0
    plane = k == KIND_HALFSPACE
    ok2 = plane | (geoms[g2, GX_KIND] >= 0)
    mode = np.where(
        plane, ExactMode.PLANE, np.where(k == KIND_SHAPE, ExactMode.SHAPE, ExactMode.GEOMS)
    )
    rec = np.zeros((g1.shape[0], X_NCOL))
    rec[:, X_MODE] = np.where(ok1 & ok2, mode, ExactMode.NONE)
    rec[:, X_G1] = g1
    rec[:, X_G2] = g2
    rec[:, X_DIST] = np.asarray(contact_distance, dtype=np.float64)
    return ExactLevel(
        geoms=geoms, records=rec, exact_below=float(exact_below), query_below=float(query_below)
    )


def corner_points(
    model: mujoco.MjModel, geoms: npt.ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The eight corners of each geom's box (``geom_aabb``), as bound-check points.

    The acceleration, the one-step discrepancy and the chord speed of a point of a rigid body
    are norms of affine functions of the point's body coordinates, so their maxima over a geom
    lie at the corners of any box around it: bounds checked there hold for every point of the
    geom (docs/theory.md, section 6).

    Args:
        model: The model.
        geoms: ``(k,)`` geom ids.

    Returns:
        ``(point_geom (8k,), point_body (8k,), point_offset (8k, 3))``, the layout of the
        covering's ``(sphere_geom, sphere_body, sphere_offset)``.
    """
    g = np.asarray(geoms, dtype=np.int64).reshape(-1)
    aabb = np.asarray(model.geom_aabb, dtype=np.float64)[g]
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
    offset = aabb[:, None, :3] + signs[None, :, :] * aabb[:, None, 3:]
    body = np.asarray(model.geom_bodyid, dtype=np.int64)[g]
    return np.repeat(g, 8), np.repeat(body, 8), offset.reshape(-1, 3)


def exact_taus(
    tau: np.ndarray,
    ids: npt.ArrayLike,
    pairs: np.ndarray,
    frame: tuple,
    shapes: np.ndarray,
    exact: tuple,
) -> np.ndarray:
    """Raise the sphere taus ``tau`` of pairs ``ids`` to their exact level, in place (the
    reset's path; the step runs the same :func:`exact_pass`).

    Args:
        tau: ``(n,)`` sphere tau of each pair in ``ids`` (overwritten).
        ids: ``(n,)`` pair ids: rows of ``pairs`` and of the exact records in ``exact``.
        pairs: ``pack_pairs`` records.
        frame: ``mjdata_frame`` tuple.
        shapes: Static shape records.
        exact: :meth:`ExactLevel.args`.

    Returns:
        ``tau``.
    """
    idx = np.ascontiguousarray(ids, dtype=np.int64)
    exact_pass(tau, idx, idx.shape[0], pairs, frame, shapes, exact, exact_buffer())
    return tau
