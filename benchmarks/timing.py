"""What the benchmark scripts share that imports nothing of the package: a call's median time
and a markdown table (a script may import it before choosing which checkout to import)."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

__all__ = ["median_time", "table"]


def median_time(fn: Callable[[], object], repeat: int, warmup: int = 1) -> float:
    """The median seconds of ``repeat`` calls of ``fn``, after ``warmup`` calls."""
    for _ in range(warmup):
        fn()
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)


def table(header: list[str], rows: list[list[str]]) -> str:
    """A markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)
