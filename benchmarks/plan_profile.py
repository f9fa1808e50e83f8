"""Where a plan's cost goes, in instructions (callgrind): ``set_plan`` and the steps under it.

    python benchmarks/plan_profile.py --robots sawyer g1 --horizon 0.2
    python benchmarks/plan_profile.py BEFORE --before-python BEFORE/.venv/bin/python  # an A/B

The protocol of ``benchmarks/plan_users.py`` (its perturbed run, control noise, nominal-model
plans every 25 steps, deviation from a pilot), replayed for ``--steps`` physics steps by one
predictor with the plans, under ``valgrind --tool=callgrind`` collecting only inside
``mj_step``, ``Runtime::SetPlan`` and ``Runtime::Step`` (the native calls: Python's own work is
not counted, and the counts do not depend on the machine's load). Per robot: each function's
inclusive instructions over the run, and the predictor's (``SetPlan`` + ``Step``) over
``mj_step``'s, per call of the run's ``mj_step`` (the plans' own rollouts call ``mj_step`` too:
their calls are counted out). Instructions are not time (``benchmarks/ab_plans.py`` times it);
with another checkout, each side runs in its own interpreter on the same runs.
"""

from __future__ import annotations

import argparse
import pickle
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
FUNCTIONS = {
    "mj_step": "mj_step",
    "set_plan": "dua::Runtime::SetPlan",
    "step": "dua::Runtime::Step",
}

REPLAY = r"""
import pickle, sys
sys.path.insert(0, sys.argv[1])
import mujoco
import plan_users as pu
from horizon import ROLLOUT_SEED
from dua_mujoco.runtime.predictor import Predictor
world, H, steps = pickle.load(open(sys.argv[2], "rb"))
drive = pu.NoisyDriver(world.nominal, ROLLOUT_SEED)
d = mujoco.MjData(world.run)
mujoco.mj_forward(world.run, d)
p = Predictor(world.nominal, accel=world.bounds, alarm_horizon=H)
mujoco.mj_step(world.run, d)
p.reset(d)
for k in range(steps + 1):
    if k:
        drive(world.run, d)
        mujoco.mj_step(world.run, d)
        p.step(d)
    if k % world.every == 0:
        world.set_plan(p, "plan", H, drive.plan(world.nominal, d, world.knots[H]), float(d.time))
"""


def world(name: str, horizon: float, steps: int, path: Path) -> None:
    """The robot's plan_users world (models, bounds, deviation profile), pickled with the run."""
    sys.path.insert(0, str(HERE))
    import plan_users as pu
    from horizon import PILOT_SEED, ROLLOUT_SEED
    from robots import load_robot

    from dua_mujoco.build.options import PilotOptions
    from dua_mujoco.models.scenes import make_controller
    from dua_mujoco.runtime.predictor import Predictor

    nominal = load_robot(name)
    drive = make_controller(nominal, "smooth", seed=PILOT_SEED, hold_steps=pu.HOLD)
    auto = Predictor(nominal, pilot=PilotOptions(controller=drive, seed=PILOT_SEED))
    knots = pu.EVERY + max(round(horizon / float(nominal.opt.timestep)), 1) + 2
    profile, _, _ = pu.pilot_profile(nominal, auto.bound_points, knots, 2000)
    run = pu.perturbed(nominal, np.random.default_rng(ROLLOUT_SEED))
    w = pu.Run(
        nominal, run, auto.bounds, auto.bound_points, profile, {horizon: knots}, pu.EVERY, None
    )

    path.write_bytes(pickle.dumps((w, horizon, steps)))


def profile(python: str, run: Path, out: Path) -> dict[str, int]:
    """Each function's inclusive instructions in a replay of ``run`` by ``python``."""
    script = out.with_suffix(".py")
    script.write_text(REPLAY)
    # C++ names carry their signature: a pattern; mj_step exactly (no nested toggle).
    toggles = [f"--toggle-collect={f}" + ("*" if "::" in f else "") for f in FUNCTIONS.values()]
    command = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", *toggles, python]
    subprocess.run([*command, str(script), str(HERE), str(run)], check=True, capture_output=True)
    text = subprocess.run(
        ["callgrind_annotate", "--inclusive=yes", str(out)], capture_output=True, text=True
    ).stdout
    counts = {}
    for key, name in FUNCTIONS.items():
        hit = re.search(rf"^\s*([\d,]+) .*\?\?\?:{re.escape(name)}[\s(\[]", text, re.M)
        counts[key] = int(hit.group(1).replace(",", "")) if hit else 0
    return counts


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", type=Path, nargs="?", help="another checkout, for an A/B")
    ap.add_argument("--before-python", help="the other checkout's interpreter")
    ap.add_argument("--robots", nargs="+", default=["baxter", "sawyer", "xarm7", "g1"])
    ap.add_argument("--horizon", type=float, default=0.2, help="seconds")
    ap.add_argument("--steps", type=int, default=250, help="physics steps replayed")
    args = ap.parse_args(argv)
    if args.before is not None and not args.before_python:
        ap.error("an A/B needs --before-python")
    sides = [("after", sys.executable)]
    if args.before is not None:
        sides.insert(0, ("before", args.before_python))
    print(
        "| robot | side | mj_step | set_plan | step | (set_plan + step) / mj_step, per run step |"
    )
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.robots:
            run = Path(tmp) / f"{name}.pkl"
            world(name, args.horizon, args.steps, run)
            w, horizon, steps = pickle.loads(run.read_bytes())
            plans = steps // w.every + 1
            calls = steps + plans * (w.knots[horizon] - 1)  # the run's and the plans' rollouts
            for side, python in sides:
                c = profile(python, run, Path(tmp) / f"{name}.{side}.out")
                mj = c["mj_step"] / calls
                ratio = (c["set_plan"] + c["step"]) / steps / mj
                print(
                    f"| {name} | {side} | {c['mj_step'] / 1e6:.1f} M | {c['set_plan'] / 1e6:.1f} M"
                    f" | {c['step'] / 1e6:.1f} M | {ratio:.2f} |",
                    flush=True,
                )
    return 0


if __name__ == "__main__":
    sys.exit(main())
