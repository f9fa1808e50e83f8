"""dua_mujoco: collision prediction for MuJoCo with the Dynamic Urgency Algorithm.

Hayward, Aubry, Foisy, Ghallab: "Efficient Collision Prediction Among Many Moving Objects",
IJRR 1995. ``dua_mujoco.core`` knows nothing of MuJoCo (tau, the schedules, pair geometry, the
predictor over raw sphere states); over MuJoCo, ``dua_mujoco.build`` turns a model and options
into tables (covering, pair filter, kinematics, bounds), ``dua_mujoco.runtime`` runs them (the
predictor) and ``dua_mujoco.measure`` holds a run against MuJoCo's contacts (the exact stage);
the demo scenes (``dua_mujoco.models``), rendering, the CLI and the test helpers sit on top.
This module exports what the README's path needs; everything else is importable from the module
that holds it.
"""

from __future__ import annotations

import importlib
import sys
from typing import TYPE_CHECKING, Any

from dua_mujoco.exceptions import (
    BoundViolationWarning,
    DeadlineOverrunWarning,
    DuaError,
    InvalidBoundError,
    InvalidChoiceError,
    InvalidInputError,
    NativeLibraryError,
    NoActivePairsWarning,
    NonFiniteStateError,
    PilotWarning,
    SchedulerError,
    ShapeError,
    UnsupportedGeomError,
)
from dua_mujoco.native import MUJOCO_FIRST

sys.meta_path.insert(0, MUJOCO_FIRST)  # MuJoCo's bundled plugins register before this one's

if TYPE_CHECKING:
    from dua_mujoco.build.bounds import MotionBounds, estimate_bounds
    from dua_mujoco.build.options import (
        CoveringOptions,
        PairOptions,
        PilotOptions,
        ScheduleOptions,
        UrgencyOptions,
    )
    from dua_mujoco.core.schedules import DUAScheduler, Schedule
    from dua_mujoco.core.spheres import SpherePredictor
    from dua_mujoco.core.urgency import time_to_collision
    from dua_mujoco.measure.report import RunReport
    from dua_mujoco.measure.rollout import run
    from dua_mujoco.models.scenes import load_scene
    from dua_mujoco.plugin import PluginOutputs, attach, plugin_outputs, standing_pairs
    from dua_mujoco.runtime.plans import Replanner, plan_from_controls
    from dua_mujoco.runtime.predictor import Alarms, Predictor
    from dua_mujoco.runtime.profiles import (
        PilotPlan,
        deviation_profile,
        plan_deviation,
        relative_profile,
    )
    from dua_mujoco.runtime.table_arrays import pilot_bounds
    from dua_mujoco.shield.shield import Shield

# Everything but the errors loads on first use (PEP 562): ``import dua_mujoco`` and the pytest
# plugin ``dua_mujoco.testing``, loaded in every test session of a project that enables it,
# import neither the compiled core nor MuJoCo.
_LAZY = {
    "MotionBounds": "dua_mujoco.build.bounds",
    "estimate_bounds": "dua_mujoco.build.bounds",
    "CoveringOptions": "dua_mujoco.build.options",
    "PairOptions": "dua_mujoco.build.options",
    "PilotOptions": "dua_mujoco.build.options",
    "ScheduleOptions": "dua_mujoco.build.options",
    "UrgencyOptions": "dua_mujoco.build.options",
    "DUAScheduler": "dua_mujoco.core.schedules",
    "Schedule": "dua_mujoco.core.schedules",
    "SpherePredictor": "dua_mujoco.core.spheres",
    "time_to_collision": "dua_mujoco.core.urgency",
    "RunReport": "dua_mujoco.measure.report",
    "run": "dua_mujoco.measure.rollout",
    "load_scene": "dua_mujoco.models.scenes",
    "PluginOutputs": "dua_mujoco.plugin",
    "attach": "dua_mujoco.plugin",
    "plugin_outputs": "dua_mujoco.plugin",
    "standing_pairs": "dua_mujoco.plugin",
    "Replanner": "dua_mujoco.runtime.plans",
    "plan_from_controls": "dua_mujoco.runtime.plans",
    "Alarms": "dua_mujoco.runtime.predictor",
    "Predictor": "dua_mujoco.runtime.predictor",
    "PilotPlan": "dua_mujoco.runtime.profiles",
    "deviation_profile": "dua_mujoco.runtime.profiles",
    "plan_deviation": "dua_mujoco.runtime.profiles",
    "relative_profile": "dua_mujoco.runtime.profiles",
    "pilot_bounds": "dua_mujoco.runtime.table_arrays",
    "Shield": "dua_mujoco.shield.shield",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'dua_mujoco' has no attribute {name!r}")


__version__ = "0.1.0"

__all__ = [
    "Alarms",
    "BoundViolationWarning",
    "CoveringOptions",
    "DUAScheduler",
    "DeadlineOverrunWarning",
    "DuaError",
    "InvalidBoundError",
    "InvalidChoiceError",
    "InvalidInputError",
    "MotionBounds",
    "NativeLibraryError",
    "NoActivePairsWarning",
    "NonFiniteStateError",
    "PairOptions",
    "PilotOptions",
    "PilotPlan",
    "PilotWarning",
    "PluginOutputs",
    "Predictor",
    "Replanner",
    "RunReport",
    "Schedule",
    "ScheduleOptions",
    "SchedulerError",
    "ShapeError",
    "Shield",
    "SpherePredictor",
    "UnsupportedGeomError",
    "UrgencyOptions",
    "__version__",
    "attach",
    "deviation_profile",
    "estimate_bounds",
    "load_scene",
    "pilot_bounds",
    "plan_deviation",
    "plan_from_controls",
    "plugin_outputs",
    "relative_profile",
    "run",
    "standing_pairs",
    "time_to_collision",
]
