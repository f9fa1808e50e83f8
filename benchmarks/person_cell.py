"""The person-and-arm scene: a planned arm next to a person nobody plans (issue 39, item 2).

    python benchmarks/person_cell.py --seeds 30 --json docs/img/person-cell.json  # docs/plans.md
    python benchmarks/person_cell.py --seeds 3 --horizons 0.2            # a quick look
    python benchmarks/person_cell.py --tables docs/img/person-cell.json  # the tables again

For each seed (the person's visit: when, from where, where it stands, what it reaches for and
how fast, within ISO 13855's 1.6 m/s walking and 2.0 m/s reaching; and the arm's order of
targets) and alarm horizon ``H``, one rollout of the bundled scene ``person_cell`` under its own
driver (``CellDriver``, the scene's 3,500 steps: the person walks in, reaches into the arm's
workspace and withdraws) is stepped by three predictors built alike from the scene's declared
bounds (``declared_bounds``: the arm's measured, the person's after ISO 13855), latency 0, each
with its own :class:`~dua_mujoco.measure.monitor.Monitor` measuring against ``H``:

- **plan**: the arm is given its flight plan every ``R = max(H, 50 ms)`` steps (a
  :class:`~dua_mujoco.runtime.plans.Replanner` with ``CellDriver.plan``: the arm's task rolled
  ahead where the person does not collide, ``bodies=("arm_*",)``); the person is left to its
  bounds. Its deviation is measured as docs/plans.md says, on a pilot making plans the same way
  (every 10 steps, seeds ``1_000_003 + i``, the person away: its touches are contacts to flag,
  not the arm's tracking error) with ``deviation_profile`` at safety 2, plus ``--floor``;
- **speed**: the same plans, the person's acceleration bound dropped (1,000 m/s^2): its reach
  is its speed times the time, ISO 13855's ``K T``;
- **none**: the motion bounds alone.

They are stepped in turn on the same ``MjData`` (order reversed every step), each timed like
``mj_step`` (this thread's CPU time): their costs are an A/B in one run. ``set_plan`` is counted
in a planned predictor's cost; the planner's (rolling the plan) is reported apart, as the
planner's.

**Measured**, per horizon over the seeds: the standing fraction (geom pairs in alarm) and the
oracle (geom pairs that do touch within ``H``), pooled (the mean standing over the mean oracle:
seeds where nothing touches have an oracle of 0), and the standing among the arm-person pairs
alone, over the run and while the person stands at the table (from the end of its walk in to
the start of its walk away); the contact onsets and those with less lead than ``H``, split held
/ after a violation or a plan break / at the start; plan breaks and bound violations; the
predictor's cost over ``mj_step`` (``set_plan`` included) and the planner's.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from dua_mujoco.measure.monitor import Monitor
from dua_mujoco.models.people import PERSON_BOUNDS, Bound
from dua_mujoco.models.person_cell import ARM, CellDriver, declared_bounds, person_blind
from dua_mujoco.models.scenes import SCENES, load_scene
from dua_mujoco.runtime.plans import PilotPlan, Replanner, deviation_profile, plan_deviation
from dua_mujoco.runtime.predictor import Predictor

sys.path.insert(0, str(Path(__file__).parent))
from bench import table

HORIZONS = (0.05, 0.2, 0.5)
SIDES = ("plan", "speed", "none")
"""The predictors of a run: the arm planned and the person on its declared speed and
acceleration; the same with the person's speed alone (ISO 13855's K T reach); no plan."""
SPEED_ONLY = {n: Bound(b.speed, 1000.0) for n, b in PERSON_BOUNDS.items()}
"""The person's bounds without the acceleration the scene declares (1,000 m/s^2: its reach
``min((|v| + D) t + A t^2 / 2, V t)`` is ``V t`` after a few milliseconds)."""
PILOT_SEED = 1_000_003
PILOT_EVERY = 10
"""Physics steps between two plans of the pilot."""
SAFETY = 2.0
SAMPLE = 5
"""Physics steps between two samples of the standing pairs by group."""
CLOCK = time.thread_time
"""This thread's CPU time: the machine is shared (plan_horizon.py's clock)."""


def pilot_profile(model: mujoco.MjModel, points: Any, knots: int, pilots: int) -> np.ndarray:
    """The arm's deviation profile (by knots past the plan's start): ``pilots`` runs of the
    scene's driver with the person away (it collides with nothing), a plan every
    :data:`PILOT_EVERY` steps made as the run makes them, ``deviation_profile`` at
    :data:`SAFETY`."""
    blind = person_blind(model)
    rows: list[np.ndarray] = []
    plans: list[PilotPlan] = []
    steps = SCENES["person_cell"].default_steps
    for i in range(pilots):
        _, d = load_scene("person_cell")
        driver = CellDriver(model, PILOT_SEED + i)
        offset = len(rows)
        for k in range(steps):
            if k % PILOT_EVERY == 0 and k + knots <= steps:  # within this pilot
                plans.append(PilotPlan(offset + k, driver.plan(blind, d, knots - 1)))
            rows.append(d.qpos.copy())
            driver(blind, d)
            mujoco.mj_step(blind, d)
        rows.append(d.qpos.copy())
    return deviation_profile(model, np.array(rows), plans, points=points, safety=SAFETY)


def groups(model: mujoco.MjModel, predictor: Predictor) -> dict[str, np.ndarray]:
    """The sphere pairs by what they join: the arm and the person, the arm and itself or the
    cell (MuJoCo collides the person, a mocap body, with neither the cell nor itself)."""
    person = np.isin(model.geom_bodyid, np.flatnonzero(np.asarray(model.body_mocapid) >= 0))
    g1, g2 = predictor.sphere_pair_geoms
    return {"arm-person": person[g1] | person[g2], "arm": ~(person[g1] | person[g2])}


def run(
    model: mujoco.MjModel,
    seed: int,
    horizon: float,
    steps: int,
    deviation: np.ndarray | float,
    floor: float,
) -> dict[str, Any]:
    """One rollout stepped by both predictors (module docstring)."""
    bounds = {s: declared_bounds(model) for s in SIDES}
    bounds["speed"] = declared_bounds(model, person=SPEED_ONLY)
    preds = {s: Predictor(model, accel=bounds[s], alarm_horizon=horizon) for s in SIDES}
    mons = {s: Monitor(preds[s], series=False, warning_horizon=horizon) for s in SIDES}
    _, d = load_scene("person_cell")
    driver = CellDriver(model, seed)
    planners = {}
    for s in ("plan", "speed"):
        planners[s] = Replanner(preds[s], driver, planner=driver.plan, bodies=ARM)
        dev = plan_deviation(np.asarray(deviation), planners[s].knots)
        planners[s].deviation = dev + floor
    # One driver call a step: the "speed" planner plans, then the "plan" one plans and drives.
    planners["speed"].controller = lambda m, d: None
    group = groups(model, preds["plan"])
    stand = {s: dict.fromkeys(group, 0.0) for s in SIDES}
    at_table = dict.fromkeys(SIDES, 0.0)  # arm-person pairs while the person stands there
    walk = driver.person.timelines["person"].moves
    arrived, leaves = walk[0].t1, walk[1].t0
    samples = samples_at = 0
    planners["plan"](model, d)
    mujoco.mj_step(model, d)
    for mon in mons.values():
        mon.start(d)
    t_mj = np.zeros(steps)
    t_step = {s: np.zeros(steps) for s in SIDES}
    for k in range(1, steps + 1):
        planners["speed"](model, d)
        planners["plan"](model, d)
        t0 = CLOCK()
        mujoco.mj_step(model, d)
        t_mj[k - 1] = CLOCK() - t0
        alarms = {}
        for s in SIDES if k % 2 else SIDES[::-1]:  # (the order reversed every step)
            t0 = CLOCK()
            alarms[s] = preds[s].step(d)
            t_step[s][k - 1] = CLOCK() - t0
        for s in SIDES:
            mons[s].observe(d, alarms[s])
        if k % SAMPLE == 0:
            samples += 1
            there = arrived <= d.time <= leaves
            samples_at += there
            for s in SIDES:
                state = preds[s].pair_state()
                up = state.alarm_state() & state.active
                for name, mask in group.items():
                    stand[s][name] += float(up[mask].mean())
                at_table[s] += there * float(up[group["arm-person"]].mean())
    row: dict[str, Any] = {"seed": seed, "horizon_s": horizon, "steps": steps}
    for s in SIDES:
        mons[s].finish()
        w = mons[s].warning
        extra = planners[s].set_plan_seconds if s in planners else 0.0
        row[s] = {
            "standing": mons[s].standing_alarm_fraction,
            "oracle": mons[s].oracle_fraction,
            "standing_by_group": {g: v / max(samples, 1) for g, v in stand[s].items()},
            "arm_person_at_table": at_table[s] / max(samples_at, 1),
            "onsets": mons[s].onsets,
            "missed": len(mons[s].misses),
            "short": w.short_leads,
            "short_held": w.short_held,
            "short_violation": w.short_after_violation,
            "short_start": w.short_at_start,
            "lead_min_s": w.lead_quantiles()[2],
            "violations": mons[s].violations,
            "plan_breaks": preds[s].plan_breaks,
            "cost": float((t_step[s].sum() + extra) / t_mj.sum()),
            "median": float(np.median(t_step[s]) / np.median(t_mj)),
        }
    for s, replan in planners.items():
        row[s] |= {
            "plans": replan.plans,
            "every": replan.every,
            "knots": replan.knots,
            "planner": replan.planner_seconds / float(t_mj.sum()),
            "set_plan_us": replan.set_plan_seconds / max(replan.plans, 1) * 1e6,
        }
    row["mj_step_us"] = float(np.median(t_mj)) * 1e6
    return row


def measure(
    seeds: int, horizons: tuple[float, ...], pilots: int, floor: float, first_seed: int
) -> dict[str, Any]:
    model, _ = load_scene("person_cell")
    h = float(model.opt.timestep)
    steps = SCENES["person_cell"].default_steps
    t0 = time.perf_counter()
    probe = Predictor(model, accel=declared_bounds(model), alarm_horizon=max(horizons))
    knots = Replanner(probe, lambda m, d: None).knots
    profile = pilot_profile(model, probe.bound_points, knots, pilots)
    arm = [model.body(b).name.startswith("arm_") for b in range(model.nbody)]
    print(
        f"deviation profile: {pilots} pilot(s), plans of {knots} knots, largest "
        f"{profile[:, arm].max():.3g} m (safety {SAFETY}), {time.perf_counter() - t0:.0f} s",
        file=sys.stderr,
    )
    rows = []
    for horizon in horizons:
        for seed in range(first_seed, first_seed + seeds):
            t0 = time.perf_counter()
            row = run(model, seed, horizon, steps, profile, floor)
            row["seconds"] = time.perf_counter() - t0
            rows.append(row)
            p, v, b = (row[s] for s in SIDES)
            print(
                f"H {1e3 * horizon:3.0f} ms seed {seed:2d}: oracle {100 * p['oracle']:5.2f} %, "
                f"standing {100 * p['standing']:5.1f} / {100 * v['standing']:5.1f} / "
                f"{100 * b['standing']:5.1f} %, onsets {p['onsets']}, short held "
                f"{p['short_held']} / {v['short_held']} / {b['short_held']}, breaks "
                f"{p['plan_breaks']}, cost {p['cost']:.2f} / {v['cost']:.2f} / {b['cost']:.2f}, "
                f"planner {p['planner']:.1f}, {row['seconds']:.1f} s",
                file=sys.stderr,
                flush=True,
            )
    return {
        "steps": steps,
        "timestep": h,
        "pilots": pilots,
        "safety": SAFETY,
        "floor_m": floor,
        "profile_max_m": float(profile[:, arm].max()),
        "rows": rows,
    }


# ----------------------------------------------------------------------------- tables


def _x(value: float) -> str:
    if not np.isfinite(value):
        return "-"
    return f"{value:.1f}x" if value < 10 else f"{value:.0f}x"


def _row(at: list[dict[str, Any]]) -> list[str]:
    """The table's row of one horizon's runs: a cell of three values reads *plan / plan, the
    person's speed alone / none* (two: the first two)."""

    def mean(side: str, key: str) -> float:
        return float(np.mean([r[side][key] for r in at]))

    def total(side: str, key: str) -> int:
        return int(sum(r[side][key] for r in at))

    def median(side: str, key: str) -> float:
        return float(np.median([r[side][key] for r in at]))

    def sides(f: Any, which: tuple[str, ...] = SIDES) -> str:
        return " / ".join(f(s) for s in which)

    oracle = mean("plan", "oracle")
    touched = [r for r in at if r["plan"]["oracle"] > 0]

    def pooled(side: str) -> str:
        return _x(mean(side, "standing") / oracle if oracle else np.inf)

    def per_seed(side: str) -> str:
        ratios = [r[side]["standing"] / r[side]["oracle"] for r in touched]
        return _x(float(np.median(ratios)) if ratios else np.inf)

    def arm_person(side: str) -> str:
        run = np.mean([r[side]["standing_by_group"]["arm-person"] for r in at])
        there = np.mean([r[side]["arm_person_at_table"] for r in at])
        return f"{100 * run:.0f} ({100 * there:.0f})"

    return [
        f"{1e3 * at[0]['horizon_s']:g} ms",
        f"{len(at)} ({len(touched)})",
        f"{100 * oracle:.2f}",
        sides(lambda s: f"{100 * mean(s, 'standing'):.1f}"),
        sides(pooled),
        sides(per_seed),
        sides(arm_person),
        str(total("plan", "onsets")),
        sides(lambda s: str(total(s, "missed"))),
        sides(lambda s: str(total(s, "short_held"))),
        sides(lambda s: str(total(s, "short_violation"))),
        sides(lambda s: str(total(s, "short_start"))),
        sides(lambda s: str(total(s, "plan_breaks")), SIDES[:2]),
        str(total("plan", "violations")),
        sides(lambda s: f"{median(s, 'cost'):.2f}"),
        sides(lambda s: f"{median(s, 'median'):.2f}"),
        f"{median('plan', 'planner'):.1f}",
    ]


def markdown(result: dict[str, Any]) -> str:
    """One row a horizon (:func:`_row`)."""
    rows = result["rows"]
    horizons = dict.fromkeys(r["horizon_s"] for r in rows)
    return table(
        [
            "horizon",
            "seeds (with a touch)",
            "oracle %",
            "standing %",
            "standing / oracle (pooled)",
            "standing / oracle (median, seeds with a touch)",
            "arm-person pairs standing % (while the person stands at the table)",
            "onsets",
            "missed",
            "lead < H, held",
            "lead < H, after a violation or break",
            "lead < H, at the start",
            "plan breaks",
            "bound violations",
            "predictor / mj_step (incl. set_plan)",
            "predictor / mj_step (median step)",
            "planner / mj_step",
        ],
        [_row([r for r in rows if r["horizon_s"] == h]) for h in horizons],
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20, help="seeds 0.. (the person's visits)")
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--horizons", type=float, nargs="+", default=list(HORIZONS))
    ap.add_argument("--pilots", type=int, default=2, help="pilot runs of the deviation profile")
    ap.add_argument("--floor", type=float, default=0.0, help="metres added to the deviation")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--tables", type=Path, default=None, help="print the tables of saved rows")
    args = ap.parse_args()
    if args.tables is not None:
        print(markdown(json.loads(args.tables.read_text())))
        return
    result = measure(args.seeds, tuple(args.horizons), args.pilots, args.floor, args.first_seed)
    if args.json is not None:
        args.json.write_text(json.dumps(result, indent=1) + "\n")
    print(markdown(result))


if __name__ == "__main__":
    main()
