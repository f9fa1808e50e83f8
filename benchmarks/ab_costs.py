"""A/B: what the predictor costs around its step, this checkout against another one.

    python benchmarks/ab_costs.py /tmp/before --before-python /tmp/before/.venv/bin/python

Each side runs in its own environment (its own build), alternately, ``--rounds`` times; every
figure is the median over rounds:

- ``fixed cost``: ``Predictor.step`` when nothing is due (two free spheres 3 m apart, no gravity),
  over ``mj_step`` of the same model: the call itself.
- ``MjData with the plugin``: ``mujoco.MjData(model)`` of a robot with the predictor attached
  (ur5e when ``benchmarks/robots.py`` has it, else two_arms), less the same without the plugin:
  what the plugin's init adds (its tables are parsed once per model).
- ``import``: a fresh interpreter's ``from dua_mujoco import Predictor`` (and ``import
  dua_mujoco`` alone).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from checkouts import same_mujoco

HERE = Path(__file__).resolve().parents[1]

PROBE = r"""
import json, sys, time
import numpy as np
import mujoco
from dua_mujoco import Predictor

XML = '''<mujoco><option gravity="0 0 0"/><worldbody>
<body pos="-1.5 0 0"><freejoint/><geom size="0.1"/></body>
<body pos="1.5 0 0"><freejoint/><geom size="0.1"/></body></worldbody></mujoco>'''
m = mujoco.MjModel.from_xml_string(XML)
d = mujoco.MjData(m)
p = Predictor(m, accel=1.0)
steps = 20000
plain, stepped = [], []
for _ in range(5):
    t0 = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(m, d)
    plain.append((time.perf_counter() - t0) / steps)
    p.reset(d)
    t0 = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(m, d)
        p.step(d)
    stepped.append((time.perf_counter() - t0) / steps)
out = {"mj_step_us": float(np.median(plain)) * 1e6,
       "fixed_us": float(np.median(np.array(stepped) - np.array(plain))) * 1e6}

from dua_mujoco import attach
try:  # the scenes' module: dua_mujoco.models since issue 41, dua_mujoco.mj before
    from dua_mujoco.models.scenes import load_spec
except ImportError:
    from dua_mujoco.mj.scenes import load_spec
sys.path.insert(0, sys.argv[1])
try:
    from robots import robot_spec
    spec = robot_spec("ur5e"); name = "ur5e"
except Exception:
    spec = load_spec("two_arms"); name = "two_arms"
plain_model = spec.compile()
attach(spec, accel=5.0)
model = spec.compile()
def make(mm, n=20):
    ts = []
    for _ in range(n):
        t0 = time.perf_counter(); mujoco.MjData(mm); ts.append(time.perf_counter() - t0)
    return float(np.median(ts))
out["plugin_model"] = name
out["mjdata_plugin_us"] = (make(model) - make(plain_model)) * 1e6
print(json.dumps(out))
"""

IMPORT = r"""
import time
t0 = time.perf_counter()
import dua_mujoco
t1 = time.perf_counter()
from dua_mujoco import Predictor
t2 = time.perf_counter()
print(t1 - t0, t2 - t0)
"""


def run(python: str, checkout: Path, code: str, *args: str) -> str:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.run(
        [python, "-c", code, *args], env=env, cwd=checkout, capture_output=True, text=True
    )
    if proc.returncode:
        raise RuntimeError(f"{checkout} failed:\n{proc.stderr[-3000:]}")
    return proc.stdout.strip().splitlines()[-1]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("--before-python", default=sys.executable)
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args(argv)
    same_mujoco(args.before_python)
    sides = {"before": (args.before_python, args.before), "after": (sys.executable, HERE)}
    results: dict[str, dict[str, list[float]]] = {s: {} for s in sides}
    bench = str(HERE / "benchmarks")
    for r in range(args.rounds):
        for side, (python, checkout) in sides.items():
            out = json.loads(run(python, checkout, PROBE, bench))
            a, b = map(float, run(python, checkout, IMPORT).split())
            out.update(import_package_s=a, import_predictor_s=b)
            for key, value in out.items():
                if isinstance(value, float):
                    results[side].setdefault(key, []).append(value)
        print(f"round {r + 1}/{args.rounds}", file=sys.stderr, flush=True)
    print("| figure | before | after |")
    print("|---|---|---|")
    med = {s: {k: float(np.median(v)) for k, v in results[s].items()} for s in sides}
    for key in med["after"]:
        print(f"| {key} | {med['before'][key]:.4g} | {med['after'][key]:.4g} |")
    for s in sides:
        ratio = med[s]["fixed_us"] / med[s]["mj_step_us"]
        print(f"| fixed cost / mj_step ({s}) | {ratio:.3f} |  |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
