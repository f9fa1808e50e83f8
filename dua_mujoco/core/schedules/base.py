"""``Scheduler``: the protocol every schedule offers, over the compiled interface in ``kernels``.

Two ways to drive a schedule, with the same results:

- the Python protocol: ``ids = select()``, evaluate tau of ``ids`` however you like, then
  ``update(ids, tau)`` returns the alarmed ids;
- a fused step: ``step_context(kernel, context, *args)`` runs one compiled
  ``kernel(context, n, *args)`` whose ``context`` holds the schedule's state, and that selects,
  evaluates and reinserts (``step_points`` for free spheres; the MuJoCo layer has its own for
  spheres on rigid bodies).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, cast

import numba as nb
import numpy as np
import numpy.typing as npt

from dua_mujoco.core.pairset import PairSet, pair_tau
from dua_mujoco.core.refs import Ref
from dua_mujoco.core.schedules import kernels
from dua_mujoco.core.schedules.state import (
    LAST_STEP,
    P_COUNT,
    P_DEFERRED,
    S_W_TAU,
    S_WORK,
    W_ALARMS,
    W_IDS,
    W_NEW,
    ScheduleState,
)
from dua_mujoco.core.validate import as_ids, check_urgencies
from dua_mujoco.exceptions import InvalidInputError, NonFiniteStateError, SchedulerError, ShapeError

__all__ = ["ContextKernel", "FusedKernel", "Scheduler", "compiled_entry", "step_points_kernel"]

FusedKernel = Callable[..., tuple[int, int, int]]
"""A compiled ``kernel(state, n, *args) -> (count, nalarm, bad)``: ``kernels.select``, tau of the
selected pairs into ``state.w_tau``, ``kernels.reinsert``; ``bad >= 0`` names a pair whose state
was not finite, after ``kernels.restore`` undid the selection."""


@nb.njit(cache=True)
def step_points_kernel(st, n, geometry):  # pragma: no cover - jitted
    """The fused step on free spheres: select, evaluate tau, reinsert (a ``FusedKernel``).

    ``geometry`` is ``pair_tau``'s tuple. A pair whose state is not finite abandons the
    step before anything is reinserted.
    """
    centers, velocities, _, _, first, second, halfspace, _, _, _, _ = geometry
    count = kernels.select(st, n)
    w_ids = st[S_WORK][W_IDS]
    for k in range(count):
        p = w_ids[k]
        i = first[p]
        state = 0.0
        for a in range(3):
            state += centers[i, a] + velocities[i, a]
        if not halfspace[p]:
            j = second[p]
            for a in range(3):
                state += centers[j, a] + velocities[j, a]
        if not math.isfinite(state):
            kernels.restore(st, n, count)
            return count, 0, p
        st[S_W_TAU][k] = pair_tau(p, geometry)
    return count, kernels.reinsert(st, n, count), -1


ContextKernel = Callable[..., tuple]
"""A compiled ``kernel(context, n, *args) -> (nalarm, bad, ...)`` (``Scheduler.step_context``)."""


@nb.njit(cache=True)
def step_points_ref_kernel(
    state_ref, n, centers, velocities, planes, shapes, pairs_ref
):  # pragma: no cover - jitted
    """:func:`step_points_kernel` on a ``Ref`` of the schedule state and one of the pair set's
    arrays (``PairSet.kernel_ref``): six arrays fewer to unbox per call than the tuples. A
    ``ContextKernel``: returns ``(nalarm, bad, count)``."""
    count, nalarm, bad = step_points_kernel(
        state_ref.value, n, (centers, velocities, planes, shapes, *pairs_ref.value)
    )
    return nalarm, bad, count


def compiled_entry(kernel: Any, *args: object) -> Callable[..., tuple]:
    """The compiled entry point of ``kernel`` for arguments of the types of ``args``.

    Calling it skips numba's dispatch (typing every argument, choosing an overload): about a
    microsecond a call, a sizeable part of a step of a few. The caller must pass arguments of
    exactly those types ever after (a ``Predictor`` does: its tables and ``MjData`` views do not
    change type); ``kernel`` itself is returned when it is not a numba dispatcher.
    """
    overloads = getattr(kernel, "overloads", None)
    if overloads is None:
        return cast(Callable[..., tuple], kernel)
    signature = tuple(kernel.typeof_pyval(a) for a in args)
    if signature not in overloads:
        kernel.compile(signature)
    return cast(Callable[..., tuple], overloads[signature].entry_point)


class Scheduler:
    """What DUA, the deadline schedule and select-all have in common.

    Attributes:
        state: The ``ScheduleState`` the compiled kernels read and write.
        initial_alarms: ``(k,)`` pairs the initial classification alarms.
        step_count: Completed steps (0 after the initial classification).
        activation_changes: Calls of :meth:`set_active` that switched some pair, so that an
            observer of :meth:`alarm_state` knows when to read it again.
    """

    def __init__(self, state: ScheduleState, initial_alarms: np.ndarray) -> None:
        self.state = state
        self.initial_alarms = np.asarray(initial_alarms, dtype=np.int64)
        self.step_count = 0
        self.activation_changes = 0
        self._pending: np.ndarray | None = None
        # step_points' compiled entry for each kind of input arrays (their flags), and the
        # arrays of the latest step with theirs.
        self._points_entries: dict[tuple[int, ...], ContextKernel] = {}
        self._points_last: tuple = (None,) * 7
        # The latest step's alarm rows (W_ALARMS, W_NEW) and their count: a copy, or the live
        # work rows after a context step (valid until the next step, which resets both).
        self._last_rows = np.ones((2, self.initial_alarms.shape[0]), dtype=np.int64)
        self._nalarm = int(self.initial_alarms.shape[0])

    @property
    def state(self) -> ScheduleState:
        """The ``ScheduleState`` the compiled kernels read and write."""
        return self._state

    @state.setter
    def state(self, state: ScheduleState) -> None:
        self._state = state
        self._kernel_state = tuple(state)
        self._state_ref: Ref | None = None  # built by step_points when first needed
        # Views read after every step: built once, not at each step (a step is microseconds).
        self._params = state.params
        self._alarm_rows = state.work[W_ALARMS : W_NEW + 1]

    @property
    def kernel_state(self) -> tuple:
        """``tuple(state)``, the form the compiled kernels take (fields at the ``S_*``
        positions): the arrays are shared, so the kernels' writes are the state's."""
        return self._kernel_state

    # ----------------------------------------------------------------------- introspection

    @property
    def npairs(self) -> int:
        """Number of pairs ``M``."""
        return int(self.state.last_tau.shape[0])

    @property
    def dt(self) -> float:
        """Predictor period (seconds)."""
        return self.state.dt

    @property
    def latency(self) -> int:
        """Periods a verdict takes to act."""
        return self.state.latency

    @property
    def active(self) -> np.ndarray:
        """``(M,)`` bool, pairs switched on (read-only view; switch with :meth:`set_active`)."""
        view = self.state.active.view()
        view.flags.writeable = False
        return view

    @property
    def last_tau(self) -> np.ndarray:
        """``(M,)`` tau at each pair's latest evaluation (``-inf``: switched on, not yet)."""
        return self.state.last_tau

    @property
    def last_step(self) -> np.ndarray:
        """``(M,)`` step of each pair's latest evaluation."""
        return self.state.ints[LAST_STEP]

    def tau(self, pair: npt.ArrayLike) -> np.ndarray:
        """tau of each pair at its latest evaluation."""
        return np.asarray(self.state.last_tau[np.asarray(pair)])

    def alarm_state(self, pair: npt.ArrayLike | None = None) -> np.ndarray:
        """Whether each pair stands in alarm: its latest verdict does not cover the time until
        its next one (the alarm rule on its last tau)."""
        idx = np.arange(self.npairs) if pair is None else np.asarray(pair, dtype=np.int64)
        return np.asarray(self.state.last_tau[idx] < self.horizon_of(idx))

    def horizon_of(self, pair: np.ndarray) -> np.ndarray:
        """The alarm horizon (seconds) each pair's latest verdict must cover."""
        return np.full(pair.shape, self.state.horizon[0])

    @property
    def last_selected(self) -> np.ndarray:
        """Pairs whose verdict the latest step renewed: those evaluated (and, for the deadline
        schedule, those due but left for a later step)."""
        if self._pending is not None or self.step_count == 0:
            return self.state.work[W_IDS, :0].copy()
        renewed = int(self._params[P_COUNT] + self._params[P_DEFERRED])
        return self.state.work[W_IDS, :renewed].copy()

    @property
    def deferred(self) -> int:
        """Pairs due at the latest step but left for a later one (a capped deadline schedule)."""
        return int(self.state.params[P_DEFERRED])

    @property
    def evaluations_per_step(self) -> int:
        """tau evaluations of the latest step."""
        return int(self.state.params[P_COUNT])

    def most_urgent(self) -> int:
        """The active pair with the smallest latest tau (-1 if none)."""
        if not self.state.active.any():
            return -1
        return int(np.argmin(np.where(self.state.active, self.state.last_tau, np.inf)))

    # ----------------------------------------------------------------------- switching

    def set_active(self, pairs: npt.ArrayLike, on: bool) -> None:
        """Switch pairs off (intended contact, paper sec. 6.3) or back on.

        A pair switched back on stands in alarm (``last_tau = -inf``) until its first
        evaluation, at the next step: nothing is known of its motion while it was off, and that
        step can be a whole period away (docs/theory.md, "Pairs switched back on").
        """
        if self._pending is not None:
            raise SchedulerError("set_active() between select() and update(): finish the step.")
        ids = as_ids("pairs", np.atleast_1d(np.asarray(pairs, dtype=np.int64)))
        if ids.size and (ids.min() < 0 or ids.max() >= self.npairs):
            raise InvalidInputError(f"pair ids must be in [0, {self.npairs}); got {ids.tolist()}.")
        if kernels.switch(
            self._kernel_state, np.ascontiguousarray(ids), bool(on), self.step_count + 1
        ):
            self.activation_changes += 1

    # ----------------------------------------------------------------------- protocol

    def select(self) -> np.ndarray:
        """Pair ids to evaluate this step (one ``update`` must follow), ``(n,)`` int64."""
        if self._pending is not None:
            raise SchedulerError(
                "select() called twice without update(): evaluate the selected pairs and pass "
                "their tau to update() first."
            )
        count = kernels.select(self._kernel_state, self.step_count + 1)
        self._pending = self.state.work[W_IDS, :count].copy()
        return self._pending.copy()

    def update(self, ids: npt.ArrayLike, tau: npt.ArrayLike) -> np.ndarray:
        """Store the new tau of the pairs selected this step; return the alarmed ids.

        Args:
            ids: ``(n,)`` the ids ``select()`` returned, in any order.
            tau: ``(n,)`` their tau at this step's state.

        Returns:
            ``(k,)`` int64 ids of the pairs that raise an alarm.
        """
        expected = self._pending
        if expected is None:
            raise SchedulerError("update() without select(): call select() first.")
        idx = as_ids("ids", ids)
        t = check_urgencies("tau", tau, idx.shape[0])
        # Select-all hands back its own order: compare directly before sorting.
        same = idx.shape == expected.shape and (
            np.array_equal(idx, expected) or np.array_equal(np.sort(idx), np.sort(expected))
        )
        if not same:
            raise SchedulerError(
                f"update() got ids {idx.tolist()[:16]} but this step selected "
                f"{expected.tolist()[:16]}: pass exactly the ids select() returned."
            )
        count = expected.shape[0]
        # Back to selection order (a pair may be selected twice: then both get its tau).
        self.state.w_tau[np.argsort(expected, kind="stable")] = t[np.argsort(idx, kind="stable")]
        nalarm = kernels.reinsert(self._kernel_state, self.step_count + 1, count)
        self.step_count += 1
        self._pending = None
        # The new flags are read (by last_new) before the next step, if at all: the live rows
        # serve. The caller keeps the ids: a copy, as the next step reuses the row.
        self._last_rows = self._alarm_rows
        self._nalarm = nalarm
        return self._alarm_rows[0, :nalarm].copy()

    def step_context(self, kernel: ContextKernel, context: object, *args: object) -> tuple:
        """Run one compiled step ``kernel(context, n, *args)`` whose ``context`` holds this
        scheduler's :attr:`kernel_state` with whatever else the step reads (a numba
        ``StructRef``: one argument to unbox instead of dozens).

        ``kernel`` returns ``(nalarm, bad, ...)``, its alarms left in the work rows as
        ``kernels.reinsert`` wrote them; ``bad >= 0`` means the step was undone. Returns the
        kernel's tuple; the alarms are the kernel's to hand out (nothing is copied here).
        """
        if self._pending is not None:
            raise SchedulerError("a fused step between select() and update(): finish the step.")
        result = kernel(context, self.step_count + 1, *args)
        if result[1] < 0:
            self.step_count += 1
            self._last_rows = self._alarm_rows
            self._nalarm = result[0]
        return result

    def begin_step(self) -> int:
        """The number of the step a driver outside this class (the native step) is about to
        run on :attr:`state`; refused between :meth:`select` and :meth:`update`."""
        if self._pending is not None:
            raise SchedulerError("a fused step between select() and update(): finish the step.")
        return self.step_count + 1

    def end_step(self, nalarm: int) -> None:
        """Record the step :meth:`begin_step` numbered, its ``nalarm`` alarms in the work rows
        (the native step ran it to completion)."""
        self.step_count += 1
        self._last_rows = self._alarm_rows
        self._nalarm = nalarm

    def step_points(
        self,
        pairs: PairSet,
        centers: npt.ArrayLike,
        velocities: npt.ArrayLike,
        halfspaces: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
    ) -> np.ndarray:
        """One fused step on free spheres: select, evaluate tau, reinsert, alarm.

        Same result as ``update(ids, pairs.tau(ids, ...))`` after ``ids = select()``, in one
        compiled call.

        Args:
            pairs: The pair geometry (``len(pairs) == npairs``).
            centers: ``(nsphere, 3)`` sphere centres at this step.
            velocities: ``(nsphere, 3)`` sphere centre velocities at this step.
            halfspaces: ``(normals (nh, 3), offsets (nh,))`` if any pair is a half-space pair.

        Returns:
            ``(k,)`` int64 ids of the alarmed pairs.
        """
        if self._state_ref is None:
            self._state_ref = Ref(self._kernel_state)
        last = self._points_last
        if (
            centers is last[0]
            and velocities is last[1]
            and halfspaces is None
            and pairs is last[2]
            and pairs.shapes is last[3]
            and centers.shape == last[6]
            and velocities.shape == last[6]
        ):
            # The arrays of the latest step, used as they were (checked then; their dtype
            # cannot change, their shape is compared): the common case, 2 us of checks saved.
            arrays, entry = last[4], last[5]
        else:
            arrays, entry = self._points_inputs(pairs, centers, velocities, halfspaces)
        nalarm, bad, _ = self.step_context(entry, self._state_ref, *arrays)
        if bad < 0:
            return self._alarm_rows[0, :nalarm].copy()
        i, j = int(pairs.first[bad]), int(pairs.second[bad])
        raise NonFiniteStateError(
            f"the state of pair {bad} (spheres {i}, {j}) is not finite: centers or "
            "velocities hold NaN or inf; check that the simulation has not diverged."
        )

    def _points_inputs(
        self,
        pairs: PairSet,
        centers: npt.ArrayLike,
        velocities: npt.ArrayLike,
        halfspaces: tuple[npt.ArrayLike, npt.ArrayLike] | None,
    ) -> tuple[tuple, ContextKernel]:
        """``step_points_ref_kernel``'s arguments after the state and the step (checked) and its
        compiled entry for them, remembered for the next step when the inputs were used as given.

        The entry point skips numba's dispatch (1 us of a step of a few); the arrays' flags
        (read-only, aligned, contiguous) are all that can change their compiled types, since
        ``PairSet.inputs`` fixes their dtypes and shapes.
        """
        if len(pairs) != self.npairs:
            raise ShapeError(f"pairs has {len(pairs)} pairs; the scheduler has {self.npairs}.")
        c, v, planes, shapes = pairs.inputs(centers, velocities, halfspaces, check_finite=False)
        key = (c.flags.num, v.flags.num, planes.flags.num, shapes.flags.num)
        arrays = (c, v, planes, shapes, pairs.kernel_ref)
        entry = self._points_entries.get(key)
        if entry is None:
            entry = compiled_entry(step_points_ref_kernel, self._state_ref, 1, *arrays)
            self._points_entries[key] = entry
        # Converted inputs (lists, other dtypes) are new arrays each step: not remembered.
        if c is centers and v is velocities and halfspaces is None:
            self._points_last = (centers, velocities, pairs, pairs.shapes, arrays, entry, c.shape)
        return arrays, entry

    @property
    def last_new(self) -> np.ndarray:
        """``(k,)`` bool, which of the latest step's alarms are new (see ``W_NEW``)."""
        return self._last_rows[1, : self._nalarm].astype(bool)
