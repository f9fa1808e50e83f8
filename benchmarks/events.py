"""Violations as events: what they recover, what they cost, and which pilot bounds win with them.

    python benchmarks/events.py                      # the section of docs/benchmarks.md
    python benchmarks/events.py --quick              # smoke run: 300 steps, two scenes
    python benchmarks/events.py --robots             # add every installed robot model

Three tables, each A/B in one run:

- ``issue``: the runs of the issue as the CLI makes them (``dua-mujoco run ... --json``), with
  and without ``--no-events``: onsets, misses, misses outside a violation's period.
- ``pilot``: ``accel="auto"`` with the pilot measuring free motion (``PilotOptions(motion=
  "free")``: no step near a contact or joint limit) against leaving out only the steps near a new
  contact (``"no-impacts"``), events on, same controls (pilot seed 99, rollout seed 0): standing
  fraction, evaluations a step, violations, misses, predictor time over ``mj_step``.
- ``overhead``: two predictors with the same bounds on the same ``MjData``, events on and off,
  stepped alternately; median microseconds of ``step`` over the steps where no bound broke (the
  check is all that differs there).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np

from dua_mujoco.build.options import PilotOptions, ScheduleOptions
from dua_mujoco.cli import main as cli
from dua_mujoco.exceptions import DuaError
from dua_mujoco.measure.rollout import run
from dua_mujoco.models.scenes import make_controller
from dua_mujoco.runtime.predictor import Predictor

sys.path.insert(0, str(Path(__file__).parent))
from bench import table
from exact import _load_any, add_scene_options, chosen_scenes

ISSUE_RUNS = (
    ("traffic", "--accel", "5"),
    ("traffic", "--accel", "5", "--ctrl", "random", "--seed", "5"),
    ("two_arms", "--accel", "20"),
    ("paper_world:16", "--accel", "2"),
)
SCENES = (
    "two_arms",
    "traffic",
    "clutter",
    "paper_world:40",
    "gym/ant",
    "gym/humanoid",
    "dmc/humanoid_CMU",
)
PILOT_SEED = 99
ROLLOUT_SEED = 0


def issue_rows(steps: int) -> list[list[str]]:
    rows = []
    for argv in ISSUE_RUNS:
        cells = [" ".join(argv)]
        for extra in ((), ("--no-events",)):
            with tempfile.TemporaryDirectory() as tmp:
                out = Path(tmp) / "r.json"
                args = ["run", *argv, "--steps", str(steps), "--no-progress", "--json", str(out)]
                with (
                    contextlib.redirect_stdout(io.StringIO()),
                    contextlib.redirect_stderr(io.StringIO()),
                ):
                    cli([*args, *extra])
                r = json.loads(out.read_text())
            missed = r["missed_onsets"]
            outside = r["missed_onsets_outside_violations"]
            cells += [
                f"{missed} ({outside}) / {r['contact_onsets']}",
                f"{r['evals_per_step']:.1f}",
                f"{r['predictor_us_per_step']:.1f}",
            ]
        rows.append(cells)
    return rows


def pilot_rows(scene: str, steps: int) -> list[list[str]]:
    rows = []
    for motion in ("no-impacts", "free"):
        m, d = _load_any(scene)
        pilot = PilotOptions(
            controller=make_controller(m, "random", seed=PILOT_SEED), motion=motion
        )
        p = Predictor(m, pilot=pilot)
        rep = run(
            m,
            d,
            p,
            steps=steps,
            controller=make_controller(m, "random", seed=ROLLOUT_SEED),
            progress=False,
            series=False,
        )
        share = rep.predictor_us_per_step / max(rep.mj_step_us_per_step, 1e-9)
        rows.append(
            [
                scene,
                motion,
                f"{np.median(p.bounds.accel[p.bounds.accel > 0]):.3g}",
                f"{100 * rep.standing_alarm_fraction:.2f} %",
                f"{rep.evals_per_step:.1f}",
                f"{rep.bound_violations / max(rep.physics_steps, 1):.2f}",
                f"{rep.missed_onsets} ({rep.missed_onsets_outside_violations}) / "
                f"{rep.contact_onsets}",
                f"{share:.2f}",
            ]
        )
    return rows


def overhead_row(scene: str, steps: int) -> list[str]:
    m, d = _load_any(scene)
    base = Predictor(
        m, pilot=PilotOptions(controller=make_controller(m, "random", seed=PILOT_SEED))
    )
    on = Predictor(m, accel=base.bounds)
    off = Predictor(m, accel=base.bounds, schedule=ScheduleOptions(violation_events=False))
    ctrl = make_controller(m, "random", seed=ROLLOUT_SEED)
    ctrl(m, d)
    mujoco.mj_step(m, d)
    on.reset(d)
    off.reset(d)
    t_on, t_off = [], []
    for k in range(steps):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        # Alternate which goes first: neither gets the warmer cache every time.
        order = (on, off) if k % 2 else (off, on)
        times = {}
        for p in order:
            t0 = time.perf_counter()
            p.step(d)
            times[p] = time.perf_counter() - t0
        if on.violated_bodies.size == 0:
            t_on.append(times[on])
            t_off.append(times[off])
    a, b = float(np.median(t_on)) * 1e6, float(np.median(t_off)) * 1e6
    return [
        scene,
        f"{on.events.nbody if on.events else 0}",
        str(len(t_on)),
        f"{b:.2f}",
        f"{a:.2f}",
        f"{a / b:.3f}",
    ]


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_scene_options(ap)
    ap.add_argument(
        "--tables", nargs="*", default=["issue", "pilot", "overhead"], help="which to measure"
    )
    args = ap.parse_args(argv)
    scenes = chosen_scenes(args, SCENES)
    steps = 300 if args.quick else args.steps
    if "issue" in args.tables:
        print("issue runs ...", file=sys.stderr)
        head = [
            "run",
            "events: missed (outside) / onsets",
            "evals/step",
            "us/step",
            "--no-events: missed (outside) / onsets",
            "evals/step",
            "us/step",
        ]
        print(table(head, issue_rows(300 if args.quick else 3000)))
        print()
    prow, orow = [], []
    for scene in scenes:
        print(f"{scene} ...", file=sys.stderr)
        try:
            if "pilot" in args.tables:
                prow += pilot_rows(scene, steps)
            if "overhead" in args.tables:
                orow.append(overhead_row(scene, steps))
        except DuaError as exc:  # a model that diverges under random controls: say so, go on
            prow.append([scene, f"not measured: {type(exc).__name__}"] + [""] * 6)
        sys.stdout.flush()
    head = [
        "scene",
        "pilot",
        "median A",
        "standing",
        "evals/step",
        "violations/step",
        "missed (outside) / onsets",
        "/ mj_step",
    ]
    if prow:
        print(table(head, prow))
        print()
    head = [
        "scene",
        "bodies checked",
        "steps without violation",
        "us/step, no events",
        "us/step, events",
        "ratio",
    ]
    if orow:
        print(table(head, orow))


if __name__ == "__main__":
    main()
