"""Pruned pair sets: the rebuild stride, the pair merge, the escape test, standing alarms.

A pruned predictor holds only the pairs of ``neighbors.candidate_pairs`` at a horizon ``T``
and rebuilds them every :func:`rebuild_stride` steps, or earlier when :func:`escapes` finds a
sphere that may have left the reach the last rebuild assumed (the native core's test, the one
the MuJoCo step runs: docs/theory.md, Lemma 6.4). The completeness proof (why a pair left out at
a rebuild needs no verdict until the next one) is in docs/many-objects.md. Everything here is
O(N) or O(pairs), in the native core or vectorised.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

import dua_mujoco._core as _core
from dua_mujoco.core.validate import check_period
from dua_mujoco.exceptions import InvalidInputError

__all__ = ["StandingAlarms", "breaks_bounds", "escapes", "match_pairs", "rebuild_stride"]

# Relative slack of the violation diagnosis: a centre that moved exactly as far as the bounds
# allow (a bang-bang trajectory integrated in float64) is not reported as breaking them.
_BREAK_SLACK = 1e-9


def rebuild_stride(horizon: float, dt: float, latency: int) -> int:
    """Steps ``R`` between rebuilds at horizon ``T``: the largest with ``(R + latency) dt <= T``.

    A pair left out at the rebuild of step ``r`` cannot touch before ``r dt + T``; if it is
    added at the next rebuild, step ``r + R``, it is evaluated there and its verdict acts from
    ``(r + R + latency) dt <= r dt + T`` (docs/many-objects.md). The product is computed as
    the deadline schedule computes it (``(s + latency) * dt``).

    Raises:
        InvalidInputError: ``T < (1 + latency) dt``: not even one step would be covered.
    """
    dt, latency = check_period(dt, latency)
    T = float(horizon)
    if not (math.isfinite(T) and (1 + latency) * dt <= T):
        raise InvalidInputError(
            f"horizon = {horizon!r} is invalid: a pruned pair set must cover at least one step "
            f"and the latency, horizon >= (1 + latency) dt = {(1 + latency) * dt!r} s; pass a "
            "longer horizon (or None for the default)."
        )
    R = max(1, math.floor(T / dt) - latency)
    # The division rounds either way: settle R on the product itself.
    while (R + latency) * dt > T:
        R -= 1
    while (R + 1 + latency) * dt <= T:
        R += 1
    return R


def match_pairs(old: np.ndarray, new: np.ndarray) -> np.ndarray:
    """For each row of ``new``, its row in ``old`` or -1; both ``(K, 2)`` sorted lexicographically.

    Keys ``i (n + 1) + j`` (``n`` the largest id: one integer a pair, in the same order) found by
    binary search: O(K_new log K_old), vectorised.
    """
    old = np.asarray(old, dtype=np.int64).reshape(-1, 2)
    new = np.asarray(new, dtype=np.int64).reshape(-1, 2)
    if old.shape[0] == 0 or new.shape[0] == 0:
        return np.full(new.shape[0], -1, dtype=np.int64)
    base = max(int(old.max()), int(new.max())) + 1
    a = old[:, 0] * base + old[:, 1]
    b = new[:, 0] * base + new[:, 1]
    at = np.minimum(np.searchsorted(a, b), a.shape[0] - 1)
    return np.where(a[at] == b, at, -1).astype(np.int64)


def escapes(
    centers: np.ndarray,
    velocities: np.ndarray,
    anchor: np.ndarray,
    speed0: np.ndarray,
    accel: np.ndarray,
    delta: np.ndarray,
    speed_bound: np.ndarray,
    t: float,
    *,
    ids: np.ndarray | None = None,
    elapsed: np.ndarray | None = None,
) -> np.ndarray:
    """The spheres that may have left the reach their anchors assumed, ``t`` seconds on.

    The native core's test (``csrc/src/reach.cc``, the MuJoCo step's, docs/theory.md Lemma 6.4):
    a sphere passes only if its centre is within ``min((s0 + delta) t + A t^2 / 2, V t)`` of its
    anchor and its measured speed at most ``min(s0 + A t, V - delta)``, each with room to spare
    for rounding; one that passes stays inside its reach until the horizon while its bounds hold
    from now on, whatever it did before.

    Args:
        centers, velocities: ``(N, 3)`` sphere states now.
        anchor: ``(N, 3)`` centres at the anchor; ``speed0`` ``(N,)`` measured speeds then.
        accel, delta, speed_bound: ``(N,)`` bounds ``A``, ``delta``, ``V`` (``inf``: none).
        t: Seconds since the anchor.
        ids, elapsed: Optional ``(N,)`` buffers for ``arange(N)`` and the elapsed times (a
            caller that checks every step keeps them).

    Returns:
        ``(k,)`` int64 ids of the spheres that may have escaped, increasing.
    """
    n = centers.shape[0]
    ids = np.arange(n, dtype=np.int64) if ids is None else ids
    elapsed = np.empty(n) if elapsed is None else elapsed
    elapsed.fill(t)
    return np.asarray(
        _core.escapes(anchor, speed0, accel, delta, speed_bound, ids, centers, velocities, elapsed)
    )


def breaks_bounds(
    ids: np.ndarray,
    centers: np.ndarray,
    velocities: np.ndarray,
    anchor: np.ndarray,
    speed0: np.ndarray,
    accel: np.ndarray,
    delta: np.ndarray,
    speed_bound: np.ndarray,
    t: float,
) -> np.ndarray:
    """Of spheres ``ids`` (that :func:`escapes` found), those whose state proves a violation.

    While the bounds hold from the anchor on, the centre stays within
    ``min((s0 + delta) t + A t^2 / 2, V t)`` of it and the measured speed below
    ``min(s0 + 2 delta + A t, V + delta)`` (the true speed within ``delta`` of both measurements);
    a state beyond either (by more than rounding) broke them. An escape short of that is in
    doubt (a feasible motion or not), and renewed all the same. Vectorised over ``ids``.
    """
    a, d, v_max, s0 = accel[ids], delta[ids], speed_bound[ids], speed0[ids]
    free = (s0 + d) * t + 0.5 * a * t * t
    # With no speed bound V t is inf and never replaces the free-motion allowance.
    allow = np.where(v_max * t < free, v_max * t, free)
    top = np.minimum(s0 + 2.0 * d + a * t, v_max + d)
    dist = np.linalg.norm(centers[ids] - anchor[ids], axis=1)
    speed = np.linalg.norm(velocities[ids], axis=1)
    scale = np.maximum(1.0, np.abs(anchor[ids]).max(axis=1))
    tol = _BREAK_SLACK * (allow + top) + 2e-12 * scale
    return np.asarray(ids[~((dist <= allow + tol) & (speed <= top + tol))])


class StandingAlarms:
    """The pairs whose latest verdict alarms, kept up to date in O(renewed pairs) a step
    (the native core's swap-remove list).

    Args:
        npairs: Number of pairs ``M``.
        alarmed: ``(k,)`` pair ids standing in alarm now.
    """

    def __init__(self, npairs: int, alarmed: npt.ArrayLike) -> None:
        self._set = _core.StandingAlarms(int(npairs), np.asarray(alarmed, dtype=np.int64))

    def renew(self, renewed: npt.ArrayLike, alarms: npt.ArrayLike) -> None:
        """A step renewed the verdicts of ``renewed``; ``alarms`` (among them) alarm."""
        self._set.renew(np.asarray(renewed, dtype=np.int64), np.asarray(alarms, dtype=np.int64))

    def ids(self) -> np.ndarray:
        """``(k,)`` sorted pair ids standing in alarm."""
        return np.asarray(self._set.ids())
