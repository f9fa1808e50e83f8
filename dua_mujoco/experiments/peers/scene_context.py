"""What every peer on a MuJoCo scene shares: the scene's predictor, pairs and bounds."""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np

from dua_mujoco.build.options import CoveringOptions
from dua_mujoco.experiments.peers.horizon import LATENCY

if TYPE_CHECKING:
    from dua_mujoco.runtime.predictor import Predictor

__all__ = ["SceneContext"]


class SceneContext:
    """A scene's predictor (covering, active pairs, bounds), shared by all peers.

    Args:
        model: The scene.
        accel: Acceleration bound of the predictor built here.
        predictor: A ready predictor instead (bounding covering, all pairs held; static geoms
            as shapes or spheres): the peers then get its latency's horizon and its pairs.
    """

    def __init__(
        self, model: mujoco.MjModel, accel: float = 0.0, *, predictor: Predictor | None = None
    ) -> None:
        from dua_mujoco import Predictor

        self.model = model
        # By default every geom one sphere, the paper's schedule, all pairs: sphere pairs then
        # correspond one to one with geom pairs, which the peers compare on.
        self.predictor = predictor or Predictor(
            model,
            accel=accel,
            latency=LATENCY,
            schedule="dua",
            pairs="all",
            covering=CoveringOptions(static="sphere"),
        )
        p = self.predictor
        gp = p.sphere_pairs.geom_pair
        # With the bounding covering every geom is one sphere (planes: one half-space), so
        # sphere pairs and active geom pairs correspond one to one.
        if not np.array_equal(np.sort(gp), np.arange(p.geom_pairs.npair)):
            raise ValueError("peers on scenes need one covering sphere per geom (bounding)")
        self.to_geom_pair = np.asarray(gp, dtype=np.int64)
        self.npairs = p.geom_pairs.npair
        self.dt = p.dt
        self.horizon = (1 + p.latency) * p.dt
        cov = p.covering
        pairs = p.pair_set
        self.sphere_accel = p.bounds.accel[cov.sphere_body]
        self.sphere_delta = p.bounds.vel_uncertainty[cov.sphere_body]
        self.radius = np.asarray(cov.sphere_radius, dtype=np.float64)
        self.nsphere = int(cov.nsphere)
        ss = pairs.kind == 0
        a = pairs.first[ss]
        b = pairs.second[ss]
        lo = np.minimum(a, b)
        hi = np.maximum(a, b)
        keys = lo * self.nsphere + hi
        order = np.argsort(keys)
        self.ss_keys = keys[order]
        self.ss_ids = np.flatnonzero(ss)[order]
        # Margins beyond the radii, per sphere pair; the broadphase inflates by half the largest.
        self.ss_eps = pairs.eps[self.ss_ids]
        extra = pairs.eps[ss] - self.radius[a] - self.radius[b]
        self.max_extra = float(extra.max(initial=0.0))
        self.hs_ids = np.flatnonzero(pairs.halfspace)
        # Pairs against static shapes (a predictor with static="shape"): tested directly.
        self.sh_ids = np.flatnonzero(pairs.shape)
