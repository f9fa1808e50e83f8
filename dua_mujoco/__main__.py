"""``python -m dua_mujoco`` = the ``dua-mujoco`` command."""

from __future__ import annotations

import sys

from dua_mujoco.cli import main

if __name__ == "__main__":
    sys.exit(main())
