"""``python -m dua_mujoco`` = the ``dua-mujoco`` command (its console script calls :func:`main`).

This module imports nothing heavy: it takes Ctrl-C over before the command's imports (MuJoCo,
numpy, the compiled core) begin, so that an interrupt at any point of the set-up is one line and
exit 130, like the run loop's. An interrupt in the middle of an extension module's
initialisation does not always surface as ``KeyboardInterrupt`` (numpy turns it into an
``ImportError``), so the handler records that it fired, and whatever escapes afterwards is
reported as the interrupt it is.
"""

from __future__ import annotations

import signal
import sys
from collections.abc import Sequence
from types import FrameType

__all__ = ["EXIT_INTERRUPTED", "main"]

EXIT_INTERRUPTED = 130
"""Ctrl-C (128 + SIGINT, the shell's convention); ``dua_mujoco.cli`` uses the same code."""


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``dua-mujoco`` command on ``argv`` (default ``sys.argv[1:]``); return its exit
    code, 130 with the line ``dua-mujoco: interrupted.`` on stderr when Ctrl-C escapes the
    command (it handles the interrupts of its run loops itself)."""
    fired = False

    def interrupt(signum: int, frame: FrameType | None) -> None:
        nonlocal fired
        fired = True
        raise KeyboardInterrupt

    previous = signal.getsignal(signal.SIGINT)
    if previous is signal.default_int_handler:  # not if the caller ignores or handles SIGINT
        signal.signal(signal.SIGINT, interrupt)
    try:
        from dua_mujoco.cli import main as cli_main

        return cli_main(argv)
    except BaseException:
        if not fired:
            raise
        print("dua-mujoco: interrupted.", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        if previous is signal.default_int_handler:
            signal.signal(signal.SIGINT, previous)


if __name__ == "__main__":
    sys.exit(main())
