"""``StepContext``: everything the predictor's compiled step reads, handed over as one object.

A ``Predictor.step`` is a few microseconds of compiled work, and handing numba the fused step's
arguments one by one (the schedule state's 12 fields, the pair, sphere and shape tables, the
``MjData`` views of the frame, the exact level's tables: about 25 arrays) cost 1.9 us a call after
``mj_step`` (measured, docs/benchmarks.md). A ``StepContext`` is a numba ``StructRef`` holding
references to those same arrays: numba unboxes it as one pointer (0.7 us a call, measured), and
the arrays stay shared with their Python owners, so the scheduler, the tables and ``MjData``
see every write.

The context also holds the alarm log: the step appends its alarms (model pair id, tau, new)
there instead of leaving them in work rows that the next step overwrites, so an ``Alarms`` is a
span of the log and a step copies nothing in Python. A log is never written twice at the same
place: when it cannot hold another step's worth of alarms, :func:`new_log` gives a fresh one
(:func:`set_log` hands it to the context), and the old one lives as long as some ``Alarms``
refers to it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numba as nb
import numpy as np
from numba.core import types
from numba.experimental import structref

from dua_mujoco.core.schedules.base import Scheduler, compiled_entry
from dua_mujoco.core.schedules.state import (
    P_DEFERRED,
    S_LAST_TAU,
    S_PARAMS,
    S_WORK,
    W_ALARMS,
    W_NEW,
)
from dua_mujoco.mj.rigid_step import scratch_buffers, step_rigid_kernel

__all__ = [
    "LOG_MIN",
    "LOG_STEPS",
    "AlarmLog",
    "StepContext",
    "StepTables",
    "Stepper",
    "context_step",
    "new_log",
    "set_log",
]

AlarmLog = tuple[np.ndarray, np.ndarray, np.ndarray]
"""``(pairs (C,) int64, tau (C,) float64, new (C,) bool)``."""

LOG_STEPS = 4
"""A log holds at least this many steps' worth of the most alarms a step can raise..."""
LOG_MIN = 1 << 14
"""...and at least this many entries (17 bytes each)."""


@structref.register
class StepContextType(types.StructRef):
    """numba's type of a :class:`StepContext` (its fields' types, literals widened)."""

    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class StepTables(NamedTuple):
    """What the compiled step reads besides the schedule's state and the log.

    Attributes:
        pairs: ``(K, ncol)`` packed records of the held pairs (``pack_pairs``).
        spheres: ``(nsphere, ncol)`` packed sphere records (``pack_spheres``).
        frame: ``mjdata_frame``'s tuple of ``MjData`` views.
        shapes: ``(nshape, 16)`` static shape records.
        exact: The exact level's tuple (``ExactLevel.args`` or ``no_exact()``).
        events: The violation check's tuple (``EventTable.args`` or ``no_events()``).
        ids: ``(K,)`` model sphere-pair id of each held pair (the identity when none is pruned).
    """

    pairs: np.ndarray
    spheres: np.ndarray
    frame: tuple
    shapes: np.ndarray
    exact: tuple
    events: tuple
    ids: np.ndarray


class StepContext(structref.StructRefProxy):
    """The fused step's arguments as one object (see the module docstring): the scheduler's
    ``kernel_state``, the :class:`StepTables` fields, the step's scratch buffers (sized for the
    state's work width) and the writeable :data:`AlarmLog` the step appends to."""

    def __new__(cls, state: tuple, tables: StepTables, log: AlarmLog) -> StepContext:
        scratch = scratch_buffers(state[S_WORK].shape[1])
        return structref.StructRefProxy.__new__(cls, state, *tables, scratch, log)


structref.define_proxy(
    StepContext, StepContextType, ["state", *StepTables._fields, "scratch", "log"]
)


def new_log(capacity: int) -> tuple[AlarmLog, AlarmLog]:
    """A fresh alarm log of ``capacity`` entries: ``(writeable, read-only views of it)``."""
    log = (
        np.empty(capacity, dtype=np.int64),
        np.empty(capacity, dtype=np.float64),
        np.empty(capacity, dtype=np.bool_),
    )
    views = tuple(a.view() for a in log)
    for v in views:
        v.flags.writeable = False
    return log, views  # type: ignore[return-value]


@nb.njit(cache=True)
def set_log(ctx, log):  # pragma: no cover - jitted
    """Hand the context a new alarm log (of the same types as its current one)."""
    ctx.log = log


@nb.njit(cache=True)
def context_step(ctx, n, start):  # pragma: no cover - jitted
    """One fused step of the schedule in ``ctx`` (``step_rigid_kernel``), its alarms appended to
    the log at ``start``: ``(nalarm, bad, deferred)``.

    ``bad >= 0`` names a held pair whose state was not finite: the step was undone and nothing
    was appended. The caller keeps ``start + nalarm + width <= capacity`` before each call.
    """
    st = ctx.state
    _, nalarm, bad = step_rigid_kernel(
        st, n, ctx.pairs, ctx.spheres, ctx.frame, ctx.shapes, ctx.exact, ctx.events, ctx.scratch
    )
    if bad >= 0:
        return 0, bad, 0
    alarms = st[S_WORK][W_ALARMS]
    new = st[S_WORK][W_NEW]
    last_tau = st[S_LAST_TAU]
    pairs, tau, fresh = ctx.log
    ids = ctx.ids
    for k in range(nalarm):
        p = alarms[k]
        pairs[start + k] = ids[p]
        tau[start + k] = last_tau[p]
        fresh[start + k] = new[k] != 0
    return nalarm, -1, st[S_PARAMS][P_DEFERRED]


class Stepper:
    """A predictor's compiled step: its ``StepContext``, the alarm log and the entry point.

    ``context`` is None until :meth:`bind` and after the owner drops it (any argument
    changed); ``used`` is the log's next write position, kept by the caller of ``entry``.

    Args:
        width: Most alarms a step can raise (the scheduler's work-row width).
    """

    __slots__ = ("capacity", "context", "entry", "log", "room", "used", "view")

    def __init__(self, width: int) -> None:
        self.room = int(width)
        # Room for many steps: a full log is replaced, never overwritten.
        self.capacity = max(LOG_STEPS * self.room, LOG_MIN)
        self.log, self.view = new_log(self.capacity)
        self.used = 0
        self.context: StepContext | None = None
        self.entry: Callable[..., tuple] = context_step

    def bind(self, state: tuple, tables: StepTables) -> StepContext:
        """A new context over ``state``, ``tables`` and the log; the entry point for it."""
        self.context = StepContext(state, tables, self.log)
        if self.entry is context_step:
            self.entry = compiled_entry(context_step, self.context, 1, 0)
        return self.context

    def next_log(self) -> int:
        """Replace a log without room for another step's alarms; the new write position (0).

        The old log lives as long as some ``Alarms`` of it does.
        """
        self.log, self.view = new_log(self.capacity)
        if self.context is not None:
            set_log(self.context, self.log)
        self.used = 0
        return 0

    @staticmethod
    def load_compiled(scheduler: Scheduler, tables: StepTables) -> None:
        """Run one step of ``scheduler`` (a throw-away one) on ``tables`` (read only) so that
        numba loads the step and the log switch from its cache (~10 ms) now."""
        log, _ = new_log(1)
        context = StepContext(scheduler.kernel_state, tables, log)
        scheduler.step_context(context_step, context, 0)
        set_log(context, log)
