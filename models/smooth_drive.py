"""A smooth scene driver: controls that move like a robot's commands, not held random steps.

Each actuator follows a *target* that is linear between random points drawn ``hold_steps``
physics steps apart (the first segment starts where the actuator is: its control, or its
joint's position):

- an actuator whose control is a set point (position and velocity servos, and every actuator
  that is not a plain motor on one hinge or slide joint) gets the target as its control, drawn
  in its ``ctrlrange`` ([-1, 1] if unlimited);
- a motor (no bias, no dynamics, fixed gain) on a hinge or slide joint gets a PD torque toward a
  joint target drawn in the joint's range (``qpos0 +- pi``, or +- 0.5 m, if unlimited),
  critically damped at ``frequency`` (1 Hz) about the joint's own inertia (the diagonal of the
  mass matrix, armature included, at the current state): ``kp = I w^2``, ``kd = 2 I w``, with the
  target's velocity fed forward, clipped to the control range.

Held random controls (``make_controller(..., "random")``) make servos snap to new set points:
accelerations of hundreds to thousands of m/s^2 that any bound must then cover. This driver is
what the warning-time benchmarks drive robots with (benchmarks/horizon.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

__all__ = ["SmoothDrive", "smooth_drive"]

_UNLIMITED_SLIDE = 0.5  # m either side of qpos0: the target range of an unlimited slide joint


@dataclass
class SmoothDrive:
    """Targets linear between random points and the controls that follow them (module doc).

    Attributes:
        hold_steps: Physics steps between two random points.
        low: ``(nu,)`` lower end of each actuator's target range (control or joint position).
        high: ``(nu,)`` upper end.
        motor: ``(nu,)`` bool, actuators driven as PD motors on their joint.
        qpos_adr: ``(nu,)`` the joint's ``qpos`` address (motors; 0 otherwise).
        dof_adr: ``(nu,)`` the joint's DOF (motors; 0 otherwise).
        gear: ``(nu,)`` the actuator's gear (motors; 1 otherwise).
        ctrl_low: ``(nu,)`` control range (-inf where unlimited).
        ctrl_high: ``(nu,)`` control range (+inf where unlimited).
        frequency: Natural frequency of the motors' PD (Hz).
        rng: Source of the random points.
    """

    hold_steps: int
    low: np.ndarray
    high: np.ndarray
    motor: np.ndarray
    qpos_adr: np.ndarray
    dof_adr: np.ndarray
    gear: np.ndarray
    ctrl_low: np.ndarray
    ctrl_high: np.ndarray
    frequency: float
    rng: np.random.Generator
    _step: int = field(default=0, init=False)
    _from: np.ndarray = field(init=False)
    _to: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self._from = np.zeros_like(self.low)
        self._to = np.zeros_like(self.low)

    @property
    def omega(self) -> float:
        """The motors' natural frequency (rad/s)."""
        return 2.0 * math.pi * self.frequency

    def target(self) -> tuple[np.ndarray, np.ndarray]:
        """The targets of the coming step, ``(nu,)``, and their rate per physics step."""
        frac = (self._step - 1) % self.hold_steps / self.hold_steps
        rate = (self._to - self._from) / self.hold_steps
        return self._from + (self._to - self._from) * frac, rate

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """The controls of the coming step, ``(nu,)`` (the caller writes them to ``data``)."""
        if self._step == 0:
            start = np.where(self.motor, data.qpos[self.qpos_adr], data.ctrl)
            self._to = np.clip(start, self.low, self.high)
        if self._step % self.hold_steps == 0:
            self._from = self._to
            self._to = self.rng.uniform(self.low, self.high)
        self._step += 1
        target, rate = self.target()
        if not self.motor.any():
            return target
        m = self.motor
        # The diagonal of M (armature included): the last entry of its row in MuJoCo's CSR.
        dof = self.dof_adr[m]
        inertia = data.M[model.M_rowadr[dof] + model.M_rownnz[dof] - 1]
        w = self.omega
        error = target[m] - data.qpos[self.qpos_adr[m]]
        error_rate = rate[m] / float(model.opt.timestep) - data.qvel[dof]
        torque = inertia * (w * w * error + 2.0 * w * error_rate)
        out = target.copy()
        out[m] = np.clip(torque / self.gear[m], self.ctrl_low[m], self.ctrl_high[m])
        return out


def smooth_drive(
    model: mujoco.MjModel,
    *,
    hold_steps: int,
    rng: np.random.Generator,
    frequency: float = 1.0,
) -> SmoothDrive:
    """The :class:`SmoothDrive` of ``model`` (which actuators are motors, their joints, ranges)."""
    nu = model.nu
    limited = model.actuator_ctrllimited.astype(bool)
    ctrl_range = np.asarray(model.actuator_ctrlrange, dtype=float).reshape(nu, 2)
    low = np.where(limited, ctrl_range[:, 0], -1.0)
    high = np.where(limited, ctrl_range[:, 1], 1.0)
    trn = np.asarray(model.actuator_trntype)
    joint = np.asarray(model.actuator_trnid)[:, 0]
    # A motor's torque is gear times gain times its control.
    gear = np.asarray(model.actuator_gear)[:, 0] * np.asarray(model.actuator_gainprm)[:, 0]
    jtype = np.asarray(model.jnt_type)
    one_dof = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    motor = (
        (trn == int(mujoco.mjtTrn.mjTRN_JOINT))
        & (np.asarray(model.actuator_biastype) == int(mujoco.mjtBias.mjBIAS_NONE))
        & (np.asarray(model.actuator_dyntype) == int(mujoco.mjtDyn.mjDYN_NONE))
        & (np.asarray(model.actuator_gaintype) == int(mujoco.mjtGain.mjGAIN_FIXED))
        & (gear != 0.0)
    )
    motor &= np.isin(jtype[np.where(motor, joint, 0)], one_dof)
    qpos_adr = np.where(motor, np.asarray(model.jnt_qposadr)[np.where(motor, joint, 0)], 0)
    dof_adr = np.where(motor, np.asarray(model.jnt_dofadr)[np.where(motor, joint, 0)], 0)
    for a in np.flatnonzero(motor):
        j = int(joint[a])
        if model.jnt_limited[j]:
            low[a], high[a] = (float(x) for x in model.jnt_range[j])
        else:
            q0 = float(model.qpos0[qpos_adr[a]])
            half = math.pi if jtype[j] == int(mujoco.mjtJoint.mjJNT_HINGE) else _UNLIMITED_SLIDE
            low[a], high[a] = q0 - half, q0 + half
    return SmoothDrive(
        hold_steps=int(hold_steps),
        low=low.astype(float),
        high=high.astype(float),
        motor=motor,
        qpos_adr=qpos_adr.astype(np.int64),
        dof_adr=dof_adr.astype(np.int64),
        gear=np.where(motor, gear, 1.0),
        ctrl_low=np.where(limited, ctrl_range[:, 0], -np.inf),
        ctrl_high=np.where(limited, ctrl_range[:, 1], np.inf),
        frequency=float(frequency),
        rng=rng,
    )
