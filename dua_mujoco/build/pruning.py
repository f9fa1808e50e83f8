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
from dua_mujoco.build.filter import contact_distance_bound
from dua_mujoco.build.universe import PairUniverse
from dua_mujoco.core.spheres import RENEW_MAX, pruned_horizon

__all__ = ["RENEW_MAX", "Reach", "reach_for"]


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


def reach_for(
    universe: PairUniverse,
    horizon: float | None,
    *,
    bounds: MotionBounds,
    delta: np.ndarray,
    dt: float,
    ahead: int,
) -> Reach:
    """A pruned predictor's :class:`Reach`. ``delta``: ``(nbody,)`` velocity uncertainties;
    ``ahead``: the periods a verdict must see past the next step, ``latency + alarm_periods - 1``;
    ``horizon`` None: ``(DEFAULT_STRIDE + ahead) dt + (dt - h)``, ``h`` the model's timestep
    (``dt`` is whole steps of it). The stride is :func:`rebuild_stride`'s with ``ahead`` for the
    latency and ``dt - h`` for the grid: a pair left out at a rebuild is then flagged at least
    the alarm horizon before it touches (the proof: docs/many-objects.md, "Between predictor
    steps"; the ``dt - h``, 0 at ``period`` 1: docs/theory.md, section 8).
    """
    covering = universe.covering
    T, stride = pruned_horizon(horizon, dt, ahead, grid=dt - universe.model.opt.timestep)
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
