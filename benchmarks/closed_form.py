"""What a closed-form tau would save and cost, on the robots where the plugin costs most.

The tau kernel finds the first root of ``|x + v t| = eps + delta t + A t^2 / 2`` (docs/theory.md,
section 1); on dmc_dog its lanes are about 40 % of the plugin's time. ``|x + v t| >= |x| - |v| t``
gives a lower bound on that root in closed form, one square root and one division:

    tau_c = 2 s / (w + sqrt(w^2 + 2 A s)),    s = |x| - eps,    w = |v| + delta

It is cheaper, and earlier: a pair is revisited sooner. Per robot, this script measures by how
much. Bounds come from plugin.py's pilot (``accel="auto"``, ``make_controller``'s random
controls, seed 99) and the run from the same kind of controller (seed 0). Every ``--every``
steps it takes every sphere-sphere pair's ``tau*`` (the kernel) and ``tau_c``, and the
evaluations a step each would give the deadline schedule: the sum over pairs of
``1 / interval(tau)``, the interval as the schedule sets it (latency 0). ::

    python benchmarks/closed_form.py                      # dmc_dog yam go1 franka_kitchen
    python benchmarks/closed_form.py --robots dmc_dog --steps 600
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from robots import robot_spec

from dua_mujoco import CoveringOptions, PilotOptions, Predictor
from dua_mujoco.mj.scenes import make_controller

ROBOTS = ("dmc_dog", "yam", "go1", "franka_kitchen")


def measure(name: str, steps: int, every: int) -> dict[str, float]:
    """Evaluations a step under ``tau*`` and under ``tau_c``, and quartiles of their ratio."""
    m = robot_spec(name).compile()
    pilot = PilotOptions(steps=1000, seed=99, controller=make_controller(m, "random", seed=99))
    p = Predictor(m, accel="auto", covering=CoveringOptions(hfield="box"), pilot=pilot)
    pairs, dt = p.pair_set, float(m.opt.timestep)
    ids = np.flatnonzero(pairs.kind == 0)
    i, j = pairs.first[ids], pairs.second[ids]
    n = len(pairs)
    eps = np.broadcast_to(pairs.eps, (n,))[ids]
    accel = np.broadcast_to(pairs.accel, (n,))[ids]
    delta = np.broadcast_to(pairs.vel_uncertainty, (n,))[ids]

    def evaluations(tau: np.ndarray) -> float:
        return float(np.sum(1.0 / np.clip(np.floor(tau / dt), 1, cap)))

    d = mujoco.MjData(m)
    drive = make_controller(m, "random", seed=0)
    mujoco.mj_forward(m, d)
    p.reset(d)
    cap = p.scheduler.max_interval  # the deadline schedule's longest interval
    exact, closed, ratios = [], [], []
    for k in range(steps):
        drive(m, d)
        mujoco.mj_step(m, d)
        if k % every:
            continue
        c, u = p.sphere_states(d)
        tau = pairs.tau(ids, c, u, p.halfspaces(d))
        s = np.linalg.norm(c[i] - c[j], axis=1) - eps
        w = np.linalg.norm(u[i] - u[j], axis=1) + delta
        tau_c = np.where(s > 0, 2 * s / (w + np.sqrt(w * w + 2 * accel * np.maximum(s, 0))), 0)
        exact.append(evaluations(tau))
        closed.append(evaluations(tau_c))
        ratios.append(tau_c[tau > 0] / tau[tau > 0])
    q = np.percentile(np.concatenate(ratios), [10, 50, 90])
    return dict(exact=np.mean(exact), closed=np.mean(closed), q10=q[0], q50=q[1], q90=q[2])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", nargs="*", default=list(ROBOTS))
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--every", type=int, default=10, help="steps between samples")
    args = ap.parse_args(argv)
    print(
        "| robot | sphere-sphere evaluations a step, tau* | with tau_c | ratio "
        "| tau_c / tau*: 10th percentile | median | 90th |"
    )
    print("|---" * 7 + "|")
    for k, name in enumerate(args.robots):
        print(f"{name} ({k + 1}/{len(args.robots)})", file=sys.stderr, flush=True)
        r = measure(name, args.steps, args.every)
        print(
            f"| {name} | {r['exact']:.0f} | {r['closed']:.0f} | {r['closed'] / r['exact']:.3f} "
            f"| {r['q10']:.3f} | {r['q50']:.3f} | {r['q90']:.3f} |",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
