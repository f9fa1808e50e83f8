"""The record layouts the Python side packs, against the native core that reads them.

The columns and codes are stated once, in C++ (``dua_mujoco/csrc/src/layout.h``, ``tables.h``),
and exported by name (``_core.LAYOUT``): Python reads its column numbers from there, so the two
cannot disagree about a column. What can still go wrong is a packer writing a width other than
the one stated, or a table the builder writes that the runtime does not read (or the reverse):
these tests hold both.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from dua_mujoco import _core
from dua_mujoco.build import kinematics
from dua_mujoco.core.pairset import PAIR_NCOL, PairSet, pack_pairs
from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.models.scenes import load_scene
from dua_mujoco.runtime import table_arrays
from dua_mujoco.runtime.predictor import Predictor


def test_the_python_packers_write_the_stated_widths() -> None:
    assert (
        pack_pairs(PairSet([0], [1], 0.1, 1.0)).shape[1] == PAIR_NCOL == _core.LAYOUT["PAIR_NCOL"]
    )
    spheres = kinematics.pack_spheres([0], [1], np.zeros((1, 3)), [0, 1])
    assert spheres.shape[1] == kinematics.SPHERE_NCOL == _core.LAYOUT["SPHERE_NCOL"]


def test_the_config_names_every_entry_once() -> None:
    entries = sorted(v for k, v in table_arrays.CONFIG.items() if k != "size")
    # Two entries for the structure hash's halves: the one after "shape" has no name.
    assert entries == sorted(set(entries))
    assert max(entries) < table_arrays.CONFIG["size"]


@pytest.mark.parametrize("pairs", ["all", "pruned"])
def test_every_table_the_builder_writes_is_read(pairs: str) -> None:
    """The runtime refuses tables missing one it reads; and every table written is needed:
    dropping any one of them is refused with its name."""
    m, _ = load_scene("two_arms")
    p = Predictor(m, accel=10.0, pairs=pairs)
    arrays = dict(p.table_arrays)
    _core.Tables.build(m, arrays)  # the full set is accepted
    for name in arrays:
        with pytest.raises(InvalidInputError, match=f"table '{name}' is missing"):
            _core.Tables.build(m, {k: v for k, v in arrays.items() if k != name})


def test_tables_of_another_model_are_refused() -> None:
    m, _ = load_scene("two_arms")
    other = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><freejoint/><geom size='.1'/></body>"
        "<body pos='1 0 0'><freejoint/><geom size='.1'/></body></worldbody></mujoco>"
    )
    arrays = Predictor(m, accel=10.0).table_arrays
    with pytest.raises(InvalidInputError, match="table 'config' was made for another model"):
        _core.Tables.build(other, arrays)
