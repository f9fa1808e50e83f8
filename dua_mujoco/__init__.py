"""dua_mujoco: collision prediction for MuJoCo with the Dynamic Urgency Algorithm.

Hayward, Aubry, Foisy, Ghallab: "Efficient Collision Prediction Among Many Moving Objects",
IJRR 1995. The core (``urgency``, ``scheduler``, ``worlds``) imports nothing from MuJoCo; the
MuJoCo layer (``covering``, ``pairs``, ``state``, ``bounds``, ``predictor``, ``monitor``,
``scenes``) builds on it.
"""

from dua_mujoco.bounds import BoundMonitor, MotionBounds, estimate_bounds
from dua_mujoco.covering import Covering, CoveringMode, cover_model
from dua_mujoco.exceptions import (
    BoundViolationWarning,
    DeadlineOverrunWarning,
    DuaError,
    InvalidBoundError,
    InvalidChoiceError,
    InvalidInputError,
    NonFiniteStateError,
    SchedulerError,
    ShapeError,
    UnsupportedGeomError,
)
from dua_mujoco.monitor import Monitor, RunReport, run
from dua_mujoco.pairs import GeomPairs, SpherePairs, active_geom_pairs, sphere_pairs
from dua_mujoco.predictor import Alarms, Predictor
from dua_mujoco.scenes import CtrlMode, load_scene, make_controller
from dua_mujoco.scheduler import DUAScheduler, PairSet, SelectAllScheduler, Urgency
from dua_mujoco.urgency import distance_urgency, time_to_collision, time_to_halfspace
from dua_mujoco.worlds import AccelProfile, SphereWorld

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
