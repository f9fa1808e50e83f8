"""What the benchmark scripts share that imports nothing of the package: a call's median time
and a markdown table (a script may import it before choosing which checkout to import)."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable, Iterable, Sequence
from typing import Any

__all__ = ["Column", "by_label", "columns_table", "median_time", "table"]


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


Column = tuple[str, Callable[[Any], str]]
"""A table column: its header and its cell of one row."""


def columns_table(columns: Sequence[Column], rows: Iterable[Any]) -> str:
    """A markdown table of ``rows``, one column a ``(header, cell)`` pair."""
    return table(
        [header for header, _ in columns], [[cell(r) for _, cell in columns] for r in rows]
    )


def by_label(rows: Iterable[Any], label: Callable[[Any], str]) -> list[tuple[str, list[Any]]]:
    """``rows`` grouped by ``label(row)``: ``(label, rows)`` in the order labels first come."""
    groups: dict[str, list[Any]] = {}
    for r in rows:
        groups.setdefault(label(r), []).append(r)
    return list(groups.items())
