"""The ``dua-mujoco paper`` subcommand: its options and its entry point."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from dua_mujoco.experiments.paper.reproduce import run_paper
from dua_mujoco.run_options import whole_number

__all__ = ["add_arguments", "main"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``dua-mujoco paper``."""
    parser.add_argument("--quick", action="store_true", help="small run (< 2 min)")
    parser.add_argument("--json", type=Path, default=None, metavar="PATH", help="write JSON here")
    parser.add_argument(
        "--out", type=Path, default=Path("out/paper"), metavar="DIR", help="tables and plots"
    )
    parser.add_argument(
        "--seeds",
        type=whole_number("--seeds", "sequences per setting", minimum=2),
        default=10,
        metavar="N",
        help="sequences per setting (at least 2: the tables give standard deviations)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")


def main(args: argparse.Namespace) -> int:
    """Run ``dua-mujoco paper`` with parsed ``args``; print the tables; return the exit code."""
    if args.seeds < 2:
        print("--seeds must be >= 2 (standard deviations need two sequences).", file=sys.stderr)
        return 2
    result = run_paper(
        quick=args.quick,
        out_dir=args.out,
        json_path=args.json,
        seeds=args.seeds,
        progress=not args.no_progress,
    )
    print(result["markdown"])
    return 0
