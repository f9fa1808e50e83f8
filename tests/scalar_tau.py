"""The native kernels one pair or point at a time: what the tests hold batches and references to.

Each is one row of a batch kernel (``_core.tau_speed_batch``, ``_core.tau_halfspace_batch``,
``_core.static_gap``, ``_core.support``, ``_core.tau_static_batch``), the same code the batches
run (bit for bit, ``test_urgency.py``, ``test_shapes.py``).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

import dua_mujoco._core as _core
from dua_mujoco.core.shapes import one_point


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


def static_gap(
    c: npt.ArrayLike, rec: npt.ArrayLike, row: int = 0
) -> tuple[float, float, float, float]:
    """Clearance of a point from a static shape along the chosen direction.

    Args:
        c: Point (sphere centre), shape ``(3,)``.
        rec: One shape record, shape ``(16,)``, or a table ``(k, 16)``.
        row: The record's row in ``rec`` when it is a table.

    Returns:
        ``(gap, nx, ny, nz)``: ``n`` is the unit direction from the closest point of the shape to
        ``c`` and ``gap = n.c - h_S(n)`` (without ``eps``). ``gap <= dist(c, S)`` for every ``c``
        and ``gap <= 0`` inside. Outside, ``gap = dist(c, S)`` up to rounding (for ``MESH_BOX``
        the distance to the box, for the ellipsoid up to the accuracy of the iterated root).
    """
    out = _core.static_gap(*one_point(c, rec, row))[0]
    return float(out[0]), float(out[1]), float(out[2]), float(out[3])


def support(n: npt.ArrayLike, rec: npt.ArrayLike, row: int = 0) -> float:
    """Support function ``h_S(n) = n.p + h_local(R^T n)`` of one shape.

    Args:
        n: Direction, shape ``(3,)``, any length (the support function is positively
            homogeneous).
        rec: One shape record, shape ``(16,)``, or a table ``(k, 16)``.
        row: The record's row in ``rec`` when it is a table.

    Returns:
        ``max_{q in S} n.q`` (for ``MESH_BOX``, that of the box around the hull: an upper bound).
    """
    return float(_core.support(*one_point(n, rec, row))[0])


def tau_static(
    c0: float,
    c1: float,
    c2: float,
    v0: float,
    v1: float,
    v2: float,
    rec: npt.ArrayLike,
    eps: float,
    accel: float,
    delta: float,
    row: int = 0,
) -> float:
    """Lower bound on the time before a sphere can touch a static shape.

    ``rec`` is one record ``(16,)``, or a table ``(k, 16)`` and ``row`` the record's row.

    The half-space tau of ``H(n)`` (``dua_mujoco.core.shapes``) with the gap lowered by a
    rounding slack and the velocity uncertainty raised by one, so that rounding cannot make it
    late. Returns 0 when the centre is inside the shape or within ``eps`` of it.
    """
    p, r, ids = one_point((c0, c1, c2), rec, row)
    v = np.array([[v0, v1, v2]], dtype=np.float64)
    bounds = (np.array([x], dtype=np.float64) for x in (eps, accel, delta))
    return float(_core.tau_static_batch(p, v, r, ids, *bounds)[0])
