"""Many moving objects: ``SpherePredictor`` (pruned pairs) against broadphases, N = 1e3 .. 1e5.

Needs scipy and matplotlib (``pip install dua_mujoco[bench]``); never run as a test.

    python benchmarks/many.py                 # the table and plot of docs/many-objects.md
    python benchmarks/many.py --quick         # N = 1e3, 1e4, fewer steps
    python benchmarks/many.py --crossover     # all pairs against pruned, N = 32 .. 2048
    python benchmarks/many.py --strides 8 16 32 64 128 --n 100000   # default stride
    python benchmarks/many.py --report docs/img/many-objects.json   # table + plot
    python benchmarks/many.py --mujoco [--before /tmp/before]       # MuJoCo scenes, A/B

The MuJoCo section (``--mujoco``) runs ``dua-mujoco run``'s rollout (default predictor, random
controls, the monitor) on bundled scenes and swarms, each in its own process: the time to load
the model (MuJoCo's own build), to set the predictor up, and to roll out; the predictor's and
``mj_step``'s median microseconds a step; the process's peak resident memory; onsets and misses.
With ``--before CHECKOUT`` every scene also runs on that checkout (``PYTHONPATH``), alternating.

World: the paper's density (as ``benchmarks/scaling.py``: ``WorldParams``' 0.1 m spheres,
speeds up to 0.4 m/s, acceleration bound 0.2 m/s^2, 40 spheres in its 10 m cube, the cube's
edge scaled by ``(N / 40)^(1/3)``), ghost spheres (``SphereWorld``, exact kinematics, the
bounds hold exactly), ``dt = 10 ms``, latency 1. Peers, all at the horizon ``H = (1 + latency)
dt`` a verdict must cover: the runtime's grid (reaches and candidate pairs every step), the
KD-tree (``cKDTree.query_pairs`` on the inflated spheres, then the exact test), MuJoCo's
gap-inflated ``mj_collision`` (N free spheres, ``geom_gap`` = each sphere's reach over H, only
``mj_collision`` timed; N <= 1e4), and the deadline schedule over all pairs (N = 1e3). A
broadphase's alarms are its candidates. Times: median and mean (the mean is the amortised cost:
rebuilds and renewals included) over the run, one thread. Memory: the growth of the
process's peak resident size (``/proc/self/status``, the peak reset first where Linux allows it)
over building the predictor, ``reset`` and one full stride of steps on pre-computed states, per
sphere: the schedule's state and the grid's work arrays are native allocations, which
``tracemalloc`` (used before) does not see. Misses: every contact onset found on a grid of 4 times a
step (``cKDTree``) must meet an alarm of the verdict acting then (tests/test_spheres.py).
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial import cKDTree
from timing import table  # benchmarks/timing.py: the script folder is on sys.path

from dua_mujoco import _core
from dua_mujoco.core.spheres import SpherePredictor
from dua_mujoco.experiments.paper.world import SphereWorld, WorldParams
from dua_mujoco.experiments.peers.memory import reset_peak, rss

DT, LATENCY, SUB = 0.01, 1, 4
WP = WorldParams()

ROUNDING_SLACK = 1.0 + 2.0**-44
"""The candidate grid's rounding slack (csrc/src/grid.cc): its pair test is ``d2 <= s * s``
times this."""


def grid_reach(radius: np.ndarray, speed: np.ndarray, accel: float, horizon: float) -> np.ndarray:
    """``(N,)`` reaches over ``horizon`` (the runtime's ``dua_reaches``; no speed bound)."""
    n = speed.shape[0]
    r, a = np.broadcast_to(radius, (n,)), np.full(n, float(accel))
    r, s = np.ascontiguousarray(r, dtype=float), np.ascontiguousarray(speed, dtype=float)
    return np.asarray(_core.reaches(r, s, a, np.zeros(n), np.full(n, np.inf), float(horizon)))


def grid_pairs(c: np.ndarray, r: np.ndarray, margin: float = 0.0) -> np.ndarray:
    """``(K, 2)`` pairs whose reachable balls meet: the runtime's grid (csrc/src/grid.cc)."""
    c, r = np.ascontiguousarray(c, dtype=float), np.ascontiguousarray(r, dtype=float)
    return np.asarray(_core.candidate_pairs(c, r, float(margin)))


def world(n: int, seed: int = 0) -> SphereWorld:
    box = WP.box * (n / 40) ** (1.0 / 3.0)
    return SphereWorld(
        n, seed=seed, box=box, radius=WP.radius, accel=WP.accel, speed=WP.speed, dt=DT
    )


def inflated(w: SphereWorld) -> np.ndarray:
    H = (1 + LATENCY) * DT
    return grid_reach(w.radius, np.linalg.norm(w.velocities, axis=1), WP.accel, H)


def kdtree_pairs(c: np.ndarray, r: np.ndarray) -> np.ndarray:
    p = cKDTree(c).query_pairs(2.0 * float(r.max()), output_type="ndarray")
    d = c[p[:, 0]] - c[p[:, 1]]
    s = r[p[:, 0]] + r[p[:, 1]]
    return np.asarray(p[np.einsum("ij,ij->i", d, d) <= s * s * ROUNDING_SLACK])


def timed(fn: Callable[..., Any], *args: object) -> tuple[Any, float]:
    t0 = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - t0


def mujoco_model(w: SphereWorld) -> tuple[Any, Any]:
    import mujoco

    bodies = "".join(
        f'<body><freejoint/><geom type="sphere" size="{w.radius[i]}"/></body>' for i in range(w.n)
    )
    # The default arena is sized for small models: 1e4 free bodies need more.
    size = f'<size memory="{max(64, w.n // 20)}M"/>'
    xml = f'<mujoco>{size}<option gravity="0 0 0"/><worldbody>{bodies}</worldbody></mujoco>'
    model = mujoco.MjModel.from_xml_string(xml)
    return model, mujoco.MjData(model)


def run_mujoco(w: SphereWorld, steps: int) -> tuple[list[float], list[int]]:
    import mujoco

    model, data = mujoco_model(w)
    ts, counts = [], []
    for _ in range(steps):
        # Gap = reach beyond the radius over H, per geom: a pair is reported when the spheres
        # inflated by their reach overlap (4.0 sums the gaps per pair).
        model.geom_gap[:] = inflated(w) - w.radius
        data.qpos.reshape(-1, 7)[:, :3] = w.positions
        data.qpos.reshape(-1, 7)[:, 3] = 1.0
        mujoco.mj_kinematics(model, data)
        t0 = time.perf_counter()
        mujoco.mj_collision(model, data)
        ts.append(time.perf_counter() - t0)
        counts.append(int(data.ncon))
        w.step()
    return ts, counts


def memory(n: int, pairs: str) -> int:
    w = world(n, seed=1)
    pred = SpherePredictor(w.radius, WP.accel, dt=DT, latency=LATENCY, pairs=pairs)
    states = [(w.positions.copy(), w.velocities.copy())]
    for _ in range(pred.stride or 2):
        w.step()
        states.append((w.positions.copy(), w.velocities.copy()))
    del pred
    before, _ = reset_peak()
    pred = SpherePredictor(w.radius, WP.accel, dt=DT, latency=LATENCY, pairs=pairs)
    pred.reset(*states[0])
    for c, v in states[1:]:
        pred.step(c, v)
    return max(0, rss("VmHWM") - before)


def run_predictor(
    n: int, steps: int, pairs: str, check: bool, horizon: float | None = None
) -> dict:
    w = world(n)
    r2 = 2.0 * WP.radius
    pred = SpherePredictor(w.radius, WP.accel, dt=DT, latency=LATENCY, pairs=pairs, horizon=horizon)
    out, t_reset = timed(pred.reset, w.positions, w.velocities)
    history = [set((out[:, 0] * n + out[:, 1]).tolist())]
    ts, alarms, evals, held = [], [], [], []
    t_grid, t_kd, n_grid = [], [], []
    onsets, missed = 0, 0
    touching = set()
    if check:
        touching = _contacts(w.positions, r2, n)
    for m in range(steps):
        if check:
            for k in range(1, SUB):
                now = _contacts(w.positions_at(DT * k / SUB), r2, n)
                o, x = _judge(now - touching, m * SUB + k, history)
                onsets, missed, touching = onsets + o, missed + x, now
        w.step()
        out, t = timed(pred.step, w.positions, w.velocities)
        ts.append(t)
        alarms.append(out.shape[0])
        evals.append(pred.evaluations)
        held.append(pred.npairs)
        history.append(set((out[:, 0] * n + out[:, 1]).tolist()))
        if pairs == "pruned" and m % 4 == 0:
            r = inflated(w)
            g, tg = timed(grid_pairs, w.positions, r)
            _, tk = timed(kdtree_pairs, w.positions, r)
            t_grid.append(tg)
            t_kd.append(tk)
            n_grid.append(g.shape[0])
        if check:
            now = _contacts(w.positions, r2, n)
            o, x = _judge(now - touching, (m + 1) * SUB, history)
            onsets, missed, touching = onsets + o, missed + x, now
    return {
        "n": n,
        "pairs": pairs,
        "steps": steps,
        "reset_s": t_reset,
        "step_median_s": float(np.median(ts)),
        "step_mean_s": float(np.mean(ts)),
        "alarms_per_step": float(np.mean(alarms)),
        "evals_per_step": float(np.mean(evals)),
        "held_pairs": float(np.mean(held)),
        "rebuilds": pred.rebuilds,
        "stride": pred.stride,
        "grid_median_s": float(np.median(t_grid)) if t_grid else None,
        "kdtree_median_s": float(np.median(t_kd)) if t_kd else None,
        "grid_alarms_per_step": float(np.mean(n_grid)) if n_grid else None,
        "onsets": onsets if check else None,
        "missed": missed if check else None,
    }


def _contacts(pos: np.ndarray, r2: float, n: int) -> set[int]:
    return set(_keys(cKDTree(pos).query_pairs(r2, output_type="ndarray"), n).tolist())


def _keys(p: np.ndarray, n: int) -> np.ndarray:
    return np.asarray(np.minimum(p[:, 0], p[:, 1]) * n + np.maximum(p[:, 0], p[:, 1]))


def _judge(new: set[int], u: int, history: list[set[int]]) -> tuple[int, int]:
    """Onsets at sub-step time ``u`` and how many the verdict acting then does not alarm."""
    acting = history[max(0, u // SUB - LATENCY)]
    return len(new), len(new - acting)


def warm_up() -> None:
    """Compile (or load) every kernel once, so no timed call pays for it."""
    for pairs in ("all", "pruned"):
        run_predictor(200, 40, pairs, check=True)
    run_mujoco(world(50), 2)
    kdtree_pairs(world(50).positions, np.full(50, 0.1))


def crossover(ns: list[int], steps: int) -> list[dict]:
    rows = []
    for n in ns:
        for pairs in ("all", "pruned"):
            res = run_predictor(n, steps, pairs, check=False)
            rows.append(res)
            print(
                f"crossover N={n} {pairs}: reset {res['reset_s'] * 1e3:.2f} ms, step median "
                f"{res['step_median_s'] * 1e6:.1f} us, mean {res['step_mean_s'] * 1e6:.1f} us",
                flush=True,
            )
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--crossover", action="store_true")
    parser.add_argument("--n", type=int, nargs="+")
    parser.add_argument("--steps", type=int, nargs="+", help="steps per N (default 300/300/160)")
    parser.add_argument("--mujoco-max", type=int, default=10_000)
    parser.add_argument("--check-max", type=int, default=100_000, help="onset checks up to N")
    parser.add_argument("--out", type=Path, default=Path("docs/img/many-objects.json"))
    parser.add_argument("--strides", type=int, nargs="+", help="stride sweep at --n (no checks)")
    parser.add_argument("--report", type=Path, nargs="+", help="result files: table and plot")
    parser.add_argument("--mujoco", nargs="*", metavar="SCENE:STEPS:ACCEL", help="MuJoCo section")
    parser.add_argument("--before", type=Path, help="--mujoco: A/B against this checkout")
    args = parser.parse_args(argv)
    if args.mujoco is not None:
        print(mujoco_section(args.mujoco or MUJOCO_SCENES, args.before))
        return
    if args.report:
        print(report(args.report, Path("docs/img/many-objects.png")))
        return
    warm_up()
    if args.strides:
        sweep = []
        for n in args.n or [100_000]:
            for R in args.strides:
                res = run_predictor(n, 4 * R + 2, "pruned", False, (R + LATENCY) * DT)
                sweep.append(res)
                print(
                    f"N={n} stride {R}: median {res['step_median_s'] * 1e6:.0f} us, mean "
                    f"{res['step_mean_s'] * 1e6:.0f} us, held {res['held_pairs']:.0f}",
                    flush=True,
                )
        args.out.with_name("many-objects-strides.json").write_text(json.dumps(sweep, indent=1))
        return
    if args.crossover:
        # Past the deadline schedule's longest revisit interval (1024 steps): far pairs then
        # come due too, the steady cost of all pairs.
        rows = crossover(args.n or [32, 64, 128, 256, 512, 1024, 2048], 1200)
        args.out.with_name("many-objects-crossover.json").write_text(json.dumps(rows, indent=1))
        return
    ns = args.n or ([1000, 10_000] if args.quick else [1000, 10_000, 100_000])
    steps = args.steps or ([100] * len(ns) if args.quick else [300, 300, 160][: len(ns)])
    results = []
    for n, k in zip(ns, steps, strict=True):
        res = run_predictor(n, k, "pruned", check=n <= args.check_max)
        res["bytes_per_sphere"] = memory(n, "pruned") / n
        if n <= args.mujoco_max:
            ts, counts = run_mujoco(world(n), min(k, 60))
            res["mujoco_median_s"] = float(np.median(ts))
            res["mujoco_alarms_per_step"] = float(np.mean(counts))
        if n <= 1000:
            full = run_predictor(n, 1200, "all", check=False)
            full["bytes_per_sphere"] = memory(n, "all") / n
            res["all_pairs"] = full
        results.append(res)
        print(json.dumps(res), flush=True)
    args.out.write_text(json.dumps(results, indent=1))


MUJOCO_SCENES = [
    "two_arms:1000:auto",
    "traffic:1000:auto",
    "clutter:1000:auto",
    "bin_pour:1000:auto",
    "swarm:1000:100:2",
    "swarm:5000:100:2",
    "swarm:20000:100:2",
]
"""``scene:steps:accel`` (``swarm:N`` keeps its count); ``--accel 2`` is the issue's."""

# Runs in each scene's own process, on either checkout: only APIs both have.
_PROBE = r"""
import json, sys, time
import mujoco
from dua_mujoco import Predictor, load_scene, run
try:  # the scenes' module: dua_mujoco.models since issue 41, dua_mujoco.mj before
    from dua_mujoco.models.scenes import make_controller
except ImportError:
    from dua_mujoco.mj.scenes import make_controller
scene, steps, accel = sys.argv[1], int(sys.argv[2]), sys.argv[3]
t = time.perf_counter(); m, d = load_scene(scene); load = time.perf_counter() - t
t = time.perf_counter()
p = Predictor(m, accel=accel if accel == "auto" else float(accel))
setup = time.perf_counter() - t
# The mean over every step (rebuilds and renewals included), beside the report's median.
spent = []
step = p.step
def timed(data):
    t0 = time.perf_counter(); out = step(data); spent.append(time.perf_counter() - t0)
    return out
p.step = timed
t = time.perf_counter()
r = run(m, d, p, steps=steps, controller=make_controller(m, "random", seed=0), progress=False,
        series=False)
print(json.dumps(dict(
    load_s=load, setup_s=setup, rollout_s=time.perf_counter() - t,
    predictor_us=r.predictor_us_per_step, mj_step_us=r.mj_step_us_per_step,
    onsets=r.contact_onsets, missed_held=r.missed_onsets_valid_bounds,
    missed_outside=r.missed_onsets_outside_violations, unfiltered=r.unfiltered_contacts,
    pairs=r.pairs, known=p.nsphere_pairs, held=int(p.held_pairs.size),
    mean_us=1e6 * sum(spent) / max(len(spent), 1), rebuilds=p.rebuilds,
    renewals=getattr(p, "renewals", 0),
)))
"""


def _probe(scene: str, steps: int, accel: str, checkout: Path) -> dict[str, Any]:
    """One scene in a fresh process on ``checkout``; its peak resident memory too."""
    import os
    import subprocess

    from checkouts import HERE, probe, scene_path

    # Another checkout reads the bundled XML scenes from this one's models/.
    scene = scene_path(scene, HERE) if checkout.resolve() != HERE else scene
    argv, env = probe(_PROBE, checkout, scene, str(steps), accel, NUMBA_NUM_THREADS="1")
    proc = subprocess.Popen(
        argv,
        env=env,
        cwd=checkout,  # "python -c" puts the working directory first on the path
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    _, status, usage = os.wait4(proc.pid, 0)
    out, err = proc.stdout.read(), proc.stderr.read()  # type: ignore[union-attr]
    if os.waitstatus_to_exitcode(status) != 0:
        return {"error": err.strip().splitlines()[-1] if err.strip() else f"status {status}"}
    row = json.loads(out.strip().splitlines()[-1])
    row["peak_mb"] = usage.ru_maxrss / 1024  # kilobytes on Linux
    return row


def mujoco_section(specs: list[str], before: Path | None) -> str:
    """The MuJoCo scenes' table (markdown); ``before``: the same on that checkout."""
    here = Path(__file__).resolve().parents[1]
    sides = [("after", here)] + ([("before", before)] if before is not None else [])
    head = (
        "| scene | side | load (s) | set-up (s) | rollout (s) | steps | predictor us | "
        "mj_step us | share | mean share | rebuilds / renewals | peak MB | pairs / known / held"
        " | onsets | missed (held / outside) | unfiltered |"
    )
    lines = [head, "|" + "---|" * head.count(" | ") + "---|"]
    for spec in specs:
        *name, steps, accel = spec.split(":")
        scene = ":".join(name)
        for side, checkout in sides:
            r = _probe(scene, int(steps), accel, checkout)
            if "error" in r:
                lines.append(f"| {scene} | {side} | {r['error']} |" + " |" * 13)
            else:
                lines.append(
                    f"| {scene} | {side} | {r['load_s']:.1f} | {r['setup_s']:.1f} | "
                    f"{r['rollout_s']:.1f} | {steps} | {r['predictor_us']:.0f} | "
                    f"{r['mj_step_us']:.0f} | {r['predictor_us'] / r['mj_step_us']:.2f} | "
                    f"{r['mean_us'] / r['mj_step_us']:.2f} | {r['rebuilds']} / {r['renewals']} | "
                    f"{r['peak_mb']:.0f} | {r['pairs']} / {r['known']} / {r['held']} | "
                    f"{r['onsets']} | {r['missed_held']} / {r['missed_outside']} | "
                    f"{r['unfiltered']} |"
                )
            print(lines[-1], flush=True)
    return "\n".join(lines)


def report(paths: list[Path], png: Path) -> str:
    """The markdown table of docs/many-objects.md and its plot, from result files of ``main``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    res = sorted((r for p in paths for r in json.loads(p.read_text())), key=lambda r: r["n"])

    def us(x: float | None) -> str:
        return "-" if x is None else f"{x * 1e6:,.0f}"

    head = [
        "N",
        "pruned: median / mean (amortised) step (us)",
        "rebuilds",
        "held pairs",
        "evals / step",
        "alarms / step",
        "B / sphere",
        "onsets (missed)",
        "grid (us)",
        "KD-tree (us)",
        "MuJoCo gap (us)",
        "broadphase alarms / step",
        "all-pairs deadline: reset (s), mean step (us), B / sphere",
    ]
    rows = []
    for r in res:
        full = r.get("all_pairs")
        rows.append(
            [
                f"{r['n']:.0e}",
                f"{us(r['step_median_s'])} / {us(r['step_mean_s'])}",
                f"{r['rebuilds']} in {r['steps']} steps",
                f"{r['held_pairs']:.0f}",
                f"{r['evals_per_step']:.1f}",
                f"{r['alarms_per_step']:.1f}",
                f"{r['bytes_per_sphere']:.0f}",
                "-" if r["onsets"] is None else f"{r['onsets']} ({r['missed']})",
                us(r["grid_median_s"]),
                us(r["kdtree_median_s"]),
                us(r.get("mujoco_median_s")),
                f"{r['grid_alarms_per_step']:.1f}",
                "-"
                if full is None
                else f"{full['reset_s']:.2f}, {us(full['step_mean_s'])}, "
                f"{full['bytes_per_sphere']:,.0f}",
            ]
        )
    n = np.array([r["n"] for r in res], dtype=float)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    series = [
        ("pruned DUA, amortised", "step_mean_s", "o-"),
        ("grid broadphase", "grid_median_s", "s--"),
        ("KD-tree broadphase", "kdtree_median_s", "^--"),
        ("MuJoCo gap-inflated", "mujoco_median_s", "v--"),
    ]
    for label, key, style in series:
        pts = [(r["n"], r[key]) for r in res if r.get(key) is not None]
        if pts:
            x, y = zip(*pts, strict=True)
            ax1.loglog(x, np.array(y) * 1e6, style, label=label)
    full_pts = [(r["n"], r["all_pairs"]) for r in res if r.get("all_pairs")]
    for x, f in full_pts:
        ax1.loglog([x], [f["step_mean_s"] * 1e6], "kx", label="all-pairs deadline")
        ax2.loglog([x], [f["bytes_per_sphere"]], "kx", label="all-pairs deadline")
    ax1.set_xlabel("spheres N")
    ax1.set_ylabel("time per step (us)")
    ax1.legend(fontsize=8)
    ax1.grid(True, which="both", alpha=0.3)
    ax2.loglog(n, [r["bytes_per_sphere"] for r in res], "o-", label="pruned DUA (peak resident)")
    ax2.axhline(2048, color="grey", ls=":", label="target 2 KB / sphere")
    ax2.set_xlabel("spheres N")
    ax2.set_ylabel("peak bytes per sphere")
    ax2.legend(fontsize=8)
    ax2.grid(True, which="both", alpha=0.3)
    fig.suptitle(
        "Ghost world at the paper's density, dt = 10 ms, latency 1 (shared 2-core machine)"
    )
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    return table(head, rows)


if __name__ == "__main__":
    main()
