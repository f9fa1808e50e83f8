"""``NativeStep``: the predictor's step in the native core, pointed at the Python side's arrays.

The step (violation check, selection, gather from ``MjData``, tau at every level, reinsertion) is
``dua_step`` of ``libdua_mujoco.so`` (``dua_mujoco/csrc/src/step.cc``), the same code the MuJoCo
plugin runs inside ``mj_step``. Its argument is one ``dua_step_args`` struct of pointers
(``dua/dua.h``), mirrored here by ctypes structures: a ``NativeStep`` fills it from the
predictor's tables, the scheduler's state, the ``MjData`` buffers and the alarm log, keeps a
reference to every array it points at, and calls the core with the struct's address. Nothing is
copied: the scheduler, the tables and ``MjData`` see every write.

**The alarm log.** The step appends its alarms (model pair id, tau, new) to a log instead of
leaving them in work rows that the next step overwrites, so an ``Alarms`` is a span of the log
and a step copies nothing in Python. A log is never written twice at the same place: when it
cannot hold another step's worth of alarms, a fresh one replaces it, and the old one lives as long
as some ``Alarms`` refers to it.
"""

from __future__ import annotations

import ctypes
import functools
from collections.abc import Callable
from typing import Any

import mujoco
import numba as nb
import numpy as np

from dua_mujoco.core.native_kernels import step_c
from dua_mujoco.core.schedules.base import compiled_entry
from dua_mujoco.core.schedules.state import ScheduleState
from dua_mujoco.native import ABI_VERSION, declare

__all__ = ["LOG_MIN", "LOG_STEPS", "AlarmLog", "NativeStep", "new_log"]

AlarmLog = tuple[np.ndarray, np.ndarray, np.ndarray]
"""``(pairs (C,) int64, tau (C,) float64, new (C,) bool)``."""

LOG_STEPS = 4
"""A log holds at least this many steps' worth of the most alarms a step can raise..."""
LOG_MIN = 1 << 14
"""...and at least this many entries (17 bytes each)."""

_p = ctypes.c_void_p
_i = ctypes.c_int64
_d = ctypes.c_double


class _Schedule(ctypes.Structure):
    _fields_ = [
        ("kind", _i),
        ("dt", _d),
        ("latency", _i),
        ("m", _i),
        ("last_tau", _p),
        ("active", _p),
        ("ints", _p),
        ("slots", _p),
        ("nslots", _i),
        ("horizon", _p),
        ("queue", _p),
        ("nqueue", _i),
        ("params", _p),
        ("work", _p),
        ("width", _i),
        ("w_tau", _p),
    ]


class _Frame(ctypes.Structure):
    _fields_ = [
        (name, _p) for name in ("pos", "mat", "twist", "twist_ref", "root_twist", "root_origin")
    ]


class _Exact(ctypes.Structure):
    _fields_ = [
        ("on", _i),
        ("geoms", _p),
        ("records", _p),
        ("below", _d),
        ("query_below", _d),
        ("verts", _p),
        ("graph", _p),
        ("model", _p),
        ("data", _p),
    ]


class _Events(ctypes.Structure):
    _fields_ = [
        ("nbody", _i),
        ("rec", _p),
        ("prev", _p),
        ("meta", _p),
        ("flagged", _p),
        ("start", _p),
        ("members", _p),
        ("params", _p),
    ]


class _StepArgs(ctypes.Structure):
    _fields_ = [
        ("abi", _i),
        ("schedule", _Schedule),
        ("pairs", _p),
        ("spheres", _p),
        ("shapes", _p),
        ("ids", _p),
        ("frame", _Frame),
        ("exact", _Exact),
        ("events", _Events),
        ("scratch", _p),
        ("scratch_rows", _i),
        ("point_state", _p),
        ("point_epoch", _p),
        ("epoch", _i),
        ("log_pairs", _p),
        ("log_tau", _p),
        ("log_new", _p),
        ("bad", _i),
        ("deferred", _i),
        ("count", _i),
    ]


@nb.njit(cache=True)
def _run(address, n, start):  # pragma: no cover - jitted
    """``dua_step`` on the struct at ``address``: called through numba's compiled entry point,
    0.1 us a call (ctypes converting the same three ints: 0.5 us, measured)."""
    return step_c(address, n, start)


@functools.cache
def _functions() -> Any:
    """The C functions called through ctypes (the step itself goes through numba's entry point),
    their signatures declared once."""
    args = ctypes.POINTER(_StepArgs)
    return declare(
        {
            "dua_evaluate": (_i, [args, _p, _i, _p]),
            "dua_exact_pass": (None, [args, _p, _i, _p]),
            "dua_reset_events": (None, [args]),
        }
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


def _address(array: np.ndarray) -> int:
    if not array.flags.c_contiguous:
        raise ValueError("the native step reads C-contiguous arrays only")  # a bug if raised
    return int(array.ctypes.data)


class NativeStep:
    """The native step's arguments for one predictor, and its entry points.

    ``bind_*`` point the struct at new arrays (keeping them alive); :meth:`step` runs one step.
    ``used`` is the log's next write position.

    Args:
        width: Most alarms a step can raise (the scheduler's work-row width).
    """

    __slots__ = (
        "_address",
        "_keep",
        "_lib",
        "_points",
        "_ref",
        "_run",
        "args",
        "capacity",
        "last_start",
        "log",
        "room",
        "used",
        "view",
    )

    def __init__(self, width: int) -> None:
        self._lib = _functions()
        self.args = _StepArgs()
        self.args.abi = ABI_VERSION
        self._ref = ctypes.byref(self.args)
        self._address = ctypes.addressof(self.args)
        self._run: Callable[[int, int, int], int] = compiled_entry(_run, self._address, 1, 0)  # type: ignore[assignment]
        self._keep: dict[str, object] = {}
        self._points = np.zeros((0, 6))
        self.room = max(int(width), 1)
        # Room for many steps: a full log is replaced, never overwritten.
        self.capacity = max(LOG_STEPS * self.room, LOG_MIN)
        self.last_start = self.capacity - self.room
        """The last position a step may start writing at (``capacity - room``)."""
        self.used = 0
        self.log, self.view = new_log(self.capacity)
        self._bind_log()
        self.bind_scratch(self.room)

    @property
    def address(self) -> int:
        """Address of the ``dua_step_args`` struct (for compiled drivers: benchmarks)."""
        return self._address

    # ----------------------------------------------------------------------- binding

    def _hold(self, name: str, *arrays: object) -> None:
        self._keep[name] = arrays

    def _bind_log(self) -> None:
        pairs, tau, new = self.log
        self.args.log_pairs = _address(pairs)
        self.args.log_tau = _address(tau)
        self.args.log_new = _address(new)
        self._hold("log", self.log)

    def bind_scratch(self, rows: int) -> None:
        """Room to gather ``rows`` pairs' states at a time (the most a step selects)."""
        scratch = np.empty((max(int(rows), 1), 12))
        self.args.scratch = _address(scratch)
        self.args.scratch_rows = scratch.shape[0]
        self._hold("scratch", scratch)

    def bind_schedule(self, state: ScheduleState) -> None:
        """Point the step at a scheduler's state."""
        s = self.args.schedule
        s.kind = int(state.kind)
        s.dt = float(state.dt)
        s.latency = int(state.latency)
        s.m = state.last_tau.shape[0]
        s.last_tau = _address(state.last_tau)
        s.active = _address(state.active)
        s.ints = _address(state.ints)
        s.slots = _address(state.slots)
        s.nslots = state.slots.shape[0]
        s.horizon = _address(state.horizon)
        s.queue = _address(state.queue)
        s.nqueue = state.queue.shape[0]
        s.params = _address(state.params)
        s.work = _address(state.work)
        s.width = state.work.shape[1]
        s.w_tau = _address(state.w_tau)
        self._hold("schedule", state)
        width = state.work.shape[1]
        if width > self.args.scratch_rows:
            self.bind_scratch(width)
        if width > self.room:
            # A step raises at most one alarm per place of the work rows.
            self.room = width
            self.capacity = max(LOG_STEPS * self.room, LOG_MIN)
            self.last_start = self.capacity - self.room
            self.next_log()

    def bind_tables(
        self, pairs: np.ndarray, spheres: np.ndarray, shapes: np.ndarray, ids: np.ndarray
    ) -> None:
        """The held pairs' ``pack_pairs`` records, the sphere and shape records, and the model
        pair id of each held pair (what the log records)."""
        ids = np.ascontiguousarray(ids, dtype=np.int64)
        self.args.pairs = _address(pairs)
        self.args.spheres = _address(spheres)
        self.args.shapes = _address(shapes)
        self.args.ids = _address(ids)
        self._hold("tables", pairs, spheres, shapes, ids)
        # Each sphere's state, read once per batch of pairs (dua.h). A renewal binds tables of
        # the same spheres: the rows stay, their epochs are all past.
        rows = max(spheres.shape[0], 1)
        if self._points.shape[0] != rows:
            self._points = np.zeros((rows, 6))
            epoch = np.full(rows, -1, dtype=np.int64)
            self.args.point_state = _address(self._points)
            self.args.point_epoch = _address(epoch)
            self._hold("points", epoch)

    def bind_frame(self, data: mujoco.MjData, root_twist: np.ndarray) -> None:
        """Read the instant from ``data`` (and the mocap roots' twists ``(nbody, 6)``)."""
        f = self.args.frame
        arrays = (
            data.geom_xpos,
            data.geom_xmat,
            data.cvel,
            data.subtree_com,
            root_twist,
            data.xpos,
        )
        f.pos, f.mat, f.twist, f.twist_ref, f.root_twist, f.root_origin = (
            _address(a) for a in arrays
        )
        self.args.exact.data = data._address
        self._hold("frame", data, *arrays)

    def bind_exact(
        self,
        model: mujoco.MjModel,
        geoms: np.ndarray,
        records: np.ndarray,
        *,
        below: float,
        query_below: float,
        verts: np.ndarray,
        graph: np.ndarray,
    ) -> None:
        """The exact level's tables (``ExactLevel``; ``records`` of the held pairs, written)."""
        x = self.args.exact
        x.on = 1
        x.geoms = _address(geoms)
        x.records = _address(records)
        x.below = float(below)
        x.query_below = float(query_below)
        x.verts = _address(verts)
        x.graph = _address(graph)
        x.model = model._address
        self._hold("exact", model, geoms, records, verts, graph)

    def unbind_exact(self) -> None:
        """No exact level."""
        self.args.exact.on = 0
        self._hold("exact")

    def bind_events(self, events: tuple) -> None:
        """The violation check's tables (``EventTable.args()``; none: ``no_events()``)."""
        # The check writes prev, meta and flagged in place (the predictor reads them): only
        # empty tables, never read, are replaced.
        arrays = [a if a.size else np.zeros(1, a.dtype) for a in events]
        e = self.args.events
        e.nbody = events[0].shape[0]
        e.rec, e.prev, e.meta, e.flagged, e.start, e.members, e.params = (
            _address(a) for a in arrays
        )
        self._hold("events", *arrays)

    # ----------------------------------------------------------------------- running

    def next_log(self) -> int:
        """Replace a log without room for another step's alarms; the new write position (0).

        The old log lives as long as some ``Alarms`` of it does.
        """
        self.log, self.view = new_log(self.capacity)
        self._bind_log()
        self.used = 0
        return 0

    def step(self, n: int) -> tuple[int, int]:
        """Step ``n``: ``(start, result)``, the step's alarms at ``log[start:start + result]``,
        or ``result = -1 - p`` for a held pair ``p`` whose state was not finite (the step was
        undone and nothing was logged)."""
        start = self.used
        if start > self.last_start:
            start = self.next_log()
        result = self._run(self._address, n, start)
        if result >= 0:
            self.used = start + result
        return start, result

    def evaluate(self, ids: np.ndarray) -> tuple[np.ndarray, int]:
        """tau of held pairs ``ids`` at every level, as the step computes it: ``(tau, bad)``,
        ``bad >= 0`` a pair whose state was not finite."""
        idx = np.ascontiguousarray(ids, dtype=np.int64)
        out = np.empty(idx.shape[0])
        bad = self._lib.dua_evaluate(self._ref, _address(idx), idx.shape[0], _address(out))
        return out, int(bad)

    def exact_pass(self, ids: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """The exact level alone on ``tau`` of held pairs ``ids`` (in place; returned)."""
        idx = np.ascontiguousarray(ids, dtype=np.int64)
        self._lib.dua_exact_pass(self._ref, _address(idx), idx.shape[0], _address(tau))
        return tau

    def reset_events(self) -> None:
        """Start the violation check over at the bound frame's instant."""
        self._lib.dua_reset_events(self._ref)
