"""``SpherePredictor``: collision alarms for free spheres given as raw states (the paper's setting).

No MuJoCo: the caller passes every sphere's centre and velocity every ``dt``, with a bound on
each centre's acceleration, and gets back the sphere pairs standing in alarm. Pairs are either
all ``N (N - 1) / 2`` of them (a plain schedule) or, for many spheres, the pruned set of
``neighbors.candidate_pairs`` at a horizon ``T``, rebuilt at least every
``pruned.rebuild_stride(T, dt, latency)`` steps into the deadline schedule with the kept pairs'
state carried over. Completeness of the pruned set: docs/many-objects.md.
"""

from __future__ import annotations

import enum
import warnings

import numpy as np
import numpy.typing as npt

from dua_mujoco.core.neighbors import candidate_pairs, reach
from dua_mujoco.core.pairset import PairSet
from dua_mujoco.core.pruned import (
    StandingAlarms,
    breaks_bounds,
    escapes,
    match_pairs,
    rebuild_stride,
)
from dua_mujoco.core.schedules import (
    DeadlineScheduler,
    Schedule,
    Scheduler,
    make_scheduler,
)
from dua_mujoco.core.schedules.deadline import (
    DEFAULT_ALARM_BACKOFF,
    check_alarm_backoff,
    check_max_evals,
)
from dua_mujoco.core.schedules.state import P_COUNT, P_DEFERRED, W_IDS
from dua_mujoco.core.validate import as_vectors, check_period, per_pair, real_array
from dua_mujoco.exceptions import (
    BoundViolationWarning,
    InvalidChoiceError,
    InvalidInputError,
    SchedulerError,
    ShapeError,
)

__all__ = ["AUTO_PRUNED_MIN", "DEFAULT_STRIDE", "PairMode", "SpherePredictor"]

AUTO_PRUNED_MIN = 256
"""``pairs="auto"`` prunes from this many spheres on. Measured by ``benchmarks/many.py``
(docs/many-objects.md): all pairs win below it (no rebuilds, no grid), pruned pairs above."""

DEFAULT_STRIDE = 32
"""Default steps between rebuilds: ``horizon = (DEFAULT_STRIDE + latency) dt``. Longer strides
rebuild less often but hold more pairs (the reach grows as ``T^2``); docs/many-objects.md."""


class PairMode(enum.Enum):
    """Which sphere pairs a ``SpherePredictor`` holds."""

    ALL = "all"
    """All ``N (N - 1) / 2`` pairs: no rebuilds; O(N^2) memory and set-up."""
    PRUNED = "pruned"
    """The pairs whose reachable balls over the horizon meet, rebuilt every stride."""
    AUTO = "auto"
    """``PRUNED`` from ``AUTO_PRUNED_MIN`` spheres on, ``ALL`` below (deadline schedule only)."""


def _per_sphere(name: str, value: npt.ArrayLike, n: int, *, allow_inf: bool = False) -> np.ndarray:
    """A bound, scalar or ``(n,)``, as an ``(n,)`` array (non-negative; finite unless allowed)."""
    return np.broadcast_to(per_pair(name, value, n, allow_inf=allow_inf), (n,)).copy()


class SpherePredictor:
    """Collision predictor over raw sphere states (centres and velocities every ``dt``).

    Args:
        radii: ``(N,)`` sphere radii (m), finite, ``>= 0``.
        accel: Scalar or ``(N,)`` bound on each centre's acceleration norm (m/s^2).
        dt: Period between calls (s), ``> 0``.
        latency: Periods a verdict takes to act (0: it acts at once, 1: one period later).
        margin: Extra distance (m) under which two spheres count as touching.
        pairs: ``"all"``, ``"pruned"`` or ``"auto"`` (a ``PairMode`` or its value).
        speed: Optional scalar or ``(N,)`` bound on each centre's speed (m/s), ``> 0``.
        vel_uncertainty: Scalar or ``(N,)`` bound on the error of each measured velocity (m/s).
        schedule: ``"deadline"`` (pruned sets need it), ``"dua"`` or ``"select-all"``.
        max_evals_per_step: Deadline only: optional cap on tau evaluations a step.
        alarm_backoff: Deadline only: longest interval (steps) between evaluations of a pair
            that keeps alarming, which stands in alarm in between (1: every step).
        horizon: Pruned only: the horizon ``T`` (s) of the reach, ``>= (1 + latency) dt``;
            default ``(DEFAULT_STRIDE + latency) dt``. Rebuilds come every
            ``rebuild_stride(T, dt, latency)`` steps.

    Attributes:
        mode: The ``PairMode`` in use (``ALL`` or ``PRUNED``, never ``AUTO``).
        stride: Pruned: steps between rebuilds (None for all pairs).
        evaluations: tau evaluations of the latest call.
        rebuilds: Rebuilds of the pruned set so far (the one in ``reset`` not counted).
        pairs: The ``PairSet`` held now (after ``reset``).
    """

    def __init__(
        self,
        radii: npt.ArrayLike,
        accel: npt.ArrayLike,
        *,
        dt: float,
        latency: int = 1,
        margin: float = 0.0,
        pairs: PairMode | str = "auto",
        speed: npt.ArrayLike | None = None,
        vel_uncertainty: npt.ArrayLike = 0.0,
        schedule: Schedule | str = "deadline",
        max_evals_per_step: int | None = None,
        alarm_backoff: int = DEFAULT_ALARM_BACKOFF,
        horizon: float | None = None,
    ) -> None:
        r = real_array("radii", radii)
        if r.ndim != 1 or r.shape[0] < 1:
            raise ShapeError(f"radii has shape {r.shape}; expected (N,), one radius per sphere.")
        n = r.shape[0]
        self.radii = _per_sphere("radii", r, n)
        self.accel = _per_sphere("accel", accel, n)
        self.vel_uncertainty = _per_sphere("vel_uncertainty", vel_uncertainty, n)
        self.speed = _per_sphere("speed", np.inf if speed is None else speed, n, allow_inf=True)
        if (self.speed == 0.0).any():
            i = int(np.flatnonzero(self.speed == 0.0)[0])
            raise InvalidInputError(
                f"speed[{i}] = 0.0 is invalid: a speed bound must be > 0 (None for no bound)."
            )
        self.dt, self.latency = check_period(dt, latency)
        self.margin = float(per_pair("margin", margin, 1)[0])
        try:
            mode = PairMode(pairs)
        except ValueError:
            raise InvalidChoiceError("pairs", pairs, [m.value for m in PairMode]) from None
        try:
            self.schedule = Schedule(schedule)
        except ValueError:
            raise InvalidChoiceError("schedule", schedule, [s.value for s in Schedule]) from None
        self.max_evals_per_step = check_max_evals(max_evals_per_step) or None
        self.alarm_backoff = check_alarm_backoff(alarm_backoff)
        if mode is PairMode.AUTO:
            prune = n >= AUTO_PRUNED_MIN and self.schedule is Schedule.DEADLINE
            mode = PairMode.PRUNED if prune else PairMode.ALL
        if mode is PairMode.PRUNED and self.schedule is not Schedule.DEADLINE:
            raise InvalidInputError(
                f"pairs='pruned' with schedule={self.schedule.value!r}: a pruned pair set is "
                "rebuilt into the deadline schedule only; pass schedule='deadline' or pairs='all'."
            )
        self.mode = mode
        self.horizon: float | None = None
        self.stride: int | None = None
        if mode is PairMode.PRUNED:
            T = (DEFAULT_STRIDE + self.latency) * self.dt if horizon is None else horizon
            self.stride = rebuild_stride(T, self.dt, self.latency)
            self.horizon = float(T)
        elif horizon is not None:
            raise InvalidInputError(
                f"horizon = {horizon!r} is given but pairs are {mode.value!r}: the horizon is "
                "the pruned set's; pass pairs='pruned' or drop horizon."
            )
        # The reach's horizon; held apart from ``horizon`` so that the tests can shorten it
        # alone and watch the guarantee break.
        self._reach_horizon = self.horizon
        self.n = n
        self.evaluations = 0
        self.rebuilds = 0
        self.pairs: PairSet | None = None
        self.scheduler: Scheduler | None = None
        self._keys = np.empty((0, 2), dtype=np.int64)
        self._standing: StandingAlarms | None = None
        self._anchor = np.empty((0, 3))
        self._speed0 = np.empty(0)
        # The escape test's buffers: every sphere, and the time since its anchor.
        self._ids = np.arange(n, dtype=np.int64)
        self._elapsed = np.empty(n)
        self._built_at = 0

    # ----------------------------------------------------------------------- introspection

    @property
    def npairs(self) -> int:
        """Pairs held now."""
        return 0 if self.pairs is None else len(self.pairs)

    @property
    def deferred(self) -> int:
        """Pairs due at the latest step but left for a later one (a capped deadline schedule)."""
        return 0 if self.scheduler is None else self.scheduler.deferred

    @property
    def keys(self) -> np.ndarray:
        """``(npairs, 2)`` sphere ids ``(i, j)``, ``i < j``, of the pairs held, sorted."""
        return self._keys

    # ----------------------------------------------------------------------- calls

    def _state(self, centers: npt.ArrayLike, velocities: npt.ArrayLike) -> tuple[np.ndarray, ...]:
        c = as_vectors("centers", centers)
        if c.shape[0] != self.n:
            raise ShapeError(
                f"centers has {c.shape[0]} rows but the predictor was built for {self.n} "
                "spheres: pass one row per sphere, every call (build a new predictor for a "
                "different N)."
            )
        v = as_vectors("velocities", velocities, self.n)
        return c, v

    def _pair_set(self, keys: np.ndarray) -> PairSet:
        i, j = keys[:, 0], keys[:, 1]
        return PairSet(
            i,
            j,
            self.radii[i] + self.radii[j] + self.margin,
            self.accel[i] + self.accel[j],
            vel_uncertainty=self.vel_uncertainty[i] + self.vel_uncertainty[j],
            speed=self.speed[i] + self.speed[j],
        )

    def _candidates(self, c: np.ndarray, v: np.ndarray) -> np.ndarray:
        speed0 = np.sqrt(np.einsum("ij,ij->i", v, v))
        assert self._reach_horizon is not None
        r = reach(
            self.radii,
            speed0,
            self.accel,
            self._reach_horizon,
            vel_uncertainty=self.vel_uncertainty,
            speed_bound=self.speed,
        )
        self._anchor, self._speed0 = c.copy(), speed0
        return candidate_pairs(c, r, margin=self.margin)

    def _output(self) -> np.ndarray:
        assert self._standing is not None
        return self._keys[self._standing.ids()]

    def reset(self, centers: npt.ArrayLike, velocities: npt.ArrayLike) -> np.ndarray:
        """Initial classification at time 0: tau of every pair held.

        Args:
            centers: ``(N, 3)`` sphere centres (m), finite.
            velocities: ``(N, 3)`` centre velocities (m/s), finite.

        Returns:
            ``(k, 2)`` int64 sphere pairs ``(i, j)``, ``i < j``, sorted, standing in alarm.
        """
        c, v = self._state(centers, velocities)
        if self.mode is PairMode.PRUNED:
            keys = self._candidates(c, v)
        else:
            i, j = np.triu_indices(self.n, k=1)
            keys = np.stack([i, j], axis=1).astype(np.int64)
        self._keys = keys
        self.pairs = self._pair_set(keys)
        tau0 = self.pairs.tau(np.arange(len(self.pairs)), c, v)
        self.scheduler = self._make(tau0)
        self._standing = StandingAlarms(len(self.pairs), self.scheduler.initial_alarms)
        self.evaluations = len(self.pairs)
        self.rebuilds = 0
        self._built_at = 0
        return self._output()

    def _make(self, tau0: np.ndarray) -> Scheduler:
        return make_scheduler(
            self.schedule,
            tau0,
            dt=self.dt,
            latency=self.latency,
            max_evals_per_step=self.max_evals_per_step,
            alarm_backoff=self.alarm_backoff,
        )

    def _rebuild(self, c: np.ndarray, v: np.ndarray, step: int) -> None:
        """New candidates at this step's state; kept pairs carry their verdicts (O(N + K))."""
        sched = self.scheduler
        assert isinstance(sched, DeadlineScheduler)
        keys = self._candidates(c, v)
        src = match_pairs(self._keys, keys)
        sched.remap(src, step)
        self._keys = keys
        self.pairs = self._pair_set(keys)
        # Kept pairs stand as their verdicts say; new ones stand (-inf) until this step's
        # selection evaluates them.
        self._standing = StandingAlarms(len(keys), np.flatnonzero(sched.alarm_state()))
        self._built_at = step
        self.rebuilds += 1

    def _escaped(self, c: np.ndarray, v: np.ndarray, t: float) -> bool:
        """Whether a sphere may have left the reach of the last rebuild, ``t`` seconds on (the
        native step's escape test); a warning when its state proves its bounds broken."""
        bounds = (self._anchor, self._speed0, self.accel, self.vel_uncertainty, self.speed)
        out = escapes(c, v, *bounds, t, ids=self._ids, elapsed=self._elapsed)
        if out.size == 0:
            return False
        broken = breaks_bounds(out, c, v, *bounds, t)
        if broken.size:
            warnings.warn(
                f"sphere {int(broken[0])} moved farther or faster than its bounds allow since "
                f"the last rebuild (step {self._built_at}): the guarantee does not hold there; "
                "the pair set is rebuilt now. Check accel/speed/vel_uncertainty.",
                BoundViolationWarning,
                stacklevel=3,
            )
        return True

    def step(self, centers: npt.ArrayLike, velocities: npt.ArrayLike) -> np.ndarray:
        """One period later: evaluate the pairs due, rebuild the pruned set if due, alarm.

        Args:
            centers: ``(N, 3)`` sphere centres (m) at this step, finite.
            velocities: ``(N, 3)`` centre velocities (m/s) at this step, finite.

        Returns:
            ``(k, 2)`` int64 sphere pairs ``(i, j)``, ``i < j``, sorted, standing in alarm
            after this step's verdicts.

        Raises:
            SchedulerError: ``step`` before ``reset``.
            ShapeError, NonFiniteStateError: the state is malformed or not finite.
        """
        sched = self.scheduler
        if sched is None or self.pairs is None or self._standing is None:
            raise SchedulerError("step() before reset(): call reset(centers, velocities) first.")
        c, v = self._state(centers, velocities)
        n = sched.step_count + 1
        if self.mode is PairMode.PRUNED:
            assert self.stride is not None
            due = n - self._built_at >= self.stride
            if not due:
                due = self._escaped(c, v, (n - self._built_at) * self.dt)
            if due:
                self._rebuild(c, v, n)
        # The state was checked finite above: the fused step cannot stop on it.
        alarms = sched.step_points(self.pairs, c, v)
        params = sched.state.params
        count = int(params[P_COUNT])
        # Deferred pairs follow the evaluated ones in the selection: their verdicts were
        # renewed too (standing in alarm if they no longer cover the wait).
        renewed = sched.state.work[W_IDS, : count + int(params[P_DEFERRED])]
        self._standing.renew(renewed, alarms)
        self.evaluations = count
        return self._output()

    def alarm_ids(self) -> np.ndarray:
        """``(k,)`` ids (into :attr:`keys`) of the pairs standing in alarm."""
        if self._standing is None:
            raise SchedulerError("alarm_ids() before reset(): call reset() first.")
        return self._standing.ids()
