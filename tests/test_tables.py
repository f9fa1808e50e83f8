"""The runtime's tables refuse what does not fit the model, naming the table (csrc/src/tables.cc).

Every table a step reads by index is checked when the tables are built (from a predictor's
arrays, or parsed from the plugin's attributes): a corrupted entry is either refused with an
error that names its table, or is a value the step can take (a margin, a bound), and then the
runtime classifies and steps on it without reading out of bounds. The fuzz target
(csrc/fuzz) drives the same code with random bytes; this is the readable, per-table version.
"""

from __future__ import annotations

import contextlib

import mujoco
import numpy as np
import pytest

from dua_mujoco import _core
from dua_mujoco.build.exact import GX_GRAPH, GX_KIND, GX_VERT
from dua_mujoco.build.options import PairOptions
from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.models.scenes import load_scene
from dua_mujoco.runtime.predictor import Predictor

# clutter has a plane, static shapes, a mocap body and events; pruned adds the reach tables.
SCENES = {"all": {}, "pruned": {"pairs": PairOptions(mode="pruned")}}
BAD = {"nan": np.nan, "inf": np.inf, "minus-two": -2.0, "huge": 1e9, "fraction": 0.5}


def _arrays(kind: str) -> tuple[mujoco.MjModel, mujoco.MjData, dict[str, np.ndarray]]:
    m, d = load_scene("clutter")
    p = Predictor(m, accel=30.0, **SCENES[kind])
    return m, d, {k: np.array(v, dtype=np.float64) for k, v in p.table_arrays.items()}


def _runs(m: mujoco.MjModel, d: mujoco.MjData, tables: _core.Tables, names: list[str]) -> None:
    rt = _core.Runtime(tables, m, names)
    rt.bind(d)
    mujoco.mj_forward(m, d)
    rt.classify()
    for _ in range(3):
        mujoco.mj_step(m, d)
        # A refused state is an answer; reading out of bounds would not be.
        with contextlib.suppress(_core.StepError):
            rt.step()


@pytest.mark.parametrize("kind", list(SCENES))
@pytest.mark.parametrize("bad", list(BAD))
def test_a_corrupted_entry_is_refused_by_name_or_taken(kind: str, bad: str) -> None:
    m, _, arrays = _arrays(kind)
    names = [m.geom(g).name for g in range(m.ngeom)]
    refused = 0
    for name, table in arrays.items():
        if table.size == 0:
            continue
        # The first, the last and a middle entry: a row's index columns and its values.
        for at in sorted({0, table.size // 2, table.size - 1}):
            corrupt = table.copy()
            corrupt.flat[at] = BAD[bad]
            try:
                tables = _core.Tables.build(m, {**arrays, name: corrupt})
            except InvalidInputError as err:
                assert f"'{name}'" in str(err) or name in str(err), (name, at, str(err))
                refused += 1
                continue
            _runs(m, mujoco.MjData(m), tables, names)
    assert refused > 0


@pytest.mark.parametrize("kind", list(SCENES))
def test_a_table_of_the_wrong_size_is_refused_by_name(kind: str) -> None:
    m, _, arrays = _arrays(kind)
    for name, table in arrays.items():
        if table.ndim < 2 or table.shape[0] == 0:
            continue
        short = table.ravel()[:-1].copy()  # not a whole number of rows
        with pytest.raises(InvalidInputError, match=f"'{name}'"):
            _core.Tables.build(m, {**arrays, name: short})
    missing = dict(arrays)
    del missing["pairs"]
    with pytest.raises(InvalidInputError, match="'pairs'"):
        _core.Tables.build(m, missing)


def test_tables_of_another_model_are_refused() -> None:
    _, _, arrays = _arrays("all")
    other, _ = load_scene("two_arms")
    with pytest.raises(InvalidInputError, match="another model"):
        _core.Tables.build(other, arrays)


@pytest.mark.parametrize(("scene", "kind"), [("clutter", -1.0), ("rough_terrain", 1.0)])
def test_a_hull_address_on_a_geom_without_a_hull_is_refused(scene: str, kind: float) -> None:
    """A geom the exact level does not read (kind -1) and a height field (kind 1) have no hull:
    an address in their record's graph column is refused, not used to index the hull graph
    (the tables fuzzer found 1e308 there read as an index)."""
    m, _ = load_scene(scene)
    arrays = {
        k: np.array(v, dtype=np.float64) for k, v in Predictor(m, accel=30.0).table_arrays.items()
    }
    geoms = arrays["exact_geoms"]
    row = int(np.flatnonzero(geoms[:, GX_KIND] == kind)[0])
    for column, value in ((GX_GRAPH, 1e308), (GX_GRAPH, 0.0), (GX_VERT, 0.0)):
        corrupt = geoms.copy()
        corrupt[row, column] = value
        with pytest.raises(InvalidInputError, match="'exact_geoms'"):
            _core.Tables.build(m, {**arrays, "exact_geoms": corrupt})
