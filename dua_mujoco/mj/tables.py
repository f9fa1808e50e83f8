"""What a predictor is built from, as tables: pair ids to geoms and names, plane half-spaces,
and the model fingerprint that tells whether an ``MjData`` may be read with them."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np

from dua_mujoco.mj.covering import Covering
from dua_mujoco.mj.filter import SpherePairs

__all__ = [
    "GEOMETRY_FIELDS",
    "PairTables",
    "contact_options",
    "geom_names",
    "plane_halfspaces",
    "same_geometry",
]


@dataclasses.dataclass(frozen=True)
class PairTables:
    """Read-only lookup tables that turn sphere-pair ids into geoms and names."""

    first: np.ndarray
    second: np.ndarray
    halfspace: np.ndarray
    geom1: np.ndarray
    geom2: np.ndarray
    geom_names: np.ndarray

    @classmethod
    def build(
        cls, model: mujoco.MjModel, covering: Covering, sphere_pairs: SpherePairs
    ) -> PairTables:
        """The tables of ``sphere_pairs`` over ``covering`` (``geom2`` of a half-space pair is
        its plane geom)."""
        sp = sphere_pairs
        plane_geom = np.asarray(covering.plane_geom, dtype=np.int64)
        h = np.asarray(sp.is_halfspace, dtype=bool)
        geom2 = np.where(
            h,
            plane_geom[np.where(h, sp.second, 0)] if plane_geom.size else -1,
            covering.sphere_geom[np.where(h, 0, sp.second)],
        )
        return cls(
            first=np.asarray(sp.first, dtype=np.int64),
            second=np.asarray(sp.second, dtype=np.int64),
            halfspace=h,
            geom1=np.asarray(covering.sphere_geom[sp.first], dtype=np.int64),
            geom2=np.asarray(geom2, dtype=np.int64),
            geom_names=geom_names(model),
        )


def geom_names(model: mujoco.MjModel) -> np.ndarray:
    """``(ngeom,)`` geom names (``geom<id>`` for unnamed geoms), as an object array."""
    names = [
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom{g}"
        for g in range(model.ngeom)
    ]
    return np.asarray(names, dtype=object)


# What the covering (geoms, meshes, height fields), the pair filter (masks, welds, <exclude>,
# <pair>, parent filtering) and the contact distances (margins, gaps) are built from.
GEOMETRY_FIELDS = (
    "geom_type",
    "geom_size",
    "geom_pos",
    "geom_quat",
    "geom_bodyid",
    "geom_dataid",
    "geom_margin",
    "geom_gap",
    "geom_contype",
    "geom_conaffinity",
    "body_parentid",
    "body_weldid",
    "mesh_vert",
    "hfield_size",
    "pair_geom1",
    "pair_geom2",
    "pair_margin",
    "pair_gap",
    "exclude_signature",
)


# The option bits the pair filter and the contact distances read (others, e.g. gravity, do not
# change what the predictor is built from).
_FILTER_DISABLE = (
    mujoco.mjtDisableBit.mjDSBL_CONTACT
    | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    | mujoco.mjtDisableBit.mjDSBL_FILTERPARENT
)


def contact_options(m: mujoco.MjModel) -> tuple[int, int, float]:
    """The contact-relevant option bits: filter disable flags, contact override, ``o_margin``."""
    override = int(m.opt.enableflags) & int(mujoco.mjtEnableBit.mjENBL_OVERRIDE)
    return int(m.opt.disableflags) & int(_FILTER_DISABLE), override, float(m.opt.o_margin)


def same_geometry(a: mujoco.MjModel, b: mujoco.MjModel) -> bool:
    """Whether two models have what a predictor is built from (e.g. one XML loaded twice)."""
    return (
        (a.ngeom, a.nbody, a.nq, a.nv) == (b.ngeom, b.nbody, b.nq, b.nv)
        and contact_options(a) == contact_options(b)
        and all(np.array_equal(getattr(a, f), getattr(b, f)) for f in GEOMETRY_FIELDS)
    )


def plane_halfspaces(data: mujoco.MjData, plane_geom: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Plane half-spaces: outward normals ``(nplane, 3)`` (each plane's local z) and offsets
    ``(nplane,)``; one placeholder row when there is no plane."""
    g = np.asarray(plane_geom, dtype=np.int64)
    if g.size == 0:
        return np.zeros((1, 3)), np.zeros(1)
    normals = np.asarray(data.geom_xmat)[g][:, [2, 5, 8]]
    return normals, np.einsum("ij,ij->i", normals, np.asarray(data.geom_xpos)[g])
