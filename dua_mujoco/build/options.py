"""The Predictor's options, grouped: what covers the geoms, which pairs are held, how they are
scheduled, how urgency is computed, and how a pilot rollout estimates the bounds.

Each group is a small frozen dataclass, validated when made, so a bad value fails where it is
written, with a message that names it. ``Predictor(covering=..., schedule=..., pairs=...)``
also takes a plain mode (a string or enum) for the group's defaults otherwise.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Callable

import mujoco
import numpy as np

from dua_mujoco import _core
from dua_mujoco.build.bounds import PilotMotion
from dua_mujoco.core.schedules import Schedule, as_schedule, deadline
from dua_mujoco.core.schedules.state import RANK
from dua_mujoco.core.spheres import PairMode
from dua_mujoco.core.validate import as_choice, check_int, check_number
from dua_mujoco.exceptions import InvalidInputError

__all__ = [
    "REMOVED_KEYWORDS",
    "CoveringOptions",
    "PairOptions",
    "PilotOptions",
    "PredictorOptions",
    "ScheduleOptions",
    "UrgencyOptions",
    "alarm_periods",
    "removed_keywords_error",
    "resolve_options",
]


def _set(obj: object, name: str, value: object) -> None:
    object.__setattr__(obj, name, value)  # a frozen dataclass normalising its own field


@dataclasses.dataclass(frozen=True, kw_only=True)
class CoveringOptions:
    """How geoms become spheres (docs/covering-and-pairs.md).

    Attributes:
        mode: ``"bounding"`` (one sphere a geom) or ``"multi"`` (a ``CoveringMode`` or its value).
        max_spheres_per_geom: Budget of the multi-sphere covering.
        hfield: ``"terrain"``: static height fields are held as the prisms of their grid
            (docs/theory.md, section 9); ``"box"``: covered by their bounding box
            (conservative, loose); ``"error"``: refused.
        static: ``"shape"``: geoms welded to the world are held as their own convex shapes
            (docs/static-shapes.md); ``"sphere"``: covered like moving geoms.
    """

    mode: str = "bounding"
    max_spheres_per_geom: int = 8
    hfield: str = "terrain"
    static: str = "shape"

    def __post_init__(self) -> None:
        _set(self, "mode", getattr(self.mode, "value", self.mode))
        check_int("max_spheres_per_geom", self.max_spheres_per_geom)


@dataclasses.dataclass(frozen=True, kw_only=True)
class ScheduleOptions:
    """Which pairs a step evaluates (README's schedule table; docs/theory.md).

    Attributes:
        kind: ``"deadline"`` (default), ``"dua"`` or ``"select-all"`` (a ``Schedule`` or its
            value).
        slots_per_bucket: ``dua`` only: the budget knob (a power of two).
        max_evals_per_step: ``deadline`` only: optional cap on tau evaluations a step.
        alarm_backoff: ``deadline`` only: a pair that keeps alarming is evaluated after twice its
            last wait, up to this many steps; 1 (and ``screen=False``) gives select-all's alarms
            exactly.
        violation_events: Each step first checks every moving body's motion against its
            bounds, and the pairs of a body that broke them are evaluated again at once (their
            verdicts assumed the bounds): a contact's impulse then costs no later collision
            (docs/theory.md, section 6). False keeps verdicts until their deadline, for A/B runs.
        screen: ``deadline`` only: a pair out of alarm that a reach test clears for the next
            step leaves the wheel, and the test (a few operations, no tau) clears it each step
            until it fails; then it is evaluated (docs/theory.md, section 3, "The screen").
            Off while a flight plan is set, while a shield or the gymnasium wrapper watches the
            pairs, and with ``period > 1``. False keeps every pair on the wheel, for A/B runs.
    """

    kind: Schedule | str = Schedule.DEADLINE
    slots_per_bucket: int = 1
    max_evals_per_step: int | None = None
    alarm_backoff: int = deadline.DEFAULT_ALARM_BACKOFF
    violation_events: bool = True
    screen: bool = True

    def __post_init__(self) -> None:
        _set(self, "kind", as_schedule(self.kind))
        _set(self, "slots_per_bucket", check_int("slots_per_bucket", self.slots_per_bucket))
        _set(self, "max_evals_per_step", deadline.check_max_evals(self.max_evals_per_step) or None)
        _set(self, "alarm_backoff", deadline.check_alarm_backoff(self.alarm_backoff))
        # The ranges are the native schedule's (ScheduleSpec::Check, as the plugin's tables):
        # a schedule of these options over no pairs.
        q, backoff = self.slots_per_bucket, self.alarm_backoff
        _core.Schedule(RANK, 1.0, 0, np.zeros(0), slots_per_bucket=q, backoff=backoff)
        for name in ("violation_events", "screen"):
            if not isinstance(getattr(self, name), bool):
                raise InvalidInputError(
                    f"{name} = {getattr(self, name)!r} is invalid: pass True or False."
                )


@dataclasses.dataclass(frozen=True, kw_only=True)
class UrgencyOptions:
    """How tau is computed beyond the bounding spheres (docs/theory.md, section 5).

    Attributes:
        exact: The exact level: a pair whose sphere tau is below ``exact_below`` is looked at
            through its geoms, and the bounds hold for every point of the geoms (checked at the
            corners of their boxes).
        exact_below: Seconds; None for ``(1 + latency)`` predictor periods, the alarm horizon
            (measured: larger thresholds cost more and clear no more alarms).
    """

    exact: bool = True
    exact_below: float | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.exact, bool):
            raise InvalidInputError(f"exact = {self.exact!r} is invalid: pass True or False.")
        b = self.exact_below
        if b is not None and (
            isinstance(b, bool) or not isinstance(b, int | float) or math.isnan(b) or b <= 0
        ):
            raise InvalidInputError(
                f"exact_below = {b!r} is invalid: pass a positive number of seconds, or None "
                "for the alarm horizon, one predictor period past the latency."
            )


@dataclasses.dataclass(frozen=True, kw_only=True)
class PilotOptions:
    """The pilot rollout of ``accel="auto"`` (docs/discrete-time.md, section 4).

    Attributes:
        steps: Its length in physics steps.
        seed: Its random seed (use one different from the monitored run).
        controller: ``controller(model, data)`` for the pilot; None for random controls.
        safety: Factor on the measured maxima.
        motion: Which steps it measures (a ``PilotMotion`` or its value): ``"free"`` leaves
            out the steps near any contact or joint limit of the body's tree, ``"no-impacts"``
            those near a new contact, ``"all"`` none. The motion left out breaks the bounds in
            the run, and each step re-evaluates the pairs of the bodies that broke them.
            ``"free"`` is the default: measured on 35 scenes and robot models
            (docs/benchmarks.md) it stands fewer pairs in alarm on every one (median 0.84x of
            ``"no-impacts"``) at the same median work, and misses nothing more.
    """

    steps: int = 2000
    seed: int = 1_000_003
    controller: Callable[[mujoco.MjModel, mujoco.MjData], None] | None = None
    safety: float = 2.0
    motion: PilotMotion | str = PilotMotion.FREE

    def __post_init__(self) -> None:
        check_int("pilot steps", self.steps)
        if isinstance(self.seed, bool) or not isinstance(self.seed, int):
            raise InvalidInputError(f"pilot seed = {self.seed!r} is invalid: pass an int.")
        _set(self, "motion", as_choice(PilotMotion, self.motion, "pilot motion"))
        if check_number("pilot safety", self.safety) < 1.0:
            raise InvalidInputError(
                f"pilot safety = {self.safety!r} is invalid: pass a factor >= 1 on the measured "
                "maxima (2 is the default)."
            )
        if self.controller is not None and not callable(self.controller):
            raise InvalidInputError(
                f"pilot controller = {self.controller!r} is not callable: pass "
                "controller(model, data), or None for random controls."
            )


@dataclasses.dataclass(frozen=True, kw_only=True)
class PairOptions:
    """Which sphere pairs are held (docs/many-objects.md).

    Attributes:
        mode: ``"all"``, ``"pruned"`` (the pairs whose reachable balls meet within ``horizon``,
            rebuilt as they move; deadline schedule only) or ``"auto"`` (pruned from 256
            covering spheres on).
        horizon: Pruned only: the reach's horizon in seconds; None for the default.
    """

    mode: PairMode | str = "auto"
    horizon: float | None = None


REMOVED_KEYWORDS = {
    "max_spheres_per_geom": "covering=CoveringOptions(max_spheres_per_geom=...)",
    "hfield": "covering=CoveringOptions(hfield=...)",
    "static": "covering=CoveringOptions(static=...)",
    "slots_per_bucket": 'schedule=ScheduleOptions(kind="dua", slots_per_bucket=...)',
    "max_evals_per_step": "schedule=ScheduleOptions(max_evals_per_step=...)",
    "alarm_backoff": "schedule=ScheduleOptions(alarm_backoff=...)",
    "exact": "urgency=UrgencyOptions(exact=...)",
    "exact_below": "urgency=UrgencyOptions(exact_below=...)",
    "pilot_steps": "pilot=PilotOptions(steps=...)",
    "pilot_seed": "pilot=PilotOptions(seed=...)",
    "pilot_controller": "pilot=PilotOptions(controller=...)",
    "safety": "pilot=PilotOptions(safety=...)",
    "horizon": 'pairs=PairOptions(mode="pruned", horizon=...)',
    "refine": "nothing: the two-level urgency is gone; the exact level (the default) replaces it",
    "refine_below": "nothing: the two-level urgency is gone",
}
"""Keywords the Predictor took before its options were grouped, and where each went."""


@dataclasses.dataclass(frozen=True, kw_only=True)
class PredictorOptions:
    """The option groups a Predictor was built with (``Predictor.options``)."""

    covering: CoveringOptions
    schedule: ScheduleOptions
    urgency: UrgencyOptions
    pilot: PilotOptions
    pairs: PairOptions


def resolve_options(
    covering: object,
    schedule: ScheduleOptions | Schedule | str,
    urgency: UrgencyOptions,
    pilot: PilotOptions,
    pairs: PairOptions | PairMode | str,
) -> PredictorOptions:
    """The Predictor's keywords as option groups: a plain mode becomes its group's defaults
    with that mode (a ready ``Covering`` keeps the default group: it is used as it is)."""
    for name, value, cls in (("urgency", urgency, UrgencyOptions), ("pilot", pilot, PilotOptions)):
        if not isinstance(value, cls):
            raise InvalidInputError(
                f"{name} = {value!r} is invalid: pass a dua_mujoco.{cls.__name__}(...)."
            )
    if isinstance(covering, CoveringOptions):
        cover = covering
    elif isinstance(covering, str | enum.Enum):
        cover = CoveringOptions(mode=covering)  # type: ignore[arg-type]
    else:
        cover = CoveringOptions()  # a ready Covering
    return PredictorOptions(
        covering=cover,
        schedule=schedule
        if isinstance(schedule, ScheduleOptions)
        else ScheduleOptions(kind=schedule),
        urgency=urgency,
        pilot=pilot,
        pairs=pairs if isinstance(pairs, PairOptions) else PairOptions(mode=pairs),
    )


def removed_keywords_error(removed: dict[str, object]) -> InvalidInputError:
    """The error for keywords the Predictor no longer takes: where each one went."""
    moved = [f"{k} -> {REMOVED_KEYWORDS[k]}" for k in removed if k in REMOVED_KEYWORDS]
    unknown = sorted(k for k in removed if k not in REMOVED_KEYWORDS)
    parts = []
    if moved:
        parts.append("these options moved into groups: " + "; ".join(moved))
    if unknown:
        parts.append(
            f"unknown keyword(s) {unknown}: the Predictor takes accel, speed, velocity_accel, "
            "period, latency, covering, schedule, urgency, pilot and pairs"
        )
    return InvalidInputError("Predictor(): " + ". ".join(parts) + ".")


def alarm_periods(alarm_horizon: object, dt: float) -> int:
    """The alarm horizon in whole predictor periods of ``dt`` seconds (rounded up; None: 1).

    Raises:
        InvalidInputError: ``alarm_horizon`` is not a finite number of seconds >= ``dt``.
    """
    if alarm_horizon is None:
        return 1
    seconds = (
        float(alarm_horizon)
        if isinstance(alarm_horizon, int | float | np.integer | np.floating)
        and not isinstance(alarm_horizon, bool)
        else math.nan
    )
    if not math.isfinite(seconds) or seconds < dt * (1 - 1e-9):
        raise InvalidInputError(
            f"alarm_horizon = {alarm_horizon!r} is invalid: pass the seconds of warning wanted, "
            f"at least one predictor period ({dt:g} s), or None for one period."
        )
    return max(1, math.ceil(seconds / dt - 1e-9))
