"""What a predictor is built from, as tables: pair ids to geoms and names, plane half-spaces,
static shape records, and the model fingerprint that tells whether an ``MjData`` may be read
with them."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np

from dua_mujoco import _core
from dua_mujoco.build.covering import Covering
from dua_mujoco.build.filter import SpherePairs
from dua_mujoco.core.pairset import KIND_SHAPE
from dua_mujoco.core.shapes import SHAPE_NCOL, ShapeKind, mesh_box, pack_shapes
from dua_mujoco.core.terrain import pack_terrain, shape_table
from dua_mujoco.exceptions import InvalidInputError

__all__ = [
    "GEOMETRY_FIELDS",
    "PairTables",
    "check_data",
    "check_forwarded",
    "contact_options",
    "geom_names",
    "plane_halfspaces",
    "same_geometry",
    "static_shapes",
]


@dataclasses.dataclass(frozen=True)
class PairTables:
    """Read-only lookup tables that turn sphere-pair ids into geoms and names.

    Attributes:
        first: ``(n,)`` sphere of each pair.
        second: ``(n,)`` sphere, plane index or shape index, by ``kind``.
        halfspace: ``(n,)`` bool, half-space pairs.
        geom1: ``(n,)`` geom of ``first``.
        geom2: ``(n,)`` geom of ``second``: the plane geom of a half-space pair, the static
            geom of a shape pair.
        geom_names: ``(ngeom,)`` names.
        kind: ``(n,)`` int8 ``PairKind`` codes.
    """

    first: np.ndarray
    second: np.ndarray
    halfspace: np.ndarray
    geom1: np.ndarray
    geom2: np.ndarray
    geom_names: np.ndarray
    kind: np.ndarray

    @classmethod
    def build(
        cls,
        model: mujoco.MjModel,
        covering: Covering,
        sphere_pairs: SpherePairs,
    ) -> PairTables:
        """The tables of ``sphere_pairs`` over ``covering`` (``geom2`` of a half-space pair is
        its plane geom, of a shape pair its static geom)."""
        sp = sphere_pairs
        kind = sp.kind
        second = np.asarray(sp.second, dtype=np.int64)
        geom2 = np.full(second.shape, -1, dtype=np.int64)
        h = np.asarray(sp.is_halfspace, dtype=bool)
        s = kind == KIND_SHAPE
        geom2[h] = np.asarray(covering.plane_geom, dtype=np.int64)[second[h]]
        geom2[s] = np.asarray(covering.shape_geom, dtype=np.int64)[second[s]]
        geom2[~(h | s)] = covering.sphere_geom[second[~(h | s)]]
        first = np.asarray(sp.first, dtype=np.int64)
        geom1 = np.asarray(covering.sphere_geom[sp.first], dtype=np.int64)
        return cls(first, second, h, geom1, geom2, geom_names(model), kind)


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
    "hfield_nrow",
    "hfield_ncol",
    "hfield_data",
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


# How far a static geom's pose in MjData may be from the one the model gives it: both come from
# the same mj_kinematics arithmetic on the same constants, so they agree to the last bit; the
# tolerance only absorbs a different summation order in a future MuJoCo.
_STATIC_POSE_TOL = 1e-9


def static_shapes(
    model: mujoco.MjModel, shape_geom: np.ndarray, data: mujoco.MjData | None = None
) -> np.ndarray:
    """Shape records of the static geoms, optionally checked against ``data``.

    A body welded to the world (``body_weldid == 0``) has no joint and no mocap body between it
    and the world, so ``mj_kinematics`` computes its geoms' poses from model constants only
    (``body_pos``, ``body_quat``, ``geom_pos``, ``geom_quat`` along the chain): they are the same
    at every step, and the records can be packed once. They are packed here from a scratch
    ``MjData`` of ``model`` and, when given, compared with ``data``: a mismatch means ``data`` is
    not of this model's placement of the static geoms (another model with the same geoms but
    moved bodies, a model edited since ``data``'s last ``mj_forward``, or poses written by hand),
    and the prediction would be wrong.

    Args:
        shape_geom: ``(nshape,)`` static geoms (``Covering.shape_geom``).
        data: its data, kinematics computed, or None for no check.

    Returns:
        ``(nshape, 16)`` records (``dua_mujoco.core.shapes``), then the blocks of the height
        fields' records (``dua_mujoco.core.terrain``); one placeholder row (never read) when
        there is no shape.

    Raises:
        InvalidInputError: a static geom's pose in ``data`` differs from the model's.
    """
    g = np.asarray(shape_geom, dtype=np.int64)
    if g.size == 0:
        return np.zeros((1, SHAPE_NCOL))
    pos, mat = static_poses(model, g)
    if data is not None:
        _check_static_poses(model, g, pos, mat, data)
    types = np.asarray(model.geom_type, dtype=np.int64)[g]
    size = np.asarray(model.geom_size, dtype=np.float64)[g]  # (indexing copies)
    mesh = types == int(ShapeKind.MESH_BOX)
    if mesh.any():
        half, centre = mesh_box(np.asarray(model.geom_aabb)[g[mesh]], pos[mesh], mat[mesh])
        size[mesh] = half
        pos[mesh] = centre
    terrain = types == int(ShapeKind.HFIELD)
    records = np.zeros((g.size, SHAPE_NCOL))
    if (~terrain).any():
        records[~terrain] = pack_shapes(
            types[~terrain], size[~terrain], pos[~terrain], mat[~terrain]
        )
    # Height fields: their grids' blocks after the records (dua_mujoco.core.terrain).
    blocks = {}
    for k in np.flatnonzero(terrain).tolist():
        h = int(model.geom_dataid[g[k]])
        adr, nrow, ncol = (
            int(a[h]) for a in (model.hfield_adr, model.hfield_nrow, model.hfield_ncol)
        )
        records[k], blocks[k] = pack_terrain(
            model.hfield_size[h],
            nrow,
            ncol,
            model.hfield_data[adr : adr + nrow * ncol],
            pos[k],
            mat[k],
        )
    return shape_table(records, blocks)


def static_poses(model: mujoco.MjModel, shape_geom: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The static geoms' ``(n, 3)`` positions and ``(n, 9)`` frames as the model places them
    (``mj_kinematics`` on a scratch ``MjData``)."""
    scratch = mujoco.MjData(model)
    mujoco.mj_kinematics(model, scratch)
    g = np.asarray(shape_geom, dtype=np.int64)
    return np.asarray(scratch.geom_xpos)[g], np.asarray(scratch.geom_xmat)[g]


def check_static_geoms(
    model: mujoco.MjModel,
    shape_geom: np.ndarray,
    data: mujoco.MjData,
    records: np.ndarray,
) -> None:
    """At a reset: refuse ``data`` whose static geoms are not where the model places them, then
    a model whose static geoms were moved, resized or reshaped since the tables were built from
    it (``records``: the ``static`` table, held to the model by the native guard the plugin runs
    too: poses, ``geom_size``, a height field's data, a mesh). The shape records, the covering
    and the pair filter are built once, so an edit of ``body_pos``, ``geom_pos``, ``geom_size``
    or ``hfield_data`` would leave them as the geoms were.

    Raises:
        InvalidInputError: naming the first static geom that differs, and the fix.
    """
    g = np.asarray(shape_geom, dtype=np.int64)
    if g.size == 0:
        return
    pos, mat = static_poses(model, g)
    _check_static_poses(model, g, pos, mat, data)
    edited = _core.static_mismatch(model, records)
    if edited:
        raise InvalidInputError(
            f"{edited}: the model was edited (body_pos, geom_pos, geom_size, hfield_data, a "
            "mesh, ...) after the predictor was built, and its tables are built once. Build a "
            "new Predictor for the edited model."
        )


def _check_static_poses(
    model: mujoco.MjModel, g: np.ndarray, pos: np.ndarray, mat: np.ndarray, data: mujoco.MjData
) -> None:
    dpos = np.asarray(data.geom_xpos)[g]
    dmat = np.asarray(data.geom_xmat)[g]
    err = np.maximum(np.abs(dpos - pos).max(axis=1), np.abs(dmat - mat).max(axis=1))
    bad = np.flatnonzero(~(err <= _STATIC_POSE_TOL))  # a NaN among them
    if bad.size:
        k = int(bad[0])
        name = geom_names(model)[g[k]]
        raise InvalidInputError(
            f"static geom {int(g[k])} ({name!r}) is at {dpos[k].tolist()} in data but the model "
            f"places it at {pos[k].tolist()} (|difference| {float(err[k]):.3g}; {bad.size} "
            "static geom(s) differ): a geom welded to the world must not move. Pass the data of "
            "this model after mujoco.mj_forward(model, data), or build a Predictor for the model "
            "data belongs to (after editing body_pos, geom_pos, ...: a new Predictor)."
        )


def check_model(model: object, fix: str = "") -> None:
    """Refuse anything but an ``MjModel``; ``fix`` ends the message (``: load it with ...``)."""
    if not isinstance(model, mujoco.MjModel):
        raise InvalidInputError(f"model must be a mujoco.MjModel, got {type(model).__name__}{fix}.")


def check_data(model: mujoco.MjModel, data: object) -> None:
    """Refuse anything but an ``MjData`` of ``model``, or of a model with the same geometry (one
    XML loaded twice): the native step reads ``MjData`` without bounds checks, and the covering
    and the pair filter must be this model's."""
    if not isinstance(data, mujoco.MjData):
        raise InvalidInputError(
            f"data must be a mujoco.MjData, got {type(data).__name__}: pass "
            "mujoco.MjData(model) after mujoco.mj_forward(model, data)."
        )
    if data.model is not model and not same_geometry(data.model, model):
        raise InvalidInputError(
            f"data belongs to another MjModel ({data.model.ngeom} geoms, {data.model.nbody} "
            f"bodies; this predictor's has {model.ngeom} and {model.nbody}) whose geoms, bodies "
            "or collision filters differ: pass the MjData of this predictor's model, or build "
            "a Predictor for that model."
        )


def check_forwarded(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Refuse an ``MjData`` whose kinematics were never computed: fresh from
    ``mujoco.MjData(model)`` every rotation matrix is zero, every geom sits at the origin and
    every pair would alarm."""
    if model.ngeom and not np.asarray(data.geom_xmat).any():
        raise InvalidInputError(
            "data holds no kinematics (every geom rotation is zero: mj_forward was never "
            "called): call mujoco.mj_forward(model, data) (or mj_step) before "
            "predictor.reset(data)."
        )
