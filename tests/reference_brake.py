"""The shield's brake, slowly and plainly in numpy: the reference the native brake
(``dua_mujoco/csrc/src/brake.cc``, ``dua_mujoco.shield.failsafe.Brake``) is held to.

Each physics step :class:`ReferenceBrake` chooses the robot's controls so that its joint
accelerations come as close as the actuators allow to ``(target - qvel) / time_constant``
(``target`` 0: a brake; any joint velocity: a drive toward it), gravity and every other bias
force held. With ``K`` the DOFs' inertia as the integrator sees it (``M`` plus ``h`` times the
damping it treats implicitly), the joint force wanted is

    tau = K a + qfrc_bias - qfrc_passive,        a = (target - qvel) / time_constant,

clipped to the joints' ``actuatorfrcrange``; the actuator forces ``f`` are the box-bounded
least-squares solution of ``moment^T f = tau`` in the metric ``K^-1`` (the acceleration error's
kinetic energy), each ``f`` within what its control range and force range allow, and each
control follows from the actuator's affine law ``f = gain * ctrl + bias``. Contact and other
constraint forces are not foreseen: the shield rolls the brake out with MuJoCo, which includes
them, rather than trusting this model of it.

**Actuators it takes**: no activation dynamics (``dyntype`` none), ``gaintype`` fixed or
affine, ``biastype`` none or affine, any transmission: MuJoCo's ``motor``, ``position`` and
``velocity`` (without ``timeconst``), ``intvelocity`` aside, and ``general`` with those types.
Others (filters, integrators, muscles, DC motors, PIDs, user and plugin actuators) are refused
by name: their force does not follow from this step's control.

Quantities read at the state in ``data.qpos``, ``data.qvel`` (a private ``MjData`` recomputes
the kinematics, the inertia, the transmission and the bias forces there: after ``mj_step`` the
user's ``MjData`` holds them for the state the step started from).
"""

from __future__ import annotations

from dataclasses import KW_ONLY, dataclass
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco.exceptions import InvalidInputError, ShapeError

__all__ = ["ReferenceBrake", "bounded_lstsq", "robot_trees"]

_DYN_OK = {int(mujoco.mjtDyn.mjDYN_NONE)}
_GAIN_OK = {int(mujoco.mjtGain.mjGAIN_FIXED), int(mujoco.mjtGain.mjGAIN_AFFINE)}
_BIAS_OK = {int(mujoco.mjtBias.mjBIAS_NONE), int(mujoco.mjtBias.mjBIAS_AFFINE)}


def robot_trees(model: mujoco.MjModel, actuators: npt.ArrayLike) -> np.ndarray:
    """The kinematic trees the actuators move: ``(k,)`` tree ids, sorted.

    Read from the actuators' moment arms at ``qpos0`` (a private ``MjData``).
    """
    acts = np.asarray(actuators, dtype=np.int64)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    dense = np.zeros((model.nu, model.nv))
    mujoco.mju_sparse2dense(
        dense, data.actuator_moment, data.moment_rownnz, data.moment_rowadr, data.moment_colind
    )
    dofs = np.flatnonzero(np.any(dense[acts] != 0.0, axis=0))
    return np.unique(np.asarray(model.dof_treeid)[dofs])


def bounded_lstsq(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``argmin |a x - b|`` over the box ``lo <= x <= hi`` (an active-set method: the
    subproblem on the free variables, a step to the first bound it crosses, a variable freed
    when the gradient points into the box)."""
    n = a.shape[1]
    x = np.clip(np.zeros(n), lo, hi)
    fixed = lo >= hi
    tol = 1e-12 * (1.0 + float(np.abs(b).max(initial=0.0)))
    for _ in range(4 * n + 4):
        z = x.copy()
        free = ~fixed
        if free.any():
            rhs = b - a[:, fixed] @ x[fixed]
            z[free] = np.linalg.lstsq(a[:, free], rhs, rcond=None)[0]
        inside = np.all((z[free] >= lo[free]) & (z[free] <= hi[free]))
        if inside:
            x = z
            grad = a.T @ (a @ x - b)
            wrong = fixed & (lo < hi) & (((x <= lo) & (grad < -tol)) | ((x >= hi) & (grad > tol)))
            if not wrong.any():
                return x
            fixed[int(np.argmax(np.abs(grad) * wrong))] = False
            continue
        d = z - x
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(d > 0, (hi - x) / d, np.where(d < 0, (lo - x) / d, np.inf))
        step = np.where(free, np.clip(step, 0.0, 1.0), np.inf)
        j = int(np.argmin(step))
        x = np.clip(x + step[j] * d, lo, hi)
        x[j] = hi[j] if d[j] > 0 else lo[j]
        fixed[j] = True
    return x


@dataclass
class ReferenceBrake:
    """The numpy reference of ``dua_mujoco.shield.failsafe.Brake``, made and called as that one
    is: the same arguments and defaults (``actuators`` all, ``time_constant`` one timestep), the
    same ``dofs`` and ``bodies``, ``brake(model, data)`` and ``brake.toward(data, target)``.
    An actuator it cannot model, or a time constant that is not positive, is refused
    (``InvalidInputError``; the wording of the native brake's messages is its own)."""

    model: mujoco.MjModel
    _: KW_ONLY
    actuators: Any = None
    time_constant: float | None = None

    def __post_init__(self) -> None:
        model = self.model
        nu = model.nu
        acts = np.arange(nu) if self.actuators is None else np.asarray(self.actuators, np.int64)
        if acts.ndim != 1 or acts.size == 0 or not (acts.min() >= 0 and acts.max() < nu):
            raise InvalidInputError(f"actuators: ids in [0, {nu}) expected, not {acts}")
        bad = [
            model.actuator(int(i)).name or str(i)
            for i in acts
            if int(model.actuator_dyntype[i]) not in _DYN_OK
            or int(model.actuator_gaintype[i]) not in _GAIN_OK
            or int(model.actuator_biastype[i]) not in _BIAS_OK
            or int(model.actuator_plugin[i]) >= 0
        ]
        if bad:
            raise InvalidInputError(f"the reference brake models affine actuators only, not {bad}")
        h = float(model.opt.timestep)
        tc = h if self.time_constant is None else float(self.time_constant)
        if not (np.isfinite(tc) and tc > 0.0):
            raise InvalidInputError(f"time_constant: a positive number of seconds, not {tc}")
        self.actuators = acts
        self.time_constant = tc
        trees = robot_trees(model, acts)
        self.dofs = np.flatnonzero(np.isin(np.asarray(model.dof_treeid), trees))
        self.bodies = np.flatnonzero(np.isin(np.asarray(model.body_treeid), trees))
        self._scratch = mujoco.MjData(model)
        self._moment = np.zeros((model.nu, model.nv))
        self._mass = np.zeros((model.nv, model.nv))
        self._implicit = self._implicit_damping(model)
        # A DOF's joint force is clipped when its joint has an actuatorfrcrange.
        jnt = np.asarray(model.dof_jntid)[self.dofs]
        limited = np.asarray(model.jnt_actfrclimited, dtype=bool)[jnt]
        rng = np.asarray(model.jnt_actfrcrange)[jnt]
        self._tau_lo = np.where(limited, rng[:, 0], -np.inf)
        self._tau_hi = np.where(limited, rng[:, 1], np.inf)

    def _implicit_damping(self, model: mujoco.MjModel) -> str:
        integrator = int(model.opt.integrator)
        if integrator == int(mujoco.mjtIntegrator.mjINT_EULER):
            off = int(model.opt.disableflags) & int(mujoco.mjtDisableBit.mjDSBL_EULERDAMP)
            return "none" if off else "dof"
        if integrator in (
            int(mujoco.mjtIntegrator.mjINT_IMPLICIT),
            int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST),
        ):
            return "actuator"
        return "none"

    def _forward(self, data: mujoco.MjData) -> mujoco.MjData:
        """The scratch data at ``data``'s state, with what the brake reads computed."""
        m, s = self.model, self._scratch
        s.qpos[:] = data.qpos
        s.qvel[:] = data.qvel
        s.ctrl[:] = data.ctrl
        if m.na:
            s.act[:] = data.act
        if m.nmocap:
            s.mocap_pos[:] = data.mocap_pos
            s.mocap_quat[:] = data.mocap_quat
        s.time = data.time
        mujoco.mj_kinematics(m, s)
        mujoco.mj_comPos(m, s)
        mujoco.mj_tendon(m, s)
        mujoco.mj_makeM(m, s)
        mujoco.mj_transmission(m, s)
        mujoco.mj_comVel(m, s)
        mujoco.mj_passive(m, s)
        mujoco.mj_rne(m, s, 0, s.qfrc_bias)
        return s

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """The brake's controls at ``data``: ``(nu,)``, the robot's actuators braking."""
        return self.toward(data, np.zeros(self.dofs.size))

    def toward(self, data: mujoco.MjData, target: npt.ArrayLike) -> np.ndarray:
        """``(nu,)`` controls: ``data.ctrl`` (read, not written) with the robot's actuators
        driving its DOFs toward the joint velocities ``target``, ``(len(dofs),)``."""
        m = self.model
        goal = np.asarray(target, dtype=np.float64)
        if goal.shape != self.dofs.shape:
            raise ShapeError(f"target must have shape {self.dofs.shape}; got {goal.shape}")
        s = self._forward(data)
        acts, dofs = self.actuators, self.dofs
        mujoco.mju_sparse2dense(
            self._moment, s.actuator_moment, s.moment_rownnz, s.moment_rowadr, s.moment_colind
        )
        mujoco.mj_fullM(m, s, self._mass)
        moment = self._moment[:, dofs]
        inertia = self._mass[np.ix_(dofs, dofs)]
        h = float(m.opt.timestep)
        if self._implicit == "dof":
            inertia = inertia + h * np.diag(np.asarray(m.dof_damping)[dofs])
        elif self._implicit == "actuator":
            # -d(force)/d(qvel) of every actuator (velocity terms of gain and bias), and the
            # DOF damping: what implicit and implicitfast integrate implicitly.
            slope = -(m.actuator_biasprm[:, 2] * (m.actuator_biastype == 1))
            slope -= m.actuator_gainprm[:, 2] * (m.actuator_gaintype == 1) * s.ctrl
            inertia = inertia + h * (moment.T * slope) @ moment
            inertia = inertia + h * np.diag(np.asarray(m.dof_damping)[dofs])
        accel = (goal - s.qvel[dofs]) / self.time_constant
        tau = inertia @ accel + s.qfrc_bias[dofs] - s.qfrc_passive[dofs]
        tau = np.clip(tau, self._tau_lo, self._tau_hi)

        # mj_fwdVelocity would compute the actuator velocities; mj_transmission does not.
        length, velocity = s.actuator_length[acts], self._moment[acts] @ s.qvel
        gain = m.actuator_gainprm[acts, 0].copy()
        affine = np.asarray(m.actuator_gaintype[acts]) == int(mujoco.mjtGain.mjGAIN_AFFINE)
        gain[affine] += (
            m.actuator_gainprm[acts, 1] * length + m.actuator_gainprm[acts, 2] * velocity
        )[affine]
        bias = m.actuator_biasprm[acts, 0] + m.actuator_biasprm[acts, 1] * length
        bias = bias + m.actuator_biasprm[acts, 2] * velocity
        bias = np.where(np.asarray(m.actuator_biastype[acts]) == 0, 0.0, bias)
        clamp = not (int(m.opt.disableflags) & int(mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL))
        climited = clamp & np.asarray(m.actuator_ctrllimited[acts], dtype=bool)
        clo = np.where(climited, m.actuator_ctrlrange[acts, 0], -np.inf)
        chi = np.where(climited, m.actuator_ctrlrange[acts, 1], np.inf)
        flimited = np.asarray(m.actuator_forcelimited[acts], dtype=bool)
        flo = np.where(flimited, m.actuator_forcerange[acts, 0], -np.inf)
        fhi = np.where(flimited, m.actuator_forcerange[acts, 1], np.inf)
        with np.errstate(invalid="ignore"):
            ends = np.stack([gain * clo + bias, gain * chi + bias])
        ends = np.where(np.isnan(ends), bias, ends)  # gain 0 with an infinite control
        lo = np.clip(ends.min(axis=0), flo, fhi)
        hi = np.clip(ends.max(axis=0), flo, fhi)

        # Least squares in the metric K^-1: with K = L L^T, |L^-1 (moment^T f - tau)|.
        chol = np.linalg.cholesky(inertia)
        a = np.linalg.solve(chol, moment[acts].T)
        b = np.linalg.solve(chol, tau)
        force = bounded_lstsq(a, b, lo, hi)
        ctrl = np.array(data.ctrl, dtype=np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            wanted = np.where(gain != 0.0, (force - bias) / gain, data.ctrl[acts])
        ctrl[acts] = np.clip(wanted, clo, chi)
        return ctrl
