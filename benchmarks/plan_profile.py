"""Where a plan's cost goes, in instructions (callgrind): ``set_plan`` and the steps under it.

    python benchmarks/plan_profile.py --robots sawyer g1 --horizon 0.2
    python benchmarks/plan_profile.py BEFORE --before-python BEFORE/.venv/bin/python  # an A/B
    python benchmarks/plan_profile.py --robots gr1 --split        # where set_plan, steps go
    python benchmarks/plan_profile.py BEFORE --before-python BEFORE/.venv/bin/python --alarms

The protocol of ``benchmarks/plan_users.py`` (its perturbed run, control noise, nominal-model
plans every 25 steps, deviation from a pilot), replayed for ``--steps`` physics steps by one
predictor with the plans, under ``valgrind --tool=callgrind`` collecting only inside
``mj_step``, ``Runtime::SetPlan`` and ``Runtime::Step`` (the native calls: Python's own work is
not counted, and the counts do not depend on the machine's load). Per robot: each function's
inclusive instructions over the run, and the predictor's (``SetPlan`` + ``Step``) over
``mj_step``'s, per call of the run's ``mj_step`` (the plans' own rollouts call ``mj_step`` too:
their calls are counted out). Instructions are not time (``benchmarks/ab_plans.py`` times it);
with another checkout, each side runs in its own interpreter on the same runs.

``--split`` profiles this checkout's ``DUA_PROFILE=ON`` build (``benchmarks/plugin_profile.py``
makes it) and splits ``set_plan`` and the steps by function (:data:`PARTS`). ``--alarms``
profiles nothing: both checkouts replay the same run and each step's alarms (pairs, taus, new
flags) and plan breaks are compared, bit for bit.
"""

from __future__ import annotations

import argparse
import os
import pickle
import re
import subprocess
import sys
import tempfile
from pathlib import Path

from checkouts import same_mujoco

HERE = Path(__file__).resolve().parent
FUNCTIONS = {
    "mj_step": "mj_step",
    "set_plan": "dua::Runtime::SetPlan",
    "step": "dua::Runtime::Step",
}
# Where each goes (``--split``: inclusive counts, read from the DUA_PROFILE=ON build of
# benchmarks/plugin_profile.py, in which the walks are their own symbols).
PARTS = {
    "finish": "dua::Plan::Finish",  # the sweeps and checks, with the knots computed as they go
    # The knots' kinematics (Finish calls it; with flexes or sleep, mj_kinematics in Build: rest).
    "knots": "dua::KnotKinematics::RunKnots",
    "rel_frames": "dua::Plan::SetRelativeFrames",  # the relative poses at every knot
    "rel_nesting": "dua::Runtime::RelativeDepartures",  # the relative pairs' nesting
    "follow": "dua::Runtime::FollowPlan",  # the step's checks of the plan and its shadows
    "check": "dua::Plan::Check",
    "check_rel": "dua::Plan::CheckRelative",
    "plan_pass": "dua::PlanPass",  # the pairs' taus under the plan
    "both_walk": "dua::(anonymous namespace)::BothWalk",
    "mixed": "dua::(anonymous namespace)::MixedKnot",
    "geom_distance": "mj_geomDistance",
}

REPLAY = r"""
import hashlib, pickle, sys
import numpy as np
sys.path.insert(0, sys.argv[1])
import mujoco
import plan_users as pu
world, H, steps = pickle.load(open(sys.argv[2], "rb"))
drive, d, p = pu.start_replay(world, H)
digests = []
for k in range(steps + 1):
    if k:
        drive(world.run, d)
        mujoco.mj_step(world.run, d)
        alarms = p.step(d)
        if len(sys.argv) > 3:  # --alarms: each step's alarms and plan breaks, to compare
            record = b"".join(
                np.ascontiguousarray(x).tobytes()
                for x in (alarms.pairs, alarms.tau, alarms.new, p.plan_breaks)
            )
            digests.append(hashlib.sha256(record).hexdigest())
    if k % world.every == 0:
        world.set_plan(p, "plan", H, drive.plan(world.nominal, d, world.knots[H]), float(d.time))
if len(sys.argv) > 3:
    open(sys.argv[3], "w").write("\n".join(digests))
"""


def world(name: str, horizon: float, steps: int, path: Path) -> None:
    """The robot's plan_users world (:func:`plan_users.world_of`: models, bounds, deviation and
    relative profiles, from the same pilots as the benchmark's run of every horizon), pickled
    with the run."""
    sys.path.insert(0, str(HERE))
    import plan_users as pu

    horizons = tuple(sorted({*pu.HORIZONS, horizon}))
    w = pu.world_of(name, horizons, steps, pu.EVERY)
    path.write_bytes(pickle.dumps((w, horizon, steps)))


def profile(python: str, run: Path, out: Path, env: dict[str, str]) -> dict[str, int]:
    """Each function's (and part's) inclusive instructions in a replay of ``run`` by ``python``
    (``env``: the child's environment over this one's)."""
    script = out.with_suffix(".py")
    script.write_text(REPLAY)
    # C++ names carry their signature: a pattern; mj_step exactly (no nested toggle).
    toggles = [f"--toggle-collect={f}" + ("*" if "::" in f else "") for f in FUNCTIONS.values()]
    command = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", *toggles, python]
    subprocess.run(
        [*command, str(script), str(HERE), str(run)],
        check=True,
        capture_output=True,
        env={**os.environ, **env},
    )
    text = subprocess.run(
        ["callgrind_annotate", "--inclusive=yes", "--threshold=100", str(out)],
        capture_output=True,
        text=True,
    ).stdout
    counts = {}
    for key, name in {**FUNCTIONS, **PARTS}.items():
        hit = re.search(rf"^\s*([\d,]+) .*?:{re.escape(name)}[\s(\[]", text, re.M)
        counts[key] = int(hit.group(1).replace(",", "")) if hit else 0
    return counts


def alarms(python: str, run: Path, out: Path) -> list[str]:
    """Each step's digest of the alarms (pairs, taus, new flags) and the plan breaks so far, in
    a replay of ``run`` by ``python`` (no profiler)."""
    script = out.with_suffix(".py")
    script.write_text(REPLAY)
    subprocess.run([python, str(script), str(HERE), str(run), str(out)], check=True)
    return out.read_text().split("\n")


def split(name: str, c: dict[str, int], steps: int) -> str:
    """A row of where ``set_plan`` and the steps go (M instructions over the run)."""
    sp, st = c["set_plan"], c["step"]
    knots = c["knots"]
    nest = sp - c["finish"] - c["rel_frames"] - c["rel_nesting"]
    walks = c["plan_pass"]
    checks = c["follow"]
    other = st - walks - checks
    cells = [
        sp,
        knots,
        c["finish"] - knots,
        c["rel_frames"],
        c["rel_nesting"],
        nest,
        st,
        c["check"],
        c["check_rel"],
        checks - c["check"] - c["check_rel"],
        walks,
        c["both_walk"],
        c["mixed"],
        c["geom_distance"],
        other,
    ]
    return f"| {name} | " + " | ".join(f"{v / 1e6:.1f}" for v in cells) + " |"


SPLIT_HEAD = (
    "| robot | set_plan | kinematics at knots | sweeps, checks | relative poses | relative "
    "nesting | rest (Build's own, body nesting, retire, due) | steps | Check | CheckRelative | "
    "shadows' rest | PlanPass | BothWalk | MixedKnot | mj_geomDistance | rest of Step |\n"
    "|---|" + "---|" * 15
)


def same_alarms(robots: list[str], horizon: float, steps: int, sides: list) -> int:
    """Each robot's replay by both sides: the first step whose alarms differ (1: any did)."""
    differ = 0
    with tempfile.TemporaryDirectory() as tmp:
        for name in robots:
            run = Path(tmp) / f"{name}.pkl"
            world(name, horizon, steps, run)
            (_, before), (_, after) = sides
            a = alarms(before, run, Path(tmp) / f"{name}.before.txt")
            b = alarms(after, run, Path(tmp) / f"{name}.after.txt")
            first = next((k for k, (x, y) in enumerate(zip(a, b, strict=True)) if x != y), None)
            verdict = "the same" if first is None else f"differ from step {first + 1}"
            print(f"{name}, {horizon * 1e3:.0f} ms, {len(a)} steps: {verdict}", flush=True)
            differ += first is not None
    return int(differ > 0)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", type=Path, nargs="?", help="another checkout, for an A/B")
    ap.add_argument("--before-python", help="the other checkout's interpreter")
    ap.add_argument("--robots", nargs="+", default=["baxter", "sawyer", "xarm7", "g1"])
    ap.add_argument("--horizon", type=float, default=0.2, help="seconds")
    ap.add_argument("--steps", type=int, default=250, help="physics steps replayed")
    ap.add_argument(
        "--split",
        action="store_true",
        help="where set_plan and the steps go, from this checkout's DUA_PROFILE=ON build",
    )
    ap.add_argument(
        "--alarms",
        action="store_true",
        help="no profile: compare each step's alarms with the other checkout's, bit for bit",
    )
    args = ap.parse_args(argv)
    if args.alarms and args.before is None:
        ap.error("--alarms compares with another checkout: give it, and --before-python")
    if args.before is not None and not args.before_python:
        ap.error("an A/B needs --before-python")
    if args.before is not None and args.split:
        ap.error("--split profiles this checkout's own profiling build: no A/B")
    sides = [("after", sys.executable)]
    if args.before is not None:
        same_mujoco(args.before_python)
        sides.insert(0, ("before", args.before_python))
    if args.alarms:
        return same_alarms(args.robots, args.horizon, args.steps, sides)
    env: dict[str, str] = {}
    if args.split:
        from plugin_profile import profile_library

        path = [str(profile_library().parent), os.environ.get("LD_LIBRARY_PATH", "")]
        env["LD_LIBRARY_PATH"] = os.pathsep.join(p for p in path if p)
    print(
        "| robot | side | mj_step | set_plan | step | (set_plan + step) / mj_step, per run step |"
    )
    print("|---|---|---|---|---|---|")
    splits = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.robots:
            run = Path(tmp) / f"{name}.pkl"
            world(name, args.horizon, args.steps, run)
            w, horizon, steps = pickle.loads(run.read_bytes())
            plans = steps // w.every + 1
            calls = steps + plans * (w.knots[horizon] - 1)  # the run's and the plans' rollouts
            for side, python in sides:
                c = profile(python, run, Path(tmp) / f"{name}.{side}.out", env)
                mj = c["mj_step"] / calls
                ratio = (c["set_plan"] + c["step"]) / steps / mj
                print(
                    f"| {name} | {side} | {c['mj_step'] / 1e6:.1f} M | {c['set_plan'] / 1e6:.1f} M"
                    f" | {c['step'] / 1e6:.1f} M | {ratio:.2f} |",
                    flush=True,
                )
                if args.split:
                    splits.append(split(name, c, steps))
    if splits:
        print(f"\nM instructions over {args.steps} steps:\n\n{SPLIT_HEAD}")
        print("\n".join(splits))
    return 0


if __name__ == "__main__":
    sys.exit(main())
