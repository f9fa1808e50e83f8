"""Tests of ``Predictor``: kernel velocities, protocol errors, O(log pairs) work, regressions.

The regressions roll out the bundled scenes and scenes written by others (gymnasium's and
dm-control's MJCF) with random controls, and check the completeness claim against MuJoCo's own
contacts: no contact onset may go unpredicted while the bounds held, and every MuJoCo contact must
lie in an active pair (otherwise the pair filter disagrees with MuJoCo and nothing could predict
it).
"""

from __future__ import annotations

import importlib.resources
import math
import os
import subprocess
import sys
import textwrap
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path

import mujoco
import numpy as np
import pytest
from mjcf import free, mjcf, motors
from random_states import random_joint_state

import dua_mujoco
from dua_mujoco.build.bounds import estimate_bounds
from dua_mujoco.build.filter import active_geom_pairs
from dua_mujoco.build.options import CoveringOptions, PilotOptions, UrgencyOptions
from dua_mujoco.core.schedules.state import P_EXTRA
from dua_mujoco.exceptions import (
    BoundViolationWarning,
    InvalidBoundError,
    InvalidChoiceError,
    InvalidInputError,
    NoActivePairsWarning,
    NonFiniteStateError,
    SchedulerError,
    UnsupportedGeomError,
)
from dua_mujoco.measure.monitor import Monitor
from dua_mujoco.measure.report import RunReport
from dua_mujoco.measure.rollout import run
from dua_mujoco.models.scenes import declared_accel_bound, load_scene, make_controller
from dua_mujoco.runtime.predictor import Predictor

REPO = Path(__file__).resolve().parent.parent

# --------------------------------------------------------------------------------------------------
# Velocity correctness of the fused kernel.
# --------------------------------------------------------------------------------------------------

# Every joint type, a nested chain (free -> hinge -> ball -> slide), a hinge/slide chain rooted at
# the world, static geoms (two planes: the fused step must find each half-space's own frame),
# and a mocap body carrying a hinged child. Geoms are off their body
# frames and rotated, inertials are off-centre, so that geom frame, body frame, COM and subtree
# COM all differ and a wrong reference point shows up as a wrong velocity.
KINEMATIC_XML = mjcf(
    '<geom name="floor" type="plane" size="3 3 .1"/>',
    '<geom name="post" type="box" size=".1 .1 .3" pos="1 1 .3" euler="0 0 20"/>',
    '<geom name="wall" type="plane" size="3 3 .1" pos="3 .5 0" zaxis="-1 .2 .3"/>',
    # free -> hinge -> ball -> slide
    """<body name="free" pos="0 0 1" euler="10 20 30">
      <freejoint/>
      <inertial pos=".03 .01 -.02" mass="1" diaginertia=".01 .02 .03"/>
      <geom name="free_cap" type="capsule" fromto="-.1 0 0 .15 .05 .02" size=".04"/>
      <geom name="free_box" type="box" size=".08 .04 .06" pos=".05 .1 0" euler="15 -20 40"/>
      <body name="hinge" pos=".2 .05 0" euler="0 30 0">
        <joint name="j_hinge" type="hinge" axis=".3 1 .2" pos="-.05 0 0"/>
        <geom name="hinge_cap" type="capsule" fromto="0 0 0 .2 .05 -.03" size=".03"/>
        <body name="ball" pos=".22 .05 -.03">
          <joint name="j_ball" type="ball" pos=".01 0 .02"/>
          <geom name="ball_box" type="box" size=".06 .03 .05" pos=".06 0 0" euler="5 10 15"/>
          <body name="slide" pos=".1 0 0">
            <joint name="j_slide" type="slide" axis="1 .4 -.2"/>
            <geom name="slide_cap" type="capsule" fromto="0 0 0 .1 0 .05" size=".02"/>
          </body>
        </body>
      </body>
    </body>""",
    # hinge -> slide, rooted at the world
    """<body name="arm" pos="-1 0 .5" euler="0 10 0">
      <joint name="j_arm" type="hinge" axis="0 .2 1" pos=".02 0 0"/>
      <geom name="arm_cap" type="capsule" fromto="0 0 0 .3 0 0" size=".03"/>
      <body name="arm_tip" pos=".3 0 0">
        <joint name="j_tip" type="slide" axis="1 0 .3"/>
        <geom name="tip_box" type="box" size=".05 .03 .04" pos=".02 0 0" euler="0 0 30"/>
      </body>
    </body>""",
    # a mocap body carrying a hinged child
    """<body name="mocap" mocap="true" pos="1 -1 .5" euler="0 0 15">
      <geom name="mocap_box" type="box" size=".1 .05 .05" pos=".05 0 .02" euler="10 0 0"/>
      <body name="mchild" pos=".2 0 0">
        <joint name="j_mchild" type="hinge" axis="0 1 .3"/>
        <geom name="mchild_cap" type="capsule" fromto="0 0 0 .15 0 .02" size=".02"/>
      </body>
    </body>""",
)


def _rotate(quat: np.ndarray, vec: np.ndarray) -> np.ndarray:
    out = np.zeros(3)
    mujoco.mju_rotVecQuat(
        out, np.asarray(vec, dtype=np.float64), np.asarray(quat, dtype=np.float64)
    )
    return out


@pytest.fixture(scope="module")
def site_model() -> mujoco.MjModel:
    """The kinematic model with a site at every sphere centre of its multi-sphere covering.

    Sites are added in the body frame at ``geom_pos + R(geom_quat) offset``; adding sites does not
    change the geoms, so the covering of the site model is the same (checked).
    """
    m0 = mujoco.MjModel.from_xml_string(KINEMATIC_XML)
    p0 = Predictor(m0, accel=1.0, covering="multi")
    cov = p0.covering
    spec = mujoco.MjSpec.from_string(KINEMATIC_XML)
    for i in range(cov.nsphere):
        g = int(cov.sphere_geom[i])
        body = spec.body(m0.body(int(m0.geom_bodyid[g])).name)
        pos = m0.geom_pos[g] + _rotate(m0.geom_quat[g], cov.sphere_offset[i])
        body.add_site(name=f"s{i}", pos=pos, size=[0.005, 0, 0])
    m = spec.compile()
    p = Predictor(m, accel=1.0, covering="multi")
    np.testing.assert_array_equal(p.covering.sphere_geom, cov.sphere_geom)
    np.testing.assert_allclose(p.covering.sphere_offset, cov.sphere_offset)
    # The point of "multi": offsets are non-zero, so the rotation part of the velocity matters.
    assert (np.linalg.norm(cov.sphere_offset, axis=1) > 1e-3).sum() >= cov.nsphere // 2
    assert cov.nsphere > m.ngeom
    return m


@pytest.fixture
def site_predictor(site_model) -> tuple[mujoco.MjModel, Predictor]:
    """A fresh predictor per test: it holds state (scheduler, mocap tracker)."""
    return site_model, Predictor(site_model, accel=1.0, covering="multi")


def _site_reference(
    m: mujoco.MjModel, d: mujoco.MjData, nsphere: int
) -> tuple[np.ndarray, np.ndarray]:
    """Site positions and ``mj_objectVelocity`` (world frame, flg_local=0) linear velocities."""
    c = np.empty((nsphere, 3))
    v = np.empty((nsphere, 3))
    res = np.zeros(6)
    for i in range(nsphere):
        sid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, f"s{i}")
        c[i] = d.site_xpos[sid]
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_SITE, sid, res, 0)
        v[i] = res[3:]
    return c, v


def test_kernel_matches_mj_object_velocity_at_random_states(site_predictor) -> None:
    m, p = site_predictor
    d = mujoco.MjData(m)
    rng = np.random.default_rng(7)
    for _ in range(25):
        random_joint_state(m, d, rng, velocity_scale=2.0)
        mujoco.mj_forward(m, d)
        c_ref, v_ref = _site_reference(m, d, p.nsphere)
        c_k, v_k = p.sphere_states(d)
        c_s, v_s = p.sphere_states(d)
        scale = 1.0 + np.abs(v_ref).max()
        for c, v in ((c_k, v_k), (c_s, v_s)):
            np.testing.assert_allclose(c, c_ref, atol=1e-12)
            np.testing.assert_allclose(v, v_ref, atol=1e-10 * scale)
        # The chain really moves (a zero-velocity comparison would prove nothing).
        assert np.linalg.norm(v_ref, axis=1).max() > 0.5


def _fused_and_row_taus(
    m: mujoco.MjModel, accel: float, seed: int, ragged: bool = False
) -> Iterator[tuple[Predictor, np.ndarray, np.ndarray, np.ndarray]]:
    """Twenty steps at random states of a select-all predictor of the spheres alone: each step's
    predictor, selected pairs, their taus from the fused ``step`` and from ``pair_set.tau`` on
    ``sphere_states``. ``ragged``: the first sphere pair switched off (the model's 1,856 sphere
    pairs, a multiple of four, end in a ragged group)."""
    # Select-all: every pair is evaluated every step, whatever the random states do to tau.
    p = Predictor(
        m, accel=accel, covering="multi", schedule="select-all", urgency=UrgencyOptions(exact=False)
    )
    d = mujoco.MjData(m)
    rng = np.random.default_rng(seed)
    random_joint_state(m, d, rng, velocity_scale=2.0)
    mujoco.mj_forward(m, d)
    p.reset(d)
    if ragged:
        p.pair_state().set_active([int(np.flatnonzero(p.pair_set.kind == 0)[0])], False)
    sched = p.scheduler
    assert sched is not None
    for _ in range(20):
        random_joint_state(m, d, rng, velocity_scale=2.0)
        d.time += p.dt
        mujoco.mj_forward(m, d)
        p.step(d)
        ids = sched.last_selected
        c, v = p.sphere_states(d)
        yield p, ids, sched.last_tau[ids], p.pair_set.tau(ids, c, v, p.halfspaces(d))


def test_fused_step_round_trips_the_pair_sets_tau(site_model) -> None:
    """The fused ``step`` computes the same tau as ``pair_set.tau`` on ``sphere_states``: a round
    trip of the pair records and the gathered states through the runtime's two entries (both run
    the same kernels, so it cannot catch a wrong tau: tests/test_reference_step.py can)."""
    halfspace_pairs_seen = evaluated = 0
    for p, ids, got, expected in _fused_and_row_taus(site_model, 1.0, 3):
        evaluated += ids.size
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-15)
        halfspace_pairs_seen += int(p.pair_set.halfspace[ids].sum())
    assert evaluated > 20
    assert halfspace_pairs_seen > 0


@pytest.mark.parametrize("accel", [1.0, 0.0])
def test_fused_steps_sphere_lanes_are_the_row_kernels_bit_for_bit(site_model, accel) -> None:
    """The fused step hands the kernel each sphere pair's two rows in place, its lanes taking the
    relative state's differences (TauSpeedFourPairs); ``pair_set.tau`` gathers rows of ten from
    ``sphere_states`` (TauSpeedFour). The same operations in the same order: the same bits, on
    the lanes' common path (accel 1) and on every lane's scalar fallback (accel 0: h = 0), in
    groups of four and a ragged last one."""
    compared = 0
    for p, ids, got, expected in _fused_and_row_taus(site_model, accel, 11, ragged=True):
        spheres = p.pair_set.kind[ids] == 0
        assert int(spheres.sum()) % 4 != 0
        np.testing.assert_array_equal(got[spheres], expected[spheres])
        compared += int(spheres.sum())
    assert compared > 20


# A plane on a body declared between two free bodies: its geom id falls between theirs, so the
# half-space pairs of the later body sit among the sphere pairs in pair order.
_INTERLEAVED_PLANE = """
<mujoco><worldbody>
  <body name="a"><freejoint/><geom type="capsule" size=".05 .2"/>
    <geom type="sphere" size=".1" pos=".3 0 0"/></body>
  <body name="floor"><geom type="plane" size="5 5 .1" pos="0 0 -1"/></body>
  <body name="b" pos="1 0 0"><freejoint/><geom type="box" size=".1 .1 .1"/>
    <geom type="capsule" size=".05 .2" pos="0 .3 0"/></body>
</worldbody></mujoco>
"""


@pytest.mark.parametrize("accel", [1.0, 0.0])
def test_fused_steps_sphere_lanes_write_each_pairs_own_place(accel) -> None:
    """Where a half-space pair sits inside a group of four sphere pairs in the step's selection,
    the group's places are not contiguous: each lane's tau goes to its own pair's place (held bit
    for bit to the row kernel, as above), not to the places after the group's first."""
    m = mujoco.MjModel.from_xml_string(_INTERLEAVED_PLANE)
    straddled = compared = 0
    # The first sphere pair switched off: the sphere pairs before the plane's no longer fill
    # whole groups, so one group takes pairs from both sides of it.
    for p, ids, got, expected in _fused_and_row_taus(m, accel, 5, ragged=True):
        spheres = p.pair_set.kind[ids] == 0
        at = np.flatnonzero(spheres)
        groups = at[: at.size // 4 * 4].reshape(-1, 4)
        straddled += int((groups[:, 3] - groups[:, 0] > 3).sum())
        np.testing.assert_array_equal(got[spheres], expected[spheres])
        compared += int(spheres.sum())
    assert straddled > 0 and compared > 20


def _quat_exp(omega_t: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_axisAngle2Quat(
        q, omega_t / max(np.linalg.norm(omega_t), 1e-300), np.linalg.norm(omega_t)
    )
    return q


@pytest.mark.parametrize("path", ["screw", "circle"])
def test_mocap_velocity_from_differenced_path(site_predictor, path: str) -> None:
    """Mocap body moved along a scripted path; ``step`` each step so the tracker differences.

    ``screw``: constant linear and angular velocity, so backward differences are exact.
    ``circle``: a horizontal circle, where the difference is the mean velocity over the last step;
    the predictor's discrete-time term assumes it is within ``A h / 2`` of the velocity at the
    instant, with ``A = r w^2``: checked here.
    """
    m, p = site_predictor
    d = mujoco.MjData(m)
    scratch = mujoco.MjData(m)
    h = m.opt.timestep
    mocap_body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "mocap")
    in_mocap_tree = np.asarray(m.body_rootid)[p.covering.sphere_body] == mocap_body
    hinge_adr = int(m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "j_mchild")])
    hinge_dof = int(m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "j_mchild")])
    p0 = np.array(m.body_pos[mocap_body])
    q0 = np.array(m.body_quat[mocap_body])
    v_lin, omega, theta_dot = np.array([0.7, -0.4, 0.3]), np.array([0.5, 1.5, -2.0]), 1.3
    radius, w = 0.2, 2.0 * math.pi / 1.5

    def pose(t: float) -> tuple[np.ndarray, np.ndarray]:
        if path == "screw":
            q = np.zeros(4)
            mujoco.mju_mulQuat(q, _quat_exp(omega * t), q0)
            return p0 + v_lin * t, q
        return p0 + radius * np.array([math.cos(w * t) - 1, math.sin(w * t), 0.0]), q0

    def place(dd: mujoco.MjData, t: float) -> None:
        pos, quat = pose(t)
        dd.mocap_pos[0], dd.mocap_quat[0] = pos, quat
        dd.qpos[hinge_adr] = 0.3 + theta_dot * t
        dd.qvel[hinge_dof] = theta_dot
        dd.time = t
        mujoco.mj_forward(m, dd)

    rng = np.random.default_rng(11)
    random_joint_state(m, d, rng, velocity_scale=2.0)
    tol = 1e-7 if path == "screw" else radius * w**2 * h / 2 + 1e-9
    errors = []
    for k in range(40):
        place(d, k * h)
        if k == 0:
            p.reset(d)
            continue
        p.step(d)
        # Independent reference: central differences of the site positions along the script.
        scratch.qpos[:] = d.qpos
        e = 1e-6
        place(scratch, k * h + e)
        c_plus, _ = _site_reference(m, scratch, p.nsphere)
        scratch.qpos[:] = d.qpos
        place(scratch, k * h - e)
        c_minus, _ = _site_reference(m, scratch, p.nsphere)
        v_ref = (c_plus - c_minus) / (2 * e)
        c_ref, v_obj = _site_reference(m, d, p.nsphere)
        c_k, v_k = p.sphere_states(d)
        c_s, v_s = p.sphere_states(d)
        np.testing.assert_allclose(c_k, c_ref, atol=1e-12)
        np.testing.assert_allclose(c_s, c_ref, atol=1e-12)
        # Spheres outside the mocap tree: mj_objectVelocity is the truth there.
        np.testing.assert_allclose(v_k[~in_mocap_tree], v_obj[~in_mocap_tree], atol=1e-9)
        errors.append(np.abs(v_k[in_mocap_tree] - v_ref[in_mocap_tree]).max())
        np.testing.assert_allclose(v_s[in_mocap_tree], v_k[in_mocap_tree], atol=1e-12)
    assert in_mocap_tree.sum() >= 2
    assert max(errors) <= tol, f"mocap velocity error {max(errors):.3g} > {tol:.3g}"


MOCAP_XML = """
<mujoco>
  <worldbody>
    <body name="m" mocap="true"><geom name="gm" size=".1"/></body>
    <body name="b" pos="1 0 0"><freejoint/><geom name="gb" size=".1"/></body>
  </worldbody>
</mujoco>
"""


def test_reset_restarts_mocap_differencing() -> None:
    """A predictor reused for a second episode (time back to 0) must not keep stale mocap state.

    ``reset`` is the start of a new trajectory: the mocap velocity must be differenced within the
    new episode only, never against a pose of the previous one.
    """
    m = mujoco.MjModel.from_xml_string(MOCAP_XML)
    h = m.opt.timestep
    p = Predictor(m, accel=1.0)
    seen = []
    for speed, n in ((0.5, 5), (-0.3, 8)):
        d = mujoco.MjData(m)
        for k in range(n):
            d.mocap_pos[0] = [speed * k * h, 0.0, 0.0]
            d.time = k * h
            mujoco.mj_forward(m, d)
            if k == 0:
                p.reset(d)
                continue
            p.step(d)
            seen.append((speed, k, float(p.sphere_states(d)[1][0, 0])))
    wrong = [(s, k, v) for s, k, v in seen if abs(v - s) > 1e-9]
    assert not wrong, f"(episode speed, step, predictor's mocap velocity): {wrong}"


# --------------------------------------------------------------------------------------------------
# Predictor protocol and input errors.
# --------------------------------------------------------------------------------------------------

TWO_BODIES_XML = mjcf(
    '<geom name="floor" type="plane" size="2 2 .1"/>',
    free("a", "0 0 1", 'name="ga" type="capsule" size=".05 .1"'),
    free("b", ".5 0 1", 'name="gb" type="box" size=".1 .1 .1"'),
)


@pytest.fixture
def two_bodies() -> tuple[mujoco.MjModel, mujoco.MjData]:
    m = mujoco.MjModel.from_xml_string(TWO_BODIES_XML)
    d = mujoco.MjData(m)
    mujoco.mj_step(m, d)
    return m, d


def test_divergence_reset_by_mujoco_is_named(two_bodies) -> None:
    """MuJoCo answers a NaN velocity by resetting the state; the error must say so."""
    m, d = two_bodies
    p = Predictor(m, accel=10.0)
    p.reset(d)
    for _ in range(5):
        mujoco.mj_step(m, d)
        p.step(d)
    d.qvel[0] = np.nan
    mujoco.mj_step(m, d)  # warns, then mj_resetData: time goes back to one step
    with pytest.raises(NonFiniteStateError, match=r"diverged.*timestep"):
        p.step(d)
    # As the message says: reset, go on; a second divergence is named too (MuJoCo's reset
    # clears the warning counters, so the count is 1 again, not 2).
    p.reset(d)
    for _ in range(5):
        mujoco.mj_step(m, d)
        p.step(d)
    d.qvel[0] = np.nan
    mujoco.mj_step(m, d)
    with pytest.raises(NonFiniteStateError, match=r"diverged.*timestep"):
        p.step(d)
    # Diverging again at the very first step after the reset (time back where it was).
    p.reset(d)
    d.qvel[0] = np.nan
    mujoco.mj_step(m, d)
    with pytest.raises(NonFiniteStateError, match=r"diverged.*timestep"):
        p.step(d)
    # After a handled divergence (its warning still counted), a rewound data.time is the
    # user's protocol error, not a divergence.
    p.reset(d)
    mujoco.mj_step(m, d)
    d.time -= 0.5
    with pytest.raises(SchedulerError, match="advanced by"):
        p.step(d)
    # The user's own reset of the data (counters cleared) is a protocol error, not divergence.
    mujoco.mj_resetData(m, d)
    mujoco.mj_step(m, d)
    with pytest.raises(SchedulerError, match="advanced by"):
        p.step(d)


def test_model_and_data_types_are_checked(two_bodies) -> None:
    m, _ = two_bodies
    with pytest.raises(InvalidInputError, match=r"model must be a mujoco\.MjModel, got str"):
        Predictor("scene.xml", accel=1.0)  # type: ignore[arg-type]
    p = Predictor(m, accel=1.0)
    with pytest.raises(InvalidInputError, match=r"data must be a mujoco\.MjData, got NoneType"):
        p.reset(None)  # type: ignore[arg-type]


def forwarded(model: mujoco.MjModel) -> mujoco.MjData:
    """A new ``MjData`` of ``model`` with its kinematics computed."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return data


def test_data_of_an_edited_model_is_refused(two_bodies) -> None:
    """Same sizes, a geom moved: the predictor's covering would be wrong for it."""
    m, _ = two_bodies
    p = Predictor(m, accel=1.0)
    twin = mujoco.MjModel.from_xml_string(TWO_BODIES_XML)
    p.reset(forwarded(twin))  # the same XML loaded twice is accepted
    twin.geom_pos[0, 0] += 0.5
    with pytest.raises(InvalidInputError, match="another MjModel"):
        p.reset(forwarded(twin))
    # Same geoms, one pair excluded: the pair filter differs.
    excluded = mujoco.MjModel.from_xml_string(
        TWO_BODIES_XML.replace(
            "</worldbody>", '</worldbody><contact><exclude body1="a" body2="b"/></contact>'
        )
    )
    with pytest.raises(InvalidInputError, match="collision filters differ"):
        p.reset(forwarded(excluded))


def test_model_without_collidable_pairs_warns() -> None:
    m = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><freejoint/><geom size='.1' contype='0' conaffinity='0'/>"
        "</body><geom size='.1' pos='1 0 0'/></worldbody></mujoco>"
    )
    with pytest.warns(NoActivePairsWarning, match="never raise an alarm"):
        p = Predictor(m, accel=1.0)
    assert len(p.pair_set) == 0


def test_step_before_reset(two_bodies) -> None:
    m, d = two_bodies
    p = Predictor(m, accel=10.0)
    with pytest.raises(SchedulerError, match="reset"):
        p.step(d)


@pytest.mark.parametrize("steps", [1, 3])
def test_step_after_wrong_number_of_physics_steps(two_bodies, steps: int) -> None:
    m, d = two_bodies
    p = Predictor(m, accel=10.0, period=2)
    p.reset(d)
    for _ in range(steps):
        mujoco.mj_step(m, d)
    with pytest.raises(SchedulerError, match=r"period") as info:
        p.step(d)
    assert "period=2" in str(info.value)


def test_step_at_the_right_period_is_accepted(two_bodies) -> None:
    m, d = two_bodies
    p = Predictor(m, accel=10.0, period=3)
    p.reset(d)
    for _ in range(4):
        for _ in range(3):
            mujoco.mj_step(m, d)
        p.step(d)
    assert p.scheduler is not None and p.scheduler.step_count == 4


def test_alarms_are_read_only(two_bodies) -> None:
    m, d = two_bodies
    p = Predictor(m, accel=10.0)
    alarms = p.reset(d)
    for name in ("step", "time", "pairs", "tau"):
        with pytest.raises(AttributeError):
            setattr(alarms, name, 0)
    assert repr(alarms).startswith("Alarms(step=0, ")


def test_nan_state_on_reset_names_the_geom(two_bodies) -> None:
    m, d = two_bodies
    p = Predictor(m, accel=10.0)
    d.qpos[0] = np.nan
    mujoco.mj_forward(m, d)
    with pytest.raises(NonFiniteStateError, match="'ga'"):
        p.reset(d)


def test_nan_state_on_step_names_a_geom(two_bodies) -> None:
    m, d = two_bodies
    # DUA evaluates bucket 0 every step (a deadline schedule reads a pair only when it is due).
    p = Predictor(m, accel=10.0, schedule="dua")
    p.reset(d)
    d.qpos[0] = np.nan
    d.time += p.dt
    mujoco.mj_forward(m, d)
    # Every pair of this model involves 'ga' or 'gb', so the scheduled pairs see the NaN.
    with pytest.raises(NonFiniteStateError, match="'ga'"):
        p.step(d)


def test_wrong_mjdata_on_reset(two_bodies) -> None:
    m, _ = two_bodies
    p = Predictor(m, accel=10.0)
    other = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><freejoint/><geom size='.1'/></body></worldbody></mujoco>"
    )
    od = mujoco.MjData(other)
    mujoco.mj_forward(other, od)
    with pytest.raises(InvalidInputError, match="MjData of this predictor's model"):
        p.reset(od)


def test_wrong_mjdata_on_step() -> None:
    """``step`` with the MjData of another (smaller) model must refuse it.

    Run in a subprocess: without the check the native step reads past the end of MjData's
    arrays, which could crash the interpreter.
    """
    code = textwrap.dedent(
        """
        import mujoco
        from dua_mujoco.exceptions import InvalidInputError
        from dua_mujoco.runtime.predictor import Predictor
        from dua_mujoco.models.scenes import load_scene
        m, d = load_scene("paper_world:30")
        other = mujoco.MjModel.from_xml_string(
            "<mujoco><worldbody><body><freejoint/><geom size='.1'/></body></worldbody></mujoco>")
        od = mujoco.MjData(other)
        p = Predictor(m, accel=2.0)
        mujoco.mj_step(m, d)
        p.reset(d)
        od.time = d.time + m.opt.timestep
        mujoco.mj_forward(other, od)
        try:
            p.step(od)
        except InvalidInputError as exc:
            print("REFUSED", exc)
        else:
            print("ACCEPTED")
        """
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=_env(), timeout=120
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert "REFUSED" in out.stdout, (
        "Predictor.step accepted the MjData of another model and returned alarms computed from "
        "out-of-bounds memory; it should raise InvalidInputError like reset() does. "
        f"stdout: {out.stdout.strip()}"
    )


def test_bad_accel_key_lists_body_names(two_bodies) -> None:
    m, _ = two_bodies
    with pytest.raises(InvalidChoiceError) as info:
        Predictor(m, accel={"nope": 1.0, "*": 2.0})
    msg = str(info.value)
    assert "'nope'" in msg
    for name in ("'a'", "'b'", "'*'"):
        assert name in msg


@pytest.mark.parametrize("accel", [-1.0, {"a": -1.0, "*": 1.0}, float("nan")])
def test_negative_accel(two_bodies, accel) -> None:
    m, _ = two_bodies
    with pytest.raises(InvalidBoundError):
        Predictor(m, accel=accel)


HFIELD_XML = """
<mujoco>
  <asset><hfield name="terrain" nrow="10" ncol="10" size="1 1 .2 .1"/></asset>
  <worldbody>
    <geom name="ground" type="hfield" hfield="terrain"/>
    <body name="a" pos="0 0 1"><freejoint/><geom name="ga" type="sphere" size=".05"/></body>
  </worldbody>
</mujoco>
"""


def test_hfield_is_terrain_by_default_box_and_error_on_request() -> None:
    m = mujoco.MjModel.from_xml_string(HFIELD_XML)
    p = Predictor(m, accel=1.0)
    assert p.nsphere_pairs == 1 and p.covering.shape_geom.tolist() == [0]
    with pytest.raises(UnsupportedGeomError) as info:
        Predictor(m, accel=1.0, covering=CoveringOptions(hfield="error"))
    msg = str(info.value)
    assert "'ground'" in msg
    assert 'hfield="box"' in msg
    assert Predictor(m, accel=1.0, covering=CoveringOptions(hfield="box")).nsphere_pairs == 1


# --------------------------------------------------------------------------------------------------
# O(log pairs) work per step.
# --------------------------------------------------------------------------------------------------


def test_log_pairs_evaluations_on_paper_world_200() -> None:
    m, d = load_scene("paper_world:200")
    bound = declared_accel_bound(m)
    assert bound is not None
    p = Predictor(m, accel=bound, schedule="dua")
    ctrl = make_controller(m, "random", seed=5)
    ctrl(m, d)
    mujoco.mj_step(m, d)
    p.reset(d)
    limit = math.ceil(math.log2(p.nsphere_pairs + 1))
    assert p.nsphere_pairs > 20_000
    assert p.evaluations_per_step == p.nsphere_pairs  # the classification evaluates every pair
    sched = p.scheduler
    assert sched is not None
    counts = []
    for _ in range(300):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        p.step(d)
        # Pairs of a body whose bounds broke are evaluated on top of the slots.
        counts.append(sched.last_selected.size - int(sched.state.params[P_EXTRA]))
        assert p.evaluations_per_step == sched.last_selected.size
    assert max(counts) <= limit
    assert min(counts) >= limit - 1  # only the partly empty last bucket may skip a slot


# --------------------------------------------------------------------------------------------------
# Regression: bundled scenes.
# --------------------------------------------------------------------------------------------------


def _summary(name: str, r: RunReport) -> str:
    return (
        f"{name}: onsets {r.contact_onsets} predicted {r.predicted_onsets} missed "
        f"{r.missed_onsets} (valid bounds {r.missed_onsets_valid_bounds}) unfiltered "
        f"{r.unfiltered_contacts} alarm episodes {r.alarm_episodes} false {r.false_alarm_episodes} "
        f"pairs {r.pairs} evals/step {r.evals_per_step:.1f} bound violations {r.bound_violations}"
    )


SCENES = ("two_arms", "traffic", "clutter", "paper_world:40")


def _assert_complete(name: str, r: RunReport) -> None:
    print(_summary(name, r))
    misses = [m for m in r.misses if m.bounds_held]
    assert r.missed_onsets_valid_bounds == 0, f"{name}: valid-bounds misses {misses[:5]}"
    assert r.unfiltered_contacts == 0, f"{name}: MuJoCo contacts outside the active pairs"
    assert r.predicted_onsets + r.missed_onsets == r.contact_onsets


BUNDLED = [
    *((s, "bounding", p, "deadline") for s in SCENES for p in (1, 4)),
    # The paper's rank buckets, once per scene.
    *((s, "bounding", 1, "dua") for s in SCENES),
    # The multi covering multiplies the pairs (12k on two_arms, 29k on traffic): two scenes.
    *((s, "multi", p, "deadline") for s in ("two_arms", "traffic") for p in (1, 4)),
]


@pytest.mark.slow
@pytest.mark.parametrize(("scene", "covering", "period", "schedule"), BUNDLED)
def test_bundled_scene_regression(scene: str, covering: str, period: int, schedule: str) -> None:
    m, d = load_scene(scene)
    p = Predictor(
        m,
        accel="auto",
        covering=covering,
        period=period,
        schedule=schedule,
        pilot=PilotOptions(controller=make_controller(m, "random", seed=99)),
    )
    r = run(m, d, p, steps=2000, controller=make_controller(m, "random", seed=0), progress=False)
    _assert_complete(f"{scene}/{covering}/{period}/{schedule}", r)
    assert r.contact_onsets > 0
    assert r.predictor_steps == 2000 // period
    # Each pair when its own tau runs out (dua: its slot comes), and the pairs of the bodies
    # whose bounds broke: far fewer than every pair every step (test_log_pairs_evaluations_...
    # holds dua's slots to O(log pairs)).
    assert r.evals_per_step < 0.5 * r.pairs


# --------------------------------------------------------------------------------------------------
# Regression: scenes written by others.
# --------------------------------------------------------------------------------------------------


def _external_scenes() -> list[tuple[str, str]]:
    gym = importlib.resources.files("gymnasium") / "envs/mujoco/assets"
    out = [
        (f"gym/{name[:-4]}", str(gym / name))
        for name in sorted(os.listdir(str(gym)))
        if name.endswith(".xml")
    ]
    import dm_control

    suite = Path(dm_control.__file__).parent / "suite"
    out += [(f"dmc/{f.stem}", str(f)) for f in sorted(suite.glob("*.xml"))]
    return out


EXTERNAL = _external_scenes()


@pytest.mark.slow
@pytest.mark.parametrize(("name", "path"), EXTERNAL, ids=[n for n, _ in EXTERNAL])
def test_external_scene_regression(name: str, path: str) -> None:
    try:
        m = mujoco.MjModel.from_xml_path(path)
    except ValueError as exc:
        # Only a model MuJoCo itself cannot load is skipped, and the reason is printed.
        print(f"{name}: MuJoCo cannot load it: {exc}")
        pytest.skip(f"MuJoCo cannot load {path}: {exc}")
    d = mujoco.MjData(m)
    if m.nkey:
        mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    # A model whose geoms can never touch (gym's inverted_double_pendulum) is worth a warning.
    expected = NoActivePairsWarning if len(active_geom_pairs(m)) == 0 else None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        p = Predictor(
            m,
            accel="auto",
            covering=CoveringOptions(hfield="box"),
            pilot=PilotOptions(
                steps=1000, controller=make_controller(m, "random", seed=99, hold_steps=20)
            ),
        )
    assert [w.category for w in caught if w.category is NoActivePairsWarning] == (
        [expected] if expected else []
    )
    ctrl = make_controller(m, "random", seed=0, hold_steps=20)
    r = run(m, d, p, steps=1000, controller=ctrl, progress=False, scene=name)
    _assert_complete(name, r)


PUCK_XML = f"""
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 .1"/>
    <geom name="post" type="box" size=".1 .1 .1" pos=".6 0 .1"/>
    <body name="puck" pos="0 0 .1">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="y" type="slide" axis="0 1 0"/>
      <geom name="gpuck" size=".1"/>
    </body>
  </worldbody>
  {motors("x", "y", ctrlrange="-1 1", ctrllimited="true")}
</mujoco>
"""


def test_auto_bounds_of_a_body_always_in_contact() -> None:
    """A puck sliding on the floor is in contact at every pilot step (as gymnasium's point.xml).

    The pilot measures out-of-contact steps only, so it sees none for the puck; a bound of 0 for a
    body that visibly moves makes every later step a bound violation, and every missed collision
    of the puck is then excused as "bounds broken" (gym/point: 30 of 53 onsets missed, 1000 of
    1000 steps in violation). ``accel="auto"`` must not silently produce a void guarantee.
    """
    m = mujoco.MjModel.from_xml_string(PUCK_XML)
    p = Predictor(m, accel="auto", pilot=PilotOptions(steps=500))
    puck = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "puck")
    assert p.bounds.accel[puck] > 0, (
        "estimate_bounds gave the moving body 'puck' an acceleration bound of 0 because it was "
        "never out of contact during the pilot"
    )


# --------------------------------------------------------------------------------------------------
# Intended contact (paper sec. 6.3).
# --------------------------------------------------------------------------------------------------

HEAD_ON_XML = mjcf(
    free("a", "-.5 0 0", 'name="ga" size=".1"'),
    free("b", ".5 0 0", 'name="gb" size=".1"'),
    free("c", "0 2 0", 'name="gc" size=".1"'),
    option='gravity="0 0 0"',
)


def _head_on(
    on_step: Callable[[int, mujoco.MjData, object, Monitor], None] | None, period: int = 1
) -> tuple[Predictor, RunReport]:
    """Spheres a and b close at 2 m/s and touch at t = 0.4 s; c stays away."""
    m = mujoco.MjModel.from_xml_string(HEAD_ON_XML)
    d = mujoco.MjData(m)
    d.qvel[0], d.qvel[6] = 1.0, -1.0
    mujoco.mj_forward(m, d)
    # Out of contact nothing accelerates; 1 m/s^2 is a valid bound.
    p = Predictor(m, accel=1.0, period=period)
    return p, run(m, d, p, steps=400, progress=False, on_step=on_step)


def _head_on_onset_step() -> int:
    first: list[int] = []

    def watch(k: int, d: mujoco.MjData, alarms: object, mon: Monitor) -> None:
        if d.ncon and not first:
            first.append(k)

    _head_on(watch)
    return first[0]


def test_contact_between_switched_off_bodies_is_not_a_miss() -> None:
    def switch_off(k: int, d: mujoco.MjData, alarms: object, mon: Monitor) -> None:
        if k == 1:
            assert mon.predictor.set_active_bodies("a", "b", on=False) == 1

    _, r = _head_on(switch_off)
    assert r.inactive_pair_contacts >= 1
    assert r.contact_onsets == 0
    assert r.missed_onsets == 0


def test_contact_in_active_pair_is_predicted() -> None:
    _, r = _head_on(None)
    assert r.contact_onsets >= 1
    assert r.predicted_onsets == r.contact_onsets
    assert r.inactive_pair_contacts == 0


def test_switched_back_on_pair_is_predicted() -> None:
    def toggle(k: int, d: mujoco.MjData, alarms: object, mon: Monitor) -> None:
        if k == 1:
            mon.predictor.set_active_bodies("a", "b", on=False)
        elif k == 100:  # 0.2 s before the contact
            mon.predictor.set_active_bodies("a", "b", on=True)

    _, r = _head_on(toggle)
    assert r.contact_onsets >= 1
    assert r.predicted_onsets == r.contact_onsets
    assert r.inactive_pair_contacts == 0


@pytest.mark.parametrize("where", ["after_predictor_step", "just_before_onset"])
def test_pair_switched_on_mid_period_alarms_until_evaluated(where: str) -> None:
    """A pair switched on inside a period (7 steps) stands in alarm until it is evaluated.

    No predictor step falls between the switch and the onset (checked), so only the standing
    alarm of a switched-on pair can cover the onset; without it (the pair keeping its stale tau
    until the next step) the onset was missed with the bounds held.
    """
    period = 7
    onset = _head_on_onset_step()
    last_step = onset - onset % period  # the last predictor step at or before the onset
    assert last_step < onset, "the onset must fall inside a period"
    on_at = last_step if where == "after_predictor_step" else onset - 1
    seen: dict[str, bool] = {}

    def toggle(k: int, d: mujoco.MjData, alarms: object, mon: Monitor) -> None:
        sched = mon.predictor.scheduler
        if k == 1:
            mon.predictor.set_active_bodies("a", "b", on=False)
        elif k == on_at:
            mon.predictor.set_active_bodies("a", "b", on=True)
            p = mon.predictor
            gp = p.geom_pairs.indices_of(np.array([0]), np.array([1]))[0]  # geoms ga, gb
            ab = np.flatnonzero(p.sphere_pairs.geom_pair == gp)
            seen["alarm_state"] = ab.size == 1 and bool(sched.alarm_state(ab)[0])

    _, r = _head_on(toggle, period=period)
    assert seen["alarm_state"]
    assert r.contact_onsets == 1
    assert r.predicted_onsets == 1 and r.missed_onsets == 0


RESTING_XML = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 .1"/>
    <body name="box" pos="0 0 .1"><freejoint/><geom name="gbox" type="box" size=".1 .1 .1"/></body>
    <body name="ball" pos="1 0 1.5"><freejoint/><geom name="gball" size=".05"/></body>
  </worldbody>
</mujoco>
"""


def test_deactivate_contacts_switches_off_resting_contact() -> None:
    m = mujoco.MjModel.from_xml_string(RESTING_XML)
    d = mujoco.MjData(m)
    for _ in range(50):  # let the box settle; the ball is still falling
        mujoco.mj_step(m, d)
    assert d.ncon > 0
    p = Predictor(m, accel=12.0)  # gravity, out of contact
    mon = Monitor(p)
    mon.start(d)
    assert p.deactivate_contacts(d) == 1
    box_floor = p.set_active_bodies("box", "world", on=False)  # same pairs: already off
    sched = p.scheduler
    assert sched is not None
    gp_box = p.geom_pairs.indices_of(
        np.array([mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")]),
        np.array([mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "gbox")]),
    )
    off = np.flatnonzero(p.sphere_pairs.geom_pair == gp_box[0])
    assert off.size == box_floor and not sched.active[off].any()
    assert sched.active.sum() == p.nsphere_pairs - off.size
    for _ in range(600):  # the ball lands at about t = 0.55 s
        mujoco.mj_step(m, d)
        mon.observe(d, p.step(d))
    assert mon.onsets >= 1  # the ball on the floor
    assert mon.predicted == mon.onsets
    assert not mon.misses
    assert not sched.active[off].any()


def test_deactivate_contacts_without_contacts(two_bodies) -> None:
    m, d = two_bodies
    p = Predictor(m, accel=10.0)
    p.reset(d)
    assert d.ncon == 0
    assert p.deactivate_contacts(d) == 0


def test_switch_names_a_pair_id_out_of_range(two_bodies) -> None:
    """The runtime names a pair id out of range (Python does not check it again); none switch."""
    m, d = two_bodies
    p = Predictor(m, accel=10.0)
    p.reset(d)
    n = p.nsphere_pairs
    msg = rf"pair id {n} \(pairs\[1\]\) is out of range: the predictor knows {n} sphere pairs"
    with pytest.raises(InvalidInputError, match=msg):
        p.pair_state().set_active([0, n], False)
    assert p.pair_state().active.all()


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    return env


def test_monitor_bound_check_follows_the_predictors_mocap_tracker() -> None:
    """After reset, the BoundMonitor must still read the tracker the predictor updates."""
    from dua_mujoco.measure.monitor import Monitor

    m = mujoco.MjModel.from_xml_string(MOCAP_XML)
    d = mujoco.MjData(m)
    p = Predictor(m, accel=1.0)
    monitor = Monitor(p)
    mujoco.mj_forward(m, d)
    monitor.start(d)
    assert p.mocap is not None and monitor.bound_checks is not None
    # A velocity the resting mocap body does not have: only a check that reads the predictor's
    # own tracker sees it (and must flag the discrepancy).
    p.mocap.set_velocity("m", [10.0, 0.0, 0.0])
    for _ in range(3):
        mujoco.mj_step(m, d)
        monitor.observe(d, p.step(d))
    assert {v.kind for v in monitor.bound_checks.violations} >= {"discrepancy"}


MOCAP_RAM_XML = """
<mujoco>
  <option timestep="0.002" gravity="0 0 0"/>
  <worldbody>
    <body name="ram" mocap="true"><geom name="gram" size=".1"/></body>
    <body name="target" pos=".25 0 0">
      <joint type="slide" axis="0 1 0"/><geom name="gtarget" size=".1"/>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.mark.parametrize("go", [8, 9, 11])
def test_broken_speed_bound_of_a_mocap_body_is_seen_when_broken(go: int) -> None:
    """A mocap body scripted at 5 m/s against a declared 1 m/s, predictor period 8.

    The tracker's velocity is refreshed only at predictor steps; the speed hypothesis is on the
    chord, fresh every physics step, so the violation is recorded at the step the mocap body
    starts moving, before the contact: the miss is one after broken bounds, never a valid one.
    """
    m = mujoco.MjModel.from_xml_string(MOCAP_RAM_XML)
    d = mujoco.MjData(m)
    p = Predictor(m, accel=5000.0, speed=1.0, period=8)

    def ram(model: mujoco.MjModel, data: mujoco.MjData) -> None:
        if round(data.time / model.opt.timestep) >= go:
            data.mocap_pos[0, 0] += 5.0 * model.opt.timestep

    first: dict[str, int] = {}

    def watch(k: int, data: mujoco.MjData, alarms: object, mon: Monitor) -> None:
        if data.ncon and "onset" not in first:
            first["onset"] = k
        if "speed" not in first and any(v.kind == "speed" for v in mon.bound_checks.violations):
            first["speed"] = k

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BoundViolationWarning)
        r = run(m, d, p, steps=40, controller=ram, on_step=watch, progress=False)
    assert first["speed"] < first["onset"]
    assert r.contact_onsets == 1
    assert r.missed_onsets_valid_bounds == 0


def _alarm_log(m: mujoco.MjModel, p: Predictor, steps: int) -> list[bytes]:
    """Every step's alarms (pair ids, the bits of tau, the new flags) over a random drive."""
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    ctrl = make_controller(m, "random", seed=0)
    log = [p.reset(d)]
    for _ in range(steps):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        log.append(p.step(d))
    return [a.pairs.tobytes() + a.tau.tobytes() + a.new.tobytes() for a in log]


@pytest.mark.filterwarnings("ignore::dua_mujoco.exceptions.PilotWarning")  # clutter's stirrer
@pytest.mark.parametrize("scene", ["two_arms", "clutter"])
def test_pilot_bounds_is_what_auto_measures(scene: str) -> None:
    """``accel="auto"`` is ``pilot_bounds`` of the same options: the same bounds and the same
    alarms bit for bit; the pilot measured at other points (the covering's centres, not the
    boxes' corners ``bound_points``) gives other bounds and other alarms, which the comparison
    sees."""
    m, _ = load_scene(scene)
    # The default pilot controller: its controls come from the pilot's seed alone.
    options = {"pilot": PilotOptions(steps=300, seed=99), "covering": "multi"}
    auto = Predictor(m, accel="auto", **options)
    bounds = dua_mujoco.pilot_bounds(m, **options)
    given = Predictor(m, accel=bounds, **options)
    np.testing.assert_array_equal(bounds.accel, auto.bounds.accel)
    assert _alarm_log(m, given, 300) == _alarm_log(m, auto, 300)
    cov = auto.covering
    centres = estimate_bounds(
        m,
        steps=300,
        seed=99,
        spheres=(cov.sphere_geom, cov.sphere_body, cov.sphere_offset),
        with_speed=False,
    )
    assert not np.array_equal(centres.accel, bounds.accel)
    other = Predictor(m, accel=centres, **options)
    assert _alarm_log(m, other, 300) != _alarm_log(m, auto, 300)


# Two free balls: sphere pairs only (no floor), placed by the test.
_FAR_BALLS = """
<mujoco>
  <option gravity="0 0 0"/>
  <worldbody>
    <body name="a"><freejoint/><geom name="ga" size=".05"/></body>
    <body name="b" pos="1 0 0"><freejoint/><geom name="gb" size=".05"/></body>
  </worldbody>
</mujoco>
"""


@pytest.mark.parametrize(
    ("xa", "xb", "finite"),
    [(1e308, 1e308, False), (1e308, 0.0, True), (1e300, 1e300, True), (-1e308, -1e308, False)],
)
def test_huge_finite_sphere_states_are_judged_by_their_sum(
    xa: float, xb: float, finite: bool
) -> None:
    """A sphere pair's state (both spheres' centres and velocities, twelve finite numbers) is
    refused when their sum is not finite, as before the gather read tame spheres (every number
    at most 1e300) without summing them: two balls at x = 1e308 are refused, one at 1e308 and
    one at 0, or both at 1e300, are judged."""
    m = mujoco.MjModel.from_xml_string(_FAR_BALLS)
    d = mujoco.MjData(m)
    d.qpos[0], d.qpos[7] = xa, xb
    mujoco.mj_forward(m, d)
    p = Predictor(m, accel=10.0)
    if finite:
        p.reset(d)
        assert p.evaluations_per_step == 1
    else:
        with pytest.raises(NonFiniteStateError, match=r"'g[ab]'"):
            p.reset(d)
