"""A cold ``set_plan`` by the clock, in two parts: its Python side and the native call.

    python benchmarks/plan_cold.py --robots xarm7 baxter sawyer --horizon 0.2
    python benchmarks/plan_cold.py BEFORE --before-python BEFORE/.venv/bin/python   # an A/B
    python benchmarks/plan_cold.py --flush 32      # a 32 MB buffer read before each plan
    python benchmarks/plan_cold.py BEFORE --before-python BEFORE/.venv/bin/python \\
        --instructions 100                         # callgrind: Python and native instructions
    python benchmarks/plan_cold.py BEFORE --before-python BEFORE/.venv/bin/python \\
        --misses                                   # callgrind's cache model: the native call's

Issue 39: the plan's cost with ``set_plan`` by the clock (``benchmarks/plan_users.py``) is
above what the instructions of the native calls say (``benchmarks/plan_profile.py`` counts
only those). This times where the difference goes. The protocol of ``plan_users.py``'s cost
replay on its world (``plan_users.world_of``, pickled by ``plan_profile.world``: the perturbed
run, the control noise, nominal-model plans every 25 steps, deviation and relative profiles
from the pilots): the plans are rolled first, then the run is replayed with one predictor, and
after each plan's step (``mj_step``, ``Predictor.step``) ``set_plan``'s work is timed in this
thread's CPU time in two parts, as the benchmark's ``Run.set_plan`` does it:

- **Python**: ``Predictor._plan_args`` (``plan_arrays``: the checks and conversions
  ``set_plan`` makes) on the horizon's deviation and relative rows (``Run.rows``: made once,
  the same for every plan);
- **native**: ``Runtime.set_plan`` on those arrays (``Runtime::SetPlan`` and nanobind's
  conversions);

cold, as the replay has them (after the steps), and the Python part again at once, warm (it
changes nothing). ``--flush MB`` reads a buffer of that size before each plan too (colder than
the benchmark). Medians over the plans of ``--rounds`` replays, each side in its own interpreter
and the sides taking turns round by round, in the replay's median ``mj_step``.

``--instructions CALLS`` times nothing: the replay's first plan is given again ``CALLS`` times
(the same plan replacing itself) under ``valgrind --tool=callgrind`` collecting only inside
that loop (a ``functools.reduce``), and each call's instructions are split into
``Runtime::SetPlan``'s and the rest (Python, nanobind's conversions): deterministic, where
the clock on a shared machine is not.

``--misses`` times nothing either: the replay above (each plan a new one, as the benchmark's)
under ``valgrind --tool=callgrind --cache-sim=yes`` collecting only inside
``Runtime::SetPlan``, its instructions and first-level data cache misses (reads, writes) a
plan, in valgrind's model of the caches (32 kB, 8 ways for the first level; its last level
is this machine's L3, where nothing here misses).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

from checkouts import same_mujoco

HERE = Path(__file__).resolve().parent

REPLAY = r"""
import json, pickle, sys, time
import numpy as np
sys.path.insert(0, sys.argv[1])
import mujoco
import plan_users as pu
world, H, steps = pickle.load(open(sys.argv[2], "rb"))
flush = np.ones(int(sys.argv[3]) << 17) if int(sys.argv[3]) else None  # MB of doubles
clock = time.thread_time_ns
n = world.knots[H]


def run(on_plan):
    drive, d, p = pu.start_replay(world, H)
    mj = []
    for k in range(steps + 1):
        if k:
            drive(world.run, d)
            t0 = clock()
            mujoco.mj_step(world.run, d)
            mj.append(clock() - t0)
            p.step(d)
        if k % world.every == 0:
            on_plan(k, p, d, drive)
    return mj


plans = {}
run(lambda k, p, d, drive: plans.__setitem__(k, (drive.plan(world.nominal, d, n), float(d.time))))
if len(sys.argv) > 4:  # --instructions: the first plan given again and again, under callgrind
    import functools

    def again(k, p, d, drive):
        if k == 0:
            q, start = plans[0]
            world.set_plan(p, "plan", H, q, start)
            # Callgrind collects inside functools.reduce alone: these calls, nothing else.
            functools.reduce(
                lambda a, _: world.set_plan(p, "plan", H, q, start), range(int(sys.argv[4])), None
            )

    steps = 0
    run(again)
    sys.exit(0)
py, native, warm = [], [], []


def python_side(p, q, start):
    dev, rel = world.rows[H, False]
    return p._plan_args(q[:n], dev, start, None, None, None, rel)


def timed(k, p, d, drive):
    q, start = plans[k]
    if flush is not None:
        flush.sum()
    t0 = clock()
    args = python_side(p, q, start)
    t1 = clock()
    p._rt.set_plan(*args)
    t2 = clock()
    python_side(p, q, start)
    t3 = clock()
    if k:
        py.append(t1 - t0)
        native.append(t2 - t1)
        warm.append(t3 - t2)


mj = run(timed)
json.dump({"mj": mj, "py": py, "native": native, "warm": warm}, sys.stdout)
"""


def replay(python: str, run: Path, flush: int) -> dict[str, list[int]]:
    """One replay of the pickled world ``run`` by ``python``: its times (ns)."""
    script = run.with_suffix(".cold.py")
    script.write_text(REPLAY)
    out = subprocess.run(
        [python, str(script), str(HERE), str(run), str(flush)],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    return json.loads(out)  # type: ignore[no-any-return]


def _callgrind(python: str, run: Path, out: Path, options: list[str], *args: str) -> str:
    """The replay of ``run`` (no flush, then ``args``) under callgrind with ``options``, its
    profile written to ``out``; the replay's stdout."""
    script = run.with_suffix(".cold.py")
    script.write_text(REPLAY)
    return subprocess.run(
        [
            "valgrind",
            "--tool=callgrind",
            "--collect-atstart=no",
            *options,
            f"--callgrind-out-file={out}",
            python,
            str(script),
            str(HERE),
            str(run),
            "0",
            *args,
        ],
        check=True,
        capture_output=True,
        text=True,
        env={**os.environ, "OPENBLAS_NUM_THREADS": "1"},
    ).stdout


def instructions(python: str, run: Path, calls: int, side: str) -> tuple[float, float]:
    """``set_plan``'s instructions a call and ``Runtime::SetPlan``'s in them, over ``calls``
    calls of the replay's first plan on a predictor that has it already (callgrind, collecting
    only inside the loop: ``functools.reduce``)."""
    out = run.with_suffix(f".{side}.callgrind")
    _callgrind(python, run, out, ["--toggle-collect=functools_reduce"], str(calls))
    text = subprocess.run(
        ["callgrind_annotate", "--inclusive=yes", "--threshold=100", str(out)],
        capture_output=True,
        text=True,
    ).stdout
    total = re.search(r"^\s*([\d,]+) .*PROGRAM TOTALS", text, re.M)
    native = re.search(r"^\s*([\d,]+) .*:dua::Runtime::SetPlan", text, re.M)
    count = [int(m.group(1).replace(",", "")) if m else 0 for m in (total, native)]
    return count[0] / calls, count[1] / calls


def misses(python: str, run: Path, side: str) -> tuple[float, float, float, int]:
    """``Runtime::SetPlan``'s instructions, D1 read and write misses a plan in a replay of
    ``run`` (callgrind's cache model, collecting only inside it), and the plans."""
    out = run.with_suffix(f".{side}.cache")
    stdout = _callgrind(
        python, run, out, ["--cache-sim=yes", "--toggle-collect=dua::Runtime::SetPlan*"]
    )
    plans = len(json.loads(stdout)["native"]) + 1  # and the first, untimed
    events = re.search(r"^events: (.*)$", out.read_text(), re.M)
    totals = re.search(r"^totals: (.*)$", out.read_text(), re.M)
    assert events and totals, "callgrind wrote no totals"
    count = dict(zip(events.group(1).split(), map(int, totals.group(1).split()), strict=False))
    return count["Ir"] / plans, count["D1mr"] / plans, count["D1mw"] / plans, plans


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", type=Path, nargs="?", help="another checkout, for an A/B")
    ap.add_argument("--before-python", help="the other checkout's interpreter")
    ap.add_argument("--robots", nargs="+", default=["xarm7", "baxter", "sawyer"])
    ap.add_argument("--horizon", type=float, default=0.2, help="seconds")
    ap.add_argument("--steps", type=int, default=500, help="physics steps a replay")
    ap.add_argument("--rounds", type=int, default=5, help="replays a side")
    ap.add_argument("--flush", type=int, default=0, help="MB read before each plan (0: none)")
    ap.add_argument(
        "--instructions",
        type=int,
        metavar="CALLS",
        help="no clock: set_plan's instructions a call over CALLS calls, Python and native apart",
    )
    ap.add_argument(
        "--misses",
        action="store_true",
        help="no clock: the native call's instructions and D1 misses a plan (callgrind's caches)",
    )
    args = ap.parse_args(argv)
    if args.before is not None and not args.before_python:
        ap.error("an A/B needs --before-python")
    sys.path.insert(0, str(HERE))
    import numpy as np
    from plan_profile import world

    sides = [("after", sys.executable)]
    if args.before is not None:
        same_mujoco(args.before_python)
        sides.insert(0, ("before", args.before_python))
    if args.misses:
        print(
            "| robot | side | plans | `Runtime::SetPlan`, k instructions | D1 read misses, k |"
            " D1 write misses, k |"
        )
        print("|---|---|---|---|---|---|")
    elif args.instructions:
        print(
            "| robot | side | `set_plan`, k instructions | of which `Runtime::SetPlan` | the rest |"
        )
        print("|---|---|---|---|---|")
    else:
        print(
            "| robot | side | plans | `mj_step` us | Python, cold | native, cold | Python, warm |"
            " `set_plan`, cold |"
        )
        print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.robots:
            run = Path(tmp) / f"{name}.pkl"
            world(name, args.horizon, args.steps, run)
            if args.misses:
                for side, python in sides:
                    ir, mr, mw, plans = misses(python, run, side)
                    print(
                        f"| {name} | {side} | {plans} | {ir / 1e3:.1f} | {mr / 1e3:.2f} |"
                        f" {mw / 1e3:.2f} |",
                        flush=True,
                    )
                continue
            if args.instructions:
                for side, python in sides:
                    total, native = instructions(python, run, args.instructions, side)
                    print(
                        f"| {name} | {side} | {total / 1e3:.1f} | {native / 1e3:.1f} |"
                        f" {(total - native) / 1e3:.1f} |",
                        flush=True,
                    )
                continue
            times: dict[str, dict[str, list[int]]] = {s: {} for s, _ in sides}
            for r in range(args.rounds):
                for side, python in sides if r % 2 == 0 else sides[::-1]:
                    for key, value in replay(python, run, args.flush).items():
                        times[side].setdefault(key, []).extend(value)
            for side, _ in sides:
                t = {k: np.asarray(v, dtype=float) for k, v in times[side].items()}
                mj = float(np.median(t["mj"]))
                py, nat, warm = (float(np.median(t[k])) / mj for k in ("py", "native", "warm"))
                total = float(np.median(t["py"] + t["native"])) / mj
                print(
                    f"| {name} | {side} | {t['py'].size} | {mj / 1e3:.1f} | {py:.2f} | {nat:.2f}"
                    f" | {warm:.2f} | {total:.2f} |",
                    flush=True,
                )
    return 0


if __name__ == "__main__":
    sys.exit(main())
