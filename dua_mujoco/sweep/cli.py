"""``dua-mujoco sweep``: scenes x seeds x option sets, on local processes or Ray, one table."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from dua_mujoco.run_options import add_count

__all__ = ["DESCRIPTION", "EPILOG", "EXIT_RUN_FAILED", "add_arguments", "main", "markdown"]

EXIT_RUN_FAILED = 4
"""A run of the sweep failed or its process crashed (its row holds the error)."""

DESCRIPTION = (
    "Run every scene x seed x option set as `run` runs it (the same options; a TOML --grid "
    "varies them) on local worker processes, or on Ray with --ray, and print one markdown "
    "table: contact onsets, misses (all, while the bounds held, outside a violation's period), "
    "the fraction of pairs standing in alarm and the oracle's (those that touch within the "
    "warning horizon), the onsets' lead (p10 / median) and those with less lead than the "
    "horizon (held / after a violation / at the start), evaluations a step, predictor and mj_step "
    "microseconds a step, bound violations. A run that fails or crashes is one row with its "
    "error; Ctrl-C writes the rows done. Times are measured with the runs sharing the machine: "
    "compare them within one sweep."
)
EPILOG = (
    "exit codes: 0 every run done, no onset missed outside a violation's period; 1 some run "
    "missed one (a bug); 2 bad input; 4 some run failed or crashed; 130 interrupted (the rows "
    'done are still written). Grid file: [grid] lists multiply (accel = ["auto", 50.0]), '
    '[[set]] tables are named sets (name = "spheres", exact = false); keys are run\'s options.'
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The scenes and the sweep's own options (the run options are added by ``cli``)."""
    p.add_argument("scenes", nargs="+", metavar="SCENE", help="as for run, one or more")
    add_count(
        p, "--seeds", "seeds", 1, "seeds a scene and set: --seed, --seed + 1, ... (default 1)"
    )
    p.add_argument("--grid", type=Path, default=None, help="TOML file of option sets (epilog)")
    add_count(
        p,
        "--workers",
        "processes",
        None,
        "local processes, or CPUs of a local Ray instance (default: the machine's CPUs)",
    )
    p.add_argument(
        "--ray",
        nargs="?",
        type=_ray_address,
        const=True,
        default=False,
        metavar="ADDRESS",
        help="run on Ray: a local instance, or the cluster at ADDRESS (needs dua_mujoco[ray])",
    )
    p.add_argument("--json", type=Path, default=None, help='write {"rows": [...]} here')
    p.add_argument("--markdown", type=Path, default=None, help="write the table here too")
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")


def _ray_address(value: str) -> str:
    """A Ray address (``auto``, ``host:port``, ``ray://host:port``): a scene name after
    ``--ray`` would otherwise be read as one."""
    if value != "auto" and ":" not in value:
        raise argparse.ArgumentTypeError(
            f"{value!r} is not a Ray address (auto, host:port or ray://host:port): put --ray "
            "after the scenes, or write --ray=ADDRESS"
        )
    return value


def run_options_of(args: argparse.Namespace) -> argparse.Namespace:
    """The ``run`` options among ``args`` (what a worker needs, nothing of the sweep's)."""
    from dua_mujoco.run_options import run_option_actions

    dests = run_option_actions()
    return argparse.Namespace(**{k: v for k, v in vars(args).items() if k in dests})


def main(args: argparse.Namespace) -> int:
    """Run ``dua-mujoco sweep``; the exit code."""
    from dua_mujoco.cli import EXIT_INTERRUPTED, EXIT_MISSED, check_output, write_output
    from dua_mujoco.models.scenes import check_scene
    from dua_mujoco.progress import Progress
    from dua_mujoco.sweep import OptionSet, SweepInterrupted, load_grid, sweep, tasks_of

    for scene in args.scenes:  # a typo is bad input, not a sweep of failed rows
        check_scene(scene)
    for path, what in ((args.json, "--json"), (args.markdown, "--markdown")):
        if path is not None:
            check_output(path, what)
    base = run_options_of(args)
    sets = load_grid(args.grid, base) if args.grid is not None else [OptionSet("default", base)]
    seeds = list(range(args.seed, args.seed + args.seeds))
    tasks = tasks_of(args.scenes, seeds, sets)
    where = "Ray" if args.ray is not False else "local processes"
    with Progress(len(tasks), f"sweep ({where})", enabled=not args.no_progress) as bar:

        def on_row(index: int, row: dict[str, Any]) -> None:
            bar.update(note=f"{row['scene']} seed {row['seed']}" + (" FAILED" * bool(row["error"])))

        interrupted = False
        try:
            rows = sweep(tasks, workers=args.workers, ray=args.ray, on_row=on_row)
        except SweepInterrupted as exc:
            rows = [exc.rows[i] for i in sorted(exc.rows)]
            interrupted = True
    table = markdown(rows)
    print(table)
    sys.stdout.flush()
    if args.markdown is not None:
        write_output(args.markdown, table + "\n", "--markdown")
    if args.json is not None:
        doc = {"rows": rows, "interrupted": interrupted}
        write_output(args.json, json.dumps(doc, indent=2) + "\n", "--json")
    failed = sum(1 for r in rows if r["error"])
    bugs = sum(1 for r in rows if r["missed_outside_violations"])
    print(
        f"dua-mujoco sweep: {len(rows)} of {len(tasks)} runs done on {where}"
        + (f", {failed} failed" if failed else "")
        + (f", {bugs} missed an onset outside a violation's period (a bug)" if bugs else ""),
        file=sys.stderr,
    )
    if interrupted:
        print("dua-mujoco: interrupted: the table holds the runs done.", file=sys.stderr)
        return EXIT_INTERRUPTED
    if bugs:
        return EXIT_MISSED
    return EXIT_RUN_FAILED if failed else 0


_HEADER = (
    "| scene | seed | set | steps | onsets | missed (held / outside) | in alarm | oracle "
    "| lead p10 / median ms | lead < horizon (held / violation / start) | evals/step "
    "| predictor us | mj_step us | share | violations (out of contact) | s | error |"
)


def markdown(rows: list[dict[str, Any]]) -> str:
    """The rows as one markdown table (failed runs: their error in the last column)."""
    lines = [_HEADER, "|" + "---|" * _HEADER.count(" | ") + "---|"]
    for r in rows:
        if r["error"]:
            cells = [r["scene"], r["seed"], r["set"], *[""] * 13, _num(r["seconds"], 2), r["error"]]
        else:
            cells = [
                r["scene"],
                r["seed"],
                r["set"],
                r["steps"],
                r["onsets"],
                f"{r['missed']} ({r['missed_valid_bounds']} / {r['missed_outside_violations']})",
                f"{100 * r['standing_fraction']:.2f} %",
                f"{100 * r['oracle_fraction']:.2f} %",
                _leads(r["lead_p10_s"], r["lead_median_s"]),
                f"{r['short_lead']} ({r['short_lead_held']} / "
                f"{r['short_lead_after_violation']} / {r['short_lead_at_start']})",
                _num(r["evals_per_step"], 1),
                _num(r["predictor_us"], 1),
                _num(r["mj_step_us"], 1),
                _num(r["predictor_share"], 2),
                f"{r['bound_violations']} ({r['bound_violations_out_of_contact']})",
                _num(r["seconds"], 2),
                "",
            ]
        lines.append("| " + " | ".join(str(c).replace("|", "/") for c in cells) + " |")
    return "\n".join(lines)


def _leads(p10: float | None, median: float | None) -> str:
    if p10 is None or median is None:
        return ""
    return f"{1e3 * p10:.1f} / {1e3 * median:.1f}"


def _num(value: float | None, digits: int) -> str:
    return "" if value is None else f"{value:.{digits}f}"
