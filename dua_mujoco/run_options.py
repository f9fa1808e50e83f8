"""``dua-mujoco run``'s options as data: the predictor and the controllers they describe.

``run``, ``view`` and ``sweep`` read the same options (``cli.py`` defines them); this module turns
parsed options (an ``argparse.Namespace``, or any object with the same attributes) into what
drives a run, in this process or in a sweep's worker. Predictor options are handed to
:class:`~dua_mujoco.Predictor` by keyword. The predictor and scene modules are looked up when
called, not imported with this module (the command line's ``--help`` stays light).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING, Any

from dua_mujoco.exceptions import InvalidInputError

if TYPE_CHECKING:
    import mujoco

    from dua_mujoco.models.scenes import Driver
    from dua_mujoco.runtime.predictor import Predictor

__all__ = [
    "PILOT_SEED_OFFSET",
    "add_count",
    "add_run_options",
    "controller_for",
    "default_steps",
    "number",
    "predictor_for",
    "predictor_options",
    "run_option_actions",
    "whole_number",
]

PILOT_SEED_OFFSET = 1_000_003
"""The pilot rollout (``--accel auto``) runs with seed ``seed + PILOT_SEED_OFFSET``: never the
monitored rollout's own controls."""


def default_steps(scene: str) -> int:
    """Physics steps of a run without ``--steps``: the bundled scene's own, 1000 for a file."""
    from dua_mujoco.models.scenes import SCENES

    base = scene.split(":")[0]
    return SCENES[base].default_steps if base in SCENES else 1000


def _driver(model: mujoco.MjModel, options: Any, seed: int) -> Driver:
    """The controller ``--ctrl`` names, drawn from ``seed``: the scene's own driver (``scene``,
    the default for a scene that has one) or :func:`make_controller`'s."""
    from dua_mujoco.models import scenes

    name = getattr(options, "scene", "")
    own = scenes.SCENES[name].driver if name in scenes.SCENES else None
    ctrl = options.ctrl or ("scene" if own is not None else "random")
    if ctrl != "scene":
        return scenes.make_controller(model, ctrl, seed=seed)
    if own is None:
        have = [s.name for s in scenes.SCENES.values() if s.driver is not None]
        raise InvalidInputError(
            f"--ctrl scene: {name!r} has no driver of its own (scenes with one: "
            f"{', '.join(have)}): drive it with zero, random or smooth controls."
        )
    return own(model, seed)


def controller_for(
    model: mujoco.MjModel, options: Any, predictor: Predictor | None = None
) -> Driver:
    """The monitored rollout's controller (``--ctrl``, ``--seed``), giving ``predictor`` a flight
    plan every ``R`` steps under ``--plan trajectory`` (a
    :class:`~dua_mujoco.runtime.plans.Replanner`: the plan of a driver that knows how its robot
    is planned, ``driver.plan`` over ``driver.planned``, else a rollout of a copy of the
    controller over every body outside mocap trees)."""
    driver = _driver(model, options, options.seed)
    if getattr(options, "plan", "none") == "none":
        return driver
    if predictor is None:
        raise InvalidInputError("--plan trajectory needs the predictor the plans are given to.")
    from dua_mujoco.runtime.plans import Replanner

    return Replanner(
        predictor,
        driver,
        planner=getattr(driver, "plan", None),
        bodies=getattr(driver, "planned", None),
    )


def predictor_for(model: mujoco.MjModel, options: Any) -> Predictor:
    """The predictor parsed ``run`` options describe (:func:`predictor_options`), with its
    pilot rollout for ``--accel auto``."""
    from dua_mujoco.runtime import predictor

    return predictor.Predictor(model, **predictor_options(model, options))


def predictor_options(model: mujoco.MjModel, options: Any) -> dict[str, Any]:
    """``Predictor``'s keyword options as the parsed ``run`` options describe them.

    Args:
        model: The model (the pilot's controller drives it).
        options: Parsed ``run`` options (``accel``, ``speed``, ``covering``, ``max_spheres``,
            ``hfield``, ``period``, ``latency``, ``alarm_horizon``, ``schedule``, ``max_evals``,
            ``alarm_backoff``, ``slots_per_bucket``, ``violation_events``, ``pairs``,
            ``static``, ``exact``, ``pilot_steps``, ``pilot_motion``, ``ctrl``, ``seed``).
    """
    from dua_mujoco.build import options as opts
    from dua_mujoco.models import scenes

    pilot_seed = options.seed + PILOT_SEED_OFFSET
    accel = options.accel
    if accel is None:  # the scene's declared bounds, if it declares them, else a pilot's
        scene = scenes.SCENES.get(getattr(options, "scene", ""))
        declared = None if scene is None or scene.bounds is None else scene.bounds(model)
        accel = "auto" if declared is None else declared
        if declared is not None and options.speed is not None:
            # --speed on top of the scene's bounds, as on top of a pilot's.
            from dua_mujoco.build.bounds import MotionBounds

            top = MotionBounds.declare(model, 0.0, speed=options.speed, integrator_term=False)
            accel = replace(declared, speed=top.speed)
    return {
        "accel": accel,
        "speed": options.speed,
        "period": options.period,
        "latency": options.latency,
        "alarm_horizon": options.alarm_horizon,
        "pairs": options.pairs,
        "covering": opts.CoveringOptions(
            mode=options.covering,
            max_spheres_per_geom=options.max_spheres,
            hfield=options.hfield,
            static=options.static,
        ),
        "schedule": opts.ScheduleOptions(
            kind=options.schedule,
            max_evals_per_step=options.max_evals,
            slots_per_bucket=options.slots_per_bucket,
            violation_events=options.violation_events,
            # Unset options keep the dataclasses' defaults.
            **({} if options.alarm_backoff is None else {"alarm_backoff": options.alarm_backoff}),
        ),
        "urgency": opts.UrgencyOptions(exact=options.exact),
        "pilot": opts.PilotOptions(
            steps=options.pilot_steps,
            seed=pilot_seed,
            controller=_driver(model, options, pilot_seed),
            **({} if options.pilot_motion is None else {"motion": options.pilot_motion}),
        ),
    }


def number(
    option: str, *, positive: bool = False, auto: bool = False, unit: str = ""
) -> Callable[[str], float | str]:
    """argparse type of a number option: finite and ``>= 0`` (``> 0`` if ``positive``), or
    ``'auto'`` if ``auto``; a value refused is named with the option (``--rate '-1' is invalid:
    pass a finite number >= 0``) and ``unit`` follows the rule (`` (m/s^2)``)."""
    rule = "> 0" if positive else ">= 0"
    what = ("'auto' or " if auto else "") + f"a finite number {rule}{unit}"

    def parse(value: str) -> float | str:
        if auto and value == "auto":
            return value
        try:
            v = float(value)
        except ValueError:
            v = math.nan
        if not (math.isfinite(v) and (v > 0 if positive else v >= 0)):
            raise argparse.ArgumentTypeError(f"{option} {value!r} is invalid: pass {what}")
        return v

    return parse


def whole_number(option: str, unit: str = "", *, minimum: int = 1) -> Callable[[str], int]:
    """argparse type of an integer option: an int >= ``minimum``.

    A value refused is named with the option and what it counts, in one sentence (``--steps must
    be a whole number of physics steps, got '1.5'``), also when a sweep's grid gives it.

    Args:
        option: The option's flag (``--steps``).
        unit: What it counts (``physics steps``); empty for a plain number (a seed).
        minimum: The least value accepted.
    """
    what = f"a whole number of {unit}" if unit else "a whole number"

    def parse(value: str) -> int:
        try:
            n = int(value)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{option} must be {what}, got {value!r}") from None
        if n < minimum:
            raise argparse.ArgumentTypeError(
                f"{option} must be {what}, at least {minimum}, got {value!r}"
            )
        return n

    return parse


def add_count(
    p: argparse.ArgumentParser, flag: str, unit: str, default: int | None, help: str, **kw: int
) -> None:
    """Add the integer option ``flag`` counting ``unit`` (:func:`whole_number`; ``minimum=``
    in ``kw``)."""
    p.add_argument(flag, type=whole_number(flag, unit, **kw), default=default, help=help)


def add_choice(
    p: argparse.ArgumentParser, flag: str, choices: list[str], default: str | None, help: str
) -> None:
    """Add the option ``flag`` taking one of ``choices`` (argparse lists them on a bad value)."""
    p.add_argument(flag, choices=choices, default=default, help=help)


def add_run_options(p: argparse.ArgumentParser) -> None:
    """Add the options of a run's driver, predictor and exact stage (``run``, ``view`` and
    ``sweep`` read them)."""
    add_count(
        p,
        "--steps",
        "physics steps",
        None,
        "physics steps (default: the scene's own, 1000 for an MJCF file)",
    )
    add_count(p, "--seed", "", 0, "seed of the controls (default 0)", minimum=0)
    add_choice(
        p,
        "--ctrl",
        ["scene", "zero", "random", "smooth"],
        None,
        "controls: the scene's own driver (person_cell's person and arm task; the default "
        "for a scene that has one), zero, random held 50 steps (the default otherwise), or "
        "smooth (targets linear between random points 250 steps apart; motors as 1 Hz PD "
        "torques); the pilot of --accel auto is driven the same way",
    )
    p.add_argument("--keyframe", default=None, help="start keyframe (id or name; default first)")
    p.add_argument(
        "--accel",
        type=number("--accel", auto=True, unit=" (m/s^2)"),
        default=None,
        help="acceleration bound in m/s^2 for every moving body, or 'auto' (pilot rollout); "
        "default: the bounds the scene declares (person_cell: the person's after ISO 13855, the "
        "arm's measured), else auto",
    )
    p.add_argument(
        "--speed", type=number("--speed", positive=True), default=None, help="speed bound in m/s"
    )
    add_choice(
        p,
        "--covering",
        ["bounding", "multi"],
        "bounding",
        "one bounding sphere per geom, or several (budget --max-spheres)",
    )
    add_count(p, "--max-spheres", "spheres per geom", 8, "multi covering budget")
    add_count(p, "--period", "physics steps", 1, "physics steps per predictor step")
    add_count(
        p,
        "--latency",
        "predictor periods",
        0,
        "periods a verdict takes to reach the user (0: synchronous, after mj_step)",
        minimum=0,
    )
    p.add_argument(
        "--alarm-horizon",
        type=number("--alarm-horizon", positive=True),
        default=None,
        metavar="SECONDS",
        help="seconds of warning: a pair stands in alarm when it may collide within them, and "
        "every collision is flagged at least this long ahead while the bounds hold (default: "
        "one predictor period)",
    )
    add_choice(
        p,
        "--schedule",
        ["deadline", "dua", "select-all"],
        "deadline",
        "which pairs to evaluate each step: each when its own tau runs out (deadline), "
        "the paper's constant-work rank buckets (dua), or all of them (select-all)",
    )
    add_count(
        p,
        "--max-evals",
        "tau evaluations a step",
        None,
        "deadline: cap on tau evaluations a step; pairs due beyond it wait, in alarm once "
        "their verdict no longer covers the wait (default: no cap)",
    )
    # The default is the Predictor's (DEFAULT_ALARM_BACKOFF): not imported here, where it
    # would pull MuJoCo and the core into every `--help`; test_cli holds the two equal.
    add_count(
        p,
        "--alarm-backoff",
        "predictor steps",
        None,
        "deadline: a pair that keeps alarming (resting contact) is evaluated again after "
        "twice its last wait, up to this many steps, standing in alarm in between; 1 gives "
        "exactly select-all's alarms (default: 8)",
    )
    add_count(
        p,
        "--slots-per-bucket",
        "slots",
        1,
        "dua: slots evaluated per bucket per step, a power of two (revisit intervals "
        "shrink that many times)",
    )
    add_choice(
        p,
        "--static",
        ["shape", "sphere"],
        "shape",
        "geoms welded to the world: held as their own convex shapes, or covered by one "
        "bounding sphere (the previous urgency, for comparison)",
    )
    p.add_argument(
        "--no-exact",
        dest="exact",
        action="store_false",
        help="turn the exact level off: urgent pairs keep the tau of their bounding spheres "
        "(for comparison; docs/theory.md, section 5)",
    )
    p.add_argument(
        "--no-events",
        dest="violation_events",
        action="store_false",
        help="do not re-evaluate the pairs of a body whose motion broke its bounds: verdicts "
        "made before an impact stand until their deadline (for comparison; docs/theory.md, "
        "section 6)",
    )
    add_choice(
        p,
        "--pairs",
        ["all", "pruned", "auto"],
        "auto",
        "deadline: hold every active sphere pair, or only those whose reachable balls "
        "meet within a horizon (rebuilt as they move; for thousands of spheres), or choose "
        "by size (default: pruned from 256 covering spheres)",
    )
    add_count(p, "--pilot-steps", "physics steps", 2000, "pilot rollout length for --accel auto")
    add_choice(
        p,
        "--pilot-motion",
        ["free", "no-impacts", "all"],
        None,
        "steps the pilot of --accel auto measures: out of every contact and joint limit "
        "(free motion), all but those near a new contact, or all (default: the "
        "PilotOptions default)",
    )
    add_choice(
        p,
        "--hfield",
        ["terrain", "box", "error"],
        "terrain",
        "height fields: hold a static one as the prisms of its grid (default), cover them "
        "by their bounding box, or refuse them",
    )
    add_choice(
        p,
        "--plan",
        ["none", "trajectory"],
        "none",
        "trajectory: every max(horizon, 50 ms) give the predictor a flight plan rolled "
        "from a copy of the controller (exact: deviation 0) for the bodies the scene's driver "
        "plans (person_cell: the arm; the person keeps its bounds), else every body outside "
        "mocap trees (docs/plans.md)",
    )
    p.add_argument("--realtime", action="store_true", help="count predictor deadline overruns")
    p.add_argument(
        "--geom-distance",
        action="store_true",
        help="measure alarmed geom pairs with mj_geomDistance (the exact distance)",
    )


def run_option_actions() -> dict[str, argparse.Action]:
    """The run options' argparse actions by destination (``accel``, ``violation_events``...):
    what ``sweep`` re-reads an option set with, and picks a run's options out by."""
    parser = argparse.ArgumentParser(add_help=False)
    add_run_options(parser)
    return {a.dest: a for a in parser._actions}
