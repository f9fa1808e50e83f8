"""The safety shield's scenes: a robot with a task among bodies it must not move into.

=================  ==============================================================================
``person_cell``    a 6-DoF arm cycling between four fixtures while a person walks in, reaches
                   into its workspace and leaves (:class:`~dua_mujoco.models.people.PersonScript`)
``arm_pair``       two 6-DoF arms sharing a table, each cycling between its own targets (two of
                   them shared); arm A is the robot, arm B runs under its own controller
``mobile_cell``    a mobile base driving between four stations among two walkers and two carts
                   (:class:`~dua_mujoco.models.people.Crowd`)
=================  ==============================================================================

Each scene says which actuators are the robot's (``robot``), which bodies it must not move into
(``protect``, fnmatch patterns of body names: the person, the other arm, the obstacles and
walls; not the table the arm works over, not the floor under the base), the declared bounds of
the bodies nobody plans (``bounds``), its control period, and how long an episode lasts.
:meth:`ShieldScene.episode` draws an episode from a seed: the initial state, the scripted
bodies, and the task controller, a policy ``policy(model, data) -> ctrl`` that also counts the
targets reached (the progress measure: targets per minute).
"""

from __future__ import annotations

import fnmatch
from collections.abc import Callable
from dataclasses import dataclass, field

import mujoco
import numpy as np

from dua_mujoco.models import models_dir
from dua_mujoco.models.motion import Move
from dua_mujoco.models.people import Bound, Crowd, PersonScript, ScriptedBodies, declared_bounds

__all__ = [
    "ARM_B_BOUNDS",
    "ROBOT_BOUNDS",
    "SHIELD_SCENES",
    "ArmTask",
    "BaseTask",
    "Episode",
    "ShieldScene",
    "body_ids",
]

ARM_TARGETS = {
    # Joint targets (rad) putting the tool 12 cm above each fixture, pointing down (solved by
    # damped least squares on the tool site's position and axis).
    "person_cell": [
        [0.588, 1.038, 0.597, 1.506, 0.0, 0.587],
        [0.0, 0.958, 0.756, 1.428, 0.0, 0.0],
        [-0.588, 1.038, 0.597, 1.506, 0.0, -0.587],
        [1.249, 0.419, 1.72, 1.003, 0.0, 1.248],
    ],
    "arm_pair": [
        [1.012, 0.414, 1.728, 1.0, 0.0, 1.011],
        [-1.012, 0.414, 1.728, 1.0, 0.0, -1.011],
        [0.395, 0.81, 1.042, 1.29, 0.0, 0.394],
        [-0.395, 0.81, 1.042, 1.29, 0.0, -0.394],
    ],
}
HOME = [0.0, -0.2, 2.0, 1.2, 0.0, 0.0]
"""The arms' start: elbow up over the base."""

ARM_SPEED = np.array([1.2, 1.2, 1.5, 2.0, 2.0, 2.5])
"""The arms' task speed per joint (rad/s): their trajectories never ask for more."""
ARM_ACCEL = np.array([5.0, 5.0, 6.0, 10.0, 10.0, 12.0])
"""The arms' task acceleration per joint (rad/s^2)."""

ARM_B_BOUNDS = {
    # Arm B alone (A folded away), 200 episodes: at the corners of every geom's box, every
    # physics step, the largest chord speed, discrete acceleration and one-step discrepancy
    # (dua_mujoco.experiments.shield.bounds), each times 1.5 (the discrepancy as the velocity
    # uncertainty, without the A h / 2 it may take off).
    "b_link1": Bound(0.18, 11.0, 0.022),
    "b_link2": Bound(1.0, 30.0, 0.061),
    "b_link3": Bound(1.4, 49.0, 0.099),
    "b_link4": Bound(1.4, 47.0, 0.093),
    "b_link5": Bound(1.4, 45.0, 0.089),
    "b_hand": Bound(1.3, 42.0, 0.085),
}
"""Arm B's declared bounds (every point of each body), for ``arm_pair``."""

ROBOT_BOUNDS = {
    # Each robot under its task with the shield's brake cutting in at random (200 episodes,
    # dua_mujoco.experiments.shield.bounds): the largest chord speed and discrete acceleration
    # at the corners of any of its geoms' boxes, times 1.5 (the discrepancy stays within the
    # integrator term A h these imply). What the shield's screen assumes of the robot.
    "person_cell": Bound(2.2, 290.0),
    "arm_pair": Bound(2.0, 335.0),
    "mobile_cell": Bound(1.5, 13.0),
}
"""The robots' declared bounds (every point of every robot body), by scene."""


def body_ids(model: mujoco.MjModel, patterns: tuple[str, ...] | list[str]) -> np.ndarray:
    """Ids of the bodies whose names match any of the fnmatch ``patterns``.

    Raises:
        ValueError: a pattern matches no body (it names the pattern and lists the bodies).
    """
    names = [model.body(b).name for b in range(model.nbody)]
    out: set[int] = set()
    for pattern in patterns:
        hits = [b for b, n in enumerate(names) if fnmatch.fnmatchcase(n, pattern)]
        if not hits:
            raise ValueError(f"no body matches {pattern!r}; bodies: {names}")
        out.update(hits)
    return np.array(sorted(out), dtype=np.int64)


def _actuators(model: mujoco.MjModel, patterns: tuple[str, ...]) -> np.ndarray:
    names = [model.actuator(a).name for a in range(model.nu)]
    return np.array(
        [a for a, n in enumerate(names) if any(fnmatch.fnmatchcase(n, p) for p in patterns)],
        dtype=np.int64,
    )


class ArmTask:
    """An arm's task controller: cycle between joint targets along straight joint-space moves.

    Each move starts from where the arm is and is the time-optimal trapezoid under the task's
    caps (:data:`ARM_SPEED`, :data:`ARM_ACCEL`); the servo targets lead the reference by
    ``kv / kp`` times its velocity, so the servos track it without lag. A target counts as
    reached when the move is over and the tool is within 2 cm of the target's site; the arm then
    waits 0.1 s and moves on to the next target (in an order drawn from the seed). When the arm
    is more than 0.1 rad off its reference (a safety layer stopped it), the move is planned
    again from where it is.

    Args:
        model: the scene's model.
        prefix: the arm's name prefix (``""`` for person_cell's arm, ``"a_"``, ``"b_"``).
        targets: ``(k, 6)`` joint targets.
        seed: draws the order of the targets.
    """

    def __init__(
        self, model: mujoco.MjModel, prefix: str, targets: list[list[float]], seed: int
    ) -> None:
        joints = [model.joint(f"{prefix}j{i}").id for i in range(1, 7)]
        self.qadr = np.asarray(model.jnt_qposadr[joints])
        self.dadr = np.asarray(model.jnt_dofadr[joints])
        self.act = np.array([model.actuator(f"{prefix}j{i}").id for i in range(1, 7)])
        self.lead = -model.actuator_biasprm[self.act, 2] / model.actuator_gainprm[self.act, 0]
        self.lo, self.hi = model.actuator_ctrlrange[self.act].T
        self.tool = model.site(f"{prefix}tool").id
        site_names = [f"{prefix}target{k}" for k in range(len(targets))]
        if not prefix:
            site_names = [f"target{k}" for k in range(len(targets))]
        self.sites = [model.site(n).id for n in site_names]
        self.targets = np.asarray(targets, dtype=np.float64)
        rng = np.random.default_rng([seed, 6])
        self.order = rng.permutation(len(targets))
        self.index = 0
        self.reached = 0
        self.move: Move | None = None
        self.wait_until: float | None = None

    def _near(self, data: mujoco.MjData) -> bool:
        site = self.sites[self.order[self.index % len(self.order)]]
        return bool(np.linalg.norm(data.site_xpos[self.tool] - data.site_xpos[site]) < 0.02)

    def _plan(self, q: np.ndarray, t: float) -> None:
        self.wait_until = None
        goal = self.targets[self.order[self.index % len(self.order)]]
        delta = goal - q
        length = float(np.linalg.norm(delta))
        if length == 0.0:
            self.move = Move.make(q, goal, t, 1.0, 1.0)
            return
        u = np.abs(delta) / length
        with np.errstate(divide="ignore"):
            vmax = float(np.min(np.where(u > 0, ARM_SPEED / u, np.inf)))
            amax = float(np.min(np.where(u > 0, ARM_ACCEL / u, np.inf)))
        self.move = Move.make(q, goal, t, vmax, amax)

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData, ctrl: np.ndarray) -> None:
        """Write the arm's servo targets into ``ctrl`` (``(nu,)``) for ``data.time``."""
        t = float(data.time)
        q = data.qpos[self.qadr].copy()
        if self.move is None:
            self._plan(q, t)
        assert self.move is not None
        ref, vel = self.move.state(t)
        if np.max(np.abs(ref - q)) > 0.1:
            self._plan(q, t)
            ref, vel = self.move.state(t)
        if t >= self.move.t1 and self._near(data):
            if self.wait_until is None:
                self.wait_until = t + 0.1
            elif t >= self.wait_until:
                self.reached += 1
                self.index += 1
                self._plan(q, t)
                ref, vel = self.move.state(t)
        ctrl[self.act] = np.clip(ref + self.lead * vel, self.lo, self.hi)


class BaseTask:
    """The mobile base's task controller: drive to each station in turn (an order drawn from the
    seed), at most 1.0 m/s, changing the velocity command by at most 1.5 m/s^2 from the base's
    own velocity, braking so as to arrive at rest; the heading is held at 0. A station counts as
    reached within 0.15 m of its centre.

    Args:
        model: ``mobile_cell``'s model.
        seed: draws the order of the stations.
        period: the control period (s), over which the command may change by 1.5 m/s^2.
    """

    VMAX = 1.0
    AMAX = 1.5

    def __init__(self, model: mujoco.MjModel, seed: int, period: float) -> None:
        self.qadr = np.array([model.joint(n).qposadr[0] for n in ("base_x", "base_y", "base_yaw")])
        self.dadr = np.array([model.joint(n).dofadr[0] for n in ("base_x", "base_y", "base_yaw")])
        self.act = np.array([model.actuator(n).id for n in ("base_x", "base_y", "base_yaw")])
        self.stations = np.array([model.site(f"station{k}").pos[:2] for k in range(4)])
        rng = np.random.default_rng([seed, 7])
        self.order = rng.permutation(4)
        self.index = 1
        self.reached = 0
        self.period = period
        self.command = np.zeros(2)

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData, ctrl: np.ndarray) -> None:
        """Write the base's velocity commands into ``ctrl`` (``(nu,)``)."""
        pos = data.qpos[self.qadr[:2]]
        vel = data.qvel[self.dadr[:2]]
        goal = self.stations[self.order[self.index % 4]]
        gap = goal - pos
        dist = float(np.linalg.norm(gap))
        if dist < 0.15:
            self.reached += 1
            self.index += 1
            goal = self.stations[self.order[self.index % 4]]
            gap = goal - pos
            dist = float(np.linalg.norm(gap))
        speed = min(self.VMAX, float(np.sqrt(2 * self.AMAX * 0.8 * dist)))
        want = gap / max(dist, 1e-9) * speed
        # Ramp the last command, unless the base is far from it (a safety layer overrode it).
        last = self.command if np.linalg.norm(self.command - vel) < 0.2 else vel
        step = want - last
        limit = self.AMAX * self.period
        norm = float(np.linalg.norm(step))
        if norm > limit:
            step *= limit / norm
        self.command = last + step
        ctrl[self.act[:2]] = self.command
        ctrl[self.act[2]] = -2.0 * float(data.qpos[self.qadr[2]])


@dataclass
class Episode:
    """One episode of a scene, drawn from a seed.

    Attributes:
        seed: the seed.
        script: the scripted (mocap) bodies, or None; call ``script.apply(data)`` before each
            ``mj_step``.
        tasks: the task controllers (the robot's first).
    """

    seed: int
    script: ScriptedBodies | None
    tasks: list[Callable[[mujoco.MjModel, mujoco.MjData, np.ndarray], None]] = field(
        default_factory=list
    )

    def policy(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """The intended controls of every actuator at ``data``: ``(nu,)``."""
        ctrl = data.ctrl.copy()
        for task in self.tasks:
            task(model, data, ctrl)
        return ctrl

    @property
    def reached(self) -> int:
        """Targets the robot reached so far."""
        return int(getattr(self.tasks[0], "reached", 0))


@dataclass(frozen=True)
class ShieldScene:
    """A scene of the shield's benchmark.

    Attributes:
        name: registry key, and the MJCF file's name in ``models/`` (``<name>.xml``).
        robot: fnmatch patterns of the robot's actuator names.
        protect: fnmatch patterns of the body names the robot must not move into.
        period: physics steps per control period.
        duration: an episode's length (s).
        task_speed: the largest speed of each robot DOF its task asks for, in the order of
            the robot's DOFs (for tests drawing states within the task's speeds).
        task_accel: the largest acceleration of each robot DOF its task asks for (a peer
            that wants joint acceleration limits, as MoveIt's joint_limits.yaml has, reads them).
        stop_time: the longest stop of the shield's brake from the task's states (s): the
            measured 38 / 30 / 386 ms (docs/shield.md) with a margin.

    The defaults are the arm cells' (``ArmTask``'s speeds and accelerations).
    """

    name: str
    robot: tuple[str, ...]
    protect: tuple[str, ...]
    duration: float
    period: int = 10
    task_speed: tuple[float, ...] = tuple(ARM_SPEED)
    task_accel: tuple[float, ...] = tuple(ARM_ACCEL)
    stop_time: float = 0.06

    def model(self) -> mujoco.MjModel:
        """Compile the scene."""
        return mujoco.MjModel.from_xml_path(str(models_dir() / f"{self.name}.xml"))

    def robot_actuators(self, model: mujoco.MjModel) -> np.ndarray:
        """Ids of the robot's actuators."""
        return _actuators(model, self.robot)

    def protected_bodies(self, model: mujoco.MjModel) -> np.ndarray:
        """Ids of the protected bodies."""
        return body_ids(model, self.protect)

    def bounds(self, model: mujoco.MjModel) -> dict[str, Bound]:
        """The declared bound of every body that moves and that nobody plans, by name."""
        if self.name == "arm_pair":
            return dict(ARM_B_BOUNDS)
        mocap = [model.body(int(b)).name for b in np.flatnonzero(model.body_mocapid >= 0)]
        return declared_bounds(mocap)

    def episode(self, model: mujoco.MjModel, data: mujoco.MjData, seed: int) -> Episode:
        """Reset ``data`` to the episode's start and return the episode drawn from ``seed``."""
        mujoco.mj_resetData(model, data)
        script: ScriptedBodies | None = None
        tasks: list = []
        period = self.period * float(model.opt.timestep)
        if self.name == "person_cell":
            data.qpos[:6] = HOME
            data.ctrl[:6] = HOME
            script = PersonScript(model, seed)
            tasks = [ArmTask(model, "", ARM_TARGETS["person_cell"], seed)]
        elif self.name == "arm_pair":
            rng = np.random.default_rng([seed, 2])
            for prefix in ("a_", "b_"):
                adr = model.joint(f"{prefix}j1").qposadr[0]
                home = np.array(HOME) + rng.uniform(-0.15, 0.15, 6)
                data.qpos[adr : adr + 6] = home
                data.ctrl[model.actuator(f"{prefix}j1").id :][:6] = home
            targets = np.asarray(ARM_TARGETS["arm_pair"])
            # Arm B stands half a turn from A: its base yaw and tool roll change sign.
            mirrored = (targets * [-1, 1, 1, 1, 1, -1]).tolist()
            tasks = [ArmTask(model, "a_", targets.tolist(), seed)]
            tasks.append(ArmTask(model, "b_", mirrored, seed + 1))
        elif self.name == "mobile_cell":
            script = Crowd(model, seed, duration=self.duration + 5.0)
            task = BaseTask(model, seed, period)
            data.qpos[task.qadr[:2]] = task.stations[task.order[0]]
            tasks = [task]
        else:
            raise ValueError(f"unknown shield scene {self.name!r}")
        if script is not None:
            script.apply(data)
        mujoco.mj_forward(model, data)
        return Episode(seed, script, tasks)


SHIELD_SCENES: dict[str, ShieldScene] = {
    s.name: s
    for s in (
        ShieldScene("person_cell", robot=("j*",), protect=("person*",), duration=6.0),
        ShieldScene("arm_pair", robot=("a_*",), protect=("b_*",), duration=5.0),
        ShieldScene(
            "mobile_cell",
            robot=("base_*",),
            protect=("walker*", "cart*", "walls"),
            duration=10.0,
            task_speed=(BaseTask.VMAX, BaseTask.VMAX, 0.5),
            task_accel=(BaseTask.AMAX, BaseTask.AMAX, 2.0),
            stop_time=0.45,
        ),
    )
}
"""The shield's scenes by name."""
