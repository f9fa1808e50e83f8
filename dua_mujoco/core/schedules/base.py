"""``Scheduler``: the protocol every schedule offers, over a ``dua_mujoco._core.Schedule``.

The schedule's state and kernels are the native core's (``csrc/src/schedule.cc``): a
``_core.Schedule`` sizes its buffers, classifies the initial tau, selects, reinserts and
switches; a ``Scheduler`` validates what it is handed, names the errors, and shapes the
results. Two ways to drive one, with the same results:

- the Python protocol: ``ids = select()``, evaluate tau of ``ids`` however you like, then
  ``update(ids, tau)`` returns the alarmed ids;
- the fused step on free spheres, ``step_points``: select, evaluate and reinsert in one native
  call (the MuJoCo layer's runtime steps its own schedule, which :meth:`Scheduler.of` shows).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import numpy.typing as npt

import dua_mujoco._core as _core
from dua_mujoco.core.pairset import PairSet
from dua_mujoco.core.schedules.state import (
    LAST_STEP,
    P_COUNT,
    P_DEFERRED,
    W_ALARMS,
    W_IDS,
    W_NEW,
    ScheduleState,
    state_of,
)
from dua_mujoco.core.validate import as_ids, check_urgencies
from dua_mujoco.exceptions import InvalidInputError, NonFiniteStateError, SchedulerError, ShapeError

__all__ = ["Scheduler", "active_mask", "standing"]


def standing(schedule: _core.Schedule) -> np.ndarray:
    """``(k,)`` the pairs standing in alarm in ``schedule`` now, increasing (its own rule)."""
    m = int(schedule.last_tau.shape[0])
    return np.flatnonzero(_core.stands(schedule, np.arange(m, dtype=np.int64)))


def active_mask(active: npt.ArrayLike | None, m: int) -> np.ndarray | None:
    """``(m,)`` 0/1 bytes of the pairs initially switched on (None: all), for ``_core``."""
    if active is None:
        return None
    mask = np.array(active, dtype=np.bool_)
    if mask.shape != (m,):
        raise ShapeError(f"active has shape {mask.shape}; expected ({m},).")
    return mask.view(np.uint8)


class Scheduler:
    """What DUA, the deadline schedule and select-all have in common.

    Subclasses build their ``_core.Schedule`` (which classifies the initial tau) and wrap it;
    :meth:`of` wraps one that exists already, without classifying again.

    Attributes:
        core: The ``_core.Schedule`` whose state this scheduler drives.
        initial_alarms: ``(k,)`` pairs the initial classification alarms (for :meth:`of`, the
            pairs standing in alarm when wrapped).
    """

    # The subclass of each schedule kind (``class DUAScheduler(Scheduler, kind=RANK)``).
    _KINDS: ClassVar[dict[int, type[Scheduler]]] = {}

    def __init_subclass__(cls, kind: int | None = None, **kwargs: object) -> None:
        super().__init_subclass__(**kwargs)
        if kind is not None:
            Scheduler._KINDS[kind] = cls

    def _wrap(self, schedule: _core.Schedule, initial_alarms: npt.ArrayLike) -> None:
        # The schedule's views, built once: a step is microseconds.
        self.core = schedule
        self._state = state_of(schedule)
        self._params = self._state.params
        self._alarm_rows = self._state.work[W_ALARMS : W_NEW + 1]
        # step_points' native step bound to the latest pairs and checked inputs (see there).
        self._points: tuple = (None,) * 7
        self.initial_alarms = np.asarray(initial_alarms, dtype=np.int64)
        self._pending: np.ndarray | None = None
        self._read_only = False
        # The latest step's alarm rows (W_ALARMS, W_NEW) and their count: the live work rows
        # (valid until the next step, which resets both), or ones for the classification.
        self._last_rows = np.ones((2, self.initial_alarms.shape[0]), dtype=np.int64)
        self._nalarm = int(self.initial_alarms.shape[0])

    @classmethod
    def of(cls, schedule: _core.Schedule, *, read_only: bool = False) -> Scheduler:
        """A scheduler over an existing ``_core.Schedule`` (the predictor's runtime's, say), of
        the subclass of its kind, without classifying again: its steps, counts and verdicts are
        the schedule's (``step_count`` reads it), its ``initial_alarms`` the pairs standing in
        alarm now.

        Args:
            schedule: The schedule to wrap.
            read_only: Refuse every call that steps the schedule or switches its pairs (a view
                of a schedule that another driver steps: a second driver would desynchronise
                the two).
        """
        if not isinstance(schedule, _core.Schedule):
            raise InvalidInputError(
                f"Scheduler.of takes a dua_mujoco._core.Schedule; got {type(schedule).__name__}."
            )
        import dua_mujoco.core.schedules  # noqa: F401 - registers the subclass of every kind

        sub = Scheduler._KINDS[int(schedule.kind)]
        out = sub.__new__(sub)
        out._wrap(schedule, standing(schedule))
        out._read_only = bool(read_only)
        out._derive()
        return out

    def _check_writable(self, call: str) -> None:
        if self._read_only:
            raise SchedulerError(
                f"{call}: this scheduler is read-only, a view of a schedule that its owner "
                "steps (Predictor.scheduler); step and switch pairs through the owner "
                "(Predictor.step, Predictor.set_active_bodies)."
            )

    def _derive(self) -> None:
        """Set the subclass's attributes from the schedule (its options)."""

    @property
    def state(self) -> ScheduleState:
        """The ``ScheduleState``: views of the schedule's buffers, which its kernels write."""
        return self._state

    # ----------------------------------------------------------------------- introspection

    @property
    def step_count(self) -> int:
        """Completed steps (0 after the initial classification): the schedule's own count."""
        return int(self.core.step_count)

    @step_count.setter
    def step_count(self, value: int) -> None:
        self._check_writable("step_count")
        self.core.step_count = int(value)

    @property
    def activation_changes(self) -> int:
        """Calls of :meth:`set_active` that switched some pair (and carries of the pair set),
        so that an observer of :meth:`alarm_state` knows when to read it again."""
        return int(self.core.activation_changes)

    @activation_changes.setter
    def activation_changes(self, value: int) -> None:
        self.core.activation_changes = int(value)

    @property
    def npairs(self) -> int:
        """Number of pairs ``M``."""
        return int(self._state.last_tau.shape[0])

    @property
    def dt(self) -> float:
        """Predictor period (seconds)."""
        return self._state.dt

    @property
    def latency(self) -> int:
        """Periods a verdict takes to act."""
        return self._state.latency

    @property
    def active(self) -> np.ndarray:
        """``(M,)`` bool, pairs switched on (read-only view; switch with :meth:`set_active`)."""
        view = self._state.active.view()
        view.flags.writeable = False
        return view

    @property
    def last_tau(self) -> np.ndarray:
        """``(M,)`` tau at each pair's latest evaluation (``-inf``: switched on, not yet)."""
        return self._state.last_tau

    @property
    def last_step(self) -> np.ndarray:
        """``(M,)`` step of each pair's latest evaluation."""
        return self._state.ints[LAST_STEP]

    def tau(self, pair: npt.ArrayLike) -> np.ndarray:
        """tau of each pair at its latest evaluation."""
        return np.asarray(self._state.last_tau[np.asarray(pair)])

    def alarm_state(self, pair: npt.ArrayLike | None = None) -> np.ndarray:
        """Whether each pair stands in alarm: switched on, and its latest verdict does not cover
        the time until its next one (the schedule's own alarm rule, ``Schedule::Stands``)."""
        idx = np.arange(self.npairs) if pair is None else np.asarray(pair, dtype=np.int64)
        flat = np.ascontiguousarray(idx.reshape(-1))
        return np.asarray(_core.stands(self.core, flat)).reshape(idx.shape)

    def next_due(self, pair: npt.ArrayLike) -> np.ndarray:
        """The step each pair is next evaluated at if it stays switched on (-1: a deadline pair
        switched off), shaped like ``pair``."""
        p = np.asarray(pair, dtype=np.int64)
        return np.asarray(self.core.next_due(np.ascontiguousarray(p.reshape(-1)))).reshape(p.shape)

    def horizon_of(self, pair: npt.ArrayLike) -> np.ndarray:
        """The alarm horizon (seconds) each pair's latest verdict must cover (``-inf`` for a
        deadline pair switched off: its verdict covers nothing), shaped like ``pair``."""
        p = np.asarray(pair, dtype=np.int64)
        flat = np.ascontiguousarray(p.reshape(-1))
        return np.asarray(self.core.horizon_of(flat)).reshape(p.shape)

    @property
    def last_selected(self) -> np.ndarray:
        """Pairs whose verdict the latest step renewed: those evaluated (and, for the deadline
        schedule, those due but left for a later step). Not the pairs of flagged bodies a
        predictor's step settled by a bound (``PairState.last_selected`` lists those too)."""
        if self._pending is not None or self.step_count == 0:
            return self._state.work[W_IDS, :0].copy()
        renewed = int(self._params[P_COUNT] + self._params[P_DEFERRED])
        return self._state.work[W_IDS, :renewed].copy()

    @property
    def deferred(self) -> int:
        """Pairs due at the latest step but left for a later one (a capped deadline schedule)."""
        return int(self._params[P_DEFERRED])

    @property
    def evaluations_per_step(self) -> int:
        """tau evaluations of the latest step."""
        return int(self._params[P_COUNT])

    def most_urgent(self) -> int:
        """The active pair with the smallest latest tau (-1 if none)."""
        active = self._state.active
        if not active.any():
            return -1
        return int(np.argmin(np.where(active, self._state.last_tau, np.inf)))

    # ----------------------------------------------------------------------- switching

    def set_active(self, pairs: npt.ArrayLike, on: bool) -> None:
        """Switch pairs off (intended contact, paper sec. 6.3) or back on.

        A pair switched back on stands in alarm (``last_tau = -inf``) until its first
        evaluation, at the next step: nothing is known of its motion while it was off, and that
        step can be a whole period away (docs/theory.md, "Pairs switched back on").
        """
        self._check_writable("set_active()")
        if self._pending is not None:
            raise SchedulerError("set_active() between select() and update(): finish the step.")
        ids = as_ids("pairs", np.atleast_1d(np.asarray(pairs, dtype=np.int64)))
        # The schedule checks the ids (naming one out of range) and counts the switches that
        # changed some pair (activation_changes).
        self.core.switch(ids, bool(on), self.step_count + 1)

    # ----------------------------------------------------------------------- protocol

    def select(self) -> np.ndarray:
        """Pair ids to evaluate this step (one ``update`` must follow), ``(n,)`` int64."""
        self._check_writable("select()")
        if self._pending is not None:
            raise SchedulerError(
                "select() called twice without update(): evaluate the selected pairs and pass "
                "their tau to update() first."
            )
        count = self.core.select(self.step_count + 1)
        self._pending = self._state.work[W_IDS, :count].copy()
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
        self._state.w_tau[np.argsort(expected, kind="stable")] = t[np.argsort(idx, kind="stable")]
        nalarm = self.core.reinsert(self.step_count + 1, count)
        self.core.step_count += 1
        self._pending = None
        # The new flags are read (by last_new) before the next step, if at all: the live rows
        # serve. The caller keeps the ids: a copy, as the next step reuses the row.
        self._last_rows = self._alarm_rows
        self._nalarm = nalarm
        return self._alarm_rows[0, :nalarm].copy()

    def step_points(
        self,
        pairs: PairSet,
        centers: npt.ArrayLike,
        velocities: npt.ArrayLike,
        halfspaces: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
    ) -> np.ndarray:
        """One fused step on free spheres: select, evaluate tau, reinsert, alarm.

        Same result as ``update(ids, pairs.tau(ids, ...))`` after ``ids = select()``, in one
        native call.

        Args:
            pairs: The pair geometry (``len(pairs) == npairs``).
            centers: ``(nsphere, 3)`` sphere centres at this step.
            velocities: ``(nsphere, 3)`` sphere centre velocities at this step.
            halfspaces: ``(normals (nh, 3), offsets (nh,))`` if any pair is a half-space pair.

        Returns:
            ``(k,)`` int64 ids of the alarmed pairs.
        """
        self._check_writable("step_points()")
        if self._pending is not None:
            raise SchedulerError("a fused step between select() and update(): finish the step.")
        last = self._points
        if (
            centers is last[0]
            and velocities is last[1]
            and halfspaces is None
            and pairs is last[2]
            and pairs.shapes is last[3]
            and np.shape(centers) == last[4]
            and np.shape(velocities) == last[4]
        ):
            # The arrays of the latest step, checked then and used as they were (shapes
            # compared: they can change in place): the common case, a few us of checks saved.
            step, c, v = last[5], centers, velocities
        else:
            step, c, v = self._points_step(pairs, centers, velocities, halfspaces)
        r = step.step(c, v)
        if r >= 0:
            self._last_rows = self._alarm_rows
            self._nalarm = r
            return self._alarm_rows[0, :r].copy()
        bad = -1 - r
        i, j = int(pairs.first[bad]), int(pairs.second[bad])
        raise NonFiniteStateError(
            f"the state of pair {bad} (spheres {i}, {j}) is not finite: centers or "
            "velocities hold NaN or inf; check that the simulation has not diverged."
        )

    def _points_step(
        self,
        pairs: PairSet,
        centers: npt.ArrayLike,
        velocities: npt.ArrayLike,
        halfspaces: tuple[npt.ArrayLike, npt.ArrayLike] | None,
    ) -> tuple[_core.FreeStep, np.ndarray, np.ndarray]:
        """The native step bound to ``pairs`` (made again when the pairs, their shapes or the
        half-spaces change) and the checked states; remembered when used as given."""
        if len(pairs) != self.npairs:
            raise ShapeError(f"pairs has {len(pairs)} pairs; the scheduler has {self.npairs}.")
        c, v, planes, shapes = pairs.inputs(centers, velocities, halfspaces, check_finite=False)
        last = self._points
        step = last[5]
        if step is None or halfspaces is not None or pairs is not last[2] or shapes is not last[6]:
            step = _core.FreeStep(self.core, pairs.records, planes, shapes)
        if c is centers and v is velocities and halfspaces is None:
            self._points = (centers, velocities, pairs, pairs.shapes, c.shape, step, shapes)
        return step, c, v

    @property
    def last_new(self) -> np.ndarray:
        """``(k,)`` bool, which of the latest step's alarms are new (see ``W_NEW``)."""
        return self._last_rows[1, : self._nalarm].astype(bool)
