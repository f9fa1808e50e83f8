"""Pruned pair sets: the rebuild stride, the pair merge, the rebuild criterion, standing alarms.

A pruned predictor holds only the pairs of ``neighbors.candidate_pairs`` at a horizon ``T``
and rebuilds them every :func:`rebuild_stride` steps, or earlier when :func:`escaped` finds a
sphere outside what the reach assumed. The completeness proof (why a pair left out at a rebuild
needs no verdict until the next one) is in docs/many-objects.md. Everything here is O(N) or
O(pairs) with compiled loops.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from dua_mujoco.core.validate import check_period
from dua_mujoco.exceptions import InvalidInputError

__all__ = ["StandingAlarms", "escaped", "match_pairs", "rebuild_stride"]

# Relative slack of the rebuild criterion: a centre that moved exactly as far as the bounds
# allow (a bang-bang trajectory integrated in float64) must not count as escaped.
_ESCAPE_SLACK = 1e-9


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


@nb.njit(cache=True)
def match_pairs(old: np.ndarray, new: np.ndarray) -> np.ndarray:  # pragma: no cover - jitted
    """For each row of ``new``, its row in ``old`` or -1; both ``(K, 2)`` sorted lexicographically.

    One merge of the two sorted key lists: O(K_old + K_new), no hashing.
    """
    src = np.full(new.shape[0], -1, dtype=np.int64)
    a = 0
    for b in range(new.shape[0]):
        i, j = new[b, 0], new[b, 1]
        while a < old.shape[0] and (old[a, 0] < i or (old[a, 0] == i and old[a, 1] < j)):
            a += 1
        if a < old.shape[0] and old[a, 0] == i and old[a, 1] == j:
            src[b] = a
    return src


@nb.njit(cache=True)
def escaped(
    centers: np.ndarray,
    velocities: np.ndarray,
    anchor: np.ndarray,
    speed0: np.ndarray,
    accel: np.ndarray,
    delta: np.ndarray,
    speed_bound: np.ndarray,
    t: float,
) -> int:  # pragma: no cover - jitted
    """First sphere whose state contradicts what the last rebuild's reach assumed, or -1.

    The reach assumed ``|x_i(t) - c_i| <= min((|v_i| + delta_i) t + A_i t^2 / 2, V_i t)`` for
    the centre and, for the measured velocity, ``|v_i(t)| <= |v_i| + 2 delta_i + A_i t``
    (true speed at most ``|v_i| + delta_i + A_i t``, measured within ``delta_i`` of it) and
    ``<= V_i + delta_i``. Per-sphere arrays may have length 1 (one value for all).
    """
    n = centers.shape[0]
    for i in range(n):
        a = accel[i if accel.shape[0] > 1 else 0]
        d = delta[i if delta.shape[0] > 1 else 0]
        V = speed_bound[i if speed_bound.shape[0] > 1 else 0]
        s0 = speed0[i]
        allow = (s0 + d) * t + 0.5 * a * t * t
        vmax = s0 + 2.0 * d + a * t
        # With no speed bound V t is inf (or NaN at t = 0) and never replaces the allowance.
        if V * t < allow:
            allow = V * t
        vmax = min(vmax, V + d)
        d2 = 0.0
        v2 = 0.0
        scale = 1.0
        for k in range(3):
            dx = centers[i, k] - anchor[i, k]
            d2 += dx * dx
            v2 += velocities[i, k] * velocities[i, k]
            scale = max(scale, abs(anchor[i, k]))
        # Rounding of positions scales with their magnitude: tolerate ~1e4 ulp of it.
        tol = _ESCAPE_SLACK * (allow + vmax) + 2e-12 * scale
        if math.sqrt(d2) > allow + tol or math.sqrt(v2) > vmax + tol:
            return i
    return -1


@nb.njit(cache=True)
def _renew(pos, lst, cnt, renewed, alarms):  # pragma: no cover - jitted
    # Swap-remove every renewed pair, then append the alarmed ones: O(renewed).
    c = cnt[0]
    for k in range(renewed.shape[0]):
        p = renewed[k]
        at = pos[p]
        if at >= 0:
            last = lst[c - 1]
            lst[at] = last
            pos[last] = at
            pos[p] = -1
            c -= 1
    for k in range(alarms.shape[0]):
        p = alarms[k]
        if pos[p] < 0:
            pos[p] = c
            lst[c] = p
            c += 1
    cnt[0] = c


class StandingAlarms:
    """The pairs whose latest verdict alarms, kept up to date in O(renewed pairs) a step.

    Args:
        npairs: Number of pairs ``M``.
        alarmed: ``(k,)`` pair ids standing in alarm now.
    """

    def __init__(self, npairs: int, alarmed: np.ndarray) -> None:
        self.pos = np.full(npairs, -1, dtype=np.int64)
        self.lst = np.empty(max(npairs, 1), dtype=np.int64)
        self.cnt = np.zeros(1, dtype=np.int64)
        _renew(self.pos, self.lst, self.cnt, self.lst[:0], np.asarray(alarmed, dtype=np.int64))

    def renew(self, renewed: np.ndarray, alarms: np.ndarray) -> None:
        """A step renewed the verdicts of ``renewed``; ``alarms`` (among them) alarm."""
        _renew(self.pos, self.lst, self.cnt, renewed, alarms)

    def ids(self) -> np.ndarray:
        """``(k,)`` sorted pair ids standing in alarm."""
        return np.sort(self.lst[: int(self.cnt[0])])
