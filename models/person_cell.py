"""The bundled scene ``person_cell`` as a run drives it: a person walks in and reaches while a
planned arm works the cell.

``load_scene("person_cell")`` gives the model at its ``home`` keyframe (the arm over its base,
at rest); :class:`CellDriver` is its controller (``dua-mujoco run person_cell``'s, its seed drawing
the person's visit and the arm's order of targets): before each physics step it puts the person
where its script says (:class:`~dua_mujoco.models.people.PersonScript`, within ISO 13855's
1.6 m/s walking and 2.0 m/s reaching) and, every control period (20 ms), the arm's servo targets
(:class:`~dua_mujoco.models.cells.ArmTask`, the shield's task). :meth:`CellDriver.plan` is the
arm's flight plan: its task rolled ahead on a copy of the state, on a model where the person
does not collide (the arm's planner knows the cell, not the person); :func:`declared_bounds`
the bounds of everything the plan does not hold: the person's (ISO 13855), and the arm's
own, measured by :func:`measure_arm_bounds` (for the steps past a plan break, and for a
predictor without a plan).
"""

from __future__ import annotations

import copy
import warnings
from collections.abc import Mapping

import mujoco
import numpy as np

from dua_mujoco.build.bounds import MotionBounds, estimate_bounds
from dua_mujoco.exceptions import PilotWarning
from dua_mujoco.models.cells import ARM_TARGETS, HOME, ArmTask
from dua_mujoco.models.people import PERSON_BOUNDS, Bound, PersonScript
from dua_mujoco.runtime.plans import plan_from_controls

__all__ = [
    "ARM",
    "ARM_BOUNDS",
    "PERIOD",
    "CellDriver",
    "declared_bounds",
    "measure_arm_bounds",
    "person_blind",
]

ARM = ("arm_*",)
"""The bodies the arm's plan holds (fnmatch patterns): the person is left to its bounds."""

PERIOD = 10
"""Physics steps a control period: the arm's task sets its servo targets every 20 ms."""

ARM_BOUNDS = {
    # The arm alone running its task (the person away), seeds 0-99, 6 s each, from `home`: at the
    # corners of every geom's box, every physics step, the largest chord speed, discrete
    # acceleration and one-step discrepancy (measure_arm_bounds(100)), each times 2 (`auto`'s
    # safety), rounded up. The discrepancy is declared as the velocity uncertainty, on top of
    # the A h / 2 MotionBounds.declare adds.
    "arm_link1": Bound(0.24, 14.0, 0.028),
    "arm_link2": Bound(1.32, 42.0, 0.083),
    "arm_link3": Bound(1.96, 65.0, 0.13),
    "arm_link4": Bound(1.94, 59.0, 0.12),
    "arm_link5": Bound(1.92, 55.0, 0.11),
    "arm_hand": Bound(1.83, 52.0, 0.105),
}
"""The arm's declared bounds (every point of each body), for its pairs off its plan."""


def declared_bounds(
    model: mujoco.MjModel, *, person: Mapping[str, Bound] = PERSON_BOUNDS
) -> MotionBounds:
    """The scene's declared bounds: the arm's (:data:`ARM_BOUNDS`) and the person's, by body
    name (default :data:`~dua_mujoco.models.people.PERSON_BOUNDS`: 1.6 m/s and 2 m/s^2 walking,
    2.0 m/s and 5 m/s^2 for the arm reaching in; the script keeps to them)."""
    bounds = {**ARM_BOUNDS, **person}
    return MotionBounds.declare(
        model,
        {name: b.accel for name, b in bounds.items()},
        speed={name: b.speed for name, b in bounds.items()},
        vel_uncertainty={name: b.delta or 0.0 for name, b in bounds.items()},
    )


def person_blind(model: mujoco.MjModel) -> mujoco.MjModel:
    """A copy of ``model`` whose person collides with nothing: the model the arm is planned on
    (a plan rolled with the person would bounce off wherever the person stood)."""
    blind = copy.copy(model)
    person = np.isin(np.asarray(model.geom_bodyid), _person_bodies(model))
    blind.geom_contype[person] = 0
    blind.geom_conaffinity[person] = 0
    return blind


def _person_bodies(model: mujoco.MjModel) -> np.ndarray:
    return np.flatnonzero(np.asarray(model.body_mocapid) >= 0)


class _ArmDrive:
    """The arm's task at its control period, writing ``data.ctrl`` (the step count is read off
    ``data.time``: a copy rolled ahead keeps the period)."""

    def __init__(self, model: mujoco.MjModel, seed: int) -> None:
        self.task = ArmTask(model, "", ARM_TARGETS["person_cell"], seed)
        self.h = float(model.opt.timestep)

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData, rng: object = None) -> None:
        # (rng: as estimate_bounds calls a pilot's controller; the task draws nothing.)
        if round(float(data.time) / self.h) % PERIOD == 0:
            ctrl = np.array(data.ctrl)
            self.task(model, data, ctrl)
            data.ctrl[:] = ctrl


class CellDriver:
    """``person_cell``'s controller: the person's script and the arm's task, drawn from ``seed``.

    Call it before each ``mj_step``. Starting from the ``home`` keyframe (``load_scene``), the
    first call puts the person at the start of its walk.

    Args:
        model: ``person_cell``'s model.
        seed: Draws the person's visit (when, where from, where it stands and reaches, how fast
            within its bounds) and the order of the arm's targets.

    Attributes:
        person: The person's script.
        arm: The arm's task (its ``reached`` counts the targets reached).
        planned: The bodies :meth:`plan` plans (:data:`ARM`).
    """

    planned = ARM

    def __init__(self, model: mujoco.MjModel, seed: int = 0) -> None:
        self.person = PersonScript(model, seed)
        self._arm = _ArmDrive(model, seed)
        self.arm = self._arm.task
        self._blind = person_blind(model)

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Move the person to its pose at ``data.time``; every period, set the arm's servos."""
        self.person.apply(data)
        self._arm(model, data)

    def plan(self, model: mujoco.MjModel, data: mujoco.MjData, steps: int) -> np.ndarray:
        """The arm's flight plan from ``data``: ``(steps + 1, nq)``, its task rolled on a copy
        of the state where the person does not collide (``plan_from_controls``; the person
        stays where it is, and is not planned: give ``bodies=CellDriver.planned``)."""
        return plan_from_controls(self._blind, data, copy.deepcopy(self._arm), steps=steps)


def measure_arm_bounds(
    model: mujoco.MjModel,
    episodes: int,
    *,
    points: tuple[np.ndarray, np.ndarray, np.ndarray],
    first_seed: int = 0,
    seconds: float = 6.0,
) -> dict[str, Bound]:
    """The arm's largest speed, acceleration and one-step discrepancy per body, running its task
    alone from ``home`` (the person away) for ``episodes`` seeds, at ``points`` (the predictor's
    ``bound_points``), by ``estimate_bounds`` at safety 1."""
    h = float(model.opt.timestep)
    worst = np.zeros((3, model.nbody))

    def init(m: mujoco.MjModel, d: mujoco.MjData, rng: np.random.Generator) -> None:
        d.qpos[:6] = d.ctrl[:6] = HOME

    for seed in range(first_seed, first_seed + episodes):
        with warnings.catch_warnings():
            # The person is away: its bounds are declared, not measured.
            warnings.simplefilter("ignore", PilotWarning)
            b = estimate_bounds(
                model,
                steps=round(seconds / h),
                seed=seed,
                safety=1.0,
                controller=_ArmDrive(model, seed),
                init=init,
                spheres=points,
                motion="all",
            )
        assert b.speed is not None
        worst = np.maximum(worst, [b.speed, b.accel, b.discrepancy])
    return {name: Bound(*worst[:, model.body(name).id]) for name in ARM_BOUNDS}
