"""The smooth driver: servo controls linear between random points, motors as 1 Hz critically
damped PD torques toward joint targets that move the same way."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from dua_mujoco.build.options import PilotOptions
from dua_mujoco.cli import main
from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.models.scenes import load_scene, make_controller
from dua_mujoco.runtime.predictor import Predictor

# One hinge driven by a motor, no gravity: its inertia about the axis is constant, so the
# tracking error of a PD with the target's velocity fed forward obeys
# e'' + 2 zeta w e' + w^2 e = 0 between two random points. A second, unlimited hinge and a
# position servo ride along.
_ARM = """
<mujoco>
  <option timestep="0.002" gravity="0 0 0"/>
  <worldbody>
    <body>
      <joint name="hinge" type="hinge" axis="0 0 1" range="-1 1" armature="0.05"/>
      <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.03" mass="2"/>
    </body>
    <body pos="0 1 0">
      <joint name="free_spin" type="hinge" axis="0 0 1"/>
      <geom type="box" size="0.2 0.05 0.05" mass="1"/>
    </body>
    <body pos="0 -1 0">
      <joint name="slider" type="slide" axis="1 0 0" range="-0.3 0.3"/>
      <geom type="box" size="0.05 0.05 0.05" mass="1"/>
    </body>
  </worldbody>
  <actuator>
    <motor joint="hinge" gear="2"/>
    <motor joint="free_spin" gear="1"/>
    <position joint="slider" kp="100" ctrlrange="-0.3 0.3"/>
  </actuator>
</mujoco>
"""


def test_servo_controls_are_linear_between_random_points() -> None:
    m, d = load_scene("two_arms")
    hold = 20
    ctrl = make_controller(m, "smooth", seed=3, hold_steps=hold)
    assert ctrl.smooth is not None and not ctrl.smooth.motor.any()  # two_arms: servos only
    start = np.clip(d.ctrl.copy(), m.actuator_ctrlrange[:, 0], m.actuator_ctrlrange[:, 1])
    u = []
    for _ in range(10 * hold):
        ctrl(m, d)
        u.append(d.ctrl.copy())
        mujoco.mj_step(m, d)
    u = np.array(u)
    np.testing.assert_allclose(u[0], start)  # from where the actuators were
    second = u[2:] - 2 * u[1:-1] + u[:-2]  # zero inside a segment, not at its ends
    knots = np.arange(1, len(u) - 1) % hold == 0
    assert np.abs(second[~knots]).max() < 1e-12
    assert np.abs(second[knots]).min(axis=1).max() > 1e-6  # each knot turns some control
    lo, hi = m.actuator_ctrlrange[:, 0], m.actuator_ctrlrange[:, 1]
    assert np.all((u >= lo - 1e-12) & (u <= hi + 1e-12))
    # The points are each actuator's own: spread over its range.
    points = u[::hold]
    assert np.all(points.max(axis=0) - points.min(axis=0) > 0.3 * (hi - lo))


def test_motors_are_critically_damped_at_one_hertz() -> None:
    m = mujoco.MjModel.from_xml_string(_ARM)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    hold = 400
    ctrl = make_controller(m, "smooth", seed=0, hold_steps=hold)
    drive = ctrl.smooth
    assert drive is not None
    np.testing.assert_array_equal(drive.motor, [True, True, False])
    w = 2 * math.pi * 1.0
    ts = float(m.opt.timestep)
    # The hinge's inertia about its axis: the capsule's, plus the armature.
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    inertia = full[0, 0]
    errors, targets = [], []
    for k in range(3 * hold):
        q, qd = d.qpos[0], d.qvel[0]
        ctrl(m, d)
        target, rate = drive.target()
        targets.append(target.copy())
        # The torque is gear * ctrl = I (w^2 e + 2 w e').
        expect = inertia * (w * w * (target[0] - q) + 2 * w * (rate[0] / ts - qd)) / 2.0
        assert d.ctrl[0] == pytest.approx(expect, rel=1e-9, abs=1e-12), k
        mujoco.mj_step(m, d)
        errors.append((target[0] + rate[0] - d.qpos[0], k))
    targets = np.array(targets)
    assert np.all((targets[:, 0] >= -1) & (targets[:, 0] <= 1))  # the hinge's range
    assert np.all(np.abs(targets[:, 1]) <= math.pi + 1e-12)  # unlimited: qpos0 +- pi
    assert np.all((targets[:, 2] >= -0.3) & (targets[:, 2] <= 0.3))  # the servo's ctrlrange
    # Within the second segment the error follows e(t) = (e0 + (e0' + w e0) t) exp(-w t).
    e = np.array([err for err, k in errors if hold <= k < 2 * hold])
    e0, e1 = e[0], e[1]
    de0 = (e1 - e0) / ts
    t = np.arange(e.size) * ts
    model_e = (e0 + (de0 + w * e0) * t) * np.exp(-w * t)
    scale = np.abs(e).max()
    assert scale > 1e-3  # the segment started with an error to damp
    assert np.abs(e - model_e).max() < 0.03 * scale


def test_smooth_pilot_measures_gentler_bounds_than_held_random_controls() -> None:
    """Servos snapping to held random set points make the pilot's accelerations; the same
    servos moved smoothly make smaller ones (the reason for the smooth drive)."""
    m, _ = load_scene("two_arms")
    accel = {}
    for mode in ("random", "smooth"):
        pilot = PilotOptions(steps=1500, controller=make_controller(m, mode, seed=1))
        accel[mode] = Predictor(m, pilot=pilot).bounds.accel
    moving = accel["random"] > 0
    assert np.median(accel["smooth"][moving]) < 0.5 * np.median(accel["random"][moving])


def test_run_drives_smoothly_from_the_command_line(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["run", "two_arms", "--ctrl", "smooth", "--steps", "100", "--pilot-steps", "300"]
    assert main([*argv, "--no-progress"]) == 0
    assert "onset lead p10 / median / min" in capsys.readouterr().out


@pytest.mark.parametrize("hold", [0, -3, 2.5, True])
def test_bad_hold_steps_are_refused(hold: object) -> None:
    m, _ = load_scene("two_arms")
    with pytest.raises(InvalidInputError, match="hold_steps"):
        make_controller(m, "smooth", hold_steps=hold)  # type: ignore[arg-type]
