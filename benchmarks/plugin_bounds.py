"""The plugin at the pilot's bounds and at a declared bound, timed in one process per robot.

    python benchmarks/plugin_bounds.py                      # every installed robot (about 1.5 min)
    python benchmarks/plugin_bounds.py --robots ur5e h1 --accel 200 --steps 3000

``plugin.py`` times each bound in runs of its own, minutes apart, and a whole run's median moves
by 0.015x or more from one run to the next (docs/benchmarks.md, "A whole A/A at auto bounds"):
more than the two bounds differ by. Here one process per robot steps the model alone and the
model with the plugin at each bound: ``accel="auto"`` (the pilot as ``plugin.py`` builds it,
1,000 steps of random controls, seed 99) and ``--accel`` m/s^2 declared. Each model has its own
``MjData`` driven by the same random controls (seed 0, held 50 steps), in blocks of ``--block``
steps, the order rotated by one model each block (so no model always follows the same one). A
time is the median over a model's steps after ``--skip``; the plugin adds (with / alone - 1),
with its tau evaluations a step. The last lines give the median and the largest over the robots
of what each bound adds.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

from dua_mujoco import CoveringOptions, PilotOptions, Predictor
from dua_mujoco.models.scenes import make_controller
from dua_mujoco.plugin import attach, plugin_outputs

sys.path.insert(0, str(Path(__file__).parent))
from robots import INSTALL, ROBOTS, available, robot_spec

PILOT_SEED = 99
RUN_SEED = 0
# Height fields (dm_control's quadruped terrain) covered by their boxes, as plugin.py does: one
# covering for the bounds' pilot and the attached plugin alike.
COVERING = CoveringOptions(hfield="box")


def _bounds(model: mujoco.MjModel, accel: float) -> dict[str, object]:
    """The two bounds' ``MotionBounds``, as ``plugin.py`` builds them."""
    pilot = PilotOptions(
        steps=1000, seed=PILOT_SEED, controller=make_controller(model, "random", seed=PILOT_SEED)
    )
    auto = Predictor(model, accel="auto", covering=COVERING, pilot=pilot)
    declared = Predictor(model, accel=accel, covering=COVERING)
    return {"auto": auto.bounds, f"{accel:g}": declared.bounds}


def _robot(name: str, accel: float, steps: int, block: int, skip: int) -> dict[str, float]:
    """One robot's row: ``mj_step`` alone (us), and per bound what the plugin adds and its
    evaluations a step."""
    model = robot_spec(name).compile()
    runs = [(None, model)]
    for label, bounds in _bounds(model, accel).items():
        spec = robot_spec(name)
        attach(spec, accel=bounds, covering=COVERING)
        runs.append((label, spec.compile()))
    datas = [mujoco.MjData(m) for _, m in runs]
    drives = [make_controller(m, "random", seed=RUN_SEED) for _, m in runs]
    times = [np.empty(steps) for _ in runs]
    evals: list[list[int]] = [[] for _ in runs]
    for start in range(0, steps, block):
        turn = (start // block) % len(runs)
        for i in [*range(turn, len(runs)), *range(turn)]:
            m, d, drive, out = runs[i][1], datas[i], drives[i], times[i]
            for k in range(start, min(start + block, steps)):
                drive(m, d)
                t0 = time.perf_counter_ns()
                mujoco.mj_step(m, d)
                out[k] = time.perf_counter_ns() - t0
                if i > 0 and k >= skip:
                    evals[i].append(plugin_outputs(m, d).evaluated)
    alone = float(np.median(times[0][skip:]))
    row = {"alone_us": alone / 1e3}
    for i, (label, _) in enumerate(runs[1:], start=1):
        row[f"{label}_adds"] = float(np.median(times[i][skip:])) / alone - 1.0
        row[f"{label}_evals"] = float(np.mean(evals[i]))
    return row


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    ap.add_argument("--robots", nargs="*", default=None, help="default: every installed robot")
    ap.add_argument("--accel", type=float, default=200.0, help="the declared bound, m/s^2")
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--block", type=int, default=150)
    ap.add_argument("--skip", type=int, default=300, help="steps left out of the medians")
    args = ap.parse_args(argv)
    if not 0 <= args.skip < args.steps:
        ap.error(
            f"--skip {args.skip} with --steps {args.steps}: pass a skip from 0 to steps - 1 "
            "(the steps left out of the medians)"
        )
    if args.block < 1:
        ap.error(f"--block {args.block}: pass at least 1 (steps a model runs in turn)")
    if not (np.isfinite(args.accel) and args.accel >= 0.0):
        ap.error(f"--accel {args.accel}: pass a finite bound >= 0 in m/s^2")
    unknown = sorted(set(args.robots or ()) - set(ROBOTS))
    if unknown:
        ap.error(f"unknown robots {', '.join(unknown)}; known: {', '.join(ROBOTS)}")
    missing = sorted(set(args.robots or ()) - set(available()))
    if missing:
        ap.error(f"robots {', '.join(missing)} are not installed: {INSTALL}")
    robots = args.robots or available()
    if not robots:
        ap.error(f"no robot model is installed: {INSTALL}")
    declared = f"{args.accel:g}"
    print(
        f"| robot | `mj_step` alone (us) | auto: plugin adds | evals/step | {declared}: plugin "
        "adds | evals/step |\n|---|---|---|---|---|---|"
    )
    rows = []
    for n, name in enumerate(robots, start=1):
        print(f"[{n}/{len(robots)}] {name}", file=sys.stderr, flush=True)
        r = _robot(name, args.accel, args.steps, args.block, args.skip)
        rows.append(r)
        print(
            f"| {name} | {r['alone_us']:.1f} | {r['auto_adds']:+.3f} | {r['auto_evals']:.1f} | "
            f"{r[declared + '_adds']:+.3f} | {r[declared + '_evals']:.1f} |",
            flush=True,
        )
    auto = np.array([r["auto_adds"] for r in rows])
    other = np.array([r[declared + "_adds"] for r in rows])
    print(
        f"\nplugin adds, median over {len(rows)} robots: auto {np.median(auto):+.3f}x, "
        f"{declared} m/s^2 {np.median(other):+.3f}x; auto higher on {int((auto > other).sum())}"
        f"\nlargest: auto {auto.max():+.3f}x ({robots[int(auto.argmax())]}), {declared} m/s^2 "
        f"{other.max():+.3f}x ({robots[int(other.argmax())]})"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
