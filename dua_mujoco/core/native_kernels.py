"""The native core's kernels as numba sees them: external C functions of ``libdua_mujoco.so``.

Every kernel of the predictor's step is implemented once, in C++ (``dua_mujoco/csrc``); the
numba code that remains (batch loops, the sphere predictor's fused step, the pilot and monitor
loops) calls these. numba links them by symbol name, so its cached machine code stays valid
across processes: this module loads the library into LLVM's symbol table before any kernel that
uses them is compiled or loaded from the cache.

Pointers are passed as ``array.ctypes``; a struct argument (the schedule, the frame) as an
``int64`` array whose entries are its fields (:func:`frame_view`; the schedule's is
``dua_mujoco.core.schedules.kernels.schedule_view``).
"""

from __future__ import annotations

from typing import Any

import llvmlite.binding as llvm
import numba as nb
import numpy as np
from numba import types

from dua_mujoco.native import library, library_path

__all__ = [
    "closest_point_c",
    "deadline_carry_c",
    "deadline_classify_c",
    "difference_poses_c",
    "exceeds12_c",
    "frame_view",
    "make_due_c",
    "rank_classify_c",
    "reinsert_c",
    "restore_c",
    "rigid_point_c",
    "select_c",
    "static_gap_c",
    "step_c",
    "support_c",
    "switch_c",
    "tau_accel_c",
    "tau_halfspace_c",
    "tau_speed_batch_c",
    "tau_speed_c",
    "tau_static_c",
]

library()
llvm.load_library_permanently(str(library_path()))

_f8 = types.float64
_i8 = types.int64
_pf8 = types.CPointer(types.float64)
_pi8 = types.CPointer(types.int64)


def _c(name: str, signature: Any) -> Any:
    # Any: numba's types do not type their calls, and the kernels call these.
    return types.ExternalFunction(name, signature)


tau_accel_c = _c("dua_tau_accel", _f8(*([_f8] * 9)))
tau_speed_c = _c("dua_tau_speed", _f8(*([_f8] * 10)))
tau_speed_batch_c = _c(
    "dua_tau_speed_batch", types.void(_i8, _pf8, _pf8, _pf8, _pf8, _pf8, _pf8, _i8, _pf8)
)
tau_halfspace_c = _c("dua_tau_halfspace", _f8(_f8, _f8, _f8, _f8))
support_c = _c("dua_support", _f8(_pf8, _pf8))
closest_point_c = _c("dua_closest_point", types.void(_pf8, _pf8, _pf8))
static_gap_c = _c("dua_static_gap", types.void(_pf8, _pf8, _pf8))
tau_static_c = _c("dua_tau_static", _f8(*([_f8] * 6), _pf8, _f8, _f8, _f8))
select_c = _c("dua_select", _i8(_pi8, _i8))
reinsert_c = _c("dua_reinsert", _i8(_pi8, _i8, _i8))
restore_c = _c("dua_restore", types.void(_pi8, _i8, _i8))
switch_c = _c("dua_switch", _i8(_pi8, _pi8, _i8, _i8, _i8))
make_due_c = _c("dua_make_due", types.void(_pi8, _i8, _i8))
deadline_classify_c = _c("dua_deadline_classify", types.void(_pi8))
rank_classify_c = _c("dua_rank_classify", types.void(_pi8))
deadline_carry_c = _c("dua_deadline_carry", types.void(_pi8, _pi8, _pi8, _i8, _i8))
rigid_point_c = _c("dua_rigid_point", types.void(_i8, _pf8, _pi8, _pf8))
# The predictor's step on a ``dua_step_args`` struct (its address: an int, as the C ABI passes a
# pointer).
step_c = _c("dua_step", _i8(_i8, _i8, _i8))
exceeds12_c = _c("dua_exceeds12", _i8(*([_f8] * 13)))
_pb = types.CPointer(types.boolean)  # numpy's bool: one byte, as the core's uint8_t
difference_poses_c = _c(
    "dua_difference_poses",
    types.void(_pf8, _pf8, _pi8, _i8, _pf8, _pf8, _f8, _pb, _pf8, _pf8, _pf8, _i8),
)


@nb.njit(cache=True)
def frame_view(frame):  # pragma: no cover - jitted
    """A ``dua_frame`` over the ``mjdata_frame`` tuple's arrays (which must outlive its use)."""
    v = np.empty(6, dtype=np.int64)
    v[0] = frame[0].ctypes.data
    v[1] = frame[1].ctypes.data
    v[2] = frame[2].ctypes.data
    v[3] = frame[3].ctypes.data
    v[4] = frame[4].ctypes.data
    v[5] = frame[5].ctypes.data
    return v
