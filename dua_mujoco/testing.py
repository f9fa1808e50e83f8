"""Regression helpers and a pytest plugin for users' own scenes (docs/testing.md).

:func:`assert_no_missed_collisions` rolls a scene out with a :class:`~dua_mujoco.Predictor` and
MuJoCo's contacts as the exact stage and fails, with the geoms and times, if a contact onset was
not preceded by an alarm while the declared bounds held (a bug); optionally it holds the alarm
counts to a stored baseline. The pytest plugin (``pytest_plugins = ["dua_mujoco.testing"]`` or
``pytest -p dua_mujoco.testing``; not loaded by itself) adds the fixture ``dua_predict`` and the
option ``--dua-update-baselines``. MuJoCo and the compiled core are imported lazily; the
assertion helpers work without pytest.
"""

from __future__ import annotations

import functools
import json
import math
import os
import sys
import warnings
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

try:
    import pytest
except ModuleNotFoundError:  # pragma: no cover - the assertion helpers work without pytest
    pytest = None  # type: ignore[assignment]

if TYPE_CHECKING:
    import mujoco

    from dua_mujoco.measure.monitor import Monitor
    from dua_mujoco.measure.report import RunReport
    from dua_mujoco.runtime.predictor import Predictor

__all__ = [
    "BASELINE_KEYS",
    "DuaPredict",
    "assert_no_missed_collisions",
    "check_baseline",
    "dua_predict",
    "load_baseline",
    "pytest_addoption",
    "write_baseline",
]

BASELINE_KEYS = ("alarm_episodes", "false_alarm_episodes")
"""The counts a baseline holds a run to (upper bounds, with a relative tolerance)."""

UPDATE_OPTION = "--dua-update-baselines"

# At most this many misses are spelled out in a failure message; the count is always given.
_MAX_LISTED = 20
# ... and at most this many bodies with broken bounds (one line per body and kind).
_MAX_BODIES = 10

Controller = Callable[["mujoco.MjModel", "mujoco.MjData"], None]
BaselineLike = Mapping[str, Any] | str | os.PathLike[str]


# ---------------------------------------------------------------------------------------- baselines


def load_baseline(baseline: BaselineLike) -> dict[str, Any]:
    """Read a baseline from a dict or a JSON file.

    Args:
        baseline: A mapping, or the path of a JSON file written by :func:`write_baseline`.

    Returns:
        The baseline as a dict; it holds at least :data:`BASELINE_KEYS`.

    Raises:
        AssertionError: The file does not exist (the message says how to create it).
        ValueError: The file is not valid JSON or a key is missing or not a count.
    """
    __tracebackhide__ = True
    if isinstance(baseline, Mapping):
        data = dict(baseline)
        where = "the baseline dict"
    else:
        path = Path(baseline)
        if not path.is_file():
            # An AssertionError, not FileNotFoundError: in a test suite a missing baseline is a
            # failing check with a fix, not a crash.
            raise AssertionError(
                f"no baseline at {str(path)!r}: run the test once with "
                f"`pytest {UPDATE_OPTION}` (or call write_baseline(report, path)) to record it."
            )
        try:
            data = json.loads(path.read_text())
        except json.JSONDecodeError as exc:
            raise ValueError(f"baseline {str(path)!r} is not valid JSON: {exc}") from None
        where = repr(str(path))
    for key in BASELINE_KEYS:
        value = data.get(key)
        if isinstance(value, bool) or not isinstance(value, int | float) or not value >= 0:
            raise ValueError(
                f"{where} needs a count {key!r} >= 0, got {value!r}; expected the keys "
                f"{', '.join(BASELINE_KEYS)} (write it with write_baseline)."
            )
    return data


def write_baseline(report: RunReport, path: str | os.PathLike[str]) -> Path:
    """Store a run's alarm counts as a baseline (JSON) at ``path``, creating parent folders;
    return the path written.

    Besides :data:`BASELINE_KEYS` the file records the context of the run (scene, steps, pairs,
    contact onsets) so that a reviewer can tell what changed when the file changes.
    """
    from dua_mujoco import __version__

    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    context = ("scene", "physics_steps", "period", "spheres", "pairs", "contact_onsets")
    content = {key: getattr(report, key) for key in (*BASELINE_KEYS, *context, "predicted_onsets")}
    content["dua_mujoco_version"] = __version__
    out.write_text(json.dumps(content, indent=2) + "\n")
    return out


def check_baseline(report: RunReport, baseline: BaselineLike, *, tolerance: float = 0.25) -> None:
    """Assert a run's alarm counts are within ``(1 + tolerance)`` of a baseline.

    A count above ``baseline * (1 + tolerance)`` fails: the predictor now sends more pairs to the
    exact stage than before. A count below ``baseline / (1 + tolerance)`` only warns (the run got
    better; update the baseline to lock the improvement in).

    Args:
        baseline: A dict or a JSON file with :data:`BASELINE_KEYS`.
        tolerance: Relative slack (``>= 0``).

    Raises:
        AssertionError: A count exceeds its allowance, or the baseline file is missing.
        ValueError: ``tolerance`` is negative or the baseline is malformed.
    """
    __tracebackhide__ = True
    if not (math.isfinite(tolerance) and tolerance >= 0):
        raise ValueError(f"tolerance = {tolerance!r} is invalid: it must be finite and >= 0.")
    base = load_baseline(baseline)
    worse, better = [], []
    for key in BASELINE_KEYS:
        got, ref = getattr(report, key), float(base[key])
        if got > ref * (1.0 + tolerance):
            worse.append(f"{key} = {got} > {ref:g} x {1.0 + tolerance:g} (baseline {ref:g})")
        elif got < ref / (1.0 + tolerance):
            better.append(f"{key} = {got} < baseline {ref:g} / {1.0 + tolerance:g}")
    if isinstance(baseline, Mapping):
        measured = {key: getattr(report, key) for key in BASELINE_KEYS}
        how = f"If the change is intended, update the baseline dict to {measured}."
    else:
        how = (
            f"If the change is intended, update {str(baseline)!r} with `pytest <this test> "
            f"{UPDATE_OPTION}` (dua_predict fixture) or write_baseline(report, path)."
        )
    if worse:
        raise AssertionError(
            f"{report.scene or 'scene'}: more alarms than the baseline allows: "
            + "; ".join(worse)
            + f". {how}"
        )
    if better:
        warnings.warn(
            f"{report.scene or 'scene'}: fewer alarms than the baseline: {'; '.join(better)}. "
            + how,
            UserWarning,
            stacklevel=_caller_level(),
        )


def _caller_level() -> int:
    """``stacklevel`` of the first frame outside this module (the user's test), for warnings."""
    frame = sys._getframe(1)
    level = 1
    while frame.f_back is not None and frame.f_globals.get("__name__") == __name__:
        frame = frame.f_back
        level += 1
    return level


# ------------------------------------------------------------------------------------ the assertion


def _listed_misses(misses: list[Any]) -> list[str]:
    lines = []
    for m in misses[:_MAX_LISTED]:
        tau = "inf" if not math.isfinite(m.last_tau) else f"{m.last_tau:.4g} s"
        lines.append(
            f"  {m.geom1!r} / {m.geom2!r} at t = {m.time:.4f} s (physics step "
            f"{m.physics_step}; last evaluated at predictor step {m.last_evaluation_step}, "
            f"tau = {tau})"
        )
    if len(misses) > _MAX_LISTED:
        lines.append(f"  ... and {len(misses) - _MAX_LISTED} more")
    return lines


def _miss_message(report: RunReport) -> str:
    outside = [m for m in report.misses if not m.in_violation_period]
    lines = [
        f"{report.scene or 'scene'}: {len(outside)} contact onset(s) were not preceded by an "
        f"alarm outside the period of a bound violation ({report.contact_onsets} onsets, "
        f"{report.predicted_onsets} predicted, {report.missed_onsets_valid_bounds} missed while "
        f"the declared bounds held, {report.missed_onsets - len(outside)} in a violation's "
        "period):",
        *_listed_misses(outside),
        "This breaks the completeness guarantee: check the bounds passed to Predictor (accel, "
        "speed, velocity_accel) and report a bug if they are right (a violation in the middle "
        "of a period > 1 can go unseen: docs/theory.md, section 6).",
    ]
    return "\n".join(lines)


def _worst_violations(monitor: Monitor | None, model: mujoco.MjModel) -> list[str]:
    """One line per (body, kind) of broken bound: the largest value against its bound."""
    if monitor is None or monitor.bound_checks is None:
        return []
    worst = {k: (v.value, v.bound, v.time) for k, v in monitor.bound_checks.worst.items()}
    ranked = sorted(worst.items(), key=lambda kv: -kv[1][0] / max(kv[1][1], 1e-300))
    lines = [
        f"  body {model.body(b).name or b!r}: {kind} {value:.4g} > bound {bound:.4g} "
        f"(at t = {t:.4f} s)"
        for (b, kind), (value, bound, t) in ranked[:_MAX_BODIES]
    ]
    if len(ranked) > _MAX_BODIES:
        lines.append(f"  ... and {len(ranked) - _MAX_BODIES} more")
    return lines


def _broken_bounds_message(
    report: RunReport, monitor: Monitor | None, model: mujoco.MjModel
) -> str:
    excused = [m for m in report.misses if not m.bounds_held]
    if excused:
        head = [
            f"{report.scene or 'scene'}: {len(excused)} contact onset(s) were missed after the "
            f"declared motion bounds were broken ({report.bound_violations} body-steps broke a "
            f"bound; {report.contact_onsets} onsets, {report.predicted_onsets} predicted):",
            *_listed_misses(excused),
        ]
    else:
        # No miss, but the run still proves nothing: onsets after a violation were predicted
        # by luck as far as the guarantee is concerned.
        head = [
            f"{report.scene or 'scene'}: the declared motion bounds were broken in free motion "
            f"({report.bound_violations_out_of_contact} body-steps out of contact, "
            f"{report.bound_violations} in all; {report.contact_onsets} onsets, "
            f"{report.predicted_onsets} predicted, none missed):"
        ]
    lines = [
        *head,
        "Bounds broken (largest value per body and kind):",
        *_worst_violations(monitor, model),
        "The guarantee only covers motion within the bounds, so this run certifies nothing for "
        "the contacts after a violation. Declare bounds that hold (accel='auto' measures them "
        "with a pilot rollout), or pass allow_broken_bounds=True to accept a run the guarantee "
        "does not cover.",
    ]
    return "\n".join(lines)


def _make_predictor(
    model: mujoco.MjModel, predictor: Predictor | Mapping[str, Any] | None
) -> Predictor:
    from dua_mujoco.exceptions import InvalidInputError
    from dua_mujoco.runtime.predictor import Predictor

    if predictor is None:
        # The pilot moves what the run's default controller moves (mocap bodies included),
        # with a seed of its own.
        from dua_mujoco.build.options import PilotOptions
        from dua_mujoco.models.scenes import make_controller

        return Predictor(
            model, pilot=PilotOptions(controller=make_controller(model, "random", seed=1))
        )
    if isinstance(predictor, Mapping):  # Predictor names an unknown option and the valid ones
        return Predictor(model, **dict(predictor))
    if predictor.model is not model:
        raise InvalidInputError(
            "the predictor was built for another MjModel: pass Predictor(model, ...) for this "
            "model, or a dict of Predictor keyword arguments."
        )
    return predictor


def assert_no_missed_collisions(
    model: mujoco.MjModel,
    data: mujoco.MjData | None = None,
    *,
    steps: int,
    controller: Controller | None = None,
    predictor: Predictor | Mapping[str, Any] | None = None,
    baseline: BaselineLike | None = None,
    tolerance: float = 0.25,
    scene: str = "",
    allow_broken_bounds: bool = False,
) -> RunReport:
    """Roll a scene out with the predictor and assert no collision was missed.

    Runs :func:`dua_mujoco.measure.rollout.run` for ``steps`` physics steps and fails if

    * a contact onset was not preceded by a standing alarm outside the period of a bound
      violation (``missed_onsets_outside_violations > 0``): a broken guarantee, a bug; the
      message lists the geom pairs and times;
    * a contact onset was missed in the period of a violation (the guarantee's one exception:
      an impulse and a collision within one predictor period), or a body broke its bounds out
      of contact (``bound_violations_out_of_contact > 0``: free motion beyond the bounds,
      missed onsets or not), unless ``allow_broken_bounds``: bounds too small for the scene;
      a green test would mean less than it says. Violations within a contact's impulse alone
      are expected and pass: the step re-evaluates the pairs of the bodies involved;
    * MuJoCo reported a contact outside the predictor's active pairs
      (``unfiltered_contacts > 0``): the pair filter disagrees with MuJoCo, so no alarm could
      ever cover that contact;
    * the model has no geom pair that could ever collide (the test would check nothing);
    * ``baseline`` is given and an alarm count exceeds it by more than ``tolerance``
      (:func:`check_baseline`).

    Args:
        data: Its data at the start state; None for a fresh ``MjData`` at the first keyframe (or
            the model defaults), after ``mj_forward``. It is advanced in place.
        steps: Physics steps to roll out.
        controller: ``controller(model, data)`` called before every ``mj_step``; None for
            :func:`dua_mujoco.models.scenes.make_controller` random held controls with seed 0 (a
            regression needs motion; pass ``make_controller(model, "zero")`` for none).
        predictor: A ``Predictor`` for ``model``, a dict of ``Predictor`` keyword arguments, or
            None for ``Predictor(model)`` with bounds from a pilot rollout driven by
            :func:`~dua_mujoco.models.scenes.make_controller` (random controls, mocap bodies moved
            as the default controller moves them; its own seed).
        baseline: A dict or JSON file path with :data:`BASELINE_KEYS` to compare the alarm counts
            with; None to skip the comparison.
        tolerance: Relative slack of the baseline comparison.
        scene: Name used in messages and the report (default ``model``'s name).
        allow_broken_bounds: Accept a run whose declared bounds were broken out of contact, and
            the misses in a violation's period (they are still in the report).

    Returns:
        The run's :class:`~dua_mujoco.measure.monitor.RunReport`.

    Raises:
        AssertionError: A missed collision, broken bounds (unless ``allow_broken_bounds``), an
            unfiltered contact, a model without collidable pairs, or a baseline regression.
        InvalidInputError: ``model``, ``data``, ``steps`` or a predictor option is invalid.
    """
    __tracebackhide__ = True
    import mujoco

    from dua_mujoco.build.tables import check_model
    from dua_mujoco.measure.rollout import run
    from dua_mujoco.models.scenes import make_controller, reset_to_keyframe

    check_model(model)
    if data is None:
        data = mujoco.MjData(model)
        reset_to_keyframe(model, data)
    pred = _make_predictor(model, predictor)
    name = scene or (model.names[: model.names.find(b"\0")].decode() if model.names else "")
    if pred.universe.empty():
        raise AssertionError(
            f"{name or 'scene'}: no geom pair of this model could ever collide (no collidable "
            "geoms, or all filtered by contype/conaffinity, parent-child or <exclude>): the "
            "regression would check nothing."
        )
    if controller is None:
        controller = make_controller(model, "random", seed=0)
    monitors: list[Monitor] = []

    def keep_monitor(k: int, d: mujoco.MjData, alarms: object, monitor: Monitor) -> None:
        if not monitors:
            monitors.append(monitor)

    report = run(
        model,
        data,
        pred,
        steps=steps,
        controller=controller,
        scene=name,
        progress=False,
        on_step=keep_monitor,
        series=False,
    )
    if report.missed_onsets_outside_violations:
        raise AssertionError(_miss_message(report))
    broken = report.missed_onsets or report.bound_violations_out_of_contact
    if broken and not allow_broken_bounds:
        raise AssertionError(
            _broken_bounds_message(report, monitors[0] if monitors else None, model)
        )
    if report.unfiltered_contacts:
        raise AssertionError(
            f"{report.scene or 'scene'}: {report.unfiltered_contacts} MuJoCo contact(s) lie "
            "outside the predictor's active pairs, so no alarm could cover them: the pair filter "
            "disagrees with MuJoCo's (report a bug with the model)."
        )
    if baseline is not None:
        check_baseline(report, baseline, tolerance=tolerance)
    return report


# ------------------------------------------------------------------------------------ pytest plugin


class DuaPredict(Protocol):
    """The callable ``dua_predict`` returns: :func:`assert_no_missed_collisions`'s signature."""

    def __call__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData | None = None,
        *,
        steps: int,
        controller: Controller | None = None,
        predictor: Predictor | Mapping[str, Any] | None = None,
        baseline: BaselineLike | None = None,
        tolerance: float = 0.25,
        scene: str = "",
        allow_broken_bounds: bool = False,
    ) -> RunReport: ...


def pytest_addoption(parser: pytest.Parser) -> None:
    """Register ``--dua-update-baselines``."""
    group = parser.getgroup("dua_mujoco", "dua_mujoco collision-prediction regressions")
    group.addoption(
        UPDATE_OPTION,
        action="store_true",
        default=False,
        help="dua_predict: write the alarm-count baselines (JSON files) instead of comparing",
    )


def dua_predict(request: pytest.FixtureRequest) -> DuaPredict:
    """Assert that a scene's rollout misses no collision (and matches its alarm baseline).

    Returns a callable with the signature of :func:`assert_no_missed_collisions`. A relative
    ``baseline`` path is resolved against the folder of the test file. With
    ``--dua-update-baselines``, path baselines are written from the run instead of compared (the
    no-missed-collision check still applies). Each call records the run's counts in the test's
    ``user_properties`` (shown in JUnit XML reports).
    """
    # getoption's default covers a plugin registered after the command line was parsed (e.g.
    # through pytest_plugins in a test module), where the option itself does not exist.
    update = bool(request.config.getoption(UPDATE_OPTION, default=False))
    folder = Path(str(request.path)).parent

    # Same signature as assert_no_missed_collisions (inspect.signature follows __wrapped__).
    @functools.wraps(assert_no_missed_collisions)
    def predict(
        model: mujoco.MjModel,
        data: mujoco.MjData | None = None,
        *,
        baseline: BaselineLike | None = None,
        **options: Any,
    ) -> RunReport:
        __tracebackhide__ = True
        target: Path | None = None
        if baseline is not None and not isinstance(baseline, Mapping):
            baseline = target = folder / baseline  # an absolute path stays as it is
        compare = None if (update and target is not None) else baseline
        report = assert_no_missed_collisions(model, data, baseline=compare, **options)
        if update and target is not None:
            write_baseline(report, target)
        for key in ("contact_onsets", "predicted_onsets", *BASELINE_KEYS):
            request.node.user_properties.append((f"dua_{key}", getattr(report, key)))
        return report

    return predict


if pytest is not None:  # without pytest the module still serves assert_no_missed_collisions
    dua_predict = pytest.fixture(dua_predict)
