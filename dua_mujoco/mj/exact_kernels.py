"""Compiled kernels of the exact level (proof in docs/theory.md, section 5).

The record layouts, the C call into ``mj_geomDistance``, the support functions of the geoms at
their current pose (a mesh by a hill climb on its hull graph), and the pass the fused step runs
over its evaluated pairs; the tables, their construction and the vectorised front are in
``dua_mujoco.mj.exact``, which re-exports what is public here.
"""

from __future__ import annotations

import ctypes
import enum
import math
import os

import mujoco
import numba as nb
import numpy as np
from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

from dua_mujoco.core.pairset import PAIR_ACCEL, PAIR_DELTA
from dua_mujoco.core.shape_kernels import support_local
from dua_mujoco.core.urgency import tau_halfspace
from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.mj.kinematics import SPHERE_BODY, SPHERE_ROOT, rigid_point_at

__all__ = [
    "GX_CENTRE",
    "GX_GRAPH",
    "GX_KIND",
    "GX_NCOL",
    "GX_RADIUS",
    "GX_SEED",
    "GX_SIZE",
    "GX_VERT",
    "X_DIST",
    "X_G1",
    "X_G2",
    "X_HULL1",
    "X_HULL2",
    "X_MODE",
    "X_N",
    "X_NCOL",
    "ExactMode",
    "exact_buffer",
    "exact_pass",
    "geom_distance_address",
]


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
GX_VERT = 16  # a mesh with a hull graph: its first vertex in the vertex table, else -1
GX_GRAPH = 17  # ... and its hull graph's address in MuJoCo's mesh_graph
GX_SEED = 18  # 6 columns: the hull vertices (local ids) farthest along -x, +x, -y, +y, -z, +z
GX_NCOL = 24
# Columns of the per-pair records: the last direction that served the pair starts at X_N.
# Then the hull vertices (local ids) that were highest last time, per side, -1 for none.
X_MODE, X_G1, X_G2, X_DIST, X_N, X_HULL1, X_HULL2 = 0, 1, 2, 3, 4, 7, 8
X_NCOL = 10

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
def _hull_support(g, geoms, verts, graph, m0, m1, m2, start):  # pragma: no cover - jitted
    """``max m.v`` over the hull vertices of mesh geom ``g`` (local direction ``m``).

    A hill climb on MuJoCo's hull graph, as MuJoCo's own GJK does: on a convex polytope a vertex
    no neighbour of which is higher along ``m`` is highest (a linear function's local maximum
    over a polytope is global). It starts at the stored extreme vertex of the axis nearest ``m``.
    """
    v0 = int(geoms[g, GX_VERT])
    adr = int(geoms[g, GX_GRAPH])
    numvert = graph[adr]
    edgeadr = adr + 2
    globalid = adr + 2 + numvert
    localid = adr + 2 + 2 * numvert
    a0, a1, a2 = abs(m0), abs(m1), abs(m2)
    if a0 >= a1 and a0 >= a2:
        seed = GX_SEED + (1 if m0 > 0.0 else 0)
    elif a1 >= a2:
        seed = GX_SEED + (3 if m1 > 0.0 else 2)
    else:
        seed = GX_SEED + (5 if m2 > 0.0 else 4)
    imax = int(geoms[g, seed])
    v = v0 + graph[globalid + imax]
    best = m0 * verts[v, 0] + m1 * verts[v, 1] + m2 * verts[v, 2]
    if start >= 0:  # the vertex that was highest last time, if it is higher than the seed
        v = v0 + graph[globalid + start]
        val = m0 * verts[v, 0] + m1 * verts[v, 1] + m2 * verts[v, 2]
        if val > best:
            best = val
            imax = start
    prev = -1
    while imax != prev:
        prev = imax
        i = graph[edgeadr + imax]
        while graph[localid + i] >= 0:
            sub = graph[localid + i]
            v = v0 + graph[globalid + sub]
            val = m0 * verts[v, 0] + m1 * verts[v, 1] + m2 * verts[v, 2]
            if val > best:
                best = val
                imax = sub
            i += 1
    return best, imax


@nb.njit(cache=True, inline="always")
def _geom_support(g, geoms, verts, graph, fp, fm, n0, n1, n2, start):  # pragma: no cover
    """Support of geom ``g`` at its current pose along ``n``: ``max n.p`` over the geom (a mesh:
    over its hull's vertices when MuJoCo has its hull graph, else over its box)."""
    m = fm  # fp, fm: the frame's positions and rotations (geom_xpos, geom_xmat)
    if geoms[g, GX_GRAPH] >= 0.0:
        l0 = m[g, 0] * n0 + m[g, 3] * n1 + m[g, 6] * n2
        l1 = m[g, 1] * n0 + m[g, 4] * n1 + m[g, 7] * n2
        l2 = m[g, 2] * n0 + m[g, 5] * n1 + m[g, 8] * n2
        h, top = _hull_support(g, geoms, verts, graph, l0, l1, l2, start)
        return n0 * fp[g, 0] + n1 * fp[g, 1] + n2 * fp[g, 2] + h, top
    # The support shape's centre: the origin plus R c (c: a mesh box's centre, else 0).
    c0 = geoms[g, GX_CENTRE]
    c1 = geoms[g, GX_CENTRE + 1]
    c2 = geoms[g, GX_CENTRE + 2]
    p0 = fp[g, 0] + m[g, 0] * c0 + m[g, 1] * c1 + m[g, 2] * c2
    p1 = fp[g, 1] + m[g, 3] * c0 + m[g, 4] * c1 + m[g, 5] * c2
    p2 = fp[g, 2] + m[g, 6] * c0 + m[g, 7] * c1 + m[g, 8] * c2
    kind = int(geoms[g, GX_KIND])
    s0, s1, s2 = geoms[g, GX_SIZE], geoms[g, GX_SIZE + 1], geoms[g, GX_SIZE + 2]
    return _support(kind, s0, s1, s2, m, g, 0, p0, p1, p2, n0, n1, n2), -1


@nb.njit(cache=True)
def exact_pass(tau, ids, count, pairs, frame, exact, buf):  # pragma: no cover - jitted
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
        exact: :meth:`ExactLevel.args`; its records' directions are written.
        buf: ``(2, 6)`` scratch (:func:`exact_buffer`).
    """
    # vx, gr: the mesh vertices and hull graphs (ExactLevel.verts, .graph).
    geoms, records, below, call, query_below, vx, gr = exact
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
                geoms,
                vx,
                gr,
                call,
                query_below,
                sa,
                sb,
            )


@nb.njit(cache=True, inline="always")
def _exact_tau(
    pairs,
    p,
    records,
    coarse,
    fp,
    fm,
    tw,
    tr,
    rt,
    ro,
    geoms,
    vx,
    gr,
    call,
    query_below,
    sa,
    sb,
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
        t = _axis_tau(n0, n1, n2, mode, r0, r1, r2, spin, pairs, records, p, fp, fm, geoms, vx, gr)
        return max(coarse, t)
    best = coarse
    n0 = records[p, X_N]
    n1 = records[p, X_N + 1]
    n2 = records[p, X_N + 2]
    if n0 != 0.0 or n1 != 0.0 or n2 != 0.0:
        t = _axis_tau(n0, n1, n2, mode, r0, r1, r2, spin, pairs, records, p, fp, fm, geoms, vx, gr)
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
    t = _axis_tau(n0, n1, n2, mode, r0, r1, r2, spin, pairs, records, p, fp, fm, geoms, vx, gr)
    return max(best, t)


@nb.njit(cache=True, inline="always")
def _axis_tau(
    n0, n1, n2, mode, r0, r1, r2, spin, pairs, records, p, fp, fm, geoms, vx, gr
):  # pragma: no cover
    """tau of the pair's separation along the unit direction ``n`` (first geom to second):
    ``d_n + (n.r - spin) t - delta t - A t^2 / 2`` with ``d_n = min_B n.b - max_A n.a`` from the
    supports and ``r`` the relative velocity of the origins."""
    g2 = int(records[p, X_G2])
    if mode == _PLANE:
        low_b = n0 * fp[g2, 0] + n1 * fp[g2, 1] + n2 * fp[g2, 2]
    else:  # a moving geom, or a static one (its pose in MjData is as good as the shape's)
        h_b, top = _geom_support(g2, geoms, vx, gr, fp, fm, -n0, -n1, -n2, int(records[p, X_HULL2]))
        low_b = -h_b
        records[p, X_HULL2] = top
    g1 = int(records[p, X_G1])
    h_a, top = _geom_support(g1, geoms, vx, gr, fp, fm, n0, n1, n2, int(records[p, X_HULL1]))
    records[p, X_HULL1] = top
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
