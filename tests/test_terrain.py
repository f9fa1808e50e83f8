"""Tests of height fields held as terrain: the kernel (dua_mujoco/csrc/src/terrain.cc), its
tables (dua_mujoco/core/terrain.py) and the claims of docs/static-shapes.md, section 13.

Independent evidence, on purpose:

* The prisms are MuJoCo's: ``reference_terrain`` rebuilds them as ``mjc_ConvexHField`` walks
  the grid, and MuJoCo's own contacts agree with them (every contact within the contact distance
  of the prisms, every clear penetration a contact).
* The search is the exhaustive minimum: the pruned branch and bound over the pyramid returns
  the bound written over every cell (``reference_terrain.cell_bound``).
* Never late: tau is at most the first time the reachable set of the bound model touches the
  prisms (``reference_terrain.first_touch``, exact distances), and no sampled feasible
  trajectory (piecewise-constant accelerations, adversarial ones towards the terrain) comes within
  eps of them before tau. The same harnesses catch a kernel fed a lowered terrain or a corrupted
  pyramid.
* Tight where it can be: on flat terrain the kernel is the plane's tau.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
import reference_terrain as ref
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scalar_tau import static_gap, support, tau_halfspace, tau_static

from dua_mujoco import _core
from dua_mujoco.core.shapes import (
    SHAPE_NCOL,
    ShapeKind,
    pack_shapes,
    time_to_static,
)
from dua_mujoco.core.terrain import (
    T_HEADER,
    T_HEIGHTS,
    T_LEVELS,
    TERRAIN_BLOCK,
    TERRAIN_ROWS,
    first_bad_row,
    pack_terrain,
    record_count,
    shape_table,
    terrain_levels,
)
from dua_mujoco.exceptions import InvalidInputError, ShapeError

SETTINGS = settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True
)


def rotation(q) -> np.ndarray:
    q = np.asarray(q, dtype=np.float64)
    q = q / np.linalg.norm(q)
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, q)
    return mat.reshape(3, 3)


class Terrain:
    """A height field packed as a table, with its reference prisms and its frame."""

    def __init__(self, size, nrow, ncol, data, pos=(0, 0, 0), rot=None) -> None:
        self.size = np.asarray(size, dtype=np.float64)
        self.nrow, self.ncol = nrow, ncol
        self.data = np.asarray(data, dtype=np.float64).reshape(-1)
        self.pos = np.asarray(pos, dtype=np.float64)
        self.rot = np.eye(3) if rot is None else np.asarray(rot, dtype=np.float64)
        record, block = pack_terrain(self.size, nrow, ncol, self.data, self.pos, self.rot)
        self.table = shape_table(record[None], {0: block})
        self.tops = ref.prism_tops(self.size, nrow, ncol, self.data)
        self.base = float(self.size[3])

    def local(self, x) -> np.ndarray:
        return self.rot.T @ (np.asarray(x, dtype=np.float64) - self.pos)

    def world(self, x) -> np.ndarray:
        return self.pos + self.rot @ np.asarray(x, dtype=np.float64)

    def distance(self, x) -> float:
        """Exact distance from a world point to the prisms."""
        return ref.point_distance(self.local(x), self.tops, self.base)

    def tau(self, c, v, eps, accel, delta=0.0) -> float:
        c, v = np.asarray(c, dtype=np.float64), np.asarray(v, dtype=np.float64)
        return tau_static(c[0], c[1], c[2], v[0], v[1], v[2], self.table, eps, accel, delta)

    def tau_object(self, shape, v, spin, eps, accel, delta=0.0) -> float:
        return self.search(shape, v, spin, eps, accel, delta)[0]

    def search(self, shape, v, spin, eps, accel, delta=0.0) -> tuple[float, int]:
        """The kernel's tau of a shape record, and what decided it (``PYRAMID``: the search)."""
        s = np.ascontiguousarray(shape, dtype=np.float64)
        vv = np.ascontiguousarray(v, dtype=np.float64)
        tau, path = _core.tau_terrain(self.table, 0, s, vv, spin, eps, accel, delta)
        return float(tau), int(path)

    def bound(self, lo, hi, lowest, u, spin, eps, accel, delta) -> float:
        return ref.cell_bound(
            self.size, self.nrow, self.ncol, self.data, lo, hi, lowest, u, spin, eps, accel, delta
        )


@st.composite
def terrains(draw, tilted: bool = True, max_cells: int = 7, min_cells: int = 1) -> Terrain:
    nrow = draw(st.integers(min_cells + 1, max_cells + 1))
    ncol = draw(st.integers(min_cells + 1, max_cells + 1))
    scale = 10.0 ** draw(st.floats(-1.0, 1.0))
    wide = 0.2 if min_cells < 32 else 0.5  # large grids: wide enough for their cells
    size = [
        draw(st.floats(wide, 2.0)) * scale,
        draw(st.floats(wide, 2.0)) * scale,
        draw(st.floats(0.05, 1.0)) * scale,
        draw(st.floats(0.01, 0.5)) * scale,
    ]
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    data = rng.random(nrow * ncol) if draw(st.booleans()) else rng.integers(0, 3, nrow * ncol) / 2
    pos = [draw(st.floats(-1, 1)) * scale for _ in range(3)]
    rot = None
    if tilted and draw(st.booleans()):
        q = [draw(st.floats(-1, 1)) for _ in range(4)]
        rot = rotation(q) if np.linalg.norm(q) > 1e-3 else None
    return Terrain(size, nrow, ncol, data, pos, rot)


@st.composite
def motions(draw, terrain: Terrain):
    """A sphere's centre near the terrain (in its box or around it), velocity and bounds."""
    s = terrain.size
    tscale = 10.0 ** draw(st.floats(-1, 1))
    local = np.array(
        [
            draw(st.floats(-1.4, 1.4)) * s[0],
            draw(st.floats(-1.4, 1.4)) * s[1],
            draw(st.floats(-s[3] - 0.5 * s[2], 2.0 * s[2])),
        ]
    )
    length = float(np.hypot(s[0], s[1]))
    v = np.array([draw(st.floats(-1, 1)) for _ in range(3)]) * length / tscale
    eps = draw(st.floats(0.0, 0.2)) * s[2]
    accel = draw(st.sampled_from([0.0, 1.0])) * draw(st.floats(0.01, 5.0)) * length / tscale**2
    delta = draw(st.sampled_from([0.0, 1.0])) * draw(st.floats(0.0, 0.5)) * length / tscale
    return terrain.world(local), terrain.rot @ v, eps, accel, delta


# What decided a search (``_core.tau_terrain``'s second value): the base or the first cell, the
# cells within reach one by one (at most 256), the pyramid's branch and bound. Grids of 32 to 64
# cells a side (1,024 to 4,096 cells: far more than the window holds) reach the pyramid.
FIRST, WINDOW, PYRAMID = 0, 1, 2


@st.composite
def reaching_motions(draw, terrain: Terrain):
    """A sphere's centre 12 to 40 cells above the terrain's highest point, anywhere over it or
    beside it, bounds that bring it down in 0.1 to 10 time units: by the time it could come
    down, it could reach more cells sideways than the window holds, so the search runs on the
    pyramid."""
    s = terrain.size
    cell = max(2 * s[0] / (terrain.ncol - 1), 2 * s[1] / (terrain.nrow - 1))
    gap = draw(st.floats(12, 40)) * cell
    top = float(np.max(terrain.data)) * s[2]
    local = np.array(
        [draw(st.floats(-1.2, 1.2)) * s[0], draw(st.floats(-1.2, 1.2)) * s[1], top + gap]
    )
    fall = 10.0 ** draw(st.floats(-1, 1))
    v = np.array([draw(st.floats(-1, 1)) for _ in range(3)]) * gap / fall
    eps = draw(st.floats(0.0, 0.5)) * cell
    accel = 2 * gap / fall**2
    delta = draw(st.sampled_from([0.0, 1.0])) * draw(st.floats(0.0, 0.5)) * gap / fall
    return terrain.world(local), terrain.rot @ v, eps, accel, delta


def _point(c) -> np.ndarray:
    """A sphere's centre as a shape record (a sphere of radius 0: its radius is in eps)."""
    return np.array([int(ShapeKind.SPHERE), 0, 0, 0, *c, *np.eye(3).ravel()], dtype=np.float64)


def _unit(x) -> np.ndarray:
    n = np.linalg.norm(x)
    return np.asarray(x, dtype=np.float64) / n if n > 0 else np.array([0.0, 0.0, -1.0])


def horizon(tau: float) -> float:
    return min(tau, 1e3) if math.isfinite(tau) else 5.0


# ------------------------------------------------------------------------------------------------
# (a) the tables
# ------------------------------------------------------------------------------------------------


def test_pack_terrain_layout() -> None:
    rng = np.random.default_rng(0)
    nrow, ncol = 6, 11
    data = rng.random(nrow * ncol)
    t = Terrain([1.0, 0.5, 0.3, 0.1], nrow, ncol, data, [0.1, 0.2, 0.3], rotation([1, 2, 3, 4]))
    rec, flat = t.table[0], t.table[1:].reshape(-1)
    assert rec[0] == int(ShapeKind.HFIELD) and rec[TERRAIN_BLOCK] == 1
    assert rec[TERRAIN_ROWS] == t.table.shape[0] - 1 and record_count(t.table) == 1
    heights = data.reshape(nrow, ncol) * 0.3
    start = int(flat[T_HEIGHTS])
    np.testing.assert_array_equal(flat[start : start + nrow * ncol], heights.reshape(-1))
    # Each level's maxima: the highest corner of every cell under the node.
    levels = terrain_levels(heights)
    assert int(flat[T_LEVELS]) == len(levels) and levels[-1].shape == (1, 1)
    at = T_HEADER
    for k, level in enumerate(levels):
        got = flat[at : at + level.size].reshape(level.shape)
        for i, j in np.ndindex(level.shape):
            rows = slice(i << k, min((i + 1) << k, nrow - 1) + 1)
            cols = slice(j << k, min((j + 1) << k, ncol - 1) + 1)
            assert got[i, j] == heights[rows, cols].max()
        at += level.size
    assert first_bad_row(t.table) == -1


def test_a_table_of_records_and_blocks() -> None:
    """Two terrains and a box in one table: each terrain record finds its own block."""
    box = pack_shapes([6], [[0.1, 0.2, 0.3]], [[1, 2, 3]], [np.eye(3).ravel()])[0]
    a = pack_terrain([1, 1, 0.2, 0.1], 3, 4, np.linspace(0, 1, 12), [0, 0, 0], np.eye(3))
    b = pack_terrain([2, 1, 0.5, 0.2], 5, 2, np.linspace(1, 0, 10), [0, 0, 1], np.eye(3))
    table = shape_table(np.stack([a[0], box, b[0]]), {0: a[1], 2: b[1]})
    assert record_count(table) == 3 and first_bad_row(table) == -1
    assert table[0, TERRAIN_BLOCK] == 3 and table[2, TERRAIN_BLOCK] == 1 + a[1].shape[0]
    np.testing.assert_array_equal(table[3 : 3 + a[1].shape[0]], a[1])
    rng = np.random.default_rng(2)
    c, v = rng.normal(size=(20, 3)) + np.array([0, 0, 2]), rng.normal(size=(20, 3))
    for row, alone in (
        (0, shape_table(a[0][None], {0: a[1]})),
        (2, shape_table(b[0][None], {0: b[1]})),
    ):
        ids = np.full(20, row)
        got = time_to_static(c, v, table, ids, 0.05, 2.0)
        want = time_to_static(c, v, alone, np.zeros(20, dtype=np.int64), 0.05, 2.0)
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize(
    ("mutate", "row"),
    [
        (lambda t: t.__setitem__((0, TERRAIN_BLOCK), 0.0), 0),  # the block on the record
        (lambda t: t.__setitem__((0, TERRAIN_BLOCK), 1e9), 0),  # beyond the table
        (lambda t: t.__setitem__((0, TERRAIN_BLOCK), 1.5), 0),  # not a row
        (lambda t: t.__setitem__((0, TERRAIN_ROWS), 1e6), 0),  # longer than the table
        (lambda t: t.__setitem__((1, 3), 1e6), 0),  # nrow beyond the block
        (lambda t: t.__setitem__((1, 4), 1.0), 0),  # a single column
        (lambda t: t.__setitem__((1, 5), 2.0), 0),  # the wrong number of levels
        (lambda t: t.__setitem__((1, 6), 1e7), 0),  # heights beyond the block
        (lambda t: t.__setitem__((1, 0), -1.0), 0),  # a negative half size
        (lambda t: t.__setitem__((2, 7), np.nan), 0),  # a NaN in the block
    ],
)
def test_check_shapes_refuses_a_bad_table(mutate, row) -> None:
    t = Terrain([1, 1, 0.2, 0.1], 7, 9, np.linspace(0, 1, 63)).table.copy()
    mutate(t)
    assert first_bad_row(t) == row
    with pytest.raises(InvalidInputError, match="shapes"):
        time_to_static([[0.0, 0.0, 1.0]], [[0.0, 0.0, 0.0]], t, [0], 0.0, 1.0)


def test_check_shapes_reads_terrain_records_only() -> None:
    """Other records read their own row only: the native check passes them (a placeholder of
    zeros too), and ``time_to_static`` refuses a kind that is none."""
    box = pack_shapes([6], [[0.1, 0.2, 0.3]], [[1, 2, 3]], [np.eye(3).ravel()])
    assert first_bad_row(np.zeros((1, SHAPE_NCOL))) == -1
    box[0, 0] = 9.0
    assert first_bad_row(box) == -1
    with pytest.raises(InvalidInputError, match="not a static shape kind"):
        time_to_static([[0.0, 0.0, 1.0]], [[0.0, 0.0, 0.0]], box, [0], 0.0, 1.0)


def test_pack_terrain_rejects() -> None:
    good = ([1, 1, 0.2, 0.1], 3, 3, np.zeros(9), [0, 0, 0], np.eye(3))
    for k, bad, exc in (
        (0, [1, 1, 0.2], ShapeError),
        (0, [1, 0, 0.2, 0.1], InvalidInputError),
        (0, [1, 1, 0.2, -0.1], InvalidInputError),
        (1, 1, InvalidInputError),
        (3, np.zeros(8), ShapeError),
        (3, np.full(9, np.nan), InvalidInputError),
        (5, np.ones((3, 3)), InvalidInputError),
    ):
        args = list(good)
        args[k] = bad
        with pytest.raises(exc):
            pack_terrain(*args)
    with pytest.raises(InvalidInputError, match="pack_terrain"):
        pack_shapes([1], [[1, 1, 1]], [[0, 0, 0]], [np.eye(3).ravel()])


# ------------------------------------------------------------------------------------------------
# (b) MuJoCo collides these prisms, within the contact distance
# ------------------------------------------------------------------------------------------------


def _hfield_model(nrow, ncol, size, data, geom, margin=0.0, gap=0.0) -> mujoco.MjModel:
    elevation = " ".join(f"{x:.6f}" for x in data)
    xml = f"""<mujoco><asset><hfield name="h" nrow="{nrow}" ncol="{ncol}"
      size="{" ".join(map(str, size))}" elevation="{elevation}"/></asset>
      <worldbody><geom name="terrain" type="hfield" hfield="h" margin="{margin}" gap="{gap}"
        pos="0.1 -0.2 0.3" euler="10 -20 30"/>
      <body name="probe"><freejoint/>{geom}</body></worldbody></mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)


@pytest.mark.parametrize(
    ("geom", "margin", "gap"),
    [
        ('<geom type="sphere" size="0.05"/>', 0.0, 0.0),
        ('<geom type="sphere" size="0.05"/>', 0.02, 0.01),
        ('<geom type="capsule" size="0.03" fromto="-0.1 0 0 0.1 0.05 0.02"/>', 0.0, 0.0),
        ('<geom type="capsule" size="0.03" fromto="-0.1 0 0 0.1 0.05 0.02"/>', 0.015, 0.0),
    ],
    ids=["sphere", "sphere-margin", "capsule", "capsule-margin"],
)
def test_mujoco_collides_these_prisms_within_the_contact_distance(geom, margin, gap) -> None:
    """Every contact MuJoCo reports with the height field lies within margin + gap of the
    reference prisms, and every clear penetration of them is a contact: the grid, the
    triangulation and the base are MuJoCo's (and the contact distance is the one eps uses)."""
    rng = np.random.default_rng(1)
    nrow, ncol = 6, 7
    m = _hfield_model(nrow, ncol, (0.5, 0.4, 0.3, 0.1), rng.random(nrow * ncol), geom, margin, gap)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    tops = ref.prism_tops(m.hfield_size[0], nrow, ncol, m.hfield_data)
    pos, rot = d.geom_xpos[0].copy(), d.geom_xmat[0].reshape(3, 3).copy()
    contacts = clear = 0
    for _ in range(400):
        local = rng.uniform([-0.6, -0.5, -0.2], [0.6, 0.5, 0.45])
        d.qpos[:3] = pos + rot @ local
        d.qpos[3:] = _quat(rng)
        mujoco.mj_forward(m, d)
        probe = _probe_distance(m, d, tops, rot, pos, d.ncon > 0, margin + gap)
        if d.ncon:
            contacts += 1
            assert probe <= margin + gap + 1e-6, (local, probe)
        elif probe < -2e-3:
            clear += 1
            raise AssertionError(f"no contact at a penetration of {-probe}: {local}")
    assert contacts > 60 and clear == 0


def _quat(rng) -> np.ndarray:
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def _probe_distance(m, d, tops, rot, pos, contact: bool, far: float) -> float:
    """Distance of the probe geom to the prisms (``-r`` when its centre or axis is inside one:
    a clear penetration). For a capsule, spheres along its axis bound it from above (they lie in
    the capsule); where that bound is not enough to judge a contact (``contact`` and above
    ``far``), the exact segment distance decides."""
    g = 1
    base = float(m.hfield_size[0][3])
    r, half = float(m.geom_size[g][0]), float(m.geom_size[g][1])
    centre = rot.T @ (d.geom_xpos[g] - pos)
    if int(m.geom_type[g]) == int(mujoco.mjtGeom.mjGEOM_SPHERE):
        dist = ref.point_distance(centre, tops, base)
        return dist - r if dist > 0 else -r
    axis = rot.T @ d.geom_xmat[g].reshape(3, 3)[:, 2] * half
    upper = ref.points_distance(centre + np.linspace(-1, 1, 9)[:, None] * axis, tops, base)
    if upper == 0.0:
        return -r
    if contact and upper - r > far:
        exact = ref.segment_distance(centre - axis, centre + axis, tops, base, iters=50)
        return exact - r if exact > 0 else -r
    return upper - r


# ------------------------------------------------------------------------------------------------
# (c) the search finds the exhaustive minimum
# ------------------------------------------------------------------------------------------------


def _sphere_bound(t: Terrain, c, v, eps, accel, delta) -> float:
    cl, u = t.local(c), t.rot.T @ v
    return t.bound(cl, cl, lambda n: float(n @ cl), u, 0.0, eps, accel, delta)


def _close(a: float, b: float) -> bool:
    """The kernel's search against the exhaustive bound: never above it (no cell that matters
    pruned), and equal but for the kernel's rounding allowances, which move a root by more than
    1e-9 of it only where it is ill-conditioned (no acceleration, a speed near 0: beyond 1e6 s)."""
    if not a <= b * (1 + 1e-9) + 1e-12:
        return False
    return abs(a - b) <= 1e-9 * max(abs(b), 1e-9) or a > 1e6


@SETTINGS
@given(st.data())
def test_search_equals_every_cell_for_a_sphere(data) -> None:
    t = data.draw(terrains())
    c, v, eps, accel, delta = data.draw(motions(t))
    got, want = t.tau(c, v, eps, accel, delta), _sphere_bound(t, c, v, eps, accel, delta)
    assert _close(got, want), (got, want)


KINDS = (
    ShapeKind.SPHERE,
    ShapeKind.CAPSULE,
    ShapeKind.ELLIPSOID,
    ShapeKind.CYLINDER,
    ShapeKind.BOX,
)


def _object(kind, size, centre, rot) -> np.ndarray:
    return pack_shapes([int(kind)], [size], [centre], [np.asarray(rot).ravel()])[0]


def _object_bound(t: Terrain, shape, v, spin, eps, accel, delta) -> float:
    def lowest(n):
        w = t.rot @ n
        return -support(np.ascontiguousarray(-w), shape) - float(w @ t.pos)

    axes = [t.rot[:, k] for k in range(3)]
    lo = [lowest(np.eye(3)[k]) for k in range(3)]
    hi = [support(np.ascontiguousarray(a), shape) - float(a @ t.pos) for a in axes]
    return t.bound(lo, hi, lowest, t.rot.T @ v, spin, eps, accel, delta)


@st.composite
def objects(draw, t: Terrain):
    kind = draw(st.sampled_from(KINDS))
    s = float(t.size[2])
    size = np.array([draw(st.floats(0.05, 0.6)) * s for _ in range(3)])
    q = [draw(st.floats(-1, 1)) for _ in range(4)]
    rot = rotation(q) if np.linalg.norm(q) > 1e-3 else np.eye(3)
    c, v, eps, accel, delta = draw(motions(t))
    spin = draw(st.sampled_from([0.0, 1.0])) * draw(st.floats(0.0, 1.0)) * float(np.linalg.norm(v))
    return _object(kind, size, c, rot), v, spin, eps, accel, delta


@SETTINGS
@given(st.data())
def test_search_equals_every_cell_for_a_geom(data) -> None:
    t = data.draw(terrains())
    shape, v, spin, eps, accel, delta = data.draw(objects(t))
    got = t.tau_object(shape, v, spin, eps, accel, delta)
    want = _object_bound(t, shape, v, spin, eps, accel, delta)
    assert _close(got, want), (got, want)


LARGE = settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True
)


@LARGE
@given(st.data())
def test_search_equals_every_cell_through_the_pyramid_for_a_sphere(data) -> None:
    """Grids of 32 to 64 cells a side, a sphere that can reach more of them than the window
    holds: the branch and bound over the pyramid runs (asserted) and finds the bound written
    over every cell."""
    t = data.draw(terrains(min_cells=32, max_cells=64))
    c, v, eps, accel, delta = data.draw(reaching_motions(t))
    got, path = t.search(_point(c), v, 0.0, eps, accel, delta)
    assert path == PYRAMID
    want = _sphere_bound(t, c, v, eps, accel, delta)
    assert _close(got, want), (got, want)


@LARGE
@given(st.data())
def test_search_equals_every_cell_through_the_pyramid_for_a_geom(data) -> None:
    t = data.draw(terrains(min_cells=32, max_cells=64))
    c, v, eps, accel, delta = data.draw(reaching_motions(t))
    kind = data.draw(st.sampled_from(KINDS))
    cell = 2 * float(t.size[0]) / (t.ncol - 1)
    size = np.array([data.draw(st.floats(0.5, 4.0)) * cell for _ in range(3)])
    q = [data.draw(st.floats(-1, 1)) for _ in range(4)]
    rot = rotation(q) if np.linalg.norm(q) > 1e-3 else np.eye(3)
    spin = data.draw(st.floats(0.0, 1.0)) * float(np.linalg.norm(v))
    shape = _object(kind, size, c + t.rot[:, 2] * float(size.max()) * 2, rot)
    got, path = t.search(shape, v, spin, eps, accel, delta)
    assert path == PYRAMID
    want = _object_bound(t, shape, v, spin, eps, accel, delta)
    assert _close(got, want), (got, want)


def _corrupt(table: np.ndarray, amount: float, levels: slice) -> np.ndarray:
    """The table with the maxima of pyramid ``levels`` lowered by ``amount`` (the heights, the
    cells' own corners, left as they are)."""
    bad = table.copy()
    flat = bad[1:].reshape(-1)
    at, sizes = T_HEADER, [lv.size for lv in terrain_levels(_heights(table))]
    for k, n in enumerate(sizes):
        if k in range(len(sizes))[levels]:
            flat[at : at + n] -= amount
        at += n
    return bad


def _heights(table: np.ndarray) -> np.ndarray:
    flat = table[1:].reshape(-1)
    nrow, ncol = int(flat[3]), int(flat[4])
    start = int(flat[T_HEIGHTS])
    return flat[start : start + nrow * ncol].reshape(nrow, ncol)


def test_the_search_test_catches_a_corrupt_pyramid() -> None:
    """A pyramid that under-reports the cells' heights prunes cells that matter, and the
    exhaustive bound then disagrees: on the window's path (few cells within reach) with every
    level lowered, and on the pyramid's (grids of 32 to 64 cells a side, a sphere that can reach
    more of them than the window holds) with every level lowered, and with the levels above
    the cells' own lowered (what only the branch and bound reads). The path of every state is
    asserted, and the correct pyramid agrees on all of them."""
    rng = np.random.default_rng(7)
    caught = {"window": 0, "pyramid": 0, "upper levels": 0}
    for k in range(12):
        # The window: a slow sphere falling onto a 32 x 32 grid.
        t = Terrain([1.0, 1.0, 0.3, 0.1], 33, 33, rng.random(33 * 33))
        c = t.world([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(0.3, 0.5)])
        v = np.asarray([*rng.normal(size=2) * 0.05, -1.0])
        want = _sphere_bound(t, c, v, 0.02, 0.5, 0.0)
        got, path = t.search(_point(c), v, 0.0, 0.02, 0.5)
        assert path == WINDOW and _close(got, want), (got, want, path)
        bad = _corrupt(t.table, 0.25, slice(None))
        caught["window"] += not _close(_tau_of(bad, c, v, 0.02, 0.5), want)
        # The pyramid: 32 to 64 cells a side, a sphere high above that can reach far sideways.
        n = int(rng.integers(33, 66))
        t = Terrain([1.0, 1.0, 0.3, 0.1], n, n, rng.random(n * n))
        cell = 2.0 / (n - 1)
        c = t.world([rng.uniform(-1, 1), rng.uniform(-1, 1), 0.3 + rng.uniform(12, 30) * cell])
        v = np.asarray([*rng.normal(size=2) * 0.3, -rng.uniform(0, 1)])
        want = _sphere_bound(t, c, v, 0.02, 5.0, 0.0)
        got, path = t.search(_point(c), v, 0.0, 0.02, 5.0)
        assert path == PYRAMID and _close(got, want), (got, want, path, k)
        for name, levels in (("pyramid", slice(None)), ("upper levels", slice(1, None))):
            bad = _corrupt(t.table, 0.25, levels)
            caught[name] += not _close(_tau_of(bad, c, v, 0.02, 5.0), want)
    # The window reads the cells' own maxima only to skip, and a state's cells within reach are
    # few: a lowered level changes the result in about half of them (7 of 12 here).
    assert caught["window"] >= 4, caught
    assert caught["pyramid"] >= 10 and caught["upper levels"] >= 10, caught


def _tau_of(table: np.ndarray, c, v, eps: float, accel: float) -> float:
    return tau_static(c[0], c[1], c[2], v[0], v[1], v[2], table, eps, accel, 0.0)


def test_a_fine_grid_reached_sideways_is_searched_not_settled_by_the_base() -> None:
    """201 x 201 points (40,000 cells), a sphere beside the grid and below its base: the base
    is nearer than the side, so its bound is the smaller, and the first cell's value, the time
    to reach the side, is the larger; the cells within that reach are far more than the window
    holds: the pyramid's search decides (the base bound does not), and finds the bound written
    over every cell, for a sphere and a spinning capsule; on a flat block, the side's time
    exactly."""
    flat = Terrain([1.0, 1.0, 0.4, 0.2], 201, 201, np.ones(201 * 201))  # a block, -0.2 to 0.4
    c, v = np.array([1.6, 0.0, -0.3]), np.zeros(3)
    base = math.sqrt(2 * 0.09 / 10.0)  # up 0.1 to the base, less eps
    got, path = flat.search(_point(c), v, 0.0, 0.01, 10.0)
    assert path == PYRAMID
    assert got == pytest.approx(math.sqrt(2 * 0.59 / 10.0), rel=1e-9) and got > 2 * base
    rng = np.random.default_rng(5)
    rough = Terrain([1.0, 1.0, 0.4, 0.2], 201, 201, rng.random(201 * 201), [0.1, 0.0, 0.0])
    for _ in range(3):
        c = np.array([rng.uniform(1.6, 1.8), rng.uniform(-0.8, 0.8), rng.uniform(-0.35, 0.3)])
        v = rng.normal(size=3) * 0.2
        got, path = rough.search(_point(c), v, 0.0, 0.01, 10.0, 0.05)
        assert path == PYRAMID
        want = _sphere_bound(rough, c, v, 0.01, 10.0, 0.05)
        assert _close(got, want) and got > 0.0, (got, want)
        # A spinning capsule there: its reach sideways grows with its spin too.
        shape = _object(ShapeKind.CAPSULE, [0.03, 0.08, 0.0], c, rotation(rng.normal(size=4)))
        got, path = rough.search(shape, v, 0.5, 0.01, 10.0, 0.05)
        assert path == PYRAMID
        want = _object_bound(rough, shape, v, 0.5, 0.01, 10.0, 0.05)
        assert _close(got, want) and got > 0.0, (got, want)


# ------------------------------------------------------------------------------------------------
# (d) never late: the reachable set, and sampled feasible trajectories
# ------------------------------------------------------------------------------------------------


def _first_touch_sphere(t: Terrain, c, v, eps, accel, delta, t_max) -> float:
    cl, u = t.local(c), t.rot.T @ v
    return ref.first_touch(
        lambda s: ref.distances(cl + np.outer(s, u), t.tops, t.base), eps, accel, delta, t_max
    )


def _not_after(tau: float, truth: float) -> bool:
    return tau <= truth * (1 + 1e-9) + 1e-12


@SETTINGS
@given(st.data())
def test_sphere_tau_never_exceeds_the_reachable_sets_first_touch(data) -> None:
    t = data.draw(terrains(max_cells=5))
    c, v, eps, accel, delta = data.draw(motions(t))
    tau = t.tau(c, v, eps, accel, delta)
    truth = _first_touch_sphere(t, c, v, eps, accel, delta, horizon(tau))
    assert _not_after(tau, truth), (tau, truth)
    if tau == 0.0 and t.distance(c) > eps * (1 + 1e-9) + 1e-12:
        # Theorem 9.3's own zero: a point over one triangle of a cell, under the other's
        # extended plane and top (docs/theory.md, section 9, Tightness), never the search's.
        assert _sphere_bound(t, c, v, eps, accel, delta) == 0.0


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow],
          derandomize=True)  # fmt: skip
@given(st.data())
def test_capsule_tau_never_exceeds_the_reachable_sets_first_touch(data) -> None:
    """The exact level's object: a capsule whose points stay within (delta + spin) t +
    accel t^2 / 2 of its translate (docs/theory.md, (5.2)). Every sphere of radius r centred on
    its axis is a part of it, so the capsule's tau is at most the first touch of any of theirs
    (exact distances, nine spheres)."""
    t = data.draw(terrains(max_cells=3))
    c, v, eps, accel, delta = data.draw(motions(t))
    s = float(t.size[2])
    r, half = data.draw(st.floats(0.05, 0.3)) * s, data.draw(st.floats(0.05, 0.6)) * s
    q = [data.draw(st.floats(-1, 1)) for _ in range(4)]
    rot = rotation(q) if np.linalg.norm(q) > 1e-3 else np.eye(3)
    spin = data.draw(st.sampled_from([0.0, 0.5])) * float(np.linalg.norm(v))
    shape = _object(ShapeKind.CAPSULE, [r, half, 0.0], c, rot)
    tau = t.tau_object(shape, v, spin, eps, accel, delta)
    u = t.rot.T @ v
    centres = np.array([t.local(c + rot[:, 2] * half * k) for k in np.linspace(-1, 1, 9)])

    def dist(s_: np.ndarray) -> np.ndarray:
        at = (centres[None, :, :] + np.outer(s_, u)[:, None, :]).reshape(-1, 3)
        return ref.distances(at, t.tops, t.base).reshape(-1, centres.shape[0]).min(axis=1) - r

    truth = ref.first_touch(dist, eps, accel, delta + spin, horizon(tau), 1000)
    assert _not_after(tau, truth), (tau, truth)


def feasible_samples(t: Terrain, c, v, accel, delta, t_end, prog, nsamp=48):
    """Sampled positions of one feasible trajectory on [0, t_end] (as in test_shapes.py):
    pieces of constant acceleration, "toward" aiming |a| = accel at the terrain's closest point
    seen from the predicted mid-piece position, and an initial velocity error |w| <= delta."""
    pieces, (wd, wmag, wmode) = prog

    def toward(x) -> np.ndarray:
        q = t.world(ref.closest_point(t.local(x), t.tops, t.base))
        return _unit(q - x)

    p = np.asarray(c, dtype=np.float64).copy()
    u = np.asarray(v, dtype=np.float64) + delta * wmag * (toward(p) if wmode else _unit(wd))
    total = sum(f for f, *_ in pieces)
    times, points, now = [], [], 0.0
    for frac, dirn, mag, aim in pieces:
        dur = t_end * frac / total
        a = accel * (toward(p + u * dur / 2) if aim else mag * _unit(dirn))
        s = np.linspace(0.0, dur, nsamp)
        times.append(now + s)
        points.append(p + np.outer(s, u) + 0.5 * np.outer(s * s, a))
        p, u, now = p + u * dur + 0.5 * a * dur * dur, u + a * dur, now + dur
    return np.concatenate(times), np.concatenate(points)


@st.composite
def programs(draw):
    pieces = [
        (
            draw(st.floats(0.05, 1.0)),
            [draw(st.floats(-1, 1)) for _ in range(3)],
            draw(st.floats(0, 1)),
            draw(st.sampled_from([True, True, False])),
        )
        for _ in range(draw(st.integers(1, 3)))
    ]
    w = [draw(st.floats(-1, 1)) for _ in range(3)]
    return pieces, (w, draw(st.sampled_from([1.0, 0.5])), draw(st.booleans()))


def _earliest_touch(t: Terrain, times, points, eps, tol):
    local = (np.asarray(points) - t.pos) @ t.rot
    hit = np.flatnonzero(ref.distances(local, t.tops, t.base) - eps < -tol)
    return float(times[hit[0]]) if hit.size else None


@SETTINGS
@given(st.data(), programs())
def test_no_feasible_trajectory_touches_before_tau(data, prog) -> None:
    t = data.draw(terrains(max_cells=5))
    c, v, eps, accel, delta = data.draw(motions(t))
    tau = t.tau(c, v, eps, accel, delta)
    if tau == 0.0:
        return
    times, points = feasible_samples(t, c, v, accel, delta, horizon(tau), prog)
    tol = 1e-9 * float(np.abs(t.size).max())
    assert _earliest_touch(t, times, points, eps, tol) is None, (tau, c, v, eps, accel, delta)


@SETTINGS
@given(st.data())
def test_at_rest_with_unit_speed_the_bound_is_a_gap(data) -> None:
    """Lemma 9.5: Theorem 9.3's bound of an object at rest whose points may move at unit speed
    (u = 0, sigma = 0, A = 0, delta = 1) is at most its distance to the prisms less eps, so a
    flight plan may use it as the planned gap of a sphere's centre or of a geom at a knot
    (plan.cc, TerrainPointGap and TerrainGeomGap): exact distances from reference_terrain, for
    points (the sphere level) and capsules (the exact level: the segment's distance less its
    radius). A kernel fed the grid at half its heights fails it."""
    t = data.draw(terrains(max_cells=5))
    c, _, eps, _, _ = data.draw(motions(t))
    rest = np.zeros(3)
    gap = t.tau(c, rest, eps, 0.0, 1.0)
    assert gap <= max(t.distance(c) - eps, 0.0) * (1 + 1e-9) + 1e-12, (gap, t.distance(c), eps)
    s = float(t.size[2])
    r, half = data.draw(st.floats(0.05, 0.3)) * s, data.draw(st.floats(0.05, 0.6)) * s
    rot = rotation([data.draw(st.floats(-1, 1)) for _ in range(3)] + [0.7])
    shape = _object(ShapeKind.CAPSULE, [r, half, 0.0], c, rot)
    ends = [t.local(c + k * half * rot[:, 2]) for k in (-1.0, 1.0)]
    dist = ref.segment_distance(ends[0], ends[1], t.tops, t.base) - r
    gap = t.tau_object(shape, rest, 0.0, eps, 0.0, 1.0)
    assert gap <= max(dist - eps, 0.0) * (1 + 1e-9) + 1e-12, (gap, dist, eps)


def test_the_gap_bound_is_the_distance_over_flat_terrain_and_catches_a_lowered_grid() -> None:
    """Over a flat grid the rest bound is the height above it less eps (Lemma 9.5 is tight
    there); the same bound computed on the grid at half its heights exceeds the true gap of
    some points (the test above would fail)."""
    rng = np.random.default_rng(5)
    h = 0.25
    flat = Terrain([2.0, 2.0, 0.5, 0.1], 9, 9, np.full(81, h / 0.5))
    for _ in range(50):
        c = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(0.3, 0.8)])
        eps = rng.uniform(0, 0.05)
        assert flat.tau(c, np.zeros(3), eps, 0.0, 1.0) == pytest.approx(c[2] - h - eps, rel=1e-9)
    data = rng.random(25)
    t, low = (
        Terrain([0.5, 0.5, 0.4, 0.1], 5, 5, data),
        Terrain([0.5, 0.5, 0.4, 0.1], 5, 5, data / 2),
    )
    late = 0
    for _ in range(100):
        c = t.world(rng.uniform([-0.5, -0.5, 0.0], [0.5, 0.5, 0.5]))
        late += low.tau(c, np.zeros(3), 0.0, 0.0, 1.0) > t.distance(c) + 1e-9
    assert late > 10


def test_the_trajectory_test_catches_a_lowered_terrain() -> None:
    """tau against the same grid at half its heights is late: the harness finds trajectories
    that touch the real terrain before it, while the correct kernel passes every state here."""
    rng = np.random.default_rng(11)
    caught = 0
    for _ in range(40):
        data = rng.random(25)
        t = Terrain([0.5, 0.5, 0.4, 0.1], 5, 5, data)
        low = Terrain([0.5, 0.5, 0.2, 0.1], 5, 5, data)
        c = np.array([rng.uniform(-0.4, 0.4), rng.uniform(-0.4, 0.4), rng.uniform(0.45, 0.7)])
        v = np.array([0.0, 0.0, -rng.uniform(0, 0.5)])
        prog = ([(1.0, [0, 0, -1], 1.0, True)], ([0, 0, -1], 1.0, True))
        for kernel, is_mutant in ((t, False), (low, True)):
            tau = kernel.tau(c, v, 0.02, 2.0, 0.1)
            times, points = feasible_samples(t, c, v, 2.0, 0.1, horizon(tau), prog)
            hit = _earliest_touch(t, times, points, 0.02, 1e-9)
            if is_mutant:
                caught += hit is not None
            else:
                assert hit is None, (c, v, tau, hit)
    assert caught >= 30, caught


# ------------------------------------------------------------------------------------------------
# (e) exact cases: flat terrain, inside, edges, base
# ------------------------------------------------------------------------------------------------


def test_flat_terrain_is_the_plane() -> None:
    """Over the inside of a flat grid, the sphere's tau is the plane's, and a geom's is the exact
    level's plane tau (its support along -z, with the spin term)."""
    rng = np.random.default_rng(3)
    h = 0.25
    t = Terrain([2.0, 2.0, 0.5, 0.1], 9, 9, np.full(81, h / 0.5))
    for _ in range(200):
        c = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(0.3, 0.8)])
        v = rng.normal(size=3) * 0.2
        eps, accel, delta = rng.uniform(0, 0.05), rng.uniform(0, 3), rng.uniform(0, 0.1)
        want = tau_halfspace(c[2] - h - eps, v[2], accel, delta)
        assert t.tau(c, v, eps, accel, delta) == pytest.approx(want, rel=1e-10)
        rot = rotation(rng.normal(size=4))
        shape = _object(ShapeKind.CAPSULE, [0.05, 0.1, 0.0], c + np.array([0, 0, 0.15]), rot)
        spin = rng.uniform(0, 0.5)
        low = -support(np.array([0.0, 0.0, -1.0]), shape)
        want = tau_halfspace(low - h - eps, v[2] - spin, accel, delta)
        got = t.tau_object(shape, v, spin, eps, accel, delta)
        assert got == pytest.approx(want, rel=1e-10)


def test_within_eps_is_zero_and_the_gap_bounds_the_distance() -> None:
    rng = np.random.default_rng(4)
    t = Terrain([0.5, 0.5, 0.3, 0.1], 6, 6, rng.random(36), [0.2, 0.1, 0.0], rotation([1, 1, 0, 0]))
    positive = 0
    for _ in range(300):
        c = t.world(rng.uniform([-0.6, -0.6, -0.2], [0.6, 0.6, 0.4]))
        dist = t.distance(c)
        eps = rng.uniform(0, 0.05)
        tau = t.tau(c, np.zeros(3), eps, 1.0)
        if dist <= eps:
            assert tau == 0.0
        positive += tau > 0.0
        gap = static_gap(c, t.table)[0]
        assert gap <= dist + 1e-12
    assert positive > 100


def test_edges_sides_and_base() -> None:
    """Beyond the grid's edge there is nothing; its sides and its base are walls."""
    t = Terrain([1.0, 1.0, 0.4, 0.2], 5, 5, np.ones(25))  # a block from -0.2 up to 0.4
    # Beside the grid, level with it and still: never.
    assert t.tau([1.5, 0.0, 0.0], [0.0, 0, 0], 0.01, 0.0) == math.inf
    # Towards its side at 1 m/s: the gap of 0.5 - eps (horizontal speed counts in any
    # direction: moving away gives the same).
    assert t.tau([1.5, 0.0, 0.0], [-1.0, 0, 0], 0.01, 0.0) == pytest.approx(0.49, rel=1e-12)
    assert t.tau([1.5, 0.0, 0.0], [1.0, 0, 0], 0.01, 0.0) == pytest.approx(0.49, rel=1e-12)
    # Above and beside it, accelerating from rest: it must reach the side and come down to
    # the top, 0.59 below (the later of the two).
    assert t.tau([1.5, 0.0, 1.0], [0.0, 0, 0], 0.01, 3.0) == pytest.approx(
        math.sqrt(2 * 0.59 / 3.0), rel=1e-9
    )
    # Under its base, rising at 2 m/s: 0.3 - eps to the base at -0.2.
    assert t.tau([0.0, 0.0, -0.5], [0, 0, 2.0], 0.01, 0.0) == pytest.approx(0.145, rel=1e-12)
    # Under it, far below and still: never.
    assert t.tau([0.0, 0.0, -3.0], [0, 0, 0], 0.01, 0.0) == math.inf
    # Beside and below a fine grid (the pyramid's search: 40,000 cells, many within reach):
    # the base, 0.49 above, binds before the side, 0.09 away.
    fine = Terrain([1.0, 1.0, 0.4, 0.2], 201, 201, np.ones(201 * 201))
    assert fine.tau([1.1, 0.0, -0.7], [0, 0, 0], 0.01, 10.0) == pytest.approx(
        math.sqrt(2 * 0.49 / 10.0), rel=1e-9
    )
    # Above the corner's diagonal, falling: the top at 0.4.
    assert t.tau([1.0, 1.0, 1.4], [0, 0, -1.0], 0.0, 0.0) == pytest.approx(1.0, rel=1e-12)


def test_tilted_terrain_is_judged_in_its_frame() -> None:
    """The same state in the terrain's frame, tilted and moved anywhere: the same tau."""
    rng = np.random.default_rng(5)
    data = rng.random(30)
    flat = Terrain([0.6, 0.5, 0.3, 0.1], 5, 6, data)
    for _ in range(50):
        rot, pos = rotation(rng.normal(size=4)), rng.normal(size=3)
        tilted = Terrain([0.6, 0.5, 0.3, 0.1], 5, 6, data, pos, rot)
        cl, ul = rng.uniform([-0.7, -0.6, 0.0], [0.7, 0.6, 0.6]), rng.normal(size=3)
        a = flat.tau(cl, ul, 0.02, 1.0, 0.1)
        b = tilted.tau(tilted.world(cl), rot @ ul, 0.02, 1.0, 0.1)
        assert b == pytest.approx(a, rel=1e-9, abs=1e-12)


def test_records_checked_by_time_to_static() -> None:
    t = Terrain([1, 1, 0.2, 0.1], 4, 4, np.zeros(16))
    with pytest.raises(InvalidInputError, match="out of range"):
        time_to_static([[0.0, 0.0, 1.0]], [[0.0, 0.0, 0.0]], t.table, [1], 0.0, 1.0)
    assert t.table.shape[1] == SHAPE_NCOL
