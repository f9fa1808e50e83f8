"""The candidate grid's contract as a slow reference, and thin calls of the runtime's grid and
reach kernels (csrc/src/grid.cc, reach.cc) for the tests that hold them to it."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from dua_mujoco import _core

# The grid's contract (grid.cc): d2 <= s * s * ROUNDING_SLACK, s = (reach_i + reach_j) + margin.
ROUNDING_SLACK = 1.0 + 2.0**-44


def candidate_pairs(c: npt.ArrayLike, r: npt.ArrayLike, margin: float = 0.0) -> np.ndarray:
    """The runtime's grid (``_core.candidate_pairs``): ``(K, 2)`` pairs, sorted."""
    c, r = np.ascontiguousarray(c, dtype=float), np.ascontiguousarray(r, dtype=float)
    return np.asarray(_core.candidate_pairs(c, r, float(margin)))


def reach(
    radius: npt.ArrayLike,
    speed: npt.ArrayLike,
    accel: npt.ArrayLike,
    horizon: float,
    *,
    vel_uncertainty: npt.ArrayLike = 0.0,
    speed_bound: npt.ArrayLike = np.inf,
) -> np.ndarray:
    """The runtime's reaches (``_core.reaches``), its arguments broadcast to one shape."""
    args = np.broadcast_arrays(*map(np.atleast_1d, (radius, speed, accel, vel_uncertainty,
                                                    speed_bound)))  # fmt: skip
    r, s, a, d, v = (np.ascontiguousarray(x, dtype=float) for x in args)
    return np.asarray(_core.reaches(r, s, a, d, v, float(horizon)))


def brute_pairs(c: np.ndarray, r: np.ndarray, margin: float) -> np.ndarray:
    """All pairs tested, in the documented float64 expression; sorted since triu_indices is."""
    i, j = np.triu_indices(c.shape[0], 1)
    d = c[i] - c[j]
    s = r[i] + r[j] + margin
    keep = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2] <= s * s * ROUNDING_SLACK
    return np.stack([i[keep], j[keep]], axis=1).astype(np.int64)
