"""Pruned sphere pairs for the MuJoCo ``Predictor``: which pairs its runtime holds, and the reach
that chooses them.

The filter (``build/filter.py``) is exact: only sphere pairs of geom pairs MuJoCo could put in
contact are ever held. A pruned predictor holds the half-space and static-shape pairs (a plane
is infinite; shapes never move), the ``<pair>`` elements' pairs among the candidates, and the
sphere pairs whose reachable balls over a horizon ``T`` meet (the candidate grid); its runtime
rebuilds that set every ``rebuild_stride(T, dt, latency)`` steps, and in between renews
the pairs of the spheres an impact may have let out of their reach (the proofs:
docs/many-objects.md and docs/theory.md, Lemmas 6.4 and 6.5). The runtime does all of it
(``csrc/src/pruned.cc``, ``reach.cc``, ``grid.cc``); this module gives it the reach's tables.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dua_mujoco.build.bounds import MotionBounds
from dua_mujoco.build.covering import Covering
from dua_mujoco.build.filter import contact_distance_bound
from dua_mujoco.build.universe import PairUniverse
from dua_mujoco.core.spheres import (
    AUTO_PRUNED_MIN,
    DEFAULT_STRIDE,
    RENEW_MAX,
    PairMode,
    rebuild_stride,
)
from dua_mujoco.exceptions import InvalidChoiceError, InvalidInputError

__all__ = ["RENEW_MAX", "Reach", "reach_for", "resolve_pair_mode"]


@dataclass(frozen=True)
class Reach:
    """What the reach of a pruned predictor's spheres is made of.

    Attributes:
        table: ``(nsphere, 4)`` each sphere's radius, acceleration bound, velocity uncertainty
            and speed bound (``inf``: none).
        horizon: The reach's horizon ``T`` (s).
        margin: The largest contact distance of any geom pair beyond the radii: candidates within
            it of each other are looked at, so no pair that could come within its own contact
            distance is left out.
        stride: Predictor steps between rebuilds.
    """

    table: np.ndarray
    horizon: float
    margin: float
    stride: int


def resolve_pair_mode(
    pairs: PairMode | str, horizon: float | None, *, deadline: bool, covering: Covering
) -> PairMode:
    """``Predictor(pairs=..., horizon=...)``'s mode, ``ALL`` or ``PRUNED``: ``"auto"`` prunes
    from ``AUTO_PRUNED_MIN`` spheres with the deadline schedule."""
    try:
        mode = PairMode(pairs)
    except ValueError:
        raise InvalidChoiceError("pairs", pairs, [m.value for m in PairMode]) from None
    if mode is PairMode.AUTO:
        big = covering.nsphere >= AUTO_PRUNED_MIN
        mode = PairMode.PRUNED if big and deadline else PairMode.ALL
    if mode is PairMode.ALL and horizon is not None:
        raise InvalidInputError(
            f"horizon = {horizon!r} is given but pairs='all': pass pairs='pruned'."
        )
    if mode is PairMode.PRUNED and not deadline:
        raise InvalidInputError(
            "pairs='pruned' needs the deadline schedule: pruned pairs are rebuilt into it "
            "only; pass schedule='deadline'."
        )
    return mode


def reach_for(
    universe: PairUniverse,
    horizon: float | None,
    *,
    bounds: MotionBounds,
    delta: np.ndarray,
    dt: float,
    latency: int,
    alarm_periods: int = 1,
) -> Reach:
    """A pruned predictor's :class:`Reach`. ``delta``: ``(nbody,)`` velocity uncertainties;
    ``horizon`` None: ``(DEFAULT_STRIDE + latency + alarm_periods - 1) dt``.

    A pair left out at the rebuild of step ``r`` is held out strictly (its reaches are farther
    apart than the contact distance), so it has no state in contact before step
    ``r + floor(T / dt) + 1``; the next rebuild holds it (standing in alarm until evaluated
    there), and that alarm acts after the latency. Rebuilds every ``R`` steps with
    ``(R + latency + alarm_periods - 1) dt <= T`` therefore flag it at least the alarm horizon
    before it touches (docs/many-objects.md).
    """
    covering = universe.covering
    ahead = latency + alarm_periods - 1
    T = (DEFAULT_STRIDE + ahead) * dt if horizon is None else horizon
    stride = rebuild_stride(T, dt, ahead)  # checks T
    body = np.asarray(covering.sphere_body, dtype=np.int64)
    speed = np.full(body.shape, np.inf) if bounds.speed is None else bounds.speed[body]
    table = np.stack(
        [
            np.asarray(covering.sphere_radius, dtype=np.float64),
            bounds.accel[body],
            delta[body],
            speed,
        ],
        axis=1,
    )
    margin = contact_distance_bound(universe.model, universe.explicit)
    return Reach(table, float(T), float(margin), stride)
