"""Benchmarks of dua_mujoco (never run as tests): prints markdown tables for docs/benchmarks.md.

    python benchmarks/bench.py            # everything (a few minutes)
    python benchmarks/bench.py core       # tau and scheduler only
    python benchmarks/bench.py scenes     # predictor on the bundled scenes
    python benchmarks/bench.py period     # traffic at predictor periods 1..8
    python benchmarks/bench.py dispatch   # the cost of calling the native core from Python

Every timing is the median of repeated runs (machines are noisy); ratios are computed from
medians measured in the same process.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from collections.abc import Callable

import numpy as np
from timing import median_time, table  # benchmarks/timing.py: the script folder is on sys.path

from dua_mujoco.build.options import PilotOptions


def bench_compile() -> str:
    """Import + first call, in two fresh processes (nothing is compiled at run time)."""
    code = (
        "import time; t0 = time.perf_counter(); import numpy as np; "
        "from dua_mujoco import time_to_collision, DUAScheduler; "
        "from dua_mujoco.experiments.paper.world import SphereWorld; "
        "time_to_collision(np.ones((4, 3)), np.zeros((4, 3)), 0.1, 1.0); "
        "w = SphereWorld(10); p = w.pairs(); import numpy as np; "
        "s = DUAScheduler(p.tau(np.arange(len(p)), w.positions, w.velocities), dt=0.01); "
        "s.step_points(p, w.positions, w.velocities); "
        "print(time.perf_counter() - t0)"
    )
    rows = []
    for label in ("first process", "second process"):
        out = subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, check=True
        )
        rows.append([label, f"{float(out.stdout.strip()):.2f} s"])
    return table(["import + first tau + first DUA step", "time"], rows)


def bench_core() -> str:
    from dua_mujoco import DUAScheduler, time_to_collision
    from dua_mujoco.core.schedules import DeadlineScheduler, SelectAllScheduler
    from dua_mujoco.experiments.paper.world import SphereWorld

    rng = np.random.default_rng(0)
    out = []
    # tau, batch.
    m = 2_000_000
    x = rng.uniform(-1, 1, (m, 3))
    v = rng.normal(0, 0.5, (m, 3))
    time_to_collision(x[:10], v[:10], 0.06, 2.0, vel_uncertainty=0.002)
    t = median_time(lambda: time_to_collision(x, v, 0.06, 2.0, vel_uncertainty=0.002), 7)
    rows = [["`time_to_collision`, 2e6 random pairs, 2 threads", f"{m / t:.3g} /s"]]
    t_a0 = median_time(lambda: time_to_collision(x, v, 0.06, 0.0), 7)
    rows.append(["same, A = 0 (ray-sphere)", f"{m / t_a0:.3g} /s"])
    out.append(table(["tau throughput", "evaluations per second"], rows))

    # Scheduler at M ~ 1e6 pairs (N = 1415 spheres) and SA at 5e5 (N = 1000).
    rows = []
    if True:  # M ~ 1e6 pairs
        w = SphereWorld(1415, seed=1, radius=0.005)
        pairs = w.pairs()
        ids = np.arange(len(pairs))
        t_tau = median_time(lambda: pairs.tau(ids, w.positions, w.velocities), 5)
        tau0 = pairs.tau(ids, w.positions, w.velocities)
        t_cls = median_time(lambda: DUAScheduler(tau0, dt=0.01), 5)
        rows.append(
            [
                f"initial classification, M = {len(pairs):.3g}: tau of all pairs",
                f"{t_tau * 1e3:.0f} ms",
            ]
        )
        rows.append(
            [
                f"initial classification, M = {len(pairs):.3g}: bucketing (argpartition)",
                f"{t_cls * 1e3:.0f} ms",
            ]
        )
        s = DUAScheduler(tau0, dt=0.01)

        def fused() -> None:
            s.step_points(pairs, w.positions, w.velocities)

        def protocol() -> None:
            sel = s.select()
            s.update(sel, pairs.tau(sel, w.positions, w.velocities))

        rows.append(
            [
                f"fused DUA step (`step_points`), M = {len(pairs):.3g}",
                f"{median_time(fused, 2000, 50) * 1e6:.1f} us",
            ]
        )
        rows.append(
            [
                f"DUA step through `select`/`update`, M = {len(pairs):.3g}",
                f"{median_time(protocol, 2000, 50) * 1e6:.1f} us",
            ]
        )
        rows.append(["evaluations per DUA step", str(s.evaluations_per_step)])
        dl = DeadlineScheduler(tau0, dt=0.01)
        evals: list[int] = []

        def deadline() -> None:
            dl.step_points(pairs, w.positions, w.velocities)
            evals.append(dl.evaluations_per_step)

        rows.append(
            [
                f"fused deadline step (`step_points`), M = {len(pairs):.3g}",
                f"{median_time(deadline, 2000, 50) * 1e6:.1f} us",
            ]
        )
        rows.append(["evaluations per deadline step (median)", f"{np.median(evals):.0f}"])
    w = SphereWorld(1000, seed=2, radius=0.005)
    pairs = w.pairs()
    ids = np.arange(len(pairs))
    sa = SelectAllScheduler(pairs.tau(ids, w.positions, w.velocities), dt=0.01)

    def sa_step() -> None:
        sel = sa.select()
        sa.update(sel, pairs.tau(sel, w.positions, w.velocities))

    rows.append([f"SA(tau) step, M = {len(pairs):.3g}", f"{median_time(sa_step, 15) * 1e3:.1f} ms"])
    out.append(table(["scheduler", "median"], rows))
    return "\n\n".join(out)


def bare_loop(name: str, predictor: object, steps: int) -> tuple[float, float]:
    """Median us of ``Predictor.step`` and of ``mj_step`` in a user's loop (no monitor)."""
    return bare_loop_period(name, predictor, steps, 1)


def bare_loop_period(name: str, predictor: object, steps: int, period: int) -> tuple[float, float]:
    """Median us per ``Predictor.step`` call (every ``period`` steps) and per ``mj_step``."""
    import mujoco

    from dua_mujoco.models.scenes import load_scene, make_controller

    m, d = load_scene(name)
    ctrl = make_controller(m, "random", seed=0)
    p = predictor
    mujoco.mj_step(m, d)
    p.reset(d)  # type: ignore[attr-defined]
    t_pred, t_mj = [], []
    for k in range(1, steps + 1):
        ctrl(m, d)
        t0 = time.perf_counter()
        mujoco.mj_step(m, d)
        t1 = time.perf_counter()
        t_mj.append(t1 - t0)
        if k % period == 0:
            p.step(d)  # type: ignore[attr-defined]
            t_pred.append(time.perf_counter() - t1)
    return float(np.median(t_pred) * 1e6), float(np.median(t_mj) * 1e6)


def tau_ns_per_eval(predictor: object, data: object, max_pairs: int = 4096) -> float:
    """Median ns per tau evaluation on this scene's own states (serial batch of <= 4096 pairs)."""
    p = predictor
    c, v = p.sphere_states(data)  # type: ignore[attr-defined]
    hs = p.halfspaces(data)  # type: ignore[attr-defined]
    n = len(p.pair_set)  # type: ignore[attr-defined]
    ids = np.random.default_rng(0).permutation(n)[: min(n, max_pairs)]
    per_call = median_time(lambda: p.pair_set.tau(ids, c, v, hs), 51, warmup=3)  # type: ignore[attr-defined]
    return per_call / ids.size * 1e9


def bench_dispatch(calls: int = 200_000) -> str:
    """What calling the native core from Python costs: the floor under any Python API's
    per-call work (``_core``'s functions are nanobind's)."""
    import dua_mujoco._core as _core

    class Result:
        __slots__ = ("a", "b")

        def __init__(self, a: object, b: object) -> None:
            self.a, self.b = a, b

    ids = np.arange(8)
    q = np.zeros(12)
    rows = []
    for label, fn in (
        (
            "a native function of 4 numbers (`_core.deadline_interval`)",
            lambda: _core.deadline_interval(0.1, 0.01, 0, 64),
        ),
        ("a native function of one array (`_core.exceeds12`)", lambda: _core.exceeds12(q, 1.0)),
        ("a slotted result object", lambda: Result(1, 2)),
        ("copy of a few alarm ids (`ids[:3].copy()`)", lambda: ids[:3].copy()),
    ):

        def many(fn: Callable[[], object] = fn) -> None:
            for _ in range(calls):
                fn()

        rows.append([label, f"{median_time(many, 7) / calls * 1e6:.2f} us"])
    return table(["per call", "median"], rows)


def bench_scenes(steps: int = 2000) -> str:
    from dua_mujoco.measure.rollout import run
    from dua_mujoco.models.scenes import load_scene, make_controller
    from dua_mujoco.runtime.predictor import Predictor

    rows = []
    for name, schedule in (
        (scene, schedule)
        for scene in (
            "two_arms",
            "traffic",
            "clutter",
            "paper_world",
            "paper_world:200",
            "paper_world:1000",
        )
        for schedule in ("deadline", "dua")
    ):
        m, d = load_scene(name)
        n_steps = steps if ":" not in name else 500
        p = Predictor(
            m,
            schedule=schedule,
            accel="auto",
            pilot=PilotOptions(steps=1000, controller=make_controller(m, "random", seed=99)),
        )
        r = run(
            m,
            d,
            p,
            steps=n_steps,
            controller=make_controller(m, "random", seed=0),
            scene=name,
            progress=False,
        )
        ratio = r.predictor_share
        bare_pred, bare_mj = bare_loop(name, p, n_steps)
        tau_us = r.evals_per_step * tau_ns_per_eval(p, d) / 1e3
        rows.append(
            [
                name,
                schedule,
                str(m.ngeom),
                str(r.spheres),
                str(r.pairs),
                f"{r.evals_per_step:.1f}",
                f"{r.pairs / r.evals_per_step:.0f}x",
                f"{r.predictor_us_per_step:.1f}",
                f"{r.mj_step_us_per_step:.1f}",
                f"{100 * ratio:.0f} %",
                f"{bare_pred:.1f} / {bare_mj:.1f} = {100 * bare_pred / bare_mj:.0f} %",
                f"{tau_us:.1f} = {100 * tau_us / bare_mj:.0f} %",
                f"{r.missed_onsets_valid_bounds}",
            ]
        )
    header = [
        "scene",
        "schedule",
        "geoms",
        "spheres",
        "pairs",
        "tau evals/step",
        "fewer than SA",
        "predictor us/step",
        "mj_step us/step",
        "predictor / mj_step",
        "bare loop: predictor / mj_step (us)",
        "tau evaluations alone (us, % of bare mj_step)",
        "valid-bound misses",
    ]
    return table(header, rows)


def bench_period(steps: int = 2000, periods: tuple[int, ...] = (1, 2, 4, 8)) -> str:
    """Traffic with its declared bound (4 m/s^2) at several predictor periods."""
    from dua_mujoco.measure.rollout import run
    from dua_mujoco.models.scenes import declared_accel_bound, load_scene, make_controller
    from dua_mujoco.runtime.predictor import Predictor

    rows = []
    for k in periods:
        m, d = load_scene("traffic")
        accel = declared_accel_bound(m)
        assert accel is not None, "traffic.xml declares dua_accel_bound"
        p = Predictor(m, accel=accel, period=k)
        r = run(
            m,
            d,
            p,
            steps=steps,
            controller=make_controller(m, "random", seed=0),
            scene="traffic",
            progress=False,
        )
        bare_pred, bare_mj = bare_loop_period("traffic", p, steps, k)
        rows.append(
            [
                str(k),
                f"{r.evals_per_step / k:.2f}",
                f"{r.predictor_us_per_step:.1f}",
                f"{100 * r.predictor_share:.0f} %",
                f"{bare_pred:.1f} / ({k} x {bare_mj:.1f}) = "
                f"{100 * bare_pred / (k * bare_mj):.0f} %",
                f"{r.predicted_onsets} / {r.contact_onsets}",
                f"{r.missed_onsets_valid_bounds}",
                f"{r.alarm_episodes} ({r.false_alarm_episodes})",
                f"{np.mean(r.alarms_per_step[1:]):.1f} of {r.evals_per_step:.1f}",
            ]
        )
    header = [
        "period",
        "tau evals per physics step",
        "predictor us/call",
        "predictor share of physics time",
        "bare loop: predictor / (period x mj_step)",
        "predicted / onsets",
        "valid-bound misses",
        "alarm episodes (false)",
        "alarms raised per predictor step, of the pairs evaluated (means)",
    ]
    return table(header, rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "what", nargs="*", default=["compile", "core", "scenes", "period", "dispatch"]
    )
    args = parser.parse_args(argv)
    for what in args.what:
        print(f"## {what}\n")
        print(
            {
                "compile": bench_compile,
                "core": bench_core,
                "scenes": bench_scenes,
                "period": bench_period,
                "dispatch": bench_dispatch,
            }[what]()
        )
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
