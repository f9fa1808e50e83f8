"""Height fields held as terrain: the triangular prisms of their grid (proof in
docs/theory.md, section 9).

MuJoCo collides a height field as prisms: over each cell of its ``nrow x ncol`` grid, two
triangles of the heights ``hfield_data * size_z`` extruded down to ``z = -base``
(``mjc_ConvexHField``). A static height field is held as a shape record of kind
``ShapeKind.HFIELD`` (``TERRAIN_BLOCK``: the rows from it to its block, ``TERRAIN_ROWS``: the
block's rows) that points to a *block* of rows after every record of the shape table: a header
(``T_*``), the pyramid of cell maxima the native kernel's branch and bound reads
(``dua_mujoco/csrc/src/terrain.cc``), then the heights, row-major. docs/static-shapes.md,
section 13, has the layout; a table's records are the rows before its first block
(:func:`record_count`).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

import dua_mujoco._core as _core
from dua_mujoco.exceptions import InvalidInputError, ShapeError

__all__ = [
    "TERRAIN_BLOCK",
    "TERRAIN_ROWS",
    "T_BASE",
    "T_HABS",
    "T_HEADER",
    "T_HEIGHTS",
    "T_LEVELS",
    "T_NCOL",
    "T_NROW",
    "T_RX",
    "T_RY",
    "first_bad_row",
    "pack_terrain",
    "record_count",
    "shape_table",
    "terrain_levels",
]

_LAYOUT = _core.LAYOUT
# Shape record columns (dua_mujoco.core.shapes, which imports this module).
SHAPE_KIND, SHAPE_POS, SHAPE_MAT = _LAYOUT["SHAPE_KIND"], _LAYOUT["SHAPE_POS"], _LAYOUT["SHAPE_MAT"]
SHAPE_NCOL = _LAYOUT["SHAPE_NCOL"]
_HFIELD: int = _LAYOUT["ShapeKind.HFIELD"]
# Record columns (the size columns of a shape record).
TERRAIN_BLOCK: int = _LAYOUT["TERRAIN_BLOCK"]
TERRAIN_ROWS: int = _LAYOUT["TERRAIN_ROWS"]
# Block header: half sizes, base, grid, number of levels, where the heights start, max |height|.
T_RX, T_RY, T_BASE = _LAYOUT["T_RX"], _LAYOUT["T_RY"], _LAYOUT["T_BASE"]
T_NROW, T_NCOL, T_LEVELS = _LAYOUT["T_NROW"], _LAYOUT["T_NCOL"], _LAYOUT["T_LEVELS"]
T_HEIGHTS, T_HABS, T_HEADER = _LAYOUT["T_HEIGHTS"], _LAYOUT["T_HABS"], _LAYOUT["T_HEADER"]


def terrain_levels(heights: np.ndarray) -> list[np.ndarray]:
    """The max pyramid of ``(nrow, ncol)`` heights (``nrow, ncol >= 2``): level 0 the cell maxima
    (the highest of each cell's four corners), each next level the maxima of 2 x 2 of the last,
    down to one cell.

    Returns:
        The levels, ``(ceil((nrow - 1) / 2^l), ceil((ncol - 1) / 2^l))`` each.
    """
    h = np.asarray(heights, dtype=np.float64)
    cells = np.maximum(np.maximum(h[:-1, :-1], h[:-1, 1:]), np.maximum(h[1:, :-1], h[1:, 1:]))
    levels = [cells]
    while levels[-1].shape != (1, 1):
        last = levels[-1]
        ny, nx = last.shape
        pad = np.full((ny + ny % 2, nx + nx % 2), -np.inf)
        pad[:ny, :nx] = last
        levels.append(pad.reshape(pad.shape[0] // 2, 2, pad.shape[1] // 2, 2).max(axis=(1, 3)))
    return levels


def pack_terrain(
    size: npt.ArrayLike,
    nrow: int,
    ncol: int,
    data: npt.ArrayLike,
    pos: npt.ArrayLike,
    mat: npt.ArrayLike,
) -> tuple[np.ndarray, np.ndarray]:
    """A height field's record and block (assemble them into a table with :func:`shape_table`).

    Args:
        size: MuJoCo's ``hfield_size`` row: ``(size_x, size_y, size_z, base)``, all positive
            but the base, which may be 0.
        nrow: ``hfield_nrow`` (>= 2).
        ncol: ``hfield_ncol`` (>= 2).
        data: ``hfield_data`` of the height field, ``nrow * ncol`` values (MuJoCo's are in
            ``[0, 1]``; the heights are ``data * size_z``, computed as MuJoCo does).
        pos: ``geom_xpos`` of the height field geom, ``(3,)``.
        mat: ``geom_xmat``, ``(9,)`` row-major or ``(3, 3)``.

    Returns:
        ``(record (16,), block (k, 16))``; the record's ``TERRAIN_BLOCK`` is set by
        :func:`shape_table`.

    Raises:
        ShapeError: ``size``, ``data``, ``pos`` or ``mat`` has the wrong number of values.
        InvalidInputError: a grid smaller than 2 x 2, a size that is not positive (a base
            that is negative), a value that is not finite, or a matrix that is not a rotation.
    """
    sz = np.asarray(size, dtype=np.float64).reshape(-1)
    if sz.shape != (4,):
        raise ShapeError(f"size has shape {np.shape(size)}; expected (4,) (MuJoCo's hfield_size).")
    if not (isinstance(nrow, int | np.integer) and isinstance(ncol, int | np.integer)):
        raise InvalidInputError(f"nrow and ncol must be ints, got {nrow!r} and {ncol!r}.")
    nrow, ncol = int(nrow), int(ncol)
    if nrow < 2 or ncol < 2:
        raise InvalidInputError(
            f"a height field of {nrow} x {ncol} points has no cell: nrow and ncol must be >= 2."
        )
    if not (np.isfinite(sz).all() and (sz[:3] > 0).all() and sz[3] >= 0):
        raise InvalidInputError(
            f"size = {sz.tolist()} is invalid: size_x, size_y, size_z must be positive and the "
            "base non-negative (MuJoCo's hfield_size)."
        )
    raw = np.asarray(data, dtype=np.float64).reshape(-1)
    if raw.shape != (nrow * ncol,):
        raise ShapeError(f"data has {raw.size} values; expected nrow * ncol = {nrow * ncol}.")
    if not np.isfinite(raw).all():
        raise InvalidInputError("data holds a value that is not finite.")
    p = np.asarray(pos, dtype=np.float64).reshape(-1)
    r = np.asarray(mat, dtype=np.float64).reshape(-1)
    if p.shape != (3,) or r.shape != (9,):
        raise ShapeError(
            f"pos and mat have shapes {np.shape(pos)}, {np.shape(mat)}; expected 3, 9."
        )
    rot = r.reshape(3, 3)
    if not (
        np.isfinite(p).all()
        and np.isfinite(r).all()
        and np.abs(rot @ rot.T - np.eye(3)).max() <= 1e-6
        and np.linalg.det(rot) > 0
    ):
        raise InvalidInputError(
            f"the pose pos = {p.tolist()}, mat = {r.tolist()} is not finite or not a rotation; "
            "pass the height field geom's geom_xpos and geom_xmat."
        )
    # MuJoCo's heights: a float widened exactly, times size_z, one rounding (as in C).
    heights = (raw * sz[2]).reshape(nrow, ncol)
    levels = terrain_levels(heights)
    start = T_HEADER + sum(level.size for level in levels)
    flat = np.zeros(-(-(start + heights.size) // SHAPE_NCOL) * SHAPE_NCOL)
    flat[[T_RX, T_RY, T_BASE]] = sz[[0, 1, 3]]
    flat[[T_NROW, T_NCOL, T_LEVELS, T_HEIGHTS]] = nrow, ncol, len(levels), start
    flat[T_HABS] = np.abs(heights).max()
    flat[T_HEADER:start] = np.concatenate([level.reshape(-1) for level in levels])
    flat[start : start + heights.size] = heights.reshape(-1)
    block = flat.reshape(-1, SHAPE_NCOL)
    record = np.zeros(SHAPE_NCOL)
    record[SHAPE_KIND] = _HFIELD
    record[TERRAIN_ROWS] = block.shape[0]
    record[SHAPE_POS : SHAPE_POS + 3] = p
    record[SHAPE_MAT : SHAPE_MAT + 9] = r
    return record, block


def shape_table(records: np.ndarray, blocks: dict[int, np.ndarray]) -> np.ndarray:
    """The shape table of ``records`` with the blocks of its terrain records after them.

    Args:
        records: ``(m, 16)`` shape records (``pack_shapes`` rows and ``pack_terrain`` records).
        blocks: the block of each terrain record, by its row in ``records``.

    Returns:
        ``(m + sum of the blocks' rows, 16)``, C-contiguous; each terrain record's
        ``TERRAIN_BLOCK`` set to the rows from it to its block.
    """
    out = [np.asarray(records, dtype=np.float64).reshape(-1, SHAPE_NCOL).copy()]
    at = out[0].shape[0]
    for row, block in sorted(blocks.items()):
        out[0][row, TERRAIN_BLOCK] = at - row
        out[0][row, TERRAIN_ROWS] = block.shape[0]
        out.append(block)
        at += block.shape[0]
    return np.ascontiguousarray(np.concatenate(out))


def record_count(table: np.ndarray) -> int:
    """How many leading rows of a ``(n, 16)`` shape table are records (the rest are terrain
    blocks)."""
    t = np.ascontiguousarray(table, dtype=np.float64)
    return int(_core.shape_record_count(t))


def first_bad_row(table: np.ndarray) -> int:
    """The first terrain record of a ``(n, 16)`` shape table whose block does not fit the table,
    its header or its grid (the native core's ``dua_check_shapes``, which the runtime runs on the
    tables it reads: what could read out of bounds); -1 when there is none."""
    t = np.ascontiguousarray(table, dtype=np.float64)
    return int(_core.check_shapes(t))
