"""MuJoCo's geom type codes as plain ints, the form ``model.geom_type`` holds them in.

The covering, the pair filter and the overlay all compare geom types; they share these instead
of each reading the ``mujoco.mjtGeom`` enum into module constants of its own.
"""

from __future__ import annotations

import mujoco

__all__ = [
    "CONVEX_TYPES",
    "GEOM_BOX",
    "GEOM_CAPSULE",
    "GEOM_CYLINDER",
    "GEOM_ELLIPSOID",
    "GEOM_HFIELD",
    "GEOM_LINE",
    "GEOM_MESH",
    "GEOM_PLANE",
    "GEOM_SDF",
    "GEOM_SPHERE",
]

GEOM_PLANE = int(mujoco.mjtGeom.mjGEOM_PLANE)
GEOM_HFIELD = int(mujoco.mjtGeom.mjGEOM_HFIELD)
GEOM_SPHERE = int(mujoco.mjtGeom.mjGEOM_SPHERE)
GEOM_CAPSULE = int(mujoco.mjtGeom.mjGEOM_CAPSULE)
GEOM_ELLIPSOID = int(mujoco.mjtGeom.mjGEOM_ELLIPSOID)
GEOM_CYLINDER = int(mujoco.mjtGeom.mjGEOM_CYLINDER)
GEOM_BOX = int(mujoco.mjtGeom.mjGEOM_BOX)
GEOM_MESH = int(mujoco.mjtGeom.mjGEOM_MESH)
GEOM_SDF = int(mujoco.mjtGeom.mjGEOM_SDF)
GEOM_LINE = int(mujoco.mjtGeom.mjGEOM_LINE)
"""Decorative line (the overlay's connectors); never a model geom."""

CONVEX_TYPES = (GEOM_SPHERE, GEOM_CAPSULE, GEOM_ELLIPSOID, GEOM_CYLINDER, GEOM_BOX, GEOM_MESH)
"""The convex types with a support function here (a mesh: its hull): what a static shape and
the exact level can be."""
