"""``SelectAllScheduler``: every active pair every step (the paper's SA(tau) and SA(d), sec. 8)."""

from __future__ import annotations

import enum

import numpy as np
import numpy.typing as npt

import dua_mujoco._core as _core
from dua_mujoco.core.schedules.base import Scheduler, active_mask, standing
from dua_mujoco.core.schedules.state import ALL
from dua_mujoco.core.validate import as_choice, check_period, check_urgencies, real_array
from dua_mujoco.exceptions import ShapeError

__all__ = ["SelectAllScheduler", "Urgency"]


class Urgency(enum.Enum):
    """What a select-all baseline ranks pairs by."""

    TAU = "tau"
    """Time to collision (docs/theory.md): the paper's SA(tau)."""
    DISTANCE = "distance"
    """Clearance ``|x| - eps``: the paper's SA(d)."""


class SelectAllScheduler(Scheduler, kind=ALL):
    """The select-all baselines: every active pair every step.

    Args:
        urgency0: ``(M,)`` initial urgency (tau, or clearance for ``Urgency.DISTANCE``).
        dt: Predictor period ``> 0``.
        urgency: ``Urgency.TAU`` (alarm if ``tau < (1 + latency) dt``) or ``Urgency.DISTANCE``
            (alarm if the clearance is below ``alarm_distance``).
        latency: As for ``DUAScheduler``.
        alarm_distance: Clearance below which SA(d) alarms (default 0: only overlaps).
        active: Optional ``(M,)`` bool mask.
    """

    def __init__(
        self,
        urgency0: npt.ArrayLike,
        *,
        dt: float,
        urgency: Urgency | str = Urgency.TAU,
        latency: int = 1,
        alarm_distance: float = 0.0,
        active: npt.ArrayLike | None = None,
    ) -> None:
        self.urgency = as_choice(Urgency, urgency, "urgency")
        dt, latency = check_period(dt, latency)
        if self.urgency is Urgency.TAU:
            values = check_urgencies("urgency0", urgency0)
            threshold = (1 + latency) * dt
        else:
            values = real_array("urgency0", urgency0)
            if values.ndim != 1 or np.isnan(values).any():
                raise ShapeError(
                    f"urgency0 must be a (M,) array without NaN; got shape {values.shape}."
                )
            threshold = float(alarm_distance)
        self.alarm_distance = float(alarm_distance)
        schedule = _core.Schedule(
            ALL,
            dt,
            latency,
            values,
            active_mask(active, values.shape[0]),
            threshold=float(threshold),
        )
        self._wrap(schedule, standing(schedule))

    def _derive(self) -> None:
        # A schedule made elsewhere (Scheduler.of): tau's threshold, or SA(d)'s distance.
        threshold = float(self.state.horizon[0])
        tau = threshold == (1 + self.latency) * self.dt
        self.urgency = Urgency.TAU if tau else Urgency.DISTANCE
        self.alarm_distance = 0.0 if tau else threshold

    @property
    def threshold(self) -> float:
        """The alarm threshold on the urgency value."""
        return float(self.state.horizon[0])

    @property
    def last(self) -> np.ndarray:
        """``(M,)`` the latest urgency of every pair."""
        return self.state.last_tau

    @property
    def evaluations_per_step(self) -> int:
        """Active pairs (all evaluated every step)."""
        return int(self.state.active.sum())
