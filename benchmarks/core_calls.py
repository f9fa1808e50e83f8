"""The core's calls from Python, A against B: medians per call of its hot paths.

    python benchmarks/core_calls.py                          # this tree
    python benchmarks/core_calls.py --before /tmp/old        # alternating with another checkout
    python benchmarks/core_calls.py --before /tmp/old --rounds 5 --json out.json

``--before CHECKOUT`` runs the same measurements on a checkout of another commit (its Python
files; the native library is this install's, so it must be ABI-compatible), each in its own
process, the two alternating ``--rounds`` times; the table gives the median of the rounds'
medians and the ratio new / old. What is timed (public API only, so both sides run it):

- ``step_points``: the fused step of ``DUAScheduler`` and ``DeadlineScheduler`` on the paper's
  world (``WorldParams``) at N spheres, states moving on each step (precomputed);
- ``SpherePredictor.step``: all pairs at N = 24, pruned at N = 1000 (a stride of rebuilds);
- ``time_to_collision`` of 2e6 random pairs and ``PairSet.tau`` of every pair at N = 1415;
- ``first``: import, the first tau and the first DUA step, in a fresh process.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

from timing import median_time  # benchmarks/timing.py: the script folder is on sys.path

ROOT = Path(__file__).resolve().parents[1]


def _use_checkout(path: str) -> None:
    """Import dua_mujoco's Python files from ``path`` instead of the editable install's."""
    sys.meta_path[:] = [f for f in sys.meta_path if "Redirect" not in type(f).__name__]
    sys.path.insert(0, path)


def _median_us(fn: Callable[[], object], repeat: int) -> float:
    return median_time(fn, repeat, warmup=3) * 1e6


def measure() -> dict[str, float]:
    """Median microseconds of each call (this process's dua_mujoco)."""
    import numpy as np

    from dua_mujoco.core.schedules import DeadlineScheduler, DUAScheduler
    from dua_mujoco.core.spheres import SpherePredictor
    from dua_mujoco.core.urgency import time_to_collision
    from dua_mujoco.experiments.paper.world import SphereWorld, WorldParams

    out: dict[str, float] = {}
    wp = WorldParams()
    for n in (5, 40, 1415):
        w = SphereWorld(n, seed=1, radius=0.005 if n > 1000 else wp.radius, dt=0.01)
        pairs = w.pairs()
        ids = np.arange(len(pairs))
        states = []
        for _ in range(64):
            w.step()
            states.append((w.positions.copy(), w.velocities.copy()))
        tau0 = pairs.tau(ids, *states[0])
        for name, sched in (
            ("DUA", DUAScheduler(tau0, dt=0.01)),
            ("deadline", DeadlineScheduler(tau0, dt=0.01)),
        ):
            k = iter(range(10**9))

            def step(s=sched, k=k, states=states, pairs=pairs) -> None:  # type: ignore[no-untyped-def]
                c, v = states[next(k) % 64]
                s.step_points(pairs, c, v)

            out[f"{name} step_points, N = {n}"] = _median_us(step, 2000 if n < 1000 else 300)
        if n == 1415:
            out[f"PairSet.tau of all {len(pairs)} pairs"] = _median_us(
                lambda p=pairs, i=ids, x=states[0]: p.tau(i, *x), 5, warmup=1
            )
    for n, mode in ((24, "all"), (1000, "pruned")):
        box = wp.box * (n / 40) ** (1 / 3)
        w = SphereWorld(n, seed=2, box=box, radius=wp.radius, accel=wp.accel, speed=wp.speed)
        states = []
        for _ in range(200):
            w.step()
            states.append((w.positions.copy(), w.velocities.copy()))
        pred = SpherePredictor(w.radius, wp.accel, dt=w.dt, pairs=mode)
        pred.reset(*states[0])
        k2 = iter(range(1, 10**9))

        def pstep(p=pred, k=k2, states=states) -> None:  # type: ignore[no-untyped-def]
            p.step(*states[next(k) % 200])

        out[f"SpherePredictor.step, {mode}, N = {n}"] = _median_us(pstep, 150)
    rng = np.random.default_rng(0)
    x = rng.uniform(-1, 1, (2_000_000, 3))
    v = rng.normal(0, 0.5, (2_000_000, 3))
    out["time_to_collision, 2e6 pairs"] = _median_us(
        lambda: time_to_collision(x, v, 0.06, 2.0, vel_uncertainty=0.002), 7, warmup=1
    )
    return out


FIRST = (
    "import time; t0 = time.perf_counter(); import numpy as np; "
    "from dua_mujoco.core.urgency import time_to_collision; "
    "from dua_mujoco.core.schedules import DUAScheduler; "
    "from dua_mujoco.experiments.paper.world import SphereWorld; "
    "time_to_collision(np.ones((4, 3)), np.zeros((4, 3)), 0.1, 1.0); "
    "w = SphereWorld(10); p = w.pairs(); "
    "s = DUAScheduler(p.tau(np.arange(len(p)), w.positions, w.velocities), dt=0.01); "
    "s.step_points(p, w.positions, w.velocities); "
    "print(time.perf_counter() - t0)"
)


def run(checkout: str | None) -> dict[str, float]:
    """One round in a fresh process (of ``checkout``, or of this tree)."""
    prologue = "" if checkout is None else f"import sys; sys.path.insert(0, {str(ROOT)!r}); "
    prologue += "import benchmarks.core_calls as b; "
    if checkout is not None:
        prologue += f"b._use_checkout({checkout!r}); "
    code = prologue + "import json; print(json.dumps(b.measure()))"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    if res.returncode:
        raise RuntimeError(res.stderr[-3000:])
    out = json.loads(res.stdout.strip().splitlines()[-1])
    with_cache = dict(env, NUMBA_CACHE_DIR=str(Path("/tmp") / f"core_calls_cache_{os.getpid()}"))
    first = FIRST if checkout is None else prologue + FIRST
    for label in ("first call (fresh cache)", "first call (warm cache)"):
        res = subprocess.run([sys.executable, "-c", first], capture_output=True, text=True,
                             env=with_cache)  # fmt: skip
        if res.returncode:
            raise RuntimeError(res.stderr[-3000:])
        out[label] = float(res.stdout.strip().splitlines()[-1]) * 1e6
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default=None, help="another checkout, measured alternately")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    sides = {"new": None} if args.before is None else {"old": args.before, "new": None}
    rounds: dict[str, list[dict[str, float]]] = {k: [] for k in sides}
    for r in range(args.rounds):
        for side, checkout in sides.items() if r % 2 == 0 else reversed(sides.items()):
            rounds[side].append(run(checkout))
            print(f"round {r + 1}/{args.rounds}: {side} done", file=sys.stderr)
    med = {
        side: {k: statistics.median(x[k] for x in rs) for k in rs[0]} for side, rs in rounds.items()
    }
    keys = list(med["new"])
    if "old" in med:
        print("| call | old (us) | new (us) | new / old |\n|---|---|---|---|")
        for k in keys:
            o, n = med["old"][k], med["new"][k]
            print(f"| {k} | {o:.1f} | {n:.1f} | {n / o:.2f} |")
    else:
        print("| call | us |\n|---|---|")
        for k in keys:
            print(f"| {k} | {med['new'][k]:.1f} |")
    if args.json:
        args.json.write_text(json.dumps({"rounds": rounds, "median": med}, indent=2))


if __name__ == "__main__":
    main()
