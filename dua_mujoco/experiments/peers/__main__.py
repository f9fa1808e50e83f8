"""``python -m dua_mujoco.experiments.peers``: the same as ``dua-mujoco peers``."""

from __future__ import annotations

import argparse

from dua_mujoco.experiments.peers import add_arguments, main

if __name__ == "__main__":  # pragma: no cover
    parser = argparse.ArgumentParser(prog="dua-mujoco peers")
    add_arguments(parser)
    raise SystemExit(main(parser.parse_args()))
