"""What the experiments' reports are made of: markdown tables, number cells, JSON, plot files."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

__all__ = ["fmt", "jsonable", "pyplot", "save_figure", "table"]


def fmt(x: float | None, digits: int = 1, *, missing: str = "-", compact: bool = False) -> str:
    """A number as a table cell.

    Args:
        x: The number (None: no value).
        digits: Digits after the decimal point.
        missing: The cell of ``None``.
        compact: No thousands separators, and ``|x| >= 1e5`` as three significant digits
            (``1e+05``): the peers' tables. Otherwise thousands separators (``12,345.6``): the
            paper's tables.

    Returns:
        The cell text; integers are printed as they are.
    """
    if x is None:
        return missing
    if not isinstance(x, float):
        return str(x)
    if compact:
        return f"{x:.3g}" if abs(x) >= 1e5 else f"{x:.{digits}f}"
    return f"{x:,.{digits}f}"


def table(
    header: Sequence[str], body: Iterable[Sequence[str]], *, right_align: bool = False
) -> str:
    """A markdown table.

    Args:
        header: ``(k,)`` column titles.
        body: Rows of ``k`` cells each.
        right_align: Right-align every column (numbers line up in a plain-text view).

    Returns:
        The table's lines joined by newlines (no trailing newline).
    """
    rule = "---:" if right_align else "---"
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(rule for _ in header) + "|"]
    lines += ["| " + " | ".join(row) + " |" for row in body]
    return "\n".join(lines)


def jsonable(x: Any) -> Any:
    """``x`` with what strict JSON cannot hold replaced, recursively.

    Dict keys become strings (the paper's prefix counts are keyed by iteration counts), NaN and
    infinities become None, numpy scalars Python ones and tuples lists.
    """
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [jsonable(v) for v in x]
    if isinstance(x, np.generic):
        return jsonable(x.item())
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def pyplot() -> ModuleType | None:
    """``matplotlib.pyplot`` on the file-only Agg backend, or None when matplotlib is missing.

    Plots are an optional extra (``pip install dua-mujoco[plots]``): without it the experiments
    still write their tables and JSON.
    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    return plt


def save_figure(plt: ModuleType, fig: Any, path: Path) -> None:
    """Lay ``fig`` out, write it to ``path`` (110 dpi) and release it."""
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
