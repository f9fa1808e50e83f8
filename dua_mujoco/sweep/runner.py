"""One run of a sweep: a task in, a row out, whatever happens inside.

:func:`run_task` is what a worker process or a Ray task calls. It never raises for a failing run:
the error becomes the row's ``error``, so one bad scene is one row, not a lost sweep.
"""

from __future__ import annotations

import argparse
import time
import traceback
import warnings
from dataclasses import dataclass
from typing import Any

__all__ = ["COLUMNS", "DETERMINISTIC", "Task", "failed_row", "run_task"]

COLUMNS = (
    "scene",
    "seed",
    "set",
    "steps",
    "onsets",
    "predicted",
    "missed",
    "missed_valid_bounds",
    "missed_outside_violations",
    "standing_fraction",
    "oracle_fraction",
    "warning_horizon_s",
    "lead_p10_s",
    "lead_median_s",
    "short_lead",
    "short_lead_held",
    "short_lead_after_violation",
    "short_lead_at_start",
    "evals_per_step",
    "predictor_us",
    "mj_step_us",
    "predictor_share",
    "bound_violations",
    "bound_violations_out_of_contact",
    "warnings",
    "error",
    "seconds",
)
"""A row's keys, in the table's order. Counts are of contact onsets (``onsets``) and of those
missed: all, while the bounds held, and outside a bound violation's period (a bug). Beside the
standing fraction, the oracle (the share of pairs that do touch within ``warning_horizon_s``);
the onsets' leads (p10, median) and those with less lead than the horizon: all, while the bounds
held, after a violation and at the start (``RunReport``)."""

DETERMINISTIC = tuple(
    c for c in COLUMNS if c not in ("predictor_us", "mj_step_us", "predictor_share", "seconds")
)
"""The columns that depend on the task only, not on the machine's load: equal wherever it ran."""


@dataclass(frozen=True)
class Task:
    """A run of a sweep: ``scene`` with the ``run`` options of set ``set_name`` at ``seed``."""

    scene: str
    seed: int
    set_name: str
    options: argparse.Namespace

    def row(self, **values: Any) -> dict[str, Any]:
        """A row of this task: its keys first, then ``values``, the rest None."""
        row: dict[str, Any] = dict.fromkeys(COLUMNS)
        row.update(scene=self.scene, seed=self.seed, set=self.set_name, **values)
        return row


def failed_row(task: Task, error: str, seconds: float | None = None) -> dict[str, Any]:
    """The row of a run that did not finish: ``error`` says why, in one line."""
    return task.row(error=" ".join(error.split()), seconds=seconds)


def run_task(task: Task) -> dict[str, Any]:
    """Run ``task`` as ``dua-mujoco run`` would (no progress bar, no series) and return its row.

    Warnings (a bound broken, a pilot that never moved a body) are counted into the row, one
    line each, instead of printed. An exception ends the run and becomes the row's ``error``.
    """
    from dua_mujoco.cli import keyframe_arg, load_scene_arg
    from dua_mujoco.exceptions import DuaError
    from dua_mujoco.measure.rollout import run
    from dua_mujoco.run_options import controller_for, default_steps, predictor_for

    start = time.perf_counter()
    options = argparse.Namespace(**{**vars(task.options), "seed": task.seed, "scene": task.scene})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            model, data = load_scene_arg(task.scene, keyframe_arg(options))
            steps = default_steps(task.scene) if options.steps is None else options.steps
            predictor = predictor_for(model, options)
            report = run(
                model,
                data,
                predictor,
                steps=steps,
                controller=controller_for(model, options, predictor),
                scene=task.scene,
                realtime=options.realtime,
                geom_distance=options.geom_distance,
                progress=False,
                series=False,
            )
        except Exception as exc:  # one failing run is one row: the sweep goes on
            where = ""
            if not isinstance(exc, DuaError):  # not a reason we gave: say where it came from
                last = traceback.extract_tb(exc.__traceback__)[-1]
                where = f" ({last.filename.rsplit('/', 1)[-1]}:{last.lineno})"
            return failed_row(task, f"{type(exc).__name__}: {exc}{where}", _since(start))
    seen = sorted({f"{w.category.__name__}: {' '.join(str(w.message).split())}" for w in caught})
    return task.row(
        steps=report.physics_steps,
        onsets=report.contact_onsets,
        predicted=report.predicted_onsets,
        missed=report.missed_onsets,
        missed_valid_bounds=report.missed_onsets_valid_bounds,
        missed_outside_violations=report.missed_onsets_outside_violations,
        standing_fraction=report.standing_alarm_fraction,
        oracle_fraction=report.oracle_fraction,
        warning_horizon_s=report.warning_horizon_s,
        lead_p10_s=report.lead_p10_s,
        lead_median_s=report.lead_median_s,
        short_lead=report.short_lead_onsets,
        short_lead_held=report.short_lead_bounds_held,
        short_lead_after_violation=report.short_lead_after_violation,
        short_lead_at_start=report.short_lead_at_start,
        evals_per_step=report.evals_per_step,
        predictor_us=report.predictor_us_per_step,
        mj_step_us=report.mj_step_us_per_step,
        predictor_share=report.predictor_share,
        bound_violations=report.bound_violations,
        bound_violations_out_of_contact=report.bound_violations_out_of_contact,
        warnings=seen,
        seconds=_since(start),
    )


def _since(start: float) -> float:
    return round(time.perf_counter() - start, 3)
