"""``dua-mujoco run swarm:N --steps 100`` end to end, and its parts, A/B against another checkout.

    python benchmarks/swarm_command.py --before /tmp/before            # N = 20,000, 3 rounds
    python benchmarks/swarm_command.py --before /tmp/before --n 5000 --rounds 5

Each round runs both sides, alternating, each in fresh processes (``checkouts.probe``: a
checkout with a ``.venv`` runs in its own Python):

* the parts, in one process: the scene generated (``load_spec("swarm:N")``), compiled by MuJoCo
  (``spec.compile()``, MuJoCo's own compile of the scene), the predictor set up
  (``Predictor(model, accel=2)``: declared bounds, as ``benchmarks/many.py --mujoco`` runs the
  swarms) and 100 monitored steps (``run``, as the command rolls out);
* the command, ``dua-mujoco run swarm:N --steps 100 --accel 2`` (its ``main`` in a fresh
  interpreter), wall time from start to exit (imports, the report and the exit included).

The table gives each side's medians over the rounds and the command's time in compiles; a second
table the same in CPU seconds (``time.process_time`` of the parts, the child's user + system
time of the command), which a machine shared with other jobs inflates less than wall time.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

from checkouts import HERE, probe

# Runs on either checkout: only APIs both have.
PARTS = r"""
import json, sys, time
import mujoco
from dua_mujoco import Predictor, run
try:  # the scenes' module: dua_mujoco.models since issue 41, dua_mujoco.mj before
    from dua_mujoco.models.scenes import load_spec, make_controller
except ImportError:
    from dua_mujoco.mj.scenes import load_spec, make_controller
n = int(sys.argv[1])
def now():
    return time.perf_counter(), time.process_time()
t0 = now(); spec = load_spec(f"swarm:{n}")
t1 = now(); model = spec.compile()
t2 = now(); data = mujoco.MjData(model); mujoco.mj_forward(model, data)
t3 = now(); p = Predictor(model, accel=2.0)
t4 = now()
run(model, data, p, steps=100, controller=make_controller(model, "random", seed=0),
    progress=False, series=False)
t5 = now()
out = {}
for suffix, k in (("", 0), ("_cpu", 1)):
    out.update({"generate" + suffix: t1[k] - t0[k], "compile" + suffix: t2[k] - t1[k],
                "setup" + suffix: t4[k] - t3[k], "steps" + suffix: t5[k] - t4[k]})
print(json.dumps(out))
"""

COMMAND = "import sys\nfrom dua_mujoco.__main__ import main\nsys.exit(main(sys.argv[1:]))"


def parts(checkout: Path, n: int) -> dict[str, float]:
    """The parts' seconds on ``checkout``."""
    argv, env = probe(PARTS, checkout, str(n))
    out = subprocess.run(argv, env=env, cwd=checkout, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def command(checkout: Path, n: int) -> tuple[float, float]:
    """The command's wall seconds on ``checkout``, from the process's start to its exit, and its
    CPU seconds (user + system)."""
    args = ("run", f"swarm:{n}", "--steps", "100", "--accel", "2")
    argv, env = probe(COMMAND, checkout, *args)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    subprocess.run(argv, env=env, cwd=checkout, capture_output=True, check=True)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--before", type=Path, required=True, help="the other checkout")
    ap.add_argument("--n", type=int, default=20_000, help="spheres")
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    sides = {"after": HERE, "before": args.before}
    rows: dict[str, list[dict[str, float]]] = {side: [] for side in sides}
    for r in range(args.rounds):
        for side, checkout in sides.items():
            row = parts(checkout, args.n)
            row["command"], row["command_cpu"] = command(checkout, args.n)
            rows[side].append(row)
            ratio = row["command"] / row["compile"]
            cpu = row["command_cpu"] / row["compile_cpu"]
            print(
                f"round {r} {side}: command / compile {ratio:.2f} (CPU {cpu:.2f}), load "
                f"{os.getloadavg()[0]:.1f}: {json.dumps(row)}",
                file=sys.stderr,
                flush=True,
            )
    for suffix in ("", "_cpu"):
        keys = ("generate", "compile", "setup", "steps", "command")
        label = "CPU s" if suffix else "s"
        print(f"| swarm:{args.n} ({label}) | " + " | ".join(keys) + " | command / compile |")
        print("|---" * (len(keys) + 2) + "|")
        for side, runs in rows.items():
            med = {k: statistics.median(run[k + suffix] for run in runs) for k in keys}
            cells = " | ".join(f"{med[k]:.1f}" for k in keys)
            print(f"| {side} | {cells} | {med['command'] / med['compile']:.2f} |")
        print()


if __name__ == "__main__":
    main()
