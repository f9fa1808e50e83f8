"""Why the pairs a step evaluates are due: a flagged body's, or the deadline wheel's, and what
the evaluations find.

    python benchmarks/why_due.py robot/yam robot/go1 --accel 200 auto

Per robot and bounds (``auto``: a pilot of random controls held 50 steps, seed 99, as
``benchmarks/plugin.py`` measures; or a declared ``accel`` in m/s^2), a ``Predictor`` with the
default options steps under ``make_controller``'s random controls (seed 0); over steps
``--skip`` to ``--steps`` it sorts each evaluated pair (``pair_state().last_selected``) by why it
was due: a pair of a body the violation check flagged at that step (``violated_bodies``: every
pair of such a body is evaluated again), else the wheel's (its verdict's interval ran out; the
wait since its last evaluation is counted). Of all evaluations: how many stood in alarm before
the step, are of a geom pair in MuJoCo's contact list, alarm now, and how far the new tau is
(in periods ``dt``). Means a step. ``settled``: pairs of flagged bodies the step settled by a
bound instead of evaluating them (docs/theory.md, section 6; not counted in ``evals``).
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

import mujoco
import numpy as np

from dua_mujoco import PilotOptions, Predictor
from dua_mujoco.models.scenes import make_controller

sys.path.insert(0, str(Path(__file__).resolve().parent))
from robots import load_robot


def measure(name: str, accel: str, steps: int, skip: int) -> dict[str, float]:
    m = load_robot(name.split("/", 1)[1])
    d = mujoco.MjData(m)
    if accel == "auto":
        pilot = PilotOptions(steps=1000, seed=99, controller=make_controller(m, "random", seed=99))
        p = Predictor(m, accel="auto", pilot=pilot)
    else:
        p = Predictor(m, accel=float(accel))
    drive = make_controller(m, "random", seed=0)
    drive(m, d)
    mujoco.mj_step(m, d)
    p.reset(d)
    g1, g2 = (np.asarray(a) for a in p.sphere_pair_geoms)
    body = m.geom_bodyid
    every = np.arange(g1.size)
    dt = m.opt.timestep * p.period
    count: Counter[str] = Counter()
    waits: list[int] = []
    measured = 0
    for k in range(steps):
        drive(m, d)
        mujoco.mj_step(m, d)
        if (k + 1) % p.period:
            continue
        state = p.pair_state()
        last_step = state.last_step_of(every)
        stood = state.alarm_state()
        p.step(d)
        if k < skip:
            continue
        measured += 1
        state = p.pair_state()
        chosen = state.last_selected
        # The pairs the step settled by a bound (docs/theory.md, section 6) are listed after the
        # evaluated ones: counted apart, not as evaluations.
        settled = int(getattr(state, "settled", 0))
        count["settled"] += settled
        if settled:
            n_eval = p.evaluations_per_step
            chosen = np.concatenate([chosen[:n_eval], chosen[n_eval + settled :]])
        flagged = np.isin(body[g1[chosen]], p.violated_bodies) | np.isin(
            body[g2[chosen]], p.violated_bodies
        )
        tau = state.last_tau_of(chosen)
        contact = {tuple(sorted(c.geom)) for c in d.contact[: d.ncon]}
        count["evals"] += chosen.size
        count["flagged"] += int(flagged.sum())
        waits.extend((state.step_count - last_step[chosen[~flagged]]).tolist())
        count["stood"] += int(stood[chosen].sum())
        count["contact"] += sum(
            (min(a, b), max(a, b)) in contact for a, b in zip(g1[chosen], g2[chosen], strict=True)
        )
        count["alarm"] += int(state.alarm_state(chosen).sum())
        periods = tau / dt
        count["tau < 4 dt"] += int((periods < 4).sum())
        count["4-15 dt"] += int(((periods >= 4) & (periods < 16)).sum())
        count[">= 16 dt"] += int((periods >= 16).sum())
    out = {key: value / max(measured, 1) for key, value in count.items()}
    out["wheel wait, median"] = float(np.median(waits)) if waits else float("nan")
    out["pairs"] = float(g1.size)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="+", help="robot/<name>")
    ap.add_argument("--accel", nargs="+", default=["200", "auto"])
    ap.add_argument("--steps", type=int, default=600)
    ap.add_argument("--skip", type=int, default=200)
    args = ap.parse_args(argv)
    columns = ["evals", "flagged", "settled", "wheel wait, median", "stood", "contact", "alarm"]
    columns += ["tau < 4 dt", "4-15 dt", ">= 16 dt"]
    print("| scene | bounds | pairs | " + " | ".join(columns) + " |")
    print("|---" * (len(columns) + 3) + "|")
    for scene in args.scenes:
        for accel in args.accel:
            row = measure(scene, accel, args.steps, args.skip)
            cells = " | ".join(f"{row.get(c, 0.0):.1f}" for c in columns)
            print(f"| {scene} | {accel} | {row['pairs']:.0f} | {cells} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
