"""What the motion costs: the plugin on a robot driven by controls of different smoothness.

The plugin's cost is its evaluations, and they follow the bounds: a pair is revisited when the
bounds allow a collision within a few steps. ``benchmarks/plugin.py`` drives every robot, pilot
and run, with ``make_controller``'s random controls: a draw over each actuator's whole range,
held 50 steps. Here the controls run linearly between random draws ``H`` steps apart (``H = 1``:
a new draw every step), the pilot (``accel="auto"``, 1,000 steps) runs the same kind of controls
(seed 99) and measures that motion's bounds, and ``mj_step`` with the plugin is timed against
plain ``mj_step`` in alternating blocks, both along the same controls (seed 0)::

    python benchmarks/bound_scale.py                          # dmc_dog yam franka_kitchen go1
    python benchmarks/bound_scale.py --robots dmc_dog --holds 1 50 --steps 1000

``flagged`` counts the bodies a step whose motion broke the pilot's bounds (events).
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from robots import robot_spec

from dua_mujoco import CoveringOptions, PilotOptions
from dua_mujoco.plugin import attach, plugin_outputs

ROBOTS = ("dmc_dog", "yam", "franka_kitchen", "go1")
HOLDS = (1, 10, 50, 250)
PILOT_STEPS = 1000


def _controls(m: mujoco.MjModel, n: int, hold: int, seed: int) -> np.ndarray:
    """Controls ``(n, nu)`` running linearly between random draws ``hold`` steps apart, each
    in its actuator's range (``[-1, 1]`` where unlimited)."""
    rng = np.random.default_rng(seed)
    limited = m.actuator_ctrllimited.astype(bool)
    lo = np.where(limited, m.actuator_ctrlrange[:, 0], -1.0)
    hi = np.where(limited, m.actuator_ctrlrange[:, 1], 1.0)
    knots = rng.uniform(lo, hi, (n // hold + 2, m.nu))
    t = np.arange(n) / hold
    i = t.astype(int)
    w = (t - i)[:, None]
    return (1.0 - w) * knots[i] + w * knots[i + 1]


def _pilot_controller(m: mujoco.MjModel, hold: int) -> Callable:
    """The pilot's controller: :func:`_controls` of seed 99, a row a step (cycling)."""
    u = _controls(m, PILOT_STEPS, hold, seed=99)
    step = itertools.count()

    def control(model: mujoco.MjModel, data: mujoco.MjData) -> None:
        data.ctrl[:] = u[next(step) % len(u)]

    return control


def measure(robot: str, holds: list[int], steps: int) -> list[dict]:
    """One row a hold: medians of ``mj_step`` plain and with the plugin, both along that
    hold's controls, and the plugin's evaluations and flagged bodies a step (means)."""
    m = robot_spec(robot).compile()
    covering = CoveringOptions(hfield="box")
    # Per hold: its bounds, its controls, and two runs along them (model, data, times, evals,
    # flagged): plain, then with the plugin. A plain run of other controls would price the
    # motion's difference, not the plugin (dmc_dog's plain step runs 113 to 219 us across H).
    sides = []
    for hold in holds:
        pilot = PilotOptions(steps=PILOT_STEPS, seed=99, controller=_pilot_controller(m, hold))
        spec = robot_spec(robot)
        p = attach(spec, accel="auto", covering=covering, pilot=pilot)
        mp = spec.compile()
        runs = [(model, mujoco.MjData(model), [], [], []) for model in (m, mp)]
        sides.append((hold, p.bounds, _controls(m, steps, hold, seed=0), runs))
    block = max(steps // 10, 1)
    for start in range(0, steps, block):
        for _, _, controls, runs in sides:
            for plugin, (model, data, times, evals, flagged) in enumerate(runs):
                for i in range(start, min(start + block, steps)):
                    data.ctrl[:] = controls[i]
                    t0 = time.perf_counter_ns()
                    mujoco.mj_step(model, data)
                    times.append(time.perf_counter_ns() - t0)
                    if plugin:
                        out = plugin_outputs(model, data)
                        evals.append(out.evaluated)
                        flagged.append(out.flagged)
        print(f"  {robot}: {min(start + block, steps)}/{steps} steps", file=sys.stderr)
    rows = []
    for hold, bounds, _, (plain_run, plugin_run) in sides:
        plain = float(np.median(plain_run[2])) / 1e3
        with_plugin = float(np.median(plugin_run[2])) / 1e3
        rows.append(
            dict(
                robot=robot,
                hold=hold,
                accel=float(np.median(bounds.accel[bounds.accel > 0])),
                plain_us=plain,
                plugin_us=with_plugin,
                adds=with_plugin / plain - 1.0,
                evals=float(np.mean(plugin_run[3])),
                flagged=float(np.mean(plugin_run[4])),
            )
        )
    return rows


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", nargs="+", default=list(ROBOTS))
    ap.add_argument("--holds", nargs="+", type=int, default=list(HOLDS))
    ap.add_argument("--steps", type=int, default=2000)
    args = ap.parse_args(argv)
    print(
        "| robot | H (steps between draws) | median accel bound (m/s^2) | `mj_step` us "
        "| with the plugin us | plugin adds (x `mj_step`) | evaluations a step "
        "| flagged bodies a step |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for robot in args.robots:
        for r in measure(robot, args.holds, args.steps):
            print(
                f"| {r['robot']} | {r['hold']} | {r['accel']:.0f} | {r['plain_us']:.1f} "
                f"| {r['plugin_us']:.1f} | {r['adds']:+.2f} | {r['evals']:.0f} "
                f"| {r['flagged']:.2f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
