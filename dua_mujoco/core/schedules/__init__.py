"""The schedules: which pairs to evaluate each step, and when a verdict alarms.

All three implement one interface (``Scheduler``: ``select``, ``update``, ``set_active``,
``alarm_state``, and the fused step ``step_points``) over one state (``ScheduleState``, views of a
``dua_mujoco._core.Schedule``) and the native core's kernels (``csrc/src/schedule.cc``).
"""

from __future__ import annotations

import enum

import numpy as np

from dua_mujoco._core import LAYOUT, TABLES_VERSION
from dua_mujoco.core.schedules.base import Scheduler
from dua_mujoco.core.schedules.deadline import (
    DEFAULT_ALARM_BACKOFF,
    DEFAULT_MAX_INTERVAL,
    DeadlineScheduler,
)
from dua_mujoco.core.schedules.dua import DUAScheduler, bucket_layout
from dua_mujoco.core.schedules.select_all import SelectAllScheduler, Urgency
from dua_mujoco.core.schedules.state import ScheduleState
from dua_mujoco.core.validate import as_choice

__all__ = [
    "DUAScheduler",
    "DeadlineScheduler",
    "Schedule",
    "ScheduleState",
    "Scheduler",
    "SelectAllScheduler",
    "Urgency",
    "as_schedule",
    "bucket_layout",
    "schedule_config",
]


class Schedule(enum.Enum):
    """Which schedule a predictor runs."""

    DUA = "dua"
    """The paper's rank buckets: constant work a step, alarm horizons that grow with M."""
    DEADLINE = "deadline"
    """Each pair at the latest step its tau allows: select-all's alarms, far less work."""
    SELECT_ALL = "select-all"
    """Every pair every step (SA(tau)): the baseline."""


def schedule_config(
    schedule: Schedule,
    *,
    dt: float,
    latency: int,
    alarm_periods: int = 1,
    slots_per_bucket: int = 1,
    max_evals_per_step: int | None = None,
    alarm_backoff: int = DEFAULT_ALARM_BACKOFF,
    screen: bool = False,
) -> np.ndarray:
    """A runtime's ``config`` table, ``(CFG_SIZE,)`` float64, with the schedule's entries
    written and the rest 0 for the caller (``Predictor``'s and ``SpherePredictor``'s tables
    alike; ``ScheduleSpec::Check`` checks them in C++).

    The alarm horizon goes in seconds, ``alarm_periods * dt`` (the ``Predictor``'s own
    ``alarm_horizon``), and select-all's threshold on tau is the horizon past the latency,
    ``(alarm_periods + latency) dt``. ``screen`` keeps the deadline schedule's screen (other
    kinds have none).
    """
    kind = {Schedule.DUA: "RANK", Schedule.DEADLINE: "DEADLINE", Schedule.SELECT_ALL: "ALL"}
    c = np.zeros(LAYOUT["CFG_SIZE"])
    c[LAYOUT["CFG_VERSION"]] = TABLES_VERSION
    c[LAYOUT["CFG_KIND"]] = LAYOUT[kind[schedule]]
    c[LAYOUT["CFG_DT"]], c[LAYOUT["CFG_LATENCY"]] = dt, latency
    c[LAYOUT["CFG_SLOTS_PER_BUCKET"]] = slots_per_bucket
    c[LAYOUT["CFG_CAP"]] = max_evals_per_step or 0
    c[LAYOUT["CFG_MAX_INTERVAL"]] = DEFAULT_MAX_INTERVAL
    c[LAYOUT["CFG_BACKOFF"]] = alarm_backoff
    c[LAYOUT["CFG_THRESHOLD"]] = (alarm_periods + latency) * dt
    c[LAYOUT["CFG_ALARM_HORIZON"]] = alarm_periods * dt
    c[LAYOUT["CFG_SCREEN"]] = 1.0 if screen and schedule is Schedule.DEADLINE else 0.0
    return c


def as_schedule(schedule: Schedule | str) -> Schedule:
    """``schedule`` as a ``Schedule``, or an error listing the choices."""
    return as_choice(Schedule, schedule, "schedule")
