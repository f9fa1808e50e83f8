"""The ghost world of the benchmark: a recorded SphereWorld trajectory and its true collisions.

The box grows as ``(N / 40)^(1/3)`` so that the density of the paper's 40-sphere unit cube is kept
at every N (a fixed cube at N = 2000 would be 23 % spheres by volume).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dua_mujoco.experiments.paper.world import SphereWorld
from dua_mujoco.experiments.peers.candidates import grid_candidates

__all__ = ["PAPER_DENSITY_N", "GhostTrajectory", "ghost_truth", "pair_id", "record_ghost"]


PAPER_DENSITY_N = 40  # the paper's world: 40 spheres in a unit cube


def pair_id(i: np.ndarray, j: np.ndarray, n: int) -> np.ndarray:
    """Index of the unordered pair ``(i, j)`` in ``np.triu_indices(n, 1)`` order."""
    a = np.minimum(i, j).astype(np.int64)
    b = np.maximum(i, j).astype(np.int64)
    return np.asarray(a * n - a * (a + 1) // 2 + (b - a - 1))


@dataclass(frozen=True)
class GhostTrajectory:
    """A recorded ghost-world trajectory and its constants."""

    n: int
    dt: float
    radius: np.ndarray
    accel: float
    positions: np.ndarray  # (steps + 1, n, 3)
    velocities: np.ndarray  # (steps + 1, n, 3)


def record_ghost(n: int, steps: int, extra: int, seed: int) -> GhostTrajectory:
    """Roll the ghost world out for ``steps + extra`` steps (exact states at every step)."""
    box = (n / PAPER_DENSITY_N) ** (1.0 / 3.0)
    world = SphereWorld(n, seed=seed, box=box)
    total = steps + extra + 1
    pos = np.empty((total, n, 3))
    vel = np.empty((total, n, 3))
    for k in range(total):
        pos[k] = world.positions
        vel[k] = world.velocities
        world.step()
    return GhostTrajectory(n, world.dt, world.radius, world.accel_bound, pos, vel)


def ghost_truth(world: GhostTrajectory) -> list[np.ndarray]:
    """Colliding pair ids at every recorded step: ``|c_i - c_j| <= r_i + r_j`` (grid + exact)."""
    out = []
    r = world.radius
    for c in world.positions:
        # The grid is exact here: candidates are then tested with the plain sphere distance.
        a, b = grid_candidates(c, r)
        d = c[a] - c[b]
        s = r[a] + r[b]
        hit = np.einsum("ij,ij->i", d, d) <= s * s
        out.append(np.unique(pair_id(a[hit], b[hit], world.n)))
    return out
