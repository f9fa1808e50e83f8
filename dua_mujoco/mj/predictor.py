"""``Predictor``: MuJoCo state in, collision alarms out.

The model is read once: geoms are covered by spheres (``covering``), MuJoCo's collision filter
gives the active geom pairs (``filter``), and those expand into sphere pairs with per-pair contact
distance, acceleration bound and velocity uncertainty. ``reset(data)`` is the initial
classification; each ``step(data)`` evaluates the scheduled pairs in one call of the native core
that reads only their spheres from ``MjData`` (``NativeStep``: the step the MuJoCo plugin runs).

Timing. Call ``step`` every ``period`` physics steps, after ``mj_step``. ``MjData`` then holds the
kinematics (``geom_xpos``, ``cvel``) and contacts of the state at the start of that step, and the
predictor uses that one instant throughout (docs/discrete-time.md).
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Mapping
from typing import Literal

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco.core.schedules import (
    DeadlineScheduler,
    Schedule,
    Scheduler,
    as_schedule,
    make_scheduler,
)
from dua_mujoco.core.spheres import PairMode
from dua_mujoco.core.validate import check_period
from dua_mujoco.exceptions import (
    InvalidInputError,
    NoActivePairsWarning,
    NonFiniteStateError,
    SchedulerError,
)
from dua_mujoco.mj.alarms import Alarms
from dua_mujoco.mj.bounds import MotionBounds, resolve_bounds
from dua_mujoco.mj.covering import Covering, CoveringMode, cover_model
from dua_mujoco.mj.diagnostics import clock_error, nonfinite_error
from dua_mujoco.mj.events import (
    M_COUNT,
    EventTable,
    body_boxes,
    build_events,
    no_events,
)
from dua_mujoco.mj.exact import EXACT_PERIODS, QUERY_PERIODS
from dua_mujoco.mj.filter import (
    body_id,
    pairs_between_bodies,
    sphere_pair_mask,
)
from dua_mujoco.mj.kinematics import mjdata_frame, pack_spheres, sphere_states
from dua_mujoco.mj.mocap import MocapVelocityTracker
from dua_mujoco.mj.native_step import NativeStep
from dua_mujoco.mj.options import (
    CoveringOptions,
    PairOptions,
    PilotOptions,
    ScheduleOptions,
    UrgencyOptions,
    removed_keywords_error,
    resolve_options,
)
from dua_mujoco.mj.pairbounds import body_vel_uncertainty
from dua_mujoco.mj.pairstate import PairState
from dua_mujoco.mj.predictor_views import PredictorViews
from dua_mujoco.mj.pruning import RENEW_MAX, HeldPairs, held_pairs_for, resolve_pair_mode
from dua_mujoco.mj.tables import (
    check_data,
    check_forwarded,
    plane_halfspaces,
    static_shapes,
)
from dua_mujoco.mj.universe import PairUniverse

_NONE = np.zeros(0, dtype=np.int64)

__all__ = ["BoundsLike", "Predictor"]

BoundsLike = float | Mapping[str, float] | MotionBounds | Literal["auto"]
"""Acceleration bounds: a scalar (m/s^2, every moving body), a dict by body name (``"*"`` for
the rest), ready ``MotionBounds``, or ``"auto"`` (estimated by a pilot rollout)."""


class Predictor(PredictorViews):
    """DUA collision predictor for a MuJoCo model.

    Args:
        model: The MuJoCo model.
        accel: Acceleration bounds (``BoundsLike``); ``"auto"`` runs a pilot rollout
            (``pilot``) and multiplies the measured maxima by its ``safety``. They bound every
            point of each body's geoms (the exact level reads them so).
        speed: Optional speed bounds (scalar or dict by body name), ignored for ready
            ``MotionBounds``.
        velocity_accel: Bound ``C`` on the centripetal/Coriolis acceleration of sphere centres,
            for the discrete-time term (docs/discrete-time.md); scalar or dict by body name.
        period: Physics steps between predictor steps (``>= 1``); the predictor period is
            ``period * model.opt.timestep``.
        latency: Periods a verdict takes to act. 0 (the default) is right when ``step`` runs
            synchronously after ``mj_step``; 1 when the alarms act one period late (the paper's).
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
            :attr:`held_pairs` maps the scheduler's ids to them.

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
        period: int = 1,
        latency: int = 0,
        covering: Covering | CoveringOptions | CoveringMode | str = "bounding",
        schedule: ScheduleOptions | Schedule | str = Schedule.DEADLINE,
        urgency: UrgencyOptions = UrgencyOptions(),
        pilot: PilotOptions = PilotOptions(),
        pairs: PairOptions | PairMode | str = "auto",
        **removed: object,
    ) -> None:
        if removed:
            raise removed_keywords_error(removed)
        if not isinstance(model, mujoco.MjModel):
            raise InvalidInputError(
                f"model must be a mujoco.MjModel, got {type(model).__name__}: load it with "
                "mujoco.MjModel.from_xml_path(path) (or dua_mujoco.load_scene(name))."
            )
        if isinstance(period, bool) or not isinstance(period, int | np.integer) or period < 1:
            raise InvalidInputError(f"period = {period!r} is invalid: it must be an int >= 1.")
        self.model = model
        self.period = int(period)
        # Validate the scheduler options now rather than at reset(): same checks, same messages.
        self.dt, self.latency = check_period(self.period * float(model.opt.timestep), latency)
        self.options = resolve_options(covering, schedule, urgency, pilot, pairs)
        """The option groups in force (``PredictorOptions``)."""
        sched = self.options.schedule
        self.schedule = as_schedule(sched.kind)
        self.slots_per_bucket = sched.slots_per_bucket
        self.max_evals_per_step = sched.max_evals_per_step
        self.alarm_backoff = sched.alarm_backoff
        cover = self.options.covering
        self.covering = (
            covering
            if isinstance(covering, Covering)
            else cover_model(
                model,
                mode=cover.mode,
                max_spheres_per_geom=cover.max_spheres_per_geom,
                hfield=cover.hfield,
                static=cover.static,
            )
        )
        cov = self.covering
        self._mode = resolve_pair_mode(
            self.options.pairs.mode,
            self.options.pairs.horizon,
            deadline=self.schedule is Schedule.DEADLINE,
            covering=cov,
        )
        exact = None
        if self.options.urgency.exact:
            below = self.options.urgency.exact_below
            below = (EXACT_PERIODS + self.latency) * self.dt if below is None else below
            exact = (below, (QUERY_PERIODS + self.latency) * self.dt)
        self.universe = PairUniverse(model, cov, lazy=self._mode is PairMode.PRUNED, exact=exact)
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
        spheres = (cov.sphere_geom, cov.sphere_body, cov.sphere_offset)
        if self.exact is not None:
            spheres = self.exact.with_corners(model, spheres, self.universe.exact_geoms())
        boxes = body_boxes(model, spheres)
        self.bound_points: tuple[np.ndarray, np.ndarray, np.ndarray] = boxes.corners()
        """``(geom, body, offset)`` of the points whose motion the bounds limit: the corners of
        one box a body around its covering spheres' centres and the exact level's geoms (the
        bounds then hold for every point inside, docs/theory.md, section 6). What the pilot
        measures, ``BoundMonitor`` checks, and the step checks before each selection."""
        self.bounds = resolve_bounds(
            model,
            accel,
            speed=speed,
            velocity_accel=velocity_accel,
            spheres=self.bound_points,
            pilot_steps=self.options.pilot.steps,
            pilot_seed=self.options.pilot.seed,
            pilot_controller=self.options.pilot.controller,
            safety=self.options.pilot.safety,
            pilot_motion=self.options.pilot.motion,
        )
        self.mocap: MocapVelocityTracker | None = (
            MocapVelocityTracker(model) if model.nmocap else None
        )
        """Velocities of mocap bodies (None without mocap bodies): ``set_velocity`` to give
        them instead of differencing."""
        # Static shape records: their poses are model constants (static_shapes), re-packed and
        # checked against the data at each reset.
        self._shapes = static_shapes(model, cov.shape_geom)
        self.universe.bind(self.bounds, period=self.period, mocap=self.mocap, shapes=self._shapes)
        self.events: EventTable | None = (
            build_events(model, boxes, self.bounds, period=self.period)
            if sched.violation_events
            else None
        )
        """The violation check's tables (None when ``violation_events`` is off)."""
        self._events = no_events()
        if self.events is not None:
            self.events.hold(self.tables.geom1, self.tables.geom2)
            self._events = self.events.args()
        self._plane_geom = np.asarray(cov.plane_geom, dtype=np.int64)
        self._spheres = pack_spheres(
            cov.sphere_geom, cov.sphere_body, cov.sphere_offset, model.body_rootid
        )
        self._exact_records = None if self.exact is None else self.exact.records
        # Mocap roots' twists, rewritten each step (zero throughout in a model without mocap).
        self._twist = np.zeros((model.nbody, 6))
        self.scheduler: Scheduler | None = None
        self._pair_state: PairState | None = None
        self._pair_state_seen: tuple = ()
        # The native step's arguments and the alarm log it appends to (made at reset).
        self._native: NativeStep | None = None
        self._time = 0.0
        self._steps_at_reset = 0
        self._frame_data: mujoco.MjData | None = None
        self._frame_cache: tuple = ()
        # stride: predictor steps between rebuilds of the held pairs (0: all pairs held).
        self._held: HeldPairs | None = None
        self.stride = 0
        if self._mode is PairMode.PRUNED:
            self._held, self.stride = held_pairs_for(
                self.universe,
                self.options.pairs.horizon,
                bounds=self.bounds,
                delta=body_vel_uncertainty(
                    model, self.bounds, period=self.period, mocap=self.mocap
                ),
                dt=self.dt,
                latency=self.latency,
            )
        # Pruned: the scheduler's pairs (ids among the known pairs), their packed records and
        # the last rebuild's step.
        self._ids = np.arange(self.universe.npair)
        self._records = self._pair_records
        self._built_at = 0
        # Spheres the latest step found outside their reach, renewed at the next step.
        self._escapes = _NONE
        self.rebuilds = 0
        """Rebuilds of the held pairs so far (pruned pairs only)."""
        self.renewals = 0
        """Renewals of escaped spheres' pairs so far (pruned pairs only)."""

    def geom_pair_ids(self, g1: npt.ArrayLike, g2: npt.ArrayLike) -> np.ndarray:
        """Ids of the active geom pairs ``{g1[k], g2[k]}``, -1 where MuJoCo's filter rejects
        the pair; a pruned predictor learns the active ones it has not met (the exact stage
        asks for every contact)."""
        gp = self.geom_pairs.indices_of(g1, g2)
        if (gp < 0).any() and self.universe.learn(np.asarray(g1)[gp < 0], np.asarray(g2)[gp < 0]):
            gp = self.geom_pairs.indices_of(g1, g2)
        return gp

    # ----------------------------------------------------------------------- setup

    def _hold(self, ids: np.ndarray) -> None:
        """Hold the pairs ``ids`` (sorted): the step reads only their records."""
        self._ids = ids
        self._records = np.ascontiguousarray(self._pair_records[ids])
        if self.events is not None:
            self.events.hold(self.tables.geom1[ids], self.tables.geom2[ids])
            self._events = self.events.args()
        if self.exact is not None:
            self._exact_records = np.ascontiguousarray(self.exact.records[ids])
        if self._native is not None:
            self._bind_tables(self._native)

    def _bind_tables(self, native: NativeStep) -> None:
        """Point the native step at the held pairs' tables as they stand now."""
        native.bind_tables(self._records, self._spheres, self._shapes, self._ids)
        native.bind_events(self._events)
        if self.exact is not None and self._exact_records is not None:
            x = self.exact
            native.bind_exact(
                self.model,
                x.geoms,
                self._exact_records,
                below=x.exact_below,
                query_below=x.query_below,
                verts=x.verts,
                graph=x.graph,
            )
        if self.scheduler is not None:
            native.bind_schedule(self.scheduler.state)

    def pair_state(self) -> PairState:
        """The scheduler's state of every sphere pair, by the model's pair ids (pruned or not)."""
        sched = self._require_scheduler()
        # The exact stage asks several times a step: one view per scheduler and held set.
        view = self._pair_state
        changes = self.rebuilds + self.renewals
        seen = (sched, changes, self.universe.version)
        if view is None or self._pair_state_seen != seen:
            self._pair_state_seen = seen
            held, left_out = None, None
            if self._held is not None:
                held = self._ids
                left_out = functools.partial(self._held.left_out_since, self.sphere_pairs)
            view = PairState(sched, self.nsphere_pairs, held, self._on, changes, left_out)
            self._pair_state = view
        return view

    # ----------------------------------------------------------------------- state

    def check_data(self, data: mujoco.MjData) -> None:
        """Refuse anything but an ``MjData`` of this predictor's model (or of one with the same
        geometry, e.g. the same XML loaded twice): the native step reads it unchecked."""
        check_data(self.model, data)

    def _bind_frame(self, data: mujoco.MjData) -> tuple:
        """Point the native step at ``data``'s buffers; cache the ``frame`` tuple (``rigid_point``).

        MjData's buffers live as long as the MjData, and every attribute access builds a new
        numpy view (about a microsecond in all), so ``step`` rebuilds the views only when it is
        handed another ``MjData``.
        """
        # The kernel does no bounds checks: refuse an MjData of another model here.
        self.check_data(data)
        self._frame_data = data
        self._frame_cache = mjdata_frame(data, self._twist)
        if self._native is not None:
            self._native.bind_frame(data, self._twist)
        return self._frame_cache

    def sphere_states(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """Centres and velocities of every covering sphere, ``(nsphere, 3)`` each.

        O(nsphere), through the same kinematics kernel as ``step``: used by ``reset``,
        rendering and tests.
        """
        if self.mocap is not None:
            self.mocap.write_body_velocity(self._twist)
        return sphere_states(self._spheres, mjdata_frame(data, self._twist))

    def halfspaces(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """Plane half-spaces: outward normals ``(nplane, 3)`` and offsets ``(nplane,)``."""
        return plane_halfspaces(data, self._plane_geom)

    def _nonfinite(self, data: mujoco.MjData, pair: int | None = None) -> NonFiniteStateError:
        if pair is not None:
            geoms = {int(self.tables.geom1[pair]), int(self.tables.geom2[pair])}
        else:
            c, v = self.sphere_states(data)
            bad = ~(np.isfinite(c).all(axis=1) & np.isfinite(v).all(axis=1))
            geoms = set(self.covering.sphere_geom[bad].tolist()[:5])
        return nonfinite_error(self.model, data, self.tables.geom_names, geoms)

    # ----------------------------------------------------------------------- protocol

    def reset(self, data: mujoco.MjData) -> Alarms:
        """Initial classification: tau of every active pair, scheduled (O(pairs)).

        Args:
            data: ``MjData`` with valid kinematics (after ``mj_forward`` or ``mj_step``).

        Returns:
            The alarms of the initial classification.

        Raises:
            InvalidInputError: ``data`` is not an MjData of this predictor's model, or its
                kinematics were never computed.
            NonFiniteStateError: a position or velocity is NaN or inf.
        """
        self._bind_frame(data)  # checks data
        check_forwarded(self.model, data)
        if self.mocap is not None:
            # A reset starts a new trajectory: difference mocap poses within it only. Reset in
            # place: the Monitor's bound checks hold this same tracker.
            self.mocap.reset()
            self.mocap.update(data, self._twist)
        c, v = self.sphere_states(data)
        # qpos/qvel too: a NaN written without mj_forward leaves finite (stale) kinematics.
        finite = np.isfinite(c).all() and np.isfinite(v).all()
        if not (finite and np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()):
            raise self._nonfinite(data)
        self._shapes = static_shapes(self.model, self.covering.shape_geom, data)
        if self.covering.nshape:
            self.pair_set.shapes = self._shapes
        if self._held is not None and self._on is not None:
            # A new scheduler starts with every pair on, held or not.
            self._on[:] = True
            self._hold(self._held.select(c, v, 0))
            self._built_at = 0
        self._escapes = _NONE
        # The same native code evaluates the classification and every step after it.
        self.scheduler = None
        native = NativeStep(max(self._ids.size, 1))
        native.bind_frame(data, self._twist)
        self._bind_tables(native)
        native.reset_events()
        tau0, bad = native.evaluate(np.arange(self._ids.size))
        if bad >= 0:
            raise self._nonfinite(data, int(self._ids[bad]))
        self.scheduler = self.new_scheduler(tau0)
        native.bind_schedule(self.scheduler.state)
        self._native = native
        self._load_compiled(data)
        self._time = float(data.time)
        self._steps_at_reset = int(data.timer[int(mujoco.mjtTimer.mjTIMER_STEP)].number)
        ids = self.scheduler.initial_alarms
        return Alarms(
            0, self._time, self._ids[ids], tau0[ids], self.tables, np.ones(ids.shape, bool), 0
        )

    def new_scheduler(self, tau0: np.ndarray) -> Scheduler:
        """A scheduler of this predictor's schedule and options over ``tau0`` ``(K,)``."""
        return make_scheduler(
            self.schedule,
            tau0,
            dt=self.dt,
            latency=self.latency,
            slots_per_bucket=self.slots_per_bucket,
            max_evals_per_step=self.max_evals_per_step,
            alarm_backoff=self.alarm_backoff,
        )

    def _load_compiled(self, data: mujoco.MjData) -> None:
        """Load what ``step`` may run from numba's cache (~10 ms each) now, not in the first
        ``step``, which a real-time user holds to its deadline too: a throw-away one-pair
        scheduler switches a pair (the step itself is native)."""
        if len(self.pair_set):
            spare = self.new_scheduler(np.full(1, np.inf))
            spare.set_active([0], False)
            spare.set_active([0], True)
            if isinstance(spare, DeadlineScheduler) and self._held is not None:
                spare.remap(np.array([0, -1]), 1)  # a pruned predictor's rebuilds and renewals
        if self.mocap is not None:
            self.mocap.load_compiled(data, self._twist)

    def step(self, data: mujoco.MjData) -> Alarms:
        """One predictor step: evaluate the scheduled pairs, reschedule them, return the alarms.

        Raises:
            SchedulerError: ``reset`` was not called, or ``data.time`` did not advance by one
                predictor period since the previous call.
            NonFiniteStateError: the state read for a scheduled pair is NaN or inf, or MuJoCo
                reset the state after the simulation diverged.
            InvalidInputError: ``data`` is not an MjData of this predictor's model.
        """
        sched = self.scheduler
        if sched is None:
            raise SchedulerError("step() before reset(): call predictor.reset(data) first.")
        # Before the clock: another model's data has its own clock, and the error must say so.
        if self._frame_data is not data:
            self._bind_frame(data)
        time = float(data.time)
        elapsed = time - self._time
        if abs(elapsed - self.dt) > 1e-6 * self.dt:
            expected = self._steps_at_reset + self.period * (sched.step_count + 1)
            raise clock_error(data, expected, elapsed, self.period, self.dt)
        if self.mocap is not None:
            self.mocap.update(data, self._twist)
        if self._held is not None:
            n = sched.step_count + 1
            if n - self._built_at >= self.stride or self._escapes.size > RENEW_MAX:
                self._rebuild(data, n)
            elif self._escapes.size:
                self._renew(data, n, self._escapes)
            self._escapes = _NONE
        native = self._native
        assert native is not None
        start, nalarm = native.step(sched.begin_step())
        if nalarm < 0:
            raise self._nonfinite(data, int(self._ids[-1 - nalarm]))
        sched.end_step(nalarm)
        if self._held is not None and self._events[2][M_COUNT]:
            # Pairs not held were left out under the bounds too: a flagged body's spheres that
            # may have left the reach that left them out are renewed at the next step.
            self._escapes = self._held.escapes(native, sched.step_count)
        self._time = time
        deferred = sched.deferred if self.max_evals_per_step is not None else 0
        return Alarms.from_log(
            sched.step_count,
            time,
            native.view,
            start,
            start + nalarm,
            self.universe.tables,
            deferred,
        )

    def _rebuild(self, data: mujoco.MjData, step: int) -> None:
        """Renew the held pairs from this state; kept ones carry their verdicts (O(N + K))."""
        assert self._held is not None
        c, v = self.sphere_states(data)
        if not (np.isfinite(c).all() and np.isfinite(v).all()):
            raise self._nonfinite(data)
        self._carry(self._held.select(c, v, step), step)
        self._built_at = step
        self.rebuilds += 1

    def _renew(self, data: mujoco.MjData, step: int, spheres: np.ndarray) -> None:
        """Anchor escaped ``spheres`` anew and hold the pairs their reach brings in
        (O(len(spheres) N) tests, then O(K) if any pair is new)."""
        assert self._held is not None and self._native is not None
        found, bad = self._held.renew(self._native, spheres, step)
        if bad >= 0:
            raise self._nonfinite(data)
        pos = np.minimum(np.searchsorted(self._ids, found), max(self._ids.size - 1, 0))
        new = found[(self._ids.size == 0) | (self._ids[pos] != found)]
        if new.size:
            self._carry(np.union1d(self._ids, new), step)
        self.renewals += 1

    def _carry(self, ids: np.ndarray, step: int) -> None:
        """Hold the sorted pairs ``ids`` from step ``step``: kept ones carry their verdicts, new
        ones stand in alarm until evaluated (due now), new ones switched off stay off."""
        sched = self.scheduler
        assert isinstance(sched, DeadlineScheduler) and self._on is not None
        pos = np.minimum(np.searchsorted(self._ids, ids), max(self._ids.size - 1, 0))
        kept = (self._ids.size > 0) & (self._ids[pos] == ids)
        sched.remap(np.where(kept, pos, -1), step)
        self._hold(ids)
        sched.set_active(np.flatnonzero(~kept & ~self._on[ids]), False)

    def _switch(self, ids: np.ndarray, on: bool) -> None:
        """Switch sphere pairs ``ids`` (among all active pairs) in the scheduler."""
        sched = self._require_scheduler()
        if self._on is None:
            sched.set_active(ids, on)
            return
        self._on[ids] = on
        pos = np.minimum(np.searchsorted(self._ids, ids), max(self._ids.size - 1, 0))
        sched.set_active(pos[(self._ids.size > 0) & (self._ids[pos] == ids)], on)

    # ----------------------------------------------------------------------- intended contact

    def set_active_bodies(
        self, body_a: int | str, body_b: int | str | None = None, *, on: bool
    ) -> int:
        """Switch the pairs between two bodies (or of one body) off or back on (paper sec. 6.3).

        Use it while contact is intended (a grasp, a box resting on a table). Returns the number
        of sphere pairs switched. Pairs switched back on stand in alarm until the next ``step``
        evaluates them (``scheduler.alarm_state``): their motion while off is unknown, and with
        ``period > 1`` that step can be a whole period away; treat the two bodies as alarmed
        until then.
        """
        self._require_scheduler()
        a = body_id(self.model, body_a)
        b = None if body_b is None else body_id(self.model, body_b)
        self.universe.between(np.array([a]), None if b is None else np.array([b]))
        gp = pairs_between_bodies(self.model, self.geom_pairs, a, b)
        ids = np.flatnonzero(sphere_pair_mask(self.sphere_pairs, gp))
        self._switch(ids, on)
        return int(ids.size)

    def deactivate_contacts(self, data: mujoco.MjData) -> int:
        """Switch off the sphere pairs of every geom pair in contact in ``data`` (resting contact).

        Returns the number of geom pairs switched off. They stay off, whatever happens to the
        contact, until switched back on with :meth:`set_active_bodies` (e.g. when the object is
        lifted or pushed away); until then their contacts are counted apart, never predicted.
        """
        self._require_scheduler()
        nc = int(data.ncon)
        if nc == 0:
            return 0
        g1, g2 = data.contact.geom1[:nc], data.contact.geom2[:nc]
        geoms = (g1 >= 0) & (g2 >= 0)  # a flex's contacts have no geom
        gp = self.geom_pair_ids(g1[geoms], g2[geoms])
        gp = np.unique(gp[gp >= 0])
        self._switch(np.flatnonzero(sphere_pair_mask(self.sphere_pairs, gp)), False)
        return int(gp.size)
