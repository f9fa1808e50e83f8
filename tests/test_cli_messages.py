"""What the command line says when it is given something wrong, or interrupted while it sets up.

Each message names the bad value and the fix in one line (``dua-mujoco: error: ...``, or
argparse's usage and one line for an option's value).
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import threading
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import pytest
from screens import ctrl_c_able

from dua_mujoco.cli import build_parser, main

REPO = Path(__file__).resolve().parent.parent


def _error(capsys: pytest.CaptureFixture[str]) -> str:
    """The one line of a refused command, without its ``dua-mujoco: error:``."""
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("dua-mujoco: error: "), err
    return err.removeprefix("dua-mujoco: error: ")


# --------------------------------------------------------------------------------------------------
# Integer options.
# --------------------------------------------------------------------------------------------------


def _integer_options() -> list[tuple[str, str, argparse.Action]]:
    """(subcommand, flag, action) of every option whose value is a whole number."""
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    found = []
    for name, command in sub.choices.items():
        for action in command._actions:
            if not action.option_strings or not callable(action.type) or action.type is Path:
                continue
            try:
                value = action.type("3")
            except (argparse.ArgumentTypeError, ValueError, TypeError):
                continue
            if type(value) is int:
                found.append((name, action.option_strings[-1], action))
    return found


INTEGER_OPTIONS = _integer_options()


def test_every_command_has_integer_options() -> None:
    """The list below is not empty by accident: run, view, sweep, export and paper each have
    some (sweep: --seeds and --workers besides run's)."""
    flags = {(name, flag) for name, flag, _ in INTEGER_OPTIONS}
    assert {
        ("run", "--steps"),
        ("run", "--fps"),
        ("view", "--seed"),
        ("export", "--period"),
    } <= flags
    assert {("sweep", "--seeds"), ("sweep", "--workers"), ("paper", "--seeds")} <= flags


@pytest.mark.parametrize(
    ("flag", "action"),
    [(flag, action) for _, flag, action in INTEGER_OPTIONS],
    ids=[f"{name} {flag}" for name, flag, _ in INTEGER_OPTIONS],
)
def test_an_integer_option_given_a_fraction_says_what_it_counts(
    flag: str, action: argparse.Action
) -> None:
    with pytest.raises(argparse.ArgumentTypeError) as info:
        action.type("1.5")  # type: ignore[misc,operator]
    assert re.fullmatch(
        rf"{flag} must be a whole number( of [a-z ]+)?, got '1\.5'", str(info.value)
    )


def test_steps_given_a_fraction_is_one_line_naming_physics_steps(
    capsys: pytest.CaptureFixture[str],
) -> None:
    with pytest.raises(SystemExit) as info:
        main(["run", "--steps", "1.5"])
    assert info.value.code == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert (
        last == "dua-mujoco run: error: --steps must be a whole number of physics steps, got '1.5'"
    )


@pytest.mark.parametrize(
    ("argv", "line"),
    [
        (
            ["run", "--seed", "-1"],
            "dua-mujoco run: error: --seed must be a whole number, at least 0, got '-1'",
        ),
        (
            ["sweep", "two_arms", "--workers", "0"],
            "dua-mujoco sweep: error: --workers must be a whole number of processes, at least 1, "
            "got '0'",
        ),
        (
            ["paper", "--seeds", "1"],
            "dua-mujoco paper: error: --seeds must be a whole number of sequences per setting, "
            "at least 2, got '1'",
        ),
    ],
    ids=["run-seed", "sweep-workers", "paper-seeds"],
)
def test_an_integer_option_below_its_least_value_names_it(
    capsys: pytest.CaptureFixture[str], argv: list[str], line: str
) -> None:
    with pytest.raises(SystemExit):
        main(argv)
    assert capsys.readouterr().err.strip().splitlines()[-1] == line


# --------------------------------------------------------------------------------------------------
# Scenes, keyframes, cameras.
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("scene", ["missing.xml", "missing.mjb", "MISSING.MJB", "sub/missing"])
def test_a_missing_file_says_no_file_at_first(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, scene: str
) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["run", scene, "--steps", "5", "--no-progress"]) == 2
    line = _error(capsys)
    assert line.startswith(f"No file at {str(tmp_path / scene)!r}: pass the path of an existing")
    assert "Unknown scene" not in line
    assert "a bundled scene (two_arms, traffic" in line


def test_a_bare_name_lists_the_bundled_scenes(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "nope", "--steps", "5", "--no-progress"]) == 2
    line = _error(capsys)
    assert line.startswith("Unknown scene 'nope'. Valid choices: 'two_arms', 'traffic'")
    assert "No file at" not in line


BALL = """
<mujoco>
  <worldbody>
    <light pos="0 0 2"/>
    {cameras}
    <body pos="0 0 0.5"><freejoint/><geom type="sphere" size="0.1"/></body>
    <geom type="plane" size="1 1 0.1"/>
  </worldbody>
  {keyframes}
</mujoco>
"""


def _model(tmp_path: Path, name: str, cameras: str = "", keyframes: str = "") -> Path:
    path = tmp_path / f"{name}.xml"
    path.write_text(BALL.format(cameras=cameras, keyframes=keyframes))
    return path


def test_keyframe_of_a_model_without_keyframes_says_so_not_fix_the_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scene = _model(tmp_path, "nokeys")
    assert main(["run", str(scene), "--keyframe", "3", "--steps", "5", "--no-progress"]) == 2
    assert _error(capsys) == (
        "--keyframe 3: the model has no keyframes: leave --keyframe out to start from the "
        "model's defaults."
    )


def test_unknown_keyframe_says_how_many_the_model_has(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    keys = '<keyframe><key name="up" qpos="0 0 1 1 0 0 0"/><key qpos="0 0 2 1 0 0 0"/></keyframe>'
    scene = _model(tmp_path, "keys", keyframes=keys)
    assert main(["run", str(scene), "--keyframe", "2", "--steps", "5", "--no-progress"]) == 2
    assert _error(capsys) == (
        "--keyframe 2: the model has only 2 keyframes (ids 0 to 1, named 'up'): pass one of "
        "those, or leave --keyframe out to start from the first."
    )
    assert main(["run", str(scene), "--keyframe", "down", "--steps", "5", "--no-progress"]) == 2
    assert _error(capsys).startswith("--keyframe down: the model has 2 keyframes (ids 0 to 1")
    argv = ["run", str(scene), "--keyframe", "up", "--steps", "5", "--accel", "20"]
    assert main([*argv, "--no-progress"]) == 0


def _run_camera(tmp_path: Path, scene: Path, camera: str) -> int:
    video = tmp_path / "v.gif"
    argv = ["run", str(scene), "--steps", "10", "--every", "5", "--accel", "20", "--no-progress"]
    return main([*argv, "--video", str(video), "--camera", camera])


@pytest.mark.parametrize(
    ("cameras", "line"),
    [
        (
            "",
            "--camera nope: the model has no camera: leave --camera out (or pass -1) for the free "
            "camera.",
        ),
        (
            '<camera pos="0 -2 1"/>',
            "--camera nope: the model has no named camera: pass a camera's id (id 0), or -1 for "
            "the free camera.",
        ),
        (
            '<camera name="front" pos="0 -2 1"/><camera pos="2 0 1"/>',
            "--camera nope is not a camera of the model: pass one of 'front' (id 0) (1 more "
            "without a name among ids 0 to 1), or -1 for the free camera.",
        ),
    ],
    ids=["no-camera", "unnamed", "named"],
)
def test_unknown_camera_lists_the_models_cameras_before_the_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], cameras: str, line: str
) -> None:
    scene = _model(tmp_path, "cams", cameras=cameras)
    assert _run_camera(tmp_path, scene, "nope") == 2
    assert _error(capsys) == line
    assert not (tmp_path / "v.gif").exists()  # refused before the run


def test_a_camera_by_name_id_or_minus_one_renders(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scene = _model(tmp_path, "cams", cameras='<camera name="front" pos="0 -2 1"/>')
    for camera in ("front", "0", "-1"):
        assert _run_camera(tmp_path, scene, camera) == 0, capsys.readouterr().err
        assert "video written to" in capsys.readouterr().out
    assert _run_camera(tmp_path, scene, "1") == 2
    assert _error(capsys).startswith("--camera 1 is not a camera of the model: pass one of")


# --------------------------------------------------------------------------------------------------
# Ctrl-C while the command sets up.
# --------------------------------------------------------------------------------------------------


def _command() -> list[str]:
    script = Path(sys.executable).with_name("dua-mujoco")
    return [str(script)] if script.is_file() else ["-m", "dua_mujoco"]


# Markers of the set-up's stages (python -X importtime prints a line as each import finishes):
# numpy is done while `import mujoco`, the command's first import, still runs; importlib.metadata
# as mujoco turns to its plugins (ours, the mujoco.plugins entry point, loads the native core
# next); mujoco when the command's module is nearly loaded; the monitor when `run` has its own
# imports and loads the scene, compiles and starts a 10^6-step pilot.
@pytest.mark.parametrize(
    "marker", ["numpy", "mujoco", "importlib.metadata", "dua_mujoco.measure.monitor"]
)
def test_ctrl_c_while_setting_up_is_one_line_and_exit_130(marker: str) -> None:
    argv = [sys.executable, "-X", "importtime", *_command(), "run", "two_arms"]
    argv += ["--pilot-steps", "1000000", "--no-progress"]
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST")}
    proc = subprocess.Popen(
        ctrl_c_able(argv),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        cwd=REPO,
    )
    assert proc.stderr is not None
    # A marker that never comes would leave the loop waiting on the silent pilot: a watchdog
    # kills it, and the test fails below instead of hanging.
    watchdog = threading.Timer(180, proc.kill)
    watchdog.start()
    seen = False
    for line in proc.stderr:
        if re.search(rf"\|\s+{re.escape(marker)}$", line.rstrip()):
            seen = True
            break
    watchdog.cancel()
    assert seen, f"the command never imported {marker}"
    proc.send_signal(signal.SIGINT)
    try:
        out, rest = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:  # deaf to Ctrl-C: killed (no pilot left running), failed
        proc.kill()
        out, rest = proc.communicate()
    said = [x for x in rest.splitlines() if not x.startswith("import time:")]
    assert proc.returncode == 130, rest[-3000:]
    assert len(said) == 1 and said[0].startswith("dua-mujoco: interrupted"), said
    assert out == ""
