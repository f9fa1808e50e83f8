"""The exact stage: alarms held against MuJoCo's own contacts, and the run's metrics.

``Monitor.observe`` is fed every physics step with the predictor's alarms when it stepped (the
bound check, the alarms, then the contacts in ``d.contact``). A *contact onset* is a geom pair of
the active set that is in ``d.contact`` now and was not at the previous physics step. It is
*predicted* when, at that instant, some sphere pair of that geom pair stands alarmed, i.e. its
latest evaluation (at or before the onset) raised an alarm: exactly the completeness theorem's
claim (docs/theory.md). A miss is *valid-bounds* when neither body broke its declared bounds
between that latest evaluation and the onset, so the theorem's hypotheses held and the miss
would be a bug.

``run`` drives a rollout (controller, ``mj_step``, predictor every ``period`` steps, monitor) and
returns a ``RunReport``.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

from dua_mujoco.mj.checks import BoundMonitor
from dua_mujoco.exceptions import DeadlineOverrunWarning, InvalidInputError
from dua_mujoco.mj.alarms import Alarms
from dua_mujoco.mj.predictor import Predictor
from dua_mujoco.mj.tables import same_geometry
from dua_mujoco.progress import Progress

__all__ = ["Miss", "Monitor", "RunReport", "run"]

Controller = Callable[[mujoco.MjModel, mujoco.MjData], None]

# mj_geomDistance stops searching beyond this distance (m); alarmed pairs are far closer.
_DISTMAX = 100.0

_NONE = np.zeros(0, dtype=np.int64)


@dataclasses.dataclass(frozen=True)
class Miss:
    """A contact onset that no standing alarm covered."""

    physics_step: int
    time: float
    geom1: str
    geom2: str
    bounds_held: bool
    last_evaluation_step: int
    last_tau: float


@dataclasses.dataclass(frozen=True)
class RunReport:
    """Metrics of a monitored run (``to_dict`` gives the CLI's JSON report)."""

    scene: str
    physics_steps: int
    predictor_steps: int
    period: int
    spheres: int
    pairs: int
    geom_pairs: int
    evals_per_step: float
    contact_onsets: int
    predicted_onsets: int
    missed_onsets: int
    missed_onsets_valid_bounds: int
    inactive_pair_contacts: int
    unfiltered_contacts: int
    alarm_episodes: int
    false_alarm_episodes: int
    lead_time_mean_s: float | None
    bound_violations: int
    deadline_overruns: int
    exact_distance_median_m: float | None
    predictor_us_per_step: float
    mj_step_us_per_step: float
    misses: tuple[Miss, ...] = ()
    alarms_per_step: tuple[int, ...] = ()
    min_tau_per_step: tuple[float, ...] = ()
    realtime: bool = False

    @property
    def evals_fraction(self) -> float:
        """tau evaluations per step as a fraction of all pairs (SA's cost)."""
        return self.evals_per_step / max(self.pairs, 1)

    @property
    def predictor_share(self) -> float:
        """Predictor time per physics step over ``mj_step`` time (medians).

        ``predictor_us_per_step`` is per predictor call, made every ``period`` physics steps.
        """
        if self.mj_step_us_per_step <= 0.0:
            return 0.0
        return self.predictor_us_per_step / (self.period * self.mj_step_us_per_step)

    def to_dict(self, *, series: bool = False) -> dict[str, Any]:
        """JSON-ready dict; ``series=True`` adds the per-step alarm and tau series."""
        out = dataclasses.asdict(self)
        out["misses"] = [dataclasses.asdict(m) for m in self.misses]
        out["predictor_share"] = self.predictor_share
        if not series:
            out.pop("alarms_per_step")
            out.pop("min_tau_per_step")
        else:
            out["min_tau_per_step"] = [
                None if not np.isfinite(t) else t for t in self.min_tau_per_step
            ]
        return out

    def summary_rows(self) -> list[tuple[str, str]]:
        """(label, value) rows for a readable table."""
        lead = "n/a" if self.lead_time_mean_s is None else f"{self.lead_time_mean_s * 1e3:.1f} ms"
        rows = [
            ("scene", self.scene),
            ("physics steps (predictor period)", f"{self.physics_steps} ({self.period})"),
            (
                "spheres / sphere pairs / geom pairs",
                f"{self.spheres} / {self.pairs} / {self.geom_pairs}",
            ),
            (
                "tau evaluations per step",
                f"{self.evals_per_step:.1f} ({100 * self.evals_fraction:.2f} % of SA)",
            ),
            ("contact onsets", str(self.contact_onsets)),
            ("predicted onsets", str(self.predicted_onsets)),
            ("missed onsets", str(self.missed_onsets)),
            ("  of them while the bounds held", str(self.missed_onsets_valid_bounds)),
            ("contacts in switched-off pairs", str(self.inactive_pair_contacts)),
            ("alarm episodes (false)", f"{self.alarm_episodes} ({self.false_alarm_episodes})"),
            ("mean lead time", lead),
            ("bound violations (body-steps)", str(self.bound_violations)),
            (
                "predictor us/call vs mj_step us/step",
                f"{self.predictor_us_per_step:.1f} vs {self.mj_step_us_per_step:.1f} "
                f"({100 * self.predictor_share:.0f} % of physics time)",
            ),
        ]
        if self.realtime:
            rows.append(("deadline overruns", str(self.deadline_overruns)))
        if self.exact_distance_median_m is not None:
            rows.append(
                ("median exact distance of alarmed pairs", f"{self.exact_distance_median_m:.4f} m")
            )
        return rows

    def table(self) -> str:
        """The summary as an aligned two-column text table."""
        rows = self.summary_rows()
        w = max(len(k) for k, _ in rows)
        return "\n".join(f"{k.ljust(w)}  {v}" for k, v in rows)


class Monitor:
    """Exact stage and metrics for one predictor on one ``MjData``.

    Args:
        predictor: A predictor (``reset`` is called by ``start``).
        check_bounds: Run a ``BoundMonitor`` each physics step (needed to tell valid-bound
            misses from misses after a broken bound).
        realtime: Treat the predictor period as a deadline: a predictor step slower than
            ``predictor.dt`` counts as an overrun and warns once (the "cannot keep up" signal).
        geom_distance: Also measure the exact distance (``mj_geomDistance``) of every alarmed
            geom pair at each predictor step: how far the exact stage finds alarmed pairs.

    An *alarm episode* of a geom pair is a maximal run of physics steps during which at least one
    of its sphere pairs stands alarmed (repeats counted once, as the paper does). It is *false*
    when the pair touches at none of its steps nor at any step up to ``horizon`` seconds after
    the step that withdrew it (a later episode of the same pair does not cut that window short),
    where ``horizon`` is the longest revisit horizon among the alarms that opened it. Episodes
    whose window is still open when the run ends count as false if no contact was seen.

    Pairs switched off or on (``set_active_bodies``, ``deactivate_contacts``) and
    ``predictor.reset`` between physics steps are followed: the standing alarms are re-read from
    the scheduler before the next step's contacts are checked.
    """

    def __init__(
        self,
        predictor: Predictor,
        *,
        check_bounds: bool = True,
        realtime: bool = False,
        geom_distance: bool = False,
    ) -> None:
        self.predictor = predictor
        self.model = predictor.model
        self.realtime = realtime
        self.geom_distance = geom_distance
        cov = predictor.covering
        self.bounds = (
            BoundMonitor(
                self.model,
                predictor.bounds,
                (cov.sphere_geom, cov.sphere_body, cov.sphere_offset),
                mocap=predictor.mocap,
                mocap_period=predictor.period,
            )
            if check_bounds
            else None
        )
        gp = predictor.sphere_pairs.geom_pair
        self._ngp = predictor.geom_pairs.npair
        order = np.argsort(gp, kind="stable")
        self._gp_order = order
        self._gp_start = np.searchsorted(gp[order], np.arange(self._ngp + 1))
        self._gp_body = np.stack(
            [
                np.asarray(self.model.geom_bodyid)[predictor.geom_pairs.geom1],
                np.asarray(self.model.geom_bodyid)[predictor.geom_pairs.geom2],
            ],
            axis=1,
        )
        self._names = predictor.tables.geom_names

    # ------------------------------------------------------------------- lifecycle

    def start(self, data: mujoco.MjData) -> Alarms:
        """Reset the predictor on ``data`` and start counting."""
        alarms = self.predictor.reset(data)
        self.physics_step = 0
        self._pred_steps = [0]  # predictor step -> physics step
        self._time = float(data.time)
        self._in_contact = self._contacts(data)[0]
        # The same set as a mask: lookups by gathering, not by np.isin (which sorts; 47 us a
        # call with the thousands of pending windows of paper_world:200).
        self._contact_mask = np.zeros(self._ngp, dtype=bool)
        self._contact_mask[self._in_contact] = True
        self._last_violation = np.full(self.model.nbody, -1, dtype=np.int64)
        self._standing = np.zeros(self._ngp, dtype=np.int64)
        self._pair_alarm = np.zeros(self.predictor.nsphere_pairs, dtype=bool)
        self._scheduler = self.predictor.scheduler
        self._activation_seen = self.predictor.scheduler.activation_changes  # type: ignore[union-attr]
        self._episode_start = np.full(self._ngp, np.nan)
        self._episode_horizon = np.zeros(self._ngp)
        self._episode_touch = np.zeros(self._ngp, dtype=bool)
        # Ended episodes whose window is still open: geom pair, deadline, contact seen. Each
        # keeps its own window even if a new episode of the same pair starts inside it.
        self._pending_pair = np.zeros(0, dtype=np.int64)
        self._pending_deadline = np.zeros(0)
        self._pending_touch = np.zeros(0, dtype=bool)
        self.onsets = 0
        self.predicted = 0
        self.lead_times: list[float] = []
        self.misses: list[Miss] = []
        self.inactive_contacts = 0
        self.unfiltered_contacts = 0
        self.episodes = 0
        self.false_episodes = 0
        self.violations = 0
        self.overruns = 0
        self.evaluations: list[int] = []
        self.exact_distances: list[float] = []
        self.alarms_per_step: list[int] = [len(alarms)]
        self.min_tau: list[float] = [float(np.min(alarms.tau, initial=np.inf))]
        if self.bounds is not None:
            self.bounds.update(self.model, data)
        self._apply_alarms(alarms.pairs, np.arange(self.predictor.nsphere_pairs), data.time)
        return alarms

    def _contacts(self, data: mujoco.MjData) -> tuple[np.ndarray, int]:
        """Active geom pairs in contact (sorted ids) and the count of contacts outside them.

        O(ncon), not O(geom pairs): the monitor runs every physics step.
        """
        nc = int(data.ncon)
        if nc == 0:
            return _NONE, 0
        gp = self.predictor.geom_pairs.indices_of(data.contact.geom1[:nc], data.contact.geom2[:nc])
        return np.unique(gp[gp >= 0]), int((gp < 0).sum())

    # ------------------------------------------------------------------- alarms

    def _apply_alarms(self, alarmed: np.ndarray, evaluated: np.ndarray, t: float) -> None:
        """Update the standing alarms from the pairs ``evaluated`` (``alarmed`` among them)."""
        sched = self.predictor.scheduler
        assert sched is not None
        gp = self.predictor.sphere_pairs.geom_pair
        ids = np.union1d(evaluated, alarmed)
        new = sched.alarm_state(ids) & sched.active[ids]
        old = self._pair_alarm[ids]
        touched = np.unique(gp[ids])
        before = self._standing[touched]  # a copy (fancy indexing)
        np.add.at(self._standing, gp[ids], new.astype(np.int64) - old.astype(np.int64))
        self._pair_alarm[ids] = new
        after = self._standing[touched]
        begins = (before == 0) & (after > 0)
        started = touched[begins]
        ended = touched[(before > 0) & (after == 0)]
        if started.size:
            self.episodes += int(started.size)
            self._episode_start[started] = t
            self._episode_touch[started] = False
            # An episode's horizon: the longest revisit horizon among the alarms that opened it.
            h = np.zeros(touched.size)
            if alarmed.size:
                at = np.searchsorted(touched, gp[alarmed])
                np.maximum.at(h, at, sched.horizon_of(alarmed))
            self._episode_horizon[started] = h[begins]
        if ended.size:
            self._pending_pair = np.concatenate([self._pending_pair, ended])
            self._pending_deadline = np.concatenate(
                [self._pending_deadline, t + self._episode_horizon[ended]]
            )
            self._pending_touch = np.concatenate([self._pending_touch, self._episode_touch[ended]])

    def _follow_reset(self) -> None:
        """After ``predictor.reset`` (a new scheduler), count predictor steps from its reset.

        The reset came after the last observed physics step; its initial classification is
        applied by the next :meth:`_sync_switches`.
        """
        if self.predictor.scheduler is not self._scheduler:
            self._scheduler = self.predictor.scheduler
            self._pred_steps = [self.physics_step]
            self._activation_seen = -1

    def _sync_switches(self, exclude: np.ndarray | None = None) -> None:
        """Re-read the standing alarms after switches (or a reset) between physics steps.

        Pairs switched off stop counting towards their geom pair's standing alarm, pairs switched
        on stand in alarm until evaluated (``DUAScheduler.set_active``). Outside such changes
        ``_pair_alarm`` equals the scheduler's ``alarm_state() & active`` pair for pair, so
        comparing the two finds every change (an off and on again in between included). The
        changes date from before this step: they are stamped with the previous step's time.
        ``exclude``: the pairs evaluated at this step, whose state the evaluation gives.
        O(pairs), only on steps after a change.
        """
        sched = self.predictor.scheduler
        assert sched is not None
        if sched.activation_changes == self._activation_seen:
            return
        self._activation_seen = sched.activation_changes
        now = sched.alarm_state() & sched.active
        differs = now != self._pair_alarm
        if exclude is not None:
            differs[exclude] = False
        changed = np.flatnonzero(differs)
        if changed.size:
            self._apply_alarms(changed[now[changed]], changed, self._time)

    def _observe_alarms(self, data: mujoco.MjData, alarms: Alarms) -> None:
        sched = self.predictor.scheduler
        assert sched is not None
        self._pred_steps.append(self.physics_step)
        evaluated = sched.last_selected
        self.evaluations.append(int(evaluated.size))
        self._apply_alarms(alarms.pairs, evaluated, float(data.time))
        if self.geom_distance and len(alarms):
            for g1, g2 in sorted(alarms.geom_pairs):
                self.exact_distances.append(
                    float(mujoco.mj_geomDistance(self.model, data, g1, g2, _DISTMAX, None))
                )
        self.alarms_per_step.append(len(alarms))
        self.min_tau.append(float(alarms.tau.min()) if len(alarms) else np.inf)

    # ------------------------------------------------------------------- physics

    def observe(self, data: mujoco.MjData, alarms: Alarms | None = None) -> None:
        """Check one physics step: call after every ``mj_step`` (and ``predictor.step``).

        Args:
            data: The data after ``mj_step``.
            alarms: The predictor's alarms if it stepped on this physics step. They are applied
                before the contacts are checked: an evaluation of this instant is "at or before"
                a contact of this instant (Theorem 2).
        """
        self._follow_reset()
        self.physics_step += 1
        if self.bounds is not None:
            broke = self.bounds.update(self.model, data)
            if broke.size:
                self._last_violation[broke] = self.physics_step
                self.violations += int(broke.size)
        sched = self.predictor.scheduler
        assert sched is not None
        if alarms is not None and alarms.step != sched.step_count:
            # predictor.reset came between step() and here: its classification is of this
            # instant, and these alarms belong to the scheduler it replaced.
            self._pred_steps = [self.physics_step]
            alarms = None
        if alarms is None:
            self._sync_switches()
        else:
            # Switches between steps first, stamped with the previous step's time; the pairs
            # evaluated now get their current state from this step's evaluation.
            self._sync_switches(exclude=sched.last_selected)
            self._observe_alarms(data, alarms)
        now, unfiltered = self._contacts(data)
        self.unfiltered_contacts += unfiltered
        t = float(data.time)
        self._episode_touch[now[self._standing[now] > 0]] = True
        onset = now[~self._contact_mask[now]]
        self._contact_mask[self._in_contact] = False
        self._contact_mask[now] = True
        self._in_contact = now
        if self._pending_pair.size:
            if now.size:
                self._pending_touch |= self._contact_mask[self._pending_pair]
            due = t >= self._pending_deadline
            if due.any():
                self.false_episodes += int(np.count_nonzero(~self._pending_touch[due]))
                keep = ~due
                self._pending_pair = self._pending_pair[keep]
                self._pending_deadline = self._pending_deadline[keep]
                self._pending_touch = self._pending_touch[keep]
        if onset.size:
            self._onsets(onset, t)
        self._time = t

    def _onsets(self, onset: np.ndarray, t: float) -> None:
        sched = self.predictor.scheduler
        assert sched is not None
        for g in onset.tolist():
            members = self._gp_order[self._gp_start[g] : self._gp_start[g + 1]]
            if not sched.active[members].any():
                self.inactive_contacts += 1
                continue
            self.onsets += 1
            if self._standing[g] > 0:
                self.predicted += 1
                self.lead_times.append(t - float(self._episode_start[g]))
                self._episode_touch[g] = True
                continue
            live = members[sched.active[members]]
            last = int(sched.last_step[live].min())
            window_start = self._pred_steps[last]
            bodies = self._gp_body[g]
            held = (
                bool((self._last_violation[bodies] <= window_start).all()) if self.bounds else False
            )
            g1 = int(self.predictor.geom_pairs.geom1[g])
            g2 = int(self.predictor.geom_pairs.geom2[g])
            self.misses.append(
                Miss(
                    physics_step=self.physics_step,
                    time=t,
                    geom1=str(self._names[g1]),
                    geom2=str(self._names[g2]),
                    bounds_held=held,
                    last_evaluation_step=last,
                    last_tau=float(sched.last_tau[live].min()),
                )
            )

    # ------------------------------------------------------------------- report

    def finish(self) -> None:
        """Classify the alarm episodes still open or pending at the end of the run."""
        self.false_episodes += int(np.count_nonzero(~self._pending_touch))
        self._pending_pair = self._pending_pair[:0]
        self._pending_deadline = self._pending_deadline[:0]
        self._pending_touch = self._pending_touch[:0]
        still_open = np.flatnonzero(self._standing > 0)
        self.false_episodes += int((~self._episode_touch[still_open]).sum())


def run(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    predictor: Predictor,
    *,
    steps: int,
    controller: Controller | None = None,
    scene: str = "",
    realtime: bool = False,
    geom_distance: bool = False,
    progress: bool = True,
    on_step: Callable[[int, mujoco.MjData, Alarms | None, Monitor], None] | None = None,
) -> RunReport:
    """Roll out ``steps`` physics steps with prediction and the exact stage.

    The first ``mj_step`` brings ``data`` to a consistent state (kinematics and contacts of one
    instant); the predictor is reset there and stepped every ``predictor.period`` steps after.

    Args:
        model: The model.
        data: The data, at the start state (e.g. after ``load_scene``).
        predictor: The predictor (built for ``model``).
        steps: Physics steps after the reset.
        controller: ``controller(model, data)`` called before each ``mj_step``.
        scene: Name recorded in the report.
        realtime: Count deadline overruns (see ``Monitor``).
        geom_distance: Measure alarmed pairs with ``mj_geomDistance`` (see ``Monitor``).
        progress: Draw a progress bar on stderr.
        on_step: Called after each physics step with ``(k, data, alarms or None, monitor)``.
    """
    if isinstance(steps, bool) or not isinstance(steps, int | np.integer) or steps < 1:
        raise InvalidInputError(f"steps = {steps!r} is invalid: pass an int >= 1 (physics steps).")
    if model is not predictor.model and not same_geometry(model, predictor.model):
        raise InvalidInputError(
            "the predictor was built for another MjModel: pass the model it was built for "
            "(Predictor(model, ...)), or build a Predictor for this one."
        )
    predictor.check_data(data)  # before the controller writes into it
    monitor = Monitor(predictor, realtime=realtime, geom_distance=geom_distance)
    if controller is not None:
        controller(model, data)
    mujoco.mj_step(model, data)
    monitor.start(data)
    period = predictor.period
    t_mj: list[float] = []
    t_pred: list[float] = []
    warned = False
    with Progress(steps, scene or "run", enabled=progress) as bar:
        for k in range(1, steps + 1):
            if controller is not None:
                controller(model, data)
            t0 = time.perf_counter()
            mujoco.mj_step(model, data)
            t1 = time.perf_counter()
            t_mj.append(t1 - t0)
            alarms = None
            if k % period == 0:
                t2 = time.perf_counter()
                alarms = predictor.step(data)
                dt = time.perf_counter() - t2
                t_pred.append(dt)
                if realtime and dt > predictor.dt:
                    monitor.overruns += 1
                    if not warned:
                        warnings.warn(
                            f"predictor step took {dt * 1e6:.0f} us > period "
                            f"{predictor.dt * 1e6:.0f} "
                            "us: the predictor cannot keep up, completeness is not guaranteed.",
                            DeadlineOverrunWarning,
                            stacklevel=2,
                        )
                        warned = True
            monitor.observe(data, alarms)
            if on_step is not None:
                on_step(k, data, alarms, monitor)
            bar.update(
                note=f"alarms {0 if alarms is None else len(alarms)} missed {len(monitor.misses)}"
            )
    monitor.finish()
    sched = predictor.scheduler
    assert sched is not None
    evals = float(np.mean(monitor.evaluations)) if monitor.evaluations else 0.0
    return RunReport(
        scene=scene,
        physics_steps=steps,
        predictor_steps=len(t_pred),
        period=period,
        spheres=predictor.nsphere,
        pairs=predictor.nsphere_pairs,
        geom_pairs=predictor.geom_pairs.npair,
        evals_per_step=evals,
        contact_onsets=monitor.onsets,
        predicted_onsets=monitor.predicted,
        missed_onsets=len(monitor.misses),
        missed_onsets_valid_bounds=sum(m.bounds_held for m in monitor.misses),
        inactive_pair_contacts=monitor.inactive_contacts,
        unfiltered_contacts=monitor.unfiltered_contacts,
        alarm_episodes=monitor.episodes,
        false_alarm_episodes=monitor.false_episodes,
        lead_time_mean_s=float(np.mean(monitor.lead_times)) if monitor.lead_times else None,
        bound_violations=monitor.violations,
        deadline_overruns=monitor.overruns,
        exact_distance_median_m=(
            float(np.median(monitor.exact_distances)) if monitor.exact_distances else None
        ),
        predictor_us_per_step=float(np.median(t_pred) * 1e6) if t_pred else 0.0,
        mj_step_us_per_step=float(np.median(t_mj) * 1e6),
        misses=tuple(monitor.misses),
        alarms_per_step=tuple(monitor.alarms_per_step),
        min_tau_per_step=tuple(monitor.min_tau),
        realtime=realtime,
    )
