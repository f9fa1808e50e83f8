"""The plugin's cost with no Python between steps: ``mj_step`` inside ``mujoco.rollout``.

``benchmarks/plugin.py`` times each ``mj_step`` from a Python loop, the controller's Python
between two calls. A C or C++ program, ``simulate`` and ``mujoco.rollout`` step with nothing in
between, so the caches hold more of the model, and a memory-bound plugin could cost a different
share there. Here each robot's model is stepped by ``mujoco.rollout`` (one thread) alone, with
the plugin (exact level on, the default), and with the plugin without the exact level, along the
same recorded controls (``make_controller``'s random controls, seed 0; bounds from the pilot
``plugin.py`` runs: ``accel="auto"``, 1,000 steps, seed 99), in alternating rounds::

    python benchmarks/plugin_rollout.py                       # every installed robot
    python benchmarks/plugin_rollout.py --robots ur5e dmc_dog --rounds 5
    python benchmarks/plugin_rollout.py --robots ur5e g1 --covering multi

Numbers are medians over rounds of a rollout's time a step; evaluations are means a step, read
from the sensor's outputs that the rollout records. The rollout copies each step's state and
sensor readings out (a few hundred numbers), the same for every variant.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import mujoco
import numpy as np
from mujoco import rollout

sys.path.insert(0, str(Path(__file__).parent))

from robots import available, robot_spec

from dua_mujoco import CoveringOptions, PilotOptions, Predictor, UrgencyOptions
from dua_mujoco.models.scenes import make_controller
from dua_mujoco.plugin import OUTPUTS, attach

VARIANTS = ("plain", "exact on", "exact off")
EVALUATED = OUTPUTS.index("evaluated")


def _models(name: str, mode: str) -> dict[str, mujoco.MjModel]:
    """The robot's model alone and with the plugin (covering ``mode``), its exact level on and
    off."""
    m = robot_spec(name).compile()
    covering = CoveringOptions(hfield="box", mode=mode)
    pilot = PilotOptions(steps=1000, seed=99, controller=make_controller(m, "random", seed=99))
    bounds = Predictor(m, accel="auto", covering=covering, pilot=pilot).bounds
    models = {"plain": m}
    for label, exact in (("exact on", True), ("exact off", False)):
        spec = robot_spec(name)
        attach(spec, accel=bounds, covering=covering, urgency=UrgencyOptions(exact=exact))
        models[label] = spec.compile()
    return models


def _controls(m: mujoco.MjModel, steps: int) -> np.ndarray:
    """``(1, steps, nu)``: the controls ``make_controller`` (random, seed 0) gives along the
    model's own motion."""
    d = mujoco.MjData(m)
    drive = make_controller(m, "random", seed=0)
    u = np.zeros((1, steps, m.nu))
    for k in range(steps):
        drive(m, d)
        u[0, k] = d.ctrl
        mujoco.mj_step(m, d)
    return u


def measure(name: str, steps: int, rounds: int, mode: str = "bounding") -> dict[str, float]:
    """Per variant: the median time a step (us); per plugin variant, evaluations a step."""
    models = _models(name, mode)
    ctrl = _controls(models["plain"], steps)
    full = mujoco.mjtState.mjSTATE_FULLPHYSICS
    times: dict[str, list[float]] = {v: [] for v in VARIANTS}
    row: dict[str, float] = {}
    order = list(models.items())
    for r in range(rounds):
        # Each round starts with the next variant: none is always the one after a cold start.
        for label, m in order[r % len(order) :] + order[: r % len(order)]:
            d = mujoco.MjData(m)
            state = np.zeros((1, mujoco.mj_stateSize(m, full)))
            mujoco.mj_getState(m, d, state[0], full)
            t0 = time.perf_counter()
            _, sensordata = rollout.rollout(m, d, state, ctrl)
            times[label].append((time.perf_counter() - t0) / steps * 1e6)
            if label != "plain":
                adr = int(m.sensor("dua").adr[0])
                row[f"{label} evals"] = float(np.mean(sensordata[0, :, adr + EVALUATED]))
    for label, t in times.items():
        row[label] = float(np.median(t))
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=None, help="default: every installed one")
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument(
        "--covering", default="bounding", choices=("bounding", "multi"), help="CoveringOptions.mode"
    )
    args = parser.parse_args(argv)
    names = args.robots or available()
    print(
        "| robot | mj_step us | with the plugin us | adds (x mj_step) | exact level off us "
        "| adds, exact off | evals/step | evals/step, exact off |\n" + "|---" * 8 + "|"
    )
    added: dict[str, list[float]] = {"exact on": [], "exact off": []}
    for i, name in enumerate(names):
        print(f"[{i + 1}/{len(names)}] {name}", file=sys.stderr, flush=True)
        r = measure(name, args.steps, args.rounds, args.covering)
        on, off = r["exact on"] / r["plain"] - 1.0, r["exact off"] / r["plain"] - 1.0
        added["exact on"].append(on)
        added["exact off"].append(off)
        print(
            f"| {name} | {r['plain']:.1f} | {r['exact on']:.1f} | {on:+.2f} | "
            f"{r['exact off']:.1f} | {off:+.2f} | {r['exact on evals']:.1f} | "
            f"{r['exact off evals']:.1f} |",
            flush=True,
        )
    for label, v in added.items():
        worst = int(np.argmax(v))
        print(
            f"\n{label}: plugin adds, median over {len(v)} robots: {np.median(v):+.3f}x mj_step; "
            f"largest: {v[worst]:+.3f}x ({names[worst]})"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
