"""Warning time of a monitored run: each contact onset's lead, and the oracle over a horizon.

*Lead.* The lead of a contact onset is how long its geom pair had stood in alarm without a
break immediately before the onset: from the physics step at which the run of standing alarms
that covers the onset began (cut at the latest ``predictor.reset``, whose classification is of a
new state) to the onset's step; 0 for a missed onset. A predictor that promises an alarm horizon
``H`` (a pair that may collide within ``H`` stands in alarm) gives every onset a lead of at
least ``H`` while the motion bounds hold. An onset with less lead is one of three kinds:

- *at the start*: within ``H`` after the run's start, the latest reset or the pair's switch-on,
  when no alarm could have stood ``H`` yet;
- *after a violation*: a hypothesis one of the verdicts that should have raised it earlier
  rested on broke after that verdict's own evaluation (for each sphere pair that raised the
  alarm, its evaluation before the raising one; for a missed onset: each active sphere pair's
  latest, the miss's own rule, :class:`~dua_mujoco.measure.report.Miss`; docs/theory.md,
  section 3, "The monitor's labels").
  A verdict rests, for each of its two bodies, on that body's motion bounds or, under a flight
  plan, on its deviation (:class:`Hypotheses`): a planned body's bound violations do not count
  for the sides judged by its plan, and do for the sides judged by its bounds;
- *while the bounds held*: neither, which the promise does not allow (without bound checks every
  such onset counts here).

*Oracle.* At each predictor step, the share of active geom pairs that do touch (are in MuJoCo's
contacts) at some physics step from that step to ``H`` after it: the pairs no predictor with
horizon ``H`` may leave out of alarm, so its mean over the run is a floor under the standing
fraction. It is known once the run is over: steps whose window runs past the last observed
step count the contacts seen until then. A contact counts while its pair was switched on when it
began. Memory is one contact interval a contact run (as many as onsets) and one record a run of
regularly spaced predictor steps, not one a step.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from dua_mujoco.measure.accumulators import Growing

if TYPE_CHECKING:
    from dua_mujoco.runtime.predictor import Predictor

__all__ = ["Hypotheses", "WarningTime", "alarm_horizon_of"]

# Leads and horizons are sums of timesteps: compare them with this relative slack.
_REL = 1e-9

# Hypotheses.broke: the bits of a hypothesis mask (Hypotheses._sides), and "no verdict rested
# on it" (no break comes after).
_BITS = np.arange(5, dtype=np.uint8)
_NEVER = np.iinfo(np.int64).max


def alarm_horizon_of(predictor: Predictor) -> float:
    """The lead (s) ``predictor`` promises, counted from the step that raised each alarm: its
    alarm horizon and the ``latency`` periods a verdict takes to act (docs/theory.md, Theorem
    3: the verdict in force the alarm horizon before the first state in contact was raised that
    much earlier). ``(1 + latency) * dt`` by default."""
    return (predictor.alarm_periods + predictor.latency) * predictor.dt


class WarningTime:
    """Leads of contact onsets and the oracle's contact intervals (module docstring).

    Fed by :class:`~dua_mujoco.measure.monitor.Monitor`; steps are the monitor's physics steps.

    Args:
        horizon: The horizon ``H`` (s) the leads and the oracle are measured against.
        timestep: Seconds a physics step.
        predictor: The predictor observed (the pairs it knows now, its model).
    """

    def __init__(self, horizon: float, timestep: float, predictor: Predictor) -> None:
        ngp, npairs = predictor.geom_pairs.npair, predictor.nsphere_pairs
        self.hypotheses = Hypotheses(predictor.model.nbody)
        """What each verdict rested on, and when those hypotheses broke (the labels)."""
        self.hypotheses.index(predictor)
        self.horizon = float(horizon)
        self.timestep = float(timestep)
        # The window of the oracle: the steps j with (j - k) * timestep <= H.
        self.horizon_steps = math.floor(self.horizon / self.timestep * (1 + _REL) + _REL)
        self._tol = _REL * max(self.horizon, self.timestep)
        self.reset_step = 0
        # Per geom pair: the step its current run of standing alarms began, its latest
        # switch-on, and the step its current contact began (-1: none, -2: in a contact that
        # began while the pair was switched off).
        self._since = np.zeros(ngp, dtype=np.int64)
        self._switched_on = np.full(ngp, -1, dtype=np.int64)
        self._open_from = np.full(ngp, -1, dtype=np.int64)
        # Per sphere pair: the step of its latest evaluation.
        self._last_eval = np.zeros(npairs, dtype=np.int64)
        self._leads = Growing(np.float64)
        self.short_held = 0
        self.short_after_violation = 0
        self.short_at_start = 0
        # Closed contact intervals [lo, hi] (steps) of active geom pairs.
        self._iv_pair = Growing(np.int64)
        self._iv_lo = Growing(np.int64)
        self._iv_hi = Growing(np.int64)
        # Predictor steps sampled for the fractions, as runs: first step, spacing, count and
        # active geom pairs (constant within a run).
        self._runs: list[list[int]] = []
        self.last_step = 0

    # ------------------------------------------------------------------- pairs

    def grow(self, predictor: Predictor) -> None:
        """Follow the pairs a pruned predictor learns (arrays only grow)."""
        self.hypotheses.index(predictor)
        ngp, npairs = predictor.geom_pairs.npair, predictor.nsphere_pairs
        more = ngp - self._since.size
        if more > 0:
            self._since = np.concatenate([self._since, np.zeros(more, dtype=np.int64)])
            self._switched_on = np.concatenate([self._switched_on, np.full(more, -1, np.int64)])
            self._open_from = np.concatenate([self._open_from, np.full(more, -1, np.int64)])
        more = npairs - self._last_eval.size
        if more > 0:
            # Never evaluated yet: their first verdict's window opens at the latest reset.
            self._last_eval = np.concatenate(
                [self._last_eval, np.full(more, self.reset_step, dtype=np.int64)]
            )

    def reset(self, step: int) -> None:
        """A ``predictor.reset`` whose classification is of step ``step`` (it evaluated every
        pair there)."""
        self.reset_step = step
        np.maximum(self._last_eval, step, out=self._last_eval)

    def alarms(
        self,
        started: np.ndarray,
        raised: np.ndarray,
        raised_gp: np.ndarray,
        evaluated: np.ndarray,
        step: int,
        *,
        switch: bool,
    ) -> None:
        """Runs of standing alarms begin at ``step`` for the geom pairs ``started`` (sorted),
        raised by the sphere pairs ``raised`` (of geom pairs ``raised_gp``), after the sphere
        pairs ``evaluated`` were evaluated there. ``switch``: the change came from switches or
        a reset, not an evaluation (pairs switched on stand in alarm until evaluated)."""
        if started.size:
            # Each raiser's verdict replaced is the one of its evaluation before this one.
            self.hypotheses.started(started, raised, raised_gp, self._last_eval[raised])
            self._since[started] = step
        if switch:
            if raised.size:
                self._switched_on[raised_gp] = step
        elif evaluated.size:
            self._last_eval[evaluated] = step

    # ------------------------------------------------------------------- onsets

    def onset(self, g: int, step: int, broke: int, *, missed: bool = False) -> None:
        """Record the onset of geom pair ``g`` at ``step``.

        Args:
            g: The geom pair.
            step: The onset's physics step.
            broke: :meth:`Hypotheses.broke` for the onset (-1: no hypothesis broke after the
                verdict that rested on it, or none was checked).
            missed: No alarm stood for the onset.
        """
        since = step if missed else max(int(self._since[g]), self.reset_step)
        lead = (step - since) * self.timestep
        self._leads.extend([lead])
        if lead >= self.horizon - self._tol:
            return
        watched = max(self.reset_step, int(self._switched_on[g]))
        if (step - watched) * self.timestep < self.horizon - self._tol:
            self.short_at_start += 1
            return
        if broke >= 0:
            self.short_after_violation += 1
        else:
            self.short_held += 1

    @property
    def leads(self) -> np.ndarray:
        """Every onset's lead so far (s), in onset order."""
        return self._leads.view()

    @property
    def short_leads(self) -> int:
        """Onsets with less lead than the horizon."""
        return self.short_held + self.short_after_violation + self.short_at_start

    def lead_quantiles(self) -> tuple[float | None, float | None, float | None]:
        """``(p10, median, minimum)`` of the leads (s), None without onsets.

        The p10 is a lead some onset had (the lower of the two around the 10th percentile):
        at least 90 % of the onsets had at least that much.
        """
        leads = self.leads
        if not leads.size:
            return None, None, None
        p10 = float(np.percentile(leads, 10.0, method="lower"))
        return p10, float(np.median(leads)), float(leads.min())

    # ------------------------------------------------------------------- oracle

    def contacts(self, before: np.ndarray, now: np.ndarray, active: np.ndarray, step: int) -> None:
        """The geom pairs in contact moved from ``before`` to ``now`` (sorted ids) at ``step``;
        ``active``: the geom pairs switched on (a mask)."""
        self.last_step = step
        if before.size:
            ended = np.setdiff1d(before, now, assume_unique=True)
            if ended.size:
                lo = self._open_from[ended]
                counted = lo >= 0
                self._close(ended[counted], lo[counted], step - 1)
                self._open_from[ended] = -1
        if now.size:
            new = now[self._open_from[now] == -1]
            if new.size:
                on = active[new] if active.size else np.zeros(new.size, dtype=bool)
                self._open_from[new] = np.where(on, step, -2)

    def _close(self, pair: np.ndarray, lo: np.ndarray, hi: int) -> None:
        if pair.size:
            self._iv_pair.extend(pair)
            self._iv_lo.extend(lo)
            self._iv_hi.extend(np.full(pair.size, hi, dtype=np.int64))

    def sample(self, step: int, nactive: int) -> None:
        """A predictor step at ``step`` counted in the fractions, over ``nactive`` pairs."""
        runs = self._runs
        if runs:
            first, spacing, count, n = runs[-1]
            if n == nactive:
                if count == 1 and step > first:
                    runs[-1][1] = step - first
                    runs[-1][2] = 2
                    return
                if step == first + count * spacing:
                    runs[-1][2] += 1
                    return
        runs.append([step, 1, 1, nactive])

    def oracle_sum(self) -> float:
        """Sum over the sampled steps of (active geom pairs that touch within the horizon) /
        (active geom pairs): the oracle times the predictor steps."""
        open_ = np.flatnonzero(self._open_from >= 0)
        pair = np.concatenate([self._iv_pair.view(), open_])
        lo = np.concatenate([self._iv_lo.view(), self._open_from[open_]])
        hi = np.concatenate([self._iv_hi.view(), np.full(open_.size, self.last_step, np.int64)])
        if not pair.size or not self._runs:
            return 0.0
        # A step k counts a pair touching at some j in [k, k + H]: k in [lo - H, hi]. Merge
        # each pair's windows so that a step is counted once a pair.
        lo = lo - self.horizon_steps
        span = int(max(hi.max(), self.last_step) - min(lo.min(), 0)) + 2
        base = int(min(lo.min(), 0))
        key_lo = (lo - base) + pair * span
        key_hi = (hi - base) + pair * span
        order = np.argsort(key_lo, kind="stable")
        key_lo, key_hi = key_lo[order], key_hi[order]
        reach = np.maximum.accumulate(key_hi)
        begins = np.ones(key_lo.size, dtype=bool)
        begins[1:] = key_lo[1:] > reach[:-1]
        idx = np.flatnonzero(begins)
        m_lo = key_lo[idx]
        m_hi = np.maximum.reduceat(key_hi, idx)
        offset = (m_lo // span) * span - base
        m_lo = m_lo - offset
        m_hi = m_hi - offset
        total = 0.0
        for first, spacing, count, nactive in self._runs:
            if nactive <= 0:
                continue
            i_lo = np.maximum(-((first - m_lo) // spacing), 0)  # ceil((lo - first) / spacing)
            i_hi = np.minimum((m_hi - first) // spacing, count - 1)
            total += float(np.maximum(i_hi - i_lo + 1, 0).sum()) / nactive
        return total


class Hypotheses:
    """What each verdict rested on, and when those hypotheses broke (docs/theory.md, section 8).

    Per sphere pair, the basis of its latest verdict and of the one before it, as the runtime
    records them (``Predictor.verdict_basis``: bit 0 set when its first geom's body was judged by
    the plan, bit 1 the same for its second; a clear bit is that body's motion bounds, and a pair
    a pruned predictor does not hold rests on both bodies' bounds). Per geom pair and hypothesis,
    the earliest evaluation step among the verdicts its current run of standing alarms replaced
    that rested on it (a break after that step excuses a short lead). Per body, the latest
    physics step it broke its bounds (``last_violation``) or was found beyond its deviation
    (``last_plan_break``), and per body pair the latest step its relative deviation was found
    broken (``last_relative_break``, keyed ``(a, b)``, ``a < b``); -1: never.

    Args:
        nbody: Bodies of the model.
    """

    def __init__(self, nbody: int) -> None:
        self.last_violation = np.full(nbody, -1, dtype=np.int64)
        self.last_plan_break = np.full(nbody, -1, dtype=np.int64)
        self.last_relative_break: dict[tuple[int, int], int] = {}
        self._basis = np.zeros(0, dtype=np.uint8)
        self._prev = np.zeros(0, dtype=np.uint8)
        self._after = np.zeros((0, _BITS.size), dtype=np.int64)
        self._flip = np.zeros(0, dtype=bool)
        self._gp_body = np.zeros((0, 2), dtype=np.int64)

    def index(self, predictor: Predictor) -> None:
        """Follow the pairs ``predictor`` knows now (arrays only grow)."""
        gp, pairs = predictor.sphere_pairs.geom_pair, predictor.geom_pairs
        # Where a sphere pair's first geom is its geom pair's second (its basis bits swapped).
        self._flip = predictor.tables.geom1 != pairs.geom1[gp]
        body = np.asarray(predictor.model.geom_bodyid)
        self._gp_body = np.stack([body[pairs.geom1], body[pairs.geom2]], axis=1)
        grow = self._flip.size - self._basis.size
        self._basis = np.concatenate([self._basis, np.zeros(grow, dtype=np.uint8)])
        self._prev = np.concatenate([self._prev, np.zeros(grow, dtype=np.uint8)])
        more = self._gp_body.shape[0] - self._after.shape[0]
        self._after = np.concatenate([self._after, np.full((more, _BITS.size), _NEVER)])

    def check_plan(self, predictor: Predictor, step: int) -> None:
        """At physics step ``step``: the bodies of the predictor's data found beyond their
        deviation (``Predictor.beyond_plan``). Their bound violations are counted apart, never
        excused by a plan."""
        beyond = predictor.beyond_plan()
        if beyond is not None:
            self.last_plan_break[beyond] = step
        for a, b in predictor.beyond_plan_relative().tolist():
            self.last_relative_break[(a, b)] = step

    def evaluated(self, pairs: np.ndarray, basis: np.ndarray) -> None:
        """Sphere ``pairs`` were evaluated: ``basis`` (n, 2) their latest verdict's and the one
        before's."""
        self._basis[pairs], self._prev[pairs] = basis[:, 0], basis[:, 1]

    def started(
        self, started: np.ndarray, raised: np.ndarray, raised_gp: np.ndarray, since: np.ndarray
    ) -> None:
        """Geom pairs ``started`` to stand in alarm, raised by sphere pairs ``raised`` (of geom
        pairs ``raised_gp``) whose verdicts replaced were made at physics steps ``since`` (all
        (n,)): what each of those rested on is what the lead rests on, from its own step."""
        self._after[started] = _NEVER
        hit = np.isin(raised_gp, started)
        r = raised[hit]
        np.minimum.at(self._after, raised_gp[hit], self._rested(r, self._prev[r], since[hit]))

    def broke(self, g: int, live: np.ndarray | None = None, since: npt.ArrayLike = ()) -> int:
        """The latest physics step at which a hypothesis of one of geom pair ``g``'s verdicts
        broke after that verdict's own step: the verdicts its standing alarm replaced, or (a
        miss) the current ones of sphere pairs ``live`` (n,), made at physics steps ``since``
        (n,); -1: none (the bounds held for the onset)."""
        if live is None:
            after = self._after[g]
        else:
            live_since = np.asarray(since, dtype=np.int64)
            after = self._rested(live, self._basis[live], live_since).min(axis=0, initial=_NEVER)
        body = self._gp_body[g]
        relative = self.last_relative_break.get((int(body.min()), int(body.max())), -1)
        steps = np.r_[self.last_plan_break[body], self.last_violation[body], relative]
        return int(steps[steps > after].max(initial=-1))

    def _rested(self, pairs: np.ndarray, basis: np.ndarray, since: np.ndarray) -> np.ndarray:
        """Per verdict of sphere ``pairs`` (bases ``basis``, made at steps ``since``) and
        hypothesis bit: the step after which a break of it excuses, ``_NEVER`` where the
        verdict did not rest on it; (n, 5)."""
        rests = (self._sides(pairs, basis)[:, None] >> _BITS) & 1
        return np.where(rests.astype(bool), since[:, None], _NEVER)

    def _sides(self, pairs: np.ndarray, basis: np.ndarray) -> np.ndarray:
        """Hypothesis masks in the geom pairs' orientation: bit 0 (1) the first (second) geom's
        body's deviation, bit 2 (3) its motion bounds, bit 4 the two bodies' relative deviation
        (the basis' bit 2, the same either way round)."""
        flip = self._flip[pairs]
        first = np.where(flip, (basis >> 1) & 1, basis & 1).astype(np.uint8)
        second = np.where(flip, basis & 1, (basis >> 1) & 1).astype(np.uint8)
        relative = ((basis >> 2) & 1).astype(np.uint8)
        return first | (second << 1) | ((1 - first) << 2) | ((1 - second) << 3) | (relative << 4)
