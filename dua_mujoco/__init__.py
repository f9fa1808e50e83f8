"""dua_mujoco: collision prediction for MuJoCo with the Dynamic Urgency Algorithm.

Hayward, Aubry, Foisy, Ghallab: "Efficient Collision Prediction Among Many Moving Objects",
IJRR 1995. The core (``urgency``, ``scheduler``, ``worlds``) is independent of MuJoCo.
"""

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
from dua_mujoco.scheduler import DUAScheduler, PairSet, SelectAllScheduler, Urgency
from dua_mujoco.urgency import distance_urgency, time_to_collision, time_to_halfspace
from dua_mujoco.worlds import AccelProfile, SphereWorld

__version__ = "0.1.0"

__all__ = [
    "AccelProfile",
    "BoundViolationWarning",
    "DUAScheduler",
    "DeadlineOverrunWarning",
    "DuaError",
    "InvalidBoundError",
    "InvalidChoiceError",
    "InvalidInputError",
    "NonFiniteStateError",
    "PairSet",
    "SchedulerError",
    "SelectAllScheduler",
    "ShapeError",
    "SphereWorld",
    "UnsupportedGeomError",
    "Urgency",
    "__version__",
    "distance_urgency",
    "time_to_collision",
    "time_to_halfspace",
]
