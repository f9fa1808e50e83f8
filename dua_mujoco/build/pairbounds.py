"""The scheduler's pairs with their bounds: the model's sphere pairs, each with the sum of its two
bodies' acceleration bounds, velocity uncertainties and speed bounds."""

from __future__ import annotations

import mujoco
import numpy as np

from dua_mujoco import _core
from dua_mujoco.build.bounds import MotionBounds
from dua_mujoco.build.covering import Covering
from dua_mujoco.build.filter import SpherePairs
from dua_mujoco.build.mocap import PredictorMocap
from dua_mujoco.core.pairset import PairSet

__all__ = ["body_vel_uncertainty", "bounded_pairs"]


def body_vel_uncertainty(
    model: mujoco.MjModel,
    bounds: MotionBounds,
    *,
    period: int = 1,
    mocap: PredictorMocap | None = None,
) -> np.ndarray:
    """``(nbody,)`` velocity uncertainty of each body for a predictor of ``period``.

    Mocap velocities are backward differences over one predictor period: their error is
    ``A period h / 2``, of which the discrete-time term already holds ``A h / 2``
    (docs/discrete-time.md); mocap trees get the rest.
    """
    delta = np.asarray(bounds.vel_uncertainty, dtype=np.float64)
    if mocap is None or period <= 1:
        return delta
    in_mocap = np.zeros(model.nbody, dtype=bool)
    in_mocap[mocap.mocap_bodies] = True
    tree = in_mocap[np.asarray(model.body_rootid)]
    extra = np.where(tree, 0.5 * (period - 1) * model.opt.timestep, 0.0)
    return np.asarray(delta + extra * bounds.accel)


def bounded_pairs(
    model: mujoco.MjModel,
    covering: Covering,
    sphere_pairs: SpherePairs,
    bounds: MotionBounds,
    *,
    period: int = 1,
    mocap: PredictorMocap | None = None,
) -> PairSet:
    """The ``PairSet`` of ``sphere_pairs`` under ``bounds`` for a predictor of ``period``.

    Mocap trees get the extra velocity uncertainty of differencing over a period
    (docs/discrete-time.md).
    """
    sp, b = sphere_pairs, bounds
    per_body = body_vel_uncertainty(model, bounds, period=period, mocap=mocap)
    # The native core's sums (the plugin's pruned pairs bound the pairs they meet with them).
    accel, delta, speed = _core.pair_bounds(
        np.asarray(sp.first, dtype=np.int64), np.asarray(sp.second, dtype=np.int64), sp.kind,
        np.asarray(covering.sphere_body, dtype=np.int64), b.accel, per_body, b.speed,
    )  # fmt: skip
    return PairSet(
        sp.first, sp.second, sp.eps, accel, kind=sp.kind, vel_uncertainty=delta, speed=speed
    )
