"""MuJoCo's own collision detection as a peer: gap-inflated, speculative, or plain.

Gap: ``geom_gap`` set per geom to its reach over the horizon. MuJoCo >= 3.9 reports contacts at
``dist < margin + gap`` and generates force only below ``margin``, so the inflated contacts are
inactive and the dynamics untouched. Speculative: ``mjENBL_SPECULATIVE`` (MuJoCo 4.0) sweeps fast
geoms along ``qvel * dt`` only. Plain: the contacts the simulation computes anyway.
"""

from __future__ import annotations

import copy
import time

import mujoco
import numpy as np

from dua_mujoco.experiments.peers.ghost_world import GhostTrajectory, pair_id
from dua_mujoco.experiments.peers.horizon import LATENCY, reach_distance
from dua_mujoco.experiments.peers.scene_context import SceneContext

__all__ = ["MujocoGhost", "MujocoScene"]


def _ghost_spec(n: int, radius: np.ndarray, dt: float) -> mujoco.MjSpec:
    """The ghost world as free spheres (gravity off); only collision detection is ever run."""
    spec = mujoco.MjSpec()
    spec.option.gravity = [0.0, 0.0, 0.0]
    spec.option.timestep = dt
    # Room for inflated contacts at N in the thousands (the default arena is sized for ~10).
    spec.memory = max(64, n // 4) * 1024 * 1024
    for i in range(n):
        body = spec.worldbody.add_body(name=f"s{i}")
        body.add_freejoint()
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[float(radius[i]), 0.0, 0.0])
    return spec


def _timed_collision(m: mujoco.MjModel, d: mujoco.MjData) -> tuple[float, np.ndarray, np.ndarray]:
    """Positions and velocities from ``d.qpos``, ``d.qvel``, then ``mj_collision``.

    Only ``mj_collision`` is timed: it is the peer's own cost, the kinematics a step computes
    anyway.

    Returns:
        ``(seconds, geom1, geom2)``: the time ``mj_collision`` took and the ``(ncon,)`` geoms of
        its contacts.
    """
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)
    mujoco.mj_comVel(m, d)
    t0 = time.perf_counter()
    mujoco.mj_collision(m, d)
    seconds = time.perf_counter() - t0
    nc = int(d.ncon)
    return seconds, d.contact.geom1[:nc], d.contact.geom2[:nc]


class MujocoGhost:
    """``mj_collision`` on the ghost state (``GhostPeer``): gap-inflated, speculative, plain."""

    def __init__(self, world: GhostTrajectory, mode: str) -> None:
        self.mode = mode
        self.name = {
            "gap": "MuJoCo gap",
            "speculative": "MuJoCo speculative",
            "plain": "MuJoCo plain",
        }[mode]
        self.note = {
            "gap": "geom_gap = reach over H: contacts reported inactive (dist < gap_i + gap_j)",
            "speculative": "mjENBL_SPECULATIVE, margin 0: sweeps fast geoms along qvel * dt",
            "plain": "no inflation: contacts already there (the cost MuJoCo pays anyway)",
        }[mode]
        self.model = _ghost_spec(world.n, world.radius, world.dt).compile()
        if mode == "speculative":
            self.model.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_SPECULATIVE)
        self.data = mujoco.MjData(self.model)
        self.n = world.n
        self.accel = world.accel
        self.horizon = (1 + LATENCY) * world.dt
        self.qpos = self.data.qpos.reshape(world.n, 7)
        self.qpos[:, 3] = 1.0
        self.qvel = self.data.qvel.reshape(world.n, 6)
        # Speculative contacts look one physics step ahead; the others as far as H.
        self.h_steps = 1 if mode == "speculative" else 1 + LATENCY

    def _alarms(self, c: np.ndarray, v: np.ndarray) -> np.ndarray:
        m, d = self.model, self.data
        self.qpos[:, :3] = c
        self.qvel[:, :3] = v
        if self.mode == "gap":
            m.geom_gap[:] = reach_distance(np.linalg.norm(v, axis=1), self.accel, 0.0, self.horizon)
        self.collision_s, geom1, geom2 = _timed_collision(m, d)
        if geom1.size == 0:
            return np.zeros(0, dtype=np.int64)
        # Geom g is sphere g (the world body has no geoms).
        return np.unique(pair_id(geom1, geom2, self.n))

    def start(self, c: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray | int]:
        return self._alarms(c, v), self.h_steps

    def step(
        self, c: np.ndarray, v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]:
        return self._alarms(c, v), self.h_steps, None, None


class MujocoScene:
    """``mj_collision`` on a copy of a scene's state (``ScenePeer``): gap or speculative."""

    def __init__(self, ctx: SceneContext, mode: str) -> None:
        self.ctx = ctx
        self.mode = mode
        self.name = "MuJoCo gap" if mode == "gap" else "MuJoCo speculative"
        self.note = (
            "geom_gap = point reach (|v_c| + |w| rbound) H + A H^2/2 + delta H"
            if mode == "gap"
            else "mjENBL_SPECULATIVE on a copy; contacts at step k alarm step k + 1"
        )
        self.model = copy.deepcopy(ctx.model)
        if mode == "speculative":
            self.model.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_SPECULATIVE)
        else:
            # The midphase prunes geom pairs of multi-geom bodies with per-body BVH boxes built
            # at compile time: a gap raised at run time is not in them, and the pair is lost
            # (measured on traffic: chassis 28 mm apart with gaps summing to 209 mm, no
            # contact). Without the midphase every geom pair reaches the gap-aware tests.
            self.model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_MIDPHASE)
        self.data = mujoco.MjData(self.model)
        self.h_steps = 1 if mode == "speculative" else 1 + LATENCY
        cov = ctx.predictor.covering
        m = ctx.model
        self.base_gap = np.asarray(m.geom_gap, dtype=np.float64).copy()
        self.sphere_geom = np.asarray(cov.sphere_geom, dtype=np.int64)
        self.geom_body = np.asarray(m.geom_bodyid, dtype=np.int64)
        self.rbound = np.asarray(m.geom_rbound, dtype=np.float64)
        self.snapshot: tuple[np.ndarray, ...] = ()

    def set_snapshot(self, data: mujoco.MjData) -> None:
        """Remember the state ``mj_step`` is about to use (call right before it)."""
        self.snapshot = (
            data.qpos.copy(),
            data.qvel.copy(),
            data.mocap_pos.copy(),
            data.mocap_quat.copy(),
        )

    def _alarms(self, data: mujoco.MjData) -> np.ndarray:
        ctx = self.ctx
        m, d = self.model, self.data
        # After mj_step, data.contact and geom_xpos describe the state *before* integration while
        # data.qpos is already the next one (docs/discrete-time.md, section 1): copy the pre-step
        # snapshot so that these contacts and MuJoCo's own describe the same instant.
        qpos, qvel, mocap_pos, mocap_quat = self.snapshot
        d.qpos[:] = qpos
        d.qvel[:] = qvel
        d.mocap_pos[:] = mocap_pos
        d.mocap_quat[:] = mocap_quat
        if self.mode == "gap":
            # Every point of geom g moves at most |v_c| + |w| rbound (v_c: the covering
            # sphere's centre velocity, mocap twists included).
            _, v = ctx.predictor.sphere_states(data)
            g = self.sphere_geom
            w = np.linalg.norm(np.asarray(data.cvel)[self.geom_body[g], :3], axis=1)
            speed = np.linalg.norm(v, axis=1) + w * self.rbound[g]
            gap = self.base_gap.copy()
            gap[g] += reach_distance(speed, ctx.sphere_accel, ctx.sphere_delta, ctx.horizon)
            m.geom_gap[:] = gap
        self.collision_s, geom1, geom2 = _timed_collision(m, d)
        if geom1.size == 0:
            return np.zeros(0, dtype=np.int64)
        gp = ctx.predictor.geom_pairs.indices_of(geom1, geom2)
        return np.unique(gp[gp >= 0])

    def start(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray | int]:
        return self._alarms(data), self.h_steps

    def step(
        self, data: mujoco.MjData
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]:
        return self._alarms(data), self.h_steps, None, None
