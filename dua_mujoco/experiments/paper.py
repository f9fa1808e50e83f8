"""Reproduction of the paper's experiments (Hayward et al. 1995, section 8; SPEC section 5).

The world is the paper's: ghost spheres in a cube under random, exactly bounded, piecewise-constant
accelerations (``dua_mujoco.core.worlds.SphereWorld``). Three measurements, each beside the paper's:

* **Table 1, cost per iteration against N**: evaluations of tau per iteration (the
  hardware-independent analogue of the paper's CPU time), wall-clock microseconds through the
  public API (DUA's fused ``step_points``, DUA's ``select``/``update``, SA(tau)'s
  ``select``/``update``) and compiled-kernel nanoseconds (no Python in the loop: the closest
  analogue of the paper's instruction counts).
* **Table 2, false alarms** (repetitive alarms counted once) in two clocks: the *work clock*
  ("realtime"), where an iteration lasts as long as it computes, ``dt = c E + overhead`` with ``E``
  the evaluations per iteration; and a *fixed* clock, one period for both algorithms. Real
  collisions are counted too, and every one must have been alarmed (asserted).
* **Table 3, most-urgent-pair agreement** at N = 10: DUA's bucket-0 occupant against SA(tau)'s
  argmin tau, and SA(d)'s argmin distance against SA(tau)'s.

Work clock. The paper's Table 1 "cycles" are exactly 60 x its Table 2 Delta t (1/60 s clock ticks),
and a fit of Delta t against evaluations per iteration gives 0.0556 s per evaluation with no
measurable overhead (``PAPER_SECONDS_PER_EVAL``). We measured our compiled kernels once
(``calibrate_work_clock``) and keep the result as constants so runs are reproducible on any
machine: ``MEASURED_NS_PER_EVAL``, ``MEASURED_NS_OVERHEAD``. The work clock is our measured cost
model expressed on the paper's time scale,
``dt(E) = PAPER_SECONDS_PER_EVAL * (E + MEASURED_NS_OVERHEAD / MEASURED_NS_PER_EVAL)``, so our
Delta t column is directly comparable with the paper's and the world can keep physical units
(metres, seconds) instead of being sped up 10^6-fold to match 80 ns evaluations.

Sampling. Both algorithms watch the *same* world trajectory (same seed, same physics step): the
world advances in whole physics steps and is sampled exactly inside a step (piecewise-constant
accelerations, closed form), so a predictor period need not be a multiple of the physics step.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numba as nb
import numpy as np

from dua_mujoco.core.schedules import (
    DUAScheduler,
    PairSet,
    SelectAllScheduler,
    _pair_tau,
    _step_points,
    bucket_layout,
)
from dua_mujoco.core.worlds import SphereWorld

__all__ = [
    "FIXED_DT",
    "MEASURED_NS_OVERHEAD",
    "MEASURED_NS_PER_EVAL",
    "PAPER_SECONDS_PER_EVAL",
    "AgreementRow",
    "PaperRow",
    "WorkClock",
    "WorldParams",
    "add_arguments",
    "calibrate_work_clock",
    "main",
    "run_paper",
]

# --------------------------------------------------------------------------- paper numbers

PAPER_N: tuple[int, ...] = (5, 10, 15, 20, 30, 40)
"""Sphere counts of the paper's Tables 1 and 2."""

PAPER_TABLE1: dict[str, tuple[float, ...]] = {
    "DUA": (12.01, 18.74, 22.42, 26.65, 31.14, 39.69),
    "SA": (29.53, 135.133, 323.90, 607.45, 1543.02, 3294.18),
}
"""Paper Table 1, "CPU cycles" per iteration (in fact 1/60 s ticks: 60 x Table 2's Delta t)."""

PAPER_TABLE2_DT: dict[str, tuple[float, ...]] = {
    "DUA": (0.2, 0.31, 0.37, 0.44, 0.52, 0.66),
    "SA": (0.48, 2.23, 5.33, 10.12, 25.31, 53.75),
}
"""Paper Table 2, Delta t per iteration (seconds on a SPARC 470, Common Lisp)."""

PAPER_TABLE2_DUA: dict[int, tuple[int, ...]] = {
    25: (0, 52, 96, 124, 164, 196),
    35: (0, 75, 133, 174, 226, 270),
    50: (0, 104, 189, 248, 319, 379),
    65: (0, 134, 246, 323, 410, 485),
    75: (0, 153, 284, 370, 471, 557),
}
"""Paper Table 2, DUA false alarms by iteration count (repetitive alarms *not* filtered)."""

PAPER_TABLE2_SA: dict[int, tuple[tuple[int, int], ...]] = {
    25: ((0, 0), (88, 102), (496, 1203), (897, 3581), (2193, 8317), (3988, 15489)),
    35: ((0, 0), (109, 125), (655, 1516), (1144, 4955), (2822, 11462), (5118, 21593)),
    50: ((0, 0), (127, 146), (914, 1944), (1538, 6937), (3746, 16076), (6717, 30649)),
    65: ((0, 0), (153, 172), (1199, 2398), (1988, 8909), (4763, 20822), (8539, 39892)),
    75: ((0, 0), (177, 196), (1368, 2671), (2315, 10168), (5433, 23927), (9668, 45958)),
}
"""Paper Table 2, SA(tau) false alarms: (repetitive counted once, all alarms)."""

PAPER_TABLE3: dict[str, dict[str, tuple[float, ...]]] = {
    "iterations": {"n": (25, 50, 75, 100, 150, 200, 250)},
    "dua_sat": {
        "mean": (63.6, 64.2, 67.87, 70.9, 68.73, 68.4, 64.56),
        "std": (27.29, 19.58, 19.30, 19.61, 18.46, 16.61, 20.94),
    },
    "sad_sat": {
        "mean": (16.8, 15.4, 19.73, 19.4, 21.67, 24.0, 21.6),
        "std": (17.66, 13.98, 10.73, 8.56, 9.25, 8.92, 9.13),
    },
}
"""Paper Table 3, most-urgent-pair agreement in percent at N = 10 (10 sequences each)."""

PAPER_TABLE3_OVERALL: dict[str, tuple[float, float]] = {
    "dua_sat": (66.89, 20.26),
    "sad_sat": (19.8, 11.18),
}

# --------------------------------------------------------------------------- clocks

PAPER_SECONDS_PER_EVAL = 0.0556
"""Seconds per tau evaluation in the paper: relative least-squares fit of Table 2's Delta t
against evaluations per iteration (DUA: ceil(log2(M + 1)), SA: M), both algorithms together.
The fitted overhead is -0.018 s, i.e. none."""

MEASURED_NS_PER_EVAL = 160.0
"""Compiled cost of one tau evaluation (ns), fitted by ``calibrate_work_clock`` on the
development machine (2 cores, numba 0.6x): DUA fused kernel and serial SA loop together."""

MEASURED_NS_OVERHEAD = 140.0
"""Compiled fixed cost of one iteration (ns): selection, sort of the withdrawn pairs, reinsertion.
From the same fit as ``MEASURED_NS_PER_EVAL``."""

FIXED_DT = 0.5
"""The fixed clock (s). Of the order of DUA's own work-clock period (0.3 to 1.2 s here), i.e. the
period a simulator would give the predictor; SA given the same period would need M / L times the
computing power DUA needs, which is the point of contrasting the two clocks."""


@dataclass(frozen=True)
class WorkClock:
    """``dt = seconds_per_eval * (E + overhead_evals)``: the paper's clock with our cost ratio.

    Attributes:
        seconds_per_eval: Seconds one evaluation of tau takes (the paper's machine).
        overhead_evals: Fixed per-iteration cost in units of one evaluation (measured here).
    """

    seconds_per_eval: float = PAPER_SECONDS_PER_EVAL
    overhead_evals: float = MEASURED_NS_OVERHEAD / MEASURED_NS_PER_EVAL

    def dt(self, evaluations: int) -> float:
        """Period of an iteration that evaluates tau ``evaluations`` times."""
        return self.seconds_per_eval * (evaluations + self.overhead_evals)


@dataclass(frozen=True)
class WorldParams:
    """The sphere world (paper sec. 8.1: spheres in a cube, random bounded accelerations).

    The paper gives no dimensions. Ours: a 10 m cell, 20 cm spheres, speeds of the order of
    0.4 m/s and an acceleration bound of 0.2 m/s^2 per sphere (0.4 m/s^2 per pair), re-drawn
    every ~5 s (physics step 2 s). On the paper's clock (0.2 to 0.7 s per DUA iteration) that is
    "a worst-case scenario as far as coherence is concerned": one SA period at N = 40 (~43 s)
    lets any pair cross the cell. The acceleration bound was picked among 0.05, 0.1 and 0.2 m/s^2
    as the one whose DUA false-alarm counts (N = 10..40, 25 iterations) came closest to the
    paper's Table 2; nothing else was tuned.

    Attributes:
        box: Cube edge (m).
        radius: Sphere radius (m).
        accel: Bound on each sphere's acceleration norm (m/s^2); pairs get twice this.
        speed: Initial speeds are uniform in ``[0, speed]`` (m/s).
        physics_dt: Physics step (s): accelerations change only at its boundaries.
        switch_steps: Mean physics steps between acceleration switches of a sphere.
    """

    box: float = 10.0
    radius: float = 0.1
    accel: float = 0.2
    speed: float = 0.4
    physics_dt: float = 2.0
    switch_steps: float = 2.5

    def world(self, n: int, seed: int) -> SphereWorld:
        """A fresh world of ``n`` spheres."""
        return SphereWorld(
            n,
            seed=seed,
            box=self.box,
            radius=self.radius,
            accel=self.accel,
            speed=self.speed,
            dt=self.physics_dt,
            switch_steps=self.switch_steps,
        )


class _Sampler:
    """Exact states of a world at non-decreasing times, independent of its physics step."""

    def __init__(self, world: SphereWorld) -> None:
        self.world = world

    def state(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        w = self.world
        # Small tolerance: world.time accumulates physics_dt and drifts by rounding.
        while w.time + w.dt <= t + 1e-12 * max(1.0, t):
            w.step()
        s = max(0.0, t - w.time)
        return w.positions_at(s), np.asarray(w.velocities + w.accelerations * s)


# --------------------------------------------------------------------------- results


@dataclass(frozen=True)
class PaperRow:
    """One (N, clock) row of the reproduction (means over seeds unless stated).

    Attributes:
        N: Number of spheres.
        mode: ``"realtime"`` (work clock) or ``"fixed"``.
        pairs: ``M = N (N - 1) / 2``.
        buckets: DUA's ``L = ceil(log2(M + 1))``.
        seeds: Random sequences.
        dua_iterations: Iterations of each DUA run.
        sa_iterations: Iterations of each SA(tau) run (smaller at N = 1000).
        dt_dua: DUA's period (s).
        dt_sa: SA(tau)'s period (s).
        dua_evals_per_iter: Mean tau evaluations per DUA iteration (empty slots skipped).
        sa_evals_per_iter: Tau evaluations per SA(tau) iteration (M).
        dua_us_per_iter: Median wall time of DUA's fused ``step_points`` (us).
        dua_select_update_us_per_iter: Median wall time of ``select`` + ``PairSet.tau`` +
            ``update`` (us).
        sa_us_per_iter: Median wall time of SA(tau)'s ``select`` + ``PairSet.tau`` + ``update``.
        dua_kernel_ns_per_iter: Compiled DUA step, no Python in the loop (ns).
        sa_kernel_ns_per_iter: Compiled serial SA(tau) iteration (ns).
        dua_false_alarms: False alarms per run, repetitive ones counted once.
        sa_false_alarms: Same for SA(tau).
        dua_alarms_all: All alarms per run (no filtering; the paper's DUA count).
        sa_alarms_all: All alarms per run (the paper's parenthesised SA count).
        dua_false_alarms_per_iter: ``dua_false_alarms / dua_iterations``.
        sa_false_alarms_per_iter: ``sa_false_alarms / sa_iterations``.
        dua_false_alarms_at: False alarms after the first k iterations, by k (paper's rows).
        sa_false_alarms_at: Same for SA(tau).
        sa_alarms_all_at: All SA(tau) alarms after the first k iterations.
        dua_alarms_all_at: All DUA alarms after the first k iterations.
        dua_collisions: Contact onsets seen at DUA's samples, per run.
        sa_collisions: Contact onsets seen at SA's samples, per run.
        missed_collisions: Sampled contacts not alarmed by the pair's latest earlier evaluation
            (both algorithms, all runs): must be 0.
        agree_dua_sat: % of DUA iterations where DUA's most urgent pair is SA(tau)'s.
        agree_sad_sat: % of the same iterations where SA(d)'s argmin is SA(tau)'s.
    """

    N: int
    mode: str
    pairs: int
    buckets: int
    seeds: int
    dua_iterations: int
    sa_iterations: int
    dt_dua: float
    dt_sa: float
    dua_evals_per_iter: float
    sa_evals_per_iter: float
    dua_us_per_iter: float
    dua_select_update_us_per_iter: float
    sa_us_per_iter: float
    dua_kernel_ns_per_iter: float | None
    sa_kernel_ns_per_iter: float | None
    dua_false_alarms: float
    sa_false_alarms: float
    dua_alarms_all: float
    sa_alarms_all: float
    dua_false_alarms_per_iter: float
    sa_false_alarms_per_iter: float
    dua_false_alarms_at: dict[int, float]
    sa_false_alarms_at: dict[int, float]
    dua_alarms_all_at: dict[int, float]
    sa_alarms_all_at: dict[int, float]
    dua_collisions: float
    sa_collisions: float
    missed_collisions: int
    agree_dua_sat: float | None
    agree_sad_sat: float | None


@dataclass(frozen=True)
class AgreementRow:
    """Table 3: most-urgent-pair agreement (%) for one run length, over sequences.

    Attributes:
        N: Number of spheres (10 in the paper).
        iterations: Iterations per run.
        sequences: Random sequences.
        dua_sat_mean: Mean % of iterations where DUA's bucket-0 pair is SA(tau)'s argmin.
        dua_sat_std: Its standard deviation over sequences.
        sad_sat_mean: Mean % where SA(d)'s argmin distance is SA(tau)'s argmin.
        sad_sat_std: Its standard deviation over sequences.
    """

    N: int
    iterations: int
    sequences: int
    dua_sat_mean: float
    dua_sat_std: float
    sad_sat_mean: float
    sad_sat_std: float


@dataclass(frozen=True)
class _Run:
    """One algorithm on one world sequence."""

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


@dataclass(frozen=True)
class _Plan:
    """Sizes of one reproduction (full, quick or tiny)."""

    n_values: tuple[int, ...]
    seeds: int
    iterations: dict[int, int]
    sa_iterations: dict[int, int]
    prefixes: tuple[int, ...]
    table3_lengths: tuple[int, ...]
    table3_sequences: int
    kernel_reps: int
    modes: tuple[str, ...] = ("realtime", "fixed")
    label: str = "full"
    seed_cap: dict[int, int] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def _plan(quick: bool, tiny: bool, seeds: int) -> _Plan:
    if tiny:
        ns: tuple[int, ...] = (5, 10)
        return _Plan(
            n_values=ns,
            seeds=min(seeds, 2),
            iterations=dict.fromkeys(ns, 25),
            sa_iterations=dict.fromkeys(ns, 25),
            prefixes=(25,),
            table3_lengths=(25,),
            table3_sequences=2,
            kernel_reps=50,
            label="tiny",
        )
    if quick:
        ns = (*PAPER_N, 100, 200)
        its = {n: 75 if n <= 40 else 25 for n in ns}
        return _Plan(
            n_values=ns,
            seeds=min(seeds, 5),
            iterations=its,
            sa_iterations=dict(its),
            prefixes=(25, 50, 75),
            table3_lengths=(25, 50, 100, 250),
            table3_sequences=5,
            kernel_reps=500,
            label="quick",
        )
    ns = (*PAPER_N, 100, 200, 400, 1000)
    its = {n: 75 if n <= 40 else 25 for n in ns}
    sa_its = dict(its)
    # SA's work-clock period is ~1.2 h of world time at N = 400 and ~7.7 h at N = 1000 (M = 79800
    # and 499500 evaluations per iteration): simulating that world time exactly dominates the
    # run, so SA gets 10 and 2 iterations there, and N = 1000 gets 5 sequences instead of 10.
    sa_its[400] = 10
    sa_its[1000] = 2
    return _Plan(
        n_values=ns,
        seeds=seeds,
        iterations=its,
        sa_iterations=sa_its,
        prefixes=(25, 35, 50, 65, 75),
        table3_lengths=PAPER_TABLE3["iterations"]["n"],  # type: ignore[arg-type]
        table3_sequences=10,
        kernel_reps=2000,
        seed_cap={1000: min(seeds, 5)},
        notes=[
            "SA(tau) runs 10 iterations at N = 400 and 2 at N = 1000; N = 1000 uses "
            f"{min(seeds, 5)} sequences (its SA period is hours of world time to simulate)."
        ],
    )


# --------------------------------------------------------------------------- compiled kernels


@nb.njit(cache=True)
def _dua_kernel_loop(
    iters, n0, slots, pair_state, last_tau, horizon, active, nbuckets, work, w_tau, geometry
):  # pragma: no cover - jitted
    total = 0
    for n in range(n0, n0 + iters):
        # Indexed, not unpacked: the kernel's result tuple has grown before (a non-finite flag).
        res = _step_points(
            slots, pair_state, last_tau, horizon, active, nbuckets, 1, n, work, w_tau, geometry
        )
        total += res[0]
    return total


@nb.njit(cache=True)
def _sa_kernel_loop(iters, threshold, geometry):  # pragma: no cover - jitted
    # Serial on purpose: the cost model counts evaluations, and DUA's step is serial too.
    nalarm = 0
    first = geometry[4]  # PairSet._geometry: (centers, velocities, normals, offsets, first, ...)
    m = first.shape[0]
    for _ in range(iters):
        for p in range(m):
            if _pair_tau(p, geometry) < threshold:
                nalarm += 1
    return nalarm


def _kernel_costs(n: int, params: WorldParams, reps: int, seed: int = 0) -> tuple[float, float]:
    """Compiled ns per iteration of DUA (fused step) and of serial SA(tau) at ``n`` spheres.

    The kernels are the scheduler's own jitted pieces, called from a compiled loop so that no
    Python call overhead is counted: the closest analogue of the paper's instruction counts.
    """
    world = params.world(n, seed)
    pairs = world.pairs()
    c, v = world.positions, world.velocities
    dua = DUAScheduler(pairs.tau(np.arange(len(pairs)), c, v), dt=1.0)
    geometry = pairs._geometry(c, v, None)
    # The DUA loop mutates the scheduler's private arrays: it runs on a throwaway instance.
    state = (
        dua.slots,
        dua._pair_state,
        dua.last_tau,
        dua.horizon,
        dua.active,
        dua.nbuckets,
        dua._work,
        dua._w_tau,
    )
    _dua_kernel_loop(1, 1, *state, geometry)
    # Best of three: other processes only ever add time, so the minimum is the cleanest estimate.
    dua_ns = math.inf
    for rep in range(3):
        t0 = time.perf_counter()
        _dua_kernel_loop(reps, 2 + rep * reps, *state, geometry)
        dua_ns = min(dua_ns, (time.perf_counter() - t0) / reps * 1e9)
    # SA: enough repetitions for ~reps * 10 evaluations, at least one.
    sa_reps = max(1, (reps * 10) // len(pairs))
    _sa_kernel_loop(1, 2.0, geometry)
    sa_ns = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        _sa_kernel_loop(sa_reps, 2.0, geometry)
        sa_ns = min(sa_ns, (time.perf_counter() - t0) / sa_reps * 1e9)
    return dua_ns, sa_ns


def calibrate_work_clock(
    n_values: Sequence[int] = (5, 10, 20, 40, 100, 200, 400),
    *,
    params: WorldParams | None = None,
    reps: int = 5000,
) -> tuple[float, float]:
    """Fit ``ns = c E + overhead`` to compiled DUA and SA(tau) iterations (relative errors).

    This produced ``MEASURED_NS_PER_EVAL`` and ``MEASURED_NS_OVERHEAD``; rerun it to recalibrate.

    Args:
        n_values: Sphere counts to measure.
        params: World parameters (default ``WorldParams()``).
        reps: DUA iterations per measurement (SA gets ``10 reps / M``).

    Returns:
        ``(c, overhead)`` in nanoseconds.
    """
    p = params or WorldParams()
    evals, ns = [], []
    for n in n_values:
        dua_ns, sa_ns = _kernel_costs(n, p, reps)
        m = n * (n - 1) // 2
        evals += [bucket_layout(m)[0], m]
        ns += [dua_ns, sa_ns]
    e = np.asarray(evals, dtype=np.float64)
    y = np.asarray(ns)
    # Relative least squares: the points span five decades of cost.
    a = np.stack([e, np.ones_like(e)], axis=1) / y[:, None]
    coef = np.linalg.lstsq(a, np.ones_like(y), rcond=None)[0]
    return float(coef[0]), float(coef[1])


# --------------------------------------------------------------------------- runs


def _prefix_counts(iters: np.ndarray, prefixes: Iterable[int], total: int) -> dict[int, int]:
    """Events with iteration ``<= k`` for each prefix ``k`` (and the whole run)."""
    keys = sorted({*(k for k in prefixes if k <= total), total})
    return {k: int((iters <= k).sum()) for k in keys}


class _Contacts:
    """Sampled contacts of all pairs, contact onsets and the completeness check (vectorised)."""

    def __init__(self, pairs: PairSet) -> None:
        self.first, self.second, self.eps = pairs.first, pairs.second, pairs.eps
        m = len(pairs)
        self.previous = np.zeros(m, dtype=np.bool_)
        self.ever = np.zeros(m, dtype=np.bool_)
        self.onsets = 0
        self.missed = 0

    def distance(self, centers: np.ndarray) -> np.ndarray:
        return np.asarray(
            np.linalg.norm(centers[self.second] - centers[self.first], axis=1) - self.eps
        )

    def observe(self, dist: np.ndarray, armed: np.ndarray) -> None:
        """Record contacts at this sample; ``armed``: the pair's latest earlier evaluation alarmed.

        Completeness (SPEC section 4): an evaluation at step m that does not alarm guarantees no
        contact up to its next evaluation m + I, so a contact at sample n is always covered by an
        alarm of the latest evaluation before n.
        """
        contact = dist <= 0.0
        self.onsets += int((contact & ~self.previous).sum())
        self.missed += int((contact & ~armed).sum())
        self.ever |= contact
        self.previous = contact


def _dua_run(
    n: int,
    seed: int,
    dt: float,
    iterations: int,
    params: WorldParams,
    prefixes: Sequence[int],
    agreement: bool,
) -> _Run:
    """DUA on one sequence; also the SA(tau)/SA(d) references for agreement at the same states."""
    sampler = _Sampler(params.world(n, seed))
    pairs = sampler.world.pairs()
    m = len(pairs)
    all_ids = np.arange(m)
    c, v = sampler.state(0.0)
    tau0 = pairs.tau(all_ids, c, v)
    fused = DUAScheduler(tau0, dt=dt)
    # A twin driven through select/update: same inputs, so the same state at every step.
    twin = DUAScheduler(tau0, dt=dt)
    contacts = _Contacts(pairs)
    armed = np.zeros(m, dtype=np.bool_)
    armed[fused.initial_alarms] = True
    # Repetitive alarms: the paper counts from iteration 1, so the initial classification does
    # not make the first in-run alarm of a pair repetitive.
    repeat = np.zeros(m, dtype=np.bool_)
    contacts.observe(contacts.distance(c), armed)
    k = np.arange(fused.nbuckets)
    base = (1 << k) - 1
    us, us_su, evals = [], [], 0
    all_iter: list[np.ndarray] = []
    all_pair: list[np.ndarray] = []
    new_iter: list[np.ndarray] = []
    new_pair: list[np.ndarray] = []
    agree_dua = agree_sad = 0
    for it in range(1, iterations + 1):
        c, v = sampler.state(it * dt)
        dist = contacts.distance(c)
        contacts.observe(dist, armed)
        t0 = time.perf_counter()
        alarms = fused.step_points(pairs, c, v)
        us.append((time.perf_counter() - t0) * 1e6)
        t0 = time.perf_counter()
        ids = twin.select()
        twin_alarms = twin.update(ids, pairs.tau(ids, c, v))
        us_su.append((time.perf_counter() - t0) * 1e6)
        if not np.array_equal(np.sort(alarms), np.sort(twin_alarms)):
            raise AssertionError(f"fused and select/update DUA disagree at N={n}, step {it}.")
        # The evaluated pairs sit in the withdrawn slots again after reinsertion.
        withdrawn = fused.slots[base + it % (1 << k)]
        evaluated = withdrawn[withdrawn >= 0]
        evals += evaluated.size
        armed[evaluated] = False
        armed[alarms] = True
        fresh = alarms[~repeat[alarms]]
        repeat[evaluated] = False
        repeat[alarms] = True
        all_iter.append(np.full(alarms.size, it))
        all_pair.append(alarms)
        new_iter.append(np.full(fresh.size, it))
        new_pair.append(fresh)
        if agreement:
            tau = pairs.tau(all_ids, c, v)
            best = tau.min()
            # Ties (e.g. two overlapping pairs at tau = 0) count as agreement.
            agree_dua += bool(tau[fused.most_urgent()] <= best)
            agree_sad += bool(tau[int(np.argmin(dist))] <= best)
    return _finish_run(
        iterations,
        evals / iterations,
        us,
        us_su,
        contacts,
        (np.concatenate(all_iter), np.concatenate(all_pair)),
        (np.concatenate(new_iter), np.concatenate(new_pair)),
        prefixes,
        100.0 * agree_dua / iterations if agreement else None,
        100.0 * agree_sad / iterations if agreement else None,
    )


def _sa_run(
    n: int,
    seed: int,
    dt: float,
    iterations: int,
    params: WorldParams,
    prefixes: Sequence[int],
) -> _Run:
    """SA(tau) on one sequence: every pair every iteration, alarm if tau < 2 dt."""
    sampler = _Sampler(params.world(n, seed))
    pairs = sampler.world.pairs()
    m = len(pairs)
    c, v = sampler.state(0.0)
    sa = SelectAllScheduler(pairs.tau(np.arange(m), c, v), dt=dt, urgency="tau")
    contacts = _Contacts(pairs)
    armed = np.zeros(m, dtype=np.bool_)
    armed[sa.initial_alarms] = True
    repeat = np.zeros(m, dtype=np.bool_)
    contacts.observe(contacts.distance(c), armed)
    us: list[float] = []
    all_iter: list[np.ndarray] = []
    all_pair: list[np.ndarray] = []
    new_iter: list[np.ndarray] = []
    new_pair: list[np.ndarray] = []
    for it in range(1, iterations + 1):
        c, v = sampler.state(it * dt)
        contacts.observe(contacts.distance(c), armed)
        t0 = time.perf_counter()
        ids = sa.select()
        alarms = sa.update(ids, pairs.tau(ids, c, v))
        us.append((time.perf_counter() - t0) * 1e6)
        fresh = alarms[~repeat[alarms]]
        armed[:] = False
        armed[alarms] = True
        repeat[:] = armed
        all_iter.append(np.full(alarms.size, it))
        all_pair.append(alarms)
        new_iter.append(np.full(fresh.size, it))
        new_pair.append(fresh)
    return _finish_run(
        iterations,
        float(m),
        us,
        us,
        contacts,
        (np.concatenate(all_iter), np.concatenate(all_pair)),
        (np.concatenate(new_iter), np.concatenate(new_pair)),
        prefixes,
        None,
        None,
    )


def _finish_run(
    iterations: int,
    evals: float,
    us: list[float],
    us_su: list[float],
    contacts: _Contacts,
    all_alarms: tuple[np.ndarray, np.ndarray],
    new_alarms: tuple[np.ndarray, np.ndarray],
    prefixes: Sequence[int],
    agree_dua: float | None,
    agree_sad: float | None,
) -> _Run:
    # An alarm is false when its pair never touches during the run (sampled contacts).
    new_iter, new_pair = new_alarms
    false_iter = new_iter[~contacts.ever[new_pair]]
    return _Run(
        iterations=iterations,
        evals=evals,
        us=us,
        us_select_update=us_su,
        false_at=_prefix_counts(false_iter, prefixes, iterations),
        all_at=_prefix_counts(all_alarms[0], prefixes, iterations),
        collisions=contacts.onsets,
        missed=contacts.missed,
        agree_dua_sat=agree_dua,
        agree_sad_sat=agree_sad,
    )


# --------------------------------------------------------------------------- progress


class _Progress:
    """A one-line text progress bar on stderr (``\\r``-rewritten), or nothing."""

    def __init__(self, total: int, enabled: bool) -> None:
        self.total, self.done, self.enabled = max(1, total), 0, enabled
        self.start = time.perf_counter()

    def advance(self, label: str) -> None:
        self.done += 1
        if not self.enabled:
            return
        width = 30
        fill = round(width * self.done / self.total)
        elapsed = time.perf_counter() - self.start
        sys.stderr.write(
            f"\r[{'#' * fill}{'.' * (width - fill)}] {self.done}/{self.total} "
            f"{elapsed:6.1f}s {label:<28}"
        )
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")
            sys.stderr.flush()


# --------------------------------------------------------------------------- driver


def _mean_at(runs: Sequence[_Run], attr: str) -> dict[int, float]:
    keys = sorted(set.intersection(*(set(getattr(r, attr)) for r in runs)))
    return {k: float(np.mean([getattr(r, attr)[k] for r in runs])) for k in keys}


def _row(
    n: int,
    mode: str,
    plan: _Plan,
    dt_dua: float,
    dt_sa: float,
    dua: Sequence[_Run],
    sa: Sequence[_Run],
    kernel: tuple[float, float] | None,
) -> PaperRow:
    m = n * (n - 1) // 2
    dua_false = _mean_at(dua, "false_at")
    sa_false = _mean_at(sa, "false_at")
    dua_all = _mean_at(dua, "all_at")
    sa_all = _mean_at(sa, "all_at")
    d_it, s_it = plan.iterations[n], plan.sa_iterations[n]
    agree = [r.agree_dua_sat for r in dua if r.agree_dua_sat is not None]
    agree_d = [r.agree_sad_sat for r in dua if r.agree_sad_sat is not None]
    return PaperRow(
        N=n,
        mode=mode,
        pairs=m,
        buckets=bucket_layout(m)[0],
        seeds=len(dua),
        dua_iterations=d_it,
        sa_iterations=s_it,
        dt_dua=dt_dua,
        dt_sa=dt_sa,
        dua_evals_per_iter=float(np.mean([r.evals for r in dua])),
        sa_evals_per_iter=float(np.mean([r.evals for r in sa])),
        dua_us_per_iter=float(np.median(np.concatenate([r.us for r in dua]))),
        dua_select_update_us_per_iter=float(
            np.median(np.concatenate([r.us_select_update for r in dua]))
        ),
        sa_us_per_iter=float(np.median(np.concatenate([r.us for r in sa]))),
        dua_kernel_ns_per_iter=None if kernel is None else kernel[0],
        sa_kernel_ns_per_iter=None if kernel is None else kernel[1],
        dua_false_alarms=dua_false[d_it],
        sa_false_alarms=sa_false[s_it],
        dua_alarms_all=dua_all[d_it],
        sa_alarms_all=sa_all[s_it],
        dua_false_alarms_per_iter=dua_false[d_it] / d_it,
        sa_false_alarms_per_iter=sa_false[s_it] / s_it,
        dua_false_alarms_at=dua_false,
        sa_false_alarms_at=sa_false,
        dua_alarms_all_at=dua_all,
        sa_alarms_all_at=sa_all,
        dua_collisions=float(np.mean([r.collisions for r in dua])),
        sa_collisions=float(np.mean([r.collisions for r in sa])),
        missed_collisions=int(sum(r.missed for r in dua) + sum(r.missed for r in sa)),
        agree_dua_sat=float(np.mean(agree)) if agree else None,
        agree_sad_sat=float(np.mean(agree_d)) if agree_d else None,
    )


def _table3(
    plan: _Plan, params: WorldParams, clock: WorkClock, progress: _Progress
) -> list[AgreementRow]:
    n = 10
    dt = clock.dt(bucket_layout(n * (n - 1) // 2)[0])
    rows = []
    for length in plan.table3_lengths:
        runs = []
        for s in range(plan.table3_sequences):
            # Distinct sequences per run length, as the paper's separate runs.
            runs.append(_dua_run(n, 10_000 + 1000 * length + s, dt, length, params, (), True))
            progress.advance(f"table 3: {length} iterations")
        a = np.asarray([r.agree_dua_sat for r in runs], dtype=np.float64)
        b = np.asarray([r.agree_sad_sat for r in runs], dtype=np.float64)
        rows.append(
            AgreementRow(
                N=n,
                iterations=length,
                sequences=len(runs),
                dua_sat_mean=float(a.mean()),
                dua_sat_std=float(a.std(ddof=1)) if a.size > 1 else 0.0,
                sad_sat_mean=float(b.mean()),
                sad_sat_std=float(b.std(ddof=1)) if b.size > 1 else 0.0,
            )
        )
    return rows


def run_paper(
    *,
    quick: bool = False,
    out_dir: Path | None = Path("out/paper"),
    json_path: Path | None = None,
    seeds: int = 10,
    progress: bool = True,
    tiny: bool = False,
    params: WorldParams | None = None,
    clock: WorkClock | None = None,
    fixed_dt: float = FIXED_DT,
) -> dict[str, Any]:
    """Run the reproduction; write tables, plots and JSON.

    Args:
        quick: Smaller run (N = 5..40, 100, 200; 5 seeds): well under 2 minutes.
        out_dir: Directory for ``paper-tables.md`` and the PNG plots (None: write nothing there).
        json_path: Where to write the JSON results (None: not written).
        seeds: Random sequences per (N, clock) (capped at 5 with ``quick``, 2 with ``tiny``).
        progress: Show a progress bar on stderr.
        tiny: Internal knob for tests: N in {5, 10}, 2 seeds, 25 iterations.
        params: World parameters (default ``WorldParams()``).
        clock: Work-clock model (default ``WorkClock()``).
        fixed_dt: Period of the fixed clock (s).

    Returns:
        ``{"rows": [PaperRow as dict, ...], "table3": [...], "meta": {...}, "markdown": str}``.

    Raises:
        AssertionError: A sampled collision was not alarmed (completeness violated).
    """
    plan = _plan(quick, tiny, seeds)
    params = params or WorldParams()
    clock = clock or WorkClock()
    started = time.perf_counter()
    total = (
        sum(1 + len(plan.modes) * plan.seed_cap.get(n, plan.seeds) for n in plan.n_values)
        + len(plan.table3_lengths) * plan.table3_sequences
    )
    bar = _Progress(total, progress)
    rows: list[PaperRow] = []
    for n in plan.n_values:
        kernel = _kernel_costs(n, params, plan.kernel_reps)
        bar.advance(f"N={n} kernels")
        m = n * (n - 1) // 2
        for mode in plan.modes:
            if mode == "realtime":
                dt_dua, dt_sa = clock.dt(bucket_layout(m)[0]), clock.dt(m)
            else:
                dt_dua = dt_sa = fixed_dt
            dua_runs, sa_runs = [], []
            for s in range(plan.seed_cap.get(n, plan.seeds)):
                dua_runs.append(
                    _dua_run(n, s, dt_dua, plan.iterations[n], params, plan.prefixes, True)
                )
                sa_runs.append(_sa_run(n, s, dt_sa, plan.sa_iterations[n], params, plan.prefixes))
                bar.advance(f"N={n} {mode} seed {s}")
            rows.append(_row(n, mode, plan, dt_dua, dt_sa, dua_runs, sa_runs, kernel))
    table3 = _table3(plan, params, clock, bar)
    bar.close()
    missed = sum(r.missed_collisions for r in rows)
    if missed:
        raise AssertionError(f"{missed} sampled collisions were not alarmed beforehand.")
    meta = {
        "plan": plan.label,
        "seconds": time.perf_counter() - started,
        "world": asdict(params),
        "work_clock": {
            "seconds_per_eval": clock.seconds_per_eval,
            "overhead_evals": clock.overhead_evals,
            "measured_ns_per_eval": MEASURED_NS_PER_EVAL,
            "measured_ns_overhead": MEASURED_NS_OVERHEAD,
        },
        "fixed_dt": fixed_dt,
        "latency": 1,
        "notes": plan.notes,
    }
    markdown = _markdown(rows, table3, meta)
    result: dict[str, Any] = {
        "rows": [_jsonable(asdict(r)) for r in rows],
        "table3": [asdict(r) for r in table3],
        "meta": meta,
        "markdown": markdown,
    }
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / "paper-tables.md").write_text(markdown)
        _plots(rows, table3, out_dir)
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        payload = {k: v for k, v in result.items() if k != "markdown"}
        json_path.write_text(json.dumps(payload, indent=2))
    return result


def _jsonable(d: dict[str, Any]) -> dict[str, Any]:
    # JSON object keys must be strings; the prefix dicts are keyed by iteration counts.
    return {
        k: ({str(a): b for a, b in v.items()} if isinstance(v, dict) else v) for k, v in d.items()
    }


# --------------------------------------------------------------------------- reporting


def _fmt(x: float | None, digits: int = 1) -> str:
    if x is None:
        return "-"
    if isinstance(x, float) and not math.isfinite(x):
        return str(x)
    return f"{x:,.{digits}f}"


def _table(header: Sequence[str], body: Iterable[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---:" for _ in header) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in body]
    return "\n".join(lines)


def _markdown(
    rows: Sequence[PaperRow], table3: Sequence[AgreementRow], meta: dict[str, Any]
) -> str:
    rt = {r.N: r for r in rows if r.mode == "realtime"}
    fx = {r.N: r for r in rows if r.mode == "fixed"}
    out = [f"# Paper reproduction ({meta['plan']} run, {meta['seconds']:.0f} s)", ""]
    wc = meta["work_clock"]
    out += [
        f"World: {meta['world']}. Latency 1 (paper eq. 26). Work clock: dt = "
        f"{wc['seconds_per_eval']} s x (E + {wc['overhead_evals']:.2f}) (E evaluations per "
        f"iteration; our measured {wc['measured_ns_per_eval']} ns/evaluation + "
        f"{wc['measured_ns_overhead']} ns/iteration on the paper's 0.0556 s/evaluation scale). "
        f"Fixed clock: dt = {meta['fixed_dt']} s.",
        "",
    ]
    if meta["notes"]:
        out += [f"Note: {' '.join(meta['notes'])}", ""]

    out += ["## Table 1: cost per iteration", ""]
    body = []
    for n, r in rt.items():
        paper = (
            (
                _fmt(PAPER_TABLE1["DUA"][PAPER_N.index(n)], 2),
                _fmt(PAPER_TABLE1["SA"][PAPER_N.index(n)], 2),
            )
            if n in PAPER_N
            else ("-", "-")
        )
        body.append(
            [
                str(n),
                str(r.pairs),
                _fmt(r.dua_evals_per_iter, 2),
                _fmt(r.sa_evals_per_iter, 0),
                _fmt(r.dua_kernel_ns_per_iter, 0),
                _fmt(r.sa_kernel_ns_per_iter, 0),
                _fmt(r.dua_us_per_iter, 1),
                _fmt(r.dua_select_update_us_per_iter, 1),
                _fmt(r.sa_us_per_iter, 1),
                *paper,
            ]
        )
    out += [
        _table(
            [
                "N",
                "pairs M",
                "DUA evals/it",
                "SA evals/it",
                "DUA kernel ns/it",
                "SA kernel ns/it",
                "DUA step_points us/it",
                "DUA select/update us/it",
                "SA us/it",
                "paper DUA ticks",
                "paper SA ticks",
            ],
            body,
        ),
        "",
        "Evaluations: mean per iteration. Kernel: compiled loop, serial, no Python. us/it: median "
        "wall time through the public API (includes input validation and, for SA, the parallel "
        "tau kernel on all cores). Paper: 'CPU cycles' = 1/60 s ticks on a SPARC 470.",
        "",
    ]

    out += ["## Table 2: false alarms per run (repetitive alarms counted once)", ""]
    for mode, by_n in (("realtime (work clock)", rt), ("fixed clock", fx)):
        out += [f"### {mode}", ""]
        body = []
        for n, r in by_n.items():
            i = PAPER_N.index(n) if n in PAPER_N and mode.startswith("realtime") else None
            last = max(PAPER_TABLE2_DUA) if r.dua_iterations >= 75 else 25
            paper_dua = "-" if i is None else str(PAPER_TABLE2_DUA[last][i])
            paper_sa = "-" if i is None else "{} ({})".format(*PAPER_TABLE2_SA[last][i])
            paper_dt = (
                "-" if i is None else f"{PAPER_TABLE2_DT['DUA'][i]} / {PAPER_TABLE2_DT['SA'][i]}"
            )
            body.append(
                [
                    str(n),
                    f"{_fmt(r.dt_dua, 2)} / {_fmt(r.dt_sa, 2)}",
                    paper_dt,
                    f"{r.dua_iterations} / {r.sa_iterations}",
                    f"{_fmt(r.dua_false_alarms)} ({_fmt(r.dua_alarms_all)})",
                    f"{_fmt(r.sa_false_alarms)} ({_fmt(r.sa_alarms_all)})",
                    f"{_fmt(r.dua_false_alarms_per_iter, 2)} / "
                    f"{_fmt(r.sa_false_alarms_per_iter, 2)}",
                    f"{_fmt(r.dua_collisions, 2)} / {_fmt(r.sa_collisions, 2)}",
                    paper_dua,
                    paper_sa,
                ]
            )
        out += [
            _table(
                [
                    "N",
                    "dt DUA / SA (s)",
                    "paper dt DUA / SA",
                    "iterations DUA / SA",
                    "DUA false (all)",
                    "SA false (all)",
                    "false per iteration DUA / SA",
                    "collisions DUA / SA",
                    "paper DUA (all)",
                    "paper SA false (all)",
                ],
                body,
            ),
            "",
        ]
    # The paper's per-iteration-count rows, for N <= 40.
    small = [n for n in PAPER_N if n in rt and len(rt[n].dua_false_alarms_at) > 1]
    if small:
        out += ["### realtime, by iteration count (ours: false; paper: DUA all / SA false)", ""]
        body = []
        for k in sorted(rt[small[0]].dua_false_alarms_at):
            cells = [str(k)]
            for n in small:
                r = rt[n]
                i = PAPER_N.index(n)
                paper_cell = (
                    f" [{PAPER_TABLE2_DUA[k][i]} / {PAPER_TABLE2_SA[k][i][0]}]"
                    if k in PAPER_TABLE2_DUA
                    else ""
                )
                cells.append(
                    f"{_fmt(r.dua_false_alarms_at.get(k), 0)} / "
                    f"{_fmt(r.sa_false_alarms_at.get(k), 0)}{paper_cell}"
                )
            body.append(cells)
        out += [_table(["iterations", *(f"N={n} DUA / SA [paper]" for n in small)], body), ""]
    out += [
        "A false alarm is an alarm episode (an alarm whose pair did not alarm at its previous "
        "evaluation during the run) of a pair never in contact at any sample of the run. '(all)': "
        "every alarm, unfiltered (the paper's DUA numbers are unfiltered). Collisions: contact "
        f"onsets at the samples, per run; every sampled contact was alarmed beforehand "
        f"(missed: {sum(r.missed_collisions for r in rows)}).",
        "",
    ]

    out += ["## Table 3: most-urgent-pair agreement (%)", ""]
    body = []
    paper_n = PAPER_TABLE3["iterations"]["n"]
    for a in table3:
        j = paper_n.index(a.iterations) if a.iterations in paper_n else None
        pd = (
            "-"
            if j is None
            else f"{PAPER_TABLE3['dua_sat']['mean'][j]} ± {PAPER_TABLE3['dua_sat']['std'][j]}"
        )
        ps = (
            "-"
            if j is None
            else f"{PAPER_TABLE3['sad_sat']['mean'][j]} ± {PAPER_TABLE3['sad_sat']['std'][j]}"
        )
        body.append(
            [
                str(a.iterations),
                f"{a.dua_sat_mean:.1f} ± {a.dua_sat_std:.1f}",
                pd,
                f"{a.sad_sat_mean:.1f} ± {a.sad_sat_std:.1f}",
                ps,
            ]
        )
    if table3:
        da = np.mean([a.dua_sat_mean for a in table3])
        sd = np.mean([a.sad_sat_mean for a in table3])
        po = PAPER_TABLE3_OVERALL
        body.append(
            [
                "overall",
                f"{da:.1f}",
                f"{po['dua_sat'][0]} ± {po['dua_sat'][1]}",
                f"{sd:.1f}",
                f"{po['sad_sat'][0]} ± {po['sad_sat'][1]}",
            ]
        )
    out += [
        _table(
            ["iterations", "DUA vs SA(τ)", "paper", "SA(d) vs SA(τ)", "paper"],
            body,
        ),
        "",
        f"N = 10, DUA on its work clock, {table3[0].sequences if table3 else 0} sequences per "
        "length; mean ± standard deviation over sequences. Ties in tau count as agreement.",
        "",
        "### Agreement at every N (same runs as Table 2)",
        "",
        _table(
            ["N", "clock", "DUA vs SA(τ)", "SA(d) vs SA(τ)"],
            [
                [str(r.N), r.mode, _fmt(r.agree_dua_sat), _fmt(r.agree_sad_sat)]
                for r in sorted(rows, key=lambda r: (r.mode, r.N))
            ],
        ),
        "",
    ]
    return "\n".join(out)


def _plots(rows: Sequence[PaperRow], table3: Sequence[AgreementRow], out_dir: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rt = [r for r in rows if r.mode == "realtime"]
    fx = [r for r in rows if r.mode == "fixed"]
    ns = np.asarray([r.N for r in rt], dtype=np.float64)

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    ax1.loglog(ns, [r.dua_evals_per_iter for r in rt], "o-", label="DUA evaluations/it")
    ax1.loglog(ns, [r.sa_evals_per_iter for r in rt], "s-", label="SA(τ) evaluations/it")
    grid = np.geomspace(ns.min(), ns.max(), 50)
    ax1.loglog(grid, np.log2(grid * (grid - 1) / 2 + 1), "k:", label="log2(M+1) = O(log N)")
    ax1.loglog(grid, grid * (grid - 1) / 2, "k--", lw=0.8, label="M = N(N-1)/2")
    ax1.set_xlabel("spheres N")
    ax1.set_ylabel("evaluations per iteration")
    ax1.set_title("Cost per iteration (hardware-independent)")
    ax1.legend(fontsize=8)
    if all(r.dua_kernel_ns_per_iter is not None for r in rt):
        ax2.loglog(ns, [r.dua_kernel_ns_per_iter for r in rt], "o-", label="DUA kernel (ns)")
        ax2.loglog(ns, [r.sa_kernel_ns_per_iter for r in rt], "s-", label="SA(τ) kernel (ns)")
    ax2.loglog(ns, [r.dua_us_per_iter * 1e3 for r in rt], "o--", label="DUA step_points (ns)")
    ax2.loglog(ns, [r.sa_us_per_iter * 1e3 for r in rt], "s--", label="SA(τ) API (ns)")
    pn = np.asarray(PAPER_N, dtype=np.float64)
    # Paper ticks are 1/60 s; plotted in ns / 1e6 so the curves share the axis (shape only).
    ax2.loglog(pn, np.asarray(PAPER_TABLE1["DUA"]) * 100, "^:", label="paper DUA (ticks x 100)")
    ax2.loglog(pn, np.asarray(PAPER_TABLE1["SA"]) * 100, "v:", label="paper SA (ticks x 100)")
    ax2.set_xlabel("spheres N")
    ax2.set_ylabel("time per iteration")
    ax2.set_title("Time per iteration")
    ax2.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out_dir / "paper-cost.png", dpi=110)
    plt.close(fig)

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, rs, title in ((axes[0], rt, "work clock (realtime)"), (axes[1], fx, "fixed clock")):
        x = [r.N for r in rs]
        # Per iteration, so runs of different lengths (SA at N = 1000) are comparable; +0.01 keeps
        # zero counts on the log axis.
        ax.loglog(x, [r.dua_false_alarms_per_iter + 0.01 for r in rs], "o-", label="DUA")
        ax.loglog(x, [r.sa_false_alarms_per_iter + 0.01 for r in rs], "s-", label="SA(τ)")
        if rs is rt:
            last = 75
            ax.loglog(
                PAPER_N,
                np.asarray(PAPER_TABLE2_DUA[last]) / last + 0.01,
                "^:",
                label="paper DUA (all)",
            )
            ax.loglog(
                PAPER_N,
                np.asarray([a for a, _ in PAPER_TABLE2_SA[last]]) / last + 0.01,
                "v:",
                label="paper SA(τ)",
            )
        ax.set_xlabel("spheres N")
        ax.set_ylabel("false alarms per iteration (+0.01)")
        ax.set_title(title)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_dir / "paper-false-alarms.png", dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(8, 4))
    labels = [str(a.iterations) for a in table3]
    xs = np.arange(len(table3))
    paper_n = PAPER_TABLE3["iterations"]["n"]

    def paper(key: str) -> list[float]:
        return [
            PAPER_TABLE3[key]["mean"][paper_n.index(a.iterations)]
            if a.iterations in paper_n
            else np.nan
            for a in table3
        ]

    w = 0.2
    ax.bar(xs - 1.5 * w, [a.dua_sat_mean for a in table3], w, label="DUA vs SA(τ), ours")
    ax.bar(xs - 0.5 * w, paper("dua_sat"), w, label="DUA vs SA(τ), paper")
    ax.bar(xs + 0.5 * w, [a.sad_sat_mean for a in table3], w, label="SA(d) vs SA(τ), ours")
    ax.bar(xs + 1.5 * w, paper("sad_sat"), w, label="SA(d) vs SA(τ), paper")
    ax.set_xticks(xs, labels)
    ax.set_xlabel("iterations per run (N = 10)")
    ax.set_ylabel("agreement on the most urgent pair (%)")
    ax.set_ylim(0, 100)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_dir / "paper-agreement.png", dpi=110)
    plt.close(fig)


# --------------------------------------------------------------------------- CLI


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``dua-mujoco paper``."""
    parser.add_argument("--quick", action="store_true", help="small run (< 2 min)")
    parser.add_argument("--json", type=Path, default=None, metavar="PATH", help="write JSON here")
    parser.add_argument(
        "--out", type=Path, default=Path("out/paper"), metavar="DIR", help="tables and plots"
    )
    parser.add_argument("--seeds", type=int, default=10, metavar="N", help="sequences per setting")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")


def main(args: argparse.Namespace) -> int:
    """Run ``dua-mujoco paper`` with parsed ``args``; print the tables; return the exit code."""
    if args.seeds < 2:
        print("--seeds must be >= 2 (standard deviations need two sequences).", file=sys.stderr)
        return 2
    result = run_paper(
        quick=args.quick,
        out_dir=args.out,
        json_path=args.json,
        seeds=args.seeds,
        progress=not args.no_progress,
    )
    print(result["markdown"])
    return 0


if __name__ == "__main__":
    _parser = argparse.ArgumentParser(prog="dua-mujoco paper", description=__doc__)
    add_arguments(_parser)
    raise SystemExit(main(_parser.parse_args()))
