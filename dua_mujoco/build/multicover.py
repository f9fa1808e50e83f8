"""Multi-sphere coverings of one geom, in its own frame: spheres over a grid of cells of the
geom's bounding box (cells provably outside the shape dropped), or along a capsule's segment.

Each function returns ``(centres (k, 3), radii (k,))`` whose union contains the geom;
``covering.cover_model`` keeps a multi covering only when its union is smaller than the one
bounding sphere's.
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco
import numpy as np

__all__ = [
    "CellTest",
    "capsule_cover",
    "grid_cover",
    "keep_convex",
    "keep_cylinder",
    "keep_ellipsoid",
    "mesh_hull_planes",
    "mesh_vertices",
    "union_volume",
]

# keep(lo (k, 3), hi (k, 3)) -> (k,) bool: False only for cells provably disjoint from the shape.
CellTest = Callable[[np.ndarray, np.ndarray], np.ndarray]

# Grids whose cell count exceeds the budget by this factor are still tried for shapes that drop
# cells (cylinder, ellipsoid, mesh): after dropping, they may fit the budget with smaller cells.
GRID_OVERSHOOT = 2

# ------------------------------------------------------------------------------------------------
# per-type coverings, all in the geom frame: (centres (k, 3), radii (k,))


def grid_cells(half: np.ndarray, shape: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Cells of a regular grid over the box ``[-half, half]``.

    Returns:
        ``(lo (k, 3), hi (k, 3))`` corners of the cells, relative to the box centre.
    """
    edges = [np.linspace(-half[a], half[a], shape[a] + 1) for a in range(3)]
    lo = np.stack(np.meshgrid(*(e[:-1] for e in edges), indexing="ij"), axis=-1).reshape(-1, 3)
    hi = np.stack(np.meshgrid(*(e[1:] for e in edges), indexing="ij"), axis=-1).reshape(-1, 3)
    return lo, hi


def candidate_grids(half: np.ndarray, max_cells: int) -> list[tuple[int, int, int]]:
    """Grid shapes with at most ``max_cells`` cells, smallest cell radius first.

    The cell radius (half the cell diagonal) is what the covering sticks out by, so minimising it
    yields roughly cubic cells; ties go to fewer cells.
    """
    full = 2.0 * np.asarray(half, dtype=np.float64)
    grids: list[tuple[float, int, tuple[int, int, int]]] = []
    for nx in range(1, max_cells + 1):
        for ny in range(1, max_cells // nx + 1):
            for nz in range(1, max_cells // (nx * ny) + 1):
                cell = full / np.array([nx, ny, nz])
                grids.append((float(np.dot(cell, cell)), nx * ny * nz, (nx, ny, nz)))
    grids.sort()
    return [g for _, _, g in grids]


def grid_cover(
    centre: np.ndarray, half: np.ndarray, budget: int, keep: CellTest | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Cover the box ``centre ± half`` by one sphere per grid cell that ``keep`` accepts.

    Every point of the shape lies in some grid cell (the grid tiles the box that contains the
    shape); that cell intersects the shape, so ``keep`` (which may only reject cells disjoint from
    the shape) keeps it; and the cell lies in its circumscribed sphere. Hence containment.

    Args:
        centre: ``(3,)`` box centre in the geom frame.
        half: ``(3,)`` box half-sizes.
        budget: maximum number of spheres.
        keep: ``keep(lo, hi) -> (k,) bool`` with cell corners in the geom frame, or None to keep
            every cell.

    Returns:
        ``(centres (k, 3), radii (k,))`` with ``k <= budget``.
    """
    half = np.maximum(np.asarray(half, dtype=np.float64), 0.0)
    max_cells = budget if keep is None else budget * GRID_OVERSHOOT
    for shape in candidate_grids(half, max_cells):
        lo, hi = (corner + centre for corner in grid_cells(half, shape))
        mask = np.ones(lo.shape[0], dtype=bool) if keep is None else keep(lo, hi)
        if 0 < int(mask.sum()) <= budget:
            lo, hi = lo[mask], hi[mask]
            return 0.5 * (lo + hi), 0.5 * np.linalg.norm(hi - lo, axis=1)
    # One cell always fits (budget >= 1) and intersects the shape; reached only if `keep`
    # rejected every cell, which means the shape is empty: fall back to the whole box.
    return centre[None, :].copy(), np.array([float(np.linalg.norm(half))])


def capsule_cover(radius: float, halflen: float, budget: int) -> tuple[np.ndarray, np.ndarray]:
    """Spheres along a capsule's segment (local z axis).

    Two constructions, the smaller sum of cubed radii wins:

    * ``budget`` pieces: the segment cut into ``budget`` equal sub-segments of half-length
      ``l = halflen / budget``; the capsule is the union of (sub-segment ⊕ ball(radius)), each of
      which lies in the ball of radius ``radius + l`` about the sub-segment's midpoint.
    * slabs + caps (``budget >= 3``): the two hemispherical caps are the exact balls of radius
      ``radius`` at the segment ends; the cylindrical part is cut into ``budget - 2`` slabs, each
      inside the sphere of radius ``sqrt(radius² + l²)`` about its centre.
    """
    options: list[tuple[np.ndarray, np.ndarray]] = []
    n = budget
    step = 2.0 * halflen / n
    z = -halflen + step * (np.arange(n) + 0.5)
    options.append((z, np.full(n, radius + 0.5 * step)))
    if budget >= 3 and halflen > 0:
        k = budget - 2
        step = 2.0 * halflen / k
        zs = -halflen + step * (np.arange(k) + 0.5)
        zc = np.concatenate([zs, [-halflen, halflen]])
        rc = np.concatenate([np.full(k, np.hypot(radius, 0.5 * step)), [radius, radius]])
        options.append((zc, rc))
    z, r = min(options, key=lambda o: float(np.sum(o[1] ** 3)))
    centres = np.zeros((z.shape[0], 3))
    centres[:, 2] = z
    return centres, r


def keep_cylinder(radius: float) -> CellTest:
    def keep(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        # Nearest point of the cell's xy rectangle to the axis: the cell meets the cylinder iff it
        # is within the radius (z always overlaps, the grid spans the height).
        near = np.clip(0.0, lo[:, :2], hi[:, :2])
        return np.einsum("ij,ij->i", near, near) <= radius * radius

    return keep


def keep_ellipsoid(radii: np.ndarray) -> CellTest:
    def keep(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        # sum (x_i / a_i)^2 is separable and convex with its minimum at 0 on each axis, so its
        # minimum over a cell is at the origin clamped into the cell: exact intersection test.
        near = np.clip(0.0, lo, hi) / radii
        return np.einsum("ij,ij->i", near, near) <= 1.0

    return keep


def keep_convex(normals: np.ndarray, offsets: np.ndarray) -> CellTest:
    """Reject cells lying entirely outside one face plane of a convex polytope.

    A face plane with the whole cell strictly on its outer side separates the cell from the hull, so
    only cells disjoint from the hull are rejected. (Cells separated only by an edge-edge axis are
    kept: conservative.)
    """

    def keep(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        centre = 0.5 * (lo + hi)
        half = 0.5 * (hi - lo)
        # Lowest value of n.x over the cell: n.c - sum |n_i| h_i.
        low = centre @ normals.T - half @ np.abs(normals).T
        tol = 1e-9 * (1.0 + np.abs(offsets))
        return ~np.any(low > offsets + tol, axis=1)

    return keep


def mesh_vertices(model: mujoco.MjModel, mesh_id: int) -> np.ndarray:
    adr = int(model.mesh_vertadr[mesh_id])
    num = int(model.mesh_vertnum[mesh_id])
    return np.asarray(model.mesh_vert[adr : adr + num], dtype=np.float64)


def mesh_hull_planes(
    model: mujoco.MjModel, mesh_id: int, verts: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """Face planes ``n.x <= d`` of the convex hull MuJoCo computed for a mesh.

    Reads ``mesh_graph`` (layout: numvert, numface, vert_edgeadr[numvert], vert_globalid[numvert],
    edge_localid[numvert + 3 numface], face_globalid[3 numface]). Returns None when MuJoCo stored no
    hull; callers then keep every cell.
    """
    adr = int(model.mesh_graphadr[mesh_id])
    if adr < 0:
        return None
    graph = model.mesh_graph
    numvert = int(graph[adr])
    numface = int(graph[adr + 1])
    if numface < 4:
        return None
    start = adr + 2 + 2 * numvert + numvert + 3 * numface
    faces = np.asarray(graph[start : start + 3 * numface], dtype=np.int64).reshape(numface, 3)
    a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    normals = np.cross(b - a, c - a)
    norm = np.linalg.norm(normals, axis=1)
    ok = norm > 1e-12 * max(1.0, float(np.max(np.abs(verts))) ** 2)
    normals = normals[ok] / norm[ok, None]
    a = a[ok]
    hull_ids = np.unique(faces)
    inside = verts[hull_ids].mean(axis=0)
    # Orient outwards whatever the winding, using a point inside the hull.
    flip = np.einsum("ij,ij->i", normals, inside - a) > 0
    normals[flip] *= -1.0
    offsets = np.einsum("ij,ij->i", normals, a)
    # Vertices may sit slightly outside their own face planes (float32 storage): widen the planes.
    slack = np.max(verts @ normals.T - offsets, axis=0)
    offsets = offsets + np.maximum(slack, 0.0)
    return normals, offsets


def union_volume(centres: np.ndarray, radii: np.ndarray, n: int = 24) -> float:
    """Volume of a union of spheres, estimated on an ``n³`` grid of points over its bounding box.

    Only used to choose between two valid coverings, so a few percent of error is harmless; the
    fixed grid keeps the choice deterministic.
    """
    lo = np.min(centres - radii[:, None], axis=0)
    hi = np.max(centres + radii[:, None], axis=0)
    step = (hi - lo) / n
    axes = [lo[a] + step[a] * (np.arange(n) + 0.5) for a in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    inside = np.zeros(pts.shape[0], dtype=bool)
    for c, r in zip(centres, radii, strict=True):
        d = pts - c
        inside |= np.einsum("ij,ij->i", d, d) <= r * r
    return float(inside.sum()) * float(np.prod(step))
