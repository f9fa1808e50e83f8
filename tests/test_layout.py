"""The record layouts, stated once in each language, held to each other.

The Python side packs pair, sphere, shape, exact-level and violation-check records and the
native code reads them by column (``dua_mujoco/csrc/src/layout.h``, ``internal.h``). A column
moved on one side only would have each side read the other's numbers as something else, with
no error: this test compares every column and code the native core exports by name
(``dua_layout_name``/``dua_layout_value``, read as ``_core.LAYOUT``), the schedule's state and
the plugin's config row included. The core's columns are read from ``_core.LAYOUT`` itself, so
for them this holds the names: a column the native core drops or renames fails here.
"""

from __future__ import annotations

import numpy as np

from dua_mujoco import _core, plugin
from dua_mujoco.core import pairset, shapes
from dua_mujoco.core.pairset import PairSet, pack_pairs
from dua_mujoco.core.schedules import state
from dua_mujoco.mj import events, exact_kernels, kinematics


def _native() -> dict[str, int]:
    return {str(k): int(v) for k, v in _core.LAYOUT.items()}


def _python() -> dict[str, int]:
    values: dict[str, int] = {}
    for module, prefixes in (
        (pairset, ("PAIR_",)),
        (kinematics, ("SPHERE_",)),
        (shapes, ("SHAPE_",)),
        (exact_kernels, ("GX_", "X_")),
        (events, ("B_", "NB_", "M_", "STATE_GROUP")),
        (state, ("W_", "P_", "WHERE", "LAST_STEP", "NEXT", "PREV", "NPARAMS")),
        (plugin, ("CFG_",)),
    ):
        values |= {k: v for k, v in vars(module).items() if k.startswith(prefixes)}
    for enum in (pairset.PairKind, shapes.ShapeKind, exact_kernels.ExactMode):
        values |= {f"{enum.__name__}.{member.name}": int(member) for member in enum}
    values |= {"RANK": state.RANK, "DEADLINE": state.DEADLINE, "ALL": state.ALL}
    return values


def test_the_python_packers_write_the_stated_widths() -> None:
    assert pack_pairs(PairSet([0], [1], 0.1, 1.0)).shape[1] == pairset.PAIR_NCOL
    spheres = kinematics.pack_spheres([0], [1], np.zeros((1, 3)), [0, 1])
    assert spheres.shape[1] == kinematics.SPHERE_NCOL


def test_every_column_and_code_is_the_same_in_python_and_in_the_native_core() -> None:
    native, python = _native(), _python()
    assert set(native) == set(python), set(native) ^ set(python)
    assert native == python
