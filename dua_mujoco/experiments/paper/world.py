"""The paper's world (sec. 8.1): ghost spheres in a cube under random bounded accelerations.

Both algorithms watch the *same* trajectory (same seed, same physics step): the world advances in
whole physics steps and is sampled exactly inside a step (piecewise-constant accelerations, closed
form), so a predictor period need not be a multiple of the physics step.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from dua_mujoco.core.worlds import SphereWorld

__all__ = ["Sampler", "WorldParams"]


@dataclass(frozen=True)
class WorldParams:
    """The sphere world (paper sec. 8.1: spheres in a cube, random bounded accelerations).

    The paper gives no dimensions. Ours: a 10 m cell, 20 cm spheres, speeds of the order of
    0.4 m/s and an acceleration bound of 0.2 m/s^2 per sphere (0.4 m/s^2 per pair), re-drawn
    every ~5 s (physics step 2 s). On the paper's clock (0.2 to 0.7 s per DUA iteration) that is
    "a worst-case scenario as far as coherence is concerned": one SA period at N = 40 (~43 s)
    lets any pair cross the cell. The acceleration bound was picked among 0.05, 0.1 and 0.2 m/s^2
    as the one whose DUA false-alarm counts (N = 10..40, 25 iterations) came closest to the
    paper's Table 2; nothing else was tuned.

    Attributes:
        box: Cube edge (m).
        radius: Sphere radius (m).
        accel: Bound on each sphere's acceleration norm (m/s^2); pairs get twice this.
        speed: Initial speeds are uniform in ``[0, speed]`` (m/s).
        physics_dt: Physics step (s): accelerations change only at its boundaries.
        switch_steps: Mean physics steps between acceleration switches of a sphere.
    """

    box: float = 10.0
    radius: float = 0.1
    accel: float = 0.2
    speed: float = 0.4
    physics_dt: float = 2.0
    switch_steps: float = 2.5

    def world(self, n: int, seed: int) -> SphereWorld:
        """A fresh world of ``n`` spheres."""
        kw = asdict(self)  # SphereWorld's keywords, its dt called physics_dt here
        return SphereWorld(n, seed=seed, dt=kw.pop("physics_dt"), **kw)


class Sampler:
    """Exact states of a world at non-decreasing times, independent of its physics step.

    Args:
        world: The world to sample; it is stepped forward as the times require.
    """

    def __init__(self, world: SphereWorld) -> None:
        self.world = world

    def state(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``(centers (n, 3), velocities (n, 3))`` at time ``t`` (not before the last call's)."""
        w = self.world
        # Small tolerance: world.time accumulates physics_dt and drifts by rounding.
        while w.time + w.dt <= t + 1e-12 * max(1.0, t):
            w.step()
        s = max(0.0, t - w.time)
        return w.positions_at(s), np.asarray(w.velocities + w.accelerations * s)
