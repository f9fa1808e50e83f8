"""Compiled cost per iteration: the scheduler's own jitted kernels in a loop without Python.

The closest analogue of the paper's instruction counts (Table 1's kernel columns), and the
measurement behind the work clock's constants (``calibrate_work_clock``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numba as nb
import numpy as np

from dua_mujoco.core.pairset import pair_tau
from dua_mujoco.core.schedules import DUAScheduler
from dua_mujoco.core.schedules.base import step_points_kernel
from dua_mujoco.experiments.paper.clock import dua_buckets
from dua_mujoco.experiments.paper.world import WorldParams

__all__ = ["calibrate_work_clock", "kernel_costs"]


@nb.njit(cache=True)
def _dua_kernel_loop(iters, n0, state, geometry):  # pragma: no cover - jitted
    total = 0
    for n in range(n0, n0 + iters):
        # Indexed, not unpacked: the kernel's result tuple has grown before (a non-finite flag).
        res = step_points_kernel(state, n, geometry)
        total += res[0]
    return total


@nb.njit(cache=True)
def _sa_kernel_loop(iters, threshold, geometry):  # pragma: no cover - jitted
    # Serial on purpose: the cost model counts evaluations, and DUA's step is serial too.
    nalarm = 0
    first = geometry[4]  # (centers, velocities, normals, offsets, first, ...)
    m = first.shape[0]
    for _ in range(iters):
        for p in range(m):
            if pair_tau(p, geometry) < threshold:
                nalarm += 1
    return nalarm


def kernel_costs(n: int, params: WorldParams, reps: int, seed: int = 0) -> tuple[float, float]:
    """Compiled ns per iteration of DUA (fused step) and of serial SA(tau) at ``n`` spheres.

    The kernels are the scheduler's own jitted pieces, called from a compiled loop so that no
    Python call overhead is counted: the closest analogue of the paper's instruction counts.

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
    # A throwaway scheduler: the loop drives its state without the Python protocol.
    dua = DUAScheduler(pairs.tau(np.arange(len(pairs)), c, v), dt=1.0)
    state, geometry = dua.kernel_state, pairs.inputs(c, v, None) + pairs.arrays()
    _dua_kernel_loop(1, 1, state, geometry)
    # Best of three: other processes only ever add time, so the minimum is the cleanest estimate.
    dua_ns = math.inf
    for rep in range(3):
        t0 = time.perf_counter()
        _dua_kernel_loop(reps, 2 + rep * reps, state, geometry)
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
