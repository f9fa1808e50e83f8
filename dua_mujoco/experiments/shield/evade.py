"""An evasive failsafe for ``mobile_cell``'s base: brake to rest, steering away from the
obstacles as the verified rollout saw them (docs/shield.md, "An evasive failsafe").

:func:`native` builds the library's :class:`~dua_mujoco.shield.failsafe.Evade` (C++, in the
shield's rollouts) for the scene. The same law as a Python user policy
(``Shield(failsafe=policy)``: called at every rolled step, the cost the native one removes) is
the reference ``tests/reference_evade.py``: the tests hold the native one to it bit for bit, and
``benchmarks/shield_evade.py`` runs both (its ``pyevade`` layer).

The shield verifies a user's failsafe as it verifies the brake (theory.md, section 10): it rolls
the failsafe out to rest on the rollout's data, whose mocap bodies stand where the state read put
them, and checks the run against that rollout at every step ((S2)). In the run it calls the
failsafe on the rollout's view (``Shield.view``: the plan's knot with the robot's coordinates the
run's), so a failsafe that reads the obstacles from the data it is given steers by them as the
rollout did; one that read where they are *now* would leave its rollout at once (a plan break,
caught: ``tests/test_shield_evade.py``).

The law: with ``s = max(|vx|, |vy|)`` (the base's planar velocity, each axis its own actuator
and force limit), drive the planar velocity toward ``gain * s * u`` (``u`` away from the
obstacles and walls, its larger component 1) and the yaw rate toward 0, as fast as the actuators
allow (:meth:`~dua_mujoco.shield.failsafe.Brake.toward`). The axis with the largest speed brakes
at its limit (its target is smaller, ``gain < 1``), so ``s`` falls as under the brake and the
base comes to rest about when the brake would have; an axis with speed to spare (the one across
an axis-aligned drive) moves the base away meanwhile. At (near) rest it is the brake, which holds
the base ((S5)).
"""

from __future__ import annotations

import mujoco

from dua_mujoco.experiments.shield.episodes import SceneSetup
from dua_mujoco.shield.failsafe import Evade

__all__ = ["native", "room_of"]


def room_of(model: mujoco.MjModel) -> tuple[float, float, float, float]:
    """``mobile_cell``'s room: the inner faces of its walls ``wall_e`` and ``wall_n`` (the room
    is symmetric about the origin), as ``(xlo, xhi, ylo, yhi)``."""
    wx, wy = (
        float(model.geom(name).pos[axis] - model.geom(name).size[axis])
        for name, axis in (("wall_e", 0), ("wall_n", 1))
    )
    return (-wx, wx, -wy, wy)


def _obstacles(setup: SceneSetup) -> list[int]:
    model = setup.model
    return [int(b) for b in setup.protected if int(model.body_mocapid[b]) >= 0]


def native(setup: SceneSetup, *, gain: float = 0.9, sideways: bool = False) -> Evade:
    """The library's evasive failsafe for ``mobile_cell``: its mocap walkers and carts, its
    walls, the base's slide joints."""
    model = setup.model
    names = [model.body(b).name for b in _obstacles(setup)]
    return Evade(
        model,
        planar=("base_x", "base_y"),
        away_from=names,
        actuators=setup.brake.actuators,
        room=room_of(model),
        gain=gain,
        sideways=sideways,
    )
