"""One algorithm on one world sequence: DUA (fused and select/update twins) or SA(tau).

Each run counts alarms (all, and repetitive ones once), contact onsets at its samples and the
completeness check, and for DUA the most-urgent-pair agreement with SA(tau) and SA(d).
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from dua_mujoco.core.pairset import PairSet
from dua_mujoco.core.schedules import DUAScheduler, SelectAllScheduler
from dua_mujoco.experiments.paper.world import Sampler, SphereWorld

__all__ = ["Contacts", "Run", "dua_run", "sa_run"]


@dataclass(frozen=True)
class Run:
    """One algorithm on one world sequence.

    Attributes:
        iterations: Iterations of the run.
        evals: Mean tau evaluations per iteration.
        us: ``(iterations,)`` wall time of each step through the public API (us).
        us_select_update: Same for DUA's ``select`` + ``PairSet.tau`` + ``update`` twin (SA:
            ``us``).
        false_at: False alarms (repetitive ones once) after the first k iterations, by k.
        all_at: All alarms after the first k iterations, by k.
        collisions: Contact onsets at the samples.
        missed: Sampled contacts not alarmed beforehand (must be 0).
        agree_dua_sat: % of iterations where DUA's most urgent pair is SA(tau)'s (DUA only).
        agree_sad_sat: % of the same iterations where SA(d)'s argmin is SA(tau)'s (DUA only).
    """

    iterations: int
    evals: float
    us: list[float]
    us_select_update: list[float]
    false_at: dict[int, int]
    all_at: dict[int, int]
    collisions: int
    missed: int
    agree_dua_sat: float | None = None
    agree_sad_sat: float | None = None


def _prefix_counts(iters: np.ndarray, prefixes: Iterable[int], total: int) -> dict[int, int]:
    """Events with iteration ``<= k`` for each prefix ``k`` (and the whole run)."""
    keys = sorted({*(k for k in prefixes if k <= total), total})
    return {k: int((iters <= k).sum()) for k in keys}


class Contacts:
    """Sampled contacts of all pairs, contact onsets and the completeness check (vectorised).

    Args:
        pairs: The world's ``(M,)`` sphere pairs.
    """

    def __init__(self, pairs: PairSet) -> None:
        self.first, self.second, self.eps = pairs.first, pairs.second, pairs.eps
        m = len(pairs)
        self.previous = np.zeros(m, dtype=np.bool_)
        self.ever = np.zeros(m, dtype=np.bool_)
        self.onsets = 0
        self.missed = 0

    def distance(self, centers: np.ndarray) -> np.ndarray:
        """``(M,)`` surface distances (``<= 0``: contact) of the pairs at ``centers (n, 3)``."""
        return np.asarray(
            np.linalg.norm(centers[self.second] - centers[self.first], axis=1) - self.eps
        )

    def observe(self, dist: np.ndarray, armed: np.ndarray) -> None:
        """Record contacts at this sample.

        Completeness (docs/theory.md, section 2): an evaluation at step m that does not alarm
        guarantees no contact up to its next evaluation m + I, so a contact at sample n is always
        covered by an alarm of the latest evaluation before n.

        Args:
            dist: ``(M,)`` surface distances at this sample (``Contacts.distance``).
            armed: ``(M,)`` bool: the pair's latest evaluation before this sample alarmed.
        """
        contact = dist <= 0.0
        self.onsets += int((contact & ~self.previous).sum())
        self.missed += int((contact & ~armed).sum())
        self.ever |= contact
        self.previous = contact


class _AlarmLog:
    """The alarms of a run by iteration: all of them, and the fresh ones (repetitive ones once).

    An alarm is repetitive when its pair's previous evaluation alarmed too. The paper counts from
    iteration 1, so the initial classification does not make the first in-run alarm of a pair
    repetitive.

    Args:
        m: Pairs of the run.
        initial: Pairs alarmed by the initial classification.

    Attributes:
        armed: ``(m,)`` bool: the pair's latest evaluation alarmed.
    """

    def __init__(self, m: int, initial: np.ndarray) -> None:
        self.armed = np.zeros(m, dtype=np.bool_)
        self.armed[initial] = True
        self._repeat = np.zeros(m, dtype=np.bool_)
        self._all_iter: list[np.ndarray] = []
        self._new_iter: list[np.ndarray] = []
        self._new_pair: list[np.ndarray] = []

    def record(self, it: int, alarms: np.ndarray, evaluated: np.ndarray | slice) -> None:
        """Record iteration ``it``'s ``alarms`` among the pairs it ``evaluated``."""
        fresh = alarms[~self._repeat[alarms]]
        for state in (self.armed, self._repeat):
            state[evaluated] = False
            state[alarms] = True
        self._all_iter.append(np.full(alarms.size, it))
        self._new_iter.append(np.full(fresh.size, it))
        self._new_pair.append(fresh)

    def finish(
        self,
        iterations: int,
        evals: float,
        us: list[float],
        us_su: list[float],
        contacts: Contacts,
        prefixes: Sequence[int],
        agree_dua: float | None = None,
        agree_sad: float | None = None,
    ) -> Run:
        """The :class:`Run` of these alarms and of the run's other measurements."""
        # An alarm is false when its pair never touches during the run (sampled contacts).
        new_iter = np.concatenate(self._new_iter)
        false_iter = new_iter[~contacts.ever[np.concatenate(self._new_pair)]]
        return Run(
            iterations=iterations,
            evals=evals,
            us=us,
            us_select_update=us_su,
            false_at=_prefix_counts(false_iter, prefixes, iterations),
            all_at=_prefix_counts(np.concatenate(self._all_iter), prefixes, iterations),
            collisions=contacts.onsets,
            missed=contacts.missed,
            agree_dua_sat=agree_dua,
            agree_sad_sat=agree_sad,
        )


def dua_run(
    world: SphereWorld,
    dt: float,
    iterations: int,
    prefixes: Sequence[int],
    agreement: bool,
) -> Run:
    """DUA on one sequence; also the SA(tau)/SA(d) references for agreement at the same states.

    Args:
        world: A fresh world (algorithms given equal worlds watch the same trajectory).
        dt: Predictor period (s).
        iterations: Iterations after the initial classification.
        prefixes: Run lengths after which the alarms are also counted.
        agreement: Also compare the most urgent pair with SA(tau)'s and SA(d)'s (Table 3).

    Raises:
        AssertionError: The fused step and the select/update twin disagree.
    """
    sampler = Sampler(world)
    pairs = world.pairs()
    m = len(pairs)
    all_ids = np.arange(m)
    c, v = sampler.state(0.0)
    tau0 = pairs.tau(all_ids, c, v)
    fused = DUAScheduler(tau0, dt=dt)
    # A twin driven through select/update: same inputs, so the same state at every step.
    twin = DUAScheduler(tau0, dt=dt)
    contacts = Contacts(pairs)
    log = _AlarmLog(m, fused.initial_alarms)
    contacts.observe(contacts.distance(c), log.armed)
    k = np.arange(fused.nbuckets)
    base = (1 << k) - 1
    us, us_su, evals = [], [], 0
    agree_dua = agree_sad = 0
    for it in range(1, iterations + 1):
        c, v = sampler.state(it * dt)
        dist = contacts.distance(c)
        contacts.observe(dist, log.armed)
        t0 = time.perf_counter()
        alarms = fused.step_points(pairs, c, v)
        us.append((time.perf_counter() - t0) * 1e6)
        t0 = time.perf_counter()
        ids = twin.select()
        twin_alarms = twin.update(ids, pairs.tau(ids, c, v))
        us_su.append((time.perf_counter() - t0) * 1e6)
        if not np.array_equal(np.sort(alarms), np.sort(twin_alarms)):
            raise AssertionError(f"fused and select/update DUA disagree at N={world.n}, step {it}.")
        # The evaluated pairs sit in the withdrawn slots again after reinsertion.
        withdrawn = fused.slots[base + it % (1 << k)]
        evaluated = withdrawn[withdrawn >= 0]
        evals += evaluated.size
        log.record(it, alarms, evaluated)
        if agreement:
            tau = pairs.tau(all_ids, c, v)
            best = tau.min()
            # Ties (e.g. two overlapping pairs at tau = 0) count as agreement.
            agree_dua += bool(tau[fused.most_urgent()] <= best)
            agree_sad += bool(tau[int(np.argmin(dist))] <= best)
    return log.finish(
        iterations,
        evals / iterations,
        us,
        us_su,
        contacts,
        prefixes,
        100.0 * agree_dua / iterations if agreement else None,
        100.0 * agree_sad / iterations if agreement else None,
    )


def sa_run(world: SphereWorld, dt: float, iterations: int, prefixes: Sequence[int]) -> Run:
    """SA(tau) on one sequence: every pair every iteration, alarm if tau < 2 dt.

    Args:
        world: A fresh world (algorithms given equal worlds watch the same trajectory).
        dt: Predictor period (s).
        iterations: Iterations after the initial classification.
        prefixes: Run lengths after which the alarms are also counted.
    """
    sampler = Sampler(world)
    pairs = world.pairs()
    m = len(pairs)
    c, v = sampler.state(0.0)
    sa = SelectAllScheduler(pairs.tau(np.arange(m), c, v), dt=dt, urgency="tau")
    contacts = Contacts(pairs)
    log = _AlarmLog(m, sa.initial_alarms)
    contacts.observe(contacts.distance(c), log.armed)
    us: list[float] = []
    for it in range(1, iterations + 1):
        c, v = sampler.state(it * dt)
        contacts.observe(contacts.distance(c), log.armed)
        t0 = time.perf_counter()
        ids = sa.select()
        alarms = sa.update(ids, pairs.tau(ids, c, v))
        us.append((time.perf_counter() - t0) * 1e6)
        log.record(it, alarms, slice(None))
    return log.finish(iterations, float(m), us, us, contacts, prefixes)
