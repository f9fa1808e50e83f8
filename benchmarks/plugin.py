"""The predictor inside ``mj_step`` (the plugin), and ``Predictor.step`` before and after the
native core (issue 20), A/B in one run.

    git worktree add --detach /tmp/before main         # and a venv of its own, /tmp/before/.venv
    python benchmarks/plugin.py --before /tmp/before   # markdown tables (about 20 min)
    python benchmarks/plugin.py --scenes two_arms gym/ant --steps 600
    python benchmarks/plugin.py --accel 200 --before /tmp/before   # declared bounds
    python benchmarks/plugin.py --scenes bin_pour swarm:1000 --steps 600   # pruned pairs too
    python benchmarks/plugin.py --accel 200 --period 2    # a predictor step every 2 mj_steps

Scenes: the bundled ones, gymnasium's and dm_control's, and every robot of
``benchmarks/robots.py`` whose package is installed. Each side (this checkout, and the one given
with ``--before``) runs every scene in a subprocess of its own, alternately, ``--rounds`` times,
each side first in every other round; the numbers are medians over rounds of per-round medians.

Per scene, on this side: bounds from the pilot (``accel="auto"``, pilot seed 99; ``--accel 200``
declares 200 m/s^2 instead), then

* ``mj_step`` of the model alone and of the model with the plugin attached (the same bounds;
  every pair, pruned pairs, and every pair with the exact level off), each timed per call, in
  alternating blocks, each run driven by the pilot's kind of controller
  (``make_controller``'s random controls, held 50 steps) with another seed: bounds measured on
  one motion and timed on another would price the mismatch, not the plugin;
* ``Predictor.step`` after each ``mj_step`` of the model alone, timed per call, and the tau
  evaluations a step;

on the ``--before`` side, the same ``Predictor.step`` (its own pilot: the same code and seeds),
and the plugin too if that checkout has one.

``--period P`` gives the plugin and ``Predictor`` a predictor period of ``P`` physics steps (both
sides): ``Predictor.step`` is called every ``P``-th ``mj_step``, and every time is per physics
step, the median over runs of ``P`` consecutive steps of their mean (one predictor step each);
the tau evaluations are a predictor step's.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from checkouts import run

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

BUNDLED = ("two_arms", "traffic", "clutter", "paper_world", "bin_pour")
EXTERNAL = ("gym/ant", "gym/humanoid", "gym/pusher", "dmc/humanoid_CMU", "dmc/quadruped")

# Runs in each side's subprocess: only what both sides have (Predictor's accel/pilot options,
# reset/step, load_scene), and the plugin on this side.
PROBE = r"""
import importlib.resources, json, sys, time
from pathlib import Path
import numpy as np
import mujoco
sys.path.insert(0, sys.argv[1])  # this checkout's benchmarks/ (robots.py)
from dua_mujoco import CoveringOptions, PilotOptions, Predictor, UrgencyOptions
try:  # the scenes' module: dua_mujoco.models since issue 41, dua_mujoco.mj before
    from dua_mujoco.models.scenes import load_spec, make_controller
except ImportError:
    from dua_mujoco.mj.scenes import load_spec, make_controller

side, steps, accel, period = sys.argv[2], int(sys.argv[3]), sys.argv[4], int(sys.argv[5])
scenes = sys.argv[6:]
# The options of a predictor period (none at 1: a checkout from before it takes none).
periodic = dict(period=period) if period > 1 else {}
steps -= steps % period


def per_step(times):
    # The median over runs of `period` consecutive steps of their mean (one predictor step each).
    t = np.asarray(times, dtype=float)
    return float(np.median(t.reshape(-1, period).mean(axis=1)))


def spec_of(scene):
    if scene.startswith("robot/"):
        from robots import robot_spec
        return robot_spec(scene.split("/", 1)[1])
    if scene.startswith("gym/"):
        path = importlib.resources.files("gymnasium") / "envs/mujoco/assets" / (scene[4:] + ".xml")
        return mujoco.MjSpec.from_file(str(path))
    if scene.startswith("dmc/"):
        import dm_control
        path = Path(dm_control.__file__).parent / "suite" / (scene[4:] + ".xml")
        return mujoco.MjSpec.from_file(str(path))
    path = Path(sys.argv[1]).parent / "models" / (scene + ".xml")
    if path.is_file():  # the other checkout finds its bundled files only when installed
        return mujoco.MjSpec.from_file(str(path))
    return load_spec(scene)  # generated scenes (swarm:N)

def model_of(scene):
    spec = spec_of(scene)
    return spec, spec.compile()

def predictor(m):
    # Height fields (dm_control's quadruped terrain) covered by their boxes.
    if accel != "auto":
        return Predictor(m, accel=float(accel), covering=CoveringOptions(hfield="box"), **periodic)
    return Predictor(m, accel="auto", covering=CoveringOptions(hfield="box"), pilot=PilotOptions(
        steps=1000, seed=99, controller=make_controller(m, "random", seed=99)), **periodic)

for scene in scenes:
    spec, m = model_of(scene)
    p = predictor(m)
    drive = make_controller(m, "random", seed=0)
    d = mujoco.MjData(m)
    drive(m, d); mujoco.mj_step(m, d); p.reset(d)
    t_pred, t_mj, evals = [], [], []
    for k in range(1, steps + 1):
        drive(m, d)
        t0 = time.perf_counter_ns(); mujoco.mj_step(m, d); t1 = time.perf_counter_ns()
        if k % period == 0:
            p.step(d); evals.append(p.evaluations_per_step)
        t2 = time.perf_counter_ns()
        t_mj.append(t1 - t0); t_pred.append(t2 - t1)
    row = dict(scene=scene, side=side, geoms=int(m.ngeom), pairs=int(p.nsphere_pairs),
               predictor_us=per_step(t_pred) / 1e3, mj_us=float(np.median(t_mj)) / 1e3,
               evals=float(np.mean(evals)))
    try:
        from dua_mujoco.plugin import attach, plugin_outputs
    except ImportError:  # a checkout from before the plugin
        attach = None
    if attach is not None:
        # The plugin holding every pair, pruned pairs, and every pair without the exact level
        # (on specs of their own).
        runs = [(m, mujoco.MjData(m), [], [], make_controller(m, "random", seed=0))]
        exact_off = dict(urgency=UrgencyOptions(exact=False))
        variants = (("all", spec, {}), ("pruned", spec_of(scene), {}),
                    ("all", spec_of(scene), exact_off))
        for pairs, s, more in variants:
            attach(s, accel=p.bounds, covering=CoveringOptions(hfield="box"), pairs=pairs,
                   **periodic, **more)
            mp = s.compile()
            runs.append((mp, mujoco.MjData(mp), [], [], make_controller(mp, "random", seed=0)))
        block = max(steps // 10 // period, 1) * period
        for start in range(0, steps, block):
            for model, data, out, ev, drive in runs:
                for k in range(start, min(start + block, steps)):
                    drive(model, data)
                    t0 = time.perf_counter_ns(); mujoco.mj_step(model, data)
                    out.append(time.perf_counter_ns() - t0)
                    if ev is not runs[0][3]:
                        ev.append(plugin_outputs(model, data).evaluated)
        row.update(plain_us=per_step(runs[0][2]) / 1e3,
                   plugin_us=per_step(runs[1][2]) / 1e3,
                   pruned_us=per_step(runs[2][2]) / 1e3,
                   inexact_us=per_step(runs[3][2]) / 1e3,
                   pruned_mean_us=float(np.mean(runs[2][2])) / 1e3,
                   plugin_mean_us=float(np.mean(runs[1][2])) / 1e3,
                   plain_mean_us=float(np.mean(runs[0][2])) / 1e3,
                   plugin_evals=float(np.mean(runs[1][3])),
                   pruned_evals=float(np.mean(runs[2][3])),
                   inexact_evals=float(np.mean(runs[3][3])))
    print(json.dumps(row), flush=True)
"""


def _scenes(requested: list[str] | None) -> list[str]:
    if requested:
        return requested
    sys.path.insert(0, str(HERE))
    from robots import available

    return [*BUNDLED, *EXTERNAL, *(f"robot/{name}" for name in available())]


def run_side(
    checkout: Path, side: str, steps: int, scenes: list[str], accel: str = "auto", period: int = 1
) -> list[dict]:
    out = run(PROBE, checkout, str(HERE), side, str(steps), accel, str(period), *scenes)
    return [json.loads(line) for line in out.splitlines() if line.startswith("{")]


def _median(rows: list[dict], scene: str, key: str) -> float:
    return float(np.median([r[key] for r in rows if r["scene"] == scene]))


def _print_summary(label: str, added: list[tuple[str, float]]) -> None:
    """What the plugin adds, ``(scene, x mj_step)`` each: the median over the robots and the
    largest over every scene (nothing without a robot)."""
    robots = [x for s, x in added if s.startswith("robot/")]
    if robots:
        worst = max(added, key=lambda a: a[1])
        print(
            f"{label}plugin adds, median over {len(robots)} robots: {np.median(robots):+.3f}x "
            f"mj_step; largest over all scenes: {worst[1]:+.3f}x ({worst[0]})"
        )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--before", type=Path, default=None, help="the other checkout (its venv runs its side)"
    )
    ap.add_argument("--scenes", nargs="*", default=None)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument(
        "--accel", default="auto", help="bounds: auto (a pilot of seed 99) or m/s^2 declared"
    )
    ap.add_argument(
        "--period", type=int, default=1, help="physics steps a predictor step (both sides)"
    )
    args = ap.parse_args(argv)
    if args.period < 1:
        ap.error(f"--period {args.period}: give a whole number of physics steps >= 1")
    scenes = _scenes(args.scenes)
    after: list[dict] = []
    before: list[dict] = []
    for r in range(args.rounds):
        print(f"round {r + 1}/{args.rounds}: {len(scenes)} scenes", file=sys.stderr, flush=True)
        # Each side first in every other round, so that neither always runs on the machine as
        # the other left it (an A/A of byte-identical libraries still reads 0.01-0.03x apart on
        # the median, up to 0.08x on one robot: docs/benchmarks.md).
        for side in ("after", "before") if r % 2 == 0 else ("before", "after"):
            if side == "after":
                after += run_side(ROOT, "after", args.steps, scenes, args.accel, args.period)
            elif args.before is not None:
                before += run_side(
                    args.before, "before", args.steps, scenes, args.accel, args.period
                )
    plugin_before = any("plugin_us" in r for r in before)
    print(
        "| scene | geoms | pairs | tau evals/step | mj_step us | with the plugin us | plugin adds "
        "(x mj_step) | Predictor.step us | Predictor.step / mj_step |"
        + (" Predictor.step before us | after / before |" if before else "")
        + (" plugin adds before |" if plugin_before else "")
    )
    print("|---" * (9 + (2 if before else 0) + (1 if plugin_before else 0)) + "|")
    pruned_rows = []
    added = []
    inexact = []  # every pair, the exact level off
    added_before = []
    for scene in scenes:
        one = next(r for r in after if r["scene"] == scene)
        plain, plugin = _median(after, scene, "plain_us"), _median(after, scene, "plugin_us")
        pred, mj = _median(after, scene, "predictor_us"), _median(after, scene, "mj_us")
        added.append((scene, (plugin - plain) / plain))
        inexact.append((scene, (_median(after, scene, "inexact_us") - plain) / plain))
        cells = [
            scene,
            str(one["geoms"]),
            str(one["pairs"]),
            f"{one['evals']:.1f}",
            f"{plain:.1f}",
            f"{plugin:.1f}",
            f"{(plugin - plain) / plain:+.2f}",
            f"{pred:.2f}",
            f"{pred / mj:.2f}",
        ]
        if before:
            old = _median(before, scene, "predictor_us")
            cells += [f"{old:.2f}", f"{pred / old:.2f}"]
        if plugin_before:
            plain_b = _median(before, scene, "plain_us")
            adds_b = (_median(before, scene, "plugin_us") - plain_b) / plain_b
            added_before.append((scene, adds_b))
            cells.append(f"{adds_b:+.2f}")
        print("| " + " | ".join(cells) + " |")
        mean = _median(after, scene, "plain_mean_us")
        pruned_rows.append(
            f"| {scene} | {one['plugin_evals']:.1f} | {one['pruned_evals']:.1f} | "
            f"{(plugin - plain) / plain:+.2f} | "
            f"{(_median(after, scene, 'pruned_us') - plain) / plain:+.2f} | "
            f"{(_median(after, scene, 'plugin_mean_us') - mean) / mean:+.2f} | "
            f"{(_median(after, scene, 'pruned_mean_us') - mean) / mean:+.2f} | "
            f"{inexact[-1][1]:+.2f} | {one['inexact_evals']:.1f} |"
        )
    print(
        "\n| scene | plugin evals/step, all pairs | pruned | adds (x mj_step, medians), all | "
        "pruned | adds (means), all | pruned | adds (medians), all, exact level off | "
        "evals/step, exact level off |\n" + "|---" * 9 + "|"
    )
    print("\n".join(pruned_rows))
    print()
    for label, adds in (("", added), ("exact level off: ", inexact), ("before: ", added_before)):
        _print_summary(label, adds)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
