"""``dua-mujoco sweep``: option grids, local worker processes and Ray give the same rows; a
failing or crashing run is one row; Ctrl-C writes the rows done."""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from screens import ctrl_c_able

from dua_mujoco.cli import main
from dua_mujoco.exceptions import InvalidChoiceError, InvalidInputError
from dua_mujoco.run_options import add_run_options
from dua_mujoco.sweep import DETERMINISTIC, OptionSet, option_sets, run_task, sweep, tasks_of

# Short runs: a small pilot and a few hundred steps are enough for rows to compare.
FAST = ["--steps", "150", "--pilot-steps", "200"]


def _base(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_run_options(parser)
    return parser.parse_args([*FAST, *argv])


def crash_on_traffic(task):
    """A runner whose process dies on one scene (as a segfault in native code would)."""
    if task.scene == "traffic":
        os.kill(os.getpid(), signal.SIGSEGV)
    return run_task(task)


def raise_on_traffic(task):
    if task.scene == "traffic":
        raise RuntimeError("the runner itself broke")
    return run_task(task)


# --- option sets ---------------------------------------------------------------------------


def test_grid_lists_multiply_and_named_sets_combine_with_every_point() -> None:
    base = _base("--accel", "30")
    sets = option_sets(
        {
            "grid": {"covering": ["bounding", "multi"], "violation_events": [True, False]},
            "set": [{"name": "spheres", "exact": False}, {"name": "exact"}],
        },
        base,
    )
    assert len(sets) == 8
    first = sets[0]
    assert first.name == "spheres, covering=bounding, violation_events=true"
    assert (first.options.exact, first.options.covering, first.options.violation_events) == (
        False,
        "bounding",
        True,
    )
    assert sets[-1].options.exact is True and sets[-1].options.covering == "multi"
    assert all(s.options.accel == 30.0 for s in sets)  # the command line's options stay
    assert base.covering == "bounding" and base.exact is True  # not modified


def test_grid_values_are_parsed_as_on_the_command_line() -> None:
    (one,) = option_sets({"set": [{"name": "a", "accel": "auto", "max-spheres": 4}]}, _base())
    assert one.options.accel == "auto" and one.options.max_spheres == 4
    (two,) = option_sets({"set": [{"accel": 12}]}, _base())
    assert two.options.accel == 12.0 and two.name == "set 1"


@pytest.mark.parametrize(
    ("doc", "error", "says"),
    [
        ({"grid": {"accell": [1]}}, InvalidChoiceError, "'accell'. Valid choices: 'accel'"),
        ({"grid": {"seed": [1, 2]}}, InvalidChoiceError, "'seed'"),
        ({"grid": {"covering": ["nope"]}}, InvalidChoiceError, "'bounding', 'multi'"),
        ({"grid": {"accel": [-1]}}, InvalidInputError, "accel = -1 is invalid"),
        ({"grid": {"exact": ["no"]}}, InvalidInputError, "it is a switch, true or false"),
        ({"grid": {"accel": []}}, InvalidInputError, "give a non-empty list"),
        ({"grids": {}}, InvalidChoiceError, "Unknown table 'grids'"),
        ({"set": [{"name": "a"}, {"name": "a"}]}, InvalidInputError, "['a'] repeat"),
        (
            {"grid": {"accel": [1]}, "set": [{"accel": 2}]},
            InvalidInputError,
            "set both in [grid] and in [[set]]",
        ),
    ],
)
def test_bad_grids_are_refused_with_the_fix(doc, error, says: str) -> None:
    with pytest.raises(error, match=None) as exc:
        option_sets(doc, _base())
    assert says in str(exc.value)


def test_a_scene_after_ray_is_not_taken_for_its_address(capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["sweep", "--ray", "two_arms"])
    assert exc.value.code == 2
    assert "'two_arms' is not a Ray address" in capsys.readouterr().err


def test_a_bad_grid_file_is_exit_2_before_any_run(tmp_path: Path, capsys) -> None:
    grid = tmp_path / "grid.toml"
    grid.write_text("[grid]\naccel = [1, \n")
    assert main(["sweep", "two_arms", "--grid", str(grid)]) == 2
    assert "cannot be read" in capsys.readouterr().err
    assert main(["sweep", "two_arms", "no_such_scene"]) == 2
    assert "Unknown scene 'no_such_scene'" in capsys.readouterr().err


# --- runs ----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def broken_xml(tmp_path_factory: pytest.TempPathFactory) -> str:
    path = tmp_path_factory.mktemp("scenes") / "broken.xml"
    path.write_text("<mujoco><worldbody><geom type='box'/></worldbody></mujoco>")  # no size
    return str(path)


def test_sweep_command_writes_one_row_a_run_and_a_failing_scene_is_one_row(
    tmp_path: Path, broken_xml: str, capsys
) -> None:
    out = tmp_path / "rows.json"
    table = tmp_path / "rows.md"
    argv = ["sweep", "two_arms", broken_xml, "--seeds", "2", "--seed", "5", *FAST]
    code = main([*argv, "--workers", "2", "--json", str(out), "--markdown", str(table)])
    assert code == 4  # a run failed
    doc = json.loads(out.read_text())
    rows = doc["rows"]
    assert doc["interrupted"] is False
    assert [(r["scene"], r["seed"]) for r in rows] == [
        ("two_arms", 5),
        ("two_arms", 6),
        (broken_xml, 5),
        (broken_xml, 6),
    ]
    for ok in rows[:2]:
        assert ok["error"] is None and ok["steps"] == 150 and ok["onsets"] >= 0
        assert ok["missed_outside_violations"] == 0 and 0 <= ok["standing_fraction"] < 1
        assert ok["predictor_us"] > 0 and ok["mj_step_us"] > 0
    assert rows[0]["predicted"] is not None
    for bad in rows[2:]:
        assert "cannot load the model" in bad["error"] and bad["steps"] is None
    printed = capsys.readouterr()
    assert printed.out.strip() == table.read_text().strip()
    assert sum(line.startswith("| ") for line in printed.out.splitlines()) == 5  # header, rows
    assert "4 of 4 runs done on local processes, 2 failed" in printed.err


def test_a_run_whose_process_dies_is_a_row_and_the_sweep_goes_on() -> None:
    sets = [OptionSet("default", _base())]
    tasks = tasks_of(["traffic", "two_arms", "traffic", "two_arms"], [0], sets)
    rows = sweep(tasks, workers=2, runner=crash_on_traffic)
    assert [r["scene"] for r in rows] == ["traffic", "two_arms", "traffic", "two_arms"]
    assert rows[0]["error"] == rows[2]["error"] == "worker died (exit code -11, SIGSEGV)"
    assert rows[1]["error"] is None and rows[3]["error"] is None
    assert {k: rows[1][k] for k in DETERMINISTIC} == {k: rows[3][k] for k in DETERMINISTIC}
    raised = sweep(tasks[:2], workers=1, runner=raise_on_traffic)
    assert raised[0]["error"] == "RuntimeError: the runner itself broke"
    assert raised[1]["error"] is None


def test_ray_gives_the_rows_local_processes_give_and_a_crash_is_a_row() -> None:
    ray = pytest.importorskip("ray")  # an extra: installed with dua_mujoco[test]
    sets = option_sets({"grid": {"exact": [True, False]}}, _base())
    tasks = tasks_of(["two_arms", "traffic"], [0, 1], sets)
    local = sweep(tasks, workers=2)
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        # The test module is not importable on Ray's workers: send the runner by value.
        ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
        remote = sweep(tasks, workers=2, ray=True)
        crashed = sweep(tasks[:1] + tasks[4:5], ray=True, runner=crash_on_traffic)
    finally:
        ray.shutdown()
    assert len(local) == len(remote) == 8
    for a, b in zip(local, remote, strict=True):
        assert a["error"] is None and b["error"] is None
        assert {k: a[k] for k in DETERMINISTIC} == {k: b[k] for k in DETERMINISTIC}
    assert crashed[0]["error"] is None
    assert crashed[1]["scene"] == "traffic" and crashed[1]["error"].startswith(
        ("WorkerCrashedError", "ActorDiedError")
    ), crashed[1]["error"]


def test_ctrl_c_writes_the_rows_done_and_exits_130(tmp_path: Path) -> None:
    out = tmp_path / "rows.json"
    argv = [sys.executable, "-m", "dua_mujoco", "sweep", "two_arms", "--seeds", "8"]
    argv += ["--workers", "1", "--steps", "2000", "--pilot-steps", "200", "--json", str(out)]
    proc = subprocess.Popen(
        ctrl_c_able(argv), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    assert proc.stderr is not None
    seen = []
    deadline = time.monotonic() + 300
    for line in proc.stderr:  # the progress line of the first run done
        seen.append(line)
        if "sweep (local processes) 1/8" in line or time.monotonic() > deadline:
            break
    proc.send_signal(signal.SIGINT)
    try:
        stdout, stderr = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:  # deaf to Ctrl-C: killed, and the test fails below
        proc.kill()
        stdout, stderr = proc.communicate()
    assert proc.returncode == 130, "".join(seen) + stderr
    doc = json.loads(out.read_text())
    assert doc["interrupted"] is True
    assert 1 <= len(doc["rows"]) < 8
    assert all(r["error"] is None for r in doc["rows"])
    assert stdout.count("| two_arms |") == len(doc["rows"])
    assert "interrupted: the table holds the runs done" in stderr
    assert "Traceback" not in stderr
