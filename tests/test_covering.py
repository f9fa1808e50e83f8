"""Containment and budgets of the sphere coverings (dua_mujoco.build.covering)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from dua_mujoco.build.covering import Covering, CoveringMode, cover_model, sphere_world_centers
from dua_mujoco.exceptions import InvalidChoiceError, InvalidInputError, UnsupportedGeomError

GEOM_TYPES = ["sphere", "capsule", "ellipsoid", "cylinder", "box", "mesh"]
BUDGETS = [1, 2, 5, 8, 27]
N_POSES = 6


def _random_mesh_vertices(rng: np.random.Generator) -> np.ndarray:
    # A random blob: many vertices are interior, so the hull differs from the vertex set.
    pts = rng.normal(size=(24, 3)) * rng.uniform(0.05, 0.6, size=3)
    return pts + rng.normal(size=3) * 0.1


def _geom_xml(gtype: str, rng: np.random.Generator) -> tuple[str, str]:
    """(asset xml, geom attributes) for a geom of random size and random offset in its body."""
    size = rng.uniform(0.02, 0.8, size=3)
    pos = " ".join(f"{x:.4f}" for x in rng.normal(size=3) * 0.2)
    quat = rng.normal(size=4)
    quat = " ".join(f"{x:.4f}" for x in quat / np.linalg.norm(quat))
    common = f'pos="{pos}" quat="{quat}"'
    if gtype == "mesh":
        verts = " ".join(f"{x:.5f}" for x in _random_mesh_vertices(rng).ravel())
        scale = " ".join(f"{x:.3f}" for x in rng.uniform(0.5, 2.0, size=3))
        asset = f'<mesh name="blob" vertex="{verts}" scale="{scale}"/>'
        return asset, f'type="mesh" mesh="blob" {common}'
    n = {"sphere": 1, "capsule": 2, "cylinder": 2, "ellipsoid": 3, "box": 3}[gtype]
    sz = " ".join(f"{x:.4f}" for x in size[:n])
    return "", f'type="{gtype}" size="{sz}" {common}'


def _model_with_geom(gtype: str, seed: int) -> tuple[mujoco.MjModel, mujoco.MjData]:
    rng = np.random.default_rng(seed)
    asset, geom = _geom_xml(gtype, rng)
    xml = f"""
    <mujoco>
      <asset>{asset}</asset>
      <worldbody>
        <body name="b"><freejoint/><geom name="g" {geom}/></body>
      </worldbody>
    </mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    q = rng.normal(size=4)
    d.qpos[:3] = rng.normal(size=3)
    d.qpos[3:7] = q / np.linalg.norm(q)
    mujoco.mj_forward(m, d)
    return m, d


def _unit(rng: np.random.Generator, n: int) -> np.ndarray:
    u = rng.normal(size=(n, 3))
    return u / np.linalg.norm(u, axis=1, keepdims=True)


def _hull_faces(m: mujoco.MjModel, mesh_id: int) -> np.ndarray:
    adr = int(m.mesh_graphadr[mesh_id])
    nv, nf = int(m.mesh_graph[adr]), int(m.mesh_graph[adr + 1])
    start = adr + 2 + 3 * nv + 3 * nf
    return np.asarray(m.mesh_graph[start : start + 3 * nf]).reshape(nf, 3)


def _local_samples(m: mujoco.MjModel, g: int, rng: np.random.Generator, n: int = 400) -> np.ndarray:
    """Points of the geom's solid in its frame: surface (edges and corners included) and inside."""
    gtype = int(m.geom_type[g])
    s = np.asarray(m.geom_size[g])
    if gtype == int(mujoco.mjtGeom.mjGEOM_SPHERE):
        surf = s[0] * _unit(rng, n)
    elif gtype == int(mujoco.mjtGeom.mjGEOM_ELLIPSOID):
        surf = s[:3] * _unit(rng, n)
    elif gtype == int(mujoco.mjtGeom.mjGEOM_CAPSULE):
        u = _unit(rng, n)
        z = rng.uniform(-s[1], s[1], size=n)
        side = np.column_stack([s[0] * u[:, :2] / np.linalg.norm(u[:, :2], axis=1)[:, None], z])
        cap = s[0] * u + np.where(u[:, 2:] >= 0, 1.0, -1.0) * np.array([0, 0, s[1]])
        surf = np.vstack([side, cap])
    elif gtype == int(mujoco.mjtGeom.mjGEOM_CYLINDER):
        phi = rng.uniform(0, 2 * np.pi, size=n)
        rho = s[0] * np.sqrt(rng.uniform(size=n))
        z = rng.uniform(-s[1], s[1], size=n)
        ring = np.column_stack([s[0] * np.cos(phi), s[0] * np.sin(phi)])
        side = np.column_stack([ring, z])
        rim = np.column_stack([ring, np.where(z > 0, s[1], -s[1])])
        caps = np.column_stack([rho * np.cos(phi), rho * np.sin(phi), np.where(z > 0, s[1], -s[1])])
        surf = np.vstack([side, rim, caps])
    elif gtype == int(mujoco.mjtGeom.mjGEOM_BOX):
        p = rng.uniform(-1, 1, size=(n, 3))
        axis = rng.integers(0, 3, size=n)
        p[np.arange(n), axis] = np.sign(p[np.arange(n), axis])
        corners = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
        surf = np.vstack([p, corners]) * s[:3]
    else:
        mesh = int(m.geom_dataid[g])
        adr, num = int(m.mesh_vertadr[mesh]), int(m.mesh_vertnum[mesh])
        verts = np.asarray(m.mesh_vert[adr : adr + num], dtype=np.float64)
        faces = _hull_faces(m, mesh)
        tri = verts[faces[rng.integers(0, len(faces), size=n)]]
        w = rng.dirichlet(np.ones(3), size=n)
        on_faces = np.einsum("nk,nkj->nj", w, tri)
        edges = tri[:, 0] + rng.uniform(size=(n, 1)) * (tri[:, 1] - tri[:, 0])
        surf = np.vstack([verts, on_faces, edges])
    inside = surf * rng.uniform(0, 1, size=(surf.shape[0], 1))
    return np.vstack([surf, inside])


def _assert_contained(cov: Covering, d: mujoco.MjData, g: int, local: np.ndarray) -> None:
    xmat = d.geom_xmat[g].reshape(3, 3)
    world = d.geom_xpos[g] + local @ xmat.T
    ids = cov.spheres_of(g)
    centres = sphere_world_centers(cov, d.geom_xpos, d.geom_xmat, ids)
    dist = np.linalg.norm(world[:, None, :] - centres[None, :, :], axis=2)
    slack = dist - cov.sphere_radius[ids][None, :]
    # float32 mesh storage and the float64 pose leave ~1e-7 relative noise.
    tol = 1e-6 * (1.0 + float(np.max(np.abs(local))))
    worst = float(np.max(np.min(slack, axis=1)))
    assert worst <= tol, f"a point lies {worst:.3g} outside every covering sphere"


@pytest.mark.parametrize("gtype", GEOM_TYPES)
@pytest.mark.parametrize("seed", range(N_POSES))
def test_containment_every_geom_type(gtype: str, seed: int) -> None:
    m, d = _model_with_geom(gtype, 1000 * seed + GEOM_TYPES.index(gtype))
    local = _local_samples(m, 0, np.random.default_rng(seed))
    cov = cover_model(m, mode="bounding")
    assert cov.nsphere == 1
    _assert_contained(cov, d, 0, local)
    for budget in BUDGETS:
        cov = cover_model(m, mode=CoveringMode.MULTI, max_spheres_per_geom=budget)
        assert 1 <= cov.nsphere <= budget
        _assert_contained(cov, d, 0, local)


def test_mesh_bounding_radius_contains_vertices() -> None:
    # geom_rbound of a mesh is about the geom origin, not the mesh centroid: check every vertex.
    for seed in range(10):
        m, _ = _model_with_geom("mesh", seed)
        mesh = int(m.geom_dataid[0])
        adr, num = int(m.mesh_vertadr[mesh]), int(m.mesh_vertnum[mesh])
        verts = np.asarray(m.mesh_vert[adr : adr + num], dtype=np.float64)
        assert np.linalg.norm(verts, axis=1).max() <= m.geom_rbound[0] * (1 + 1e-6)


def test_multi_tighter_than_bounding_for_elongated_box() -> None:
    m = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><geom type="box" size="1 .1 .1"/></worldbody></mujoco>'
    )
    # A world geom: covered by spheres only with static="sphere".
    vb = np.sum(cover_model(m, mode="bounding", static="sphere").sphere_radius ** 3)
    multi = cover_model(m, mode="multi", max_spheres_per_geom=8, static="sphere")
    assert multi.nsphere <= 8
    assert np.sum(multi.sphere_radius**3) < 0.2 * vb


def test_multi_exact_sphere_and_capsule_shapes() -> None:
    m = mujoco.MjModel.from_xml_string(
        """<mujoco><worldbody>
        <geom type="sphere" size=".3"/>
        <geom type="capsule" size=".1 .5"/>
        <geom type="ellipsoid" size=".2 .2 .2"/>
        </worldbody></mujoco>"""
    )
    cov = cover_model(m, mode="multi", max_spheres_per_geom=6, static="sphere")
    assert cov.spheres_of(0).size == 1 and cov.sphere_radius[0] == pytest.approx(0.3)
    caps = cov.spheres_of(1)
    assert 1 < caps.size <= 6
    assert np.allclose(cov.sphere_offset[caps][:, :2], 0.0)
    # A round ellipsoid is a sphere: the bounding sphere beats any grid.
    assert cov.spheres_of(2).size == 1
    assert cov.sphere_radius[cov.spheres_of(2)][0] == pytest.approx(0.2)


def test_layout_planes_and_visual_geoms() -> None:
    m = mujoco.MjModel.from_xml_string(
        """<mujoco><worldbody>
        <geom name="floor" type="plane" size="1 1 .1"/>
        <body><freejoint/>
          <geom name="a" type="box" size=".1 .2 .3"/>
          <geom name="vis" type="sphere" size=".1" contype="0" conaffinity="0"/>
          <geom name="c" type="capsule" size=".1 .2"/>
        </body>
        </worldbody></mujoco>"""
    )
    cov = cover_model(m, mode="multi", max_spheres_per_geom=4)
    assert cov.plane_geom.tolist() == [0]
    assert cov.geom_plane.tolist() == [0, -1, -1, -1]
    assert cov.nplane == 1 and bool(cov.plane_static[0])
    assert cov.spheres_of(0).size == 0
    assert cov.spheres_of(2).size == 0  # visual-only geom
    assert cov.spheres_of(1).size > 0 and cov.spheres_of(3).size > 0
    assert cov.geom_sphere_start.shape == (m.ngeom + 1,)
    assert cov.geom_sphere_start[-1] == cov.nsphere
    assert np.all(cov.sphere_body == m.geom_bodyid[cov.sphere_geom])
    for g in range(m.ngeom):
        assert np.all(cov.sphere_geom[cov.spheres_of(g)] == g)
    every = cover_model(m, only_collidable=False)
    assert every.spheres_of(2).size == 1
    assert cov.sphere_geom.dtype == np.int32 and cov.geom_sphere_start.dtype == np.int32


def test_sphere_world_centers_matches_loop() -> None:
    m, d = _model_with_geom("box", 3)
    cov = cover_model(m, mode="multi", max_spheres_per_geom=8)
    allc = sphere_world_centers(cov, d.geom_xpos, d.geom_xmat)
    for i in range(cov.nsphere):
        g = cov.sphere_geom[i]
        want = d.geom_xpos[g] + d.geom_xmat[g].reshape(3, 3) @ cov.sphere_offset[i]
        np.testing.assert_allclose(allc[i], want, atol=1e-12)
    ids = np.array([cov.nsphere - 1, 0])
    np.testing.assert_allclose(sphere_world_centers(cov, d.geom_xpos, d.geom_xmat, ids), allc[ids])


HFIELD_XML = """
<mujoco>
  <asset>
    <hfield name="hf" nrow="4" ncol="5" size="1.5 1 .4 .2"
            elevation="0 .2 .5 1 .3  .1 .9 .4 0 .2  1 0 .3 .6 .8  .2 .4 .1 .9 0"/>
  </asset>
  <worldbody>
    <geom name="terrain" type="hfield" hfield="hf" pos=".3 -.2 .1" euler="0 0 30"/>
    <body pos="0 0 1"><freejoint/><geom type="sphere" size=".1"/></body>
  </worldbody>
</mujoco>"""


def test_hfield_is_terrain_by_default_and_error_names_geom_and_fix() -> None:
    m = mujoco.MjModel.from_xml_string(HFIELD_XML)
    cov = cover_model(m)
    assert cov.shape_geom.tolist() == [0] and cov.spheres_of(0).size == 0
    with pytest.raises(UnsupportedGeomError, match=r"terrain.*hfield=\"box\""):
        cover_model(m, hfield="error")


@pytest.mark.parametrize("mode", ["bounding", "multi"])
def test_hfield_box_contains_surface(mode: str) -> None:
    m = mujoco.MjModel.from_xml_string(HFIELD_XML)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    cov = cover_model(m, mode=mode, hfield="box", max_spheres_per_geom=6)
    assert 1 <= cov.spheres_of(0).size <= 6
    sx, sy, sz, base = m.hfield_size[0]
    nrow, ncol = int(m.hfield_nrow[0]), int(m.hfield_ncol[0])
    elev = np.asarray(m.hfield_data[: nrow * ncol]).reshape(nrow, ncol)
    # Grid points of the surface (rows along y, columns along x), the base, and points between.
    x = np.linspace(-sx, sx, ncol)
    y = np.linspace(-sy, sy, nrow)
    xx, yy = np.meshgrid(x, y)
    top = np.column_stack([xx.ravel(), yy.ravel(), sz * elev.ravel()])
    bottom = top.copy()
    bottom[:, 2] = -base
    rng = np.random.default_rng(0)
    mid = top.copy()
    mid[:, 2] = -base + rng.uniform(size=top.shape[0]) * (top[:, 2] + base)
    _assert_contained(cov, d, 0, np.vstack([top, bottom, mid]))


def test_argument_validation() -> None:
    m = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><geom type="box" size="1 1 1"/></worldbody></mujoco>'
    )
    with pytest.raises(InvalidChoiceError, match="bounding"):
        cover_model(m, mode="tight")
    with pytest.raises(InvalidChoiceError, match="box"):
        cover_model(m, hfield="ignore")
    for bad in (0, -1, 2.5, True):
        with pytest.raises(InvalidInputError, match="max_spheres_per_geom"):
            cover_model(m, mode="multi", max_spheres_per_geom=bad)  # type: ignore[arg-type]
    assert cover_model(m, mode="MULTI").mode is CoveringMode.MULTI
    cov = cover_model(m)
    with pytest.raises(InvalidInputError, match="out of range"):
        cov.spheres_of(5)
    # A sphere id out of range is named by the kinematics kernel (no Python check repeats it).
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    with pytest.raises(
        InvalidInputError,
        match=r"sphere id 1 \(ids\[0\]\) is out of range: "
        r"the records hold 1 spheres \(valid ids 0\.\.0\)",
    ):
        sphere_world_centers(cover_model(m, static="sphere"), d.geom_xpos, d.geom_xmat, [1])


@pytest.mark.parametrize(
    ("gtype", "size"),
    [
        ("ellipsoid", "0.8 0.1 0.2"),
        ("cylinder", "0.1 0.8"),
        ("cylinder", "0.8 0.05"),
        ("capsule", "0.05 0.7"),
        ("box", "0.05 0.6 0.3"),
    ],
)
@pytest.mark.parametrize("budget", [2, 8, 40])
def test_elongated_shapes_use_grids_and_contain(gtype: str, size: str, budget: int) -> None:
    m = mujoco.MjModel.from_xml_string(
        f"""<mujoco><worldbody><body pos=".1 .2 .3" euler="20 30 40"><freejoint/>
        <geom type="{gtype}" size="{size}" pos=".05 0 0" euler="10 0 5"/>
        </body></worldbody></mujoco>"""
    )
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    cov = cover_model(m, mode="multi", max_spheres_per_geom=budget)
    assert cov.nsphere <= budget
    if budget >= 8 and size != "0.8 0.05":
        assert cov.nsphere > 1
    if budget >= 40:
        # A flat disk needs more than 8 cells before a grid beats one sphere.
        assert cov.nsphere > 1
    _assert_contained(cov, d, 0, _local_samples(m, 0, np.random.default_rng(budget), n=2000))
