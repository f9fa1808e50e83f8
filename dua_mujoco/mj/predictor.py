"""``Predictor``: MuJoCo state in, collision alarms out.

The model is read once: geoms are covered by spheres (``covering``), MuJoCo's collision filter
gives the active geom pairs (``filter``), and those expand into sphere pairs with per-pair contact
distance, acceleration bound and velocity uncertainty. ``reset(data)`` is the initial
classification; each ``step(data)`` evaluates the scheduled pairs in one compiled call that reads
only their spheres from ``MjData`` (``kinematics.step_rigid_kernel``).

Timing. Call ``step`` every ``period`` physics steps, after ``mj_step``. ``MjData`` then holds the
kinematics (``geom_xpos``, ``cvel``) and contacts of the state at the start of that step, and the
predictor uses that one instant throughout (docs/discrete-time.md).
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable, Mapping
from typing import Literal

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco.core.pairset import PairSet, pack_pairs
from dua_mujoco.core.schedules import (
    DeadlineScheduler,
    DUAScheduler,
    Schedule,
    Scheduler,
    SelectAllScheduler,
)
from dua_mujoco.core.schedules.deadline import check_max_evals
from dua_mujoco.core.schedules.dua import check_slots_per_bucket
from dua_mujoco.core.validate import check_period
from dua_mujoco.exceptions import (
    InvalidChoiceError,
    InvalidInputError,
    NoActivePairsWarning,
    NonFiniteStateError,
    SchedulerError,
)
from dua_mujoco.mj.alarms import Alarms
from dua_mujoco.mj.bounds import DIVERGENCE_WARNINGS, MotionBounds, estimate_bounds
from dua_mujoco.mj.covering import Covering, CoveringMode, cover_model
from dua_mujoco.mj.filter import (
    GeomPairs,
    SpherePairs,
    active_geom_pairs,
    pairs_between_bodies,
    sphere_pair_mask,
    sphere_pairs,
)
from dua_mujoco.mj.kinematics import mjdata_frame, pack_spheres, sphere_states, step_rigid_kernel
from dua_mujoco.mj.mocap import MocapVelocityTracker
from dua_mujoco.mj.refine import Refinement, build_refinement, no_refinement, refine_taus
from dua_mujoco.mj.tables import PairTables, plane_halfspaces, same_geometry, static_shapes

__all__ = ["BoundsLike", "Predictor"]

BoundsLike = float | Mapping[str, float] | MotionBounds | Literal["auto"]
"""Acceleration bounds: a scalar (m/s^2, every moving body), a dict by body name (``"*"`` for
the rest), ready ``MotionBounds``, or ``"auto"`` (estimated by a pilot rollout)."""


def make_scheduler(
    schedule: Schedule,
    tau0: np.ndarray,
    *,
    dt: float,
    latency: int,
    slots_per_bucket: int = 1,
    max_evals_per_step: int | None = None,
) -> Scheduler:
    """The scheduler of ``schedule`` over the initial tau ``tau0``."""
    if schedule is Schedule.DUA:
        return DUAScheduler(tau0, dt=dt, latency=latency, slots_per_bucket=slots_per_bucket)
    if schedule is Schedule.DEADLINE:
        return DeadlineScheduler(
            tau0, dt=dt, latency=latency, max_evals_per_step=max_evals_per_step
        )
    return SelectAllScheduler(tau0, dt=dt, latency=latency)


def as_schedule(schedule: Schedule | str) -> Schedule:
    """``schedule`` as a ``Schedule``, or an error listing the choices."""
    try:
        return Schedule(schedule)
    except ValueError:
        raise InvalidChoiceError("schedule", schedule, [s.value for s in Schedule]) from None


class Predictor:
    """DUA collision predictor for a MuJoCo model.

    Args:
        model: The MuJoCo model.
        accel: Acceleration bounds (``BoundsLike``). ``"auto"`` runs a pilot rollout on its own
            ``MjData`` with ``pilot_seed`` and multiplies the measured maxima by ``safety``.
        speed: Optional speed bounds (scalar or dict by body name), ignored for ready
            ``MotionBounds``.
        covering: ``"bounding"``, ``"multi"``, a ``CoveringMode`` or a ready ``Covering``.
        max_spheres_per_geom: Budget of the multi-sphere covering.
        hfield: ``"error"`` or ``"box"`` (conservative box covering of height fields).
        static: ``"shape"`` (default): geoms welded to the world are held as their own convex
            shapes (docs/static-shapes.md); ``"sphere"``: covered by spheres like moving geoms.
            Ignored for a ready ``Covering``.
        refine: Two-level urgency (docs/static-shapes.md, section 12): with an int ``n >= 1``,
            pairs of the bounding covering whose tau is below ``refine_below`` are refined with
            the geoms' ``multi`` coverings of ``n`` spheres each (requires
            ``covering="bounding"``). None (default): off.
        refine_below: Refine pairs whose bounding tau is below this many seconds.
        period: Physics steps between predictor steps (``>= 1``); the predictor period is
            ``period * model.opt.timestep``.
        latency: Periods a verdict takes to act. 0 (the default) is right when ``step`` runs
            synchronously after ``mj_step``: the verdict is ready before the next physics step.
            Use 1 when the alarms act one period late (the paper's setting).
        schedule: Which pairs to evaluate each step (``Schedule`` or its value): ``"deadline"``
            (default: each pair when its own tau runs out; select-all's alarms for a fraction of
            its work), ``"dua"`` (the paper's constant work a step; alarm horizons grow with the
            number of pairs) or ``"select-all"``. See docs/theory.md.
        slots_per_bucket: ``dua`` only: the budget knob (a power of two): revisit intervals
            shrink that many times, work grows as many.
        max_evals_per_step: ``deadline`` only: optional cap on tau evaluations a step; pairs
            due beyond it wait, standing in alarm once their verdict no longer covers the wait
            (``Alarms.deferred`` says how many waited).
        velocity_accel: Bound ``C`` on the centripetal/Coriolis acceleration of sphere centres,
            for the discrete-time term (docs/discrete-time.md); scalar or dict by body name.
        pilot_steps: Length of the pilot rollout for ``accel="auto"``.
        pilot_seed: Seed of the pilot rollout (use one different from the monitored run).
        pilot_controller: ``controller(model, data)`` for the pilot; default random controls.
        safety: Factor on the pilot's maxima.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        *,
        accel: BoundsLike = "auto",
        speed: float | Mapping[str, float] | None = None,
        covering: Covering | CoveringMode | str = "bounding",
        max_spheres_per_geom: int = 8,
        hfield: str = "error",
        static: str = "shape",
        refine: int | None = None,
        refine_below: float = 0.1,
        period: int = 1,
        latency: int = 0,
        schedule: Schedule | str = Schedule.DEADLINE,
        slots_per_bucket: int = 1,
        max_evals_per_step: int | None = None,
        velocity_accel: float | Mapping[str, float] | None = None,
        pilot_steps: int = 2000,
        pilot_seed: int = 1_000_003,
        pilot_controller: Callable[[mujoco.MjModel, mujoco.MjData], None] | None = None,
        safety: float = 2.0,
    ) -> None:
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
        self.schedule = as_schedule(schedule)
        self.slots_per_bucket = check_slots_per_bucket(slots_per_bucket)
        self.max_evals_per_step = check_max_evals(max_evals_per_step) or None
        self.covering = (
            covering
            if isinstance(covering, Covering)
            else cover_model(
                model,
                mode=covering,
                max_spheres_per_geom=max_spheres_per_geom,
                hfield=hfield,
                static=static,
            )
        )
        self.geom_pairs: GeomPairs = active_geom_pairs(model)
        self.sphere_pairs: SpherePairs = sphere_pairs(self.covering, self.geom_pairs)
        if len(self.geom_pairs) == 0:
            warnings.warn(
                "the model has no geom pair MuJoCo could ever put in contact (no collidable "
                "geoms, one geom only, or every pair filtered out by contype/conaffinity, "
                "parent-child or <exclude>): the predictor will never raise an alarm.",
                NoActivePairsWarning,
                stacklevel=2,
            )
        cov = self.covering
        spheres = (cov.sphere_geom, cov.sphere_body, cov.sphere_offset)
        self.refinement: Refinement | None = None
        """The two-level urgency's fine coverings (None without ``refine``)."""
        if refine is not None:
            fine = cover_model(
                model, mode="multi", max_spheres_per_geom=refine, hfield=hfield, static=static
            )
            # Before the pilot: a refinement that cannot be built fails fast.
            self.refinement = build_refinement(
                model.body_rootid, cov, fine, self.sphere_pairs, self.geom_pairs, refine_below
            )
            # The bounds must hold for the fine sphere centres too: the pilot measures both.
            spheres = tuple(  # type: ignore[assignment]
                np.concatenate([a, b])
                for a, b in zip(
                    spheres, (fine.sphere_geom, fine.sphere_body, fine.sphere_offset), strict=True
                )
            )
        if isinstance(accel, MotionBounds):
            if accel.accel.shape != (model.nbody,):
                raise InvalidInputError(
                    f"the MotionBounds have {accel.accel.shape[0]} bodies but the model has "
                    f"{model.nbody}: build them for this model (MotionBounds.declare(model, ...))."
                )
            self.bounds = accel
        elif isinstance(accel, str):
            if accel != "auto":
                raise InvalidInputError(
                    f"accel = {accel!r} is invalid: pass 'auto', a number, a dict by body name "
                    "or MotionBounds."
                )
            pilot = None
            if pilot_controller is not None:
                ctrl = pilot_controller

                def pilot(m: mujoco.MjModel, d: mujoco.MjData, rng: np.random.Generator) -> None:
                    ctrl(m, d)

            self.bounds = estimate_bounds(
                model,
                steps=pilot_steps,
                seed=pilot_seed,
                safety=safety,
                controller=pilot,
                spheres=spheres,
                with_speed=False,
            )
            if speed is not None:
                # A declared speed bound still applies on top of estimated accelerations.
                declared = MotionBounds.declare(model, 0.0, speed=speed, integrator_term=False)
                self.bounds = dataclasses.replace(self.bounds, speed=declared.speed)
        else:
            self.bounds = MotionBounds.declare(
                model, accel, speed=speed, velocity_accel=velocity_accel
            )
        self.mocap: MocapVelocityTracker | None = (
            MocapVelocityTracker(model) if model.nmocap else None
        )
        """Velocities of mocap bodies (None without mocap bodies): ``set_velocity`` to give
        them instead of differencing."""
        self.pair_set = self._pair_set()
        self.tables = PairTables.build(model, cov, self.sphere_pairs)
        self._plane_geom = np.asarray(cov.plane_geom, dtype=np.int64)
        self._spheres = pack_spheres(
            cov.sphere_geom, cov.sphere_body, cov.sphere_offset, model.body_rootid
        )
        self._pair_records = pack_pairs(self.pair_set, self._plane_geom)
        self._refine = no_refinement() if self.refinement is None else self.refinement.args
        # Static shape records: their poses are model constants (static_shapes), re-packed and
        # checked against the data at each reset.
        self._shapes = static_shapes(model, cov.shape_geom)
        if cov.nshape:
            self.pair_set.shapes = self._shapes
        # Mocap roots' twists, rewritten each step (zero throughout in a model without mocap).
        self._twist = np.zeros((model.nbody, 6))
        self.scheduler: Scheduler | None = None
        self._time = 0.0
        self._steps_at_reset = 0
        self._frame_data: mujoco.MjData | None = None
        self._frame_cache: tuple = ()

    # ----------------------------------------------------------------------- setup

    def _pair_set(self) -> PairSet:
        sp, cov, b = self.sphere_pairs, self.covering, self.bounds
        body1 = cov.sphere_body[sp.first]
        # Half-space and shape pairs: planes and shapes are static (the world body's bounds).
        lone = sp.is_halfspace | sp.is_shape
        body2 = np.where(lone, 0, cov.sphere_body[np.where(lone, 0, sp.second)])
        accel = b.accel[body1] + b.accel[body2]
        delta = b.vel_uncertainty[body1] + b.vel_uncertainty[body2]
        if self.mocap is not None and self.period > 1:
            # Mocap velocities are backward differences over one predictor period: their error
            # is A * period * h / 2, of which the discrete-time term already holds A * h / 2.
            in_mocap = np.zeros(self.model.nbody, dtype=bool)
            in_mocap[self.mocap.mocap_bodies] = True
            tree = in_mocap[np.asarray(self.model.body_rootid)]
            extra = np.where(tree, 0.5 * (self.period - 1) * self.model.opt.timestep, 0.0)
            delta = delta + (extra * b.accel)[body1] + (extra * b.accel)[body2]
        speed: npt.ArrayLike = np.inf
        if b.speed is not None:
            speed = np.where(lone, b.speed[body1], b.speed[body1] + b.speed[body2])
        return PairSet(
            sp.first,
            sp.second,
            sp.eps,
            accel,
            kind=sp.kind,
            vel_uncertainty=delta,
            speed=speed,
        )

    # ----------------------------------------------------------------------- state

    def check_data(self, data: mujoco.MjData) -> None:
        """Refuse anything but an ``MjData`` of this predictor's model (or of one with the same
        geometry, e.g. the same XML loaded twice): the compiled step reads it unchecked."""
        m = self.model
        if not isinstance(data, mujoco.MjData):
            raise InvalidInputError(
                f"data must be a mujoco.MjData, got {type(data).__name__}: pass "
                "mujoco.MjData(model) after mujoco.mj_forward(model, data)."
            )
        # The same object, or another one with the same geometry (one XML loaded twice): the
        # compiled step reads MjData without bounds checks, and the covering and the pair
        # filter must be this model's.
        if data.model is not m and not same_geometry(data.model, m):
            raise InvalidInputError(
                f"data belongs to another MjModel ({data.model.ngeom} geoms, {data.model.nbody} "
                f"bodies; this predictor's has {m.ngeom} and {m.nbody}) whose geoms, bodies or "
                "collision filters differ: pass the MjData of this predictor's model, or build "
                "a Predictor for that model."
            )

    def _bind_frame(self, data: mujoco.MjData) -> tuple:
        """Build and cache the fused step's ``frame`` tuple (``rigid_point``) for ``data``.

        MjData's buffers live as long as the MjData, and every attribute access builds a new
        numpy view (about a microsecond in all), so ``step`` rebuilds the views only when it is
        handed another ``MjData``.
        """
        # The kernel does no bounds checks: refuse an MjData of another model here.
        self.check_data(data)
        self._frame_data = data
        self._frame_cache = mjdata_frame(data, self._twist)
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
            g = {int(self.tables.geom1[pair]), int(self.tables.geom2[pair])}
        else:
            c, v = self.sphere_states(data)
            bad = ~(np.isfinite(c).all(axis=1) & np.isfinite(v).all(axis=1))
            g = set(self.covering.sphere_geom[bad].tolist()[:5])
        if g:
            what = f"the state of geom(s) {self._listed(g)}"
        else:  # finite kinematics computed before a NaN was written into qpos or qvel
            m = self.model
            bad = [
                mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint{j}"
                for vec, adr in ((data.qpos, m.jnt_qposadr), (data.qvel, m.jnt_dofadr))
                for j in np.unique(
                    np.searchsorted(adr, np.flatnonzero(~np.isfinite(vec)), "right") - 1
                )
            ]
            what = f"data.qpos or data.qvel of joint(s) {sorted(set(bad))}"
        return NonFiniteStateError(
            f"{what} is not finite at t = {data.time}: the simulation has diverged (reduce the "
            "timestep or check the model) or MjData was not initialised (call mujoco.mj_forward)."
        )

    def _listed(self, geoms: set[int]) -> str:
        return ", ".join(repr(self.tables.geom_names[i]) for i in sorted(geoms))

    @staticmethod
    def _divergence_count(data: mujoco.MjData) -> int:
        return sum(int(data.warning[int(w)].number) for w in DIVERGENCE_WARNINGS)

    def _divergence(self, data: mujoco.MjData) -> str:
        """Why the state jumped, if MuJoCo reset it after diverging since ``reset`` (or "").

        Called only when ``data.time`` did not advance by one period. MuJoCo answers a diverged
        state with a warning and ``mj_resetData``, which also restarts its count of
        ``mj_step`` calls: a divergence warning standing and a step count other than the one
        this predictor's calls imply mean MuJoCo reset the state (a user's own ``mj_resetData``
        clears the warnings; a rewound ``data.time`` leaves the step count as it was).
        """
        if self._divergence_count(data) == 0:
            return ""
        sched = self.scheduler
        assert sched is not None
        steps = int(data.timer[int(mujoco.mjtTimer.mjTIMER_STEP)].number)
        if steps == self._steps_at_reset + self.period * (sched.step_count + 1):
            return ""
        names = [w.name for w in DIVERGENCE_WARNINGS if data.warning[int(w)].number]
        return (
            f"MuJoCo reported a NaN, inf or huge value ({', '.join(names)}) and reset the "
            f"simulation state itself (data.time is now {data.time:g} s): the simulation "
            "diverged. Reduce model.opt.timestep or check the model and controls, then call "
            "predictor.reset(data)."
        )

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
        frame = self._bind_frame(data)  # checks data
        self._check_forwarded(data)
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
        halfspaces = self.halfspaces(data)
        self._shapes = static_shapes(self.model, self.covering.shape_geom, data)
        if self.covering.nshape:
            self.pair_set.shapes = self._shapes
        ids = np.arange(len(self.pair_set))
        tau0 = self.pair_set.tau(ids, c, v, halfspaces)
        if self.refinement is not None:
            refine_taus(tau0, ids, self._pair_records, frame, self._shapes, self._refine)
        self.scheduler = self._scheduler(tau0)
        self._load_compiled(data, frame)
        self._time = float(data.time)
        self._steps_at_reset = int(data.timer[int(mujoco.mjtTimer.mjTIMER_STEP)].number)
        ids = self.scheduler.initial_alarms
        return Alarms(0, self._time, ids, tau0[ids], self.tables, np.ones(ids.shape, bool), 0)

    def _scheduler(self, tau0: np.ndarray) -> Scheduler:
        return make_scheduler(
            self.schedule,
            tau0,
            dt=self.dt,
            latency=self.latency,
            slots_per_bucket=self.slots_per_bucket,
            max_evals_per_step=self.max_evals_per_step,
        )

    def _check_forwarded(self, data: mujoco.MjData) -> None:
        """An ``MjData`` fresh from ``mujoco.MjData(model)`` has all-zero rotation matrices:
        every geom sits at the origin and every pair would alarm."""
        if self.model.ngeom and not np.asarray(data.geom_xmat).any():
            raise InvalidInputError(
                "data holds no kinematics (every geom rotation is zero: mj_forward was never "
                "called): call mujoco.mj_forward(model, data) (or mj_step) before "
                "predictor.reset(data)."
            )

    def _load_compiled(self, data: mujoco.MjData, frame: tuple) -> None:
        """Load what ``step`` runs from numba's cache (~10 ms each) now, not in ``step``.

        A real-time user holds every ``step`` to its deadline, the first one included. One
        step of a throw-away one-pair scheduler of the same schedule on the real tables (read
        only) loads the fused step and the switching kernel; the mocap differencing runs on
        copies.
        """
        if len(self.pair_set):
            spare = self._scheduler(np.full(1, np.inf))
            spare.step_with(
                step_rigid_kernel,
                self._pair_records[:1],
                self._spheres,
                frame,
                self._shapes,
                self._refine,
            )
            spare.set_active([0], False)
            spare.set_active([0], True)
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
        frame = self._frame_cache if self._frame_data is data else self._bind_frame(data)
        time = float(data.time)
        elapsed = time - self._time
        if abs(elapsed - self.dt) > 1e-6 * self.dt:
            diverged = self._divergence(data)
            if diverged:
                raise NonFiniteStateError(diverged)
            raise SchedulerError(
                f"data.time advanced by {elapsed:.9g} s since the previous predictor call, but "
                f"the predictor period is {self.dt:.9g} s (period={self.period} x timestep "
                f"{self.model.opt.timestep:g}): call step() every {self.period} physics step(s), "
                "or reset() after changing the state."
            )
        if self.mocap is not None:
            self.mocap.update(data, self._twist)
        alarmed, bad = sched.step_with(
            step_rigid_kernel, self._pair_records, self._spheres, frame, self._shapes, self._refine
        )
        if bad >= 0:
            raise self._nonfinite(data, bad)
        self._time = time
        return Alarms(
            sched.step_count,
            time,
            alarmed,
            sched.last_tau[alarmed],
            self.tables,
            sched.last_new,
            sched.deferred,
        )

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
        sched = self._require_scheduler()
        gp = pairs_between_bodies(self.model, self.geom_pairs, body_a, body_b)
        ids = np.flatnonzero(sphere_pair_mask(self.sphere_pairs, gp))
        sched.set_active(ids, on)
        return int(ids.size)

    def deactivate_contacts(self, data: mujoco.MjData) -> int:
        """Switch off the sphere pairs of every geom pair in contact in ``data`` (resting contact).

        Returns the number of geom pairs switched off. They stay off, whatever happens to the
        contact, until switched back on with :meth:`set_active_bodies` (e.g. when the object is
        lifted or pushed away); until then their contacts are counted apart, never predicted.
        """
        sched = self._require_scheduler()
        nc = int(data.ncon)
        if nc == 0:
            return 0
        gp = self.geom_pairs.indices_of(data.contact.geom1[:nc], data.contact.geom2[:nc])
        gp = np.unique(gp[gp >= 0])
        sched.set_active(np.flatnonzero(sphere_pair_mask(self.sphere_pairs, gp)), False)
        return int(gp.size)

    def _require_scheduler(self) -> Scheduler:
        if self.scheduler is None:
            raise SchedulerError("call predictor.reset(data) first.")
        return self.scheduler

    # ----------------------------------------------------------------------- introspection

    @property
    def nsphere(self) -> int:
        """Number of covering spheres."""
        return int(self.covering.nsphere)

    @property
    def nsphere_pairs(self) -> int:
        """Number of sphere pairs (the scheduler's pairs)."""
        return len(self.pair_set)

    @property
    def evaluations_per_step(self) -> int:
        """tau evaluations of the latest step (``dua``: the slots handed out a step)."""
        return self._require_scheduler().evaluations_per_step

    @property
    def sphere_pair_geoms(self) -> tuple[np.ndarray, np.ndarray]:
        """``(geom1, geom2)``, each ``(nsphere_pairs,)``: the geoms of every sphere pair
        (``geom2`` is the plane geom of half-space pairs, the static geom of shape pairs)."""
        return self.tables.geom1, self.tables.geom2

    def geom_pair_of(self, pairs: npt.ArrayLike) -> np.ndarray:
        """Index into ``geom_pairs`` of sphere pairs."""
        return np.asarray(self.sphere_pairs.geom_pair[np.asarray(pairs, dtype=np.int64)])
