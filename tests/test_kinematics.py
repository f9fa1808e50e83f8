"""dua_mujoco.build.kinematics: sphere centres and velocities against MuJoCo's own functions."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from random_states import random_joint_state

from dua_mujoco.build.kinematics import mjdata_frame, pack_spheres, sphere_states
from dua_mujoco.build.mocap import MocapVelocityTracker
from dua_mujoco.exceptions import InvalidChoiceError, ShapeError


def states(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    sg: np.ndarray,
    sb: np.ndarray,
    so: np.ndarray,
    ids: np.ndarray | None = None,
    tracker: MocapVelocityTracker | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Sphere states through the kinematics kernel, as the predictor reads them."""
    twist = np.zeros((m.nbody, 6)) if tracker is None else tracker.twist
    return sphere_states(pack_spheres(sg, sb, so, m.body_rootid), mjdata_frame(d, twist), ids)


# One body per joint type; geoms deliberately off the body frame and rotated, so that geom frame,
# body frame, COM and subtree COM all differ.
JOINTS = {
    "free": "<freejoint/>",
    "ball": '<joint type="ball" pos=".05 0 .02"/>',
    "hinge": '<joint type="hinge" axis="0.3 1 0.2" pos="-.1 0 0"/>',
    "slide": '<joint type="slide" axis="1 0.5 -0.2"/>',
}

OFFSETS = np.array([[0.0, 0.0, 0.0], [0.07, -0.03, 0.05], [-0.1, 0.02, 0.0]])


def _geoms(prefix: str) -> str:
    return (
        f'<geom name="{prefix}box" type="box" size=".1 .05 .08" pos=".1 .02 0" euler="10 20 30"/>'
        f'<geom name="{prefix}cap" type="capsule" size=".03" fromto="0 0 0 .2 .1 0"/>'
    )


def _xml(joint: str, nested: bool, sites: str = "", sites2: str = "") -> str:
    inner = ""
    if nested:
        inner = (
            f'<body name="c" pos=".3 .1 -.05" euler="0 30 0">{JOINTS["hinge"]}'
            f'{_geoms("c")}{sites2}<body name="g" pos=".2 0 0">{JOINTS["ball"]}{_geoms("g")}'
            "</body></body>"
        )
    return (
        '<mujoco><option gravity="0 0 -9.81"/><worldbody>'
        '<geom name="floor" type="plane" size="2 2 .1"/>'
        f'<body name="b" pos=".1 .2 1" euler="5 -10 15">'
        f'<inertial pos=".04 .01 -.02" mass="1.3" diaginertia=".01 .02 .03"/>'
        f"{JOINTS[joint]}{_geoms('b')}{sites}{inner}</body></worldbody></mujoco>"
    )


def _model_with_sites(joint: str, nested: bool) -> mujoco.MjModel:
    """Model whose site s{g}_{i} sits exactly at sphere centre (geom g, OFFSETS[i])."""
    m0 = mujoco.MjModel.from_xml_string(_xml(joint, nested))
    per_body: dict[int, str] = {}
    for g in range(m0.ngeom):
        b = int(m0.geom_bodyid[g])
        if b == 0:
            continue
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, m0.geom_quat[g])
        for i, off in enumerate(OFFSETS):
            p = m0.geom_pos[g] + R.reshape(3, 3) @ off
            per_body[b] = per_body.get(b, "") + (
                f'<site name="s{g}_{i}" pos="{p[0]:.17g} {p[1]:.17g} {p[2]:.17g}"/>'
            )
    xml = _xml(joint, nested, per_body.get(1, ""), per_body.get(2, ""))
    if nested:
        # The grandchild's sites go into its body tag.
        xml = xml.replace(
            f'<body name="g" pos=".2 0 0">{JOINTS["ball"]}',
            f'<body name="g" pos=".2 0 0">{JOINTS["ball"]}{per_body.get(3, "")}',
        )
    return mujoco.MjModel.from_xml_string(xml)


def _random_state(m: mujoco.MjModel, d: mujoco.MjData, rng: np.random.Generator) -> None:
    mujoco.mj_resetData(m, d)
    random_joint_state(m, d, rng, velocity_scale=3.0)
    mujoco.mj_forward(m, d)


def _spheres(m: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] != 0]
    sg = np.repeat(geoms, len(OFFSETS))
    so = np.tile(OFFSETS, (len(geoms), 1))
    return sg, np.asarray(m.geom_bodyid)[sg], so


def test_centers_zero_offset_match_geom_xpos() -> None:
    m = _model_with_sites("free", nested=True)
    d = mujoco.MjData(m)
    _random_state(m, d, np.random.default_rng(1))
    g = np.arange(m.ngeom)
    c, _ = states(m, d, g, np.asarray(m.geom_bodyid), np.zeros((m.ngeom, 3)))
    np.testing.assert_array_equal(c, d.geom_xpos)


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    n=st.integers(1, 20),
)
def test_centers_match_slow_loop(seed: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    ngeom = 7
    xpos = rng.normal(size=(ngeom, 3))
    xmat = np.array([np.linalg.qr(rng.normal(size=(3, 3)))[0].ravel() for _ in range(ngeom)])
    sg = rng.integers(0, ngeom, size=n)
    so = rng.normal(size=(n, 3))
    ids = rng.permutation(n)[: max(1, n // 2)]
    at_rest = (np.zeros((1, 6)), np.zeros((1, 3)), np.zeros((1, 6)), np.zeros((1, 3)))
    c, v = sphere_states(pack_spheres(sg, np.zeros(n, int), so, [0]), (xpos, xmat, *at_rest), ids)
    np.testing.assert_array_equal(v, 0.0)
    ref = np.array([xpos[sg[i]] + xmat[sg[i]].reshape(3, 3) @ so[i] for i in ids])
    np.testing.assert_allclose(c, ref, rtol=0, atol=1e-14)


@pytest.mark.parametrize("nested", [False, True], ids=["single", "chain"])
@pytest.mark.parametrize("joint", list(JOINTS))
def test_centers_and_velocities_match_mujoco(joint: str, nested: bool) -> None:
    m = _model_with_sites(joint, nested)
    d = mujoco.MjData(m)
    sg, sb, so = _spheres(m)
    rng = np.random.default_rng(hash((joint, nested)) % 2**32)
    res = np.zeros(6)
    for _ in range(5):
        _random_state(m, d, rng)
        c, v = states(m, d, sg, sb, so)
        for i in range(sg.size):
            g, k = int(sg[i]), i % len(OFFSETS)
            sid = mujoco.mj_name2id(m, int(mujoco.mjtObj.mjOBJ_SITE), f"s{g}_{k}")
            np.testing.assert_allclose(c[i], d.site_xpos[sid], atol=1e-12)
            mujoco.mj_objectVelocity(m, d, int(mujoco.mjtObj.mjOBJ_SITE), sid, res, 0)
            np.testing.assert_allclose(v[i], res[3:], atol=1e-10)
            if k == 0:  # zero offset: the geom frame itself
                mujoco.mj_objectVelocity(m, d, int(mujoco.mjtObj.mjOBJ_GEOM), g, res, 0)
                np.testing.assert_allclose(v[i], res[3:], atol=1e-10)


def test_ids_subset_and_order() -> None:
    m = _model_with_sites("hinge", nested=True)
    d = mujoco.MjData(m)
    _random_state(m, d, np.random.default_rng(3))
    sg, sb, so = _spheres(m)
    full = states(m, d, sg, sb, so)
    ids = np.array([5, 0, 9, 2])
    sub = states(m, d, sg, sb, so, ids)
    np.testing.assert_array_equal(sub[0], full[0][ids])
    np.testing.assert_array_equal(sub[1], full[1][ids])


def test_shape_and_id_errors() -> None:
    with pytest.raises(ShapeError, match=r"sphere_offset has shape \(3, 3\)"):
        pack_spheres([0, 1], [0, 0], np.zeros((3, 3)), [0])
    with pytest.raises(ShapeError, match=r"sphere_body has shape \(1,\)"):
        pack_spheres([0, 1], [0], np.zeros((2, 3)), [0])
    rest = (np.zeros((2, 3)), np.zeros((2, 9)), np.zeros((1, 6)), np.zeros((1, 3)))
    frame = (*rest, np.zeros((1, 6)), np.zeros((1, 3)))
    spheres = pack_spheres([0, 1], [0, 0], np.zeros((2, 3)), [0])
    with pytest.raises(
        ShapeError,
        match=r"sphere id 2 \(ids\[0\]\) is out of range: the records "
        r"hold 2 spheres \(valid ids 0\.\.1\)",
    ):
        sphere_states(spheres, frame, [2])
    with pytest.raises(ShapeError, match="frame 2"):
        sphere_states(pack_spheres([0, 2], [0, 0], np.zeros((2, 3)), [0]), frame)


@pytest.mark.parametrize("integrator", ["Euler", "implicitfast", "implicit"])
def test_after_step_kinematics_describe_start_of_step(integrator: str) -> None:
    """geom_xpos and cvel after mj_step are those of the pre-step qpos/qvel."""
    m = _model_with_sites("free", nested=True)
    m.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")
    d = mujoco.MjData(m)
    _random_state(m, d, np.random.default_rng(4))
    ref = mujoco.MjData(m)
    ref.qpos[:], ref.qvel[:] = d.qpos, d.qvel
    mujoco.mj_step(m, d)
    mujoco.mj_forward(m, ref)
    np.testing.assert_array_equal(d.geom_xpos, ref.geom_xpos)
    np.testing.assert_array_equal(d.cvel, ref.cvel)
    assert not np.array_equal(d.qpos, ref.qpos)


def test_after_step_rk4_kinematics_are_last_stage() -> None:
    """With RK4, MjData keeps the last stage's kinematics: near the end of the step, not start."""
    m = _model_with_sites("hinge", nested=True)
    m.opt.integrator = int(mujoco.mjtIntegrator.mjINT_RK4)
    d = mujoco.MjData(m)
    _random_state(m, d, np.random.default_rng(5))
    start = d.geom_xpos.copy()
    mujoco.mj_step(m, d)
    end = mujoco.MjData(m)
    end.qpos[:], end.qvel[:] = d.qpos, d.qvel
    mujoco.mj_forward(m, end)
    assert np.abs(d.geom_xpos - end.geom_xpos).max() < 1e-6
    assert np.abs(d.geom_xpos - start).max() > 1e-4


MOCAP_XML = """<mujoco><option gravity="0 0 0" timestep="0.002"/><worldbody>
<body name="m" mocap="true" pos="0 0 1"><geom name="mg" type="box" size=".1 .1 .1" pos=".1 0 0"/>
  <body name="arm" pos=".2 0 0"><joint type="hinge" axis="0 0 1"/>
    <geom name="ag" type="capsule" fromto="0 0 0 .3 0 0" size=".02"/></body></body>
<body name="n" mocap="true"><geom name="ng" type="sphere" size=".05"/></body>
</worldbody></mujoco>"""


def _script(t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pose and true velocity of the scripted mocap body 'm' at time t."""
    pos = np.array([0.3 * np.sin(2 * t), 0.2 * np.cos(3 * t), 1 + 0.1 * t**2])
    vel = np.array([0.6 * np.cos(2 * t), -0.6 * np.sin(3 * t), 0.2 * t])
    ang = 1.5 * t + 0.4 * np.sin(t)  # rotation about a fixed axis
    rate = 1.5 + 0.4 * np.cos(t)
    axis = np.array([0.2, -0.3, 1.0]) / np.linalg.norm([0.2, -0.3, 1.0])
    quat = np.concatenate([[np.cos(ang / 2)], np.sin(ang / 2) * axis])
    return pos, vel, quat, rate * axis


def test_mocap_tracker_matches_scripted_velocity() -> None:
    m = mujoco.MjModel.from_xml_string(MOCAP_XML)
    d = mujoco.MjData(m)
    d.qvel[0] = 1.3
    tracker = MocapVelocityTracker(m)
    sg = np.arange(m.ngeom)
    sb = np.asarray(m.geom_bodyid)
    so = np.zeros((m.ngeom, 3))
    so[1] = [0.15, 0, 0]  # a point along the arm, not at its frame origin
    h = m.opt.timestep
    prev_c = None
    for k in range(400):
        pos, _, quat, _ = _script(d.time)
        d.mocap_pos[0], d.mocap_quat[0] = pos, quat
        mujoco.mj_step(m, d)
        tracker.update(d)
        # After the step the kinematics are those of time d.time - h.
        t_kin = d.time - h
        if k < 2:
            continue
        _, vel, _, omega = _script(t_kin)
        centers, velocities = states(m, d, sg, sb, so, tracker=tracker)
        # Backward difference vs the true velocity: error <= |accel| h / 2 (+ rotation terms).
        np.testing.assert_allclose(tracker.linear[0], vel, atol=2e-3)
        np.testing.assert_allclose(tracker.angular[0], omega, atol=2e-3)
        # The mocap-driven sphere velocity is exactly the backward discrete velocity of the
        # centre up to the chord/tangent difference of the rotation (O(h |omega|^2 r)).
        if prev_c is not None:
            u = (centers - prev_c) / h
            for i in (0, 1):
                np.testing.assert_allclose(velocities[i], u[i], atol=2e-2)
        prev_c = centers
    # The unmoved mocap body 'n' reads zero.
    np.testing.assert_array_equal(tracker.linear[1], 0.0)


def test_mocap_user_velocity_and_errors() -> None:
    m = mujoco.MjModel.from_xml_string(MOCAP_XML)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    tracker = MocapVelocityTracker(m)
    tracker.set_velocity("n", [1.0, 2.0, 3.0])
    tracker.update(d)
    d.mocap_pos[1] = [5, 5, 5]
    mujoco.mj_step(m, d)
    tracker.update(d)
    np.testing.assert_array_equal(tracker.linear[1], [1.0, 2.0, 3.0])
    ng = mujoco.mj_name2id(m, int(mujoco.mjtObj.mjOBJ_GEOM), "ng")
    _, v = states(m, d, np.array([ng]), m.geom_bodyid[[ng]], np.zeros((1, 3)), tracker=tracker)
    np.testing.assert_array_equal(v[0], [1.0, 2.0, 3.0])
    tracker.clear_velocity("n")
    d.mocap_pos[1] = [5, 5, 5.01]
    mujoco.mj_step(m, d)
    tracker.update(d)
    np.testing.assert_allclose(tracker.linear[1], [0, 0, 0.01 / m.opt.timestep])
    with pytest.raises(InvalidChoiceError, match="'m'"):
        tracker.set_velocity("arm", [0, 0, 0])


def test_the_tracker_and_the_predictors_runtime_share_one_differencing() -> None:
    """One native state (``csrc/src/mocap.h``) serves the predictor's runtime and the trackers: a
    tracker updated at the predictor's steps holds the same velocities and twists, bit for bit,
    given rows included; a repeated instant keeps them; ``reset`` forgets the poses and keeps
    the given velocities; the data of another model is refused."""
    from dua_mujoco import Predictor

    m = mujoco.MjModel.from_xml_string(MOCAP_XML)
    d = mujoco.MjData(m)
    p = Predictor(m, accel=50.0, period=1)
    tracker = MocapVelocityTracker(m)
    assert p.mocap is not None
    for mocap in (p.mocap, tracker):
        mocap.set_velocity("n", [1.0, -2.0, 0.5], [0.1, 0.2, 0.3])
    mujoco.mj_forward(m, d)
    p.reset(d)
    tracker.update(d)
    for k in range(6):
        pos, _, quat, _ = _script(d.time)
        d.mocap_pos[0], d.mocap_quat[0] = pos, quat
        mujoco.mj_step(m, d)
        p.step(d)
        tracker.update(d)
        if k == 3:
            tracker.update(d)  # the same instant again: nothing to difference
        np.testing.assert_array_equal(tracker.twist, p.mocap.twist)
        np.testing.assert_array_equal(tracker.linear, p.mocap.linear)
        assert tracker.nupdates == p.mocap.nupdates == k + 2
    assert np.abs(tracker.linear[0]).min() > 0 and tracker.twist[1].any()
    assert not tracker.twist[2].any()  # the arm: a hinge under the mocap body, not a root
    tracker.reset()
    assert tracker.nupdates == 0 and not tracker.linear[0].any()
    np.testing.assert_array_equal(tracker.linear[1], [1.0, -2.0, 0.5])
    other = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body mocap='true'><geom size='.1'/></body></worldbody></mujoco>"
    )
    with pytest.raises(ShapeError, match="not an MjData of the tracker's model"):
        tracker.update(mujoco.MjData(other))
