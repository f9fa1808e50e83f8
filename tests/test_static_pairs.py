"""Static geoms held as their own shapes in the MuJoCo layer (docs/static-shapes.md, section 10).

Which geoms become shapes, how geom pairs expand into sphere-shape pairs, that the fused step's
tau of a shape pair is ``time_to_static`` (and ``PairSet.tau``) on the same state, the guard on
the static poses, and rollouts of the bundled scenes without a miss.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from geom_types import BLOB_ASSET, GEOM_TYPES
from rollouts import predictor_rollout
from static_guard import assert_reset_refuses_a_moved_static_body

from dua_mujoco.build.covering import cover_model, static_shape_geoms
from dua_mujoco.build.filter import active_geom_pairs, sphere_pairs
from dua_mujoco.build.options import CoveringOptions, PilotOptions, UrgencyOptions
from dua_mujoco.build.tables import PairTables, static_shapes
from dua_mujoco.core.pairset import PairKind, PairSet, pack_pairs
from dua_mujoco.core.shapes import SHAPE_KIND, ShapeKind, closest_point, time_to_static
from dua_mujoco.exceptions import InvalidChoiceError, InvalidInputError
from dua_mujoco.measure.rollout import run
from dua_mujoco.models.scenes import load_scene, make_controller
from dua_mujoco.runtime.predictor import Predictor

# A table top: the capsule's covering sphere reaches into it from 0.6 m up.
TABLE_TOP = 'type="box" size=".9 .45 .02"'


def _scene(static_geom: str, margin: float = 0.0, gap: float = 0.0) -> mujoco.MjModel:
    """A static geom (world child body, rotated) and a moving capsule with a 3-sphere covering."""
    return mujoco.MjModel.from_xml_string(
        f"""<mujoco>
          {BLOB_ASSET}
          <worldbody>
            <body name="stand" pos=".1 -.2 .5" euler="10 20 30">
              <geom name="static" {static_geom} pos=".05 0 .02" euler="0 15 0"
                    margin="{margin}" gap="{gap}"/>
            </body>
            <body name="arm" pos="0 0 1.5"><freejoint/>
              <geom name="link" type="capsule" size=".05 .3" margin="{margin}" gap="{gap}"/>
            </body>
            <body name="ghost" mocap="true" pos="2 0 0"><geom type="box" size=".1 .1 .1"/></body>
          </worldbody>
        </mujoco>"""
    )


@pytest.mark.parametrize("gtype", list(GEOM_TYPES))
def test_static_geoms_become_shapes(gtype: str) -> None:
    m = _scene(GEOM_TYPES[gtype])
    cov = cover_model(m)  # static="shape" is the default
    static = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "static")
    link = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "link")
    assert cov.shape_geom.tolist() == [static]
    assert cov.geom_shape[static] == 0 and cov.nshape == 1
    assert cov.spheres_of(static).size == 0
    # The moving geom and the mocap box keep their spheres.
    assert cov.spheres_of(link).size == 1 and cov.nsphere == 2
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    rec = static_shapes(m, cov.shape_geom, d)
    assert rec.shape == (1, 16)
    assert int(rec[0, SHAPE_KIND]) == int(m.geom_type[static])
    if gtype == "mesh":
        assert int(rec[0, SHAPE_KIND]) == int(ShapeKind.MESH_BOX)
        # Every hull vertex is inside the record's box.
        adr, num = int(m.mesh_vertadr[0]), int(m.mesh_vertnum[0])
        verts = np.asarray(m.mesh_vert[adr : adr + num], dtype=np.float64)
        world = d.geom_xpos[static] + verts @ d.geom_xmat[static].reshape(3, 3).T
        for p in world:
            q = np.asarray(closest_point(p, rec[0]))
            assert np.linalg.norm(q - p) <= 1e-6
    # The old behaviour on demand.
    old = cover_model(m, static="sphere")
    assert old.nshape == 0 and old.spheres_of(static).size == 1


def test_which_geoms_are_static() -> None:
    m = mujoco.MjModel.from_xml_string(
        """<mujoco>
          <asset><hfield name="hf" nrow="2" ncol="2" size="1 1 .1 .1"/></asset>
          <worldbody>
            <geom name="floor" type="plane" size="5 5 .1"/>
            <geom name="terrain" type="hfield" hfield="hf" pos="3 0 0"/>
            <geom name="wall" type="box" size=".1 1 1" pos="-2 0 1"/>
            <geom name="visual" type="box" size=".1 .1 .1" contype="0" conaffinity="0"/>
            <geom name="paired_a" type="box" size=".1 .1 .1" pos="0 3 0"/>
            <body name="shelf" pos="1 1 0"><geom name="board" type="box" size=".3 .3 .01"/>
              <body name="bin" pos="0 0 .3"><geom name="bin" type="cylinder" size=".1 .1"/></body>
            </body>
            <body name="m" mocap="true"><geom name="mocap" type="box" size=".1 .1 .1"/></body>
            <body name="free" pos="0 0 2"><freejoint/><geom name="ball" type="sphere" size=".1"/>
              <geom name="paired_b" type="box" size=".1 .1 .1" pos=".3 0 0"/></body>
          </worldbody>
          <contact>
            <pair geom1="paired_a" geom2="wall"/>
            <pair geom1="paired_a" geom2="paired_b"/>
          </contact>
        </mujoco>"""
    )

    def gid(name: str) -> int:
        return mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)

    mask = static_shape_geoms(m)
    # World geoms and geoms of bodies welded to the world (any depth) are static; a <pair> of
    # two static geoms keeps both as spheres (an explicit pair is active even then).
    assert sorted(np.flatnonzero(mask).tolist()) == sorted(
        gid(n) for n in ("visual", "board", "bin")
    )
    cov = cover_model(m, hfield="box")
    # Visual geoms never collide: no shape, no sphere.
    assert sorted(cov.shape_geom.tolist()) == sorted([gid("board"), gid("bin")])
    assert cov.spheres_of(gid("terrain")).size == 1  # height fields keep their spheres
    assert cov.spheres_of(gid("mocap")).size == 1
    assert cov.spheres_of(gid("wall")).size == 1 and cov.spheres_of(gid("paired_a")).size == 1
    assert cov.geom_plane[gid("floor")] == 0
    sp = sphere_pairs(cov, active_geom_pairs(m))  # no pair without a sphere
    assert sp.npair > 0
    with pytest.raises(InvalidChoiceError, match="sphere"):
        cover_model(m, hfield="box", static="box")


@pytest.mark.parametrize("mode", ["bounding", "multi"])
def test_shape_pairs_expand_and_name_the_static_geom(mode: str) -> None:
    m = _scene(TABLE_TOP, margin=0.01, gap=0.02)
    cov = cover_model(m, mode=mode, max_spheres_per_geom=3)
    gp = active_geom_pairs(m)
    sp = sphere_pairs(cov, gp)
    static = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "static")
    link = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "link")
    k = gp.index_of(static, link)
    assert k >= 0
    mine = sp.geom_pair == k
    spheres = cov.spheres_of(link)
    assert mine.sum() == spheres.size and (mode == "bounding" or spheres.size == 3)
    assert sp.is_shape[mine].all() and not sp.is_halfspace[mine].any()
    assert sorted(sp.first[mine].tolist()) == spheres.tolist()
    assert (sp.second[mine] == cov.geom_shape[static]).all()
    # Summed margins and gaps (0.01 + 0.01 + 0.02 + 0.02), plus the sphere radius.
    np.testing.assert_allclose(sp.eps[mine], cov.sphere_radius[sp.first[mine]] + 0.06)
    assert (sp.kind[mine] == PairKind.SHAPE).all()
    tables = PairTables.build(m, cov, sp)
    assert (tables.geom2[mine] == static).all() and (tables.geom1[mine] == link).all()


def _predictor_states(p: Predictor, d: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    c, v = p.sphere_states(d)
    return c, v


@pytest.mark.parametrize("scene", ["two_arms", "clutter"])
def test_fused_step_equals_time_to_static(scene: str) -> None:
    m, d = load_scene(scene)
    p = Predictor(
        m, accel=15.0, schedule="select-all", urgency=UrgencyOptions(exact=False)
    )  # the shape level alone
    assert p.covering.nshape > 0
    ctrl = make_controller(m, "random", seed=4, hold_steps=10)
    ps = p.pair_set
    shape_ids = np.flatnonzero(ps.shape)
    assert shape_ids.size > 0
    checked = 0
    for k in predictor_rollout(m, d, p, ctrl, 60):
        if k == 0:
            continue
        sched = p.scheduler
        assert sched is not None
        c, v = _predictor_states(p, d)
        shapes = static_shapes(m, p.covering.shape_geom, d)
        # The slow reference, pair by pair, through the validated front of the shape kernel.
        i = ps.first[shape_ids]
        want = time_to_static(
            c[i],
            v[i],
            shapes,
            ps.second[shape_ids],
            ps.eps[shape_ids],
            ps.accel[shape_ids],
            vel_uncertainty=ps.vel_uncertainty[shape_ids],
        )
        np.testing.assert_array_equal(sched.last_tau[shape_ids], want)
        every = ps.tau(np.arange(len(ps)), c, v, p.halfspaces(d), shapes=shapes)
        np.testing.assert_array_equal(sched.last_tau, every)
        checked += int(np.sum(np.isfinite(want) & (want < 1.0)))
    assert checked > 0  # some shape pairs were close enough to matter


def test_pairset_kinds_and_geometry() -> None:
    shapes = np.zeros((1, 16))
    shapes[0, :] = [6, 0.5, 0.5, 0.5, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1]
    c = np.array([[0.0, 0.0, 2.0], [0.0, 0.0, 5.0]])
    v = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 0.0]])
    ps = PairSet([0, 0, 0], [1, 0, 0], [0.2, 0.1, 0.1], 0.0, kind=[0, 1, 2])
    assert ps.halfspace.tolist() == [False, True, False]
    assert ps.shape.tolist() == [False, False, True]
    planes = (np.array([[0.0, 0.0, 1.0]]), np.array([0.0]))
    tau = ps.tau([0, 1, 2], c, v, planes, shapes=shapes)
    # Sphere 0 falls at 1 m/s: to sphere 1 never, to the floor 1.9 s, to the box top 1.4 s.
    assert tau[0] == np.inf
    assert tau[1] == pytest.approx(1.9)
    assert tau[2] == pytest.approx(1.4)
    with pytest.raises(InvalidInputError, match="shapes="):
        ps.tau([2], c, v, planes)
    # A pair id out of range is named by the native evaluation (Python does not check it again).
    for bad in (3, -1):
        with pytest.raises(InvalidInputError, match=rf"pair id {bad} is out of range \[0, 3\)"):
            ps.tau([0, bad], c, v, planes, shapes=shapes)
    # Records held by the pair set serve when none are passed (static shapes do not move).
    held = PairSet([0, 0, 0], [1, 0, 0], [0.2, 0.1, 0.1], 0.0, kind=[0, 1, 2], shapes=shapes)
    np.testing.assert_array_equal(held.tau([0, 1, 2], c, v, planes), tau)
    with pytest.raises(InvalidInputError, match="not both"):
        PairSet([0], [1], 0.1, 0.0, kind=[0], halfspace=[False])
    with pytest.raises(InvalidInputError, match="PairKind"):
        PairSet([0], [1], 0.1, 0.0, kind=[3])
    rec = pack_pairs(ps, plane_frame=[7])
    assert rec[:, 2].tolist() == [0, 1, 2] and rec[:, 7].tolist() == [0, 7, 0]
    # The halfspace= form still works and means what it did.
    old = PairSet([0, 0], [1, 0], [0.2, 0.1], 0.0, halfspace=[False, True])
    assert old.kind.tolist() == [0, 1] and not old.has_shape


def test_reset_refuses_a_moved_static_geom() -> None:
    m = _scene(TABLE_TOP)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    p = Predictor(m, accel=5.0)
    p.reset(d)
    # Another model with the same geoms but the stand moved: same_geometry cannot tell.
    m2 = _scene(TABLE_TOP)
    m2.body_pos[1] += [0.0, 0.0, 0.3]
    d2 = mujoco.MjData(m2)
    mujoco.mj_forward(m2, d2)
    with pytest.raises(InvalidInputError, match=r"static geom .*'static'.* must not move"):
        p.reset(d2)
    # The model edited after data's last mj_forward, and after it.
    assert_reset_refuses_a_moved_static_body(_scene(TABLE_TOP), 1, "static")


def test_alarms_name_static_geom() -> None:
    m = _scene(TABLE_TOP)
    d = mujoco.MjData(m)
    d.qpos[2] = 0.6  # the capsule inside the table top
    mujoco.mj_forward(m, d)
    p = Predictor(m, accel=5.0)
    a = p.reset(d)
    static = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "static")
    assert static in a.geom2.tolist()
    assert (a.sphere2[a.geom2 == static] == -1).all()


@pytest.mark.slow
@pytest.mark.parametrize("scene", ["two_arms", "traffic", "clutter"])
def test_rollout_with_static_shapes_misses_nothing(scene: str) -> None:
    m, d = load_scene(scene)
    p = Predictor(
        m,
        covering=CoveringOptions(static="shape"),
        pilot=PilotOptions(controller=make_controller(m, "random", seed=99)),
    )
    assert p.covering.nshape > 0
    r = run(m, d, p, steps=2000, controller=make_controller(m, "random", seed=0), progress=False)
    assert r.missed_onsets_valid_bounds == 0, [x for x in r.misses if x.bounds_held][:5]
    assert r.unfiltered_contacts == 0
    assert r.predicted_onsets + r.missed_onsets == r.contact_onsets
    # Contacts with the static geoms happen and were predicted.
    assert r.contact_onsets > 0


WALL = """<mujoco><option timestep="0.002" gravity="0 0 0"/><worldbody>
<geom name="floor" type="plane" size="5 5 .1"/>
<geom name="wall" type="box" pos="1.2 0 0.5" size="0.1 1 0.5"/>
<body name="ball" pos="0 0 0.5"><freejoint/><geom name="ball" type="sphere" size=".05"/></body>
</worldbody></mujoco>"""


@pytest.mark.parametrize("exact", [False, True])
def test_a_speed_bound_lasts_a_static_gap(exact: bool) -> None:
    """A ball under a large acceleration bound and a speed bound V, by a static wall (a shape
    pair) over the floor (a half-space): its points move at most V t, so a gap g lasts at least
    g / V, and tau is raised to it (without the term, tau is the acceleration bound's, far
    below); never above: a ball already moving at V straight in touches at exactly g / V. A
    ball measured faster than V has broken its bound: the term is dropped."""
    m = mujoco.MjModel.from_xml_string(WALL)
    d = mujoco.MjData(m)
    speed = 1.5
    p = Predictor(m, accel=1000.0, speed=speed, urgency=UrgencyOptions(exact=exact))
    ball = m.geom("ball").id
    rng = np.random.default_rng(5)

    def tau_of(name: str) -> float:
        g = m.geom(name).id
        t = p.tables
        ids = np.flatnonzero(
            ((t.geom1 == g) & (t.geom2 == ball)) | ((t.geom2 == g) & (t.geom1 == ball))
        )
        return float(p.pair_state().last_tau_of(ids).min())

    for _ in range(20):
        x, z = rng.uniform(-0.5, 0.9), rng.uniform(0.3, 0.9)
        direction = rng.normal(size=3)
        v = direction / np.linalg.norm(direction) * rng.uniform(0, speed)
        for into, velocity in [("any", v), ("wall", [speed, 0, 0]), ("floor", [0, 0, -speed])]:
            d.qpos[:3] = [x, 0.0, z]
            d.qvel[:3] = velocity
            mujoco.mj_forward(m, d)
            p.reset(d)
            gaps = {"wall": 1.1 - x - 0.05, "floor": z - 0.05}
            for name, gap in gaps.items():
                tau = tau_of(name)
                assert tau >= gap / speed * (1 - 1e-9), (name, tau, gap / speed)
                if into == name:
                    assert tau <= gap / speed * (1 + 1e-12), (name, tau, gap / speed)
    d.qpos[:3] = [0.5, 0.0, 0.5]
    d.qvel[:3] = [2 * speed, 0, 0]  # faster than the bound: the acceleration term alone
    mujoco.mj_forward(m, d)
    p.reset(d)
    assert tau_of("wall") < 0.55 / (2 * speed)
