"""A plan's knots' kinematics (csrc/src/kinematics.h) against MuJoCo's own mj_kinematics.

``Plan::Build`` computes the poses of the geoms a plan reads, at every knot, with its own loop
over the bodies that carry them (MuJoCo's arithmetic, call for call), not ``mj_kinematics``. A
hinge's sine and cosine are the one exception: polynomials in lanes (``HalfAngleSinCos``) where
libmujoco calls ``sin`` and ``cos``, each within ``SIN_COS_ERROR`` of the exact value. So every
pose lies within the plan's tolerance (``KnotKinematics::tolerance``, added to every
deviation the plan declares) of ``mj_kinematics``', and the plan's check of a run that follows it
exactly (deviation 0) never breaks it. These hold:

- the sine and cosine to their bound, four at a time and one at a time alike;
- with every hinge exact (libmujoco's calls: a plan in a world past ``WORLD_REACH``), the
  knots to ``mj_kinematics`` bit for bit (the bytes of ``xpos``, ``xquat``, ``xmat``,
  ``geom_xpos`` and ``geom_xmat``, so also the sign of every zero);
- with the polynomials, every corner of every geom's box within the tolerance of where
  ``mj_kinematics`` puts it, and within three times it in every other geom's frame (a relative
  pair's measure), on every bundled scene, the plan robots and models with every joint type.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from benchmark_scripts import script
from rollouts import held_control_states

from dua_mujoco import _core
from dua_mujoco.models.scenes import SCENES, load_scene

# Every joint type, and the bodies mj_kinematics treats apart: a free body, a ball, a slide, a
# hinge at the body's origin and one off it (the anchor), several joints on one body (each
# kind, in both orders), a mocap body with a jointed child, bodies welded to the world and to a
# moving body, a body turned and offset from its parent without a joint, geoms at the body's
# inertial frame (a lone geom: its frame is the inertia's), turned as a rotated inertial frame
# but placed off it (INERTIAROT), and off it, geoms on the world body, a hinge at the origin of
# a body placed at x = -0 (where mj_kinematics' anchor, added and taken off, leaves +0; a geom at
# that body's frame reads it), and a hinge anchored at x = -0 (the anchor's full path).
JOINTS = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="3 3 .1"/>
    <geom name="post" type="box" size=".05 .05 .3" pos="1 1 .3" euler="0 0 20"/>
    <body name="ball_free" pos="0 0 1">
      <freejoint/>
      <geom type="sphere" size=".05" pos=".01 .02 0"/>
      <geom type="box" size=".04 .03 .02" euler="10 20 30" pos="0 .05 0"/>
    </body>
    <body name="lone" pos=".5 0 1" euler="0 30 0">
      <freejoint/>
      <geom type="capsule" fromto="0 0 0 .2 .1 0" size=".03"/>
    </body>
    <body name="base" pos="0 .5 .2" euler="5 0 10">
      <joint name="slide" type="slide" axis="1 0 0"/>
      <geom type="box" size=".1 .1 .05"/>
      <body name="upper" pos="0 0 .1">
        <joint name="shoulder" type="hinge" axis="0 1 0"/>
        <joint name="twist" type="hinge" axis="0 0 1" pos=".02 0 .01"/>
        <geom type="capsule" fromto="0 0 0 .3 0 0" size=".03"/>
        <body name="welded" pos=".3 0 0" euler="0 0 45">
          <geom type="box" size=".02 .02 .02" pos=".01 0 0"/>
          <body name="fore" pos=".05 0 0">
            <joint name="elbow" type="ball" pos=".01 .02 0"/>
            <geom type="capsule" fromto="0 0 0 .25 0 0" size=".025" euler="0 10 0"/>
            <body name="hand" pos=".25 0 0">
              <joint name="wrist_slide" type="slide" axis="0 1 1" pos=".1 0 0"/>
              <joint name="wrist_hinge" type="hinge" axis="1 0 0" pos="0 .03 0"/>
              <geom type="ellipsoid" size=".03 .02 .01"/>
            </body>
          </body>
        </body>
      </body>
    </body>
    <body name="turret" pos="-.5 -.5 .1">
      <joint type="hinge" axis="0 0 1" pos=".1 0 0"/>
      <joint type="slide" axis="0 0 1"/>
      <joint type="ball"/>
      <geom type="cylinder" size=".05 .05" pos="0 0 .05"/>
    </body>
    <body name="static" pos="-1 0 .2" euler="0 0 33">
      <geom type="box" size=".1 .2 .2"/>
      <body name="static_child" pos=".1 0 .3">
        <geom type="sphere" size=".05" pos="0 0 .01"/>
      </body>
    </body>
    <body name="person" mocap="true" pos="1 -1 1">
      <geom type="capsule" fromto="0 0 -.5 0 0 .3" size=".15"/>
      <body name="person_arm" pos=".2 0 .2">
        <joint type="hinge" axis="0 1 0" pos="0 0 .05"/>
        <geom type="capsule" fromto="0 0 0 .3 0 0" size=".04"/>
      </body>
    </body>
    <body name="signed" pos="-0 -1 .5">
      <joint type="hinge" axis="0 0 1"/>
      <geom type="box" size=".05 .02 .02" pos=".05 0 0"/>
      <geom type="sphere" size=".01" contype="0" conaffinity="0"/>
    </body>
    <body name="turned_inertia" pos="-.5 .5 .5" quat="1 .2 .3 .4">
      <joint type="ball"/>
      <inertial pos=".1 .2 .3" quat="1 2 3 4" mass="1" diaginertia="1 2 3"/>
      <geom type="box" size=".1 .2 .3" pos=".3 .2 .1" quat="1 2 3 4"/>
      <geom type="sphere" size=".1" pos=".1 .2 .3" quat="1 2 3 4"/>
    </body>
    <body name="signed_anchor" pos=".7 .7 .3">
      <joint name="signed_anchor" type="hinge" axis="0 1 0" pos="-0 0 0"/>
      <geom type="box" size=".05 .02 .02" pos=".05 0 0"/>
    </body>
    <body name="mount" pos="0 -1 .5" euler="0 0 15">
      <body name="mounted" euler="0 0 -15">
        <joint type="hinge" axis="0 0 1"/>
        <geom type="box" size=".1 .02 .02" pos=".1 0 0"/>
        <geom type="sphere" size=".01" pos=".3 .1 0" contype="0" conaffinity="0"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _draws(model: mujoco.MjModel, rng: np.random.Generator, n: int):
    """``n`` rows of qpos (joint positions far from qpos0, quaternions unnormalised) and mocap
    poses (unnormalised quaternions too), the first row qpos0 and the model's mocap poses."""
    d = mujoco.MjData(model)
    yield d.qpos.copy(), d.mocap_pos.copy(), d.mocap_quat.copy()
    for _ in range(n - 1):
        q = model.qpos0 + rng.normal(0.0, 2.0, model.nq)
        yield q, rng.normal(0.0, 1.0, (model.nmocap, 3)), rng.normal(0.0, 1.0, (model.nmocap, 4))


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64).view(np.uint64)


def _kept_bodies(model: mujoco.MjModel, geoms: np.ndarray) -> set[int]:
    """The bodies KnotKinematics computes for ``geoms``: theirs and their ancestors (no world)."""
    need = set()
    for g in geoms:
        b = int(model.geom_bodyid[g])
        while b:
            need.add(b)
            b = int(model.body_parentid[b])
    return need


def _same_as_mujoco(model: mujoco.MjModel, geoms: np.ndarray, rows: int = 12) -> None:
    """KnotKinematics on ``geoms`` with every hinge exact gives mj_kinematics' frames, bit for
    bit, for every body it computes and every geom, on ``rows`` draws; the bodies it computes
    are the geoms' bodies and their ancestors (no other)."""
    geoms = np.asarray(geoms, dtype=np.int64)
    need = _kept_bodies(model, geoms)
    d = mujoco.MjData(model)
    rng = np.random.default_rng(model.nbody * 1000 + model.ngeom)
    for qpos, mocap_pos, mocap_quat in _draws(model, rng, rows):
        d.qpos[:] = qpos
        d.mocap_pos[:] = mocap_pos
        d.mocap_quat[:] = mocap_quat
        mujoco.mj_kinematics(model, d)
        bodies, xpos, xquat, xmat, gpos, gmat = _core.knot_kinematics(
            model, geoms, d.qpos, d.mocap_pos.ravel(), d.mocap_quat.ravel(), exact=True
        )
        assert sorted(bodies.tolist()) == sorted(need)
        assert all(
            model.body_parentid[b] == 0 or model.body_parentid[b] in bodies[:i]
            for i, b in enumerate(bodies)
        )  # parents first
        for ours, theirs, what in (
            (xpos, d.xpos[bodies], "xpos"),
            (xquat, d.xquat[bodies], "xquat"),
            (xmat, d.xmat[bodies], "xmat"),
            (gpos, d.geom_xpos[geoms], "geom_xpos"),
            (gmat, d.geom_xmat[geoms], "geom_xmat"),
        ):
            assert np.array_equal(_bits(ours), _bits(theirs)), (what, np.abs(ours - theirs).max())


def _collision_geoms(model: mujoco.MjModel) -> np.ndarray:
    return np.flatnonzero((model.geom_contype | model.geom_conaffinity) != 0)


def test_exact_hinges_give_mujocos_poses_bit_for_bit_on_every_joint_type() -> None:
    model = mujoco.MjModel.from_xml_string(JOINTS)
    # The model holds what the docstring says: each joint type, a mocap body, static bodies,
    # geoms at their body's inertial frame and off it, anchors off the origin.
    assert set(model.jnt_type.tolist()) == {0, 1, 2, 3}
    assert model.nmocap == 1
    assert np.any(np.abs(model.jnt_pos).sum(1) > 0) and np.any(np.abs(model.jnt_pos).sum(1) == 0)
    assert mujoco.mjtSameFrame.mjSAMEFRAME_INERTIA in model.geom_sameframe
    assert mujoco.mjtSameFrame.mjSAMEFRAME_NONE in model.geom_sameframe
    assert np.any(model.body_jntnum > 1)
    assert np.signbit(model.body("signed").pos[0])
    assert mujoco.mjtSameFrame.mjSAMEFRAME_INERTIAROT in model.geom_sameframe
    assert np.signbit(model.joint("signed_anchor").pos[0])
    _same_as_mujoco(model, np.arange(model.ngeom), rows=40)
    # A plan's selection: the bodies between them (a mount without geoms) kept, others not.
    _same_as_mujoco(model, _collision_geoms(model), rows=10)
    hand = model.body("hand").id
    _same_as_mujoco(model, np.flatnonzero(model.geom_bodyid == hand), rows=10)


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_exact_hinges_give_mujocos_poses_bit_for_bit_on_every_bundled_scene(scene: str) -> None:
    model, _ = load_scene(scene)
    _same_as_mujoco(model, np.arange(model.ngeom))
    _same_as_mujoco(model, _collision_geoms(model))


def test_a_run_that_is_the_plan_never_breaks_it_at_deviation_0() -> None:
    # Through the runtime: a plan's geoms at each knot (set_plan's KnotKinematics, its hinges by
    # the polynomials) against a rollout's own geom poses (mj_step's mj_kinematics): within the
    # tolerance the plan adds to its deviations, so a run that is the plan never breaks it at
    # deviation 0 (the plan's check reads them at the step's knot).
    from dua_mujoco import Predictor

    model = mujoco.MjModel.from_xml_string(JOINTS)
    model.opt.gravity[:] = 0.0
    d = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    d.qvel[:] = rng.normal(0.0, 1.0, model.nv)
    mujoco.mj_forward(model, d)
    p = Predictor(model, accel=50.0, alarm_horizon=0.05)
    p.reset(d)
    p.set_plan(held_control_states(model, d, 60), deviation=0.0, start=d.time)
    for _ in range(60):
        mujoco.mj_step(model, d)
        p.step(d)
    assert p.has_plan and p.plan_breaks == 0
    assert p.plan_tolerance > 0.0  # (its hinges by the polynomials: the case in question)


def test_a_query_that_copies_the_plans_knots_declares_the_plans_tolerance() -> None:
    # A candidate (plan_contact_knots) copies the knots it shares with the plan followed, poses
    # and all. With sleep on, the candidate's own knots are mj_kinematics' (no KnotKinematics,
    # tolerance 0 of its own), while the copied ones came from the polynomials: it must declare
    # the followed plan's tolerance, or its verdicts would read poses up to that far off against
    # deviations not widened for them.
    from dua_mujoco import Predictor, plan_from_controls

    model = mujoco.MjModel.from_xml_string(JOINTS)
    model.opt.gravity[:] = 0.0
    d = mujoco.MjData(model)
    d.qvel[:] = np.random.default_rng(5).normal(0.0, 1.0, model.nv)
    mujoco.mj_forward(model, d)
    p = Predictor(model, accel=50.0, alarm_horizon=0.05)
    p.reset(d)
    start = d.time
    rows = plan_from_controls(model, d, np.zeros((30, model.nu)))
    p.set_plan(rows, deviation=0.0, start=start)
    mujoco.mj_step(model, d)  # the state the query starts from: the plan's first knot
    p.step(d)
    pairs = np.array([[0, g] for g in range(1, model.ngeom)])
    without_sleep = p.plan_contact_knots(rows, pairs, deviation=0.0, start=start)
    assert p._rt.plan_query_tolerance == p.plan_tolerance > 0.0
    model.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    with_sleep = p.plan_contact_knots(rows, pairs, deviation=0.0, start=start)
    assert p._rt.plan_query_tolerance == p.plan_tolerance
    np.testing.assert_array_equal(with_sleep, without_sleep)


# set_plan's path: KnotKinematics::RunKnots computes four knots at once in AVX2 lanes (the last
# two or three together, a lone last one alone) and holds its first batch to the one-knot path
# byte for byte, falling back to it for good on a difference. The rows below hold the lanes to
# that path and to mj_kinematics, and hold the lanes *on*: a lane off by a bit would otherwise
# pass unseen (the self-check turns lanes off and the one-knot path gives the right poses).


def _rows(model: mujoco.MjModel, n: int, seed: int) -> tuple[np.ndarray, ...]:
    """``n`` rows of qpos and mocap poses far from qpos0, quaternions unnormalised, with the
    values mj_kinematics branches on among them: qpos0 (hinge angles 0), a ball's and a free
    joint's quaternion at zero (normalised to the unit), at the unit and at norm 1 exactly, a
    mocap orientation at the unit (its rotation matrix the identity)."""
    rng = np.random.default_rng(seed)
    q = model.qpos0 + rng.normal(0.0, 2.0, (n, model.nq))
    mp = rng.normal(0.0, 1.0, (n, model.nmocap, 3))
    mq = rng.normal(0.0, 1.0, (n, model.nmocap, 4))
    q[0] = model.qpos0
    free, ball = int(mujoco.mjtJoint.mjJNT_FREE), int(mujoco.mjtJoint.mjJNT_BALL)
    types = model.jnt_type.astype(int)
    quats = [
        int(model.jnt_qposadr[j]) + (3 if types[j] == free else 0)
        for j in range(model.njnt)
        if types[j] in (free, ball)
    ]
    assert len(quats) == np.sum((types == free) | (types == ball))
    for j, a in enumerate(quats):
        if n > 1:
            q[1, a : a + 4] = 0.0 if j % 2 == 0 else (1.0, 0.0, 0.0, 0.0)
        if n > 2:
            q[2, a : a + 4] = (0.0, 0.6, 0.0, 0.8)  # norm 1 exactly: not scaled
    if n > 1 and model.nmocap:
        mq[1] = (1.0, 0.0, 0.0, 0.0)
    return q, mp, mq


def _corners(model: mujoco.MjModel, geoms: np.ndarray) -> np.ndarray:
    """(ngeom, 9, 3): each geom's origin and the eight corners of its box (``geom_aabb``), in
    its own frame: the points Lemma 8.1's measure reads."""
    aabb = model.geom_aabb[geoms]
    corners = [[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    signs = np.array([[0.0, 0.0, 0.0], *corners])
    out = aabb[:, None, :3] + signs[None] * aabb[:, None, 3:]
    out[:, 0] = 0.0
    return out


def _from_mujoco(
    model: mujoco.MjModel, geoms: np.ndarray, pos: np.ndarray, mat: np.ndarray, d: mujoco.MjData
) -> tuple[float, float]:
    """How far the knot's geom boxes lie from mj_kinematics' on ``d``: the largest displacement
    of a corner in the world, and in another moving geom's frame (a relative pair's measure: of
    the moving geoms' boxes, a plane's or a height field's being unbounded)."""
    q = _corners(model, geoms)
    r, r0 = mat.reshape(-1, 3, 3), d.geom_xmat[geoms].reshape(-1, 3, 3)
    p, p0 = pos, d.geom_xpos[geoms]
    world = p[:, None] + np.einsum("gij,gkj->gki", r, q)
    world0 = p0[:, None] + np.einsum("gij,gkj->gki", r0, q)
    absolute = float(np.linalg.norm(world - world0, axis=-1).max())
    # Geom a's corners in geom b's frame, every (a, b) of moving bounded geoms.
    unbounded = (int(mujoco.mjtGeom.mjGEOM_PLANE), int(mujoco.mjtGeom.mjGEOM_HFIELD))
    moving = model.body_weldid[model.geom_bodyid[geoms]] != 0
    keep = moving & ~np.isin(model.geom_type[geoms], unbounded)
    if not keep.any():
        return absolute, 0.0
    r, r0, p, p0 = r[keep], r0[keep], p[keep], p0[keep]
    world, world0 = world[keep], world0[keep]
    rel = np.einsum("bji,abkj->abki", r, world[:, None] - p[None, :, None])
    rel0 = np.einsum("bji,abkj->abki", r0, world0[:, None] - p0[None, :, None])
    relative = float(np.linalg.norm(rel - rel0, axis=-1).max())
    return absolute, relative


def _lanes_same_as_mujoco(model: mujoco.MjModel, geoms: np.ndarray, n: int, seed: int = 0) -> None:
    """knot_kinematics_rows with lanes on: lanes stay on (the self-check passed), every knot's
    poses are those with lanes off, bit for bit; with every hinge exact they are
    mj_kinematics', bit for bit, and with the polynomials within the tolerance of them (three
    times it in another geom's frame), the tolerance 0 exactly when no kept body has a hinge."""
    geoms = np.asarray(geoms, dtype=np.int64)
    q, mp, mq = _rows(model, n, seed)
    pos, mat, lanes, tol = _core.knot_kinematics_rows(model, geoms, q, mp, mq, lanes=True)
    pos1, mat1, lanes1, tol1 = _core.knot_kinematics_rows(model, geoms, q, mp, mq, lanes=False)
    exact = _core.knot_kinematics_rows(model, geoms, q, mp, mq, exact=True)
    assert lanes and not lanes1 and exact[2] and exact[3] == tol == tol1
    assert pos.shape == (n, len(geoms), 3) and mat.shape == (n, len(geoms), 9)
    assert np.array_equal(_bits(pos), _bits(pos1)) and np.array_equal(_bits(mat), _bits(mat1))
    hinged = _kept_hinge(model, geoms)
    assert (tol > 0.0) == hinged
    d = mujoco.MjData(model)
    for j in range(n):
        d.qpos[:] = q[j]
        d.mocap_pos[:] = mp[j]
        d.mocap_quat[:] = mq[j]
        mujoco.mj_kinematics(model, d)
        assert np.array_equal(_bits(exact[0][j]), _bits(d.geom_xpos[geoms])), ("geom_xpos", j)
        assert np.array_equal(_bits(exact[1][j]), _bits(d.geom_xmat[geoms])), ("geom_xmat", j)
        if not hinged:
            assert np.array_equal(_bits(pos[j]), _bits(d.geom_xpos[geoms])), ("geom_xpos", j)
            assert np.array_equal(_bits(mat[j]), _bits(d.geom_xmat[geoms])), ("geom_xmat", j)
            continue
        absolute, relative = _from_mujoco(model, geoms, pos[j], mat[j], d)
        assert absolute <= tol and relative <= 3.0 * tol, (j, absolute, relative, tol)


def _kept_hinge(model: mujoco.MjModel, geoms: np.ndarray) -> bool:
    """Whether a hinge moves a body that carries one of ``geoms`` or is an ancestor of one."""
    hinge, kept = int(mujoco.mjtJoint.mjJNT_HINGE), _kept_bodies(model, geoms)
    return any(
        int(model.jnt_type[j]) == hinge and int(model.jnt_bodyid[j]) in kept
        for j in range(model.njnt)
    )


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 6, 7, 9])
def test_lanes_give_mujocos_poses_within_the_tolerance_on_every_joint_type(n: int) -> None:
    # 1 knot: the one-knot path alone; 2, 3: one batch of lanes with lanes past the knots idle;
    # 5: a batch and a lone knot after it; 6, 7: a batch and a partial one.
    model = mujoco.MjModel.from_xml_string(JOINTS)
    for seed in range(3):
        _lanes_same_as_mujoco(model, np.arange(model.ngeom), n, seed)
        _lanes_same_as_mujoco(model, _collision_geoms(model), n, seed)


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_lanes_give_mujocos_poses_within_the_tolerance_on_every_bundled_scene(scene: str) -> None:
    model, _ = load_scene(scene)
    _lanes_same_as_mujoco(model, np.arange(model.ngeom), 7)
    _lanes_same_as_mujoco(model, _collision_geoms(model), 5)


ROBOTS = ["xarm7", "baxter", "tiago", "sawyer", "spot_arm", "gr1", "g1"]


@pytest.mark.parametrize("robot", ROBOTS)
def test_lanes_give_mujocos_poses_within_the_tolerance_on_the_plan_robots(robot: str) -> None:
    # benchmarks/plan_profile.py's robots (benchmarks/robots.py; skipped without their wheels).
    try:
        model = script("robots").load_robot(robot)
    except (ImportError, FileNotFoundError) as e:
        pytest.skip(f"{robot}: {e}")
    _lanes_same_as_mujoco(model, np.arange(model.ngeom), 9)
    _lanes_same_as_mujoco(model, _collision_geoms(model), 6)


CHAIN = """
<mujoco>
  <worldbody>
    <body name="b0">
      <joint type="hinge" axis="0 0 1"/>
      <geom type="capsule" fromto="0 0 0 .2 0 0" size=".02"/>
      <body name="b1" pos=".2 0 0">
        <joint type="hinge" axis="0 1 0" pos=".01 0 0"/>
        <geom type="capsule" fromto="0 0 0 .2 0 0" size=".02"/>
        <body name="b2" pos=".2 0 0">
          <joint type="hinge" axis="1 1 0"/>
          <joint type="hinge" axis=".3 -.2 .9"/>
          <geom type="box" size=".05 .02 .01" pos=".05 0 0"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_knots_stand_to_mujocos_poses_at_hinge_angles_of_every_scale() -> None:
    # A hinge's rotation in lanes over 2,000 knots of angles from 1e-300 to 1e6 radians, either
    # sign, -0 and +0 (mju_axisAngle2Quat's test of 0), half-angles at the polynomials' edge
    # (HALF_ANGLE_MAX, past which libmujoco's calls take over) and beside glibc's own branches
    # (2^-26, 0.85546875): with every hinge exact, mj_kinematics' bit for bit; with the
    # polynomials, within the tolerance.
    model = mujoco.MjModel.from_xml_string(CHAIN)
    rng = np.random.default_rng(7)
    n = 2000
    scales = 10.0 ** rng.integers(-300, 7, (n, model.nq))
    q = model.qpos0 + scales * rng.uniform(-1.0, 1.0, (n, model.nq))
    q[: model.nq, :] = np.where(np.eye(model.nq, dtype=bool), -0.0, q[: model.nq, :])
    q[model.nq, :] = 0.0
    edges = np.array([2.0**-26, 0.85546875, _core.HALF_ANGLE_MAX])
    angles = 2.0 * np.concatenate(
        [edges, np.nextafter(edges, 0.0), np.nextafter(edges, 100.0), [np.pi / 2, np.pi]]
    )
    angles = np.concatenate([angles, -angles])
    q[model.nq + 1 : model.nq + 1 + angles.size, :] = angles[:, None]
    mp, mq = np.zeros((n, 0, 3)), np.zeros((n, 0, 4))
    geoms = np.arange(model.ngeom, dtype=np.int64)
    exact = _core.knot_kinematics_rows(model, geoms, q, mp, mq, exact=True)
    pos, mat, lanes, tol = _core.knot_kinematics_rows(model, geoms, q, mp, mq)
    assert lanes and exact[2] and tol > 0.0
    d = mujoco.MjData(model)
    for j in range(n):
        d.qpos[:] = q[j]
        mujoco.mj_kinematics(model, d)
        assert np.array_equal(_bits(exact[0][j]), _bits(d.geom_xpos)), ("geom_xpos", j, q[j])
        assert np.array_equal(_bits(exact[1][j]), _bits(d.geom_xmat)), ("geom_xmat", j, q[j])
        absolute, relative = _from_mujoco(model, geoms, pos[j], mat[j], d)
        assert absolute <= tol and relative <= 3.0 * tol, (j, q[j], absolute, relative, tol)
        if np.all(q[j] == 0.0) or np.all(np.abs(q[j]) > 2.0 * _core.HALF_ANGLE_MAX):
            # No hinge by the polynomials: mj_kinematics' bits (its zero angle's +0 included).
            assert np.array_equal(_bits(pos[j]), _bits(d.geom_xpos)), ("geom_xpos", j, q[j])
            assert np.array_equal(_bits(mat[j]), _bits(d.geom_xmat)), ("geom_xmat", j, q[j])


def test_the_hinges_sine_and_cosine_stay_within_their_bound() -> None:
    # HalfAngleSinCos against glibc's sin and cos (within half an ulp of 1 of the exact values,
    # 2^-53): each within SIN_COS_ERROR + 2^-53 of them on |x| <= HALF_ANGLE_MAX, at random, at
    # and beside every multiple of pi/4 (the reduction's quadrant edges and their middles), at
    # the range's ends and at tiny and zero arguments; the lanes and the one-at-a-time path the
    # same bits.
    rng = np.random.default_rng(11)
    edges = np.arange(-81, 82) * (np.pi / 4)
    edges = edges[np.abs(edges) <= _core.HALF_ANGLE_MAX]
    x = np.concatenate(
        [
            rng.uniform(-_core.HALF_ANGLE_MAX, _core.HALF_ANGLE_MAX, 200_000),
            rng.uniform(-1.0, 1.0, 50_000) * 10.0 ** rng.integers(-300, 0, 50_000),
            edges,
            np.nextafter(edges, -np.inf),
            np.nextafter(edges, np.inf),
            [0.0, -0.0, 5e-324, -5e-324, _core.HALF_ANGLE_MAX, -_core.HALF_ANGLE_MAX],
        ]
    )
    x = np.concatenate([x, x[: (-x.size) % 4 + 3]])  # a tail the lanes leave to the scalar path
    sn, cs = _core.half_angle_sincos(x)
    sn1, cs1 = _core.half_angle_sincos(x, lanes=False)
    assert np.array_equal(_bits(sn), _bits(sn1)) and np.array_equal(_bits(cs), _bits(cs1))
    bound = _core.SIN_COS_ERROR + 2.0**-53
    assert np.abs(sn - np.sin(x)).max() <= bound
    assert np.abs(cs - np.cos(x)).max() <= bound
    assert np.all(sn[x == 0.0] == 0.0) and np.all(cs[x == 0.0] == 1.0)  # (-0's sine is +0)
    with pytest.raises(ValueError, match="HALF_ANGLE_MAX"):
        _core.half_angle_sincos(np.array([np.nextafter(_core.HALF_ANGLE_MAX, 100.0)]))


_RAIL = """
<mujoco><worldbody><geom name="post" type="box" size=".1 .1 .1" pos="0 2 0"/>
<body name="cart"><joint name="rail" type="slide" axis="1 0 0"/>
  <geom type="box" size=".1 .1 .1"/>
  <body name="arm" pos="0 0 .2"><joint type="hinge" axis="0 1 0"/>
    <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02"/></body>
</body></worldbody></mujoco>"""


def test_a_plan_past_the_worlds_reach_takes_every_hinge_exactly() -> None:
    # A slide carrying a hinged arm, driven past WORLD_REACH at one knot: the bound's allowance
    # for the world's lengths is spent, so every hinge of those knots is libmujoco's
    # (mj_kinematics' poses bit for bit); within reach the polynomials. The tolerance is the
    # model's either way (a plan's deviations are widened alike, so replans nest).
    model = mujoco.MjModel.from_xml_string(_RAIL)
    geoms = np.arange(model.ngeom, dtype=np.int64)
    q = np.tile([10.0, 0.7], (6, 1))
    none3, none4 = np.zeros((6, 0, 3)), np.zeros((6, 0, 4))
    near = _core.knot_kinematics_rows(model, geoms, q, none3, none4)
    q[4, 0] = _core.WORLD_REACH + 1.0
    pos, mat, lanes, tol = _core.knot_kinematics_rows(model, geoms, q, none3, none4)
    assert lanes and tol == near[3] > 0.0
    d = mujoco.MjData(model)
    for j in range(len(q)):
        d.qpos[:] = q[j]
        mujoco.mj_kinematics(model, d)
        assert np.array_equal(_bits(pos[j]), _bits(d.geom_xpos)), j
        assert np.array_equal(_bits(mat[j]), _bits(d.geom_xmat)), j


def test_plans_near_and_past_the_worlds_reach_follow_a_run_that_is_them() -> None:
    # Through the runtime: the cart sliding past WORLD_REACH while the arm swings, planned
    # exactly (deviation 0) every 20 steps, the plans before it within reach (polynomial hinges)
    # and after it past (exact ones), each replan copying the knots it shares with the plan it
    # replaces: no break, and every plan declares the model's tolerance.
    from dua_mujoco import Predictor, plan_from_controls

    model = mujoco.MjModel.from_xml_string(_RAIL)
    model.opt.gravity[:] = 0.0
    d = mujoco.MjData(model)
    d.qpos[0] = _core.WORLD_REACH - 0.5
    d.qvel[:] = [10.0, 3.0]
    mujoco.mj_forward(model, d)
    p = Predictor(model, accel=50.0, alarm_horizon=0.05)
    p.reset(d)
    tolerances = []
    for k in range(200):
        if k % 20 == 0:
            rows = plan_from_controls(model, d, np.zeros((60, model.nu)))
            p.set_plan(rows, deviation=0.0, start=d.time)
            tolerances.append(p.plan_tolerance)
        mujoco.mj_step(model, d)
        p.step(d)
    assert d.qpos[0] > _core.WORLD_REACH + 1.0  # (the later plans past the reach)
    assert p.plan_breaks == 0
    assert len(set(tolerances)) == 1 and tolerances[0] > 0.0


@pytest.mark.parametrize("n", [2, 5, 8])
def test_a_lane_off_by_a_bit_turns_lanes_off_and_the_poses_stay_mujocos(n: int) -> None:
    # The self-check: a flipped bit in the lanes' first pose (the test hook) is caught on the
    # first batch, lanes go off, and every knot (that batch's too) is the one-knot path's.
    model = mujoco.MjModel.from_xml_string(JOINTS)
    geoms = np.arange(model.ngeom, dtype=np.int64)
    q, mp, mq = _rows(model, n, 1)
    pos, mat, lanes, _ = _core.knot_kinematics_rows(model, geoms, q, mp, mq, fault=True)
    pos1, mat1, _, _ = _core.knot_kinematics_rows(model, geoms, q, mp, mq, lanes=False)
    assert not lanes
    assert np.array_equal(_bits(pos), _bits(pos1)) and np.array_equal(_bits(mat), _bits(mat1))
