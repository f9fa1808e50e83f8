"""A/B: a plan's cost (``set_plan`` and the steps under it), this checkout against another one.

    python benchmarks/ab_plans.py /tmp/before --before-python /tmp/before/.venv/bin/python
    python benchmarks/ab_plans.py /tmp/before --before-python ... --robots baxter g1 --rounds 5

The runs of ``benchmarks/plan_users.py`` (a plan every 25 steps rolled on the nominal model,
the perturbed run, the deviation from a pilot), recorded once here: the state before each
physics step and each plan. Each side, in its own environment, replays them
(``plan_users.costs``: the same ``MjData`` after every ``mj_step``, the same plans at the same
steps, the predictor with the plans and the one without stepped in turn), alternately,
``--rounds`` times, in CPU time and in wall-clock time; every figure is the median over rounds
of the run's medians: ``set_plan``, the step after a plan, the other steps, and the amortised
cost, ``(set_plan + first + (R - 1) other) / R``, each over ``mj_step``.
"""

from __future__ import annotations

import argparse
import json
import pickle
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from checkouts import same_mujoco

HERE = Path(__file__).resolve().parent
ROBOTS = ("baxter", "sawyer", "spot_arm", "g1", "tiago")
HORIZONS = (0.05, 0.2)

PROBE = r"""
import json, pickle, sys, time
import numpy as np
sys.path.insert(0, sys.argv[1])
import plan_users
from plan_users import Record, Run, costs, perturbed
from robots import load_robot
out = {}
for path in sys.argv[3:]:
    rec = pickle.loads(open(path, "rb").read())
    nominal = load_robot(rec["robot"])
    world = Run(nominal=nominal, run=perturbed(nominal, np.random.default_rng(rec["seed"])),
                **rec["world"])
    record = Record(rec["states"], rec["plans"])
    plan_users.CLOCK = time.thread_time if sys.argv[2] == "cpu" else time.perf_counter
    out[rec["robot"]] = {str(H): costs(world, H, record, peer=False) for H in rec["horizons"]}
print(json.dumps(out))
"""


def record(name: str, horizons: tuple[float, ...], steps: int, path: Path) -> None:
    """The run of ``plan_users.py`` (its pilots, its perturbed model, its plans), saved."""
    import mujoco

    sys.path.insert(0, str(HERE))
    from horizon import ROLLOUT_SEED
    from plan_users import _STATE, EVERY, NoisyDriver, world_of

    # The benchmark's own world (its pilots, deviation and relative rows, declared arms): each
    # side rebuilds only the models.
    world = world_of(name, horizons, steps, EVERY)
    nominal, run, knots = world.nominal, world.run, world.knots
    longest = max(knots.values())
    drive = NoisyDriver(nominal, ROLLOUT_SEED)
    d = mujoco.MjData(run)
    mujoco.mj_forward(run, d)
    states = np.empty((steps + 1, mujoco.mj_stateSize(run, _STATE)))
    plans = {}
    for k in range(steps + 1):
        drive(run, d)
        mujoco.mj_getState(run, d, states[k], _STATE)
        mujoco.mj_step(run, d)
        if k % EVERY == 0:
            plans[k] = (float(d.time), drive.plan(nominal, d, longest))
    rec = {
        "robot": name,
        "seed": ROLLOUT_SEED,
        "world": {k: v for k, v in world._asdict().items() if k not in ("nominal", "run")},
        "horizons": horizons,
        "states": states,
        "plans": plans,
    }
    path.write_bytes(pickle.dumps(rec))


def probe(python: str, clock: str, paths: list[Path]) -> dict:
    out = subprocess.run(
        [python, "-c", PROBE, str(HERE), clock, *map(str, paths)],
        capture_output=True,
        text=True,
    )
    if out.returncode != 0:
        raise SystemExit(f"{python}'s replay failed:\n{out.stderr}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("before", type=Path, help="the other checkout (its dua_mujoco is imported)")
    ap.add_argument("--before-python", required=True, help="the other checkout's interpreter")
    ap.add_argument("--robots", nargs="+", default=list(ROBOTS))
    ap.add_argument("--horizons", nargs="+", type=float, default=list(HORIZONS))
    ap.add_argument("--steps", type=int, default=1000, help="physics steps a run")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="ab_plans_"))
    paths = []
    for name in args.robots:
        path = tmp / f"{name}.pkl"
        record(name, tuple(args.horizons), args.steps, path)
        paths.append(path)
        print(f"recorded {name}", file=sys.stderr, flush=True)
    same_mujoco(args.before_python)
    sides = {"after": sys.executable, "before": args.before_python}
    got: dict[str, dict[str, list[dict]]] = {s: {"cpu": [], "wall": []} for s in sides}
    for r in range(args.rounds):
        order = list(sides) if r % 2 == 0 else list(sides)[::-1]
        for clock in ("cpu", "wall"):
            for side in order:
                got[side][clock].append(probe(sides[side], clock, paths))
        print(f"round {r + 1} of {args.rounds}", file=sys.stderr, flush=True)
    rows = []
    for name in args.robots:
        for H in args.horizons:
            row = [name, f"{1e3 * H:g} ms"]
            for clock in ("cpu", "wall"):
                for key in ("set_plan", "amortised"):
                    vals = {
                        s: float(np.median([g[name][str(H)]["plan"][key] for g in got[s][clock]]))
                        for s in sides
                    }
                    row.append(f"{vals['before']:.2f} -> {vals['after']:.2f}")
            bounds = float(
                np.median([g[name][str(H)]["bounds"]["amortised"] for g in got["after"]["cpu"]])
            )
            row.append(f"{bounds:.2f}")
            rows.append(row)
    header = [
        "robot",
        "H",
        "set_plan / mj_step (CPU)",
        "plan incl. set_plan / mj_step (CPU)",
        "set_plan (wall)",
        "plan incl. set_plan (wall)",
        "no plan / mj_step (CPU, after)",
    ]
    print("| " + " | ".join(header) + " |\n|" + "---|" * len(header))
    for row in rows:
        print("| " + " | ".join(row) + " |")
    if args.json is not None:
        args.json.write_text(json.dumps(got, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
