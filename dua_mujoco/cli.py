"""Command line: ``dua-mujoco run [SCENE] ...`` and ``dua-mujoco paper ...``."""

from __future__ import annotations

import argparse
import importlib
import json
import math
import os
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path

# Videos are rendered offscreen: without a display, MuJoCo must use EGL, and it reads the choice
# when it is first imported.
if not os.environ.get("DISPLAY"):
    os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco

from dua_mujoco.exceptions import DuaError, InvalidInputError

__all__ = ["build_parser", "main"]


def _accel(value: str) -> str | float:
    if value == "auto":
        return value
    try:
        a = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--accel {value!r} is invalid: pass 'auto' or a number in m/s^2"
        ) from None
    if not a >= 0:
        raise argparse.ArgumentTypeError(f"--accel {value!r} is invalid: it must be >= 0")
    return a


def _positive(kind: type) -> object:
    def parse(value: str) -> object:
        try:
            v = kind(value)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{value!r} is not a {kind.__name__}") from None
        if not v > 0:
            raise argparse.ArgumentTypeError(f"{value!r} must be > 0")
        return v

    return parse


def _non_negative_int(value: str) -> int:
    """argparse type: an int >= 0 (seeds, latency)."""
    try:
        v = int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{value!r} is not an int") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"{value!r} must be >= 0")
    return v


def _add_run(sub: argparse._SubParsersAction) -> None:
    from dua_mujoco.mj.scenes import DEFAULT_SCENE, scene_names

    p = sub.add_parser(
        "run",
        help="predict collisions on a scene and check them against MuJoCo's contacts",
        description="Roll out a scene with the DUA predictor and MuJoCo's contacts as the exact "
        "stage; print a summary table and optionally write a JSON report and a video.",
    )
    p.add_argument(
        "scene",
        nargs="?",
        default=DEFAULT_SCENE,
        help=f"bundled scene ({', '.join(scene_names())}) or an MJCF path "
        f"(default {DEFAULT_SCENE})",
    )
    p.add_argument(
        "--steps",
        type=_positive(int),
        default=None,
        help="physics steps (default: the scene's own, 1000 for an MJCF file)",
    )
    p.add_argument(
        "--seed", type=_non_negative_int, default=0, help="seed of the controls (default 0)"
    )
    p.add_argument("--ctrl", choices=["zero", "random"], default="random", help="controls")
    p.add_argument("--keyframe", default=None, help="start keyframe (id or name; default first)")
    p.add_argument(
        "--accel",
        type=_accel,
        default="auto",
        help="acceleration bound in m/s^2 for every moving body, or 'auto' (pilot rollout)",
    )
    p.add_argument("--speed", type=_positive(float), default=None, help="speed bound in m/s")
    p.add_argument(
        "--covering",
        choices=["bounding", "multi"],
        default="bounding",
        help="one bounding sphere per geom, or several (budget --max-spheres)",
    )
    p.add_argument("--max-spheres", type=_positive(int), default=8, help="multi covering budget")
    p.add_argument(
        "--period", type=_positive(int), default=1, help="physics steps per predictor step"
    )
    p.add_argument(
        "--latency",
        type=_non_negative_int,
        default=0,
        help="periods a verdict takes to reach the user (0: synchronous, after mj_step)",
    )
    p.add_argument("--budget", type=_positive(int), default=1, help="slots per bucket per step")
    p.add_argument(
        "--pilot-steps",
        type=_positive(int),
        default=2000,
        help="pilot rollout length for --accel auto",
    )
    p.add_argument(
        "--hfield",
        choices=["error", "box"],
        default="error",
        help="height fields: refuse them, or cover them conservatively by their bounding box",
    )
    p.add_argument("--realtime", action="store_true", help="count predictor deadline overruns")
    p.add_argument(
        "--geom-distance",
        action="store_true",
        help="measure alarmed geom pairs with mj_geomDistance (the exact distance)",
    )
    p.add_argument("--json", type=Path, default=None, help="write the report as JSON here")
    p.add_argument("--series", action="store_true", help="add per-step series to the JSON")
    p.add_argument("--video", type=Path, default=None, help="render a video (.mp4 or .gif)")
    p.add_argument("--fps", type=_positive(int), default=30, help="video frame rate")
    p.add_argument("--width", type=_positive(int), default=480, help="video width in pixels")
    p.add_argument("--height", type=_positive(int), default=360, help="video height in pixels")
    p.add_argument("--camera", default=None, help="camera name or id (default free camera)")
    p.add_argument(
        "--every",
        type=_positive(int),
        default=5,
        help="render every k-th physics step (one at which the predictor steps: with --period, "
        "a multiple of both)",
    )
    p.add_argument("--show-spheres", action="store_true", help="draw the covering spheres")
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    p.set_defaults(func=_cmd_run)


def _check_output(path: Path, what: str) -> None:
    """Refuse an output path that cannot be written, before a long run rather than after it."""
    if path.is_dir():
        raise InvalidInputError(f"{what} {str(path)!r} is a folder: pass a file path.")
    if path.exists() and not os.access(path, os.W_OK):
        raise InvalidInputError(f"{what} {str(path)!r} exists and is not writable.")
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise InvalidInputError(
                    f"{what} {str(path)!r}: {str(parent)!r} is a file, not a folder."
                )
            if not os.access(parent, os.W_OK):
                raise InvalidInputError(f"{what} {str(path)!r}: {str(parent)!r} is not writable.")
            break


def _check_outputs(args: argparse.Namespace, steps: int) -> None:
    if args.json is not None:
        _check_output(args.json, "--json")
    if args.video is not None:
        from dua_mujoco.render import _check_mp4_size, _video_path

        _check_output(_video_path(args.video), "--video")
        if args.video.suffix.lower() == ".mp4":
            _check_mp4_size(args.width, args.height)
        every = math.lcm(args.every, args.period)  # frames need a predictor step (its alarms)
        if steps < every:
            raise InvalidInputError(
                f"a run of {steps} steps renders no frame: frames are taken every {every} "
                f"physics steps (--every {args.every}, --period {args.period}); pass more "
                "--steps or a lower --every."
            )


def _cmd_run(args: argparse.Namespace) -> int:
    from dua_mujoco.mj.alarms import Alarms
    from dua_mujoco.mj.monitor import Monitor, run
    from dua_mujoco.mj.predictor import Predictor
    from dua_mujoco.mj.scenes import SCENES, load_scene, make_controller

    keyframe: int | str | None = args.keyframe
    if isinstance(keyframe, str) and keyframe.isdigit():
        keyframe = int(keyframe)
    model, data = load_scene(args.scene, keyframe=keyframe)
    steps = args.steps
    if steps is None:
        base = args.scene.split(":")[0]
        steps = SCENES[base].default_steps if base in SCENES else 1000
    _check_outputs(args, steps)
    controller = make_controller(model, args.ctrl, seed=args.seed)
    pilot = make_controller(model, args.ctrl, seed=args.seed + 1_000_003)
    predictor = Predictor(
        model,
        accel=args.accel,
        speed=args.speed,
        covering=args.covering,
        max_spheres_per_geom=args.max_spheres,
        hfield=args.hfield,
        period=args.period,
        latency=args.latency,
        slots_per_bucket=args.budget,
        pilot_steps=args.pilot_steps,
        pilot_seed=args.seed + 1_000_003,
        pilot_controller=pilot,
    )
    on_step = None
    renderer = None
    frames: list = []
    if args.video is not None:
        from dua_mujoco.render import OverlayOptions, OverlayRenderer

        renderer = OverlayRenderer(
            predictor,
            width=args.width,
            height=args.height,
            options=OverlayOptions(show_spheres=args.show_spheres),
            grow_buffer=True,
        )
        camera = int(args.camera) if args.camera and args.camera.isdigit() else args.camera

        def on_step(k: int, d: mujoco.MjData, alarms: Alarms | None, monitor: Monitor) -> None:
            if k % args.every == 0 and alarms is not None:  # a predictor step: alarms to draw
                frames.append(renderer.render(d, alarms, camera=camera, misses=len(monitor.misses)))

    try:
        report = run(
            model,
            data,
            predictor,
            steps=steps,
            controller=controller,
            scene=args.scene,
            realtime=args.realtime,
            geom_distance=args.geom_distance,
            progress=not args.no_progress,
            on_step=on_step,
        )
    finally:
        if renderer is not None:
            renderer.close()
    print(report.table())
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(report.to_dict(series=args.series), indent=2))
        print(f"report written to {args.json}")
    if args.video is not None:
        from dua_mujoco.render import write_video

        write_video(frames, args.video, fps=args.fps)
        print(f"video written to {args.video} ({len(frames)} frames)")
    return 0


# Experiment subcommands: each module has add_arguments(parser) and main(args).
_EXPERIMENTS = {
    "paper": "reproduce the paper's experiments (sec. 8) and write tables, plots and JSON",
    "peers": "measure DUA against SA(tau), swept-sphere broadphases, MuJoCo and FCL",
}


def _add_experiment(sub: argparse._SubParsersAction, name: str) -> None:
    module = importlib.import_module(f"dua_mujoco.experiments.{name}")
    p = sub.add_parser(name, help=_EXPERIMENTS[name])
    module.add_arguments(p)
    p.set_defaults(func=module.main)


def build_parser() -> argparse.ArgumentParser:
    """The ``dua-mujoco`` argument parser with its subcommands."""
    parser = argparse.ArgumentParser(
        prog="dua-mujoco",
        description="Collision prediction for MuJoCo with the Dynamic Urgency Algorithm.",
    )
    from dua_mujoco import __version__

    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    _add_run(sub)
    for name in _EXPERIMENTS:
        _add_experiment(sub, name)
    return parser


def _one_line_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: object = None,
    line: str | None = None,
) -> None:
    """``warnings.showwarning`` for the command line: one line, no source location."""
    print(f"dua-mujoco: {category.__name__}: {' '.join(str(message).split())}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit code (2 on bad input, with a one-line reason)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    with warnings.catch_warnings():
        # A command line shows warnings as one line each, not as Python source locations.
        warnings.showwarning = _one_line_warning
        try:
            return int(args.func(args))
        except (DuaError, ValueError, OSError) as exc:
            # mujoco raises ValueError for MJCF it cannot load: also bad input. OSError: a file
            # that cannot be read or written.
            reason = " ".join(str(exc).split())
            print(f"dua-mujoco: error: {reason}", file=sys.stderr)
            return 2
