"""Scripted people and carts for the shield's scenes: mocap bodies within declared bounds.

:class:`PersonScript` moves the person of ``person_cell``: it walks in from a few metres away,
stands at the cell, reaches into the arm's workspace, withdraws and walks away. :class:`Crowd`
moves the obstacles of ``mobile_cell`` between random waypoints. Every move is a
:class:`~dua_mujoco.models.motion.Move` whose caps are drawn below the body's declared bounds,
and the moves of the two bodies of the person never overlap in time (the arm rides on the body
while it walks, and reaches only while it stands), so each mocap body's speed and acceleration
stay within its own bounds at every instant, hence at every physics step.

Declared bounds (speed m/s, acceleration m/s^2), after ISO 13855: 1.6 m/s for a walking person,
2.0 m/s for a hand reaching in.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from dua_mujoco.models.motion import Timeline

__all__ = [
    "CROWD_BOUNDS",
    "PERSON_BOUNDS",
    "Bound",
    "Crowd",
    "PersonScript",
    "ScriptedBodies",
    "declared_bounds",
]


@dataclass(frozen=True)
class Bound:
    """A declared bound on every point of a body: speed (m/s), acceleration (m/s^2), and the
    velocity uncertainty of a step (m/s; None: ``accel * h / 2``, docs/discrete-time.md)."""

    speed: float
    accel: float
    delta: float | None = None


PERSON_BOUNDS = {"person": Bound(1.6, 2.0), "person_arm": Bound(2.0, 5.0)}
"""The person's declared bounds: the walking body, and the arm that reaches in."""

CROWD_BOUNDS = {"walker": Bound(1.6, 2.0), "cart": Bound(1.0, 1.0)}
"""``mobile_cell``'s obstacles by kind: people (``walker*``) and carts (``cart*``)."""

_ARM_REST = np.array([0.15, -0.2, 1.4])
"""The arm's frame (the shoulder) relative to the body's frame, at rest."""
_HAND_TIP = np.array([-0.55, 0.0, -0.375])
"""The hand's tip in the arm's frame (``person_arm``'s last capsule ends there)."""


class ScriptedBodies:
    """Mocap bodies following :class:`~dua_mujoco.models.motion.Timeline`s, one a body.

    Subclasses fill ``self.timelines`` (body name -> timeline of its frame's position; a
    timeline may be ``base + offset`` through ``self.riders``).
    """

    def __init__(self, model: mujoco.MjModel) -> None:
        self.timelines: dict[str, Timeline] = {}
        self.riders: dict[str, str] = {}
        """Body name -> the body it rides on: its position is the sum of both timelines."""
        self._model = model
        self._ids: dict[str, int] | None = None

    def mocap_ids(self) -> dict[str, int]:
        """Mocap id of each scripted body."""
        out = {}
        for name in self.timelines:
            bid = mujoco.mj_name2id(self._model, int(mujoco.mjtObj.mjOBJ_BODY), name)
            out[name] = int(self._model.body_mocapid[bid])
        return out

    def state(self, name: str, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity of the body's frame at time ``t``."""
        pos, vel = self.timelines[name].state(t)
        base = self.riders.get(name)
        if base is not None:
            p, v = self.timelines[base].state(t)
            pos, vel = pos + p, vel + v
        return pos, vel

    def apply(self, data: mujoco.MjData) -> None:
        """Write every scripted body's pose at ``data.time`` into ``data.mocap_pos``: call it
        before each ``mj_step`` (the step then reads the pose of the time it starts from)."""
        if self._ids is None:
            self._ids = self.mocap_ids()
        for name, mid in self._ids.items():
            data.mocap_pos[mid] = self.state(name, float(data.time))[0]

    @property
    def t_end(self) -> float:
        """When the last move ends."""
        return max(tl.t_end for tl in self.timelines.values())


class PersonScript(ScriptedBodies):
    """One visit of a person to the cell of ``person_cell``, drawn from ``seed``.

    Drawn per seed: when the walk starts (0-0.6 s), where from (3-4 m in front, 1.5 m to either
    side), where the person stands (1.05-1.2 m from the table's centre, within 0.5 m of its
    axis), the point in the arm's workspace the hand reaches to, the holds, and the caps of
    each move (walking 1.0-1.6 m/s and 1.0-2.0 m/s^2, reaching 1.0-2.0 m/s and 2.5-5.0 m/s^2),
    all within :data:`PERSON_BOUNDS`.

    Args:
        model: ``person_cell``'s model.
        seed: the episode's seed.
    """

    def __init__(self, model: mujoco.MjModel, seed: int) -> None:
        super().__init__(model)
        rng = np.random.default_rng([seed, 13855])
        walk_v, walk_a = rng.uniform(1.0, 1.6), rng.uniform(1.0, 2.0)
        reach_v, reach_a = rng.uniform(1.0, 2.0), rng.uniform(2.5, 5.0)
        start = np.array([rng.uniform(3.0, 4.0), rng.uniform(-1.5, 1.5), 0.0])
        stand = np.array([rng.uniform(1.05, 1.2), rng.uniform(-0.5, 0.5), 0.0])
        leave = np.array([rng.uniform(3.0, 4.0), rng.uniform(-1.5, 1.5), 0.0])
        reach_to = np.array(
            [rng.uniform(0.1, 0.5), rng.uniform(-0.45, 0.45), rng.uniform(0.85, 1.15)]
        )
        body = Timeline(start)
        arm = Timeline(_ARM_REST)
        t = body.go(stand, at=rng.uniform(0.0, 0.6), vmax=walk_v, amax=walk_a)
        # The hand's tip goes to reach_to: the arm's frame, relative to the body, goes to
        reach = reach_to - stand - _HAND_TIP
        t = arm.go(reach, at=t + rng.uniform(0.1, 0.5), vmax=reach_v, amax=reach_a)
        t = arm.go(_ARM_REST, at=t + rng.uniform(0.3, 1.0), vmax=reach_v, amax=reach_a)
        body.go(leave, at=t + rng.uniform(0.1, 0.3), vmax=walk_v, amax=walk_a)
        self.timelines = {"person": body, "person_arm": arm}
        self.riders = {"person_arm": "person"}
        self.reach_to = reach_to
        """``(3,)`` where the hand's tip goes."""


class Crowd(ScriptedBodies):
    """``mobile_cell``'s obstacles, each between random waypoints of the arena, from ``seed``.

    Each obstacle holds 0-1 s, then goes to a waypoint drawn in the arena, holds 0-1 s, and so
    on until ``duration``; its caps are drawn in the upper half of its kind's bound
    (:data:`CROWD_BOUNDS`).

    Args:
        model: ``mobile_cell``'s model.
        seed: the episode's seed.
        duration: how long the script must cover (s).
        half: the arena's half extents ``(x, y)`` the waypoints are drawn in.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        seed: int,
        *,
        duration: float = 30.0,
        half: tuple[float, float] = (2.4, 1.9),
    ) -> None:
        super().__init__(model)
        rng = np.random.default_rng([seed, 4242])
        names = [
            model.body(int(b)).name for b in np.flatnonzero(np.asarray(model.body_mocapid) >= 0)
        ]
        for name in names:
            bound = CROWD_BOUNDS[_kind(name)]
            bid = mujoco.mj_name2id(model, int(mujoco.mjtObj.mjOBJ_BODY), name)
            timeline = Timeline(np.array(model.body_pos[bid]))
            t = rng.uniform(0.0, 1.0)
            z = float(model.body_pos[bid][2])
            while t < duration:
                to = np.array([rng.uniform(-half[0], half[0]), rng.uniform(-half[1], half[1]), z])
                v = rng.uniform(0.5, 1.0) * bound.speed
                a = rng.uniform(0.5, 1.0) * bound.accel
                t = timeline.go(to, at=t, vmax=v, amax=a) + rng.uniform(0.0, 1.0)
            self.timelines[name] = timeline


def _kind(name: str) -> str:
    for kind in CROWD_BOUNDS:
        if name.startswith(kind):
            return kind
    raise ValueError(f"mobile_cell's mocap body {name!r} is neither a walker* nor a cart*")


def declared_bounds(names: list[str]) -> dict[str, Bound]:
    """The declared bound of each scripted body by name (person or crowd)."""
    out = {}
    for name in names:
        out[name] = PERSON_BOUNDS[name] if name in PERSON_BOUNDS else CROWD_BOUNDS[_kind(name)]
    return out
