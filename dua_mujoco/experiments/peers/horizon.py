"""The prediction horizon every peer shares: the latency and how far a point can travel."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from dua_mujoco.experiments.peers.ghost_world import GhostTrajectory

__all__ = ["LATENCY", "InflatedGhost", "reach_distance"]


LATENCY = 1
"""Verdict latency in periods for every peer (the paper's): a verdict computed at the collision
instant is useless, so prediction means an alarm from an earlier evaluation."""


def reach_distance(
    speed: np.ndarray, accel: np.ndarray | float, delta: np.ndarray | float, horizon: float
) -> np.ndarray:
    """Distance a point can travel within ``horizon``: ``|v| H + A H^2 / 2 + delta H``."""
    return np.asarray(speed * horizon + 0.5 * accel * horizon * horizon + delta * horizon)


class InflatedGhost:
    """Base of the ghost-world peers that test spheres inflated by their reach over the horizon.

    Such a peer judges every pair at every step, all with the same horizon: a subclass gives
    ``_alarms(c, v) -> (alarms, candidates)`` and inherits ``GhostPeer``'s ``start`` and ``step``.

    Args:
        world: The recording the peer watches.
    """

    def __init__(self, world: GhostTrajectory) -> None:
        self.n = world.n
        self.radius = world.radius
        self.accel = np.full(world.n, world.accel)
        self.horizon = (1 + LATENCY) * world.dt

    def _grown(self, v: np.ndarray) -> np.ndarray:
        """``(n,)`` radii grown by the reach at velocities ``v (n, 3)``."""
        return self.radius + reach_distance(
            np.linalg.norm(v, axis=1), self.accel, 0.0, self.horizon
        )

    def _alarms(self, c: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, int]:
        raise NotImplementedError

    def start(self, c: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray | int]:
        return self._alarms(c, v)[0], 1 + LATENCY

    def step(
        self, c: np.ndarray, v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]:
        alarms, cand = self._alarms(c, v)
        return alarms, 1 + LATENCY, None, float(cand)
