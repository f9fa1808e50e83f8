"""Command line: ``dua-mujoco run [SCENE] ...`` and ``dua-mujoco paper ...``."""

from __future__ import annotations

import argparse
import importlib
import json
import math
import os
import re
import stat
import sys
import tempfile
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

# Videos are rendered offscreen: without a display, MuJoCo must use EGL, and it reads the choice
# when it is first imported.
if not os.environ.get("DISPLAY"):
    os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco

from dua_mujoco.exceptions import DuaError, InvalidInputError
from dua_mujoco.outputs import publish, temporary_beside, writes_in_place
from dua_mujoco.run_options import add_count, add_run_options

if TYPE_CHECKING:
    from dua_mujoco.measure.report import RunReport

__all__ = [
    "EXIT_BOUNDS_BROKEN",
    "EXIT_INTERRUPTED",
    "EXIT_MISSED",
    "EXIT_USAGE",
    "build_parser",
    "check_output",
    "keyframe_arg",
    "load_scene_arg",
    "main",
    "print_report",
    "write_output",
]

EXIT_MISSED = 1
"""``run --strict``: a contact onset was missed outside a violation's period (a bug: the
guarantee covers it)."""
EXIT_USAGE = 2
"""Bad input: a one-line reason on stderr."""
EXIT_BOUNDS_BROKEN = 3
"""``run --strict``: the declared motion bounds were broken in free motion (out of contact), or
an onset was missed in the period of a violation, the guarantee's one exception."""
EXIT_INTERRUPTED = 130
"""Ctrl-C (128 + SIGINT, the shell's convention)."""

_EXIT_CODES = (
    "exit codes: 0 done; 1 (--strict) a contact onset was missed outside the period of a bound "
    "violation (a bug); 2 bad input or an output that cannot be written; 3 (--strict) the "
    "declared motion bounds were broken out of contact, or an onset was missed in the period "
    "of a violation (violations within a contact's impulse alone are expected); 130 "
    "interrupted (Ctrl-C; the partial report is still written)."
)


def _add_run(sub: argparse._SubParsersAction) -> None:
    from dua_mujoco.models.scenes import DEFAULT_SCENE, scene_names

    p = sub.add_parser(
        "run",
        help="predict collisions on a scene and check them against MuJoCo's contacts",
        description="Roll out a scene with the DUA predictor and MuJoCo's contacts as the exact "
        "stage; print a summary table and optionally write a JSON report and a video.",
        epilog=_EXIT_CODES,
    )
    p.add_argument(
        "scene",
        nargs="?",
        default=DEFAULT_SCENE,
        help=f"bundled scene ({', '.join(scene_names())}), an MJCF path or a binary .mjb model "
        f"(default {DEFAULT_SCENE})",
    )
    add_run_options(p)
    p.set_defaults(func=_cmd_run)
    p.add_argument(
        "--strict",
        action="store_true",
        help="exit 1 if a contact onset was missed while the bounds held, 3 if the declared "
        "bounds were broken in free motion or an onset was missed after that (see the exit "
        "codes below)",
    )
    p.add_argument(
        "--json",
        type=Path,
        default=None,
        help="write the report as JSON here (replaced atomically; /dev/stdout works)",
    )
    p.add_argument(
        "--series",
        action="store_true",
        help="record per-predictor-step series (alarm count, minimum tau) into the JSON; "
        "without it memory does not grow with --steps",
    )
    p.add_argument(
        "--video",
        type=Path,
        default=None,
        help="render a video (.mp4 or .gif), streamed to the file as frames are rendered",
    )
    add_count(p, "--fps", "frames per second", 30, "video frame rate")
    add_count(p, "--width", "pixels", 480, "video width in pixels")
    add_count(p, "--height", "pixels", 360, "video height in pixels")
    p.add_argument("--camera", default=None, help="camera name or id (default -1: the free camera)")
    add_count(
        p,
        "--every",
        "physics steps",
        5,
        "render every k-th physics step (one at which the predictor steps: with --period, "
        "the least common multiple of both, noted on stderr)",
    )
    p.add_argument("--show-spheres", action="store_true", help="draw the covering spheres")
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")


def check_output(path: Path, what: str) -> None:
    """Open an output before the run, so that a path that cannot be written fails in a second.

    ``os.access`` says yes to root for anything, so this tries: a temporary file beside a
    regular target (created, then removed), or an open for appending, which truncates nothing,
    of a device, FIFO or symlink (``/dev/stdout``). No folder is created.
    """
    if path.is_dir():
        raise InvalidInputError(f"{what} {str(path)!r} is a folder: pass a file path.")
    if writes_in_place(path):
        if path.exists() and stat.S_ISFIFO(os.stat(path).st_mode):
            return  # opening a FIFO blocks until its reader comes: nothing to probe
        try:
            with open(path, "ab"):
                pass
        except OSError as exc:
            raise InvalidInputError(
                f"{what} {str(path)!r} cannot be opened for writing ({exc.strerror or exc}): "
                "pass another path."
            ) from None
        return
    parent = path.parent
    if not parent.exists():
        raise InvalidInputError(
            f"{what} {str(path)!r}: the folder {str(parent)!r} does not exist: create it "
            "first, or pass a path in an existing folder."
        )
    if not parent.is_dir():
        raise InvalidInputError(f"{what} {str(path)!r}: {str(parent)!r} is a file, not a folder.")
    try:
        fd, probe = tempfile.mkstemp(dir=parent, prefix=f".{path.name}.", suffix=".probe")
    except OSError as exc:
        raise InvalidInputError(
            f"{what} {str(path)!r} cannot be written: creating a file in {str(parent)!r} "
            f"failed ({exc.strerror or exc}): pass a path in a writable folder."
        ) from None
    os.close(fd)
    os.unlink(probe)


def write_output(path: Path, text: str, what: str) -> None:
    """Write ``text`` to ``path`` atomically (a temporary file beside it, then ``os.replace``).

    A device, FIFO or symlink is written in place instead (``--json /dev/stdout``). A failed
    write (a full disk, ``/dev/full``) leaves no temporary file and raises one line.
    """
    try:
        if writes_in_place(path):
            with open(path, "w") as f:
                f.write(text)
            return
        tmp = temporary_beside(path, ".tmp")
        try:
            tmp.write_text(text)
            publish(tmp, path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
    except OSError as exc:
        raise InvalidInputError(
            f"{what} {str(path)!r} could not be written ({exc.strerror or exc}): pass another path."
        ) from None


def _camera_arg(model: mujoco.MjModel, camera: str | None) -> int | None:
    """``--camera`` as the model's camera id (-1: the free camera), or None when not given."""
    if camera is None:
        return None
    n = int(model.ncam)
    if re.fullmatch(r"-?\d+", camera):
        cid = int(camera)
        if -1 <= cid < n:
            return cid
    else:
        cid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
        if cid >= 0:
            return int(cid)
    if n == 0:
        raise InvalidInputError(
            f"--camera {camera}: the model has no camera: leave --camera out (or pass -1) for "
            "the free camera."
        )
    named = [f"{model.camera(i).name!r} (id {i})" for i in range(n) if model.camera(i).name]
    ids = "id 0" if n == 1 else f"ids 0 to {n - 1}"
    if not named:
        raise InvalidInputError(
            f"--camera {camera}: the model has no named camera: pass a camera's id ({ids}), or "
            "-1 for the free camera."
        )
    unnamed = n - len(named)
    more = f" ({unnamed} more without a name among {ids})" if unnamed else ""
    raise InvalidInputError(
        f"--camera {camera} is not a camera of the model: pass one of {', '.join(named)}{more}, "
        "or -1 for the free camera."
    )


def _check_outputs(args: argparse.Namespace, model: mujoco.MjModel, steps: int) -> None:
    if args.json is not None:
        check_output(args.json, "--json")
    if args.video is not None:
        from dua_mujoco.render import check_frame_size, check_mp4_size, video_path

        video_path(args.video)
        args.camera = _camera_arg(model, args.camera)
        if args.video.suffix.lower() == ".mp4":
            check_mp4_size(args.width, args.height)
        check_frame_size(model, args.width, args.height, grow_buffer=True)
        check_output(args.video, "--video")
        every = math.lcm(args.every, args.period)  # frames need a predictor step (its alarms)
        if steps < every:
            raise InvalidInputError(
                f"a run of {steps} steps renders no frame: frames are taken every {every} "
                f"physics steps (--every {args.every}, --period {args.period}); pass more "
                "--steps or a lower --every."
            )
        if every != args.every:
            print(
                f"dua-mujoco: note: --every {args.every} is not a multiple of --period "
                f"{args.period}: a frame is rendered every {every} physics steps (frames are "
                "taken at predictor steps, to draw their alarms).",
                file=sys.stderr,
            )
        args.every = every


def load_scene_arg(scene: str, keyframe: int | str | None) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """``load_scene``, with the file named in the error when MuJoCo cannot load it, and an
    unknown ``--keyframe`` told apart from a broken file."""
    from dua_mujoco.models.scenes import SCENES, load_scene, reset_to_keyframe

    try:
        model, data = load_scene(scene)
    except DuaError:
        raise
    except ValueError as exc:
        if scene in SCENES or not Path(scene).is_file():
            raise
        reason = " ".join(str(exc).split())
        raise InvalidInputError(
            f"cannot load the model {scene!r}: {reason} (fix the file, or pass an MJCF .xml or "
            "binary .mjb model)."
        ) from None
    if keyframe is not None:
        _check_keyframe(model, keyframe)
        reset_to_keyframe(model, data, keyframe)
    return model, data


def _check_keyframe(model: mujoco.MjModel, keyframe: int | str) -> None:
    """Refuse a ``--keyframe`` the model does not have, saying which it has."""
    from dua_mujoco.models.scenes import keyframe_id

    n = int(model.nkey)
    if n == 0:
        raise InvalidInputError(
            f"--keyframe {keyframe}: the model has no keyframes: leave --keyframe out to start "
            "from the model's defaults."
        )
    if keyframe_id(model, keyframe) >= 0:
        return
    names = [repr(model.key(k).name) for k in range(n) if model.key(k).name]
    listing = ("id 0" if n == 1 else f"ids 0 to {n - 1}") + (
        f", named {', '.join(names)}" if names else ", none named"
    )
    count = f"{'only ' if isinstance(keyframe, int) else ''}{n} keyframe{'s' if n > 1 else ''}"
    raise InvalidInputError(
        f"--keyframe {keyframe}: the model has {count} ({listing}): pass one of those, or leave "
        "--keyframe out to start from the first."
    )


def print_report(report: RunReport) -> bool:
    """Print the table and the warnings; return whether the guarantee did not apply."""
    print(report.table())
    sys.stdout.flush()
    bounds_broken = bool(
        report.bound_violations_out_of_contact
        or report.missed_onsets > report.missed_onsets_outside_violations
    )
    if bounds_broken:  # the guarantee did not apply to (part of) the run
        bodies = ", ".join(repr(b) for b in report.broken_bound_bodies[:8])
        more = len(report.broken_bound_bodies) - 8
        if more > 0:
            bodies += f" and {more} more"
        missed = report.missed_onsets - report.missed_onsets_outside_violations
        print(
            f"WARNING: the declared motion bounds were broken {report.bound_violations} times "
            f"(body-steps, {report.bound_violations_out_of_contact} out of contact; bodies "
            f"{bodies}): an onset in the period of a violation is not covered by the guarantee "
            f"({missed} such miss(es) in this run), and each violation makes its bodies' pairs "
            "due at once. Declare bounds that hold in free motion (--accel auto measures them) "
            "or raise --accel/--speed.",
            file=sys.stderr,
        )
    if report.missed_onsets_outside_violations:
        print(
            f"WARNING: {report.missed_onsets_outside_violations} contact onset(s) were missed "
            f"outside the period of a bound violation ({report.missed_onsets_valid_bounds} "
            "while the bounds held): the completeness guarantee is broken (a bug, unless "
            "--no-events or --period > 1 hid the violation; please report it with the scene "
            "and command).",
            file=sys.stderr,
        )
    return bounds_broken


def keyframe_arg(args: argparse.Namespace) -> int | str | None:
    """``--keyframe`` as an id (all digits) or a name."""
    keyframe: int | str | None = args.keyframe
    if isinstance(keyframe, str) and keyframe.isdigit():
        keyframe = int(keyframe)
    return keyframe


def _cmd_run(args: argparse.Namespace) -> int:
    from dua_mujoco.measure.monitor import Monitor
    from dua_mujoco.measure.report import RunInterrupted
    from dua_mujoco.measure.rollout import run
    from dua_mujoco.run_options import controller_for, default_steps, predictor_for
    from dua_mujoco.runtime.alarms import Alarms

    model, data = load_scene_arg(args.scene, keyframe_arg(args))
    steps = default_steps(args.scene) if args.steps is None else args.steps
    _check_outputs(args, model, steps)
    predictor = predictor_for(model, args)
    controller = controller_for(model, args, predictor)
    on_step = None
    renderer = None
    writer = None
    interrupted = False
    try:
        if args.video is not None:
            from dua_mujoco.render import OverlayOptions, OverlayRenderer, VideoWriter

            renderer = OverlayRenderer(
                predictor,
                width=args.width,
                height=args.height,
                options=OverlayOptions(show_spheres=args.show_spheres),
                grow_buffer=True,
            )
            writer = VideoWriter(args.video, fps=args.fps)
            camera = args.camera  # an id, checked by _check_outputs
            render, add = renderer.render, writer.add

            def on_step(k: int, d: mujoco.MjData, alarms: Alarms | None, monitor: Monitor) -> None:
                if k % args.every == 0 and alarms is not None:  # a predictor step: its alarms
                    add(render(d, alarms, camera=camera, misses=len(monitor.misses)))

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
                series=args.series,
            )
        except RunInterrupted as exc:
            report = exc.report
            interrupted = True
    finally:
        if renderer is not None:
            renderer.close()
        if writer is not None:
            writer.close()  # also on Ctrl-C: the frames rendered so far make a playable video
    bounds_broken = print_report(report)
    if args.json is not None:
        text = json.dumps(report.to_dict(series=args.series), indent=2) + "\n"
        write_output(args.json, text, "--json")
        print(f"report written to {args.json}")
    if writer is not None:
        if writer.count:
            print(f"video written to {args.video} ({writer.count} frames)")
        else:
            print(f"no video written: the run stopped before the first frame ({args.video})")
    if interrupted:
        print(
            f"dua-mujoco: interrupted after {report.physics_steps} of {steps} physics steps: the "
            'report covers those ("interrupted": true).',
            file=sys.stderr,
        )
        return EXIT_INTERRUPTED
    if args.strict and report.missed_onsets_outside_violations:
        return EXIT_MISSED
    if args.strict and bounds_broken:
        return EXIT_BOUNDS_BROKEN
    return 0


# Subcommands that drive runs with `run`'s options, each in its own module: add_arguments(parser)
# adds its own arguments (the run options follow), main(args) runs it; DESCRIPTION and EPILOG.
_RUN_COMMANDS = {
    "view": ("dua_mujoco.view", "watch a scene in MuJoCo's viewer with the alarm overlay live"),
    "sweep": ("dua_mujoco.sweep.cli", "run scenes x seeds x option sets on processes or Ray"),
    "export": (
        "dua_mujoco.export",
        "write a scene with the predictor as a MuJoCo plugin, for C/C++ and simulate",
    ),
}


# Experiment subcommands: each module has add_arguments(parser) and main(args).
_EXPERIMENTS = {
    "paper": "reproduce the paper's experiments (sec. 8) and write tables, plots and JSON",
    "peers": "measure DUA against SA(tau), swept-sphere broadphases, MuJoCo and FCL",
}


class _Parser(argparse.ArgumentParser):
    """argparse's parser (its subcommands' too), without the ``argument --steps:`` that argparse
    puts before a reason that already starts with the option's name."""

    def error(self, message: str) -> NoReturn:
        named = re.fullmatch(r"argument (\S+): (.*)", message, flags=re.DOTALL)
        if named and named[2].startswith(tuple(f"{flag} " for flag in named[1].split("/"))):
            message = named[2]
        super().error(message)


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The ``dua-mujoco`` argument parser with its subcommands (the experiments' options only
    if ``argv``, the command line it is for, names them; None: all)."""
    parser = _Parser(
        prog="dua-mujoco",
        description="Collision prediction for MuJoCo with the Dynamic Urgency Algorithm.",
    )
    from dua_mujoco import __version__

    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    _add_run(sub)
    for name, (path, help_text) in _RUN_COMMANDS.items():
        module = importlib.import_module(path)
        p = sub.add_parser(
            name, help=help_text, description=module.DESCRIPTION, epilog=module.EPILOG
        )
        module.add_arguments(p)
        add_run_options(p)
        p.set_defaults(func=module.main)
    for name, help_text in _EXPERIMENTS.items():
        p = sub.add_parser(name, help=help_text)
        if argv is None or name in argv:  # else listed only: importing one takes 0.2 s
            module = importlib.import_module(f"dua_mujoco.experiments.{name}")
            module.add_arguments(p)
            p.set_defaults(func=module.main)
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
    """Entry point; returns the exit code (2 on bad input, with a one-line reason).

    The codes are listed by ``dua-mujoco run --help``: 1 and 3 come only with ``--strict``,
    130 after a Ctrl-C.
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser(argv).parse_args(argv)
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
            return EXIT_USAGE
        except KeyboardInterrupt:
            # Outside the rollout (loading, the pilot rollout, writing): no report to write.
            print("dua-mujoco: interrupted: no report written.", file=sys.stderr)
            return EXIT_INTERRUPTED
