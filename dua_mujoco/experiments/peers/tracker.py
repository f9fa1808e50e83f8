"""Alarm bookkeeping of one peer: standing alarms, predicted and missed onsets, false alarms."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["Tracker", "onsets_by_step", "truth_keys"]


class Tracker:
    """Standing alarms, onsets, lead times and alarm events of one peer (not timed).

    A pair *stands alarmed* when its latest evaluation alarmed. Peers that evaluate every pair
    each step pass ``evaluated=None``: pairs alarmed at the previous step and not now stand down.
    """

    def __init__(self, npairs: int) -> None:
        self.since = np.full(npairs, -1, dtype=np.int64)
        self.prev = np.zeros(0, dtype=np.int64)
        self.event_step: list[np.ndarray] = []
        self.event_pair: list[np.ndarray] = []
        self.event_horizon: list[np.ndarray] = []
        self.onsets = 0
        self.missed = 0
        self.leads: list[np.ndarray] = []
        self.initial = 0

    def check_onsets(self, k: int, onset_pairs: np.ndarray) -> None:
        """Count the onsets at step ``k`` against the alarms standing from steps ``< k``."""
        if onset_pairs.size == 0:
            return
        since = self.since[onset_pairs]
        hit = since >= 0
        self.onsets += int(onset_pairs.size)
        self.missed += int((~hit).sum())
        self.leads.append(k - since[hit])

    def apply(
        self,
        n: int,
        alarmed: np.ndarray,
        horizon_steps: np.ndarray | int,
        evaluated: np.ndarray | None,
        *,
        record: bool = True,
    ) -> None:
        """Apply step ``n``'s alarms (unique ids); ``record`` them as events to be judged.

        The initial classification (step 0) stands like any evaluation but is not recorded:
        DUA's alarms almost every pair there (every pair of a large bucket has tau below the
        bucket's horizon), which says nothing about the steady state.
        """
        alarmed = np.asarray(alarmed, dtype=np.int64)
        if evaluated is None:
            dropped = np.setdiff1d(self.prev, alarmed, assume_unique=True)
            self.prev = alarmed
        else:
            dropped = np.setdiff1d(evaluated, alarmed, assume_unique=True)
        self.since[dropped] = -1
        cur = self.since[alarmed]
        self.since[alarmed] = np.where(cur >= 0, cur, n)
        if not record:
            self.initial = int(alarmed.size)
            return
        self.event_step.append(np.full(alarmed.size, n, dtype=np.int64))
        self.event_pair.append(alarmed)
        self.event_horizon.append(
            np.broadcast_to(np.asarray(horizon_steps, dtype=np.int64), alarmed.shape).copy()
        )

    def judge(self, truth_keys: np.ndarray, last_step: int) -> tuple[int, int, int, int]:
        """``(alarms, false, open, judged)`` against the sorted collision keys ``pair * S + step``.

        ``S = last_step + 1``; an alarm at ``n`` with horizon ``h`` is true if the pair collides at
        a step in ``[n, min(n + h, last_step)]``.
        """
        if not self.event_step:
            return 0, 0, 0, 0
        step = np.concatenate(self.event_step)
        pair = np.concatenate(self.event_pair)
        h = np.concatenate(self.event_horizon)
        stride = last_step + 1
        end = np.minimum(step + h, last_step)
        lo = np.searchsorted(truth_keys, pair * stride + step, side="left")
        hi = np.searchsorted(truth_keys, pair * stride + end, side="right")
        true = hi > lo
        beyond = step + h > last_step
        false = int((~true & ~beyond).sum())
        open_ = int((~true & beyond).sum())
        return int(step.size), false, open_, int((~beyond).sum())

    def lead_mean(self, dt: float) -> float | None:
        """Mean lead time (s) of the predicted onsets at period ``dt``; None if none."""
        if not self.leads:
            return None
        lead = np.concatenate(self.leads)
        return float(lead.mean() * dt) if lead.size else None


def onsets_by_step(keys_per_step: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Pairs colliding at step ``k`` and not at ``k - 1`` (step 0 has no onsets)."""
    out = [np.zeros(0, dtype=np.int64)]
    for k in range(1, len(keys_per_step)):
        out.append(np.setdiff1d(keys_per_step[k], keys_per_step[k - 1], assume_unique=True))
    return out


def truth_keys(keys_per_step: Sequence[np.ndarray]) -> np.ndarray:
    """Sorted keys ``pair * S + step`` (``S`` steps) of every colliding pair at every step."""
    stride = len(keys_per_step)
    parts = [p * stride + k for k, p in enumerate(keys_per_step)]
    return np.sort(np.concatenate(parts)) if parts else np.zeros(0, dtype=np.int64)
