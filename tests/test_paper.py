"""Smoke test of the paper reproduction at tiny size (no timing assertions)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest

from dua_mujoco.experiments import paper

ROW_KEYS = {
    "N",
    "mode",
    "dua_evals_per_iter",
    "sa_evals_per_iter",
    "dua_us_per_iter",
    "sa_us_per_iter",
    "dua_false_alarms",
    "sa_false_alarms",
    "agree_dua_sat",
    "agree_sad_sat",
}


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, Path, Path]:
    out = tmp_path_factory.mktemp("paper")
    json_path = out / "paper.json"
    result = paper.run_paper(tiny=True, out_dir=out, json_path=json_path, progress=False)
    return result, out, json_path


def test_json_schema(tiny_run: tuple[dict, Path, Path]) -> None:
    _, _, json_path = tiny_run
    data = json.loads(json_path.read_text())
    rows = data["rows"]
    assert {(r["N"], r["mode"]) for r in rows} == {
        (n, m) for n in (5, 10) for m in ("realtime", "fixed")
    }
    for r in rows:
        assert r.keys() >= ROW_KEYS
        assert r["mode"] in ("realtime", "fixed")
        assert r["missed_collisions"] == 0
        for key in ("agree_dua_sat", "agree_sad_sat"):
            assert r[key] is None or 0.0 <= r[key] <= 100.0
    assert data["table3"], "Table 3 rows missing"
    for a in data["table3"]:
        assert 0.0 <= a["dua_sat_mean"] <= 100.0
        assert 0.0 <= a["sad_sat_mean"] <= 100.0


def test_dua_cheaper_than_sa(tiny_run: tuple[dict, Path, Path]) -> None:
    result, _, _ = tiny_run
    for r in result["rows"]:
        if r["N"] >= 10:
            assert r["dua_evals_per_iter"] < r["sa_evals_per_iter"]
        # The work clock charges each algorithm its own evaluations.
        if r["mode"] == "realtime":
            assert r["dt_dua"] < r["dt_sa"]
        else:
            assert r["dt_dua"] == r["dt_sa"]


def test_outputs_written(tiny_run: tuple[dict, Path, Path]) -> None:
    result, out, _ = tiny_run
    md = (out / "paper-tables.md").read_text()
    assert md == result["markdown"]
    for heading in ("Table 1", "Table 2", "Table 3"):
        assert heading in md
    for png in ("paper-cost.png", "paper-false-alarms.png", "paper-agreement.png"):
        assert (out / png).stat().st_size > 0


def test_cli_arguments() -> None:
    parser = argparse.ArgumentParser()
    paper.add_arguments(parser)
    args = parser.parse_args(["--quick", "--json", "x.json", "--seeds", "4", "--no-progress"])
    assert args.quick and args.json == Path("x.json") and args.seeds == 4 and args.no_progress
    assert parser.parse_args([]).out == Path("out/paper")


def test_work_clock_model() -> None:
    clock = paper.WorkClock()
    assert clock.dt(10) == pytest.approx(
        paper.PAPER_SECONDS_PER_EVAL
        * (10 + paper.MEASURED_NS_OVERHEAD / paper.MEASURED_NS_PER_EVAL)
    )
    assert clock.dt(780) > 50 * clock.dt(10)
