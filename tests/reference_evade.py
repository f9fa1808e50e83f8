"""The evasive failsafe's law as a Python policy: the reference the native
:class:`~dua_mujoco.shield.failsafe.Evade` (``csrc/src/brake.h``) is held to, bit for bit
(``tests/test_shield_evade.py``), and the cost the native one removes
(``benchmarks/shield_evade.py``'s ``pyevade`` layer: ``Shield(failsafe=policy)`` calls it at
every rolled step).

It shares the brake with the library (``Brake.native.compute``: the box-bounded least squares
toward a velocity, held to ``tests/reference_brake.py``), and nothing else: the direction away
from the obstacles and walls, the choice of target and the switch to the brake at rest are
written here again, in plain floats, from docs/shield.md ("An evasive failsafe").

The law: with ``s = max(|vx|, |vy|)`` (the base's planar velocity, each axis its own actuator
and force limit), drive the planar velocity toward ``gain * s * u`` (``u`` away from the
obstacles and walls, its larger component 1) and the yaw rate toward 0, as fast as the actuators
allow. At most ``still`` on both axes it is the brake, which holds the base ((S5)).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco.experiments.shield.episodes import SceneSetup
from dua_mujoco.experiments.shield.evade import room_of
from dua_mujoco.shield.failsafe import Brake

__all__ = ["EvadePolicy"]


class EvadePolicy:
    """The law as a Python policy, ``policy(model, data) -> (nu,)``: it reads the obstacles from
    the data it is given (the rollout's, or the view in the run).

    Args:
        model: the run's model.
        brake: the robot's brake (its ``dofs``: the base's x, y and yaw DOFs in that order).
        obstacles: ``(k,)`` ids of the mocap bodies to steer away from.
        radius: ``(k,)`` their radii (m; the clearance counts from their surface).
        room: ``(xlo, xhi, ylo, yhi)``, the walls' inner faces (m).
        gain: the share of the base's speed to drive away with (0: the brake).
        still: at most this planar speed on both axes (m/s) the policy is the brake.
        sideways: steer across the velocity, to the side away from the obstacles.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        brake: Brake,
        obstacles: npt.ArrayLike,
        radius: npt.ArrayLike,
        room: npt.ArrayLike,
        *,
        gain: float = 0.9,
        still: float = 0.01,
        sideways: bool = False,
    ) -> None:
        if not 0.0 <= gain < 1.0:
            raise ValueError(f"gain = {gain} is invalid: pass 0 <= gain < 1 (1 never stops)")
        self.model = model
        self.brake = brake
        self.mocap = np.asarray(model.body_mocapid)[np.asarray(obstacles, dtype=np.int64)]
        self.radius = [float(r) for r in np.asarray(radius, dtype=np.float64).reshape(-1)]
        self.room = tuple(float(r) for r in np.asarray(room, dtype=np.float64).reshape(4))
        self.gain, self.still, self.sideways = gain, still, sideways
        self.q = np.asarray([model.jnt_qposadr[model.dof_jntid[i]] for i in brake.dofs])
        self.v = np.asarray(brake.dofs)

    @classmethod
    def of(cls, setup: SceneSetup, *, gain: float = 0.9, sideways: bool = False) -> EvadePolicy:
        """The policy for ``mobile_cell``'s setup: its mocap walkers and carts (cylinders), and
        its walls (as ``dua_mujoco.experiments.shield.evade.native`` builds the native one)."""
        model = setup.model
        obstacles = [int(b) for b in setup.protected if int(model.body_mocapid[b]) >= 0]
        radius = [float(model.geom_size[model.body_geomadr[b], 0]) for b in obstacles]
        return cls(
            model, setup.brake, obstacles, radius, room_of(model), gain=gain, sideways=sideways
        )

    def where(self, data: mujoco.MjData) -> list[list[float]]:
        """The obstacles' planar positions the policy steers by: ``data``'s."""
        return data.mocap_pos[self.mocap, :2].tolist()

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """The failsafe's controls at ``data``: ``(nu,)``."""
        vel = data.qvel[self.v]
        vx, vy = float(vel[0]), float(vel[1])
        s = max(abs(vx), abs(vy))
        if s <= self.still:
            return self.brake(model, data)
        pos = data.qpos[self.q]
        ux, uy = self.away(float(pos[0]), float(pos[1]), self.where(data))
        if self.sideways:  # across the velocity, to the side (ux, uy) points to
            norm = math.sqrt(vx * vx + vy * vy)
            qx, qy = -vy / norm, vx / norm
            if qx * ux + qy * uy < 0.0:
                qx, qy = -qx, -qy
            top = max(abs(qx), abs(qy))
            ux, uy = qx / top, qy / top
        target = np.zeros(self.v.size)
        target[0], target[1] = self.gain * s * ux, self.gain * s * uy
        return self.brake.native.compute(data, target)

    def away(self, x: float, y: float, where: list[list[float]]) -> tuple[float, float]:
        """The direction away from the obstacles at ``where`` (``k`` points ``[x, y]``) and the
        walls from ``(x, y)``, each pushing by the inverse square of its clearance, its larger
        component 1 (plain floats: a handful of obstacles, called at every rolled step)."""
        px = py = 0.0
        for (ox, oy), r in zip(where, self.radius, strict=True):
            gx, gy = x - ox, y - oy
            dist = math.sqrt(gx * gx + gy * gy)
            if dist == 0.0:
                continue
            clear = max(dist - r, 0.05)
            w = 1.0 / (dist * clear * clear)
            px, py = px + gx * w, py + gy * w
        xlo, xhi, ylo, yhi = self.room
        w, e = max(x - xlo, 0.05), max(xhi - x, 0.05)
        s, n = max(y - ylo, 0.05), max(yhi - y, 0.05)
        px += 1.0 / (w * w) - 1.0 / (e * e)
        py += 1.0 / (s * s) - 1.0 / (n * n)
        top = max(abs(px), abs(py))
        return (px / top, py / top) if top > 0.0 else (0.0, 0.0)
