"""Urgency: conservative lower bounds on the time to collision (docs/theory.md, section 1).

For a pair of spheres with relative centre position ``x``, relative velocity ``v``, contact
distance ``eps`` (radii plus margin), bound ``A`` on the norm of the relative acceleration and
velocity uncertainty ``delta``, the relative position at time ``t`` lies in the ball
``B(x + v t, delta t + A t^2 / 2)``. A collision at ``t`` needs that ball to reach ``B(0, eps)``, so

    tau = min { t >= 0 : |x + v t| <= eps + delta t + A t^2 / 2 }       (+inf if none)

is a lower bound on the time to collision (paper eq. 13, extended by ``delta``).

The kernels never return more than the exact first root: they solve a slightly inflated
problem, locate the one interior minimum where a root could hide, and return the lower end of
a certified bracket (Theorem 1's proof in docs/theory.md). They are implemented once, in the
native core (``dua_mujoco/csrc/src/urgency.cc``, called through ``dua_mujoco._core``); the
functions here validate and call them, four pairs at a time in the same code as one (the same
values, bit for bit, as one row: tests/scalar_tau.py).
"""

from __future__ import annotations

import warnings

import numpy as np
import numpy.typing as npt

import dua_mujoco._core as _core
from dua_mujoco.core.validate import as_vectors, per_pair
from dua_mujoco.exceptions import BoundViolationWarning, InvalidBoundError, ShapeError

__all__ = ["PARALLEL_MIN", "distance_urgency", "time_to_collision", "time_to_halfspace"]

PARALLEL_MIN = 1 << 16
"""Rows from which a batch (``time_to_collision``, ``PairSet.tau``) runs on two threads: below
it, starting a thread costs more than the work (``_core``'s ``tau_speed_batch``, ``tau_pairs``)."""

_INF = np.full(1, np.inf)


def time_to_collision(
    x: npt.ArrayLike,
    v: npt.ArrayLike,
    eps: npt.ArrayLike,
    accel: npt.ArrayLike,
    *,
    speed: npt.ArrayLike | None = None,
    vel_uncertainty: npt.ArrayLike = 0.0,
) -> np.ndarray:
    """Conservative time to collision of sphere pairs (docs/theory.md, section 1).

    Args:
        x: Relative centre positions ``c_j - c_i``, shape ``(M, 3)`` or ``(3,)``.
        v: Relative centre velocities, same shape as ``x``.
        eps: Contact distance (radii plus margin), scalar or ``(M,)``, ``>= 0``.
        accel: Bound ``A`` on the norm of the relative acceleration, scalar or ``(M,)``, ``>= 0``.
        speed: Optional bound ``V`` on the relative speed, scalar or ``(M,)``, ``> 0`` (``inf``
            for none). Rows whose measured ``|v|`` exceeds it break the declared bound: they fall
            back to the acceleration-only value and a ``BoundViolationWarning`` is issued.
        vel_uncertainty: Bound ``delta`` on the error of ``v``, scalar or ``(M,)``, ``>= 0``.

    Returns:
        ``(M,)`` float64 lower bounds on the time to collision: never above the exact first root
        of ``|x + v t| = eps + delta t + A t^2 / 2``, ``0`` where already within ``eps`` and
        ``+inf`` where no collision is possible.

    Raises:
        ShapeError: Shapes do not match.
        NonFiniteStateError: ``x`` or ``v`` holds NaN or inf.
        InvalidBoundError: A bound is negative or NaN.
    """
    xa = as_vectors("x", x)
    m = xa.shape[0]
    va = as_vectors("v", v, m)
    eps_a = per_pair("eps", eps, m)
    acc_a = per_pair("accel", accel, m)
    del_a = per_pair("vel_uncertainty", vel_uncertainty, m)
    if speed is None:
        spd_a = _INF
    else:
        spd_a = per_pair("speed", speed, m, allow_inf=True)
        if (spd_a == 0.0).any():
            i = int(np.flatnonzero(spd_a == 0.0)[0])
            raise InvalidBoundError(
                f"speed[{i}] = 0 is invalid: a speed bound must be positive (use inf for none)."
            )
        broken = np.einsum("ij,ij->i", va, va) > spd_a * spd_a
        if broken.any():
            i = int(np.flatnonzero(broken)[0])
            warnings.warn(
                f"{int(broken.sum())} pair(s) move faster than their speed bound (e.g. pair {i}: "
                f"|v| = {np.linalg.norm(va[i]):.6g} > V = {spd_a[min(i, spd_a.size - 1)]:.6g}); "
                "the bound is broken "
                "there and those pairs fall back to the acceleration-only tau.",
                BoundViolationWarning,
                stacklevel=2,
            )
    return np.asarray(_core.tau_speed_batch(xa, va, eps_a, acc_a, del_a, spd_a))


def time_to_halfspace(
    gap: npt.ArrayLike,
    normal_velocity: npt.ArrayLike,
    accel: npt.ArrayLike,
    *,
    vel_uncertainty: npt.ArrayLike = 0.0,
) -> np.ndarray:
    """Conservative time until spheres reach half-spaces (MuJoCo planes).

    Args:
        gap: ``n . c - r - contact_distance`` (signed clearance), scalar or ``(M,)``.
        normal_velocity: ``n . v``, the clearance rate, scalar or ``(M,)``.
        accel: Bound on the acceleration norm of the sphere centre, scalar or ``(M,)``, ``>= 0``.
        vel_uncertainty: Bound on the error of the velocity, scalar or ``(M,)``, ``>= 0``.

    Returns:
        ``(M,)`` float64: the first ``t >= 0`` with
        ``gap + normal_velocity t - vel_uncertainty t - accel t^2 / 2 <= 0`` (a lower bound), ``0``
        where ``gap <= 0`` and ``+inf`` where never.
    """
    g = np.atleast_1d(np.asarray(gap, dtype=np.float64))
    if g.ndim != 1:
        raise ShapeError(f"gap has shape {g.shape}; expected a scalar or (M,).")
    m = g.shape[0]
    g = per_pair("gap", g, m, state=True)
    vn = per_pair("normal_velocity", normal_velocity, m, state=True)
    acc = per_pair("accel", accel, m)
    dl = per_pair("vel_uncertainty", vel_uncertainty, m)
    return np.asarray(_core.tau_halfspace_batch(g, vn, acc, dl))


def distance_urgency(x: npt.ArrayLike, eps: npt.ArrayLike) -> np.ndarray:
    """Distance urgency ``|x| - eps`` (the paper's SA(d) ranking), shape ``(M,)``.

    Args:
        x: Relative centre positions, ``(M, 3)`` or ``(3,)``.
        eps: Contact distance, scalar or ``(M,)``, ``>= 0``.
    """
    xa = as_vectors("x", x)
    return np.asarray(np.linalg.norm(xa, axis=1) - per_pair("eps", eps, xa.shape[0]))
