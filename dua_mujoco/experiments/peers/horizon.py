"""The prediction horizon every peer shares: the latency and how far a point can travel."""

from __future__ import annotations

import numpy as np

__all__ = ["LATENCY", "reach_distance"]


LATENCY = 1
"""Verdict latency in periods for every peer (the paper's): a verdict computed at the collision
instant is useless, so prediction means an alarm from an earlier evaluation."""


def reach_distance(
    speed: np.ndarray, accel: np.ndarray | float, delta: np.ndarray | float, horizon: float
) -> np.ndarray:
    """Distance a point can travel within ``horizon``: ``|v| H + A H^2 / 2 + delta H``."""
    return np.asarray(speed * horizon + 0.5 * accel * horizon * horizon + delta * horizon)
