"""The MuJoCo layer's fused step: one compiled call selects the due pairs, reads their spheres
from ``MjData`` through :func:`~dua_mujoco.mj.kinematics.rigid_point`, evaluates tau at every
level it has (spheres; the fine coverings of the two-level urgency; the geoms themselves, the
exact level) and reschedules."""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from dua_mujoco.core.pairset import (
    KIND_HALFSPACE,
    KIND_SHAPE,
    PAIR_ACCEL,
    PAIR_DELTA,
    PAIR_EPS,
    PAIR_FIRST,
    PAIR_KIND,
    PAIR_OTHER,
    PAIR_SECOND,
    PAIR_SPEED,
)
from dua_mujoco.core.schedules import kernels
from dua_mujoco.core.schedules.state import S_W_TAU, S_WORK, W_IDS
from dua_mujoco.core.shapes import tau_static
from dua_mujoco.core.urgency import tau_between, tau_halfspace
from dua_mujoco.mj.events import violation_pass
from dua_mujoco.mj.exact import exact_buffer, exact_pass
from dua_mujoco.mj.kinematics import rigid_point

__all__ = ["scratch_buffers", "step_rigid_kernel"]


def scratch_buffers(width: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`step_rigid_kernel`'s ``scratch``: ``(width, 12)`` gathered pair states (``width``
    the schedule's work width, the most pairs a step selects) and
    :func:`~dua_mujoco.mj.exact.exact_buffer`."""
    return np.empty((max(int(width), 1), 12)), exact_buffer()


@nb.njit(cache=True)
def step_rigid_kernel(  # pragma: no cover - jitted
    st, n, pairs, spheres, frame, shapes, exact, events, scratch
):
    """The fused step on spheres attached to rigid frames (a ``FusedKernel``).

    Reads only the selected spheres. ``pairs`` and ``spheres`` are ``pack_pairs`` /
    ``pack_spheres`` records; ``shapes`` the ``(nshape, 16)`` static shape records
    (``pack_shapes``, one placeholder row without shapes) that shape pairs' ``PAIR_OTHER``
    indexes; ``exact`` the exact level's tuple (``dua_mujoco.mj.exact``: a pair whose tau is
    below its threshold is looked at through its geoms by :func:`exact_pass`); ``events`` the
    violation check's tuple (``dua_mujoco.mj.events``: the held pairs of a body that broke its
    bounds since the last step are made due now, before the selection); ``scratch`` the buffers
    of :func:`scratch_buffers` (allocating them here cost a microsecond a step, measured). Two
    passes: first every selected pair's state is gathered (independent loads, which the CPU
    overlaps; the tables are cold after ``mj_step``), then tau is computed from that small
    buffer. A pair whose state is not finite abandons the step.
    """
    frame_pos, frame_mat = frame[0], frame[1]
    state, xbuf = scratch
    violation_pass(st, n, events, frame)
    count = kernels.select(st, n)
    w_ids = st[S_WORK][W_IDS]
    # Row k: sphere i's centre and velocity, then sphere j's (or the plane's normal, offset;
    # zeros for a static shape, whose record is constant and checked when packed).
    for k in range(count):
        rec = pairs[w_ids[k]]
        rigid_point(int(rec[PAIR_FIRST]), spheres, frame, state[k, 0:6])
        kind = int(rec[PAIR_KIND])
        if kind == KIND_HALFSPACE:
            g = int(rec[PAIR_OTHER])
            state[k, 6] = frame_mat[g, 2]
            state[k, 7] = frame_mat[g, 5]
            state[k, 8] = frame_mat[g, 8]
            state[k, 9] = (
                state[k, 6] * frame_pos[g, 0]
                + state[k, 7] * frame_pos[g, 1]
                + state[k, 8] * frame_pos[g, 2]
            )
            state[k, 10] = 0.0
            state[k, 11] = 0.0
        elif kind == KIND_SHAPE:
            for a in range(6, 12):
                state[k, a] = 0.0
        else:
            rigid_point(int(rec[PAIR_SECOND]), spheres, frame, state[k, 6:12])
    for k in range(count):
        rec = pairs[w_ids[k]]
        s = state[k]
        total = 0.0
        for a in range(12):
            total += s[a]
        if not math.isfinite(total):
            bad = w_ids[k]
            kernels.restore(st, n, count)
            return count, 0, bad
        kind = int(rec[PAIR_KIND])
        if kind == KIND_HALFSPACE:
            gap = s[6] * s[0] + s[7] * s[1] + s[8] * s[2] - s[9] - rec[PAIR_EPS]
            vn = s[6] * s[3] + s[7] * s[4] + s[8] * s[5]
            t = tau_halfspace(gap, vn, rec[PAIR_ACCEL], rec[PAIR_DELTA])
        elif kind == KIND_SHAPE:
            t = tau_static(
                s[0],
                s[1],
                s[2],
                s[3],
                s[4],
                s[5],
                shapes[int(rec[PAIR_OTHER])],
                rec[PAIR_EPS],
                rec[PAIR_ACCEL],
                rec[PAIR_DELTA],
            )
        else:
            t = tau_between(
                s[0:3],
                s[3:6],
                s[6:9],
                s[9:12],
                rec[PAIR_EPS],
                rec[PAIR_ACCEL],
                rec[PAIR_DELTA],
                rec[PAIR_SPEED],
            )
        st[S_W_TAU][k] = t
    exact_pass(st[S_W_TAU], w_ids, count, pairs, frame, exact, xbuf)
    return count, kernels.reinsert(st, n, count), -1
