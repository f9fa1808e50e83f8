"""The exact stage: alarms held against MuJoCo's own contacts, and the run's metrics.

``Monitor.observe`` is fed every physics step with the predictor's alarms when it stepped (the
bound check, the alarms, then the contacts in ``d.contact``). A *contact onset* is a geom pair of
the active set that is in ``d.contact`` now and was not at the previous physics step. It is
*predicted* when, at that instant, some sphere pair of that geom pair stands alarmed, i.e. its
latest evaluation (at or before the onset) raised an alarm: exactly the completeness theorem's
claim (docs/theory.md). A miss is *valid-bounds* when no hypothesis a verdict rested on (a
body's bounds, or under a plan its deviation: :class:`~dua_mujoco.measure.warning_time.Hypotheses`)
broke between that verdict's evaluation (its pair's latest) and the onset: a bug. It is *in a
violation's period* when such a break came after the latest predictor step at or before the
onset (two steps with pruned pairs): the one exception of the guarantee with violations as
events (docs/theory.md, sections 3 "The monitor's labels" and 6). Each
onset's lead and the oracle are counted by :class:`WarningTime`.

:func:`~dua_mujoco.measure.rollout.run` drives a rollout (controller, ``mj_step``, predictor every
``period`` steps, monitor) and returns a ``RunReport``.
"""

from __future__ import annotations

import warnings

import mujoco
import numpy as np

from dua_mujoco.core.validate import check_number
from dua_mujoco.measure.accumulators import Growing, Series, StepMap
from dua_mujoco.measure.checks import BoundMonitor
from dua_mujoco.measure.report import Miss
from dua_mujoco.measure.warning_time import WarningTime, alarm_horizon_of
from dua_mujoco.runtime.alarms import Alarms
from dua_mujoco.runtime.pairstate import PairState
from dua_mujoco.runtime.predictor import Predictor

__all__ = ["Monitor"]


# mj_geomDistance stops searching beyond this distance (m); alarmed pairs are far closer.
_DISTMAX = 100.0

_NONE = np.zeros(0, dtype=np.int64)

# A contact's impulse shows in the bound check's finite differences for this many physics steps
# (the current one and the two before it): a violation then is the contact's, not free motion's.
_CONTACT_LAG = 3


class Monitor:
    """Exact stage and metrics for one predictor on one ``MjData``.

    Args:
        predictor: A predictor (``reset`` is called by ``start``).
        check_bounds: Run a ``BoundMonitor`` each physics step (needed to tell valid-bound
            misses from misses after a broken bound).
        realtime: Deprecated, and never had an effect (a ``DeprecationWarning`` when given): the
            monitor does not time the predictor's steps; the caller that does counts the steps
            slower than ``predictor.dt`` in ``overruns``, as
            :func:`~dua_mujoco.measure.rollout.run` does with ``realtime=True``.
        geom_distance: Also measure the exact distance (``mj_geomDistance``) of every alarmed
            geom pair at each predictor step: how far the exact stage finds alarmed pairs (one
            float64 per alarmed pair and step is kept for the median).
        series: Record the alarm count and minimum tau of every predictor step (``series``);
            otherwise memory does not grow with the run's length.
        warning_horizon: The horizon (s) each onset's lead and the oracle are measured against
            (:mod:`~dua_mujoco.measure.warning_time`); None for the predictor's own alarm horizon
            (:func:`~dua_mujoco.measure.warning_time.alarm_horizon_of`).

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
        realtime: bool | None = None,
        geom_distance: bool = False,
        series: bool = False,
        warning_horizon: float | None = None,
    ) -> None:
        self.predictor = predictor
        self.warning_horizon = warning_horizon
        if warning_horizon is not None:  # None: the predictor's own
            self.warning_horizon = check_number(
                "warning_horizon", warning_horizon, zero=True, unit=" of seconds"
            )
        self.record_series = series
        self.model = predictor.model
        if realtime is not None:
            warnings.warn(
                "Monitor(realtime=...) has no effect and will be removed: the monitor does not "
                "time the predictor's steps; count overruns where they are timed (run(..., "
                "realtime=True) does, into monitor.overruns).",
                DeprecationWarning,
                stacklevel=2,
            )
        self.geom_distance = geom_distance
        self.bound_checks = (
            BoundMonitor(
                self.model,
                predictor.bounds,
                predictor.bound_points,
                mocap=predictor.mocap,
                mocap_period=predictor.period,
            )
            if check_bounds
            else None
        )
        self._ngp = 0
        self._fitted = -1
        self._names = predictor.tables.geom_names
        self._geom_root = np.asarray(self.model.body_rootid)[np.asarray(self.model.geom_bodyid)]
        self._body_root = np.asarray(self.model.body_rootid)

    # ------------------------------------------------------------------- lifecycle

    def start(self, data: mujoco.MjData) -> Alarms:
        """Reset the predictor on ``data`` and start counting."""
        alarms = self.predictor.reset(data)
        self.physics_step = 0
        self._pred_steps = StepMap(0, self.predictor.period)
        self._time = float(data.time)
        self._in_contact = self._contacts(data)[0]
        self._index_pairs()
        horizon = alarm_horizon_of(self.predictor)
        self.warning = WarningTime(
            horizon if self.warning_horizon is None else self.warning_horizon,
            float(self.model.opt.timestep),
            self.predictor,
        )
        # The same set as a mask: lookups by gathering, not by np.isin (which sorts; 47 us a
        # call with the thousands of pending windows of paper_world:200).
        self._contact_mask = np.zeros(self._ngp, dtype=bool)
        self._contact_mask[self._in_contact] = True
        self.last_violation = self.warning.hypotheses.last_violation
        # Per kinematic tree (root body): the last physics step it was in a contact.
        self._root_contact = np.full(self.model.nbody, -_CONTACT_LAG, dtype=np.int64)
        self._mark_contacts(data)
        self.free_violations = 0
        self._standing = np.zeros(self._ngp, dtype=np.int64)
        self._pair_alarm = np.zeros(self.predictor.nsphere_pairs, dtype=bool)
        self._resets = self.predictor.resets
        self._activation_seen = self.predictor.pair_state().activation_changes
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
        self.misses: list[Miss] = []
        self.inactive_contacts = 0
        self.unfiltered_contacts = 0
        self.flex_contacts = 0
        """Contacts of a flex seen (a physics step each): no geom pair, so no alarm covers them
        (docs/covering-and-pairs.md: out of scope)."""
        self.episodes = 0
        self.false_episodes = 0
        self.violations = 0
        self.overruns = 0
        """Predictor steps slower than ``predictor.dt``, counted by the caller that times them
        (:func:`~dua_mujoco.measure.rollout.run` with ``realtime=True``)."""
        # Running sums over predictor steps, not per-step lists: memory stays flat.
        self.predictor_steps = 0
        self.evaluation_sum = 0
        self.standing_sum = 0.0
        self.contact_sum = 0.0
        self._nstanding = 0  # geom pairs with a standing alarm
        self._gp_active = np.zeros(self._ngp, dtype=bool)
        self._nactive = 0
        self._gp_active_seen: tuple[int, int] | None = None
        self._distances = Growing()
        self.series = Series() if self.record_series else None
        if self.series is not None:
            self.series.append(len(alarms), float(np.min(alarms.tau, initial=np.inf)))
        if self.bound_checks is not None:
            self.bound_checks.update(self.model, data)
        self._apply_alarms(alarms.pairs, np.arange(self.predictor.nsphere_pairs), data.time, 0)
        self.warning.contacts(_NONE, self._in_contact, self._active_geom_pairs(), 0)
        return alarms

    def _index_pairs(self) -> None:
        """Index the predictor's known pairs by geom pair (O(known pairs), after a change)."""
        predictor = self.predictor
        self._fitted = predictor.universe.version
        gp = predictor.sphere_pairs.geom_pair
        self._ngp = predictor.geom_pairs.npair
        order = np.argsort(gp, kind="stable")
        self._gp_order = order
        self._gp_start = np.searchsorted(gp[order], np.arange(self._ngp + 1))
        gbody = np.asarray(self.model.geom_bodyid)
        self._gp_body = np.stack(
            [gbody[predictor.geom_pairs.geom1], gbody[predictor.geom_pairs.geom2]], axis=1
        )

    def _fit(self) -> None:
        """Grow the per-pair arrays to the pairs the predictor knows now (a pruned predictor
        learns pairs as its candidates, or a contact, bring them in)."""
        if self._fitted == self.predictor.universe.version:
            return
        before = self._ngp
        self._index_pairs()
        grow = self._ngp - before
        self._contact_mask = np.concatenate([self._contact_mask, np.zeros(grow, dtype=bool)])
        self._standing = np.concatenate([self._standing, np.zeros(grow, dtype=np.int64)])
        self._episode_start = np.concatenate([self._episode_start, np.full(grow, np.nan)])
        self._episode_horizon = np.concatenate([self._episode_horizon, np.zeros(grow)])
        self._episode_touch = np.concatenate([self._episode_touch, np.zeros(grow, dtype=bool)])
        more = self.predictor.nsphere_pairs - self._pair_alarm.size
        self._pair_alarm = np.concatenate([self._pair_alarm, np.zeros(more, dtype=bool)])
        self._gp_active_seen = None
        self.warning.grow(self.predictor)

    def _mark_contacts(self, data: mujoco.MjData) -> None:
        """Stamp the kinematic trees of every contact (any geom pair, static ones too; of a
        flex's contact, the geom's side: the flex's side is no geom, -1)."""
        nc = int(data.ncon)
        if nc:
            g = np.concatenate([data.contact.geom1[:nc], data.contact.geom2[:nc]])
            self._root_contact[self._geom_root[g[g >= 0]]] = self.physics_step

    def _contacts(self, data: mujoco.MjData) -> tuple[np.ndarray, int, int]:
        """Active geom pairs in contact (sorted ids), the count of geom contacts outside them
        and the count of a flex's contacts (geom -1: out of scope, docs/covering-and-pairs.md).

        O(ncon), not O(geom pairs): the monitor runs every physics step.
        """
        nc = int(data.ncon)
        if nc == 0:
            return _NONE, 0, 0
        g1, g2 = data.contact.geom1[:nc], data.contact.geom2[:nc]
        geoms = (g1 >= 0) & (g2 >= 0)
        flex = nc - int(np.count_nonzero(geoms))
        if flex:
            g1, g2 = g1[geoms], g2[geoms]
        gp = self.predictor.geom_pair_ids(g1, g2)
        return np.unique(gp[gp >= 0]), int((gp < 0).sum()), flex

    # ------------------------------------------------------------------- alarms

    def _apply_alarms(
        self,
        alarmed: np.ndarray,
        evaluated: np.ndarray,
        t: float,
        step: int,
        *,
        switch: bool = False,
        deferred: int = 0,
    ) -> None:
        """Update the standing alarms from the pairs ``evaluated`` (``alarmed`` among them) at
        physics step ``step`` (``switch``: a switch or reset, not an evaluation; ``deferred``:
        how many of ``evaluated``, its last, a capped schedule deferred: their verdicts were
        renewed, not made, and their windows still open at their evaluation)."""
        sched = self.predictor.pair_state()
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
        self._nstanding += int(started.size) - int(ended.size)
        raised = ids[new & ~old]
        made = evaluated[: evaluated.size - deferred]
        self.warning.alarms(started, raised, gp[raised], made, step, switch=switch)
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
        if self.predictor.resets != self._resets:
            self._resets = self.predictor.resets
            self._pred_steps = StepMap(self.physics_step, self.predictor.period)
            self._activation_seen = -1
            self.warning.reset(self.physics_step)

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
        sched = self.predictor.pair_state()
        if sched.activation_changes == self._activation_seen:
            return
        self._activation_seen = sched.activation_changes
        now = sched.alarm_state() & sched.active
        differs = now != self._pair_alarm
        if exclude is not None:
            differs[exclude] = False
        changed = np.flatnonzero(differs)
        if changed.size:
            self._apply_alarms(
                changed[now[changed]], changed, self._time, self.physics_step - 1, switch=True
            )

    def _observe_alarms(
        self, data: mujoco.MjData, alarms: Alarms, sched: PairState, evaluated: np.ndarray
    ) -> None:
        """The step's alarms, ``evaluated`` the pairs whose verdict it renewed (``sched``'s
        ``last_selected``)."""
        self._pred_steps.append(self.physics_step)
        self.warning.hypotheses.evaluated(evaluated, self.predictor.verdict_basis(evaluated))
        self.predictor_steps += 1
        # Deferred pairs (a capped deadline schedule) had their verdict renewed, not evaluated;
        # settled ones a verdict from a bound, cleared ones the screen's test: none is counted.
        self.evaluation_sum += self.predictor.evaluations_per_step
        self._apply_alarms(
            alarms.pairs, evaluated, float(data.time), self.physics_step, deferred=sched.deferred
        )
        if self.geom_distance and len(alarms):
            self._distances.extend(
                [
                    mujoco.mj_geomDistance(self.model, data, g1, g2, _DISTMAX, None)
                    for g1, g2 in sorted(alarms.geom_pairs)
                ]
            )
        if self.series is not None:
            self.series.append(len(alarms), float(alarms.tau.min()) if len(alarms) else np.inf)

    @property
    def exact_distances(self) -> np.ndarray:
        """The ``mj_geomDistance`` of every alarmed geom pair so far (``geom_distance``)."""
        return self._distances.view()

    @property
    def oracle_fraction(self) -> float:
        """Mean over predictor steps of (active geom pairs that touch within the warning
        horizon from that step) / (active geom pairs): the floor under the standing fraction
        (:mod:`~dua_mujoco.measure.warning_time`; windows past the last step count what's seen)."""
        if not self.predictor_steps:
            return 0.0
        return self.warning.oracle_sum() / self.predictor_steps

    @property
    def standing_alarm_fraction(self) -> float:
        """Mean over predictor steps of (geom pairs in alarm) / (active geom pairs)."""
        return self.standing_sum / self.predictor_steps if self.predictor_steps else 0.0

    @property
    def contact_pair_fraction(self) -> float:
        """Mean over predictor steps of (active geom pairs in contact) / (active geom pairs)."""
        return self.contact_sum / self.predictor_steps if self.predictor_steps else 0.0

    def _active_geom_pairs(self) -> np.ndarray:
        """Mask of geom pairs with an active sphere pair; O(pairs) only after a switch."""
        sched = self.predictor.pair_state()
        seen = (self.predictor.resets, sched.activation_changes)
        if seen != self._gp_active_seen:
            self._gp_active_seen = seen
            on = self.predictor.sphere_pairs.geom_pair[sched.active]
            self._gp_active = np.bincount(on, minlength=self._ngp) > 0
            # A pruned predictor has not met every active pair: the rest are on.
            unmet = self.predictor.universe.counts()[0] - self._ngp
            self._nactive = int(np.count_nonzero(self._gp_active)) + unmet
        return self._gp_active

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
        self._fit()
        self.physics_step += 1
        self._mark_contacts(data)
        self.warning.hypotheses.check_plan(self.predictor, self.physics_step)
        if self.bound_checks is not None:
            broke = self.bound_checks.update(self.model, data)
            if broke.size:
                self.last_violation[broke] = self.physics_step
                self.violations += int(broke.size)
                since = self.physics_step - self._root_contact[self._body_root[broke]]
                self.free_violations += int(np.count_nonzero(since >= _CONTACT_LAG))
        sched = self.predictor.pair_state()
        if alarms is not None and alarms.step != sched.step_count:
            # predictor.reset came between step() and here: its classification is of this
            # instant, and these alarms belong to the scheduler it replaced.
            self._pred_steps = StepMap(self.physics_step, self.predictor.period)
            self.warning.reset(self.physics_step)
            alarms = None
        if alarms is None:
            self._sync_switches()
        else:
            # Switches between steps first, stamped with the previous step's time; the pairs
            # evaluated now get their current state from this step's evaluation.
            selected = sched.last_selected
            self._sync_switches(exclude=selected)
            self._observe_alarms(data, alarms, sched, selected)
        now, unfiltered, flex = self._contacts(data)
        self._fit()  # a contact of an active pair the predictor had not met: now it has
        self.unfiltered_contacts += unfiltered
        self.flex_contacts += flex
        active = self._active_geom_pairs()
        if alarms is not None and self._nactive:
            self.standing_sum += self._nstanding / self._nactive
            self.contact_sum += int(np.count_nonzero(active[now])) / self._nactive
            self.warning.sample(self.physics_step, self._nactive)
        self.warning.contacts(self._in_contact, now, active, self.physics_step)
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
        sched = self.predictor.pair_state()
        for g in onset.tolist():
            members = self._gp_order[self._gp_start[g] : self._gp_start[g + 1]]
            if not sched.active[members].any():
                self.inactive_contacts += 1
                continue
            self.onsets += 1
            if self._standing[g] > 0:
                self.predicted += 1
                self._episode_touch[g] = True
                self.warning.onset(g, self.physics_step, self.warning.hypotheses.broke(g))
                continue
            # Each live pair's verdict against the breaks after its own latest evaluation.
            live = members[sched.active[members]]
            last = sched.last_step_of(live)
            broke = self.warning.hypotheses.broke(g, live, self._pred_steps.at(last))
            held = broke < 0 if self.bound_checks else False
            self.warning.onset(g, self.physics_step, broke, missed=True)
            # The step sees a violation at the first predictor instant at or after it, and
            # renews the pairs of its bodies there (a pruned predictor the pairs it did not
            # hold, one step later): an onset before that is the one exception left.
            steps = self._pred_steps
            seen = steps[max(steps.count - (2 if self.predictor.stride else 1), 0)]
            in_period = bool(self.bound_checks) and broke > seen
            g1 = int(self.predictor.geom_pairs.geom1[g])
            g2 = int(self.predictor.geom_pairs.geom2[g])
            self.misses.append(
                Miss(
                    physics_step=self.physics_step,
                    time=t,
                    geom1=str(self._names[g1]),
                    geom2=str(self._names[g2]),
                    bounds_held=held,
                    in_violation_period=in_period,
                    last_evaluation_step=int(last.min()),
                    last_tau=float(sched.last_tau_of(live).min()),
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
