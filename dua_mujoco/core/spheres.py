"""``SpherePredictor``: collision alarms for free spheres given as raw states (the paper's setting).

No MuJoCo: the caller passes every sphere's centre and velocity every ``dt``, with a bound on
each centre's acceleration, and gets back the sphere pairs standing in alarm. The predictor is
the native runtime that ``Predictor`` and the MuJoCo plugin run (``dua_mujoco._core.Runtime``,
``csrc/src/runtime.cc``), on N point bodies whose states the caller gives: this class checks its
options, builds the tables (``config`` and the per-sphere ``reach``, ``csrc/src/tables.cc:
FreeTables``) and makes each call one native call, which checks the states. Pairs are all
``N (N - 1) / 2`` of them (a plain schedule) or, for many spheres, the pruned set of pairs whose
reachable balls over a horizon ``T`` meet, rebuilt every :func:`rebuild_stride` steps and renewed
in between for the spheres that may have left their reach. Completeness: docs/many-objects.md
and docs/theory.md, Lemmas 6.4 and 6.5.
"""

from __future__ import annotations

import enum
import math

import numpy as np
import numpy.typing as npt

import dua_mujoco._core as _core
from dua_mujoco.core.pairset import PairSet
from dua_mujoco.core.schedules import Schedule, Scheduler, as_schedule, schedule_config
from dua_mujoco.core.schedules.deadline import (
    DEFAULT_ALARM_BACKOFF,
    check_alarm_backoff,
    check_max_evals,
)
from dua_mujoco.core.validate import as_choice, check_period, per_pair, per_sphere, real_array
from dua_mujoco.exceptions import InvalidInputError, SchedulerError, ShapeError

__all__ = [
    "AUTO_PRUNED_MIN",
    "DEFAULT_STRIDE",
    "RENEW_MAX",
    "PairMode",
    "SpherePredictor",
    "pair_mode",
    "pruned_horizon",
    "rebuild_stride",
    "runtime_count",
]

AUTO_PRUNED_MIN = 256
"""``pairs="auto"`` prunes from this many spheres on. Measured by ``benchmarks/many.py``
(docs/many-objects.md): all pairs win below it (no rebuilds, no grid), pruned pairs above."""

DEFAULT_STRIDE = 32
"""Default steps between rebuilds: ``horizon = (DEFAULT_STRIDE + latency) dt`` (plus ``dt - h``
for a MuJoCo predictor stepping every ``p > 1`` physics steps of ``h``). Longer strides
rebuild less often but hold more pairs (the reach grows as ``T^2``); docs/many-objects.md."""

RENEW_MAX = 512
"""Most escaped spheres a step renews alone (``k N`` pair tests, ~1.1 ns each); more, and the
whole held set is rebuilt (O(N + K), ~1 us a sphere on swarms), so that a renewal costs at most
about half a rebuild at any ``N`` (measured, docs/many-objects.md)."""

_LAYOUT = _core.LAYOUT


class PairMode(enum.Enum):
    """Which sphere pairs a ``SpherePredictor`` holds."""

    ALL = "all"
    """All ``N (N - 1) / 2`` pairs: no rebuilds; O(N^2) memory and set-up."""
    PRUNED = "pruned"
    """The pairs whose reachable balls over the horizon meet, rebuilt every stride."""
    AUTO = "auto"
    """``PRUNED`` from ``AUTO_PRUNED_MIN`` spheres on, ``ALL`` below (deadline schedule only)."""


def rebuild_stride(horizon: float, dt: float, latency: int, *, grid: float = 0.0) -> int:
    """Steps ``R`` between rebuilds at horizon ``T``: the largest with
    ``(R + latency) dt + grid <= T``.

    A pair left out at the rebuild of step ``r`` cannot touch before ``r dt + T``; if it is
    added at the next rebuild, step ``r + R``, it is evaluated there and its verdict acts from
    ``(r + R + latency) dt <= r dt + T`` (docs/many-objects.md). ``grid``: ``dt - h`` when the
    predictor steps every ``p > 1`` physics steps of ``h`` (0 otherwise): a contact just after
    ``r dt + T`` may fall between two predictor steps, and the alarm must lead it by the
    horizon from the one before (docs/theory.md, section 8). The product is computed as the
    deadline schedule computes it (``(s + latency) * dt``).

    Raises:
        InvalidInputError: ``T < (1 + latency) dt + grid``: not even one step would be covered.
    """
    dt, latency = check_period(dt, latency)
    T = float(horizon)
    if not (math.isfinite(T) and (1 + latency) * dt + grid <= T):
        # The grid's term named only where it is in the sum (free spheres have no timestep).
        rule = "(1 + latency) dt + (dt - timestep)" if grid else "(1 + latency) dt"
        raise InvalidInputError(
            f"horizon = {horizon!r} is invalid: a pruned pair set must cover at least one step "
            f"and the latency, horizon >= {rule} = {(1 + latency) * dt + grid!r} s; pass a "
            "longer horizon (or None for the default)."
        )
    R = max(1, math.floor(T / dt) - latency)
    # The division rounds either way: settle R on the product itself.
    while R > 1 and (R + latency) * dt + grid > T:
        R -= 1
    while (R + 1 + latency) * dt + grid <= T:
        R += 1
    return R


def pair_mode(
    pairs: PairMode | str, horizon: float | None, *, nsphere: int, deadline: bool
) -> PairMode:
    """The pairs a predictor holds, ``ALL`` or ``PRUNED`` (``SpherePredictor``'s and
    ``Predictor``'s ``pairs`` and ``horizon``): ``"auto"`` prunes from ``AUTO_PRUNED_MIN`` spheres
    with the deadline schedule, the one a pruned set is rebuilt into."""
    mode = as_choice(PairMode, pairs, "pairs")
    if mode is PairMode.AUTO:
        mode = PairMode.PRUNED if nsphere >= AUTO_PRUNED_MIN and deadline else PairMode.ALL
    if mode is PairMode.PRUNED and not deadline:
        raise InvalidInputError(
            "pairs='pruned' needs the deadline schedule: a pruned pair set is rebuilt into it "
            "only; pass schedule='deadline' or pairs='all'."
        )
    if mode is PairMode.ALL and horizon is not None:
        raise InvalidInputError(
            f"horizon = {horizon!r} is given but pairs are 'all': the horizon is the pruned "
            "set's; pass pairs='pruned' or drop horizon."
        )
    return mode


def pruned_horizon(
    horizon: float | None, dt: float, ahead: int, *, grid: float = 0.0
) -> tuple[float, int]:
    """A pruned set's horizon ``T`` and rebuild stride: ``T`` None is ``(DEFAULT_STRIDE +
    ahead) dt + grid``; ``ahead``, the periods a verdict must see past the next step (the
    latency, plus the alarm horizon's periods beyond one), stands for the latency of
    :func:`rebuild_stride`, which checks ``T``, as ``grid``."""
    T = (DEFAULT_STRIDE + ahead) * dt + grid if horizon is None else horizon
    return float(T), rebuild_stride(T, dt, ahead, grid=grid)


def runtime_count(name: str, doc: str) -> property:
    """A read-only int property: the count ``name`` of the object's native runtime (``_rt``)."""
    return property(lambda self: int(getattr(self._rt, name)), doc=doc)


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
        self.radii = per_sphere("radii", r, n)
        self.accel = per_sphere("accel", accel, n)
        self.vel_uncertainty = per_sphere("vel_uncertainty", vel_uncertainty, n)
        self.speed = per_sphere("speed", np.inf if speed is None else speed, n, allow_inf=True)
        if (self.speed == 0.0).any():
            i = int(np.flatnonzero(self.speed == 0.0)[0])
            raise InvalidInputError(
                f"speed[{i}] = 0.0 is invalid: a speed bound must be > 0 (None for no bound)."
            )
        self.dt, self.latency = check_period(dt, latency)
        self.margin = float(per_pair("margin", margin, 1)[0])
        self.schedule = as_schedule(schedule)
        self.max_evals_per_step = check_max_evals(max_evals_per_step) or None
        self.alarm_backoff = check_alarm_backoff(alarm_backoff)
        deadline = self.schedule is Schedule.DEADLINE
        self.mode = pair_mode(pairs, horizon, nsphere=n, deadline=deadline)
        self.horizon: float | None = None
        self.stride: int | None = None
        if self.mode is PairMode.PRUNED:
            self.horizon, self.stride = pruned_horizon(horizon, self.dt, self.latency)
        self.n = n
        self._rt = self._runtime(self.horizon)
        self._scheduler: Scheduler | None = None

    def _runtime(self, reach_horizon: float | None) -> _core.Runtime:
        """The native runtime on this predictor's tables, the reach over ``reach_horizon`` (the
        horizon, which the tests shorten alone to watch the guarantee break)."""
        c = schedule_config(
            self.schedule,
            dt=self.dt,
            latency=self.latency,
            max_evals_per_step=self.max_evals_per_step,
            alarm_backoff=self.alarm_backoff,
        )
        c[_LAYOUT["CFG_MARGIN"]] = self.margin
        c[_LAYOUT["CFG_HAS_SPEED"]] = bool(np.isfinite(self.speed).any())
        if self.stride is not None:
            c[_LAYOUT["CFG_PRUNED"]] = 1
            c[_LAYOUT["CFG_HORIZON"]] = reach_horizon
            c[_LAYOUT["CFG_STRIDE"]], c[_LAYOUT["CFG_RENEW_MAX"]] = self.stride, RENEW_MAX
        reach = np.stack([self.radii, self.accel, self.vel_uncertainty, self.speed], axis=1)
        tables = _core.Tables.free({"config": c, "reach": reach})
        # One step's worth of alarm log (its whole selection, at worst), rewound at every step:
        # nothing here holds the runtime's Alarms.
        return _core.Runtime(tables, None, None, 1, 0)

    # ----------------------------------------------------------------------- introspection

    @property
    def npairs(self) -> int:
        """Pairs held now."""
        return int(self._rt.schedule.last_tau.shape[0])  # (a view: O(1))

    evaluations = runtime_count("evaluated", "tau evaluations of the latest call.")
    deferred = runtime_count(
        "deferred", "Pairs due at the latest step but left for a later one (a capped schedule)."
    )
    rebuilds = runtime_count("rebuilds", "Rebuilds of the pruned set so far (not the reset's).")
    renewals = runtime_count(
        "renewals", "Renewals of the pruned set so far: steps whose escaped spheres were anchored."
    )

    @property
    def keys(self) -> np.ndarray:
        """``(npairs, 2)`` sphere ids ``(i, j)``, ``i < j``, of the pairs held, in the order of
        :attr:`scheduler`'s pair ids (all pairs: increasing)."""
        return self._rt.held_records[:, :2].astype(np.int64)

    @property
    def pairs(self) -> PairSet:
        """The ``PairSet`` held now (a copy of the runtime's records)."""
        rec = self._rt.held_records
        return PairSet(rec[:, 0], rec[:, 1], rec[:, 3], rec[:, 4], vel_uncertainty=rec[:, 5],
                       speed=rec[:, 6])  # fmt: skip

    @property
    def scheduler(self) -> Scheduler | None:
        """The schedule the runtime runs now, as a read-only ``Scheduler`` over :attr:`keys`
        (None before ``reset``). A reset and, pruned, a rebuild or renewal replace it."""
        if not self._rt.classified:
            return None
        core = self._rt.schedule
        if self._scheduler is None or self._scheduler.core is not core:
            self._scheduler = Scheduler.of(core, read_only=True)
        return self._scheduler

    def alarm_ids(self) -> np.ndarray:
        """``(k,)`` ids (into :attr:`keys`) of the pairs standing in alarm, increasing."""
        sched = self.scheduler
        if sched is None:
            raise SchedulerError("alarm_ids() before reset(): call reset() first.")
        return np.flatnonzero(sched.alarm_state())

    # ----------------------------------------------------------------------- calls

    def reset(self, centers: npt.ArrayLike, velocities: npt.ArrayLike) -> np.ndarray:
        """Initial classification at time 0: tau of every pair held.

        Args:
            centers: ``(N, 3)`` sphere centres (m), finite.
            velocities: ``(N, 3)`` centre velocities (m/s), finite.

        Returns:
            ``(k, 2)`` int64 sphere pairs ``(i, j)``, ``i < j``, sorted, standing in alarm.

        Raises:
            ShapeError, NonFiniteStateError: the state is malformed or not finite.
        """
        c = np.asarray(centers, dtype=np.float64)
        return self._rt.classify_spheres(c, np.asarray(velocities, dtype=np.float64))

    def step(self, centers: npt.ArrayLike, velocities: npt.ArrayLike) -> np.ndarray:
        """One period later: evaluate the pairs due, rebuild or renew the pruned set, alarm.

        The state and the result as :meth:`reset`'s, at this step and after its verdicts. A
        sphere whose state proves its bounds broken since its anchor warns
        (``BoundViolationWarning``): the guarantee does not hold for its pairs then.

        Raises:
            SchedulerError: ``step`` before ``reset``.
            ShapeError, NonFiniteStateError: the state is malformed or not finite.
        """
        c = np.asarray(centers, dtype=np.float64)
        return self._rt.step_spheres(c, np.asarray(velocities, dtype=np.float64))
