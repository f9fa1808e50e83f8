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
from dua_mujoco.build.geom_types import GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER, GEOM_SPHERE
from dua_mujoco.exceptions import InvalidInputError, ShapeError
from dua_mujoco.runtime.flightplan import body_mask

__all__ = ["Brake", "Evade"]


class Brake:
    """A brake to rest within the actuators' limits; also drives toward a joint velocity.

    Args:
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


def planar_radius(model: mujoco.MjModel, body: int) -> float:
    """The largest horizontal distance from ``body``'s frame origin to a point of its geoms
    (spheres, cylinders and capsules by their radius, boxes by their half diagonal, others by
    their bounding sphere): the clearance an evasive failsafe counts from."""
    out = 0.0
    first = int(model.body_geomadr[body])
    for g in range(first, first + int(model.body_geomnum[body])):
        size, kind = model.geom_size[g], int(model.geom_type[g])
        if kind in (GEOM_SPHERE, GEOM_CYLINDER, GEOM_CAPSULE):
            r = float(size[0])
        elif kind == GEOM_BOX:
            r = float(np.hypot(size[0], size[1]))
        else:
            r = float(model.geom_rbound[g])
        out = max(out, float(np.hypot(*model.geom_pos[g][:2])) + r)
    return out


class Evade:
    """An evasive failsafe for a robot on two planar slide joints (a mobile base): it brakes
    while steering away from named bodies and a room's walls (docs/shield.md, "An evasive
    failsafe"; native, in the shield's rollouts: its cost is about the brake's).

    Each physics step, with ``s = max(|vx|, |vy|)`` the base's larger planar axis speed, it
    drives the planar velocity toward ``gain * s * u`` and every other DOF of the robot toward 0
    as fast as the actuators allow (:meth:`Brake.toward`): ``u`` points away from the bodies of
    ``away_from`` (each pushing by the inverse square of its clearance from its ``radius``) and the
    walls of ``room``, its larger component 1. The axis with the larger speed still brakes at its
    limit (``gain < 1``), so the base comes to rest about when the brake would have; the other
    moves it away meanwhile. At most ``still`` on both axes it is the brake (which holds the base,
    theory.md (S5)). It reads the bodies where its data has them: the shield calls it on the
    rollout's data, and in the run on the rollout's view, so it steers by the obstacles as the
    verified rollout saw them.

    Args:
        planar: the names of the two slide joints (x, y) of the base.
        away_from: the bodies to steer away from (names or fnmatch patterns).
        actuators: the robot's actuators (default: all).
        radius: each body's radius (m): a number for all, or one per body (default: each one's
            largest horizontal reach, :func:`planar_radius`).
        room: ``(xlo, xhi, ylo, yhi)``, the inner faces of axis-aligned walls around the base
            in its joints' coordinates (m), or None.
        gain: the share of the base's speed to drive away with, in [0, 1) (0: the brake).
        still: at most this speed on both axes it is the brake (m/s; the shield's rest speed).
        sideways: steer across the planar velocity (``u`` perpendicular to it, to the side away
            from the bodies and walls) instead of straight away from them: on mobile_cell it
            keeps more of the task's progress (docs/shield.md).
        time_constant: the brake's (default: one timestep).

    Raises:
        InvalidInputError: a joint that is not a slide joint of the robot, a bad value.

    Attributes:
        actuators: ``(k,)`` the robot's actuators, as its brake takes them.
        robot_bodies: ``(k,)`` the bodies of the kinematic trees they move (the brake's).
        bodies: ``(k,)`` the bodies it steers away from, ``radius`` their radii.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        *,
        planar: tuple[str, str],
        away_from: str | list[str],
        actuators: npt.ArrayLike | None = None,
        radius: float | npt.ArrayLike | None = None,
        room: npt.ArrayLike | None = None,
        gain: float = 0.9,
        still: float = 0.01,
        sideways: bool = False,
        time_constant: float | None = None,
    ) -> None:
        if not isinstance(sideways, bool):
            raise InvalidInputError(f"sideways = {sideways!r} is invalid: pass True or False.")
        if isinstance(planar, str) or len(planar) != 2:
            raise InvalidInputError(
                f"planar = {planar!r} is invalid: pass the names of the base's two slide "
                "joints, (x, y)."
            )
        acts = np.arange(model.nu) if actuators is None else np.asarray(actuators, np.int64)
        tc = float(model.opt.timestep) if time_constant is None else float(time_constant)
        dofs = []
        for name in planar:
            j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
            if j < 0:
                raise InvalidInputError(f"planar joint {name!r} is not a joint of the model.")
            dofs.append(int(model.jnt_dofadr[j]))
        bodies = np.flatnonzero(body_mask(model, away_from, what="away_from"))
        if radius is None:
            radii = np.array([planar_radius(model, int(b)) for b in bodies])
        else:
            radii = np.asarray(radius, dtype=np.float64)
            if radii.ndim != 0 and radii.shape != bodies.shape:
                raise InvalidInputError(
                    f"radius of shape {radii.shape} is invalid: away_from = {away_from!r} names "
                    f"{bodies.size} bodies; pass one number for all or one radius per body."
                )
            radii = np.broadcast_to(radii, bodies.shape).copy()
        walls = [] if room is None else _room(room)
        self.model = model
        self.args = (
            dofs[0], dofs[1], [int(b) for b in bodies], [float(r) for r in radii], walls,
            float(gain), float(still), sideways,
        )  # fmt: skip
        self.still = float(still)
        # One native brake, the Evade's own: the robot's actuators and bodies read from it.
        self.native = _core.Evade(model, acts.reshape(-1), tc, *self.args)
        self.actuators = np.asarray(self.native.actuators, dtype=np.int64)
        self.robot_bodies = np.asarray(self.native.bodies, dtype=np.int64)
        self.bodies = bodies
        self.radius = radii
        self.time_constant = tc

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """The failsafe's controls at ``data`` (the bodies where ``data`` has them): ``(nu,)``."""
        return self.native.compute(data)


def _room(room: npt.ArrayLike) -> list[float]:
    """``room`` as four walls ``[xlo, xhi, ylo, yhi]`` (their order is the native check's)."""
    walls = np.asarray(room, dtype=np.float64)
    if walls.shape != (4,):
        raise InvalidInputError(
            f"room of shape {walls.shape} is invalid: pass (xlo, xhi, ylo, yhi) or None."
        )
    return [float(w) for w in walls]
