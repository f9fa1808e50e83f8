"""Standing alarm fraction with static geoms as spheres or as shapes (docs/static-shapes.md).

    python benchmarks/standing_alarms.py                 # the table of docs/static-shapes.md
    python benchmarks/standing_alarms.py --why two_arms  # which geom pairs stand in alarm

The standing alarm fraction of a predictor step is the number of active geom pairs with some
sphere pair in alarm (alarmed by the step, or standing in alarm by ``scheduler.alarm_state``)
over the number of active geom pairs; the table gives its mean over the steps of a seeded random
rollout (pilot seed 99, rollout seed 0, 2000 physics steps, period 1).
"""

from __future__ import annotations

import argparse
import collections
import importlib.resources
from pathlib import Path

import mujoco
import numpy as np

from dua_mujoco.build.options import CoveringOptions, PilotOptions, UrgencyOptions
from dua_mujoco.models.scenes import load_scene, make_controller
from dua_mujoco.runtime.predictor import Predictor

STEPS = 2000


def _external(name: str) -> str:
    group, stem = name.split("/")
    if group == "gym":
        return str(importlib.resources.files("gymnasium") / "envs/mujoco/assets" / f"{stem}.xml")
    import dm_control

    return str(Path(dm_control.__file__).parent / "suite" / f"{stem}.xml")


SCENES = ("two_arms", "traffic", "clutter", "dmc/manipulator", "gym/pusher", "gym/ant")


def measure(
    scene: str, schedule: str, static: str, *, exact: bool = False, why: bool = False
) -> dict[str, float]:
    """Mean standing alarm fraction (and the work) of one rollout."""
    m, d = load_scene(scene if "/" not in scene else _external(scene))
    p = Predictor(
        m,
        schedule=schedule,
        covering=CoveringOptions(static=static),
        urgency=UrgencyOptions(exact=exact),
        pilot=PilotOptions(controller=make_controller(m, "random", seed=99)),
    )
    ctrl = make_controller(m, "random", seed=0)
    ctrl(m, d)
    mujoco.mj_step(m, d)
    p.reset(d)
    sched = p.scheduler
    assert sched is not None
    gp_of = np.asarray(p.sphere_pairs.geom_pair, dtype=np.int64)
    ngp = p.geom_pairs.npair
    kind = p.pair_set.kind
    fractions = []
    evals = 0
    counts: collections.Counter[tuple[str, str]] = collections.Counter()
    for _ in range(STEPS):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        alarms = p.step(d)
        evals += p.evaluations_per_step
        standing = sched.alarm_state()
        standing[np.asarray(alarms.pairs, dtype=np.int64)] = True
        alarmed_gp = np.unique(gp_of[standing])
        fractions.append(alarmed_gp.size / max(ngp, 1))
        if why:
            for k in alarmed_gp:
                counts[
                    (
                        p.tables.geom_names[p.geom_pairs.geom1[k]],
                        p.tables.geom_names[p.geom_pairs.geom2[k]],
                    )
                ] += 1
    out = {
        "fraction": float(np.mean(fractions)),
        "geom_pairs": float(ngp),
        "shape_pairs": float(np.sum(kind == 2)),
        "evals": evals / STEPS,
    }
    if why:
        print(f"{scene} {schedule} {static}: geom pairs standing in alarm, % of steps")
        for (a, b), n in counts.most_common(15):
            print(f"  {a:>24} {b:<24} {100 * n / STEPS:5.1f}")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--why", nargs="*", default=None, help="scenes to explain")
    parser.add_argument("--scenes", nargs="*", default=list(SCENES))
    args = parser.parse_args()
    if args.why:
        for scene in args.why:
            for static in ("sphere", "shape"):
                measure(scene, "select-all", static, why=True)
        return
    print(
        "| scene | geom pairs | schedule | static as spheres | static as shapes | cut "
        "| shapes + exact level | cut |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for scene in args.scenes:
        for schedule in ("select-all", "deadline"):
            old = measure(scene, schedule, "sphere")
            new = measure(scene, schedule, "shape")
            two = measure(scene, schedule, "shape", exact=True)
            print(
                f"| {scene} | {int(old['geom_pairs'])} | {schedule} | {old['fraction']:.3f} | "
                f"{new['fraction']:.3f} | {_cut(old, new)} | {two['fraction']:.3f} | "
                f"{_cut(old, two)} |",
                flush=True,
            )


def _cut(old: dict[str, float], new: dict[str, float]) -> str:
    return f"{old['fraction'] / new['fraction']:.2f}x" if new["fraction"] > 0 else "inf"


if __name__ == "__main__":
    main()
