"""``Predictor``: MuJoCo state in, collision alarms out.

The model and the options become tables once (``runtime/table_arrays.py``: the covering,
MuJoCo's collision filter, the sphere pairs and their bounds, declared or measured by a pilot
rollout); the native core runs the predictor on them (``dua_mujoco._core.Runtime``, the same
runtime the MuJoCo plugin runs inside ``mj_step``): ``reset(data)`` is the initial
classification, each ``step(data)`` one call into it.

Timing. Call ``step`` every ``period`` physics steps, after ``mj_step``. ``MjData`` then holds the
kinematics (``geom_xpos``, ``cvel``) and contacts of the state at the start of that step, and the
predictor uses that one instant throughout (docs/discrete-time.md).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Literal, TypeVar

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco import _core
from dua_mujoco.build.bounds import MotionBounds, resolve_bounds
from dua_mujoco.build.events import EventTable
from dua_mujoco.build.exact import ExactLevel
from dua_mujoco.build.filter import GeomPairs, SpherePairs, body_id
from dua_mujoco.build.kinematics import mjdata_frame, sphere_states
from dua_mujoco.build.mocap import PredictorMocap
from dua_mujoco.build.pruning import Reach
from dua_mujoco.build.tables import (
    PairTables,
    check_data,
    check_forwarded,
    check_static_geoms,
    plane_halfspaces,
)
from dua_mujoco.core.pairset import PairSet
from dua_mujoco.core.schedules import Scheduler, as_schedule
from dua_mujoco.core.spheres import runtime_count
from dua_mujoco.exceptions import NoActivePairsWarning, NonFiniteStateError, SchedulerError
from dua_mujoco.runtime.alarms import Alarms
from dua_mujoco.runtime.diagnostics import clock_error, nonfinite_error
from dua_mujoco.runtime.flightplan import PlanFollowing
from dua_mujoco.runtime.pairstate import PairState
from dua_mujoco.runtime.table_arrays import LayoutOptions, build, layout, measure_pilot

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = ["BoundsLike", "Predictor"]

T = TypeVar("T")

BoundsLike = float | Mapping[str, float] | MotionBounds | Literal["auto"]
"""Acceleration bounds: a scalar (m/s^2, every moving body), a dict by body name (``"*"`` for
the rest), ready ``MotionBounds``, or ``"auto"`` (estimated by a pilot rollout)."""

LOG_STEPS = 4
"""The alarm log holds at least this many steps' worth of the most alarms a step can raise..."""
LOG_MIN = 1 << 14
"""...and at least this many entries: ``Alarms`` are views of it, never copied; a full log is
replaced, never overwritten, so an old ``Alarms`` keeps its values."""


class Predictor(PlanFollowing):
    """DUA collision predictor for a MuJoCo model.

    The keywords from ``period`` to ``pairs`` are ``LayoutOptions``
    (``runtime/table_arrays.py``): :func:`~dua_mujoco.runtime.table_arrays.layout` checks them
    and holds their defaults, for this constructor and ``pilot_bounds`` alike.

    Args:
        accel: Acceleration bounds (``BoundsLike``); ``"auto"`` runs a pilot rollout
            (``pilot``; ``pilot_bounds(model, **options)`` is the same call) and multiplies the
            measured maxima by its ``safety``. They bound every point of each body's geoms (the
            exact level reads them so).
        speed: Optional speed bounds (scalar or dict by body name), ignored for ready
            ``MotionBounds``.
        velocity_accel: Bound ``C`` on the centripetal/Coriolis acceleration of sphere centres,
            for the discrete-time term (docs/discrete-time.md); scalar or dict by body name.
        period: Physics steps between predictor steps (``>= 1``); the predictor period is
            ``period * model.opt.timestep``.
        latency: Periods a verdict takes to act. 0 (the default) is right when ``step`` runs
            synchronously after ``mj_step``; 1 when the alarms act one period late (the paper's).
        alarm_horizon: Seconds of warning (None: one predictor period). A pair stands in alarm
            when it may collide within the alarm horizon (after the latency): while the bounds
            hold, every collision is flagged at least this long before its first state in
            contact (docs/theory.md, section 3). Rounded up to whole predictor periods.
        covering: ``CoveringOptions``, a mode (``"bounding"``, ``"multi"``), or a ready
            ``Covering``.
        schedule: ``ScheduleOptions`` or a ``Schedule`` (``"deadline"``, the default: each pair
            when its own tau runs out; ``"dua"``, the paper's; ``"select-all"``). See
            docs/theory.md.
        urgency: ``UrgencyOptions``: the exact level (on by default) and its threshold.
        pilot: ``PilotOptions`` of ``accel="auto"``'s pilot rollout.
        pairs: ``PairOptions`` or a mode: ``"all"`` holds every active sphere pair, ``"pruned"``
            the pairs whose reachable balls meet within a horizon (deadline schedule only;
            docs/many-objects.md), ``"auto"`` (default) prunes from 256 covering spheres on.
            Alarms name sphere pairs by their id among all active pairs either way;
            :attr:`held_pairs` maps the schedule's ids to them.

    Raises:
        InvalidInputError: A keyword of the flat options of earlier releases (the message names
            the option group it moved to), or an invalid value.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        *,
        accel: BoundsLike = "auto",
        speed: float | Mapping[str, float] | None = None,
        velocity_accel: float | Mapping[str, float] | None = None,
        **options: Unpack[LayoutOptions],
    ) -> None:
        lay = layout(model, **options)
        self.model = model
        self.period, self.dt, self.latency = lay.period, lay.dt, lay.latency
        self.alarm_periods = lay.alarm_periods
        """The alarm horizon in predictor periods (1 by default)."""
        self.alarm_horizon = self.alarm_periods * self.dt
        """The alarm horizon (seconds): every collision is flagged at least this long before its
        first state in contact while the bounds hold. The runtime's tables carry it as is."""
        self.options = lay.options
        """The option groups in force (``PredictorOptions``)."""
        self.schedule = as_schedule(self.options.schedule.kind)
        self.covering = lay.covering
        self.universe = lay.universe
        """The sphere pairs this predictor knows and their tables (a pruned one learns the
        pairs its candidates bring in)."""
        if self.universe.empty():
            warnings.warn(
                "the model has no geom pair MuJoCo could ever put in contact (no collidable "
                "geoms, one geom only, or every pair filtered out by contype/conaffinity, "
                "parent-child or <exclude>): the predictor will never raise an alarm.",
                NoActivePairsWarning,
                stacklevel=2,
            )
        self.bound_points: tuple[np.ndarray, np.ndarray, np.ndarray] = lay.points
        """``(geom, body, offset)`` of the points whose motion the bounds limit: the corners of
        one box a body around its covering spheres' centres and the exact level's geoms (the
        bounds then hold for every point inside, docs/theory.md, section 6). What the pilot
        (``pilot_bounds``) measures, ``BoundMonitor`` checks, and the step checks before each
        selection."""
        self.bounds = (
            measure_pilot(lay, speed)
            if isinstance(accel, str) and accel == "auto"
            else resolve_bounds(model, accel, speed=speed, velocity_accel=velocity_accel)
        )
        self.mocap: PredictorMocap | None = (
            PredictorMocap(model, lambda: self._rt) if model.nmocap else None
        )
        """Velocities of mocap bodies (None without mocap bodies): ``set_velocity`` to give
        them instead of differencing."""
        built = build(lay, self.bounds, mocap=self.mocap)
        self._shapes, self._spheres = built.shapes, built.spheres
        self.events: EventTable | None = built.events
        """The violation check's tables (None when ``violation_events`` is off)."""
        self.reach: Reach | None = built.reach
        """Pruned pairs: what their reach is made of (None when every pair is held)."""
        self.table_arrays = built.arrays
        """The tables the native runtime reads, by name (``runtime/table_arrays.py``)."""
        tables = _core.Tables.build(model, self.table_arrays)
        self._held_ids: tuple[tuple[int, int], np.ndarray] | None = None
        self._rt = _core.Runtime(
            tables, model, list(self.universe.tables.geom_names), LOG_STEPS, LOG_MIN
        )
        self.universe.attach(self._rt)
        self._data: mujoco.MjData | None = None
        self._scheduler: Scheduler | None = None
        self._steps_at_reset = 0
        self.resets = 0
        """Classifications so far (each ``reset``)."""

    # ----------------------------------------------------------------------- state

    def check_data(self, data: mujoco.MjData) -> None:
        """Refuse anything but an ``MjData`` of this predictor's model (or of one with the same
        geometry, e.g. the same XML loaded twice)."""
        check_data(self.model, data)

    def _bind(self, data: mujoco.MjData) -> None:
        """Read the state from ``data`` from now on (checked: the runtime reads it by index)."""
        self.check_data(data)
        self._rt.bind(data)
        self._data = data

    def sphere_states(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """Centres and velocities of every covering sphere, ``(nsphere, 3)`` each: the step's
        kinematics kernel, with the mocap twists of the latest step."""
        nbody = self.model.nbody
        twist = np.zeros((nbody, 6)) if self.mocap is None else self.mocap.body_velocity(nbody)
        return sphere_states(self._spheres, mjdata_frame(data, twist))

    def halfspaces(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """Plane half-spaces: outward normals ``(nplane, 3)`` and offsets ``(nplane,)``."""
        return plane_halfspaces(data, np.asarray(self.covering.plane_geom, dtype=np.int64))

    def _nonfinite(self, data: mujoco.MjData, pair: int | None = None) -> NonFiniteStateError:
        tables = self.tables
        if pair is not None:
            geoms = {int(tables.geom1[pair]), int(tables.geom2[pair])}
        else:
            c, v = self.sphere_states(data)
            bad = ~(np.isfinite(c).all(axis=1) & np.isfinite(v).all(axis=1))
            geoms = set(self.covering.sphere_geom[bad].tolist()[:5])
        return nonfinite_error(self.model, data, tables.geom_names, geoms)

    def _step_error(self, data: mujoco.MjData, error: BaseException) -> Exception:
        """The error a failed native step stands for (``_core.StepError``'s ``(kind, value)``)."""
        kind, value = error.args
        if kind == "unclassified":
            return SchedulerError("step() before reset(): call predictor.reset(data) first.")
        if kind == "clock":
            expected = self._steps_at_reset + self.period * (self._rt.step_count + 1)
            return clock_error(data, expected, float(value), self.period, self.dt)
        return self._nonfinite(data, None if kind == "state" else int(value))

    # ----------------------------------------------------------------------- protocol

    def reset(self, data: mujoco.MjData) -> Alarms:
        """Initial classification: tau of every active pair, scheduled (O(pairs)).

        Args:
            data: ``MjData`` with valid kinematics (after ``mj_forward`` or ``mj_step``).

        Returns:
            The alarms of the initial classification.

        Raises:
            InvalidInputError: ``data`` is not an MjData of this predictor's model, or its
                kinematics were never computed, or a static geom is not where the model puts
                it, or the model's static geoms moved since the predictor was built.
            NonFiniteStateError: a position or velocity is NaN or inf.
        """
        self._bind(data)
        check_forwarded(self.model, data)
        c, v = self.sphere_states(data)
        # qpos/qvel too: a NaN written without mj_forward leaves finite (stale) kinematics.
        finite = np.isfinite(c).all() and np.isfinite(v).all()
        if not (finite and np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()):
            raise self._nonfinite(data)
        check_static_geoms(
            self.model,
            self.covering.shape_geom,
            data,
            self.table_arrays["static"],
        )
        try:
            alarms: Alarms = self._rt.classify()
        except _core.StepError as error:
            raise self._step_error(data, error) from None
        self._steps_at_reset = int(data.timer[int(mujoco.mjtTimer.mjTIMER_STEP)].number)
        self.resets += 1
        return alarms

    def step(self, data: mujoco.MjData) -> Alarms:
        """One predictor step: evaluate the pairs due, reschedule them, return the alarms.

        One call into the native runtime, which checks the clock (``data.time`` one predictor
        period after the last call), differences the mocap poses, renews pruned pairs, runs the
        violation check, evaluates and reschedules.

        Raises:
            SchedulerError: ``reset`` was not called, or ``data.time`` did not advance by one
                predictor period since the previous call.
            NonFiniteStateError: the state read for a pair due is NaN or inf, or MuJoCo reset the
                state after the simulation diverged.
            InvalidInputError: ``data`` is not an MjData of this predictor's model.
        """
        alarms: Alarms = self._native_step(data, self._rt.step)
        return alarms

    def _native_step(self, data: mujoco.MjData, step: Callable[..., T], *args: Any) -> T:
        """``step(*args)``, a native step of the runtime (``step``; the gym wrapper's
        ``step_info``), on ``data`` (bound first if it is new), with its failure raised as the
        error it stands for."""
        if data is not self._data:
            self._bind(data)
        try:
            return step(*args)
        except _core.StepError as error:
            raise self._step_error(data, error) from None

    # ----------------------------------------------------------------------- intended contact

    def set_active_bodies(
        self, body_a: int | str, body_b: int | str | None = None, *, on: bool
    ) -> int:
        """Switch the pairs between two bodies (or of one body) off or back on (paper sec. 6.3).

        Use it while contact is intended (a grasp, a box resting on a table). Returns the number
        of sphere pairs switched. Pairs switched back on stand in alarm until the next ``step``
        evaluates them (``pair_state().alarm_state``): their motion while off is unknown, and
        with ``period > 1`` that step can be a whole period away; treat the two bodies as
        alarmed until then.
        """
        self._require_reset()
        a = body_id(self.model, body_a)
        b = -1 if body_b is None else body_id(self.model, body_b)
        ids = self._rt.pairs_between_bodies(a, b)
        self._rt.switch(ids, bool(on))
        return int(ids.size)

    def deactivate_contacts(self, data: mujoco.MjData) -> int:
        """Switch off the sphere pairs of every geom pair in contact in ``data`` (resting contact).

        Returns the number of geom pairs switched off. They stay off, whatever happens to the
        contact, until switched back on with :meth:`set_active_bodies` (e.g. when the object is
        lifted or pushed away); until then their contacts are counted apart, never predicted.
        """
        self._require_reset()
        if data is not self._data:
            self._bind(data)
        return int(self._rt.deactivate_contacts())

    def geom_pair_ids(self, g1: npt.ArrayLike, g2: npt.ArrayLike) -> np.ndarray:
        """Ids of the active geom pairs ``{g1[k], g2[k]}``, -1 where MuJoCo's filter rejects
        the pair; a pruned predictor learns the active ones it has not met (the exact stage
        asks for every contact)."""
        a = np.asarray(g1, dtype=np.int64).reshape(-1)
        b = np.asarray(g2, dtype=np.int64).reshape(-1)
        return np.asarray(self._rt.geom_pair_ids(a, b))

    # ----------------------------------------------------------------------- what it holds

    def _require_reset(self) -> None:
        if not self._rt.classified and self.resets == 0:
            raise SchedulerError("call predictor.reset(data) first.")

    @property
    def scheduler(self) -> Scheduler | None:
        """The schedule the runtime runs now, as a ``Scheduler`` (read it, do not step it;
        None before ``reset``). A reset and, with pruned pairs, a rebuild replace it."""
        if self.resets == 0:
            return None
        core = self._rt.schedule
        if self._scheduler is None or self._scheduler.core is not core:
            self._scheduler = Scheduler.of(core, read_only=True)
        return self._scheduler

    def pair_state(self) -> PairState:
        """The schedule's state of every sphere pair, by the model's pair ids (pruned or not)."""
        self._require_reset()
        # The held ids are copied out of the runtime only when its held set changed (the monitor
        # asks for the state several times a step; each copy was O(held pairs)).
        version = (self._rt.held_version, self._rt.universe_version)
        if self._held_ids is None or self._held_ids[0] != version:
            self._held_ids = (version, np.asarray(self._rt.ids))
        return PairState(self._rt, self.universe, held=self._held_ids[1])

    @property
    def geom_pairs(self) -> GeomPairs:
        """The known active geom pairs (all of them unless pruned: ``universe``)."""
        return self.universe.geom_pairs

    @property
    def sphere_pairs(self) -> SpherePairs:
        """The known sphere pairs, grouped by geom pair."""
        return self.universe.sphere_pairs

    @property
    def tables(self) -> PairTables:
        """Sphere pair ids to geoms and names."""
        return self.universe.tables

    @property
    def exact(self) -> ExactLevel | None:
        """The exact level's tables (None when off)."""
        return self.universe.exact

    @property
    def pair_set(self) -> PairSet:
        """The known pairs with their bounds."""
        pairs = self.universe.pair_set
        assert pairs is not None
        return pairs

    @property
    def pair_records(self) -> np.ndarray:
        """``(nsphere_pairs, 8)`` packed records of the known sphere pairs (``pack_pairs``)."""
        return self.universe.records

    @property
    def shape_records(self) -> np.ndarray:
        """``(nshape, 16)`` records of the static shapes (``core.shapes``)."""
        return self._shapes

    @property
    def held_pairs(self) -> np.ndarray:
        """``(K,)`` id among all active sphere pairs of each of the schedule's pairs."""
        return np.asarray(self._rt.ids)

    @property
    def stride(self) -> int:
        """Predictor steps between rebuilds of the held pairs (0: every pair held)."""
        return 0 if self.reach is None else self.reach.stride

    rebuilds = runtime_count("rebuilds", "Rebuilds of the held pairs so far (pruned pairs only).")
    renewals = runtime_count(
        "renewals", "Renewals of escaped spheres' pairs so far (pruned pairs only)."
    )

    @property
    def nsphere(self) -> int:
        """Number of covering spheres."""
        return int(self.covering.nsphere)

    nsphere_pairs = runtime_count("npair", "Number of known sphere pairs.")

    @property
    def evaluations_per_step(self) -> int:
        """tau evaluations of the latest step (every held pair at a classification)."""
        self._require_reset()
        return int(self._rt.evaluated)

    @property
    def sphere_pair_geoms(self) -> tuple[np.ndarray, np.ndarray]:
        """``(geom1, geom2)``, each ``(nsphere_pairs,)``: the geoms of every sphere pair
        (``geom2`` is the plane geom of half-space pairs, the static geom of shape pairs)."""
        return self.tables.geom1, self.tables.geom2

    @property
    def violated_bodies(self) -> np.ndarray:
        """``(k,)`` ids of the bodies whose motion broke their bounds over the latest step's
        period: every pair of theirs was evaluated again at that step (empty when
        ``violation_events`` is off)."""
        self._require_reset()
        return np.asarray(self._rt.flagged_bodies)

    @property
    def violation_events(self) -> int:
        """Body-steps whose bounds broke since the reset, as the step saw them."""
        self._require_reset()
        return int(self._rt.violation_events)
