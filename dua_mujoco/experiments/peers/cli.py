"""The ``dua-mujoco peers`` subcommand: its options and its entry point."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from dua_mujoco.experiments.peers.benchmark import run_peers
from dua_mujoco.experiments.peers.ghost import COMPLETE_PEERS
from dua_mujoco.experiments.peers.markdown import markdown

__all__ = ["add_arguments", "main"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``dua-mujoco peers``."""
    parser.add_argument("--quick", action="store_true", help="small run (< 2 min)")
    parser.add_argument("--json", type=Path, default=None, metavar="PATH", help="write JSON here")
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("out/peers"),
        metavar="DIR",
        help="folder for peers.md, peers.json and plots (default out/peers)",
    )
    parser.add_argument("--no-memory", action="store_true", help="skip the large-N memory probes")
    parser.add_argument("--no-progress", action="store_true", help="no progress line on stderr")


def main(args: argparse.Namespace) -> int:
    """Run ``dua-mujoco peers``; prints the markdown tables. Returns the exit code."""
    result = run_peers(
        quick=bool(args.quick),
        out_dir=args.out,
        json_path=args.json,
        progress=not args.no_progress,
        memory=not getattr(args, "no_memory", False),
    )
    print(markdown(result))
    if args.out is not None:
        print(f"tables, plots and JSON written to {args.out}")
    bad = [r for r in result["ghost"] if r["peer"] in COMPLETE_PEERS and r["missed"]]
    if bad:
        print(f"warning: complete peers missed collisions: {bad}", file=sys.stderr)
        return 1
    return 0
