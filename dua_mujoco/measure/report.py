"""What a monitored run reports: ``RunReport``, its misses, and the interrupt that carries it."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from dua_mujoco.exceptions import InvalidInputError

__all__ = ["Miss", "RunInterrupted", "RunReport"]


@dataclasses.dataclass(frozen=True)
class Miss:
    """A contact onset that no standing alarm covered.

    ``bounds_held``: no hypothesis a verdict in force rested on (a body's bounds, or its plan's
    deviation) broke since that verdict's evaluation (each sphere pair's latest).
    ``in_violation_period``: one of those broke after the latest predictor step at or
    before the onset (two steps with pruned pairs), so no step had seen it yet: the guarantee's
    one exception (docs/theory.md, section 6). A miss that is not in a violation's period is a
    bug.
    """

    physics_step: int
    time: float
    geom1: str
    geom2: str
    bounds_held: bool
    last_evaluation_step: int
    last_tau: float
    in_violation_period: bool = False


@dataclasses.dataclass(frozen=True)
class RunReport:
    """Metrics of a monitored run (``to_dict`` gives the CLI's JSON report).

    ``alarms_per_step`` (int32) and ``min_tau_per_step`` (float64, ``inf`` without alarms) hold
    one entry per predictor step, entry 0 the initial classification, when the run recorded
    series (``run(..., series=True)``), else None. ``standing_alarm_fraction`` is the mean over
    predictor steps of the fraction of active geom pairs standing in alarm after the step's
    verdicts; ``contact_pair_fraction`` the same mean for active geom pairs in MuJoCo's contacts
    at that step (alarms no predictor can avoid), and ``oracle_fraction`` the same mean for active
    geom pairs that touch at some step within ``warning_horizon_s`` of it (the floor under the
    standing fraction of any predictor that warns that long ahead; steps whose window runs past
    the end count the contacts seen until then). ``lead_*_s`` are the 10th percentile (a lead
    some onset had: the lower one), median and minimum of the onsets' leads, how long an alarm
    had stood for each without a break (0 for a miss; None without onsets);
    ``short_lead_onsets`` counts the onsets with less lead than ``warning_horizon_s``, split into
    ``short_lead_bounds_held`` (the promise allows none while ``warning_horizon_s`` is the
    predictor's alarm horizon, the default, at any ``period``: docs/theory.md, sections 3 and
    8), ``short_lead_after_violation`` and ``short_lead_at_start``
    (:mod:`~dua_mujoco.measure.warning_time`).
    ``missed_onsets_outside_violations`` counts the misses not in a violation's period
    (:class:`Miss`): the guarantee covers them, so any is a bug. ``broken_bound_bodies`` names
    the bodies that broke their declared bounds; ``bound_violations_out_of_contact`` counts the
    violations (body steps) of bodies whose kinematic tree was in no contact at that step nor
    the two before: free motion beyond the declared bounds, not a contact's impulse.
    ``interrupted`` marks a run stopped early (Ctrl-C), whose ``physics_steps`` are those
    observed.
    """

    scene: str
    physics_steps: int
    predictor_steps: int
    period: int
    spheres: int
    pairs: int
    geom_pairs: int
    evals_per_step: float
    contact_onsets: int
    predicted_onsets: int
    missed_onsets: int
    missed_onsets_valid_bounds: int
    missed_onsets_outside_violations: int
    inactive_pair_contacts: int
    unfiltered_contacts: int
    alarm_episodes: int
    false_alarm_episodes: int
    bound_violations: int
    deadline_overruns: int
    exact_distance_median_m: float | None
    predictor_us_per_step: float
    mj_step_us_per_step: float
    misses: tuple[Miss, ...] = ()
    alarms_per_step: np.ndarray | None = None
    min_tau_per_step: np.ndarray | None = None
    realtime: bool = False
    standing_alarm_fraction: float = 0.0
    contact_pair_fraction: float = 0.0
    broken_bound_bodies: tuple[str, ...] = ()
    bound_violations_out_of_contact: int = 0
    interrupted: bool = False
    oracle_fraction: float = 0.0
    warning_horizon_s: float = 0.0
    lead_p10_s: float | None = None
    lead_median_s: float | None = None
    lead_min_s: float | None = None
    short_lead_onsets: int = 0
    short_lead_bounds_held: int = 0
    short_lead_after_violation: int = 0
    short_lead_at_start: int = 0

    @property
    def evals_fraction(self) -> float:
        """tau evaluations per step as a fraction of all pairs (SA's cost)."""
        return self.evals_per_step / max(self.pairs, 1)

    @property
    def predictor_share(self) -> float:
        """Predictor time per physics step over ``mj_step`` time (medians).

        ``predictor_us_per_step`` is per predictor call, made every ``period`` physics steps.
        """
        if self.mj_step_us_per_step <= 0.0:
            return 0.0
        return self.predictor_us_per_step / (self.period * self.mj_step_us_per_step)

    def to_dict(self, *, series: bool = False) -> dict[str, Any]:
        """JSON-ready dict; ``series=True`` adds the per-step alarm and tau series.

        Raises:
            InvalidInputError: ``series=True`` for a run that recorded none.
        """
        out = dataclasses.asdict(self)
        out["misses"] = [dataclasses.asdict(m) for m in self.misses]
        out["broken_bound_bodies"] = list(self.broken_bound_bodies)
        out["predictor_share"] = self.predictor_share
        out.pop("alarms_per_step")
        out.pop("min_tau_per_step")
        if series:
            if self.alarms_per_step is None or self.min_tau_per_step is None:
                raise InvalidInputError(
                    "this report holds no per-step series: run it with run(..., series=True) "
                    "(dua-mujoco run --series)."
                )
            out["alarms_per_step"] = self.alarms_per_step.tolist()
            # JSON has no infinity: a step without alarms has null.
            tau = self.min_tau_per_step.astype(object)
            tau[~np.isfinite(self.min_tau_per_step)] = None
            out["min_tau_per_step"] = tau.tolist()
        return out

    def summary_rows(self) -> list[tuple[str, str]]:
        """(label, value) rows for a readable table."""
        leads = (self.lead_p10_s, self.lead_median_s, self.lead_min_s)
        lead = (
            "n/a"
            if self.lead_min_s is None
            else " / ".join(f"{1e3 * (v or 0.0):.1f}" for v in leads) + " ms"
        )
        steps = f"{self.physics_steps} ({self.period})"
        rows = [
            ("scene", self.scene),
            (
                "physics steps (predictor period)",
                f"{steps}, interrupted" if self.interrupted else steps,
            ),
            (
                "spheres / sphere pairs / geom pairs",
                f"{self.spheres} / {self.pairs} / {self.geom_pairs}",
            ),
            (
                "tau evaluations per step",
                f"{self.evals_per_step:.1f} ({100 * self.evals_fraction:.2f} % of SA)",
            ),
            ("contact onsets", str(self.contact_onsets)),
            ("predicted onsets", str(self.predicted_onsets)),
            ("missed onsets", str(self.missed_onsets)),
            ("  outside a violation's period", str(self.missed_onsets_outside_violations)),
            ("  while the bounds held", str(self.missed_onsets_valid_bounds)),
            ("contacts in switched-off pairs", str(self.inactive_pair_contacts)),
            ("alarm episodes (false)", f"{self.alarm_episodes} ({self.false_alarm_episodes})"),
            ("active geom pairs in alarm (mean)", f"{100 * self.standing_alarm_fraction:.2f} %"),
            ("active geom pairs in contact (mean)", f"{100 * self.contact_pair_fraction:.2f} %"),
            (
                f"  touching within {1e3 * self.warning_horizon_s:.4g} ms (oracle)",
                f"{100 * self.oracle_fraction:.2f} %",
            ),
            ("onset lead p10 / median / min", lead),
            (
                f"onsets with lead < {1e3 * self.warning_horizon_s:.4g} ms",
                str(self.short_lead_onsets),
            ),
            (
                "  held / after violation / at start",
                f"{self.short_lead_bounds_held} / {self.short_lead_after_violation} / "
                f"{self.short_lead_at_start}",
            ),
            ("bound violations (body-steps)", str(self.bound_violations)),
            ("  of them out of contact", str(self.bound_violations_out_of_contact)),
            (
                "predictor us/call vs mj_step us/step",
                f"{self.predictor_us_per_step:.1f} vs {self.mj_step_us_per_step:.1f} "
                f"({100 * self.predictor_share:.0f} % of physics time)",
            ),
        ]
        if self.realtime:
            rows.append(("deadline overruns", str(self.deadline_overruns)))
        if self.exact_distance_median_m is not None:
            rows.append(
                ("median exact distance of alarmed pairs", f"{self.exact_distance_median_m:.4f} m")
            )
        return rows

    def table(self) -> str:
        """The summary as an aligned two-column text table."""
        rows = self.summary_rows()
        w = max(len(k) for k, _ in rows)
        return "\n".join(f"{k.ljust(w)}  {v}" for k, v in rows)


class RunInterrupted(KeyboardInterrupt):
    """A Ctrl-C stopped :func:`run`: a ``KeyboardInterrupt`` that carries the partial report.

    Attributes:
        report: The :class:`RunReport` of the physics steps observed before the interrupt
            (``interrupted=True``).
    """

    def __init__(self, report: RunReport) -> None:
        super().__init__(
            f"interrupted after {report.physics_steps} physics steps (the report covers them)"
        )
        self.report = report
