"""A/B: the same alarms, bit for bit, from this checkout and another one (e.g. the last release).

    git worktree add --detach /tmp/before <commit>     # then build it in a venv of its own
    python benchmarks/same_alarms.py /tmp/before --before-python /tmp/before/.venv/bin/python

Each side runs in its own subprocess (its own Python: the other checkout's native library is
built in its own environment), on every scene given: a predictor of the given options, driven by
``make_controller``'s random controls (seed 0) after a pilot (seed 99) when ``accel="auto"``,
for ``--steps`` physics steps. Each side reports, per scene, a digest of every step's alarms
(pair ids, the bits of tau, the new flags) and of its bounds, and the first step where the two
sides differ is printed, with each side's standing fraction (the share of sphere pairs in alarm
after a step, ``pair_state().alarm_state()``, its mean over the steps). Scenes: the bundled
ones, and ``robot/<name>`` for the robot models of ``benchmarks/robots.py`` whose packages are
installed in both environments.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from checkouts import HERE, same_mujoco

SCENES = ("two_arms", "traffic", "clutter", "bin_pour", "paper_world")

# Runs inside each side's subprocess: only APIs both sides have.
PROBE = r"""
import hashlib, json, sys, zlib
from pathlib import Path
import numpy as np
import mujoco
from dua_mujoco import PilotOptions, Predictor, load_scene
try:  # the scenes' module: dua_mujoco.models since issue 41, dua_mujoco.mj before
    from dua_mujoco.models.scenes import make_controller
except ImportError:
    from dua_mujoco.mj.scenes import make_controller

scene, steps, options = sys.argv[1], int(sys.argv[2]), json.loads(sys.argv[3])
if scene.startswith("robot/"):
    sys.path.insert(0, str(Path(sys.argv[4])))
    from robots import load_robot
    m = load_robot(scene.split("/", 1)[1])
    d = mujoco.MjData(m)
else:
    m, d = load_scene(scene)
accel = options.pop("accel", "auto")
pilot = PilotOptions(steps=1000, seed=99, controller=make_controller(m, "random", seed=99))
p = Predictor(m, accel=accel, pilot=pilot, **options)
ctrl = make_controller(m, "random", seed=0)
ctrl(m, d)
mujoco.mj_step(m, d)
digest = hashlib.sha256()
bounds = hashlib.sha256(np.ascontiguousarray(p.bounds.accel).tobytes()).hexdigest()[:16]
per_step = []
nalarm = 0
standing = []  # the share of sphere pairs in alarm after each step
def feed(a):
    global nalarm
    pairs = np.ascontiguousarray(a.pairs, dtype=np.int64).tobytes()
    tau = np.ascontiguousarray(a.tau, dtype=np.float64).tobytes()
    new = np.ascontiguousarray(a.new, dtype=np.uint8).tobytes()
    nalarm += len(a)
    digest.update(pairs + tau + new)
    per_step.append(zlib.crc32(pairs + tau + new))
feed(p.reset(d))
for k in range(steps):
    ctrl(m, d)
    mujoco.mj_step(m, d)
    if (k + 1) % p.period == 0:
        feed(p.step(d))
        standing.append(float(np.mean(p.pair_state().alarm_state())))
print(json.dumps({"digest": digest.hexdigest()[:16], "bounds": bounds, "alarms": nalarm,
                  "standing": float(np.mean(standing)), "steps": per_step}))
"""


def side(code: str, checkout: Path, python: str, scene: str, steps: int, options: str) -> dict:
    """One side's report on one scene, run by ``python``: the checkout's own environment, where
    it is installed (so its native library and bundled scenes are its own)."""
    argv = [python, "-c", code, scene, str(steps), options, str(HERE / "benchmarks")]
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.run(argv, env=env, cwd=checkout, capture_output=True, text=True)
    if proc.returncode:
        raise RuntimeError(f"{checkout} on {scene} failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("before", type=Path, help="the other checkout")
    ap.add_argument("--before-python", default=sys.executable, help="its Python (own venv)")
    ap.add_argument("--scenes", nargs="+", default=list(SCENES))
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument(
        "--options", default="{}", help='Predictor options as JSON, e.g. \'{"pairs": "pruned"}\''
    )
    args = ap.parse_args(argv)
    same_mujoco(args.before_python)
    print(
        "| scene | steps | alarms | bounds equal | alarms equal | first differing step | "
        "standing before | standing after / before | s |"
    )
    print("|---" * 9 + "|")
    same_everywhere = True
    for scene in args.scenes:
        t0 = time.perf_counter()
        before = side(PROBE, args.before, args.before_python, scene, args.steps, args.options)
        after = side(PROBE, HERE, sys.executable, scene, args.steps, args.options)
        same = before["digest"] == after["digest"]
        first = next(
            (
                k
                for k, (a, b) in enumerate(zip(before["steps"], after["steps"], strict=True))
                if a != b
            ),
            None,
        )
        same_everywhere &= same
        print(
            f"| {scene} | {args.steps} | {after['alarms']} | "
            f"{before['bounds'] == after['bounds']} | {same} | "
            f"{'' if first is None else first} | {before['standing']:.5f} | "
            f"{after['standing'] / max(before['standing'], 1e-300):.5f} | "
            f"{time.perf_counter() - t0:.0f} |",
            flush=True,
        )
    return 0 if same_everywhere else 1


if __name__ == "__main__":
    raise SystemExit(main())
