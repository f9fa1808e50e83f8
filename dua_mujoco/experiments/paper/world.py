"""The paper's world (sec. 8.1): ghost spheres in a cube under random bounded accelerations.

Both algorithms watch the *same* trajectory (same seed, same physics step): the world advances in
whole physics steps and is sampled exactly inside a step (piecewise-constant accelerations, closed
form), so a predictor period need not be a multiple of the physics step.

``SphereWorld`` is kinematic: spheres pass through each other (nothing reacts to a collision), so
the declared bounds hold exactly for the whole run: every sphere's acceleration is piecewise
constant with norm at most ``accel``, and positions are integrated in closed form
(``x + v s + a s^2 / 2``), not by a numerical scheme. That makes the world an exact test bed for
the completeness theorem (the tests' ghost worlds).
"""

from __future__ import annotations

import enum
from dataclasses import asdict, dataclass

import numpy as np
import numpy.typing as npt

from dua_mujoco.core.pairset import PairSet
from dua_mujoco.exceptions import InvalidChoiceError, InvalidInputError

__all__ = ["AccelProfile", "Sampler", "SphereWorld", "WorldParams"]


class AccelProfile(enum.Enum):
    """How accelerations are drawn at each switch."""

    UNIFORM = "uniform"
    """Random direction, magnitude uniform in ``[0, accel]``."""
    BANG_BANG = "bang_bang"
    """Random direction, magnitude exactly ``accel`` (the extreme trajectories of the bound)."""


class SphereWorld:
    """``n`` ghost spheres in the cube ``[-box/2, box/2]^3`` with bounded accelerations.

    Args:
        n: Number of spheres (``>= 2``).
        seed: Random seed (positions, velocities and the acceleration sequence).
        box: Edge length of the cube.
        radius: Sphere radius, scalar or ``(n,)``.
        accel: Bound on every sphere's acceleration norm (``> 0``).
        speed: Initial speeds are drawn uniformly in ``[0, speed]``.
        dt: Step length; accelerations change only at step boundaries.
        switch_steps: Mean number of steps between acceleration switches of a sphere.
        profile: Acceleration profile (``AccelProfile`` or its value).

    The spheres are steered back towards the centre (with an acceleration of norm ``accel``)
    when they leave the inner 80 % of the cube while moving outwards, so they stay in the box
    without any wall impulse.
    """

    def __init__(
        self,
        n: int,
        *,
        seed: int = 0,
        box: float = 1.0,
        radius: npt.ArrayLike = 0.03,
        accel: float = 1.0,
        speed: float = 0.3,
        dt: float = 0.01,
        switch_steps: float = 5.0,
        profile: AccelProfile | str = AccelProfile.UNIFORM,
    ) -> None:
        if int(n) < 2:
            raise InvalidInputError(f"n = {n} is invalid: a sphere world needs at least 2 spheres.")
        for name, value in (
            ("box", box),
            ("accel", accel),
            ("dt", dt),
            ("switch_steps", switch_steps),
        ):
            if not (np.isfinite(value) and value > 0):
                raise InvalidInputError(f"{name} = {value!r} is invalid: it must be > 0.")
        try:
            self.profile = AccelProfile(profile)
        except ValueError:
            raise InvalidChoiceError("profile", profile, [p.value for p in AccelProfile]) from None
        self.n = int(n)
        self.box = float(box)
        self.radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), (self.n,)).copy()
        if (self.radius < 0).any() or not np.isfinite(self.radius).all():
            raise InvalidInputError("radius must be finite and >= 0.")
        self.accel_bound = float(accel)
        self.dt = float(dt)
        self.switch_probability = min(1.0, 1.0 / float(switch_steps))
        self.rng = np.random.default_rng(seed)
        half = 0.5 * self.box
        self.positions = self.rng.uniform(-0.8 * half, 0.8 * half, (self.n, 3))
        self.velocities = _random_directions(self.rng, self.n) * self.rng.uniform(
            0.0, speed, (self.n, 1)
        )
        self.accelerations = self._draw(self.n)
        self.time = 0.0
        self.step_count = 0

    def _draw(self, k: int) -> np.ndarray:
        mag = (
            np.full((k, 1), self.accel_bound)
            if self.profile is AccelProfile.BANG_BANG
            else self.rng.uniform(0.0, self.accel_bound, (k, 1))
        )
        return _random_directions(self.rng, k) * mag

    def pairs(self, *, margin: float = 0.0, vel_uncertainty: float = 0.0) -> PairSet:
        """All ``n (n - 1) / 2`` sphere pairs with this world's radii and acceleration bound."""
        return PairSet.all_pairs(
            self.radius, self.accel_bound, margin=margin, vel_uncertainty=vel_uncertainty
        )

    def positions_at(self, s: float) -> np.ndarray:
        """``(n, 3)`` positions at time ``time + s`` for ``0 <= s <= dt`` (exact, this step)."""
        return np.asarray(self.positions + self.velocities * s + 0.5 * self.accelerations * s * s)

    def step(self) -> None:
        """Advance exactly one ``dt`` and pick the accelerations of the next step."""
        s = self.dt
        self.positions = self.positions_at(s)
        self.velocities = self.velocities + self.accelerations * s
        self.time += s
        self.step_count += 1
        switch = self.rng.random(self.n) < self.switch_probability
        if switch.any():
            self.accelerations[switch] = self._draw(int(switch.sum()))
        # Steer back inside: outside the inner region and moving outwards -> full inward push.
        out = np.abs(self.positions) > 0.4 * self.box
        leaving = (out & (self.positions * self.velocities > 0)).any(axis=1)
        if leaving.any():
            inward = -self.positions[leaving]
            inward /= np.linalg.norm(inward, axis=1, keepdims=True)
            self.accelerations[leaving] = inward * self.accel_bound


def _random_directions(rng: np.random.Generator, k: int) -> np.ndarray:
    d = rng.normal(size=(k, 3))
    return np.asarray(d / np.linalg.norm(d, axis=1, keepdims=True))


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
