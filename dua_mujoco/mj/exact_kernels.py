"""The exact level's record layouts (proof in docs/theory.md, section 5).

The kernels (the call into ``mj_geomDistance``, the support functions of the geoms at their
current pose, a mesh's by a hill climb on its hull graph, and the pass the step runs over its
evaluated pairs) are the native core's (``dua_mujoco/csrc/src/step.cc``), which reads these
columns; the tables and their construction are in ``dua_mujoco.mj.exact``.
"""

from __future__ import annotations

import enum

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
