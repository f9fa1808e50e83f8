"""Geoms -> spheres and half-spaces.

Every collidable geom is replaced by spheres whose union contains its solid (a mesh's: its
convex hull, which MuJoCo collides): ``BOUNDING``, one sphere a geom (MuJoCo's ``geom_rbound``),
or ``MULTI``, at most ``max_spheres_per_geom`` a geom (spheres exact, capsules along their
segment, other solids one sphere a grid cell that can meet the solid; the bounding sphere where
it is smaller). Planes stay half-spaces, static geoms their own convex shapes (``static="shape"``,
docs/static-shapes.md), static height fields terrain (``hfield="terrain"``, docs/theory.md,
section 9). A collision of two geoms then implies one of their spheres (shapes, half-spaces)
meeting; docs/covering-and-pairs.md gives the containment argument per geom type.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco.build.bounds import moving_bodies
from dua_mujoco.build.geom_types import (
    CONVEX_TYPES,
    GEOM_BOX,
    GEOM_CAPSULE,
    GEOM_CYLINDER,
    GEOM_ELLIPSOID,
    GEOM_HFIELD,
    GEOM_PLANE,
    GEOM_SDF,
    GEOM_SPHERE,
)
from dua_mujoco.build.kinematics import pack_spheres, sphere_states
from dua_mujoco.build.multicover import (
    capsule_cover,
    grid_cover,
    keep_convex,
    keep_cylinder,
    keep_ellipsoid,
    mesh_hull_planes,
    mesh_vertices,
    union_volume,
)
from dua_mujoco.core.validate import check_int
from dua_mujoco.exceptions import (
    InvalidChoiceError,
    InvalidInputError,
    ShapeError,
    UnsupportedGeomError,
)

__all__ = [
    "HFIELD_CHOICES",
    "STATIC_CHOICES",
    "Covering",
    "CoveringMode",
    "cover_model",
    "sphere_world_centers",
    "static_shape_geoms",
    "terrain_geoms",
]


HFIELD_CHOICES = ("terrain", "box", "error")
"""``cover_model``'s ``hfield`` option: static height fields as terrain (the prisms of their
grid), every height field covered by its bounding box, or refused."""
STATIC_CHOICES = ("shape", "sphere")
"""``cover_model``'s ``static`` option: static geoms as their own shapes, or as spheres."""


class CoveringMode(enum.Enum):
    """How geoms are covered by spheres."""

    BOUNDING = "bounding"
    """One sphere per geom: centre at the geom origin, radius ``m.geom_rbound``."""

    MULTI = "multi"
    """Up to ``max_spheres_per_geom`` spheres per geom, over the segment or a grid of cells."""


@dataclass(frozen=True)
class Covering:
    """Spheres (and half-spaces) that together contain every covered geom of a model.

    Sphere ids index the ``sphere_*`` arrays; the spheres of geom ``g`` are the contiguous range
    ``geom_sphere_start[g]:geom_sphere_start[g + 1]`` (CSR layout). Planes, static shapes and
    uncovered geoms (geoms that can never collide) have no spheres; planes are listed in
    ``plane_geom``, static shapes in ``shape_geom``.

    Attributes:
        sphere_geom: ``(nsphere,)`` int32, the geom each sphere covers.
        sphere_body: ``(nsphere,)`` int32, the body of that geom.
        sphere_offset: ``(nsphere, 3)`` float64, sphere centre in the geom frame.
        sphere_radius: ``(nsphere,)`` float64, sphere radius.
        geom_sphere_start: ``(ngeom + 1,)`` int32, CSR start of each geom's spheres.
        plane_geom: ``(nplane,)`` int32, geom ids of plane geoms (half-spaces).
        geom_plane: ``(ngeom,)`` int32, plane index of each geom, or -1.
        mode: the covering mode used.
        plane_static: ``(nplane,)`` bool, the plane's body is welded to the world (only static
            planes are fixed half-spaces).
        shape_geom: ``(nshape,)`` int32, geom ids of static geoms held as their own convex shape
            or, for height fields, as terrain (records packed by
            ``dua_mujoco.build.tables.static_shapes``).
        geom_shape: ``(ngeom,)`` int32, shape index of each geom, or -1.
        static: ``"shape"`` or ``"sphere"``, the ``cover_model`` option used.
    """

    sphere_geom: np.ndarray
    sphere_body: np.ndarray
    sphere_offset: np.ndarray
    sphere_radius: np.ndarray
    geom_sphere_start: np.ndarray
    plane_geom: np.ndarray
    geom_plane: np.ndarray
    mode: CoveringMode = field(default=CoveringMode.BOUNDING)
    plane_static: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    shape_geom: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int32))
    geom_shape: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int32))
    static: str = "sphere"

    def __post_init__(self) -> None:
        # Coverings built by hand may omit plane_static: planes are then taken as static.
        if self.plane_static.shape != self.plane_geom.shape:
            object.__setattr__(self, "plane_static", np.ones(self.plane_geom.shape, dtype=bool))
        # ... and the shapes: then there are none.
        if self.geom_shape.shape != self.geom_plane.shape:
            lookup = np.full(self.geom_plane.shape, -1, dtype=np.int32)
            lookup[self.shape_geom] = np.arange(self.shape_geom.shape[0], dtype=np.int32)
            object.__setattr__(self, "geom_shape", lookup)

    @property
    def nsphere(self) -> int:
        """Number of spheres."""
        return int(self.sphere_radius.shape[0])

    @property
    def nplane(self) -> int:
        """Number of plane geoms (half-spaces)."""
        return int(self.plane_geom.shape[0])

    @property
    def nshape(self) -> int:
        """Number of static geoms held as shapes."""
        return int(self.shape_geom.shape[0])

    @property
    def ngeom(self) -> int:
        """Number of geoms of the model the covering was built from."""
        return int(self.geom_plane.shape[0])

    def spheres_of(self, geom_id: int) -> np.ndarray:
        """``(k,)`` int64 ids of the spheres covering geom ``geom_id`` (none for planes and
        uncovered geoms).

        Raises:
            InvalidInputError: if ``geom_id`` is not a geom id of the model.
        """
        g = int(geom_id)
        if not 0 <= g < self.ngeom:
            raise InvalidInputError(
                f"geom id {geom_id!r} is out of range: the model has {self.ngeom} geoms "
                f"(valid ids 0..{self.ngeom - 1})."
            )
        return np.arange(self.geom_sphere_start[g], self.geom_sphere_start[g + 1], dtype=np.int64)


def _geom_name(model: mujoco.MjModel, g: int) -> str:
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
    return f"geom {g} ({name!r})" if name else f"geom {g} (unnamed)"


def _type_name(t: int) -> str:
    try:
        return mujoco.mjtGeom(t).name
    except ValueError:
        return f"type {t}"


def _collidable_geoms(model: mujoco.MjModel) -> np.ndarray:
    """Geoms that can appear in some contact: nonzero contype or conaffinity, or in a <pair>."""
    mask = (np.asarray(model.geom_contype) != 0) | (np.asarray(model.geom_conaffinity) != 0)
    if model.npair:
        mask[np.asarray(model.pair_geom1)] = True
        mask[np.asarray(model.pair_geom2)] = True
    return mask


def static_shape_geoms(model: mujoco.MjModel) -> np.ndarray:
    """``(ngeom,)`` bool: the geoms ``cover_model(static="shape")`` holds as their own shape.

    A geom qualifies when its body is welded to the world (``body_weldid == 0``: no joint and no
    mocap body between it and the world, so its pose is a constant of the model), its type is a
    sphere, capsule, ellipsoid, cylinder, box or mesh, and it is in no ``<pair>`` with another
    static geom. Dynamic pairs of two static geoms are never active (same weld group), but an
    explicit pair is; a shape pairs with spheres only, so such a geom keeps its spheres.
    """
    return _static_geoms(model) & np.isin(np.asarray(model.geom_type, dtype=np.int64), CONVEX_TYPES)


def _static_geoms(model: mujoco.MjModel) -> np.ndarray:
    """Geoms welded to the world and in no ``<pair>`` with another such geom: ``(ngeom,)``."""
    static = ~moving_bodies(model)[np.asarray(model.geom_bodyid, dtype=np.int64)]
    if model.npair:
        p1 = np.asarray(model.pair_geom1, dtype=np.int64)
        p2 = np.asarray(model.pair_geom2, dtype=np.int64)
        both = static[p1] & static[p2]
        keep_static = static.copy()
        keep_static[p1[both]] = False
        keep_static[p2[both]] = False
        static = keep_static
    return static


def terrain_geoms(model: mujoco.MjModel) -> np.ndarray:
    """``(ngeom,)`` bool: the geoms ``cover_model(hfield="terrain")`` holds as terrain.

    A height field qualifies when its body is welded to the world (its pose, and so every prism,
    is a constant of the model) and it is in no ``<pair>`` with another static geom (a terrain
    pairs with spheres only; such a height field keeps its box covering), held as the prisms
    of its grid.
    """
    return _static_geoms(model) & (np.asarray(model.geom_type, dtype=np.int64) == GEOM_HFIELD)


def _cover_geom(
    model: mujoco.MjModel, g: int, mode: CoveringMode, budget: int, hfield: str
) -> tuple[np.ndarray, np.ndarray]:
    """Spheres covering one non-plane geom, in its frame: ``(centres (k, 3), radii (k,))``."""
    gtype = int(model.geom_type[g])
    size = np.asarray(model.geom_size[g], dtype=np.float64)
    rbound = float(model.geom_rbound[g])
    aabb = np.asarray(model.geom_aabb[g], dtype=np.float64)

    if gtype == GEOM_SDF:
        raise UnsupportedGeomError(
            f"{_geom_name(model, g)} is an SDF geom: SDF geoms cannot be covered by spheres. "
            "Set its contype and conaffinity to 0 (and remove it from <pair> elements) to leave "
            "it out of collision prediction."
        )
    if gtype != GEOM_HFIELD and gtype not in CONVEX_TYPES:
        raise UnsupportedGeomError(
            f"{_geom_name(model, g)} has geom type {_type_name(gtype)}, which dua_mujoco cannot "
            "cover by spheres."
        )
    if gtype == GEOM_HFIELD:
        if hfield == "error":
            raise UnsupportedGeomError(
                f'{_geom_name(model, g)} is a height field, and hfield="error" refuses them. '
                'Pass hfield="terrain" (the default; CLI: --hfield terrain) to hold a static one '
                'as the prisms of its grid, or hfield="box" to cover it by its bounding box.'
            )
        # The height field spans x, y in [-size_x, size_x] x [-size_y, size_y] and z from -base
        # to the top elevation; geom_aabb is exactly that box in the geom frame.
        hsize = np.asarray(model.hfield_size[int(model.geom_dataid[g])], dtype=np.float64)
        centre = np.array([0.0, 0.0, 0.5 * (hsize[2] - hsize[3])])
        half = np.array([hsize[0], hsize[1], 0.5 * (hsize[2] + hsize[3])])
        if mode is CoveringMode.BOUNDING:
            return centre[None, :], np.array([float(np.linalg.norm(half))])
        return grid_cover(centre, half, budget)

    one = (np.zeros((1, 3)), np.array([rbound]))
    if mode is CoveringMode.BOUNDING:
        return one
    if gtype == GEOM_SPHERE:
        return np.zeros((1, 3)), np.array([size[0]])

    if gtype == GEOM_CAPSULE:
        multi = capsule_cover(size[0], size[1], budget)
    elif gtype == GEOM_BOX:
        multi = grid_cover(np.zeros(3), size[:3], budget)
    elif gtype == GEOM_CYLINDER:
        half = np.array([size[0], size[0], size[1]])
        multi = grid_cover(np.zeros(3), half, budget, keep_cylinder(size[0]))
    elif gtype == GEOM_ELLIPSOID:
        multi = grid_cover(np.zeros(3), size[:3], budget, keep_ellipsoid(size[:3]))
    else:  # mesh: cover the convex hull MuJoCo collides with
        mesh_id = int(model.geom_dataid[g])
        verts = mesh_vertices(model, mesh_id)
        lo, hi = verts.min(axis=0), verts.max(axis=0)
        # Also enclose geom_aabb: it is MuJoCo's own box for this geom and costs nothing extra.
        lo = np.minimum(lo, aabb[:3] - aabb[3:])
        hi = np.maximum(hi, aabb[:3] + aabb[3:])
        planes = mesh_hull_planes(model, mesh_id, verts)
        keep = None if planes is None else keep_convex(*planes)
        multi = grid_cover(0.5 * (lo + hi), 0.5 * (hi - lo), budget, keep)

    # A single bounding sphere can beat a grid (near-spherical shapes, budget 1): keep whichever
    # union is smaller, i.e. sticks out of the shape less.
    if union_volume(*multi) >= union_volume(*one):
        return one
    return multi


def _terrain_of(model: mujoco.MjModel, collidable: np.ndarray) -> np.ndarray:
    """The collidable height fields held as terrain; a moving one is refused."""
    hfields = collidable & (np.asarray(model.geom_type, dtype=np.int64) == GEOM_HFIELD)
    gbody = np.asarray(model.geom_bodyid, dtype=np.int64)
    moving = hfields & moving_bodies(model)[gbody]
    if moving.any():
        g = int(np.flatnonzero(moving)[0])
        body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(gbody[g])) or "unnamed"
        raise UnsupportedGeomError(
            f"{_geom_name(model, g)} is a height field on body {int(gbody[g])} ({body!r}), "
            "which moves (a joint or a mocap body lies between it and the world): terrain must "
            "be static. Weld it to the world (no joint on its body or above it), or pass "
            'hfield="box" (CLI: --hfield box) to cover it by its bounding box.'
        )
    return hfields & terrain_geoms(model)


def _as_mode(mode: CoveringMode | str) -> CoveringMode:
    if isinstance(mode, CoveringMode):
        return mode
    try:
        return CoveringMode(str(mode).lower())
    except ValueError:
        raise InvalidChoiceError("covering mode", mode, [m.value for m in CoveringMode]) from None


def cover_model(
    model: mujoco.MjModel,
    *,
    mode: CoveringMode | str = CoveringMode.BOUNDING,
    max_spheres_per_geom: int = 8,
    hfield: str = "terrain",
    only_collidable: bool = True,
    static: str = "shape",
) -> Covering:
    """Cover every geom of a model by spheres (planes become half-spaces, static geoms shapes).

    Args:
        mode: ``"bounding"`` (one sphere per geom, radius ``geom_rbound``) or ``"multi"`` (up to
            ``max_spheres_per_geom`` tighter spheres per geom), or a :class:`CoveringMode`.
        max_spheres_per_geom: sphere budget per geom in ``"multi"`` mode (int >= 1).
        hfield: ``"terrain"`` (default) holds each static height field (``terrain_geoms``) as
            the prisms of its grid, with no spheres, and refuses one on a moving body;
            ``"box"`` covers every height field by its full bounding box (base included):
            conservative, never tight; ``"error"`` refuses height fields.
        only_collidable: leave out geoms that can never be in a contact (contype and conaffinity
            both 0, and in no ``<pair>``); they get zero spheres. Visual geoms then cost nothing.
        static: ``"shape"`` (default) holds each static geom (``static_shape_geoms``) as its
            own convex shape, with no spheres; ``"sphere"`` covers it by spheres like any
            other geom (the behaviour before static shapes, for comparisons).

    Returns:
        The :class:`Covering`.

    Raises:
        InvalidChoiceError: unknown ``mode``, ``hfield`` or ``static``.
        InvalidInputError: ``max_spheres_per_geom`` is not an int >= 1.
        UnsupportedGeomError: a height field with ``hfield="error"``, one on a moving body with
            ``hfield="terrain"``, an SDF geom, or an unknown geom type, among the geoms to cover.
    """
    cmode = _as_mode(mode)
    if hfield not in HFIELD_CHOICES:
        raise InvalidChoiceError(
            "hfield option",
            hfield,
            HFIELD_CHOICES,
            'Use "terrain" for static height fields as the prisms of their grid, "box" for '
            "bounding boxes.",
        )
    if static not in STATIC_CHOICES:
        raise InvalidChoiceError(
            "static option",
            static,
            STATIC_CHOICES,
            'Use "shape" for static geoms as their own shapes, "sphere" for bounding spheres.',
        )
    budget = check_int("max_spheres_per_geom", max_spheres_per_geom)

    ngeom = int(model.ngeom)
    gtypes = np.asarray(model.geom_type, dtype=np.int64)
    collidable = _collidable_geoms(model) if only_collidable else np.ones(ngeom, dtype=bool)
    as_shape = (
        static_shape_geoms(model) & collidable if static == "shape" else np.zeros(ngeom, dtype=bool)
    )
    if hfield == "terrain":
        as_shape |= _terrain_of(model, collidable)
    counts = np.zeros(ngeom, dtype=np.int64)
    centres: list[np.ndarray] = []
    radii: list[np.ndarray] = []
    plane_geom: list[int] = []
    geom_plane = np.full(ngeom, -1, dtype=np.int32)
    for g in range(ngeom):
        if gtypes[g] == GEOM_PLANE:
            geom_plane[g] = len(plane_geom)
            plane_geom.append(g)
            continue
        if not collidable[g] or as_shape[g]:
            continue
        c, r = _cover_geom(model, g, cmode, budget, hfield)
        centres.append(np.asarray(c, dtype=np.float64).reshape(-1, 3))
        radii.append(np.asarray(r, dtype=np.float64).reshape(-1))
        counts[g] = radii[-1].shape[0]

    start = np.zeros(ngeom + 1, dtype=np.int32)
    np.cumsum(counts, out=start[1:])
    sphere_geom = np.repeat(np.arange(ngeom, dtype=np.int32), counts)
    body = np.asarray(model.geom_bodyid, dtype=np.int32)
    planes = np.asarray(plane_geom, dtype=np.int32)
    return Covering(
        sphere_geom=sphere_geom,
        sphere_body=body[sphere_geom],
        sphere_offset=np.concatenate(centres) if centres else np.zeros((0, 3)),
        sphere_radius=np.concatenate(radii) if radii else np.zeros(0),
        geom_sphere_start=start,
        plane_geom=planes,
        geom_plane=geom_plane,
        mode=cmode,
        plane_static=np.asarray(model.body_weldid)[body[planes]] == 0,
        shape_geom=np.flatnonzero(as_shape).astype(np.int32),
        static=static,
    )


def sphere_world_centers(
    covering: Covering,
    geom_xpos: npt.ArrayLike,
    geom_xmat: npt.ArrayLike,
    ids: npt.ArrayLike | None = None,
) -> np.ndarray:
    """World centres of spheres: ``geom_xpos[g] + geom_xmat[g] @ offset``.

    Args:
        geom_xpos: ``(ngeom, 3)`` geom positions (``d.geom_xpos``).
        geom_xmat: ``(ngeom, 9)`` or ``(ngeom, 3, 3)`` geom orientations (``d.geom_xmat``).
        ids: ``(n,)`` sphere ids, or None for all spheres.

    Returns:
        ``(n, 3)`` float64 world centres.

    Raises:
        ShapeError: if the arrays do not have the documented shapes.
        InvalidInputError: if a sphere id is out of range (the kinematics kernel names it).
    """
    xpos = np.asarray(geom_xpos, dtype=np.float64)
    xmat = np.asarray(geom_xmat, dtype=np.float64)
    ngeom = covering.ngeom
    if xpos.shape != (ngeom, 3):
        raise ShapeError(f"geom_xpos must have shape ({ngeom}, 3), got {xpos.shape}.")
    if xmat.shape == (ngeom, 9):
        xmat = xmat.reshape(ngeom, 3, 3)
    if xmat.shape != (ngeom, 3, 3):
        raise ShapeError(
            f"geom_xmat must have shape ({ngeom}, 9) or ({ngeom}, 3, 3), got {xmat.shape}."
        )
    if ids is None:
        sel = np.arange(covering.nsphere)
    else:
        sel = np.asarray(ids)
        if sel.ndim != 1 or not np.issubdtype(sel.dtype, np.integer):
            raise ShapeError(f"ids must be a 1-D integer array, got {sel.dtype} {sel.shape}.")
    # Positions only: the kinematics kernel with a frame at rest.
    nbody = int(covering.sphere_body.max(initial=-1)) + 1
    records = pack_spheres(
        covering.sphere_geom, covering.sphere_body, covering.sphere_offset, np.zeros(nbody, int)
    )
    rest = (np.zeros((nbody, 6)), np.zeros((nbody, 3)), np.zeros((nbody, 6)), np.zeros((nbody, 3)))
    frame = (np.ascontiguousarray(xpos), np.ascontiguousarray(xmat.reshape(ngeom, 9)), *rest)
    return sphere_states(records, frame, sel)[0]
