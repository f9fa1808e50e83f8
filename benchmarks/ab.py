"""A/B: this checkout against another one (e.g. the last release), interleaved in one run.

    git worktree add --detach /tmp/before <commit>
    python benchmarks/ab.py /tmp/before            # prints a markdown table

Each side runs in its own subprocess (``PYTHONPATH`` set to its checkout), alternately, ``--rounds``
times; every number is the median over rounds of per-round medians, and the ratio is
after / before from those medians. The predictor runs DUA (the paper's schedule, the only one
the older versions have, with the older urgency) and, on this side only, the defaults.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from checkouts import run

HERE = Path(__file__).resolve().parents[1]

# Runs inside each side's subprocess: only APIs both sides have, found where each keeps them.
PROBE = r"""
import json, sys, time
import numpy as np
import mujoco
import dua_mujoco
from dua_mujoco import DUAScheduler
# Decided by the package's own layout: the editable install's finder can resolve a module the
# other side lacks to this checkout's copy.
if hasattr(dua_mujoco, "SphereWorld"):
    from dua_mujoco import SphereWorld
    from dua_mujoco.predictor import Predictor
    from dua_mujoco.scenes import load_scene, make_controller
else:
    from dua_mujoco.experiments.paper.world import SphereWorld
    from dua_mujoco import Predictor, load_scene
    try:  # the scenes' module: dua_mujoco.models since issue 41, dua_mujoco.mj before
        from dua_mujoco.models.scenes import make_controller
    except ImportError:
        from dua_mujoco.mj.scenes import make_controller
if sys.argv[1] == "after":  # the Predictor's options are grouped on this side
    from dua_mujoco import CoveringOptions

def median_us(fn, n):
    ts = []
    for _ in range(n):
        t0 = time.perf_counter(); fn(); ts.append(time.perf_counter() - t0)
    return float(np.median(ts)) * 1e6

out = {}
w = SphereWorld(1415, seed=1, radius=0.005)
pairs = w.pairs()
s = DUAScheduler(pairs.tau(np.arange(len(pairs)), w.positions, w.velocities), dt=0.01)
for _ in range(50):
    s.step_points(pairs, w.positions, w.velocities)
out["fused DUA step on free spheres, M = 1e6 (us)"] = median_us(
    lambda: s.step_points(pairs, w.positions, w.velocities), 2000)
schedules = ["dua"] + (["deadline"] if sys.argv[1] == "after" else [])
for scene in ("two_arms", "traffic", "clutter", "paper_world:200"):
    for schedule in schedules:
        m, d = load_scene(scene)
        # Like with like: the paper's schedule with the previous urgency (every geom a sphere);
        # the default (deadline, static geoms as shapes) on this side only.
        kw = {} if sys.argv[1] == "before" else (
            {"schedule": "dua", "covering": CoveringOptions(static="sphere")}
            if schedule == "dua"
            else {}
        )
        p = Predictor(m, accel=30.0, **kw)
        ctrl = make_controller(m, "random", seed=0)
        mujoco.mj_step(m, d)
        p.reset(d)
        tp, tm = [], []
        for _ in range(1000):
            ctrl(m, d)
            t0 = time.perf_counter(); mujoco.mj_step(m, d); t1 = time.perf_counter()
            p.step(d); t2 = time.perf_counter()
            tm.append(t1 - t0); tp.append(t2 - t1)
        out[f"{scene}: Predictor.step, {schedule} (us)"] = float(np.median(tp)) * 1e6
        out[f"{scene}: mj_step, {schedule} run (us)"] = float(np.median(tm)) * 1e6
print(json.dumps(out))
"""


def run_side(checkout: Path, side: str) -> dict[str, float]:
    return json.loads(run(PROBE, checkout, side).strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path, help="checkout to compare against")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args(argv)
    runs: dict[str, list[dict[str, float]]] = {"before": [], "after": []}
    for r in range(args.rounds):
        for side, path in (("before", args.before), ("after", HERE)):
            print(f"round {r + 1}/{args.rounds}: {side}", file=sys.stderr)
            runs[side].append(run_side(path.resolve(), side))
    keys = list(runs["after"][0])
    rows = ["| measurement | before | after | after / before |", "|---|---|---|---|"]
    for key in keys:
        after = float(np.median([r[key] for r in runs["after"]]))
        if key in runs["before"][0]:
            before = float(np.median([r[key] for r in runs["before"]]))
            rows.append(f"| {key} | {before:.2f} | {after:.2f} | {after / before:.2f} |")
        else:
            rows.append(f"| {key} | | {after:.2f} | |")
    print("\n".join(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
