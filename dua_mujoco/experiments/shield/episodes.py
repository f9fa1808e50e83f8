"""An episode of a shield scene under a safety layer, and what it counts.

A *layer* sits between the task controller and ``mj_step``: each physics step,
``ctrl = layer(data, intended)`` (the scripted bodies have moved to the step's pose, the task
controller's output is held over its control period). :func:`run_episode` runs one episode and
counts:

* **protected contact onsets** (a robot-protected geom pair in ``d.contact`` at a step and not
  at the one before), each judged by the speed of the robot's body in the pair at the state the
  contact was found at (``|v| + |w| r`` from ``cvel``): *at rest* (at most 1 cm/s) or *moving*;
  a moving onset is *free* when no protected contact touched the robot during the preceding
  ``recovery`` seconds and every declared bound of the protected bodies held so far (the robot's
  motion was its controller's: what a layer answers for), *excused* otherwise (pushed, or after
  a bound broke); a layer that says whether its guarantee holds (``layer.guaranteed``, the
  shield's) has its moving onsets without one counted apart too (*unguaranteed*);
* **progress**: targets the robot reached, per minute;
* **interventions**: physics steps at which the layer overrode the intended controls;
* **cost**: the layer's time and ``mj_step``'s, both timed at every step (interleaved);
* **bound violations** of the protected bodies: body-steps at which a point of the body (the
  corners of its geoms' boxes) moved faster than its declared speed or changed its chord
  velocity by more than its declared acceleration times the step.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Protocol

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco.build.exact import corner_points
from dua_mujoco.build.filter import active_geom_pairs
from dua_mujoco.build.kinematics import PointMotion, pack_spheres
from dua_mujoco.models.cells import SHIELD_SCENES, ShieldScene
from dua_mujoco.models.people import Bound
from dua_mujoco.shield.failsafe import Brake

__all__ = [
    "EpisodeResult",
    "Layer",
    "NoLayer",
    "SceneSetup",
    "body_reach_radius",
    "body_speeds",
    "run_episode",
]

REST_SPEED = 0.01
"""m/s: a body at most this fast is at rest (ISO/TS 15066's contact with the robot stopped)."""


def body_reach_radius(model: mujoco.MjModel) -> np.ndarray:
    """``(nbody,)`` the largest distance from each body's frame origin to a point of its geoms
    (0 for a body without geoms; planes, unbounded, are left out)."""
    out = np.zeros(model.nbody)
    plane = int(mujoco.mjtGeom.mjGEOM_PLANE)
    for g in range(model.ngeom):
        if int(model.geom_type[g]) == plane:
            continue
        b = int(model.geom_bodyid[g])
        out[b] = max(out[b], float(np.linalg.norm(model.geom_pos[g]) + model.geom_rbound[g]))
    return out


def body_speeds(
    model: mujoco.MjModel, data: mujoco.MjData, bodies: npt.ArrayLike, radius: np.ndarray
) -> np.ndarray:
    """``(k,)`` a bound on the speed of every point of each body's geoms, ``|v| + |w| r``, from
    ``data.cvel`` (after ``mj_step``: the state the step started from, its contacts' state)."""
    ids = np.asarray(bodies, dtype=np.int64)
    out = np.empty(ids.size)
    vel = np.empty(6)
    for i, b in enumerate(ids):
        mujoco.mj_objectVelocity(model, data, int(mujoco.mjtObj.mjOBJ_XBODY), int(b), vel, 0)
        out[i] = np.linalg.norm(vel[3:]) + np.linalg.norm(vel[:3]) * radius[b]
    return out


class Layer(Protocol):
    """A safety layer: ``ctrl = layer(data, intended)`` every physics step."""

    @property
    def interventions(self) -> int:
        """Physics steps at which it overrode the intended controls."""

    def reset(self, data: mujoco.MjData) -> None:
        """Start an episode at ``data``."""

    def __call__(self, data: mujoco.MjData, intended: npt.ArrayLike) -> np.ndarray:
        """The controls to apply: ``(nu,)``."""


class NoLayer:
    """No safety layer: the intended controls, always."""

    def __init__(self) -> None:
        self.interventions = 0

    def reset(self, data: mujoco.MjData) -> None:
        """Nothing to forget."""

    def __call__(self, data: mujoco.MjData, intended: npt.ArrayLike) -> np.ndarray:
        """The intended controls."""
        return np.array(intended, dtype=np.float64)


@dataclass
class SceneSetup:
    """What every layer and the counting need of a scene, built once a process.

    Attributes:
        scene: the scene.
        model: its model.
        brake: the robot's brake (its ``actuators``, ``dofs``, ``bodies`` are the robot).
        protected: ``(k,)`` protected body ids.
        bounds: declared bounds of the protected bodies that move, by body id.
        pairs: ``(n, 2)`` the geom pairs MuJoCo can collide between a robot body and a
            protected one, robot geom first.
        radius: ``(nbody,)`` each body's reach radius from its frame origin.
    """

    scene: ShieldScene
    model: mujoco.MjModel
    brake: Brake
    protected: np.ndarray
    bounds: dict[int, Bound]
    pairs: np.ndarray
    radius: np.ndarray

    @staticmethod
    def of(name: str) -> SceneSetup:
        """Build the setup of the scene ``name``."""
        scene = SHIELD_SCENES[name]
        model = scene.model()
        brake = Brake(model, actuators=scene.robot_actuators(model))
        protected = scene.protected_bodies(model)
        bounds = {model.body(n).id: b for n, b in scene.bounds(model).items()}
        active = active_geom_pairs(model)
        body = np.asarray(model.geom_bodyid)
        robot = np.isin(body, brake.bodies)
        prot = np.isin(body, protected) & ~robot
        g1, g2 = active.geom1, active.geom2
        keep1 = robot[g1] & prot[g2]
        keep2 = robot[g2] & prot[g1]
        pairs = np.concatenate(
            [np.stack([g1[keep1], g2[keep1]], 1), np.stack([g2[keep2], g1[keep2]], 1)]
        ).astype(np.int64)
        return SceneSetup(scene, model, brake, protected, bounds, pairs, body_reach_radius(model))


@dataclass
class EpisodeResult:
    """What :func:`run_episode` counted (module docstring)."""

    scene: str
    layer: str
    seed: int
    steps: int
    reached: int
    minutes: float
    moving_free: int
    moving_excused: int
    moving_unguaranteed: int
    at_rest: int
    max_onset_speed: float
    interventions: int
    layer_seconds: float
    step_seconds: float
    violations: int
    first_violation: float | None
    first_touch: float | None

    @property
    def progress(self) -> float:
        """Targets reached per minute."""
        return self.reached / self.minutes

    @property
    def cost(self) -> float:
        """The layer's time over ``mj_step``'s."""
        return self.layer_seconds / self.step_seconds

    def as_dict(self) -> dict:
        """A JSON-ready dict."""
        return asdict(self)


class _BoundCheck:
    """Chord speed and discrete acceleration of the corners of the protected bodies' geom boxes,
    every physics step, against their declared bounds: the native point check
    (:class:`~dua_mujoco.build.kinematics.PointMotion`, the one the bound monitor runs)."""

    def __init__(self, model: mujoco.MjModel, bounds: dict[int, Bound]) -> None:
        geoms = [g for g in range(model.ngeom) if int(model.geom_bodyid[g]) in bounds]
        geom, self.body, local = corner_points(model, geoms)
        self.points = PointMotion(
            pack_spheres(geom, self.body, local, model.body_rootid),
            accel=np.array([bounds[int(b)].accel for b in self.body]),
            speed=np.array([bounds[int(b)].speed for b in self.body]),
            rtol=1e-6,
        )
        self.h = float(model.opt.timestep)
        self.twist = np.zeros((model.nbody, 6))  # chords only: no point velocity is read

    def __call__(self, data: mujoco.MjData) -> int:
        """Body-steps out of bounds at this step (call once after each ``mj_step``)."""
        if self.points.update(data, self.twist, self.h) == 0:
            return 0
        return int(np.unique(self.body[self.points.broken.any(axis=1)]).size)


def run_episode(
    setup: SceneSetup,
    layer: Layer,
    name: str,
    seed: int,
    *,
    recovery: float = 1.0,
    duration: float | None = None,
    on_step: Callable[[mujoco.MjData, int], None] | None = None,
) -> EpisodeResult:
    """Run one episode of ``setup``'s scene under ``layer`` and count (module docstring).

    Args:
        setup: the scene's setup.
        layer: the safety layer.
        name: the layer's name for the result.
        seed: the episode's seed.
        recovery: seconds after a protected touch during which a moving onset is excused.
        duration: the episode's length (s; default: the scene's).
        on_step: called after each ``mj_step`` with the data and the step index (videos).

    Returns:
        The :class:`EpisodeResult`.
    """
    scene, model = setup.scene, setup.model
    data = mujoco.MjData(model)
    episode = scene.episode(model, data, seed)
    layer.reset(data)
    seconds = scene.duration if duration is None else duration
    nsteps = round(seconds / float(model.opt.timestep))
    ngeom = int(model.ngeom)
    watched = np.zeros((ngeom, ngeom), dtype=bool)
    watched[setup.pairs[:, 0], setup.pairs[:, 1]] = True
    watched[setup.pairs[:, 1], setup.pairs[:, 0]] = True
    robot_of = np.where(
        np.isin(np.asarray(model.geom_bodyid), setup.brake.bodies), model.geom_bodyid, -1
    )
    check = _BoundCheck(model, setup.bounds)
    previous = np.zeros(0, dtype=np.int64)
    last_touch = -np.inf
    violated = False
    counts = {
        "moving_free": 0,
        "moving_excused": 0,
        "moving_unguaranteed": 0,
        "at_rest": 0,
        "violations": 0,
    }
    max_speed = 0.0
    first_violation: float | None = None
    first_touch: float | None = None
    layer_s = step_s = 0.0
    intended = data.ctrl.copy()
    for k in range(nsteps):
        if episode.script is not None:
            episode.script.apply(data)
        if k % scene.period == 0:
            intended = episode.policy(model, data)
        t0 = time.perf_counter()
        ctrl = layer(data, intended)
        t1 = time.perf_counter()
        guaranteed = bool(getattr(layer, "guaranteed", True))
        data.ctrl[:] = ctrl
        mujoco.mj_step(model, data)
        t2 = time.perf_counter()
        layer_s += t1 - t0
        step_s += t2 - t1
        if on_step is not None:
            on_step(data, k)
        broke = check(data)
        counts["violations"] += broke
        geoms = np.asarray(data.contact.geom)[: data.ncon]
        hits = geoms[watched[geoms[:, 0], geoms[:, 1]]] if data.ncon else geoms
        keys = np.unique(
            np.minimum(hits[:, 0], hits[:, 1]) * ngeom + np.maximum(hits[:, 0], hits[:, 1])
        )
        now = float(data.time) - float(model.opt.timestep)  # the state the contacts were found at
        for key in np.setdiff1d(keys, previous, assume_unique=True).tolist():
            g1, g2 = divmod(key, ngeom)
            body = robot_of[g1] if robot_of[g1] >= 0 else robot_of[g2]
            speed = float(body_speeds(model, data, [body], setup.radius)[0])
            max_speed = max(max_speed, speed)
            if speed <= REST_SPEED:
                counts["at_rest"] += 1
                continue
            counts["moving_unguaranteed"] += not guaranteed
            if violated or now - last_touch <= recovery:
                counts["moving_excused"] += 1
            else:
                counts["moving_free"] += 1
        if keys.size:
            last_touch = now
            first_touch = now if first_touch is None else first_touch
        if broke and first_violation is None:
            first_violation = now
        violated = violated or broke > 0
        previous = keys
    return EpisodeResult(
        scene=scene.name,
        layer=name,
        seed=seed,
        steps=nsteps,
        reached=episode.reached,
        minutes=seconds / 60.0,
        max_onset_speed=max_speed,
        interventions=int(layer.interventions),
        layer_seconds=layer_s,
        step_seconds=step_s,
        first_violation=first_violation,
        first_touch=first_touch,
        **counts,
    )
