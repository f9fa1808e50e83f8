"""A monitored rollout: :func:`run` drives the controller, ``mj_step``, the predictor every
``period`` steps and a :class:`~dua_mujoco.measure.monitor.Monitor`, and returns the
``RunReport`` that :func:`build_report` makes of the monitor and the timings."""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable

import mujoco
import numpy as np

from dua_mujoco.build.tables import same_geometry
from dua_mujoco.core.validate import check_int
from dua_mujoco.exceptions import DeadlineOverrunWarning, InvalidInputError
from dua_mujoco.measure.accumulators import Durations
from dua_mujoco.measure.monitor import Monitor
from dua_mujoco.measure.report import RunInterrupted, RunReport
from dua_mujoco.progress import Progress
from dua_mujoco.runtime.alarms import Alarms
from dua_mujoco.runtime.predictor import Predictor

__all__ = ["build_report", "run"]

Controller = Callable[[mujoco.MjModel, mujoco.MjData], None]


def run(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    predictor: Predictor,
    *,
    steps: int,
    controller: Controller | None = None,
    scene: str = "",
    realtime: bool = False,
    geom_distance: bool = False,
    progress: bool = True,
    on_step: Callable[[int, mujoco.MjData, Alarms | None, Monitor], None] | None = None,
    series: bool = True,
    warning_horizon: float | None = None,
) -> RunReport:
    """Roll out ``steps`` physics steps with prediction and the exact stage.

    The first ``mj_step`` brings ``data`` to a consistent state (kinematics and contacts of one
    instant); the predictor is reset there and stepped every ``predictor.period`` steps after.
    Memory does not grow with ``steps`` except for the per-step series (``series``, 12 bytes a
    predictor step) and the misses.

    Args:
        data: The data, at the start state (e.g. after ``load_scene``).
        predictor: The predictor (built for ``model``).
        steps: Physics steps after the reset.
        controller: ``controller(model, data)`` called before each ``mj_step``.
        scene: Name recorded in the report.
        realtime: Time each predictor step and count those slower than ``predictor.dt``
            (``monitor.overruns``, the report's ``deadline_overruns``), warning at the first.
        geom_distance: Measure alarmed pairs with ``mj_geomDistance`` (see ``Monitor``).
        progress: Draw a progress bar on stderr.
        on_step: Called after each physics step with ``(k, data, alarms or None, monitor)``.
        series: Record the alarm count and minimum tau of every predictor step in the report
            (``alarms_per_step``, ``min_tau_per_step``); False keeps memory flat.
        warning_horizon: The horizon (s) the leads and the oracle are measured against; None
            for the predictor's own alarm horizon (see ``Monitor``).

    Raises:
        RunInterrupted: On a ``KeyboardInterrupt`` during the rollout (Ctrl-C, or raised by the
            controller or ``on_step``), with the report of the steps observed until then.
    """
    check_int("steps", steps, 1, " (physics steps)")
    if model is not predictor.model and not same_geometry(model, predictor.model):
        raise InvalidInputError(
            "the predictor was built for another MjModel: pass the model it was built for "
            "(Predictor(model, ...)), or build a Predictor for this one."
        )
    predictor.check_data(data)  # before the controller writes into it
    monitor = Monitor(
        predictor,
        geom_distance=geom_distance,
        series=series,
        warning_horizon=warning_horizon,
    )
    if controller is not None:
        controller(model, data)
    mujoco.mj_step(model, data)
    monitor.start(data)
    period = predictor.period
    t_mj = Durations()
    t_pred = Durations()
    try:
        with Progress(steps, scene or "run", enabled=progress) as bar:
            for k in range(1, steps + 1):
                if controller is not None:
                    controller(model, data)
                t0 = time.perf_counter()
                mujoco.mj_step(model, data)
                t1 = time.perf_counter()
                t_mj.add(t1 - t0)
                alarms = None
                if k % period == 0:
                    t2 = time.perf_counter()
                    alarms = predictor.step(data)
                    dt = time.perf_counter() - t2
                    t_pred.add(dt)
                    if realtime and dt > predictor.dt:
                        monitor.overruns += 1
                        if monitor.overruns == 1:  # warned once
                            warnings.warn(
                                f"predictor step took {dt * 1e6:.0f} us > period "
                                f"{predictor.dt * 1e6:.0f} us: the predictor cannot keep up, "
                                "completeness is not guaranteed.",
                                DeadlineOverrunWarning,
                                stacklevel=2,
                            )
                monitor.observe(data, alarms)
                if on_step is not None:
                    on_step(k, data, alarms, monitor)
                bar.update(
                    note=f"alarms {0 if alarms is None else len(alarms)} "
                    f"missed {len(monitor.misses)}"
                )
    except KeyboardInterrupt as exc:
        monitor.finish()
        report = build_report(monitor, scene, realtime, t_mj, t_pred, interrupted=True)
        raise RunInterrupted(report) from exc
    monitor.finish()
    return build_report(monitor, scene, realtime, t_mj, t_pred, interrupted=False)


def build_report(
    monitor: Monitor,
    scene: str,
    realtime: bool,
    t_mj: Durations,
    t_pred: Durations,
    *,
    interrupted: bool,
) -> RunReport:
    predictor = monitor.predictor
    alarms_series, tau_series = (None, None) if monitor.series is None else monitor.series.arrays()
    broken = np.flatnonzero(monitor.last_violation >= 0)
    distances = monitor.exact_distances
    warning = monitor.warning
    p10, median, least = warning.lead_quantiles()
    return RunReport(
        scene=scene,
        physics_steps=monitor.physics_step,
        predictor_steps=t_pred.count,
        period=predictor.period,
        spheres=predictor.nsphere,
        # Of the whole model: a pruned predictor knows the pairs it met, and counts the rest.
        pairs=predictor.universe.counts()[1],
        geom_pairs=predictor.universe.counts()[0],
        evals_per_step=monitor.evaluation_sum / max(monitor.predictor_steps, 1),
        contact_onsets=monitor.onsets,
        predicted_onsets=monitor.predicted,
        missed_onsets=len(monitor.misses),
        missed_onsets_valid_bounds=sum(m.bounds_held for m in monitor.misses),
        missed_onsets_outside_violations=sum(not m.in_violation_period for m in monitor.misses),
        inactive_pair_contacts=monitor.inactive_contacts,
        unfiltered_contacts=monitor.unfiltered_contacts,
        alarm_episodes=monitor.episodes,
        false_alarm_episodes=monitor.false_episodes,
        bound_violations=monitor.violations,
        bound_violations_out_of_contact=monitor.free_violations,
        deadline_overruns=monitor.overruns,
        exact_distance_median_m=float(np.median(distances)) if distances.size else None,
        predictor_us_per_step=t_pred.median() * 1e6,
        mj_step_us_per_step=t_mj.median() * 1e6,
        misses=tuple(monitor.misses),
        alarms_per_step=alarms_series,
        min_tau_per_step=tau_series,
        realtime=realtime,
        standing_alarm_fraction=monitor.standing_alarm_fraction,
        contact_pair_fraction=monitor.contact_pair_fraction,
        broken_bound_bodies=tuple(
            monitor.model.body(int(b)).name or str(int(b)) for b in broken.tolist()
        ),
        interrupted=interrupted,
        oracle_fraction=monitor.oracle_fraction,
        warning_horizon_s=warning.horizon,
        lead_p10_s=p10,
        lead_median_s=median,
        lead_min_s=least,
        short_lead_onsets=warning.short_leads,
        short_lead_bounds_held=warning.short_held,
        short_lead_after_violation=warning.short_after_violation,
        short_lead_at_start=warning.short_at_start,
    )
