"""Smoke test of the peers benchmark (dua_mujoco.experiments.peers) at a tiny size."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dua_mujoco.experiments import peers
from dua_mujoco.experiments.peers import (
    GHOST_PEERS,
    SCENE_PEERS,
    GhostRow,
    SceneRow,
    grid_candidates,
    run_peers,
    sweep_candidates,
)

SIZES = (12, 40)
GHOST_KEYS = {f for f in GhostRow.__dataclass_fields__}
SCENE_KEYS = {f for f in SceneRow.__dataclass_fields__}


@pytest.fixture(scope="module")
def result(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, Path]:
    out = tmp_path_factory.mktemp("peers")
    json_path = out / "copy.json"
    res = run_peers(
        quick=True,
        sizes=SIZES,
        steps=40,
        scenes=("paper_world",),
        scene_steps=80,
        memory=False,
        progress=False,
        out_dir=out,
        json_path=json_path,
    )
    return res, out


def test_one_ghost_row_per_peer_and_size(result: tuple[dict, Path]) -> None:
    res, _ = result
    expected = [p for p in GHOST_PEERS if p != "FCL" or peers.fcl_available()]
    got = {(r["peer"], r["n"]) for r in res["ghost"]}
    assert got == {(p, n) for p in expected for n in SIZES}
    for r in res["ghost"]:
        assert set(r) == GHOST_KEYS
        assert r["time_us"] > 0
        assert r["pairs"] == r["n"] * (r["n"] - 1) // 2


def test_scene_rows_have_the_metric_keys(result: tuple[dict, Path]) -> None:
    res, _ = result
    assert [r["peer"] for r in res["scenes"]] == list(SCENE_PEERS)
    for r in res["scenes"]:
        assert set(r) == SCENE_KEYS


def test_complete_peers_miss_nothing_in_the_ghost_world(result: tuple[dict, Path]) -> None:
    """SA(tau), the swept-sphere broadphases and DUA are complete when the bounds hold."""
    res, _ = result
    rows = [r for r in res["ghost"] if r["peer"] in ("DUA", "SA(tau)", "sweep", "grid")]
    assert rows
    assert sum(r["onsets"] for r in rows) > 0, "the tiny world should collide at least once"
    for r in rows:
        assert r["missed"] == 0, r


def test_complete_peers_miss_nothing_on_the_scene(result: tuple[dict, Path]) -> None:
    res, _ = result
    for r in res["scenes"]:
        if r["peer"] in ("DUA", "SA(tau)", "sweep", "grid"):
            assert r["missed"] == 0, r


def test_files_are_written(result: tuple[dict, Path]) -> None:
    res, out = result
    assert (out / "peers.md").read_text().startswith("# DUA against its peers")
    assert json.loads((out / "peers.json").read_text())["ghost"] == res["ghost"]
    assert json.loads((out / "copy.json").read_text())["meta"]["latency"] == 1
    pytest.importorskip("matplotlib")
    for name in ("peers_time.png", "peers_false_alarms.png", "peers_candidates.png"):
        assert (out / name).stat().st_size > 0


def test_speculative_demo_shows_a_tunnel_dua_predicts(result: tuple[dict, Path]) -> None:
    """A body accelerated from rest tunnels through a thin plate with speculative contacts on;
    DUA, given the acceleration bound, alarms before the sphere reaches the plate."""
    res, _ = result
    rest = [r for r in res["tunnel"] if r["speed0"] == 0.0 and r["accel"] > 0]
    assert any(r["speculative"] == "tunneled" for r in rest)
    for r in res["tunnel"]:
        assert 0 <= r["dua_alarm_step"] < r["crossing_step"], r


@pytest.mark.parametrize("find", [sweep_candidates, grid_candidates])
def test_broadphases_find_every_overlap(find: object) -> None:
    rng = np.random.default_rng(3)
    c = rng.uniform(-1, 1, (300, 3))
    r = rng.uniform(0.01, 0.12, 300)
    a, b = find(c, r)  # type: ignore[operator]
    got = {(min(i, j), max(i, j)) for i, j in zip(a.tolist(), b.tolist(), strict=True)}
    assert len(got) == a.size, "each candidate pair once"
    d = np.linalg.norm(c[:, None] - c[None], axis=2)
    i, j = np.nonzero(np.triu(d <= r[:, None] + r[None], 1))
    assert set(zip(i.tolist(), j.tolist(), strict=True)) <= got


def test_memory_probe_runs_in_a_subprocess() -> None:
    """The probe is imported by module path in a fresh interpreter: a moved module fails here."""
    from dua_mujoco.experiments.peers.memory import memory_row

    row = memory_row("grid", 30)
    assert not row.note.startswith("failed"), row.note
    assert row.pairs == 30 * 29 // 2
    assert row.step_us > 0 and row.build_s >= 0
