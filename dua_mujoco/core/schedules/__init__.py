"""The schedules: which pairs to evaluate each step, and when a verdict alarms.

All three implement one interface (``Scheduler``: ``select``, ``update``, ``set_active``,
``alarm_state``, and fused steps through ``step_with``) over one typed state
(``ScheduleState``) and one set of compiled kernels (``kernels``).
"""

from __future__ import annotations

import enum

from dua_mujoco.core.schedules.base import FusedKernel, Scheduler
from dua_mujoco.core.schedules.deadline import DeadlineScheduler
from dua_mujoco.core.schedules.dua import DUAScheduler, bucket_layout
from dua_mujoco.core.schedules.select_all import SelectAllScheduler, Urgency
from dua_mujoco.core.schedules.state import ScheduleState

__all__ = [
    "DUAScheduler",
    "DeadlineScheduler",
    "FusedKernel",
    "Schedule",
    "ScheduleState",
    "Scheduler",
    "SelectAllScheduler",
    "Urgency",
    "bucket_layout",
]


class Schedule(enum.Enum):
    """Which schedule a predictor runs."""

    DUA = "dua"
    """The paper's rank buckets: constant work a step, alarm horizons that grow with M."""
    DEADLINE = "deadline"
    """Each pair at the latest step its tau allows: select-all's alarms, far less work."""
    SELECT_ALL = "select-all"
    """Every pair every step (SA(tau)): the baseline."""
