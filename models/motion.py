"""Rest-to-rest moves under a speed and an acceleration cap: the bundled scenes' scripts.

A :class:`Move` goes along the straight line from ``start`` to ``end`` with the time-optimal
trapezoidal speed profile of its caps (a triangle when the line is too short to reach the
speed cap): ``|velocity| <= vmax`` and ``|acceleration| <= amax`` at every instant, so also for
the positions sampled at MuJoCo's steps (a chord's speed is a mean of speeds, a second
difference over ``h^2`` a mean of accelerations). A :class:`Timeline` chains moves and holds.
The person, the obstacles and the arms' task trajectories are all made of these.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

__all__ = ["Move", "Timeline", "trapezoid"]


def trapezoid(length: float, vmax: float, amax: float) -> tuple[float, float, float]:
    """The time-optimal rest-to-rest profile of a move of ``length`` under the caps.

    Returns:
        ``(t_acc, t_cruise, peak)``: the time spent accelerating (the same decelerating), the
        time at the peak speed, and the peak speed (``<= vmax``).
    """
    if not (vmax > 0 and amax > 0):
        raise ValueError(f"caps must be positive: vmax={vmax}, amax={amax}")
    length = abs(float(length))
    if length * amax >= vmax * vmax:
        t_acc = vmax / amax
        return t_acc, length / vmax - t_acc, vmax
    peak = math.sqrt(length * amax)
    return peak / amax, 0.0, peak


@dataclass(frozen=True)
class Move:
    """A straight rest-to-rest move from ``start`` to ``end``, beginning at ``t0``.

    Attributes:
        start: ``(n,)`` where the move starts (any dimension: a point, a joint vector).
        end: ``(n,)`` where it ends.
        t0: when it starts (s).
        vmax: cap on the speed along the line (m/s or rad/s).
        amax: cap on the acceleration along the line.
        length: the line's length.
        duration: how long the move takes (s).
    """

    start: np.ndarray
    end: np.ndarray
    t0: float
    vmax: float
    amax: float
    length: float = field(init=False)
    duration: float = field(init=False)
    _profile: tuple[float, float, float] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        length = float(np.linalg.norm(self.end - self.start))
        profile = trapezoid(length, self.vmax, self.amax) if length else (0.0, 0.0, 0.0)
        object.__setattr__(self, "length", length)
        object.__setattr__(self, "_profile", profile)
        object.__setattr__(self, "duration", 2 * profile[0] + profile[1])

    @staticmethod
    def make(start: npt.ArrayLike, end: npt.ArrayLike, t0: float, vmax: float, amax: float) -> Move:
        """A move between two points (arrays are copied as float64)."""
        return Move(
            np.array(start, dtype=np.float64), np.array(end, dtype=np.float64), t0, vmax, amax
        )

    @property
    def t1(self) -> float:
        """When the move ends."""
        return self.t0 + self.duration

    def state(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity at time ``t`` (at ``start`` before, at ``end`` after)."""
        length = self.length
        if length == 0.0 or t <= self.t0:
            return self.start.copy(), np.zeros_like(self.start)
        t_acc, t_cruise, peak = self._profile
        a = peak / t_acc
        s = t - self.t0
        if s <= t_acc:
            along, speed = 0.5 * a * s * s, a * s
        elif s <= t_acc + t_cruise:
            along, speed = 0.5 * peak * t_acc + peak * (s - t_acc), peak
        elif s < 2 * t_acc + t_cruise:
            r = 2 * t_acc + t_cruise - s
            along, speed = length - 0.5 * a * r * r, a * r
        else:
            return self.end.copy(), np.zeros_like(self.start)
        u = (self.end - self.start) / length
        return self.start + along * u, speed * u


class Timeline:
    """Moves one after the other, holding still between them and after the last.

    Args:
        start: ``(n,)`` where the timeline starts (held until the first move).
    """

    def __init__(self, start: npt.ArrayLike) -> None:
        self.moves: list[Move] = []
        self._start = np.array(start, dtype=np.float64)

    @property
    def end(self) -> np.ndarray:
        """Where the last move ends (the start when there is none)."""
        return self.moves[-1].end if self.moves else self._start

    @property
    def t_end(self) -> float:
        """When the last move ends (0 when there is none)."""
        return self.moves[-1].t1 if self.moves else 0.0

    def go(self, end: npt.ArrayLike, *, at: float, vmax: float, amax: float) -> float:
        """Add a move from the current end to ``end`` starting at ``at`` (no earlier than the
        last move's end).

        Returns:
            When the new move ends.
        """
        if at < self.t_end - 1e-12:
            raise ValueError(f"a move at t={at} would overlap the last one (ends {self.t_end})")
        self.moves.append(Move.make(self.end, end, at, vmax, amax))
        return self.moves[-1].t1

    def state(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity at time ``t``."""
        for move in self.moves:
            if t < move.t1:
                return move.state(t)
        return self.end.copy(), np.zeros_like(self._start)
