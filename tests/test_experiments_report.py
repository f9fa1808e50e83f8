"""The report helpers both experiments share: cells, markdown tables, strict JSON, figure files."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from dua_mujoco.experiments.report import fmt, jsonable, pyplot, save_figure, table


def test_fmt_paper_style_groups_thousands() -> None:
    assert fmt(1543.02, 2) == "1,543.02"
    assert fmt(2749305.4, 0) == "2,749,305"
    assert fmt(None) == "-"
    assert fmt(math.inf) == "inf"


def test_fmt_compact_style_switches_to_three_significant_digits() -> None:
    assert fmt(99999.0, 1, compact=True) == "99999.0"
    assert fmt(1e5, 0, compact=True) == "1e+05"
    assert fmt(-2.5e6, compact=True) == "-2.5e+06"
    assert fmt(None, missing="n/a", compact=True) == "n/a"


def test_fmt_prints_integers_as_they_are() -> None:
    assert fmt(12345, 2) == "12345"
    assert fmt(np.float64(0.125), 2) == "0.12"  # numpy floats are floats


def test_table_rules_and_rows() -> None:
    md = table(["a", "b"], [["1", "2"], ["3", "4"]])
    assert md.splitlines() == ["| a | b |", "|---|---|", "| 1 | 2 |", "| 3 | 4 |"]
    right = table(["a", "b"], [], right_align=True)
    assert right.splitlines()[1] == "|---:|---:|"


def test_jsonable_is_strict_json() -> None:
    raw = {
        "at": {25: 3, 75: 9},
        "x": [np.float64(1.5), np.int64(2), (math.nan, -math.inf)],
        "ok": "text",
    }
    out = jsonable(raw)
    assert out == {"at": {"25": 3, "75": 9}, "x": [1.5, 2, [None, None]], "ok": "text"}
    assert type(out["x"][1]) is int
    json.dumps(out, allow_nan=False)  # raises if a NaN or an inf survived


def test_save_figure_writes_and_releases(tmp_path: Path) -> None:
    plt = pyplot()
    if plt is None:
        pytest.skip("matplotlib is not installed")
    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    path = tmp_path / "line.png"
    save_figure(plt, fig, path)
    assert path.stat().st_size > 0
    assert not plt.fignum_exists(fig.number)
