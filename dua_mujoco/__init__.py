"""dua_mujoco: collision prediction for MuJoCo with the Dynamic Urgency Algorithm.

Hayward, Aubry, Foisy, Ghallab: "Efficient Collision Prediction Among Many Moving Objects",
IJRR 1995. The core (``urgency``, ``scheduler``, ``worlds``) imports nothing from MuJoCo; the
MuJoCo layer (``covering``, ``pairs``, ``state``, ``bounds``, ``predictor``, ``monitor``,
``scenes``) builds on it.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from dua_mujoco.exceptions import (
    BoundViolationWarning,
    DeadlineOverrunWarning,
    DuaError,
    InvalidBoundError,
    InvalidChoiceError,
    InvalidInputError,
    NoActivePairsWarning,
    NonFiniteStateError,
    SchedulerError,
    ShapeError,
    UnsupportedGeomError,
)
from dua_mujoco.scheduler import DUAScheduler, PairSet, SelectAllScheduler, Urgency
from dua_mujoco.urgency import distance_urgency, time_to_collision, time_to_halfspace
from dua_mujoco.worlds import AccelProfile, SphereWorld

if TYPE_CHECKING:
    from dua_mujoco.bounds import BoundMonitor, MotionBounds, estimate_bounds
    from dua_mujoco.covering import Covering, CoveringMode, cover_model
    from dua_mujoco.monitor import Monitor, RunReport, run
    from dua_mujoco.pairs import GeomPairs, SpherePairs, active_geom_pairs, sphere_pairs
    from dua_mujoco.predictor import Alarms, Predictor
    from dua_mujoco.scenes import CtrlMode, load_scene, make_controller

# The MuJoCo layer loads on first use (PEP 562), so that ``import dua_mujoco`` (and the pytest
# plugin ``dua_mujoco.testing``, loaded in every test session) does not import MuJoCo.
_LAZY = {
    "Alarms": "dua_mujoco.predictor",
    "BoundMonitor": "dua_mujoco.bounds",
    "Covering": "dua_mujoco.covering",
    "CoveringMode": "dua_mujoco.covering",
    "CtrlMode": "dua_mujoco.scenes",
    "GeomPairs": "dua_mujoco.pairs",
    "Monitor": "dua_mujoco.monitor",
    "MotionBounds": "dua_mujoco.bounds",
    "Predictor": "dua_mujoco.predictor",
    "RunReport": "dua_mujoco.monitor",
    "SpherePairs": "dua_mujoco.pairs",
    "active_geom_pairs": "dua_mujoco.pairs",
    "cover_model": "dua_mujoco.covering",
    "estimate_bounds": "dua_mujoco.bounds",
    "load_scene": "dua_mujoco.scenes",
    "make_controller": "dua_mujoco.scenes",
    "run": "dua_mujoco.monitor",
    "sphere_pairs": "dua_mujoco.pairs",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'dua_mujoco' has no attribute {name!r}")


__version__ = "0.1.0"

__all__ = [
    "AccelProfile",
    "Alarms",
    "BoundMonitor",
    "BoundViolationWarning",
    "Covering",
    "CoveringMode",
    "CtrlMode",
    "DUAScheduler",
    "DeadlineOverrunWarning",
    "DuaError",
    "GeomPairs",
    "InvalidBoundError",
    "InvalidChoiceError",
    "InvalidInputError",
    "Monitor",
    "MotionBounds",
    "NoActivePairsWarning",
    "NonFiniteStateError",
    "PairSet",
    "Predictor",
    "RunReport",
    "SchedulerError",
    "SelectAllScheduler",
    "ShapeError",
    "SpherePairs",
    "SphereWorld",
    "UnsupportedGeomError",
    "Urgency",
    "__version__",
    "active_geom_pairs",
    "cover_model",
    "distance_urgency",
    "estimate_bounds",
    "load_scene",
    "make_controller",
    "run",
    "sphere_pairs",
    "time_to_collision",
    "time_to_halfspace",
]
