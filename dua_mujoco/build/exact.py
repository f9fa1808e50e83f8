"""The exact level of the urgency: a conservative tau from the geoms themselves, not their balls.

A pair whose sphere tau is below ``exact_below`` is looked at again through its two geoms:
MuJoCo's narrowphase (``mj_geomDistance``, which the native step calls) gives a witness
direction ``n``, this package's own support functions the separation ``d_n`` of the geoms along
it (never MuJoCo's distance, whose tolerance could make it too large), and the pair's bounds,
which hold for every point of both geoms, bound how fast it can close; the first root
(:func:`~dua_mujoco.core.urgency.time_to_halfspace`'s) is a second lower bound, and the pair's
tau the larger of the two (proof in docs/theory.md, section 5; a plane needs no query). A
height field held as terrain is read through its grid (``ExactMode.TERRAIN``, section 9); SDF
geoms, height fields covered by spheres and pairs with a degenerate witness keep their sphere
tau.
"""

from __future__ import annotations

import dataclasses
import enum

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco._core import LAYOUT, exact_rows
from dua_mujoco.build.events import BodyBoxes
from dua_mujoco.build.geom_types import CONVEX_TYPES, GEOM_HFIELD, GEOM_MESH
from dua_mujoco.build.kinematics import pack_spheres
from dua_mujoco.core.shapes import ShapeKind

__all__ = [
    "EXACT_PERIODS",
    "EXACT_TYPES",
    "GX_CENTRE",
    "GX_GRAPH",
    "GX_KIND",
    "GX_NCOL",
    "GX_RADIUS",
    "GX_SEED",
    "GX_SIZE",
    "GX_VERT",
    "QUERY_PERIODS",
    "X_DIST",
    "X_G1",
    "X_G2",
    "X_HULL1",
    "X_HULL2",
    "X_MODE",
    "X_N",
    "X_NCOL",
    "ExactLevel",
    "ExactMode",
    "build_exact",
    "corner_points",
    "exact_records",
]


class ExactMode(enum.IntEnum):
    """What the exact level does for a pair (``X_MODE``)."""

    NONE = LAYOUT["ExactMode.NONE"]
    """Keep the sphere tau (a height field covered by spheres, an SDF, or the level is off)."""
    GEOMS = LAYOUT["ExactMode.GEOMS"]
    """Two geoms that may both move: ``mj_geomDistance`` gives the direction."""
    PLANE = LAYOUT["ExactMode.PLANE"]
    """A geom and a plane: the plane's normal is the direction."""
    SHAPE = LAYOUT["ExactMode.SHAPE"]
    """A geom and a static shape (its record in the shape table): ``mj_geomDistance``."""
    TERRAIN = LAYOUT["ExactMode.TERRAIN"]
    """A geom and a height field held as terrain: the prisms of its grid (``terrain.cc``), never
    ``mj_geomDistance``, which is no lower bound there."""


# Columns of the per-geom records: the first eight are ``pack_spheres``' (a "sphere" at the geom
# origin, whose velocity the kinematics kernel gives), then the support shape: its kind
# (ShapeKind, 1 for a height field read as terrain, -1 where the level does not apply), size
# (3), centre in the geom frame (3, a mesh's box centre), radius (max |p - origin| over the
# geom's points), a mesh's first vertex and hull
# graph address (-1: none), and six seeds of the hull climb (the hull vertices farthest along
# -x, +x, -y, +y, -z, +z).
GX_KIND, GX_SIZE, GX_CENTRE = LAYOUT["GX_KIND"], LAYOUT["GX_SIZE"], LAYOUT["GX_CENTRE"]
GX_RADIUS, GX_VERT, GX_GRAPH = LAYOUT["GX_RADIUS"], LAYOUT["GX_VERT"], LAYOUT["GX_GRAPH"]
GX_SEED, GX_NCOL = LAYOUT["GX_SEED"], LAYOUT["GX_NCOL"]
# Columns of the per-pair records: mode, geoms, contact distance, the last direction that served
# the pair (3), the hull vertices (local ids) highest last time per side (-1: none).
X_MODE, X_G1, X_G2, X_DIST = LAYOUT["X_MODE"], LAYOUT["X_G1"], LAYOUT["X_G2"], LAYOUT["X_DIST"]
X_N, X_HULL1, X_HULL2, X_NCOL = (
    LAYOUT["X_N"],
    LAYOUT["X_HULL1"],
    LAYOUT["X_HULL2"],
    LAYOUT["X_NCOL"],
)

EXACT_PERIODS = 1
"""Pairs whose sphere tau is below this many predictor periods past the latency are looked at
through their geoms: the alarm horizon, where the look can clear an alarm. Measured on 34
scenes (docs/benchmarks.md) against 2 periods: the same standing alarms on every scene, 0-2 %
more evaluations, dmc_dog 1.49x -> 1.27x of ``mj_step``, the rest within noise (the native step
makes a sphere tau cheap next to a look)."""
QUERY_PERIODS = 1
"""MuJoCo is asked for a new direction when the pair's tau along its last one is below this
many predictor periods past the latency: the alarm horizon, the only place a better direction
can clear an alarm (above it, it would only lengthen a revisit interval). Measured on 34 scenes
(docs/benchmarks.md) against 4 periods: the same standing alarms on every scene, 1-5 % more
evaluations, and the predictor 0.32x -> 0.25x of ``mj_step`` (median over robots; aloha 1.17x ->
0.47x: MuJoCo's distances between its gripper meshes were most of its step)."""

EXACT_TYPES = frozenset(CONVEX_TYPES)
"""Geom types the exact level reads (convex, with a support function here); planes too, as the
second member of a half-space pair."""


@dataclasses.dataclass(frozen=True)
class ExactLevel:
    """The tables the exact level reads.

    Attributes:
        geoms: ``(ngeom, 16)`` per-geom records (``pack_spheres`` columns for the origin, then
            the support shape: kind, size, centre, radius).
        records: ``(npair, 10)`` per sphere pair ``[mode, g1, g2, contact distance, n (3),
            hull vertex 1, hull vertex 2]``
            (``n``: the last witness direction that served the pair, zero before the first;
            written by the step).
        exact_below: Pairs whose sphere tau is below this (seconds) are looked at exactly.
        query_below: MuJoCo is asked for a new direction when the pair's tau along its last
            one is below this (seconds).
        verts: ``(nmeshvert, 3)`` mesh vertices in their geoms' frames (``mesh_vert``, float64).
        graph: MuJoCo's ``mesh_graph`` (the hulls' vertex graphs), int32.
    """

    geoms: np.ndarray
    records: np.ndarray
    exact_below: float
    query_below: float
    verts: np.ndarray
    graph: np.ndarray

    def with_corners(
        self,
        model: mujoco.MjModel,
        points: tuple[np.ndarray, np.ndarray, np.ndarray],
        geoms: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``points`` (``(geom, body, offset)``, the covering's centres) and the box corners of
        every moving geom the level reads (``geoms``, by default those of its records): the
        bounds hold for every point of those geoms when they hold at the corners
        (:func:`corner_points`)."""
        if geoms is None:
            used = self.records[self.records[:, X_MODE] != ExactMode.NONE]
            geoms = np.unique(np.concatenate([used[:, X_G1], used[:, X_G2]]).astype(np.int64))
        # Planes are read by their normal only, height fields (static) by their grid.
        geoms = geoms[self.geoms[geoms, GX_KIND] >= int(ShapeKind.SPHERE)]
        corners = corner_points(model, geoms)
        return tuple(  # type: ignore[return-value]
            np.concatenate([a, b]) for a, b in zip(points, corners, strict=True)
        )


def _geom_records(model: mujoco.MjModel) -> np.ndarray:
    """``(ngeom, 24)`` records of every geom (``GX_KIND`` -1 for types the level skips)."""
    ngeom = model.ngeom
    gtype = np.asarray(model.geom_type, dtype=np.int64)
    rec = np.zeros((ngeom, GX_NCOL))
    rec[:, :8] = pack_spheres(
        np.arange(ngeom), model.geom_bodyid, np.zeros((ngeom, 3)), model.body_rootid
    )
    usable = np.isin(gtype, sorted(EXACT_TYPES))
    rec[:, GX_KIND] = np.where(usable, gtype, -1)
    # A height field: terrain pairs (ExactMode.TERRAIN) read its grid, sphere pairs nothing.
    rec[gtype == GEOM_HFIELD, GX_KIND] = int(ShapeKind.HFIELD)
    size = np.asarray(model.geom_size, dtype=np.float64)
    aabb = np.asarray(model.geom_aabb, dtype=np.float64)
    mesh = gtype == GEOM_MESH
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
    # Meshes with a hull graph: their hull vertices (what MuJoCo collides), by a hill climb.
    rec[:, GX_VERT] = -1.0
    rec[:, GX_GRAPH] = -1.0
    verts, graph = _hull_tables(model)
    for g in np.flatnonzero(mesh):
        mesh_id = int(model.geom_dataid[g])
        adr = int(model.mesh_graphadr[mesh_id])
        if adr < 0:
            continue  # no hull graph: the box stands
        v0 = int(model.mesh_vertadr[mesh_id])
        numvert = int(graph[adr])
        hull = verts[v0 + graph[adr + 2 + numvert : adr + 2 + 2 * numvert]]
        rec[g, GX_VERT] = v0
        rec[g, GX_GRAPH] = adr
        # Seeds of the climb: the hull's extreme vertices along -x, +x, -y, +y, -z, +z.
        for axis in range(3):
            rec[g, GX_SEED + 2 * axis] = int(np.argmin(hull[:, axis]))
            rec[g, GX_SEED + 2 * axis + 1] = int(np.argmax(hull[:, axis]))
    return rec


def _hull_tables(model: mujoco.MjModel | None) -> tuple[np.ndarray, np.ndarray]:
    """``(verts (nmeshvert, 3) float64, graph int32)`` of ``model`` (placeholders for None)."""
    if model is None or model.nmeshvert == 0:
        return np.zeros((1, 3)), np.full(1, -1, dtype=np.int32)
    graph = np.asarray(model.mesh_graph, dtype=np.int32)
    if graph.size == 0:
        graph = np.full(1, -1, dtype=np.int32)
    verts = np.ascontiguousarray(model.mesh_vert, dtype=np.float64).reshape(-1, 3)
    return verts, np.ascontiguousarray(graph)


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
        geom1: ``(n,)`` geom of each pair's first sphere.
        geom2: ``(n,)`` geom of the second member (a plane geom for half-space pairs, the static
            geom for shape pairs).
        kind: ``(n,)`` ``PairKind`` codes.
        contact_distance: ``(n,)`` the geom pair's contact distance (MuJoCo reports a contact
            below it).
        exact_below: Seconds (``> 0``, checked by ``UrgencyOptions``; ``inf`` looks at every
            evaluated pair exactly).
        query_below: Seconds: ask MuJoCo for a new direction when the last one leaves the pair
            below this (0: only for a pair without one; ``inf``: at every exact look).
    """
    geoms = _geom_records(model)
    verts, graph = _hull_tables(model)
    rec = exact_records(geoms, geom1, geom2, kind, contact_distance)
    return ExactLevel(
        geoms=geoms,
        records=rec,
        exact_below=float(exact_below),
        query_below=float(query_below),
        verts=verts,
        graph=graph,
    )


def exact_records(
    geoms: np.ndarray,
    geom1: npt.ArrayLike,
    geom2: npt.ArrayLike,
    kind: npt.ArrayLike,
    contact_distance: npt.ArrayLike,
) -> np.ndarray:
    """``(n, X_NCOL)`` records of sphere pairs (``build_exact``'s arguments) over the level's
    per-geom records ``geoms``: a pruned predictor adds the pairs it meets with these."""
    g1 = np.asarray(geom1, dtype=np.int64)
    dist = np.broadcast_to(np.asarray(contact_distance, dtype=np.float64), g1.shape)
    return exact_rows(geoms, g1, np.asarray(geom2, dtype=np.int64), np.asarray(kind, np.int8), dist)


def corner_points(
    model: mujoco.MjModel, geoms: npt.ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The eight corners of the box (``geom_aabb``) of each of the ``(k,)`` geoms ``geoms``, as
    bound-check points.

    The acceleration, the one-step discrepancy and the chord speed of a point of a rigid body
    are norms of affine functions of the point's body coordinates, so their maxima over a geom
    lie at the corners of any box around it: bounds checked there hold for every point of the
    geom (docs/theory.md, section 5).

    Returns:
        ``(point_geom (8k,), point_body (8k,), point_offset (8k, 3))``, the layout of the
        covering's ``(sphere_geom, sphere_body, sphere_offset)``.
    """
    g = np.asarray(geoms, dtype=np.int64).reshape(-1)
    aabb = np.asarray(model.geom_aabb, dtype=np.float64)[g]
    body = np.asarray(model.geom_bodyid, dtype=np.int64)[g]
    return BodyBoxes(g, body, aabb[:, :3], aabb[:, 3:]).corners()
