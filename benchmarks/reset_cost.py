"""What ``mj_resetData`` and ``mj_step`` cost with the plugin, before and after a change, in one
run: the static guard's price (docs/benchmarks.md, "Reset cost").

    python benchmarks/reset_cost.py BEFORE --before-python BEFORE/.venv/bin/python
    python benchmarks/reset_cost.py BEFORE --before-python ... --tool time   # wall clock

Each side (its own Python, the checkout's own install, as benchmarks/same_alarms.py runs them)
attaches the predictor (``accel=20``, no pilot) to each scene and saves the model with and
without the plugin as ``.mjb``; then one process per side loads them and runs ``--resets``
``mj_resetData`` calls and ``--steps`` ``mj_step`` calls on each. ``callgrind`` (the default)
counts the instructions inside ``mj_resetData`` and inside ``mj_step`` only
(``--toggle-collect``), so the counts do not depend on the machine's load; ``time`` takes the
median over rounds of the wall clock. The plugin's cost is the model with it less the model
without: per reset, and per step.

Scenes: ``boxes+hfield`` (300 static boxes on the world body, a 512 x 512 height field, a ball
on a free joint falling onto them: the guard's worst case here, 300 poses and a 1 MB digest per
reset) and bundled scenes (``clutter``: meshes and a mocap body; ``rough_terrain``: a height
field; ``two_arms``).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from checkouts import same_mujoco

HERE = Path(__file__).resolve().parents[1]
SCENES = ("boxes+hfield", "clutter", "rough_terrain", "two_arms")

# Run by each side's Python in its own checkout: saves each scene with and without the plugin.
BUILD = r"""
import sys, warnings
import mujoco
import numpy as np
from dua_mujoco.models.scenes import load_spec
from dua_mujoco.plugin import attach

folder, scenes = sys.argv[1], sys.argv[2:]

def boxes_and_hfield():
    n = 512
    rng = np.random.default_rng(0)
    spec = mujoco.MjSpec()
    hf = spec.add_hfield(name="ground", nrow=n, ncol=n, size=[10, 10, 0.5, 0.1])
    hf.userdata = list(rng.random(n * n) * 0.2)
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_HFIELD, hfieldname="ground")
    for i in range(300):
        x, y = -7.5 + (i % 20) * 0.8, -6.0 + (i // 20) * 0.8
        spec.worldbody.add_geom(
            type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.2, 0.2, 0.2], pos=[x, y, 0.4]
        )
    ball = spec.worldbody.add_body(pos=[0.1, 0.1, 1.5])
    ball.add_freejoint()
    ball.add_geom(size=[0.1, 0, 0])
    return spec

for scene in scenes:
    for plugin in (False, True):
        spec = boxes_and_hfield() if scene == "boxes+hfield" else load_spec(scene)
        if plugin:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                attach(spec, accel=20.0)
        m = spec.compile()
        mujoco.mj_saveModel(m, f"{folder}/{scene}.{int(plugin)}.mjb", None)
"""

# Loads each model and runs it: resets, then steps (callgrind counts inside each call only).
RUN = r"""
import json, sys, time
import mujoco
import dua_mujoco.plugin  # registers dua_mujoco.predictor

resets, steps, timed, paths = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3] == "1", sys.argv[4:]
out = {}
for path in paths:
    m = mujoco.MjModel.from_binary_path(path)
    d = mujoco.MjData(m)
    mujoco.mj_step(m, d)
    mujoco.mj_version()  # callgrind: a dump before the counted calls
    best = {}
    for name, call, n in (("reset", mujoco.mj_resetData, resets), ("step", mujoco.mj_step, steps)):
        rounds = []
        for _ in range(5 if timed else 1):
            t0 = time.perf_counter()
            for _ in range(n):
                call(m, d)
            rounds.append((time.perf_counter() - t0) / n)
        rounds.sort()
        best[name] = rounds[len(rounds) // 2] * 1e6
        mujoco.mj_version()
    out[path] = best
print(json.dumps(out))
"""


def side(checkout: Path, python: str, folder: Path, args: argparse.Namespace) -> dict:
    """One side's cost per scene: the plugin's microseconds (time) or instructions (callgrind)
    per reset and per step, with the model's own."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    build = [python, "-c", BUILD, str(folder), *args.scenes]
    subprocess.run(build, env=env, cwd=checkout, check=True, capture_output=True)
    paths = [str(folder / f"{s}.{p}.mjb") for s in args.scenes for p in (0, 1)]
    timed = args.tool == "time"
    run = [python, "-c", RUN, str(args.resets), str(args.steps), str(int(timed)), *paths]
    prefix: list[str] = []
    if not timed:
        prefix = [
            "valgrind",
            "--tool=callgrind",
            "--collect-atstart=no",
            "--toggle-collect=mj_resetData",
            "--toggle-collect=mj_step",
            "--dump-before=mj_version",
            f"--callgrind-out-file={folder}/cg.out",
        ]
    proc = subprocess.run(
        [*prefix, *run], env=env, cwd=checkout, capture_output=True, text=True, check=False
    )
    if proc.returncode:
        raise RuntimeError(f"{checkout} failed:\n{proc.stderr[-3000:]}")
    cost = json.loads(proc.stdout.strip().splitlines()[-1])
    if not timed:
        # Dumps before each mj_version: [start, reset, step] per model (the first holds the
        # set-up's calls), in the paths' order.
        dumps = sorted(folder.glob("cg.out.*"), key=lambda p: int(p.suffix[1:]))
        for k, path in enumerate(paths):
            reset, step = (_instructions(dumps[3 * k + j]) for j in (1, 2))
            cost[path] = {"reset": reset / args.resets, "step": step / args.steps}
    rows = {}
    for s in args.scenes:
        plain, plugin = cost[str(folder / f"{s}.0.mjb")], cost[str(folder / f"{s}.1.mjb")]
        rows[s] = {k: (plugin[k] - plain[k], plain[k]) for k in ("reset", "step")}
    return rows


def _instructions(dump: Path) -> float:
    """The instructions a callgrind dump counted (its summary line)."""
    for line in dump.read_text().splitlines():
        if line.startswith(("summary:", "totals:")):
            return float(line.split()[1])
    raise RuntimeError(f"{dump}: no summary line")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("before", type=Path, help="the other checkout")
    ap.add_argument("--before-python", default=sys.executable, help="its Python (own venv)")
    ap.add_argument("--scenes", nargs="+", default=list(SCENES))
    ap.add_argument("--tool", choices=("callgrind", "time"), default="callgrind")
    ap.add_argument("--resets", type=int, default=None, help="default: 20 (callgrind), 2000")
    ap.add_argument("--steps", type=int, default=None, help="default: 20 (callgrind), 2000")
    args = ap.parse_args(argv)
    n = 20 if args.tool == "callgrind" else 2000
    args.resets = args.resets or n
    args.steps = args.steps or n
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "before").mkdir()
        (Path(tmp) / "after").mkdir()
        same_mujoco(args.before_python)
        before = side(args.before, args.before_python, Path(tmp) / "before", args)
        after = side(HERE, sys.executable, Path(tmp) / "after", args)
    unit = "instructions" if args.tool == "callgrind" else "us"
    print(
        f"| scene | plugin's reset before ({unit}) | after | after - before | "
        f"mj_resetData alone | plugin's step before | after |"
    )
    print("|---" * 7 + "|")
    for s in args.scenes:
        (rb, plain_r), (sb, _) = before[s]["reset"], before[s]["step"]
        (ra, _), (sa, _) = after[s]["reset"], after[s]["step"]
        print(
            f"| {s} | {rb:,.1f} | {ra:,.1f} | {ra - rb:+,.1f} | {plain_r:,.1f} | "
            f"{sb:,.1f} | {sa:,.1f} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
