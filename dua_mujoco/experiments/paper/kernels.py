"""Native cost per iteration: the scheduler's own native step, one call an iteration.

The closest analogue of the paper's instruction counts (Table 1's kernel columns), and the
measurement behind the work clock's constants (``calibrate_work_clock``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np

import dua_mujoco._core as _core
from dua_mujoco.core.schedules import DUAScheduler
from dua_mujoco.core.urgency import PARALLEL_MIN
from dua_mujoco.experiments.paper.clock import dua_buckets
from dua_mujoco.experiments.paper.world import WorldParams

__all__ = ["calibrate_work_clock", "kernel_costs"]


def kernel_costs(n: int, params: WorldParams, reps: int, seed: int = 0) -> tuple[float, float]:
    """Native ns per iteration of DUA (fused step) and of serial SA(tau) at ``n`` spheres.

    Each iteration is one call of the native core (``_core.step_free``: select, tau, reinsert;
    ``_core.tau_pairs`` of every pair, in batches below the threaded size), so the Python
    around it is one call's fixed cost (a fraction of a microsecond): the closest analogue of
    the paper's instruction counts.

    Args:
        n: Spheres of the world (``WorldParams.world(n, seed)``).
        params: World parameters.
        reps: DUA iterations per measurement (SA gets ``10 reps / M``, at least one).
        seed: World seed.

    Returns:
        ``(dua_ns, sa_ns)``: best of three measurements each.
    """
    world = params.world(n, seed)
    pairs = world.pairs()
    c, v = world.positions, world.velocities
    ids = np.arange(len(pairs))
    # A throwaway scheduler: the loop drives its schedule without the Python protocol.
    dua = DUAScheduler(pairs.tau(ids, c, v), dt=1.0)
    inputs = (pairs.records, *pairs.inputs(c, v, None))
    step = _core.step_free
    schedule = dua.core
    step(schedule, *inputs)
    # Best of three: other processes only ever add time, so the minimum is the cleanest estimate.
    dua_ns = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        for _ in range(reps):
            step(schedule, *inputs)
        dua_ns = min(dua_ns, (time.perf_counter() - t0) / reps * 1e9)
    # SA: enough repetitions for ~reps * 10 evaluations, at least one. Serial on purpose (the
    # cost model counts evaluations, and DUA's step is serial too): batches below the size the
    # native batch splits over two threads.
    batches = np.array_split(ids, max(1, -(-ids.size // (PARALLEL_MIN - 1))))
    sa_reps = max(1, (reps * 10) // len(pairs))

    def sa() -> int:
        return sum(
            int((_core.tau_pairs(inputs[0], b, *inputs[1:])[0] < 2.0).sum()) for b in batches
        )

    sa()
    sa_ns = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        for _ in range(sa_reps):
            sa()
        sa_ns = min(sa_ns, (time.perf_counter() - t0) / sa_reps * 1e9)
    return dua_ns, sa_ns


def calibrate_work_clock(
    n_values: Sequence[int] = (5, 10, 20, 40, 100, 200, 400),
    *,
    params: WorldParams | None = None,
    reps: int = 5000,
) -> tuple[float, float]:
    """Fit ``ns = c E + overhead`` to native DUA and SA(tau) iterations (relative errors).

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
        dua_ns, sa_ns = kernel_costs(n, p, reps)
        m = n * (n - 1) // 2
        evals += [dua_buckets(m), m]
        ns += [dua_ns, sa_ns]
    e = np.asarray(evals, dtype=np.float64)
    y = np.asarray(ns)
    # Relative least squares: the points span five decades of cost.
    a = np.stack([e, np.ones_like(e)], axis=1) / y[:, None]
    coef = np.linalg.lstsq(a, np.ones_like(y), rcond=None)[0]
    return float(coef[0]), float(coef[1])
