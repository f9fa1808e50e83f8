"""``run_peers``: every peer on the ghost world, the scenes, the tunnel demo and at large N."""

from __future__ import annotations

import json
import os
import time
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import mujoco

from dua_mujoco.experiments.peers.fcl_tree import fcl_available
from dua_mujoco.experiments.peers.ghost import GHOST_PEERS, run_ghost_peer
from dua_mujoco.experiments.peers.ghost_world import ghost_truth, record_ghost
from dua_mujoco.experiments.peers.horizon import LATENCY
from dua_mujoco.experiments.peers.markdown import markdown
from dua_mujoco.experiments.peers.memory import memory_row
from dua_mujoco.experiments.peers.plan import make_plan
from dua_mujoco.experiments.peers.plots import plots
from dua_mujoco.experiments.peers.rows import GhostRow, MemoryRow, SceneRow
from dua_mujoco.experiments.peers.scene import run_scene
from dua_mujoco.experiments.peers.tracker import onsets_by_step, truth_keys
from dua_mujoco.experiments.peers.tunnel import tunnel_cases, tunnel_sweep
from dua_mujoco.experiments.report import jsonable
from dua_mujoco.progress import Progress

__all__ = ["run_peers"]


def run_peers(
    *,
    quick: bool = False,
    out_dir: Path | None = None,
    json_path: Path | None = None,
    progress: bool = True,
    sizes: Sequence[int] | None = None,
    steps: int | None = None,
    scenes: Sequence[str] | None = None,
    scene_steps: int | None = None,
    memory: bool = True,
    seed: int = 0,
) -> dict[str, Any]:
    """Measure DUA against its peers; write ``peers.md``, plots and JSON.

    Args:
        quick: Small sizes and short runs (under two minutes).
        out_dir: Folder for ``peers.md``, ``peers.json`` and ``peers_*.png`` (None: write nothing
            there).
        json_path: Also write the JSON here.
        progress: Draw a progress line on stderr.
        sizes: Override the ghost-world sphere counts.
        steps: Override the ghost-world predictor steps.
        scenes: Override the bundled scenes (empty: none).
        scene_steps: Override the physics steps per scene.
        memory: Run the large-N memory probes (subprocesses).
        seed: Seed of the worlds and controls.

    Returns:
        A JSON-ready dict with ``ghost``, ``scenes``, ``memory``, ``tunnel``, ``tunnel_sweep``
        (lists of row dicts), ``meta`` and ``runtime_s``.
    """
    start = time.perf_counter()
    load_before = os.getloadavg()
    result = _run(quick, progress, sizes, steps, scenes, scene_steps, memory, seed)
    result["meta"]["load_average"] = [load_before[0], os.getloadavg()[0]]
    result["runtime_s"] = time.perf_counter() - start
    result = jsonable(result)
    if out_dir is not None:
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / "peers.json").write_text(json.dumps(result, indent=2))
        (out_dir / "peers.md").write_text(markdown(result))
        plots(result, out_dir)
    if json_path is not None:
        json_path = Path(json_path)
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(result, indent=2))
    return result


def _run(
    quick: bool,
    progress: bool,
    sizes: Sequence[int] | None,
    steps: int | None,
    scenes: Sequence[str] | None,
    scene_steps: int | None,
    memory: bool,
    seed: int,
) -> dict[str, Any]:
    plan = make_plan(quick)
    sizes = tuple(sizes) if sizes is not None else plan.sizes
    steps = int(steps) if steps is not None else plan.steps
    extra = plan.extra if steps == plan.steps else steps
    scene_list = tuple(scenes) if scenes is not None else plan.scenes
    scene_steps = int(scene_steps) if scene_steps is not None else plan.scene_steps
    has_fcl = fcl_available()
    ghost_peers = [p for p in GHOST_PEERS if p != "FCL" or has_fcl]
    notes = []
    if not has_fcl:
        notes.append("python-fcl is not installed (pip install python-fcl): FCL rows skipped.")
    units = len(sizes) * len(ghost_peers) + len(scene_list) + 2
    if memory:
        units += len(plan.memory_peers)
    ghost_rows: list[GhostRow] = []
    scene_rows: list[SceneRow] = []
    memory_rows: list[MemoryRow] = []
    with Progress(units, "peers", enabled=progress) as bar:
        for n in sizes:
            world = record_ghost(n, steps, extra, seed)
            truth_steps = ghost_truth(world)
            onsets = onsets_by_step(truth_steps[: steps + 1])
            keys = truth_keys(truth_steps)
            for name in ghost_peers:
                bar.update(0, note=f"N={n} {name}")
                if name == "SA(tau)" and n > plan.sa_max_n:
                    bar.update()
                    continue
                ghost_rows.append(run_ghost_peer(name, world, steps, onsets, keys))
                bar.update(note=f"N={n} {name}")
        for scene in scene_list:
            bar.update(0, note=f"scene {scene}")
            scene_rows.extend(run_scene(scene, scene_steps, seed))
            bar.update(note=f"scene {scene}")
        bar.update(0, note="speculative demo")
        tunnel = tunnel_cases()
        bar.update()
        sweep = tunnel_sweep(plan.tunnel_accels, plan.tunnel_clearances)
        bar.update()
        if memory:
            for peer in plan.memory_peers:
                if peer == "FCL" and not has_fcl:
                    bar.update()
                    continue
                bar.update(0, note=f"memory N={plan.memory_n} {peer}")
                memory_rows.append(memory_row(peer, plan.memory_n))
                bar.update()
    result: dict[str, Any] = {
        "meta": {
            "quick": quick,
            "latency": LATENCY,
            "ghost_steps": steps,
            "ghost_truth_steps": steps + extra,
            "scene_steps": scene_steps,
            "seed": seed,
            "density": "paper's: 40 spheres per unit volume; box = (N/40)^(1/3)",
            "mujoco": mujoco.__version__,
            "fcl": has_fcl,
            "cpus": os.cpu_count(),
            "threads": 1,
            "notes": notes,
        },
        "ghost": [asdict(r) for r in ghost_rows],
        "scenes": [asdict(r) for r in scene_rows],
        "memory": [asdict(r) for r in memory_rows],
        "tunnel": [asdict(r) for r in tunnel],
        "tunnel_sweep": sweep,
    }
    return result
