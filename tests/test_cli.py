"""The ``dua-mujoco`` command line, called in-process through ``main(argv)`` with short runs."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import pytest

from dua_mujoco.cli import main

REPO = Path(__file__).resolve().parent.parent


REPORT_KEYS = {
    "spheres",
    "pairs",
    "evals_per_step",
    "contact_onsets",
    "predicted_onsets",
    "missed_onsets",
    "missed_onsets_valid_bounds",
    "inactive_pair_contacts",
    "alarm_episodes",
    "false_alarm_episodes",
    "lead_time_mean_s",
    "bound_violations",
    "predictor_us_per_step",
    "mj_step_us_per_step",
}


def test_cli_run_writes_json(tmp_path: Path, capsys) -> None:
    out = tmp_path / "sub" / "out.json"
    assert main(["run", "--steps", "300", "--json", str(out), "--no-progress"]) == 0
    report = json.loads(out.read_text())
    assert report.keys() >= REPORT_KEYS
    assert report["physics_steps"] == 300
    assert report["missed_onsets_valid_bounds"] == 0
    assert report["predictor_share"] == pytest.approx(
        report["predictor_us_per_step"] / (report["period"] * report["mj_step_us_per_step"])
    )
    assert "contact onsets" in capsys.readouterr().out


@pytest.mark.parametrize(
    "flags",
    [
        ["--ctrl", "zero"],
        ["--keyframe", "0"],
        ["--accel", "30"],
        ["--speed", "5"],
        ["--accel", "30", "--speed", "5"],
        ["--covering", "multi"],
        ["--period", "2"],
    ],
    ids=lambda f: " ".join(f),
)
def test_cli_run_accepts_options(tmp_path: Path, flags: list[str]) -> None:
    out = tmp_path / "out.json"
    argv = ["run", "--steps", "200", "--pilot-steps", "500", "--json", str(out), "--no-progress"]
    assert main([*argv, *flags]) == 0
    report = json.loads(out.read_text())
    if "--period" in flags:
        assert report["period"] == 2 and report["predictor_steps"] == 100


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("dua-mujoco: error:")
    return err


def test_cli_unknown_scene(capsys) -> None:
    assert main(["run", "no_such_scene", "--steps", "10", "--no-progress"]) != 0
    err = _one_line_error(capsys)
    assert "no_such_scene" in err and "two_arms" in err


def test_cli_broken_xml(tmp_path: Path, capsys) -> None:
    path = tmp_path / "broken.xml"
    path.write_text("<mujoco><worldbody><body><geom type='sphere' size='.1'></body></mujoco>")
    assert main(["run", str(path), "--steps", "10", "--no-progress"]) != 0
    _one_line_error(capsys)


def test_cli_negative_accel(capsys) -> None:
    with pytest.raises(SystemExit) as info:
        main(["run", "--accel", "-1", "--steps", "10", "--no-progress"])
    assert info.value.code != 0
    # argparse prints its usage, then the one-line reason.
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert "--accel" in last and ">= 0" in last


@pytest.mark.parametrize(
    ("flags", "reason"),
    [
        (["--json", "{file}/r.json"], "is a file, not a folder"),
        (["--json", "{dir}"], "is a folder"),
        (["--video", "{dir}/v.avi"], "Unknown video format '.avi'"),
        (["--video", "{dir}/v.mp4", "--width", "321"], "needs even frame sizes"),
        (["--video", "{dir}/v.gif", "--every", "50"], "renders no frame"),
    ],
    ids=["json-under-file", "json-folder", "video-format", "mp4-odd-size", "no-frames"],
)
def test_cli_bad_outputs_fail_before_the_run(
    tmp_path: Path, capsys, flags: list[str], reason: str
) -> None:
    (tmp_path / "afile").write_text("")
    argv = [f.format(file=tmp_path / "afile", dir=tmp_path) for f in flags]
    assert main(["run", "two_arms", "--steps", "20", "--no-progress", *argv]) == 2
    out, err = capsys.readouterr()
    assert out == ""  # refused before the rollout: no summary table was printed
    assert len(err.strip().splitlines()) == 1 and err.startswith("dua-mujoco: error:"), err
    assert reason in err


def test_cli_unknown_keyframe_lists_ids_and_names(capsys) -> None:
    assert main(["run", "two_arms", "--keyframe", "7", "--steps", "5", "--no-progress"]) == 2
    assert "Valid choices: 0, 'ready'" in _one_line_error(capsys)


def test_cli_table_separates_valid_misses_and_shows_realtime(capsys) -> None:
    assert main(["run", "two_arms", "--steps", "50", "--realtime", "--no-progress"]) == 0
    rows = dict(
        re.split(r"\s{2,}", line.strip(), maxsplit=1)
        for line in capsys.readouterr().out.splitlines()
    )
    assert rows["missed onsets"].isdigit()
    assert rows["of them while the bounds held"] == "0"
    assert rows["deadline overruns"].isdigit()


def test_cli_warnings_are_one_line(tmp_path: Path, capsys) -> None:
    path = tmp_path / "nocollide.xml"
    path.write_text(
        "<mujoco><worldbody><body><freejoint/><geom size='.1' contype='0' conaffinity='0'/>"
        "</body></worldbody></mujoco>"
    )
    assert main(["run", str(path), "--steps", "5", "--accel", "1", "--no-progress"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "dua-mujoco: NoActivePairsWarning: the model has no geom pair MuJoCo could ever put in "
        "contact (no collidable geoms, one geom only, or every pair filtered out by "
        "contype/conaffinity, parent-child or <exclude>): the predictor will never raise an alarm."
    ]


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    return env


def test_python_dash_m(tmp_path: Path) -> None:
    out = subprocess.run(
        [sys.executable, "-m", "dua_mujoco", "run", "--steps", "50", "--no-progress"],
        capture_output=True,
        text=True,
        env=_env(),
        cwd=tmp_path,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert "contact onsets" in out.stdout


def test_cli_video_gif(tmp_path) -> None:
    """``run --video`` renders headless through EGL and writes a video that reads back."""
    from dua_mujoco.render import read_video

    out = tmp_path / "run.gif"
    code = main(
        [
            "run",
            "--steps",
            "40",
            "--every",
            "10",
            "--width",
            "64",
            "--height",
            "48",
            "--video",
            str(out),
            "--no-progress",
        ]
    )
    assert code == 0
    assert read_video(out).shape[0] == 4
