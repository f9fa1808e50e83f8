"""DUA and SA(tau) as peers, in the ghost world and on MuJoCo scenes."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from dua_mujoco.core.pairset import PairSet
from dua_mujoco.core.schedules import DUAScheduler, SelectAllScheduler
from dua_mujoco.core.urgency import PARALLEL_MIN
from dua_mujoco.experiments.peers.ghost_world import GhostTrajectory
from dua_mujoco.experiments.peers.horizon import LATENCY
from dua_mujoco.experiments.peers.scene_context import SceneContext

__all__ = ["DuaGhost", "DuaScene", "SaGhost", "SaScene", "serial_tau"]


def serial_tau(pairs: PairSet, ids: np.ndarray, *state: Any) -> np.ndarray:
    """``pairs.tau(ids, *state)`` on one thread: in batches below the size from which the
    native core splits a batch over two (every peer runs on one thread)."""
    if ids.size < PARALLEL_MIN:
        return pairs.tau(ids, *state)
    batches = np.array_split(ids, -(-ids.size // (PARALLEL_MIN - 1)))
    return np.concatenate([pairs.tau(b, *state) for b in batches])


class _ScheduledGhost:
    """A scheduler over all sphere pairs of the ghost world, made at the first state."""

    scheduler: type[DUAScheduler] | type[SelectAllScheduler]
    sched: DUAScheduler | SelectAllScheduler | None = None

    def __init__(self, world: GhostTrajectory) -> None:
        self.pairs = PairSet.all_pairs(world.radius, world.accel)
        self.dt = world.dt

    def start(self, c: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray | int]:
        tau = serial_tau(self.pairs, np.arange(len(self.pairs)), c, v)
        self.sched = self.scheduler(tau, dt=self.dt, latency=LATENCY)
        ids = self.sched.initial_alarms
        return ids, self._horizon(ids)

    def _horizon(self, ids: np.ndarray) -> np.ndarray | int:
        """The alarms' horizons in steps (the revisit interval plus the latency)."""
        return 1 + LATENCY


class DuaGhost(_ScheduledGhost):
    """DUA on the ghost world (``GhostPeer``): the fused ``step_points``."""

    name = "DUA"
    note = "fused step_points (select, tau, sort, reinsert in one native call)"
    scheduler = DUAScheduler
    sched: DUAScheduler | None = None

    def _horizon(self, ids: np.ndarray) -> np.ndarray:
        assert self.sched is not None
        return np.rint(self.sched.horizon_of(ids) / self.dt).astype(np.int64)

    def step(
        self, c: np.ndarray, v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]:
        assert self.sched is not None
        alarms = self.sched.step_points(self.pairs, c, v)
        return alarms, self._horizon(alarms), self.sched.last_selected, None


class SaGhost(_ScheduledGhost):
    """SA(tau) on the ghost world (``GhostPeer``): tau of every pair every step (the revisit
    interval one step)."""

    name = "SA(tau)"
    note = "tau of every pair every step (native batches)"
    scheduler = SelectAllScheduler
    sched: SelectAllScheduler | None = None

    def step(
        self, c: np.ndarray, v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]:
        assert self.sched is not None
        ids = self.sched.select()
        alarms = self.sched.update(ids, serial_tau(self.pairs, ids, c, v))
        return alarms, 1 + LATENCY, None, float(ids.size)


class DuaScene:
    """DUA on a scene (``ScenePeer``): the scene's ``Predictor``."""

    name = "DUA"
    note = "Predictor.step (fused rigid step, reads only the scheduled spheres)"

    def __init__(self, ctx: SceneContext) -> None:
        self.ctx = ctx

    def _out(self, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        sched = self.ctx.predictor.scheduler
        assert sched is not None
        # Horizons in steps: the revisit interval plus the latency.
        return self.ctx.to_geom_pair[ids], np.rint(sched.horizon_of(ids) / sched.dt).astype(int)

    def start(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray | int]:
        alarms = self.ctx.predictor.reset(data)
        return self._out(alarms.pairs)

    def step(
        self, data: mujoco.MjData
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]:
        alarms = self.ctx.predictor.step(data)
        sched = self.ctx.predictor.scheduler
        assert sched is not None
        evaluated = self.ctx.to_geom_pair[sched.last_selected]
        ids, h = self._out(alarms.pairs)
        return ids, h, np.unique(evaluated), float(evaluated.size)


class SaScene:
    """SA(tau) on a scene (``ScenePeer``): tau of every active sphere pair every step."""

    name = "SA(tau)"
    note = "tau of every active sphere pair every step"

    def __init__(self, ctx: SceneContext) -> None:
        self.ctx = ctx
        self.sched: SelectAllScheduler | None = None

    def _tau(self, data: mujoco.MjData, ids: np.ndarray) -> np.ndarray:
        p = self.ctx.predictor
        c, v = p.sphere_states(data)
        return serial_tau(p.pair_set, ids, c, v, p.halfspaces(data))

    def start(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray | int]:
        tau0 = self._tau(data, np.arange(len(self.ctx.predictor.pair_set)))
        self.sched = SelectAllScheduler(tau0, dt=self.ctx.dt, latency=LATENCY)
        return self.ctx.to_geom_pair[self.sched.initial_alarms], 1 + LATENCY

    def step(
        self, data: mujoco.MjData
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]:
        assert self.sched is not None
        ids = self.sched.select()
        alarms = self.sched.update(ids, self._tau(data, ids))
        return np.unique(self.ctx.to_geom_pair[alarms]), 1 + LATENCY, None, float(ids.size)
