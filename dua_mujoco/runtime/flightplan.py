"""Flight plans as the native runtime reads them: checked joint positions and deviation bounds.

A plan is the motion the caller expects over the coming physics steps (an MPC's or a planner's
trajectory, or a rollout of known controls: :mod:`dua_mujoco.runtime.plans` makes them) and a bound
on how far every point of each body may stray from where the plan puts it. While it holds, a
pair's verdict follows the plan instead of the motion bounds (docs/theory.md, section 8).
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco.exceptions import InvalidInputError, ShapeError

__all__ = ["finite_rows", "governing_violations", "plan_arrays"]


def finite_rows(name: str, value: npt.ArrayLike, ncol: int, cols: str, rows: str) -> np.ndarray:
    """``value`` as a checked ``(n, ncol)`` float64 array, ``n >= 1``, every entry finite.

    Args:
        name: What the caller called it, for the errors (``qpos``, ``plans[2].qpos``).
        value: The array.
        ncol: Its columns (``model.nq``, ``model.nu``).
        cols: What counts the columns (``nq``), for the errors.
        rows: What a row is (``joint positions per physics step``), for the errors.

    Raises:
        ShapeError: Not ``(n, ncol)`` with ``n >= 1``.
        InvalidInputError: An entry is not finite (the first is named).
    """
    a = np.ascontiguousarray(value, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != ncol or a.shape[0] < 1:
        raise ShapeError(
            f"{name} has shape {a.shape}; expected (n, {cols}) = (n, {ncol}) with n >= 1: one "
            f"row of {rows}."
        )
    bad = np.argwhere(~np.isfinite(a))
    if bad.size:
        j, i = (int(x) for x in bad[0])
        raise InvalidInputError(
            f"{name}[{j}, {i}] = {float(a[j, i])} is not finite: pass finite values."
        )
    return a


def plan_arrays(
    model: mujoco.MjModel, qpos: npt.ArrayLike, deviation: npt.ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """A plan's arrays as the runtime reads them, checked.

    Args:
        model: The model the plan is for.
        qpos: ``(n, nq)`` planned joint positions, row ``j`` the state ``j`` timesteps after the
            plan's start.
        deviation: A bound in metres on the distance of every point of a body's geoms from where
            the plan puts it: one number, ``(n,)`` (each knot, every body) or ``(n, nbody)``.

    Returns:
        ``qpos (n, nq)`` and ``deviation (n, nbody)``, float64 and contiguous.

    Raises:
        ShapeError: The arrays do not fit the model or each other.
        InvalidInputError: A value is not finite, or a deviation is negative.
    """
    q = finite_rows("qpos", qpos, model.nq, "nq", "joint positions per physics step")
    n, nbody = q.shape[0], model.nbody
    dev = np.asarray(deviation, dtype=np.float64)
    if dev.ndim == 0 or (dev.ndim == 1 and dev.shape[0] == n):
        dev = np.broadcast_to(dev.reshape(-1, 1) if dev.ndim else dev, (n, nbody))
    if dev.shape != (n, nbody):
        raise ShapeError(
            f"deviation has shape {np.shape(deviation)}; pass one number, ({n},) (one per "
            f"knot) or ({n}, {nbody}) (one per knot and body)."
        )
    bad_d = np.argwhere(~(np.isfinite(dev) & (dev >= 0)))
    if bad_d.size:
        j, b = (int(v) for v in bad_d[0])
        raise InvalidInputError(
            f"deviation at knot {j} of body {b} ({model.body(b).name!r}) is {dev[j, b]}: pass a "
            "finite distance >= 0 (0 where the plan is exact)."
        )
    return q, np.ascontiguousarray(dev)


def governing_violations(runtime: Any, broke_bounds: np.ndarray) -> np.ndarray:
    """The bodies whose governing hypothesis broke at the state the runtime is bound to: the
    plan's deviation for a body the plan still holds (its pairs' verdicts follow the plan, and a
    motion bound it broke, a foreseen impact, is no violation of them), the motion bounds for
    the rest (``broke_bounds``, the run monitor's check). A body beyond its deviation is one.

    Args:
        runtime: The predictor's ``dua_mujoco._core.Runtime``, bound to the state checked.
        broke_bounds: ``(k,)`` bodies whose motion bounds broke at that state.

    Returns:
        ``(k',)`` int64 body ids, increasing.
    """
    beyond = runtime.plan_broken() if runtime.has_plan else None
    if beyond is None:
        return np.asarray(broke_bounds, dtype=np.int64)
    held = np.asarray(runtime.plan_ok)
    bounds = np.asarray(broke_bounds, dtype=np.int64)
    return np.union1d(bounds[~held[bounds]], np.asarray(beyond, dtype=np.int64))
