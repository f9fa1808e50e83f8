"""The native tau kernels one pair at a time: what the tests hold batches and references to.

Each is one row of the batch kernel (``_core.tau_speed_batch``, ``_core.tau_halfspace_batch``),
the same code the batches run four pairs at a time (bit for bit, ``test_urgency.py``).
"""

from __future__ import annotations

import numpy as np

import dua_mujoco._core as _core


def tau_speed(
    x0: float,
    x1: float,
    x2: float,
    v0: float,
    v1: float,
    v2: float,
    eps: float,
    accel: float,
    delta: float,
    speed: float = np.inf,
) -> float:
    """min {t >= 0 : |x + v t| <= eps + delta t + accel t^2 / 2} (a lower bound), with a
    relative speed bound ``speed`` (``inf``: none): no collision before ``(|x| - eps) / V``
    either, unless the measured ``|v| > V`` breaks the bound (the speed term is then dropped)."""
    row = np.array([[x0, x1, x2, v0, v1, v2]])
    bounds = np.array([[eps], [accel], [delta], [speed]], dtype=np.float64)
    return float(_core.tau_speed_batch(row[:, :3], row[:, 3:], *bounds)[0])


def tau_halfspace(gap: float, normal_velocity: float, accel: float, delta: float) -> float:
    """min {t >= 0 : gap + (n.v) t - delta t - accel t^2 / 2 <= 0} (a lower bound)."""
    args = (np.array([v], dtype=np.float64) for v in (gap, normal_velocity, accel, delta))
    return float(_core.tau_halfspace_batch(*args)[0])
