"""The command line the example videos share (the scripts' folder is on ``sys.path``)."""

from __future__ import annotations

import argparse
from pathlib import Path


def video_parser(doc: str, gif: str, *, fps: float, frames: int = 0) -> argparse.ArgumentParser:
    """A parser described by the first line of the script's ``doc``, with ``--out`` (default
    ``docs/img/<gif>``), ``--fps`` (default ``fps``) and, where ``frames`` > 0, ``--frames``: a
    folder for a PNG of one video frame in ``frames``."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "img" / gif)
    ap.add_argument("--fps", type=float, default=fps)
    if frames:
        ap.add_argument(
            "--frames", type=Path, default=None, help=f"also save one frame in {frames} here"
        )
    return ap
