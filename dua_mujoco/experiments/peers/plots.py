"""The benchmark's plots: time, false alarms and work per step against N, one line per peer."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from dua_mujoco.experiments.report import pyplot, save_figure

__all__ = ["plots"]


def plots(result: dict[str, Any], out_dir: Path) -> None:
    """Write ``peers_time.png``, ``peers_false_alarms.png`` and ``peers_candidates.png``.

    Nothing is written without matplotlib (the ``plots`` extra).

    Args:
        result: A ``run_peers`` result (its ``ghost`` rows are plotted).
        out_dir: An existing folder.
    """
    plt = pyplot()
    if plt is None:
        return
    rows = result["ghost"]
    peers = list(dict.fromkeys(r["peer"] for r in rows))

    def per_peer(
        value: Callable[[dict[str, Any]], float | None],
        ylabel: str,
        title: str,
        name: str,
        floor: float | None = None,
    ) -> None:
        # One log-log line per peer against N; peers without the value (None) are left out.
        fig, ax = plt.subplots(figsize=(6.4, 4.4))
        for p in peers:
            pts = [(r["n"], value(r)) for r in rows if r["peer"] == p]
            pts = [(x, y) for x, y in pts if y is not None]
            if pts:
                x, y = zip(*pts, strict=True)
                ax.loglog(x, y if floor is None else np.maximum(y, floor), marker="o", label=p)
        ax.set_xlabel("spheres N")
        ax.set_ylabel(ylabel)
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
        save_figure(plt, fig, out_dir / name)

    per_peer(
        lambda r: r["time_us"],
        "median time per step (us)",
        "Time per step, ghost world",
        "peers_time.png",
    )
    per_peer(
        lambda r: (r["false_alarms"] + r["open_alarms"]) / r["steps"],
        "false (+ open) alarms per step",
        "False alarms, ghost world (floor 1e-3 = none)",
        "peers_false_alarms.png",
        floor=1e-3,
    )
    per_peer(
        lambda r: r["candidates_per_step"],
        "pair evaluations / candidates per step",
        "Work per step, ghost world",
        "peers_candidates.png",
    )
