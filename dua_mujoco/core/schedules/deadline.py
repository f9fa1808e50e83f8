"""``DeadlineScheduler``: each pair revisited at the latest step its own tau allows.

DUA sizes its buckets by rank, so in a simulator's fixed clock most pairs alarm. The deadline
schedule keys the revisit on tau instead: a pair evaluated at step ``n`` is next due at
``n + s``, ``s`` the largest interval with ``(s + latency) dt <= tau``, so it alarms only when even
``s = 1`` is not covered (select-all's rule), at about ``sum(dt / tau)`` evaluations a step. A pair
that keeps alarming is evaluated after 1, 2, 4, then every ``alarm_backoff`` steps. Due pairs
wait in a timing wheel (O(1) an evaluation); an optional cap serves those with the least time
left and reports the rest (``deferred``). Completeness, with and without the cap:
docs/theory.md, section 3.
"""

from __future__ import annotations

import numpy.typing as npt

import dua_mujoco._core as _core
from dua_mujoco.core.schedules.base import Scheduler, active_mask, standing
from dua_mujoco.core.schedules.state import DEADLINE, P_BACKOFF, P_CAP, P_MAX_INTERVAL
from dua_mujoco.core.validate import check_int, check_period, check_urgencies

__all__ = ["DEFAULT_ALARM_BACKOFF", "DeadlineScheduler", "check_alarm_backoff", "check_max_evals"]

DEFAULT_MAX_INTERVAL = 1024
"""Longest revisit interval (steps) by default: 2 s at MuJoCo's 2 ms, a few % of the work."""

DEFAULT_ALARM_BACKOFF = 8
"""Longest revisit interval (steps) of a pair that keeps alarming, by default: 16 ms at
MuJoCo's 2 ms. Measured on six scenes (docs/benchmarks.md): it cuts the evaluations
a step 1.5-3.4x (resting contacts stop costing one each a step) while the share of pairs
standing in alarm grows by 0.1-3 % of itself."""


def check_max_evals(value: object) -> int:
    """``max_evals_per_step``: None (no cap, returned as 0) or an int ``>= 1``."""
    return 0 if value is None else check_int("max_evals_per_step", value, 1, ", or None for no cap")


def check_alarm_backoff(value: object) -> int:
    """``alarm_backoff``: an int ``>= 1`` (steps)."""
    return check_int("alarm_backoff", value, 1, " (steps; 1 re-evaluates alarmed pairs every step)")


class DeadlineScheduler(Scheduler, kind=DEADLINE):
    """Revisit each pair at the latest step that keeps the guarantee, given its own tau.

    Args:
        tau0: ``(M,)`` tau of every pair at time 0 (the initial classification).
        dt: Predictor period ``> 0`` (seconds between steps).
        latency: As for ``DUAScheduler``.
        max_evals_per_step: Optional cap on tau evaluations a step (None: no cap). Pairs due
            beyond it wait, least time left served first; see :attr:`deferred`.
        max_interval: Longest revisit interval in steps (``>= 1``): a pair far from everything
            is still looked at every ``max_interval`` steps.
        alarm_backoff: Longest revisit interval in steps (``>= 1``, at most ``max_interval``)
            of a pair that keeps alarming: evaluated at the next step after its first alarm,
            then after twice its last wait while it alarms again, standing in alarm in between.
            1 evaluates every alarmed pair every step (exactly select-all's alarms); larger
            values spare the pairs in resting contact (docs/theory.md, section 3).
        active: Optional ``(M,)`` bool mask of pairs initially switched on (default all).
    """

    def __init__(
        self,
        tau0: npt.ArrayLike,
        *,
        dt: float,
        latency: int = 1,
        max_evals_per_step: int | None = None,
        max_interval: int = DEFAULT_MAX_INTERVAL,
        alarm_backoff: int = DEFAULT_ALARM_BACKOFF,
        active: npt.ArrayLike | None = None,
    ) -> None:
        tau = check_urgencies("tau0", tau0)
        dt, latency = check_period(dt, latency)
        cap = check_max_evals(max_evals_per_step)
        max_interval = check_int("max_interval", max_interval)
        backoff = check_alarm_backoff(alarm_backoff)
        schedule = _core.Schedule(
            DEADLINE,
            dt,
            latency,
            tau,
            active_mask(active, tau.shape[0]),
            cap=cap,
            max_interval=int(max_interval),
            backoff=backoff,
        )
        self._wrap(schedule, standing(schedule))
        self._derive()

    def _derive(self) -> None:
        params = self.state.params
        self.max_evals_per_step = int(params[P_CAP]) or None
        self.max_interval = int(params[P_MAX_INTERVAL])
        self.alarm_backoff = int(params[P_BACKOFF])
