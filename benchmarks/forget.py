"""Memory over a long run of pruned pairs in the plugin (issue 35): a swarm whose spheres keep
meeting new neighbours, ``mj_step`` with the predictor inside, 10^6 steps, the process's peak
resident memory at checkpoints, with the plugin forgetting (``attach``'s default,
``forget=8`` rebuilds) and without (``forget=None``), each in a process of its own.

    python benchmarks/forget.py                     # swarm:300, 10^6 steps, both runs (~1 h)
    python benchmarks/forget.py --forget 8          # one side (docs/many-objects.md ran the
    python benchmarks/forget.py --forget never      #   two side by side, ~27 min)
    python benchmarks/forget.py --n 1000 --steps 100000

Controls: each sphere's motors drawn uniformly in their range and held 50 steps (numpy, one
draw a block: no Python loop over spheres). Printed every checkpoint (progress on stderr as it
runs): steps, wall seconds, peak RSS (``VmHWM`` of ``/proc/self/status``, MiB), the plugin's
known sphere pairs, geom pairs forgotten so far. The last line is a JSON record.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time

PROBE = r"""
import json, sys, time
import mujoco, numpy as np
from dua_mujoco.models.scenes import load_spec
from dua_mujoco.plugin import attach, known_pairs

n, steps, forget = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
forget = None if forget == "never" else int(forget)

def hwm():
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024.0

spec = load_spec(f"swarm:{n}")
attach(spec, accel=2.0, pairs="pruned", forget=forget, overlay=False)
m = spec.compile()
d = mujoco.MjData(m)
mujoco.mj_resetDataKeyframe(m, d, 0)
rng = np.random.default_rng(0)
lo, hi = m.actuator_ctrlrange[:, 0], m.actuator_ctrlrange[:, 1]
marks = sorted({int(v) for v in np.unique(np.geomspace(1000, steps, 13).round(-3))} | {steps})
rows, t0, k = [], time.perf_counter(), 0
for mark in marks:
    while k < mark:
        if k % 50 == 0:
            d.ctrl[:] = rng.uniform(lo, hi)
        mujoco.mj_step(m, d)
        k += 1
    kp = known_pairs(m, d)
    row = dict(steps=k, seconds=round(time.perf_counter() - t0, 1), peak_mib=round(hwm(), 1),
               npair=kp.npair, held=kp.held, forgotten=kp.forgotten)
    rows.append(row)
    print(json.dumps(row), file=sys.stderr, flush=True)
print(json.dumps(dict(n=n, forget=forget, rows=rows)))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=300, help="spheres in the swarm")
    ap.add_argument("--steps", type=int, default=1_000_000)
    ap.add_argument(
        "--forget", nargs="+", default=["8", "never"], help="rebuilds, or never (one run each)"
    )
    args = ap.parse_args()
    for forget in args.forget:
        print(f"swarm:{args.n}, forget={forget}, {args.steps} steps", flush=True)
        out = subprocess.run(
            [sys.executable, "-c", PROBE, str(args.n), str(args.steps), forget],
            check=True,
            stdout=subprocess.PIPE,
            text=True,
        ).stdout
        record = json.loads(out.strip().splitlines()[-1])
        rows = record["rows"]
        print("| steps | wall s | peak RSS MiB | sphere pairs known | geom pairs forgotten |")
        print("|---:|---:|---:|---:|---:|")
        for r in rows:
            print(
                f"| {r['steps']:,} | {r['seconds']} | {r['peak_mib']} | {r['npair']:,} | "
                f"{r['forgotten']:,} |"
            )
        at = {r["steps"]: r["peak_mib"] for r in rows}
        if 100_000 in at:
            last = rows[-1]
            print(
                f"peak at {last['steps']:,} / at 100,000: {last['peak_mib'] / at[100_000]:.3f}",
                flush=True,
            )
        print(json.dumps(record), flush=True)
        time.sleep(0)


if __name__ == "__main__":
    main()
