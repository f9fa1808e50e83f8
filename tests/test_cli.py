"""The ``dua-mujoco`` command line, called in-process through ``main(argv)`` with short runs."""

from __future__ import annotations

import dataclasses
import json
import os
import re
import subprocess
import sys
import tracemalloc
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco
import pytest

from dua_mujoco.cli import main
from dua_mujoco.measure import rollout

REPO = Path(__file__).resolve().parent.parent


REPORT_KEYS = {
    "spheres",
    "pairs",
    "evals_per_step",
    "contact_onsets",
    "predicted_onsets",
    "missed_onsets",
    "missed_onsets_valid_bounds",
    "missed_onsets_outside_violations",
    "inactive_pair_contacts",
    "alarm_episodes",
    "false_alarm_episodes",
    "lead_p10_s",
    "lead_median_s",
    "lead_min_s",
    "short_lead_onsets",
    "short_lead_bounds_held",
    "short_lead_after_violation",
    "short_lead_at_start",
    "warning_horizon_s",
    "oracle_fraction",
    "bound_violations",
    "predictor_us_per_step",
    "mj_step_us_per_step",
    "standing_alarm_fraction",
    "contact_pair_fraction",
    "broken_bound_bodies",
    "interrupted",
}


def test_cli_run_writes_json(tmp_path: Path, capsys) -> None:
    out = tmp_path / "out.json"
    assert main(["run", "--steps", "300", "--json", str(out), "--no-progress"]) == 0
    report = json.loads(out.read_text())
    assert report.keys() >= REPORT_KEYS
    assert report["interrupted"] is False
    assert "alarms_per_step" not in report  # no --series
    assert 0 < report["contact_pair_fraction"] < report["standing_alarm_fraction"] < 1
    assert report["contact_pair_fraction"] <= report["oracle_fraction"]
    assert report["oracle_fraction"] <= report["standing_alarm_fraction"]
    assert report["lead_min_s"] <= report["lead_p10_s"] <= report["lead_median_s"]
    assert report["short_lead_onsets"] == (
        report["short_lead_bounds_held"]
        + report["short_lead_after_violation"]
        + report["short_lead_at_start"]
    )
    assert report["physics_steps"] == 300
    assert report["missed_onsets_valid_bounds"] == 0
    assert report["missed_onsets_outside_violations"] == 0
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


def test_cli_alarm_backoff(tmp_path: Path) -> None:
    """--alarm-backoff 1 re-evaluates standing alarms every step: more work than the default,
    which is the Predictor's (the help says which; the CLI does not import it)."""
    from dua_mujoco.cli import build_parser
    from dua_mujoco.core.schedules.deadline import DEFAULT_ALARM_BACKOFF

    evals = {}
    for backoff in (["--alarm-backoff", "1"], []):
        out = tmp_path / "out.json"
        argv = ["run", "--steps", "300", "--accel", "30", "--json", str(out), "--no-progress"]
        assert main([*argv, *backoff]) == 0
        evals[bool(backoff)] = json.loads(out.read_text())["evals_per_step"]
    assert evals[True] > evals[False]
    run_parser = build_parser()._subparsers._group_actions[0].choices["run"]  # type: ignore[union-attr]
    (action,) = (a for a in run_parser._actions if a.dest == "alarm_backoff")
    assert f"(default: {DEFAULT_ALARM_BACKOFF})" in str(action.help)


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
    assert main(["run", str(path), "--steps", "10", "--no-progress"]) == 2
    assert f"cannot load the model {str(path)!r}" in _one_line_error(capsys)


def test_cli_runs_a_binary_model(tmp_path: Path, capsys) -> None:
    """A compiled ``.mjb`` model loads as one (it failed as malformed XML)."""
    from dua_mujoco.models.scenes import load_scene

    model, _ = load_scene("two_arms")
    path = tmp_path / "two_arms.mjb"
    mujoco.mj_saveModel(model, str(path), None)
    assert main(["run", str(path), "--steps", "20", "--accel", "30", "--no-progress"]) == 0
    assert "contact onsets" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("flag", "value", "reason"),
    [
        ("--accel", "-1", "a finite number >= 0 (m/s^2)"),
        ("--accel", "nan", "a finite number >= 0 (m/s^2)"),
        ("--accel", "inf", "a finite number >= 0 (m/s^2)"),
        ("--speed", "inf", "a finite number > 0"),
    ],
)
def test_cli_bad_bounds_are_refused_up_front(capsys, flag: str, value: str, reason: str) -> None:
    with pytest.raises(SystemExit) as info:
        main(["run", flag, value, "--steps", "10", "--no-progress"])
    assert info.value.code == 2
    # argparse prints its usage, then the one-line reason.
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert flag in last and repr(value) in last and reason in last
    if flag == "--accel":
        assert "'auto'" in last


@pytest.mark.parametrize(
    ("flags", "reason"),
    [
        (["--json", "{file}/r.json"], "is a file, not a folder"),
        (["--json", "{dir}"], "is a folder"),
        (["--video", "{dir}/v.avi"], "Unknown video format '.avi'"),
        (["--video", "{dir}/v.mp4", "--width", "321"], "needs even frame sizes"),
        (["--video", "{dir}/v.gif", "--every", "50"], "renders no frame"),
        (["--json", "/proc/nope.json"], "cannot be written: creating a file in '/proc'"),
        (["--video", "/proc/out.mp4"], "cannot be written: creating a file in '/proc'"),
        (["--json", "{dir}/missing/out.json"], "missing' does not exist: create it first"),
        (["--video", "{dir}/v.mp4", "--width", "100000"], "100000x360 frame is larger"),
    ],
    ids=[
        "json-under-file",
        "json-folder",
        "video-format",
        "mp4-odd-size",
        "no-frames",
        "json-in-proc",
        "video-in-proc",
        "json-missing-folder",
        "video-too-wide",
    ],
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
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]  # no folder, no probe left


def test_cli_unknown_keyframe_lists_ids_and_names(capsys) -> None:
    assert main(["run", "two_arms", "--keyframe", "7", "--steps", "5", "--no-progress"]) == 2
    assert _one_line_error(capsys) == (
        "dua-mujoco: error: --keyframe 7: the model has only 1 keyframe (id 0, named 'ready'): "
        "pass one of those, or leave --keyframe out to start from the first."
    )


def test_cli_table_separates_valid_misses_and_shows_realtime(capsys) -> None:
    assert main(["run", "two_arms", "--steps", "50", "--realtime", "--no-progress"]) == 0
    rows = dict(
        re.split(r"\s{2,}", line.strip(), maxsplit=1)
        for line in capsys.readouterr().out.splitlines()
    )
    assert rows["missed onsets"].isdigit()
    assert rows["outside a violation's period"] == "0"
    assert rows["while the bounds held"] == "0"
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


ARGS = ["run", "two_arms", "--steps", "60", "--accel", "30", "--no-progress"]


def test_cli_unwritable_special_file_fails_before_the_run(tmp_path: Path, capsys) -> None:
    link = tmp_path / "out.json"
    link.symlink_to("/proc/nope.json")
    assert main([*ARGS, "--json", str(link)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1
    assert "cannot be opened for writing" in err and str(link) in err


def test_cli_json_replaces_the_report_atomically(tmp_path: Path) -> None:
    """The report goes to a new file moved over the old one: a hard link keeps the old one."""
    out = tmp_path / "out.json"
    out.write_text("old")
    os.link(out, tmp_path / "old.json")
    assert main([*ARGS, "--json", str(out)]) == 0
    assert json.loads(out.read_text())["physics_steps"] == 60
    assert (tmp_path / "old.json").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.json", "out.json"]


def test_cli_json_through_a_symlink_is_written_in_place(tmp_path: Path) -> None:
    target = tmp_path / "real.json"
    target.write_text("")
    link = tmp_path / "out.json"
    link.symlink_to(target)
    assert main([*ARGS, "--json", str(link)]) == 0
    assert link.is_symlink() and json.loads(target.read_text())["physics_steps"] == 60


def test_cli_failed_final_write_is_one_line_and_leaves_no_temporary(
    tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "out.json"
    out.write_text("old")

    def full(src: object, dst: object) -> None:
        raise OSError(28, "No space left on device")

    # Only the report's move fails (a global os.replace patch would also fail numba's cache).
    monkeypatch.setattr("dua_mujoco.cli.publish", full)
    assert main([*ARGS, "--json", str(out)]) == 2
    err = [x for x in capsys.readouterr().err.splitlines() if x.startswith("dua-mujoco:")]
    assert err == [
        f"dua-mujoco: error: --json {str(out)!r} could not be written (No space left on device): "
        "pass another path."
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]
    assert out.read_text() == "old"


def test_cli_dev_full_is_one_line_exit_2(capsys) -> None:
    assert main([*ARGS, "--json", "/dev/full"]) == 2
    err = [x for x in capsys.readouterr().err.splitlines() if x.startswith("dua-mujoco:")]
    assert err == [
        "dua-mujoco: error: --json '/dev/full' could not be written (No space left on device): "
        "pass another path."
    ]


def _interrupting_controller(monkeypatch: pytest.MonkeyPatch, after: int) -> None:
    """Controllers from make_controller raise KeyboardInterrupt at their ``after``-th call."""
    from dua_mujoco.models import scenes

    make = scenes.make_controller

    def make_interrupting(*args: object, **kwargs: object):
        inner = make(*args, **kwargs)  # type: ignore[arg-type]
        calls = [0]

        def controller(m: mujoco.MjModel, d: mujoco.MjData) -> None:
            calls[0] += 1
            if calls[0] == after:
                raise KeyboardInterrupt
            inner(m, d)

        return controller

    monkeypatch.setattr(scenes, "make_controller", make_interrupting)


def test_cli_interrupt_writes_the_partial_report_and_video(
    tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ctrl-C: one line, exit 130, the partial report marked, a playable video of the frames."""
    from dua_mujoco.render import read_video

    out = tmp_path / "out.json"
    out.write_text('{"physics_steps": 60, "interrupted": false}')  # an older run's report
    video = tmp_path / "v.gif"
    _interrupting_controller(monkeypatch, after=42)
    argv = [*ARGS, "--json", str(out), "--video", str(video), "--every", "10"]
    argv += ["--width", "64", "--height", "48"]
    assert main(argv) == 130
    stdout, err = capsys.readouterr()
    assert [x for x in err.splitlines() if x.startswith("dua-mujoco:")] == [
        "dua-mujoco: interrupted after 40 of 60 physics steps: the report covers those "
        '("interrupted": true).'
    ]
    assert "Traceback" not in stdout
    report = json.loads(out.read_text())
    assert report["interrupted"] is True and report["physics_steps"] == 40
    assert read_video(video).shape[0] == 4  # frames at steps 10, 20, 30, 40
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json", "v.gif"]


def test_cli_interrupt_before_the_rollout_is_one_line(
    capsys, monkeypatch: pytest.MonkeyPatch
) -> None:
    from dua_mujoco.runtime import predictor

    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(predictor, "Predictor", interrupted)
    assert main(ARGS) == 130
    assert capsys.readouterr().err.strip().splitlines() == [
        "dua-mujoco: interrupted: no report written."
    ]


def test_cli_broken_bounds_warn_and_strict_exits_3(capsys) -> None:
    argv = ["run", "two_arms", "--steps", "300", "--accel", "0", "--no-progress"]
    assert main(argv) == 0
    err = capsys.readouterr().err
    line = next(x for x in err.splitlines() if x.startswith("WARNING: the declared motion"))
    assert re.search(r"broken \d+ times \(body-steps, \d+ out of contact; bodies 'a_link\d'", line)
    assert "an onset in the period of a violation is not covered by the guarantee" in line
    assert main([*argv, "--strict"]) == 3


def test_cli_strict_exits_1_on_a_miss_outside_a_violations_period(
    capsys, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A miss outside a violation's period (a bug: faked here) exits 1, before the broken
    bounds' 3."""
    real = rollout.run
    violations = []

    def missing(*args: object, **kwargs: object) -> rollout.RunReport:
        report = real(*args, **kwargs)  # type: ignore[arg-type]
        violations.append(report.bound_violations)
        return dataclasses.replace(report, missed_onsets=1, missed_onsets_outside_violations=1)

    monkeypatch.setattr(rollout, "run", missing)
    assert main(ARGS) == 0
    assert "the completeness guarantee is broken" in capsys.readouterr().err
    assert main([*ARGS, "--strict"]) == 1
    assert violations[-1] > 0  # the bounds were broken too: 1 takes precedence over 3


def test_cli_strict_run_with_contact_violations_only_exits_0(capsys) -> None:
    """A contact's impulse breaks the bounds of the bodies it hits: expected, not a failure."""
    argv = ["run", "two_arms", "--steps", "100", "--pilot-steps", "1000", "--no-progress"]
    assert main([*argv, "--strict"]) == 0
    out, err = capsys.readouterr()
    rows = dict(re.split(r"\s{2,}", line.strip(), maxsplit=1) for line in out.splitlines())
    assert int(rows["bound violations (body-steps)"]) > 0
    assert rows["of them out of contact"] == "0"
    assert "WARNING" not in err
    assert rows["active geom pairs in alarm (mean)"].endswith("%")
    assert rows["active geom pairs in contact (mean)"].endswith("%")


def test_cli_every_not_a_multiple_of_period_is_noted(tmp_path: Path, capsys) -> None:
    from dua_mujoco.render import read_video

    video = tmp_path / "v.gif"
    argv = [*ARGS, "--every", "7", "--period", "2", "--video", str(video)]
    assert main([*argv, "--width", "64", "--height", "48"]) == 0
    err = [x for x in capsys.readouterr().err.splitlines() if x.startswith("dua-mujoco:")]
    assert err == [
        "dua-mujoco: note: --every 7 is not a multiple of --period 2: a frame is rendered every "
        "14 physics steps (frames are taken at predictor steps, to draw their alarms)."
    ]
    assert read_video(video).shape[0] == 60 // 14


def test_cli_series_are_written_with_series(tmp_path: Path) -> None:
    out = tmp_path / "out.json"
    assert main([*ARGS, "--series", "--json", str(out)]) == 0
    report = json.loads(out.read_text())
    assert len(report["alarms_per_step"]) == report["predictor_steps"] + 1 == 61


def _video_run_peak(steps: int, video: Path) -> int:
    argv = [*ARGS[:3], str(steps), *ARGS[4:], "--video", str(video), "--every", "1"]
    tracemalloc.start()
    try:
        assert main(argv) == 0
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("suffix", [".gif", ".mp4"])
def test_cli_video_frames_are_not_held(tmp_path: Path, suffix: str, capsys) -> None:
    """A 4x longer video peaks no higher: frames go to the encoder as they are rendered.

    The old CLI kept every frame (230 kB at 320x240) until the end: +9 MB here.
    """
    _video_run_peak(10, tmp_path / f"warm{suffix}")
    short = _video_run_peak(15, tmp_path / f"short{suffix}")
    long = _video_run_peak(55, tmp_path / f"long{suffix}")
    assert long - short < 2_000_000, (short, long)
