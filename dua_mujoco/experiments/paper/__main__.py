"""``python -m dua_mujoco.experiments.paper``: the same as ``dua-mujoco paper``."""

from __future__ import annotations

import argparse

from dua_mujoco.experiments.paper import add_arguments, main

if __name__ == "__main__":
    parser = argparse.ArgumentParser(prog="dua-mujoco paper")
    add_arguments(parser)
    raise SystemExit(main(parser.parse_args()))
