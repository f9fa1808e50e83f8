"""The shield's default failsafe: a brake to rest within the actuators' limits, for any MJCF
whose actuators are affine (the native ``Brake`` of ``csrc/src/brake.h``, which the shield's
rollouts run too).

Each physics step it asks for the joint accelerations ``(target - qvel) / time_constant``
(``target`` 0: a brake), gravity and every bias force held: the joint force
``tau = K a + qfrc_bias - qfrc_passive`` (``K`` the inertia as the integrator sees it), clipped to
``actuatorfrcrange``, becomes actuator forces by box-bounded least squares (``mju_boxQP``) and
controls by each actuator's affine law ``f = gain * ctrl + bias``; contact forces are not
foreseen (the shield's rollouts have them). Actuators it takes: no activation dynamics,
``gaintype`` fixed or affine, ``biastype`` none or affine, no plugin; others are refused, each
named with its types (docs/shield.md; ``tests/reference_brake.py`` is the reference).
"""

from __future__ import annotations

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco import _core
from dua_mujoco.exceptions import ShapeError

__all__ = ["Brake"]


class Brake:
    """A brake to rest within the actuators' limits; also drives toward a joint velocity.

    Args:
        model: the model.
        actuators: ids of the robot's actuators (default: all of them). Every other control is
            left as ``data.ctrl`` holds it.
        time_constant: seconds over which the joint velocities would close on their target if
            the actuators were strong enough (default: one timestep, the fastest stop the
            actuators allow).

    Raises:
        InvalidInputError: an actuator is not affine (the message lists each one with its
            types), an id is out of range, or the time constant is not positive.

    Attributes:
        dofs: ``(k,)`` the DOFs braked: every DOF of the kinematic trees the actuators move.
        bodies: ``(k,)`` the bodies of those trees (the robot's bodies).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        *,
        actuators: npt.ArrayLike | None = None,
        time_constant: float | None = None,
    ) -> None:
        acts = np.arange(model.nu) if actuators is None else np.asarray(actuators, np.int64)
        tc = float(model.opt.timestep) if time_constant is None else float(time_constant)
        self.model = model
        self.native = _core.Brake(model, acts.reshape(-1), tc)
        self.actuators = np.asarray(self.native.actuators, dtype=np.int64)
        self.dofs = np.asarray(self.native.dofs, dtype=np.int64)
        self.bodies = np.asarray(self.native.bodies, dtype=np.int64)
        self.time_constant = tc

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """The brake's controls at ``data``: ``(nu,)``, the robot's actuators braking."""
        return self.native.compute(data)

    def toward(self, data: mujoco.MjData, target: npt.ArrayLike) -> np.ndarray:
        """Controls driving the robot's DOFs toward the joint velocities ``target``.

        Args:
            data: the data (its state is read, nothing is written).
            target: ``(len(dofs),)`` joint velocities, in the order of :attr:`dofs`.

        Returns:
            ``(nu,)`` controls: ``data.ctrl`` with the robot's actuators set.
        """
        goal = np.asarray(target, dtype=np.float64)
        if goal.shape != self.dofs.shape:
            raise ShapeError(f"target must have shape {self.dofs.shape}; got {goal.shape}")
        return self.native.compute(data, goal)
