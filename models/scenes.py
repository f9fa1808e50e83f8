"""Bundled scenes, the paper's sphere world as an ``MjSpec``, and scene drivers.

Bundled scenes live beside this module in the top-level ``models/`` folder, shipped as the
package ``dua_mujoco.models`` (in the source tree, the link ``dua_mujoco/models`` imports it):

========================  ==================================================================
``two_arms``              two 5-DoF arms over a table with obstacles (the default scene)
``traffic``               a four-way intersection, 12 cars on slide joints (the paper's
                          traffic-controller example)
``clutter``               a walled bin with every collidable primitive type, a pushing paddle
                          and a mocap stirrer
``bin_pour``              300 loose objects (boxes, spheres, capsules, cylinders, ellipsoids)
                          poured into a bin in layers (:func:`bin_pour_spec`)
``bin_pour:N``            the same with ``N`` objects, the bin's floor grown with ``N``
``paper_world``           the paper's world (sec. 8) with 40 spheres, saved from
                          :func:`paper_world_spec`
``paper_world:N``         the same world generated with ``N`` spheres
``swarm:N``               ``N`` spheres at the density of the paper's 40 in its unit cube (the
                          cube's side grows as ``(N / 40)^(1/3)``): thousands of geoms, for
                          pruned pair sets (docs/many-objects.md)
``rough_terrain``         a 12-DoF quadruped on a height field of rough terrain (5 cm cells,
                          12 cm of relief; docs/static-shapes.md, section 13)
``flat_terrain``          the same quadruped on a plane at the terrain's mean height
                          (:func:`flat_terrain_spec`), for comparisons
``person_cell``           a 6-DoF arm working a cell while a mocap person walks in and reaches
                          (:mod:`~dua_mujoco.models.person_cell`, docs/plans.md)
========================  ==================================================================

:func:`load_scene` also accepts a path to any MJCF file. :func:`make_controller` drives a scene
with zero, random (held, hence piecewise-constant) or smooth controls (targets linear between
random points, :mod:`~dua_mujoco.models.smooth_drive`) and moves mocap bodies on circles, so that
every scene keeps moving and colliding. A scene may have a driver of its own and declare every
body's bounds (:attr:`Scene.driver`, :attr:`Scene.bounds`: ``person_cell``'s person and arm).

Motion bounds. The paper world and the traffic scene declare an exact acceleration bound in a
``<numeric name="dua_accel_bound">`` custom field (read it with :func:`declared_accel_bound`):
it holds whenever the bodies are not in contact (and, for traffic, not at a joint limit). For the
arm and clutter scenes :attr:`Scene.accel_hint` is an empirical value measured on random
rollouts, not a proof.
"""

from __future__ import annotations

import enum
import importlib.resources
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from dua_mujoco.exceptions import InvalidChoiceError, InvalidInputError
from dua_mujoco.models import models_dir
from dua_mujoco.models.bin_pour import BIN_POUR_DEFAULT, bin_pour_spec
from dua_mujoco.models.paper_world import (
    ACCEL_BOUND_NUMERIC,
    paper_world_accel_bound,
    paper_world_model,
    paper_world_spec,
)
from dua_mujoco.models.smooth_drive import SmoothDrive, smooth_drive

if TYPE_CHECKING:
    from dua_mujoco.build.bounds import MotionBounds

Driver = Callable[[mujoco.MjModel, mujoco.MjData], None]
"""A scene's driver: ``driver(model, data)`` before each ``mj_step``."""

__all__ = [
    "ACCEL_BOUND_NUMERIC",
    "DEFAULT_SCENE",
    "SCENES",
    "CtrlMode",
    "MocapCircle",
    "Scene",
    "SceneController",
    "check_scene",
    "declared_accel_bound",
    "flat_terrain_spec",
    "keyframe_id",
    "load_scene",
    "load_spec",
    "make_controller",
    "models_dir",
    "paper_world_accel_bound",
    "paper_world_model",
    "paper_world_spec",
    "reset_to_keyframe",
    "scene_names",
]

DEFAULT_SCENE = "two_arms"


_PAPER_PREFIX = "paper_world:"
_SWARM_PREFIX = "swarm:"
_POUR_PREFIX = "bin_pour:"
_COUNTED = (_PAPER_PREFIX, _SWARM_PREFIX, _POUR_PREFIX)
"""Scene names that take a count, ``name:N``."""


def declared_accel_bound(model: mujoco.MjModel) -> float | None:
    """The exact acceleration-norm bound a scene declares in ``<numeric name="dua_accel_bound">``.

    Returns:
        The bound (m/s^2) on every movable body's acceleration while out of contact, or None
        if the model declares none.
    """
    nid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_NUMERIC, ACCEL_BOUND_NUMERIC)
    if nid < 0:
        return None
    return float(model.numeric_data[model.numeric_adr[nid]])


# --------------------------------------------------------------------------------------------------
# Registry of bundled scenes.
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Scene:
    """A bundled scene.

    Attributes:
        name: Registry key.
        source: XML file name inside ``models/``, or a builder returning an ``MjSpec``.
        description: One line for ``--help`` and reports.
        default_steps: A rollout length that shows the scene's collisions.
        accel_hint: A suggested acceleration-norm bound (m/s^2) for the predictor. Exact (out of
            contact) for the paper world and traffic; measured on random rollouts otherwise.
        driver: The scene's own controller, ``driver(model, seed)`` (None: the scene is driven by
            :func:`make_controller`).
        bounds: The bounds the scene declares for every moving body, ``bounds(model)`` (None:
            none; ``--accel auto`` measures them).
    """

    name: str
    source: str | Callable[[], mujoco.MjSpec]
    description: str
    default_steps: int
    accel_hint: float
    driver: Callable[[mujoco.MjModel, int], Driver] | None = None
    bounds: Callable[[mujoco.MjModel], MotionBounds] | None = None

    def model(self) -> mujoco.MjModel:
        """Compile the scene.

        Returns:
            The compiled model.
        """
        return self.spec().compile()

    def spec(self) -> mujoco.MjSpec:
        """The scene's spec (a fresh one each call)."""
        if callable(self.source):
            return self.source()
        with importlib.resources.as_file(_model_file(self.source)) as path:
            return mujoco.MjSpec.from_file(str(path))


def _model_file(filename: str) -> Path:
    return models_dir() / filename


def flat_terrain_spec() -> mujoco.MjSpec:
    """``rough_terrain`` with its height field replaced by a plane at the terrain's mean height:
    the same robot, controls and start, on flat ground."""
    spec = mujoco.MjSpec.from_file(str(_model_file("rough_terrain.xml")))
    hfield = spec.hfield("rough")
    raw = np.asarray(hfield.userdata, dtype=np.float64)
    # MuJoCo scales the elevation data to [0, 1] of the height field's elevation (size[2]).
    mean = float((raw.mean() - raw.min()) / (raw.max() - raw.min()) * hfield.size[2])
    spec.modelname = "flat_terrain"
    ground = spec.geom("ground")
    ground.type = mujoco.mjtGeom.mjGEOM_PLANE
    ground.hfieldname = ""
    ground.size = [float(hfield.size[0]), float(hfield.size[1]), 0.1]
    ground.pos = [0.0, 0.0, mean]
    spec.delete(hfield)
    return spec


def _person_cell_driver(model: mujoco.MjModel, seed: int) -> Driver:
    from dua_mujoco.models.person_cell import CellDriver

    return CellDriver(model, seed)


def _person_cell_bounds(model: mujoco.MjModel) -> MotionBounds:
    from dua_mujoco.models.person_cell import declared_bounds

    return declared_bounds(model)


SCENES: dict[str, Scene] = {
    s.name: s
    for s in (
        Scene(
            name="two_arms",
            source="two_arms.xml",
            description="Two 5-DoF arms sharing a table with fixed and loose obstacles.",
            default_steps=2000,
            # Geom centres out of contact, random controls: 99.9th percentile 59, max 74 m/s^2.
            accel_hint=80.0,
        ),
        Scene(
            name="traffic",
            source="traffic.xml",
            description="Four-way intersection, 12 cars driven along their lanes (paper sec. 1).",
            default_steps=1000,
            # Exact out of contact and off the joint limits (motor gear = mass * 4).
            accel_hint=4.0,
        ),
        Scene(
            name="clutter",
            source="clutter.xml",
            description="Walled bin of free primitives and meshes, a paddle and a mocap stirrer.",
            default_steps=2000,
            # Geom centres out of contact, random controls: 99.9th percentile 42, max 48 m/s^2.
            accel_hint=50.0,
        ),
        Scene(
            name="bin_pour",
            source=lambda: bin_pour_spec(BIN_POUR_DEFAULT),
            description=f"{BIN_POUR_DEFAULT} loose objects poured into a bin, falling in layers.",
            default_steps=1000,
            # Gravity out of contact; every other acceleration is an impact.
            accel_hint=9.81,
        ),
        Scene(
            name="paper_world",
            source="paper_world.xml",
            description="The paper's world: 40 spheres, bounded accelerations, in a unit cube.",
            default_steps=1000,
            accel_hint=paper_world_accel_bound(1.0),
        ),
        Scene(
            name="rough_terrain",
            source="rough_terrain.xml",
            description="A 12-DoF quadruped on rough terrain, a height field of 5 cm cells.",
            default_steps=2000,
            # Geom centres, random controls, seeds 0-4, 3000 steps each, every step (the feet
            # are nearly always on the ground): 99.9th percentile 308, max 574 m/s^2.
            accel_hint=310.0,
        ),
        Scene(
            name="flat_terrain",
            source=flat_terrain_spec,
            description="The quadruped of rough_terrain on a plane at the terrain's mean height.",
            default_steps=2000,
            # Measured as for rough_terrain: 99.9th percentile 307, max 532 m/s^2.
            accel_hint=310.0,
        ),
        Scene(
            name="person_cell",
            source="person_cell.xml",
            description="A 6-DoF arm working a cell while a person walks in and reaches.",
            # 7 s: the person walks in, reaches into the arm's workspace and withdraws.
            default_steps=3500,
            # The arm's largest declared acceleration (models/person_cell.py: ARM_BOUNDS).
            accel_hint=65.0,
            driver=_person_cell_driver,
            bounds=_person_cell_bounds,
        ),
    )
}


def scene_names() -> tuple[str, ...]:
    """Every name :func:`load_scene` accepts (``paper_world:N`` stands for any N >= 1)."""
    return (*SCENES, *(f"{prefix}N" for prefix in _COUNTED))


def _looks_like_path(name: str) -> bool:
    return name.lower().endswith((".xml", ".mjcf", ".mjb")) or "/" in name or "\\" in name


def load_scene(
    name_or_path: str, *, keyframe: int | str | None = None
) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """Load a bundled scene or an MJCF file, reset to a keyframe and run ``mj_forward``.

    Args:
        name_or_path: A bundled name (``two_arms``, ``traffic``, ``clutter``, ``paper_world``),
            ``paper_world:N`` for the generated world with ``N`` spheres (seed 0), ``swarm:N``
            for ``N`` spheres at the paper world's density, ``bin_pour:N`` for ``N`` objects
            poured into a bin, or a path to an MJCF file or a binary ``.mjb`` model.
        keyframe: See :func:`reset_to_keyframe`; None means the first keyframe, if any.

    Returns:
        ``(model, data)``, with ``data`` at the keyframe and its derived quantities computed.

    Raises:
        InvalidChoiceError: If the name is neither a bundled scene nor a path.
        InvalidInputError: If a path (ending in .xml, .mjcf or .mjb, or with a folder) names
            no file, or ``N`` in ``name:N`` is not a positive integer.
    """
    path = Path(name_or_path)
    if name_or_path not in SCENES and path.suffix.lower() == ".mjb" and path.is_file():
        # A compiled model (mj_saveModel) is binary: the XML parser would call it malformed XML.
        model = mujoco.MjModel.from_binary_path(str(path))
    else:
        model = load_spec(name_or_path).compile()
    data = mujoco.MjData(model)
    reset_to_keyframe(model, data, keyframe)
    return model, data


def load_spec(name_or_path: str) -> mujoco.MjSpec:
    """The ``MjSpec`` of a bundled scene (names as for :func:`load_scene`) or an MJCF file.

    Raises:
        InvalidChoiceError: If the name is neither a bundled scene nor a path.
        InvalidInputError: If a path (ending in .xml, .mjcf or .mjb, or with a folder) names
            no file, ``N`` in ``name:N`` is not a positive integer, or the file is a compiled
            ``.mjb`` model, which has no spec.
    """
    check_scene(name_or_path)
    if name_or_path in SCENES:
        return SCENES[name_or_path].spec()
    if name_or_path.startswith(_POUR_PREFIX):
        return bin_pour_spec(int(name_or_path.split(":", 1)[1]))
    if name_or_path.startswith((_PAPER_PREFIX, _SWARM_PREFIX)):
        prefix, count = name_or_path.split(":", 1)
        n = int(count)
        # The unit cube holds the paper's 40 spheres; a swarm keeps that density.
        box = {"box_size": (n / 40) ** (1 / 3)} if prefix == _SWARM_PREFIX[:-1] else {}
        return paper_world_spec(n, **box)
    if Path(name_or_path).suffix.lower() == ".mjb":
        raise InvalidInputError(
            f"{name_or_path!r} is a compiled model: it has no MjSpec. Pass its MJCF file."
        )
    return mujoco.MjSpec.from_file(name_or_path)


def check_scene(name_or_path: str) -> None:
    """Raise what :func:`load_scene` raises for a name that names no scene, without loading.

    Raises:
        InvalidChoiceError: If the name is neither a bundled scene nor a path.
        InvalidInputError: If a path (ending in .xml, .mjcf or .mjb, or with a folder) names
            no file, or ``N`` in ``paper_world:N`` is not a positive integer.
    """
    if name_or_path in SCENES:
        return
    if name_or_path.startswith(_COUNTED):
        prefix, count = name_or_path.split(":", 1)
        if not count.isdigit() or int(count) < 1:
            raise InvalidInputError(
                f"In {name_or_path!r}, N must be a positive integer, e.g. '{prefix}:20'."
            )
        return
    if not Path(name_or_path).is_file():
        if _looks_like_path(name_or_path):  # meant as a file: the missing file is the news
            raise InvalidInputError(
                f"No file at {str(Path(name_or_path).resolve())!r}: pass the path of an existing "
                "MJCF (.xml) or binary (.mjb) model, or a bundled scene "
                f"({', '.join(scene_names())})."
            )
        raise InvalidChoiceError(
            "scene",
            name_or_path,
            scene_names(),
            "Or pass the path of an existing MJCF (.xml) or binary (.mjb) model.",
        )


def keyframe_id(model: mujoco.MjModel, keyframe: int | str) -> int:
    """The id of a keyframe given by id or name, or -1 when the model has no such keyframe."""
    if isinstance(keyframe, str):
        return int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, keyframe))
    return int(keyframe) if 0 <= int(keyframe) < model.nkey else -1


def reset_to_keyframe(
    model: mujoco.MjModel, data: mujoco.MjData, keyframe: int | str | None = None
) -> None:
    """Reset ``data`` to a keyframe (or to the model's defaults) and run ``mj_forward``.

    Args:
        model: The model.
        data: Its data, modified in place.
        keyframe: Index or name of the keyframe; None means the first keyframe if the model has
            one, else the model defaults (``qpos0``, zero velocity).

    Raises:
        InvalidChoiceError: If the keyframe index or name does not exist (lists the valid ones).
        InvalidInputError: If a keyframe is asked of a model that has none.
    """
    key = (0 if model.nkey > 0 else -1) if keyframe is None else keyframe_id(model, keyframe)
    if keyframe is not None and key < 0:
        if model.nkey == 0:
            raise InvalidInputError(
                f"keyframe {keyframe!r} does not exist: the model has no keyframes (leave the "
                "keyframe out to start from the model's defaults)."
            )
        names = [model.key(k).name for k in range(model.nkey)]
        choices = [*range(model.nkey), *(n for n in names if n)]
        raise InvalidChoiceError("keyframe", keyframe, choices, "Pass an id or a name.")
    if key >= 0:
        mujoco.mj_resetDataKeyframe(model, data, key)
    else:
        mujoco.mj_resetData(model, data)
    mujoco.mj_forward(model, data)


# --------------------------------------------------------------------------------------------------
# Scene drivers.
# --------------------------------------------------------------------------------------------------


class CtrlMode(enum.Enum):
    """How :func:`make_controller` drives a scene."""

    ZERO = "zero"
    """``ctrl = 0`` and mocap bodies stay where they are."""
    RANDOM = "random"
    """Uniform controls held for ``hold_steps`` steps; mocap bodies move on circles."""
    SMOOTH = "smooth"
    """Targets linear between random points ``hold_steps`` apart: servos take them as their
    controls, motors a 1 Hz critically damped PD torque toward them (``SmoothDrive``); mocap
    bodies move on circles."""


@dataclass(frozen=True)
class MocapCircle:
    """A horizontal circle along which :class:`SceneController` moves each mocap body.

    A mocap body starting at ``p0`` with phase ``phi`` is at
    ``p0 + radius (cos(w t + phi) - cos(phi), sin(w t + phi) - sin(phi), 0)`` at time ``t``,
    ``w = 2 pi / period``, with a fixed orientation: every point of the body has speed
    ``radius w`` and acceleration ``radius w^2``. Sampling at the timestep ``h`` the discrete second
    difference is ``2 radius (1 - cos(w h)) / h^2 <= radius w^2``, so the bound also holds for the
    positions MuJoCo sees.

    Attributes:
        radius: Circle radius (m).
        period: Time of one turn (s).
    """

    radius: float = 0.1
    period: float = 3.0

    @property
    def omega(self) -> float:
        """Angular rate (rad/s)."""
        return 2.0 * math.pi / self.period

    @property
    def speed_bound(self) -> float:
        """Speed of every mocap point (m/s)."""
        return self.radius * self.omega

    @property
    def accel_bound(self) -> float:
        """Acceleration norm of every mocap point (m/s^2)."""
        return self.radius * self.omega**2


@dataclass
class SceneController:
    """A stateful scene driver; call it with ``(model, data)`` before every ``mj_step``.

    Not frozen: it counts steps to know when to draw the next held control.

    Attributes:
        mode: Zero, random or smooth controls.
        hold_steps: Physics steps each random control is held (piecewise-constant controls), or
            between two random points of the smooth drive.
        ctrl_low: Lower control bounds, shape ``(nu,)``: ``ctrlrange`` or -1 for unlimited.
        ctrl_high: Upper control bounds, shape ``(nu,)``: ``ctrlrange`` or +1 for unlimited.
        mocap: The circle mocap bodies follow in random mode.
        mocap_start: Start positions of the mocap bodies, shape ``(nmocap, 3)``.
        mocap_phase: Phases of the mocap circles, shape ``(nmocap,)``.
        rng: Source of the random controls (seeded by :func:`make_controller`).
        smooth: The smooth drive (smooth mode only).
    """

    mode: CtrlMode
    hold_steps: int
    ctrl_low: np.ndarray
    ctrl_high: np.ndarray
    mocap: MocapCircle
    mocap_start: np.ndarray
    mocap_phase: np.ndarray
    rng: np.random.Generator
    smooth: SmoothDrive | None = None
    _step: int = field(default=0, init=False)
    _ctrl: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self._ctrl = np.zeros_like(self.ctrl_low)

    @property
    def mocap_accel_bound(self) -> float:
        """Acceleration bound of mocap points (m/s^2); 0 in zero mode."""
        return 0.0 if self.mode is CtrlMode.ZERO else self.mocap.accel_bound

    @property
    def mocap_speed_bound(self) -> float:
        """Speed bound of mocap points (m/s); 0 in zero mode."""
        return 0.0 if self.mode is CtrlMode.ZERO else self.mocap.speed_bound

    def mocap_pos(self, time: float) -> np.ndarray:
        """Mocap positions at ``time`` (s) in random and smooth modes, shape ``(nmocap, 3)``."""
        angle = self.mocap.omega * time + self.mocap_phase
        offset = np.zeros_like(self.mocap_start)
        offset[:, 0] = np.cos(angle) - np.cos(self.mocap_phase)
        offset[:, 1] = np.sin(angle) - np.sin(self.mocap_phase)
        return self.mocap_start + self.mocap.radius * offset

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Write ``data.ctrl`` (and ``data.mocap_pos``) for the coming step."""
        if self.mode is CtrlMode.ZERO:
            data.ctrl[:] = 0.0
            return
        if self.smooth is not None:
            data.ctrl[:] = self.smooth(model, data)
        else:
            if self._step % self.hold_steps == 0:
                self._ctrl = self.rng.uniform(self.ctrl_low, self.ctrl_high)
            self._step += 1
            data.ctrl[:] = self._ctrl
        if self.mocap_start.shape[0]:
            # Driven by data.time so that resets and keyframes give the same path.
            data.mocap_pos[:] = self.mocap_pos(float(data.time))


def make_controller(
    model: mujoco.MjModel,
    mode: CtrlMode | str,
    *,
    seed: int = 0,
    hold_steps: int | None = None,
    mocap: MocapCircle | None = None,
) -> SceneController:
    """A driver writing ``data.ctrl`` (and moving mocap bodies) before each physics step.

    Random mode draws each control uniformly in its ``ctrlrange`` ([-1, 1] if unlimited) and holds
    it for ``hold_steps`` steps, so motions are smooth rather than white noise; with motor
    actuators that is the paper's piecewise-constant bounded acceleration. Mocap bodies start where
    the model puts them and follow :class:`MocapCircle` paths (random phases), whose speed and
    acceleration bounds are :attr:`SceneController.mocap_speed_bound` and
    :attr:`SceneController.mocap_accel_bound`. Smooth mode moves each actuator's target linearly
    between random points ``hold_steps`` apart: servos take it as their control, motors on a
    hinge or slide joint a PD torque toward it, critically damped at 1 Hz
    (:mod:`~dua_mujoco.models.smooth_drive`).

    Args:
        model: The model to drive.
        mode: ``CtrlMode`` or its value (``"zero"``, ``"random"``, ``"smooth"``).
        seed: Seed of the random controls and mocap phases.
        hold_steps: Physics steps each random control is held, or between the smooth drive's
            random points (>= 1; None: 50 random, 250 smooth).
        mocap: The mocap circle; ``MocapCircle()`` if None.

    Returns:
        A callable ``controller(model, data)`` to call before every ``mj_step``.

    Raises:
        InvalidChoiceError: If ``mode`` is not a ``CtrlMode`` value.
        InvalidInputError: If ``hold_steps < 1``.
    """
    if not isinstance(mode, CtrlMode):
        try:
            mode = CtrlMode(mode)
        except ValueError:
            raise InvalidChoiceError("control mode", mode, [m.value for m in CtrlMode]) from None
    if hold_steps is None:
        hold_steps = 250 if mode is CtrlMode.SMOOTH else 50
    if isinstance(hold_steps, bool) or not isinstance(hold_steps, int | np.integer):
        raise InvalidInputError(f"hold_steps must be an int >= 1, got {hold_steps!r}.")
    if hold_steps < 1:
        raise InvalidInputError(f"hold_steps must be >= 1, got {hold_steps}.")
    limited = model.actuator_ctrllimited.astype(bool)
    low = np.where(limited, model.actuator_ctrlrange[:, 0], -1.0)
    high = np.where(limited, model.actuator_ctrlrange[:, 1], 1.0)
    mocap_bodies = [b for b in range(model.nbody) if int(model.body_mocapid[b]) >= 0]
    mocap_bodies.sort(key=lambda b: int(model.body_mocapid[b]))
    rng = np.random.default_rng(seed)
    start = np.array([model.body_pos[b] for b in mocap_bodies], dtype=float).reshape(-1, 3)
    phase = rng.uniform(0.0, 2.0 * math.pi, size=len(mocap_bodies))
    return SceneController(
        mode=mode,
        hold_steps=int(hold_steps),
        ctrl_low=low.astype(float),
        ctrl_high=high.astype(float),
        mocap=mocap if mocap is not None else MocapCircle(),
        mocap_start=start,
        mocap_phase=phase,
        rng=rng,
        smooth=(
            smooth_drive(model, hold_steps=int(hold_steps), rng=rng)
            if mode is CtrlMode.SMOOTH
            else None
        ),
    )
