"""Swept-sphere broadphases as peers: every sphere inflated by its reach over the horizon.

``reach = |v| H + A H^2 / 2 + delta H`` with ``H = (1 + latency) dt``; every pair whose inflated
spheres overlap is an alarm. Candidates come from ``candidates.BROADPHASES``.
"""

from __future__ import annotations

import mujoco
import numpy as np

import dua_mujoco._core as _core
from dua_mujoco.experiments.peers.candidates import BROADPHASES
from dua_mujoco.experiments.peers.ghost_world import GhostTrajectory, pair_id
from dua_mujoco.experiments.peers.horizon import LATENCY, InflatedGhost, reach_distance
from dua_mujoco.experiments.peers.scene_context import SceneContext

__all__ = ["BroadphaseGhost", "BroadphaseScene"]


class BroadphaseGhost(InflatedGhost):
    """Swept-sphere broadphase on the ghost world (``GhostPeer``): candidates, overlap test."""

    def __init__(self, world: GhostTrajectory, kind: str) -> None:
        super().__init__(world)
        self.name = kind
        self.note = {
            "sweep": "sort-and-sweep on the axis of largest spread",
            "grid": "uniform grid, cell = 2 max inflated radius",
        }[kind]
        self.candidates = BROADPHASES[kind]

    def _alarms(self, c: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, int]:
        grown = self._grown(v)
        a, b = self.candidates(c, grown)
        d = c[a] - c[b]
        reach = grown[a] + grown[b]
        hit = np.einsum("ij,ij->i", d, d) <= reach * reach
        return np.unique(pair_id(a[hit], b[hit], self.n)), int(a.size)


class BroadphaseScene:
    """Swept covering spheres on a scene (``ScenePeer``), filtered to MuJoCo's active pairs."""

    def __init__(self, ctx: SceneContext, kind: str) -> None:
        self.ctx = ctx
        self.name = kind
        self.note = "covering spheres inflated by reach over H; half-spaces tested directly"
        self.candidates = BROADPHASES[kind]

    def _alarms(self, data: mujoco.MjData) -> tuple[np.ndarray, int]:
        ctx = self.ctx
        p = ctx.predictor
        c, v = p.sphere_states(data)
        reach = reach_distance(
            np.linalg.norm(v, axis=1), ctx.sphere_accel, ctx.sphere_delta, ctx.horizon
        )
        grown = ctx.radius + reach + 0.5 * ctx.max_extra
        a, b = self.candidates(c, grown)
        key = np.minimum(a, b) * ctx.nsphere + np.maximum(a, b)
        pos = np.minimum(np.searchsorted(ctx.ss_keys, key), max(ctx.ss_keys.size - 1, 0))
        active = ctx.ss_keys[pos] == key if ctx.ss_keys.size else np.zeros(key.size, bool)
        pid = pos[active]
        ia, ib = a[active], b[active]
        d = c[ia] - c[ib]
        limit = ctx.ss_eps[pid] + reach[ia] + reach[ib]
        hit = np.einsum("ij,ij->i", d, d) <= limit * limit
        alarms = [ctx.ss_ids[pid[hit]]]
        if ctx.hs_ids.size:
            # A handful of planes: test every sphere-half-space pair (O(N)).
            pairs = p.pair_set
            normals, offsets = p.halfspaces(data)
            i = pairs.first[ctx.hs_ids]
            j = pairs.second[ctx.hs_ids]
            gap = np.einsum("ij,ij->i", normals[j], c[i]) - offsets[j] - pairs.eps[ctx.hs_ids]
            alarms.append(ctx.hs_ids[gap <= reach[i]])
        if ctx.sh_ids.size:
            # A handful of static shapes too: their exact gap, as for the planes.
            pairs = p.pair_set
            assert pairs.shapes is not None  # shape pairs carry their records
            i = pairs.first[ctx.sh_ids]
            gaps = _core.static_gap(c[i], pairs.shapes, pairs.second[ctx.sh_ids])[:, 0]
            alarms.append(ctx.sh_ids[gaps - pairs.eps[ctx.sh_ids] <= reach[i]])
        ids = np.concatenate(alarms)
        return np.unique(ctx.to_geom_pair[ids]), int(a.size + ctx.hs_ids.size + ctx.sh_ids.size)

    def start(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray | int]:
        return self._alarms(data)[0], 1 + LATENCY

    def step(
        self, data: mujoco.MjData
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]:
        alarms, cand = self._alarms(data)
        return alarms, 1 + LATENCY, None, float(cand)
