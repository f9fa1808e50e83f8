"""The reproduction's result rows: Tables 1 and 2 (``PaperRow``) and Table 3 (``AgreementRow``).

``paper_row`` condenses the runs of one (N, clock) into a row; ``agreement_rows`` runs Table 3.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dua_mujoco.experiments.paper.clock import WorkClock, dua_buckets
from dua_mujoco.experiments.paper.plan import Plan
from dua_mujoco.experiments.paper.sequences import Run, dua_run
from dua_mujoco.experiments.paper.world import WorldParams
from dua_mujoco.progress import Progress

__all__ = ["AgreementRow", "PaperRow", "agreement_rows", "paper_row"]


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


def _mean_at(runs: Sequence[Run], attr: str) -> dict[int, float]:
    # Prefixes every run reached (SA at large N runs fewer iterations than DUA).
    keys = sorted(set.intersection(*(set(getattr(r, attr)) for r in runs)))
    return {k: float(np.mean([getattr(r, attr)[k] for r in runs])) for k in keys}


def paper_row(
    n: int,
    mode: str,
    plan: Plan,
    dt_dua: float,
    dt_sa: float,
    dua: Sequence[Run],
    sa: Sequence[Run],
    kernel: tuple[float, float] | None,
) -> PaperRow:
    """Tables 1 and 2's row of one (N, clock) from its runs: means over seeds, median times.

    Args:
        n: Spheres.
        mode: ``"realtime"`` or ``"fixed"``.
        plan: The run's plan (iterations per algorithm).
        dt_dua: DUA's period (s).
        dt_sa: SA(tau)'s period (s).
        dua: DUA's runs, one per seed.
        sa: SA(tau)'s runs, same seeds.
        kernel: ``kernel_costs``'s ``(dua_ns, sa_ns)``, or None.
    """
    m = n * (n - 1) // 2
    d_it, s_it = plan.iterations[n], plan.sa_iterations[n]
    agree = [r.agree_dua_sat for r in dua if r.agree_dua_sat is not None]
    agree_d = [r.agree_sad_sat for r in dua if r.agree_sad_sat is not None]
    return PaperRow(
        N=n,
        mode=mode,
        pairs=m,
        buckets=dua_buckets(m),
        seeds=len(dua),
        **_algorithm_fields("dua", dua, d_it, dt_dua),
        **_algorithm_fields("sa", sa, s_it, dt_sa),
        dua_select_update_us_per_iter=float(
            np.median(np.concatenate([r.us_select_update for r in dua]))
        ),
        dua_kernel_ns_per_iter=None if kernel is None else kernel[0],
        sa_kernel_ns_per_iter=None if kernel is None else kernel[1],
        missed_collisions=int(sum(r.missed for r in dua) + sum(r.missed for r in sa)),
        agree_dua_sat=float(np.mean(agree)) if agree else None,
        agree_sad_sat=float(np.mean(agree_d)) if agree_d else None,
    )


def _algorithm_fields(name: str, runs: Sequence[Run], iterations: int, dt: float) -> dict[str, Any]:
    """The ``PaperRow`` fields of one algorithm (``name``: ``"dua"`` or ``"sa"``) from its runs
    of ``iterations`` iterations each at period ``dt``."""
    false = _mean_at(runs, "false_at")
    alarms = _mean_at(runs, "all_at")
    fields = {
        "iterations": iterations,
        "evals_per_iter": float(np.mean([r.evals for r in runs])),
        "us_per_iter": float(np.median(np.concatenate([r.us for r in runs]))),
        "false_alarms": false[iterations],
        "alarms_all": alarms[iterations],
        "false_alarms_per_iter": false[iterations] / iterations,
        "false_alarms_at": false,
        "alarms_all_at": alarms,
        "collisions": float(np.mean([r.collisions for r in runs])),
    }
    return {f"dt_{name}": dt} | {f"{name}_{key}": value for key, value in fields.items()}


def agreement_rows(
    plan: Plan, params: WorldParams, clock: WorkClock, progress: Progress
) -> list[AgreementRow]:
    """Table 3: DUA at N = 10 on its work clock, ``plan.table3_sequences`` runs per length.

    Args:
        plan: Run lengths and sequences per length.
        params: World parameters.
        clock: The work clock (DUA's period at N = 10).
        progress: Advanced once per run.
    """
    n = 10
    dt = clock.dt(dua_buckets(n * (n - 1) // 2))
    rows = []
    for length in plan.table3_lengths:
        runs = []
        for s in range(plan.table3_sequences):
            # Distinct sequences per run length, as the paper's separate runs.
            runs.append(dua_run(params.world(n, 10_000 + 1000 * length + s), dt, length, (), True))
            progress.update(note=f"table 3: {length} iterations")
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
