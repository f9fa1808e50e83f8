"""``Predictor``: MuJoCo state in, collision alarms out.

The model is read once: geoms are covered by spheres (``covering``), MuJoCo's collision filter
gives the active geom pairs (``pairs``), and those expand into sphere pairs with per-pair contact
distance, acceleration bound and velocity uncertainty. ``reset(data)`` is the DUA initial
classification; each ``step(data)`` evaluates the O(log pairs) scheduled pairs in one compiled
call that reads only their spheres from ``MjData``.

Timing. Call ``step`` every ``period`` physics steps, after ``mj_step``. ``MjData`` then holds the
kinematics (``geom_xpos``, ``cvel``) and contacts of the state at the start of that step, and the
predictor uses that one instant throughout (SPEC section 6); ``latency=0`` is right for this
synchronous use (the verdict is ready before the next physics step).
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable, Mapping
from typing import Literal

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco.bounds import _DIVERGENCE_WARNINGS, MotionBounds, estimate_bounds
from dua_mujoco.covering import Covering, CoveringMode, cover_model
from dua_mujoco.exceptions import (
    InvalidInputError,
    NoActivePairsWarning,
    NonFiniteStateError,
    SchedulerError,
)
from dua_mujoco.pairs import (
    GeomPairs,
    SpherePairs,
    active_geom_pairs,
    pairs_between_bodies,
    sphere_pair_mask,
    sphere_pairs,
)
from dua_mujoco.scheduler import DUAScheduler, PairSet, pack_pairs, pack_spheres
from dua_mujoco.state import MocapVelocityTracker, sphere_centers, sphere_velocities

__all__ = ["Alarms", "BoundsLike", "Predictor"]

BoundsLike = float | Mapping[str, float] | MotionBounds | Literal["auto"]
"""Acceleration bounds: a scalar (m/s^2, every moving body), a dict by body name (``"*"`` for
the rest), ready ``MotionBounds``, or ``"auto"`` (estimated by a pilot rollout)."""


@dataclasses.dataclass(frozen=True)
class _PairTables:
    """Read-only lookup tables that turn sphere-pair ids into geoms and names."""

    first: np.ndarray
    second: np.ndarray
    halfspace: np.ndarray
    geom1: np.ndarray
    geom2: np.ndarray
    geom_names: np.ndarray


class Alarms:
    """The alarms of one predictor step (read-only).

    A slotted class rather than a frozen dataclass: one is built every predictor step, and a
    frozen dataclass's ``__init__`` (``object.__setattr__`` per field) cost 1.1 us of a step
    budget of a few microseconds (measured; this class: 0.3 us).

    Attributes:
        step: Predictor step (0 for the initial classification).
        time: ``data.time`` when read.
        pairs: ``(k,)`` sphere-pair ids that raised an alarm.
        tau: ``(k,)`` their tau (seconds).
    """

    __slots__ = ("_pairs", "_step", "_tables", "_tau", "_time")

    def __init__(
        self, step: int, time: float, pairs: np.ndarray, tau: np.ndarray, tables: _PairTables
    ) -> None:
        self._step = step
        self._time = time
        self._pairs = pairs
        self._tau = tau
        self._tables = tables

    @property
    def step(self) -> int:
        """Predictor step (0 for the initial classification)."""
        return self._step

    @property
    def time(self) -> float:
        """``data.time`` when read."""
        return self._time

    @property
    def pairs(self) -> np.ndarray:
        """``(k,)`` sphere-pair ids that raised an alarm."""
        return self._pairs

    @property
    def tau(self) -> np.ndarray:
        """``(k,)`` their tau (seconds)."""
        return self._tau

    def __repr__(self) -> str:
        return (
            f"Alarms(step={self._step}, time={self._time!r}, pairs={self._pairs!r}, "
            f"tau={self._tau!r})"
        )

    def __len__(self) -> int:
        return int(self.pairs.shape[0])

    @property
    def geom1(self) -> np.ndarray:
        """``(k,)`` first geom of each alarmed pair."""
        return np.asarray(self._tables.geom1[self.pairs])

    @property
    def geom2(self) -> np.ndarray:
        """``(k,)`` second geom of each alarmed pair (a plane geom for half-space pairs)."""
        return np.asarray(self._tables.geom2[self.pairs])

    @property
    def sphere1(self) -> np.ndarray:
        """``(k,)`` first sphere of each alarmed pair."""
        return np.asarray(self._tables.first[self.pairs])

    @property
    def sphere2(self) -> np.ndarray:
        """``(k,)`` second sphere, ``-1`` for half-space pairs."""
        return np.asarray(
            np.where(self._tables.halfspace[self.pairs], -1, self._tables.second[self.pairs])
        )

    @property
    def names(self) -> list[tuple[str, str]]:
        """Geom names of each alarmed pair (``geom<id>`` for unnamed geoms)."""
        n = self._tables.geom_names
        return list(zip(n[self.geom1].tolist(), n[self.geom2].tolist(), strict=True))

    @property
    def geom_pairs(self) -> set[tuple[int, int]]:
        """The distinct alarmed geom pairs ``(g1, g2)``, ``g1 < g2``."""
        a, b = self.geom1, self.geom2
        return set(zip(np.minimum(a, b).tolist(), np.maximum(a, b).tolist(), strict=True))


def _geom_names(model: mujoco.MjModel) -> np.ndarray:
    names = [
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom{g}"
        for g in range(model.ngeom)
    ]
    return np.asarray(names, dtype=object)


# What the covering (geoms, meshes, height fields), the pair filter (masks, welds, <exclude>,
# <pair>, parent filtering) and the contact distances (margins, gaps) are built from.
_GEOMETRY_FIELDS = (
    "geom_type",
    "geom_size",
    "geom_pos",
    "geom_quat",
    "geom_bodyid",
    "geom_dataid",
    "geom_margin",
    "geom_gap",
    "geom_contype",
    "geom_conaffinity",
    "body_parentid",
    "body_weldid",
    "mesh_vert",
    "hfield_size",
    "pair_geom1",
    "pair_geom2",
    "pair_margin",
    "pair_gap",
    "exclude_signature",
)


# The option bits the pair filter and the contact distances read (others, e.g. gravity, do not
# change what the predictor is built from).
_FILTER_DISABLE = (
    mujoco.mjtDisableBit.mjDSBL_CONTACT
    | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    | mujoco.mjtDisableBit.mjDSBL_FILTERPARENT
)


def _contact_options(m: mujoco.MjModel) -> tuple[int, int, float]:
    override = int(m.opt.enableflags) & int(mujoco.mjtEnableBit.mjENBL_OVERRIDE)
    return int(m.opt.disableflags) & int(_FILTER_DISABLE), override, float(m.opt.o_margin)


def _same_geometry(a: mujoco.MjModel, b: mujoco.MjModel) -> bool:
    """Whether two models have what a predictor is built from (e.g. one XML loaded twice)."""
    return (
        (a.ngeom, a.nbody, a.nq, a.nv) == (b.ngeom, b.nbody, b.nq, b.nv)
        and _contact_options(a) == _contact_options(b)
        and all(np.array_equal(getattr(a, f), getattr(b, f)) for f in _GEOMETRY_FIELDS)
    )


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
        period: Physics steps between predictor steps (``>= 1``); the predictor period is
            ``period * model.opt.timestep``.
        latency: Periods a verdict takes (0 for synchronous use after ``mj_step``).
        slots_per_bucket: DUA's budget knob (a power of two).
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
        period: int = 1,
        latency: int = 0,
        slots_per_bucket: int = 1,
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
        if not isinstance(period, int | np.integer) or period < 1:
            raise InvalidInputError(f"period = {period!r} is invalid: it must be an int >= 1.")
        self.model = model
        self.period = int(period)
        self.dt = self.period * float(model.opt.timestep)
        # Validate the scheduler options now rather than at reset(): same checks, same messages.
        DUAScheduler(np.zeros(1), dt=self.dt, latency=latency, slots_per_bucket=slots_per_bucket)
        self.latency = int(latency)
        self.slots_per_bucket = int(slots_per_bucket)
        self.covering = (
            covering
            if isinstance(covering, Covering)
            else cover_model(
                model, mode=covering, max_spheres_per_geom=max_spheres_per_geom, hfield=hfield
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
        self._mocap = MocapVelocityTracker(model) if model.nmocap else None
        self.pairs = self._pair_set()
        sp = self.sphere_pairs
        plane_geom = np.asarray(cov.plane_geom, dtype=np.int64)
        geom2 = np.where(
            sp.is_halfspace,
            plane_geom[np.where(sp.is_halfspace, sp.second, 0)] if plane_geom.size else -1,
            cov.sphere_geom[np.where(sp.is_halfspace, 0, sp.second)],
        )
        self._tables = _PairTables(
            first=self.pairs.first,
            second=self.pairs.second,
            halfspace=self.pairs.halfspace,
            geom1=np.asarray(cov.sphere_geom[sp.first], dtype=np.int64),
            geom2=np.asarray(geom2, dtype=np.int64),
            geom_names=_geom_names(model),
        )
        self._pair_args = (
            pack_pairs(self.pairs, plane_geom),
            pack_spheres(cov.sphere_geom, cov.sphere_body, cov.sphere_offset, model.body_rootid),
        )
        self._rootid = np.asarray(model.body_rootid, dtype=np.int64)
        # Mocap roots' twists, rewritten each step (zero throughout in a model without mocap).
        self._twist = np.zeros((model.nbody, 6))
        self.scheduler: DUAScheduler | None = None
        self._time = 0.0
        self._steps_at_reset = 0
        self._frame_data: mujoco.MjData | None = None
        self._frame_cache: tuple = ()

    # ----------------------------------------------------------------------- setup

    def _pair_set(self) -> PairSet:
        sp, cov, b = self.sphere_pairs, self.covering, self.bounds
        body1 = cov.sphere_body[sp.first]
        # Half-space pairs: planes are static (covering/pairs reject moving planes).
        body2 = np.where(
            sp.is_halfspace, 0, cov.sphere_body[np.where(sp.is_halfspace, 0, sp.second)]
        )
        accel = b.accel[body1] + b.accel[body2]
        delta = b.vel_uncertainty[body1] + b.vel_uncertainty[body2]
        if self._mocap is not None and self.period > 1:
            # Mocap velocities are backward differences over one predictor period: their error
            # is A * period * h / 2, of which the discrete-time term already holds A * h / 2.
            in_mocap = np.zeros(self.model.nbody, dtype=bool)
            in_mocap[self._mocap.mocap_bodies] = True
            tree = in_mocap[np.asarray(self.model.body_rootid)]
            extra = np.where(tree, 0.5 * (self.period - 1) * self.model.opt.timestep, 0.0)
            delta = delta + (extra * b.accel)[body1] + (extra * b.accel)[body2]
        speed: npt.ArrayLike = np.inf
        if b.speed is not None:
            speed = np.where(sp.is_halfspace, b.speed[body1], b.speed[body1] + b.speed[body2])
        return PairSet(
            sp.first,
            sp.second,
            sp.eps,
            accel,
            halfspace=sp.is_halfspace,
            vel_uncertainty=delta,
            speed=speed,
        )

    # ----------------------------------------------------------------------- state

    def _check_data(self, data: mujoco.MjData) -> None:
        m = self.model
        if not isinstance(data, mujoco.MjData):
            raise InvalidInputError(
                f"data must be a mujoco.MjData, got {type(data).__name__}: pass "
                "mujoco.MjData(model) after mujoco.mj_forward(model, data)."
            )
        # The same object, or another one with the same geometry (one XML loaded twice): the
        # compiled step reads MjData without bounds checks, and the covering and the pair
        # filter must be this model's.
        if data.model is not m and not _same_geometry(data.model, m):
            raise InvalidInputError(
                f"data belongs to another MjModel ({data.model.ngeom} geoms, {data.model.nbody} "
                f"bodies; this predictor's has {m.ngeom} and {m.nbody}) whose geoms, bodies or "
                "collision filters differ: pass the MjData of this predictor's model, or build "
                "a Predictor for that model."
            )

    def _bind_frame(self, data: mujoco.MjData) -> tuple:
        """Build and cache the fused step's ``frame`` tuple (``_rigid_point``) for ``data``.

        MjData's buffers live as long as the MjData, and every attribute access builds a new
        numpy view (about a microsecond in all), so ``step`` rebuilds the views only when it is
        handed another ``MjData``.
        """
        # The kernel does no bounds checks: refuse an MjData of another model here.
        self._check_data(data)
        self._frame_data = data
        self._frame_cache = (
            data.geom_xpos,
            data.geom_xmat,
            data.cvel,
            data.subtree_com,
            self._twist,
            data.xpos,
        )
        return self._frame_cache

    def sphere_states(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """Centres and velocities of every covering sphere, ``(nsphere, 3)`` each.

        Vectorised, O(nsphere): used by ``reset``, rendering and tests, not by ``step``.
        """
        cov = self.covering
        c = sphere_centers(data.geom_xpos, data.geom_xmat, cov.sphere_geom, cov.sphere_offset)
        v = sphere_velocities(
            data.cvel, data.subtree_com, self.model.body_rootid, cov.sphere_body, c
        )
        if self._mocap is not None:
            twist = self._mocap.body_velocity(self.model.nbody)[self._rootid[cov.sphere_body]]
            v = (
                v
                + twist[:, 3:]
                + np.cross(twist[:, :3], c - data.xpos[self._rootid[cov.sphere_body]])
            )
        return c, v

    def halfspaces(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """Plane half-spaces: outward normals ``(nplane, 3)`` and offsets ``(nplane,)``."""
        g = np.asarray(self.covering.plane_geom, dtype=np.int64)
        if g.size == 0:
            return np.zeros((1, 3)), np.zeros(1)
        normals = np.asarray(data.geom_xmat)[g][:, [2, 5, 8]]
        return normals, np.einsum("ij,ij->i", normals, np.asarray(data.geom_xpos)[g])

    def _nonfinite(self, data: mujoco.MjData, pair: int | None = None) -> NonFiniteStateError:
        if pair is not None:
            g = {int(self._tables.geom1[pair]), int(self._tables.geom2[pair])}
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
        return ", ".join(repr(self._tables.geom_names[i]) for i in sorted(geoms))

    @staticmethod
    def _divergence_count(data: mujoco.MjData) -> int:
        return sum(int(data.warning[int(w)].number) for w in _DIVERGENCE_WARNINGS)

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
        names = [w.name for w in _DIVERGENCE_WARNINGS if data.warning[int(w)].number]
        return (
            f"MuJoCo reported a NaN, inf or huge value ({', '.join(names)}) and reset the "
            f"simulation state itself (data.time is now {data.time:g} s): the simulation "
            "diverged. Reduce model.opt.timestep or check the model and controls, then call "
            "predictor.reset(data)."
        )

    # ----------------------------------------------------------------------- protocol

    def reset(self, data: mujoco.MjData) -> Alarms:
        """Initial classification: tau of every active pair, bucketed (O(pairs)).

        Args:
            data: ``MjData`` with valid kinematics (after ``mj_forward`` or ``mj_step``).

        Returns:
            The alarms of the initial classification.

        Raises:
            InvalidInputError: ``data`` is not an MjData of this predictor's model.
            NonFiniteStateError: a position or velocity is NaN or inf.
        """
        frame = self._bind_frame(data)  # checks data
        if self._mocap is not None:
            # A reset starts a new trajectory: difference mocap poses within it only. Reset in
            # place: the Monitor's BoundMonitor holds this same tracker.
            self._mocap.reset()
            self._mocap.update(data)
        c, v = self.sphere_states(data)
        # qpos/qvel too: a NaN written without mj_forward leaves finite (stale) kinematics.
        finite = np.isfinite(c).all() and np.isfinite(v).all()
        if not (finite and np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()):
            raise self._nonfinite(data)
        halfspaces = self.halfspaces(data)
        tau0 = self.pairs.tau(np.arange(len(self.pairs)), c, v, halfspaces)
        self.scheduler = DUAScheduler(
            tau0, dt=self.dt, latency=self.latency, slots_per_bucket=self.slots_per_bucket
        )
        self._load_compiled(data, frame, (c, v, halfspaces))
        self._time = float(data.time)
        self._steps_at_reset = int(data.timer[int(mujoco.mjtTimer.mjTIMER_STEP)].number)
        ids = self.scheduler.initial_alarms
        return Alarms(0, self._time, ids, tau0[ids], self._tables)

    def _load_compiled(
        self,
        data: mujoco.MjData,
        frame: tuple,
        states: tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]],
    ) -> None:
        """Load what ``step`` runs from numba's cache (~10 ms each) now, not in ``step``.

        A real-time user holds every ``step`` to its deadline, the first one included. One
        step of a throw-away one-pair scheduler on the real tables (read only) loads the fused
        step, and one through ``select``/``update`` the path taken after pairs are switched
        back on; the mocap differencing runs on copies. ``states``: the sphere centres,
        velocities and half-spaces ``reset`` read.
        """
        if len(self.pairs):
            spare = DUAScheduler(np.full(1, np.inf), dt=self.dt)
            spare.step_rigid(self._pair_args, frame)
            ids = spare.select()
            spare.update(ids, self.pairs.tau(ids, *states))
        if self._mocap is not None:
            self._mocap.load_compiled(data, self._twist)

    def step(self, data: mujoco.MjData) -> Alarms:
        """One predictor step: evaluate the scheduled pairs, re-bucket, return the alarms.

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
        if self._mocap is not None:
            self._mocap.update(data, self._twist)
        frame = self._frame_cache if self._frame_data is data else self._bind_frame(data)
        if sched._reactivated:
            ids = sched.select()
            c, v = self.sphere_states(data)
            alarmed = sched.update(ids, self.pairs.tau(ids, c, v, self.halfspaces(data)))
        else:
            alarmed, bad = sched.step_rigid(self._pair_args, frame)
            if bad >= 0:
                raise self._nonfinite(data, bad)
        self._time = time
        return Alarms(sched.step_count, time, alarmed, sched.last_tau[alarmed], self._tables)

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

    def _require_scheduler(self) -> DUAScheduler:
        if self.scheduler is None:
            raise SchedulerError("call predictor.reset(data) first.")
        return self.scheduler

    # ----------------------------------------------------------------------- introspection

    @property
    def nsphere(self) -> int:
        """Number of covering spheres."""
        return int(self.covering.nsphere)

    @property
    def npairs(self) -> int:
        """Number of active sphere pairs."""
        return len(self.pairs)

    @property
    def evaluations_per_step(self) -> int:
        """tau evaluations per step (at most; empty and inactive slots are skipped)."""
        return self._require_scheduler().evaluations_per_step

    @property
    def pair_geoms(self) -> tuple[np.ndarray, np.ndarray]:
        """``(geom1, geom2)``, each ``(npairs,)``: the geoms of every sphere pair (``geom2`` is
        the plane geom for half-space pairs)."""
        return self._tables.geom1, self._tables.geom2

    def geom_pair_of(self, pairs: npt.ArrayLike) -> np.ndarray:
        """Index into ``geom_pairs`` of sphere pairs."""
        return np.asarray(self.sphere_pairs.geom_pair[np.asarray(pairs, dtype=np.int64)])
