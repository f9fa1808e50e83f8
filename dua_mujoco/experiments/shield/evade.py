"""An evasive failsafe for ``mobile_cell``'s base: brake to rest, steering away from the
obstacles as they stood when the stop was verified (docs/shield.md, "An evasive failsafe").

The shield verifies a user's failsafe as it verifies the brake (theory.md, section 10): it rolls
the failsafe out to rest on the rollout's data, whose mocap bodies stand where the state read put
them, and then checks the run against that rollout at every step ((S2)). A policy that read the
obstacles' *current* positions in the run would leave its rollout (they have moved since), a
plan break at once. So this one reads them in the rollouts only, and keys what it read by the
robot's state there (its joint positions and velocities: a rollout's knot, which the run repeats
bit for bit); in the run it looks that state up and steers by the same positions. A state it
never rolled out (``misses``) gets the brake, and the shield's check says whether that left the
plan.

The law: with ``s = max(|vx|, |vy|)`` (the base's planar velocity, each axis its own actuator
and force limit), drive the planar velocity toward ``gain * s * u`` (``u`` away from the
obstacles, its larger component 1) and the yaw rate toward 0, as fast as the actuators allow
(:meth:`~dua_mujoco.shield.failsafe.Brake.toward`). The axis with the largest speed brakes at
its limit (its target is smaller, ``gain < 1``), so ``s`` falls as under the brake and the base
comes to rest about when the brake would have; an axis with speed to spare (the one across an
axis-aligned drive) moves the base away meanwhile. At (near) rest it is the brake, which holds
the base ((S5)).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco.experiments.shield.episodes import SceneSetup
from dua_mujoco.shield.failsafe import Brake

__all__ = ["Evade"]


class Evade:
    """The evasive failsafe policy, ``policy(model, data) -> (nu,)`` (``Shield(failsafe=...)``).

    Args:
        model: the run's model (the shield's rollouts call with their own copy).
        brake: the robot's brake (its ``dofs``: the base's x, y and yaw DOFs in that order).
        obstacles: ``(k,)`` ids of the mocap bodies to steer away from.
        radius: ``(k,)`` their radii (m; the clearance counts from their surface).
        room: ``(2,)`` the inner half-extents of the walls around the origin (m): the walls
            repel as the obstacles do.
        gain: the share of the base's speed to drive away with (0: the brake).
        still: at most this planar speed on both axes (m/s) the policy is the brake: the
            shield's rest speed (1 cm/s), so that at every knot at rest, which its rollouts end
            at without calling the failsafe, and past it, the run needs nothing they saw.
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
    ) -> None:
        if not 0.0 <= gain < 1.0:
            raise ValueError(f"gain = {gain} is invalid: pass 0 <= gain < 1 (1 never stops)")
        self.model = model
        self.brake = brake
        self.mocap = np.asarray(model.body_mocapid)[np.asarray(obstacles, dtype=np.int64)]
        self.radius = [float(r) for r in np.asarray(radius, dtype=np.float64).reshape(-1)]
        self.room = tuple(float(r) for r in np.asarray(room, dtype=np.float64).reshape(2))
        self.gain, self.still = gain, still
        self.q = np.asarray([model.jnt_qposadr[model.dof_jntid[i]] for i in brake.dofs])
        self.v = np.asarray(brake.dofs)
        self.seen: dict[bytes, tuple[float, list[list[float]]]] = {}
        self.misses = 0

    @classmethod
    def of(cls, setup: SceneSetup, *, gain: float = 0.9) -> Evade:
        """The policy for ``mobile_cell``'s setup: its mocap walkers and carts (cylinders), and
        the inner faces of its walls ``wall_e`` and ``wall_n`` (the room is symmetric)."""
        model = setup.model
        obstacles = [int(b) for b in setup.protected if int(model.body_mocapid[b]) >= 0]
        radius = [float(model.geom_size[model.body_geomadr[b], 0]) for b in obstacles]
        room = [
            float(model.geom(name).pos[axis] - model.geom(name).size[axis])
            for name, axis in (("wall_e", 0), ("wall_n", 1))
        ]
        return cls(model, setup.brake, obstacles, radius, room, gain=gain)

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """The failsafe's controls at ``data``: ``(nu,)``."""
        vel = data.qvel[self.v]
        vx, vy = float(vel[0]), float(vel[1])
        s = max(abs(vx), abs(vy))
        if s <= self.still:
            return self.brake(model, data)
        pos = data.qpos[self.q]
        key = pos.tobytes() + vel.tobytes()
        if model is self.model:  # the run: the obstacles as the rollout saw them
            hit = self.seen.get(key)
            if hit is None:
                self.misses += 1
                return self.brake(model, data)
            where = hit[1]
        else:  # a rollout: its mocap bodies stand where the state read put them
            where = data.mocap_pos[self.mocap, :2].tolist()
            self.seen[key] = (float(data.time), where)
            if len(self.seen) > 200_000:  # plans last at most a period and a stop
                old = float(data.time) - 2.0
                self.seen = {k: v for k, v in self.seen.items() if v[0] >= old}
        ux, uy = self.away(float(pos[0]), float(pos[1]), where)
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
        (wx, wy) = self.room
        px += 1.0 / max(x + wx, 0.05) ** 2 - 1.0 / max(wx - x, 0.05) ** 2
        py += 1.0 / max(y + wy, 0.05) ** 2 - 1.0 / max(wy - y, 0.05) ** 2
        top = max(abs(px), abs(py))
        return (px / top, py / top) if top > 0.0 else (0.0, 0.0)
