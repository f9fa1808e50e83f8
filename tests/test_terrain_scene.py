"""Height fields as terrain in the MuJoCo layer: which geoms, the predictor's step, the exact
level's branch, the bundled scenes, and rollouts (docs/static-shapes.md, section 13)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from rollouts import predictor_rollout
from static_guard import assert_reset_refuses_a_moved_static_body

from dua_mujoco import _core
from dua_mujoco.build.covering import cover_model, terrain_geoms
from dua_mujoco.build.exact import GX_RADIUS, X_DIST, X_G1, X_G2, X_MODE, ExactMode
from dua_mujoco.build.options import CoveringOptions, PilotOptions, UrgencyOptions
from dua_mujoco.build.tables import static_shapes
from dua_mujoco.core.pairset import PairKind
from dua_mujoco.core.shapes import ShapeKind, pack_shapes, time_to_static
from dua_mujoco.core.terrain import T_HEIGHTS, TERRAIN_BLOCK
from dua_mujoco.exceptions import UnsupportedGeomError
from dua_mujoco.measure.rollout import run
from dua_mujoco.models.scenes import load_scene, make_controller
from dua_mujoco.runtime.predictor import Predictor

WORLD = """<mujoco>
  <asset><hfield name="h" nrow="6" ncol="7" size="1 1 .3 .1"
    elevation="{}"/></asset>
  <worldbody>
    {}
    <body name="free" pos="0 0 1"><freejoint/><geom name="ball" type="sphere" size=".1"/>
      <geom name="rod" type="capsule" size=".03" fromto="0 0 0 .3 0 -.2"/></body>
  </worldbody>
  {}
</mujoco>"""
ELEVATION = " ".join(f"{x:.3f}" for x in np.random.default_rng(0).random(42))


def _model(ground: str, extra: str = "") -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(WORLD.format(ELEVATION, ground, extra))


def _gid(m: mujoco.MjModel, name: str) -> int:
    return mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)


def test_static_height_fields_are_terrain_and_a_moving_one_is_refused() -> None:
    m = _model('<body name="stand"><geom name="t" type="hfield" hfield="h" pos="0 0 .2"/></body>')
    cov = cover_model(m)
    assert cov.shape_geom.tolist() == [_gid(m, "t")] and cov.spheres_of(_gid(m, "t")).size == 0
    assert terrain_geoms(m).tolist() == [True, False, False]
    assert cover_model(m, hfield="box").spheres_of(_gid(m, "t")).size == 1
    for body in ('<body name="walker"><joint type="slide"/>', '<body name="walker" mocap="true">'):
        moving = _model(f'{body}<geom name="t" type="hfield" hfield="h"/></body>')
        with pytest.raises(UnsupportedGeomError) as info:
            cover_model(moving)
        message = str(info.value)
        assert "'t'" in message and "'walker'" in message and 'hfield="box"' in message
        assert cover_model(moving, hfield="box").spheres_of(0).size == 1
    # A terrain in a <pair> with another static geom keeps its box spheres (a terrain pairs
    # with spheres only), as a static box would.
    paired = _model(
        '<geom name="t" type="hfield" hfield="h"/><geom name="post" type="box" size=".1 .1 .1"/>',
        '<contact><pair geom1="t" geom2="post"/></contact>',
    )
    cov = cover_model(paired)
    assert cov.spheres_of(_gid(paired, "t")).size == 1 and cov.nshape == 0


def test_pairs_against_terrain_are_shape_pairs_with_the_terrain_mode() -> None:
    m = _model('<geom name="t" type="hfield" hfield="h" margin=".01"/>')
    p = Predictor(m, accel=5.0)
    t = _gid(m, "t")
    assert (p.pair_set.kind == int(PairKind.SHAPE)).all() and len(p.pair_set) == 2
    assert (p.tables.geom2 == t).all()
    assert p.exact is not None
    assert (p.exact.records[:, X_MODE] == int(ExactMode.TERRAIN)).all()
    # eps: the covering sphere's radius and the pair's contact distance (margins summed).
    np.testing.assert_allclose(p.pair_set.eps, p.covering.sphere_radius[p.pair_set.first] + 0.01)
    # The records: the terrain's, its block after every record.
    assert p.shape_records[0, 0] == int(ShapeKind.HFIELD) and p.shape_records[0, TERRAIN_BLOCK] == 1


@pytest.mark.parametrize("exact", [False, True])
def test_the_step_equals_the_kernels_on_rough_terrain(exact: bool) -> None:
    """Along a random rollout of the bundled quadruped: every terrain pair's tau in the fused
    step is ``time_to_static`` on the same state (the sphere level), or, with the exact level,
    the larger of that and the terrain kernel on the pair's geom, assembled here from MjData
    (its support shape, ``mj_objectVelocity``, the spin term): equal up to the rounding of
    the two ways to the velocities."""
    m, d = load_scene("rough_terrain")
    p = Predictor(m, accel=60.0, schedule="select-all", urgency=UrgencyOptions(exact=exact))
    ps = p.pair_set
    ids = np.flatnonzero(ps.shape)
    assert ids.size == len(ps) == 13
    ctrl = make_controller(m, "random", seed=2, hold_steps=20)
    close = 0
    for k in predictor_rollout(m, d, p, ctrl, 80):
        if k == 0:
            continue
        c, v = p.sphere_states(d)
        shapes = static_shapes(m, p.covering.shape_geom, d)
        i = ps.first[ids]
        sphere = time_to_static(
            c[i], v[i], shapes, ps.second[ids], ps.eps[ids], ps.accel[ids],
            vel_uncertainty=ps.vel_uncertainty[ids],
        )  # fmt: skip
        want = sphere
        if exact:
            assert p.exact is not None
            want = np.array(
                [
                    max(sphere[n], _exact_reference(p, d, shapes, q))
                    if sphere[n] < p.exact.exact_below
                    else sphere[n]
                    for n, q in enumerate(ids)
                ]
            )
            assert (want >= sphere).all()
        np.testing.assert_allclose(p.scheduler.last_tau[ids], want, rtol=1e-12, atol=0)
        close += int(np.sum(sphere < 0.05))
    assert close > 50  # the feet: close to the ground, where the level matters


def _exact_reference(p: Predictor, d: mujoco.MjData, shapes: np.ndarray, pair: int) -> float:
    """The exact level's terrain tau of one pair, assembled from MjData."""
    assert p.exact is not None
    m = p.model
    g, terrain = int(p.exact.records[pair, X_G1]), int(p.exact.records[pair, X_G2])
    vel = np.empty(6)
    mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_GEOM, g, vel, 0)
    spin = float(np.linalg.norm(vel[:3])) * p.exact.geoms[g, GX_RADIUS]
    kind, size = int(m.geom_type[g]), m.geom_size[g]
    assert kind in (int(ShapeKind.CAPSULE), int(ShapeKind.SPHERE), int(ShapeKind.BOX))
    shape = np.ascontiguousarray(pack_shapes([kind], [size], [d.geom_xpos[g]], [d.geom_xmat[g]])[0])
    rec = p.pair_set  # the bounds of the pair
    row = int(np.flatnonzero(p.covering.shape_geom == terrain)[0])
    linear = np.ascontiguousarray(vel[3:])
    return float(
        _core.tau_terrain(
            np.ascontiguousarray(shapes), row, shape, linear, spin,
            p.exact.records[pair, X_DIST], rec.accel[pair], rec.vel_uncertainty[pair],
        )[0]
    )  # fmt: skip


def test_the_tables_hold_the_heights_and_reset_guards_the_pose() -> None:
    m, d = load_scene("rough_terrain")
    p = Predictor(m, accel=60.0)
    mujoco.mj_step(m, d)
    p.reset(d)
    block = p.shape_records[1:].reshape(-1)
    heights = block[int(block[T_HEIGHTS]) :][: m.hfield_data.size]
    np.testing.assert_array_equal(heights, m.hfield_data * m.hfield_size[0][2])
    # A terrain on a body welded to the world, moved: refused before and after mj_forward.
    m = _model('<body name="stand"><geom name="t" type="hfield" hfield="h"/></body>')
    assert_reset_refuses_a_moved_static_body(m, 1, "t")


def _standing(scene: str, seed: int, steps: int) -> tuple[float, int, int]:
    m, d = load_scene(scene)
    p = Predictor(m, pilot=PilotOptions(controller=make_controller(m, "random", seed=99)))
    r = run(m, d, p, steps=steps, controller=make_controller(m, "random", seed=seed),
            progress=False)  # fmt: skip
    return r.standing_alarm_fraction, r.missed_onsets_valid_bounds, r.contact_onsets


@pytest.mark.slow
def test_rough_terrain_misses_nothing_and_stands_near_the_plane() -> None:
    """Defaults (accel "auto", the exact level) on the bundled quadruped: no onset missed while
    the bounds held, and on the terrain at most 1.5 times the plane's share of pairs in alarm
    (the same robot, controls and seed)."""
    rough, missed, onsets = _standing("rough_terrain", 0, 1500)
    flat, missed_flat, _ = _standing("flat_terrain", 0, 1500)
    assert onsets > 50 and missed == 0 and missed_flat == 0
    assert rough <= 1.5 * flat, (rough, flat)
    box_m, box_d = load_scene("rough_terrain")
    box = Predictor(
        box_m,
        covering=CoveringOptions(hfield="box"),
        pilot=PilotOptions(controller=make_controller(box_m, "random", seed=99)),
    )
    r = run(box_m, box_d, box, steps=300, controller=make_controller(box_m, "random", seed=0),
            progress=False)  # fmt: skip
    assert r.standing_alarm_fraction > 2 * rough  # what the terrain replaces
    assert math.isfinite(rough)


@pytest.mark.parametrize("entry", [(1, 1e9), (1, 0.5), (2, 1e6), (20, 1e6)])
def test_the_plugin_refuses_a_terrain_table_that_does_not_fit(entry: tuple[int, float]) -> None:
    """A terrain record whose block lies beyond the table (or a header that does not fit its
    grid) in the model's tables: the plugin does not start (a warning names the table; MuJoCo
    prints it), rather than read out of bounds."""
    import base64

    from dua_mujoco import attach
    from dua_mujoco.models.scenes import load_spec
    from dua_mujoco.plugin import _encode

    spec = load_spec("rough_terrain")
    attach(spec, accel=30.0)
    text = next(t for t in spec.texts if t.name == "dua:shapes")
    table = np.frombuffer(base64.b64decode(text.data.split(" ", 1)[1]), dtype="<f8").copy()
    k, value = entry  # the record's block, its length; the block's nrow (16 + 3)
    table[k if k < 16 else k - 1] = value
    text.data = _encode(table)
    with pytest.raises(Exception, match="terrain record whose block does not fit"):
        mujoco.MjData(spec.compile())


def test_a_plan_on_rough_terrain_misses_nothing() -> None:
    """A terrain's pairs follow the plan, their planned gaps the terrain's own bound at rest
    (docs/theory.md, Lemma 9.5; StaticGap and mj_geomDistance are no lower bounds on a height
    field): exact plans of the run, limbs against the terrain, bounds above the scene's measured
    maximum; no onset is missed, none comes short of the horizon while held, no plan breaks."""
    from dua_mujoco.measure.monitor import Monitor

    m, d = load_scene("rough_terrain")
    h, every, steps = float(m.opt.timestep), 25, 500
    n = round(0.05 / h) + 2 * every
    lo, hi = m.actuator_ctrlrange[:, 0], m.actuator_ctrlrange[:, 1]
    held = np.random.default_rng(4).uniform(lo, hi, ((steps + n) // 20 + 1, m.nu))
    controls = np.repeat(held, 20, axis=0)  # random controls held 20 steps
    p = Predictor(m, accel=600.0, alarm_horizon=0.05)
    monitor = Monitor(p)
    mujoco.mj_step(m, d)
    monitor.start(d)
    plan_data = mujoco.MjData(m)
    for k in range(steps):
        if k % every == 0:
            mujoco.mj_copyData(plan_data, m, d)
            qpos = [plan_data.qpos.copy()]
            for j in range(n - 1):
                plan_data.ctrl[:] = controls[k + j]
                mujoco.mj_step(m, plan_data)
                qpos.append(plan_data.qpos.copy())
            p.set_plan(np.array(qpos), deviation=0.0)
        d.ctrl[:] = controls[k]
        mujoco.mj_step(m, d)
        monitor.observe(d, p.step(d))
    monitor.finish()
    assert p.plan_breaks == 0 and p.has_plan
    assert monitor.onsets >= 20 and monitor.misses == []
    assert monitor.warning.short_held == 0
