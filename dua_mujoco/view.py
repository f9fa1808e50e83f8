"""``dua-mujoco view``: a scene stepped as ``run`` steps it, shown live in MuJoCo's viewer.

The command's arguments and ``main``; the viewer and its overlay are
:mod:`dua_mujoco.render.live`.
"""

from __future__ import annotations

import argparse
import os
import sys

from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.run_options import number

__all__ = ["DESCRIPTION", "EPILOG", "add_arguments", "main"]

DESCRIPTION = (
    "Step a scene as `run` does (the same options; --steps defaults to until the window is "
    "closed) in MuJoCo's passive viewer, with the alarm overlay of the videos: tinted geoms, red "
    "connectors, covering spheres. Keys: Space pauses and resumes, Right steps one predictor "
    "period while paused, Enter shows or hides the covering spheres. Needs a display; on a "
    "machine without one, run it under Xvfb (xvfb-run -a dua-mujoco view ...). The run's table "
    "is printed when it ends."
)
EPILOG = (
    "exit codes: 0 done (the steps run, or the window closed); 2 bad input or no display; 130 "
    "interrupted (Ctrl-C; the table covers the steps shown)."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The scene and the viewer's own options (the run options are added by ``cli``)."""
    from dua_mujoco.models.scenes import DEFAULT_SCENE

    p.add_argument(
        "scene", nargs="?", default=DEFAULT_SCENE, help=f"as for run (default {DEFAULT_SCENE})"
    )
    p.add_argument(
        "--rate",
        type=number("--rate"),
        default=1.0,
        help="simulated seconds per second of wall time (default 1: real time; 0: as fast as it "
        "goes)",
    )
    p.add_argument("--show-spheres", action="store_true", help="start with the spheres shown")
    p.add_argument("--hide-ui", action="store_true", help="hide the viewer's side panels")


def main(args: argparse.Namespace) -> int:
    """Run ``dua-mujoco view``; the exit code."""
    from dua_mujoco.cli import EXIT_INTERRUPTED, keyframe_arg, load_scene_arg, print_report
    from dua_mujoco.measure.report import RunInterrupted
    from dua_mujoco.render import OverlayOptions
    from dua_mujoco.render.live import view
    from dua_mujoco.run_options import controller_for, predictor_for

    if sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
        raise InvalidInputError(
            "dua-mujoco view needs a display and DISPLAY is not set: run it on a desktop, or "
            "under Xvfb (xvfb-run -a dua-mujoco view ...), or render a video (run --video)."
        )
    model, data = load_scene_arg(args.scene, keyframe_arg(args))
    predictor = predictor_for(model, args)
    try:
        report = view(
            model,
            data,
            predictor,
            steps=args.steps,
            controller=controller_for(model, args, predictor),
            rate=args.rate,
            options=OverlayOptions(show_spheres=args.show_spheres),
            show_ui=not args.hide_ui,
            scene=args.scene,
            realtime=args.realtime,
            geom_distance=args.geom_distance,
            log=sys.stderr,
        )
    except RunInterrupted as exc:
        print_report(exc.report)
        print("dua-mujoco: interrupted: the table covers the steps shown.", file=sys.stderr)
        return EXIT_INTERRUPTED
    print_report(report)
    return 0
