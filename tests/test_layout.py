"""The record layouts, stated once in each language, held to each other.

The Python side packs pair, sphere, shape, exact-level and violation-check records and the
native code reads them by column (``dua_mujoco/csrc/src/layout.h``, ``internal.h``). A column
moved on one side only would have each side read the other's numbers as something else, with
no error: this test compares every column and code the native core exports by name
(``dua_layout_name``/``dua_layout_value``), the schedule's state and the plugin's config row
included.
"""

from __future__ import annotations

import ctypes

import numpy as np

from dua_mujoco import plugin
from dua_mujoco.core import pairset, shape_kernels
from dua_mujoco.core.pairset import PairSet, pack_pairs
from dua_mujoco.core.schedules import state
from dua_mujoco.mj import events, exact_kernels, kinematics
from dua_mujoco.native import declare


def _native() -> dict[str, int]:
    lib = declare(
        {
            "dua_layout_name": (ctypes.c_char_p, [ctypes.c_int64]),
            "dua_layout_value": (ctypes.c_int64, [ctypes.c_int64]),
        }
    )
    out, i = {}, 0
    while (name := lib.dua_layout_name(i)) is not None:
        out[name.decode()] = int(lib.dua_layout_value(i))
        i += 1
    return out


def _python() -> dict[str, int]:
    values: dict[str, int] = {}
    for module, prefixes in (
        (pairset, ("PAIR_",)),
        (kinematics, ("SPHERE_",)),
        (shape_kernels, ("SHAPE_",)),
        (exact_kernels, ("GX_", "X_")),
        (events, ("B_", "NB_", "M_", "STATE_GROUP")),
        (state, ("W_", "P_", "WHERE", "LAST_STEP", "NEXT", "PREV", "NPARAMS")),
        (plugin, ("CFG_",)),
    ):
        values |= {k: v for k, v in vars(module).items() if k.startswith(prefixes)}
    for enum in (pairset.PairKind, shape_kernels.ShapeKind, exact_kernels.ExactMode):
        values |= {f"{enum.__name__}.{member.name}": int(member) for member in enum}
    values |= {"RANK": state.RANK, "DEADLINE": state.DEADLINE}
    return values


def test_the_python_packers_write_the_stated_widths() -> None:
    assert pack_pairs(PairSet([0], [1], 0.1, 1.0)).shape[1] == pairset.PAIR_NCOL
    spheres = kinematics.pack_spheres([0], [1], np.zeros((1, 3)), [0, 1])
    assert spheres.shape[1] == kinematics.SPHERE_NCOL


def test_every_column_and_code_is_the_same_in_python_and_in_the_native_core() -> None:
    native, python = _native(), _python()
    assert set(native) == set(python), set(native) ^ set(python)
    assert native == python
