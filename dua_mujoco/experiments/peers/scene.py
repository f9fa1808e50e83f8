"""The bundled-scene benchmark: all peers watch one MuJoCo rollout; its contacts are the truth."""

from __future__ import annotations

import time
from collections.abc import Callable
from functools import partial
from typing import Protocol

import mujoco
import numpy as np

from dua_mujoco.experiments.peers.broadphase import BroadphaseScene
from dua_mujoco.experiments.peers.candidates import BROADPHASES
from dua_mujoco.experiments.peers.mujoco_collision import MujocoScene
from dua_mujoco.experiments.peers.rows import SceneRow, peer_measures
from dua_mujoco.experiments.peers.scene_context import SceneContext
from dua_mujoco.experiments.peers.schedulers import DuaScene, SaScene
from dua_mujoco.experiments.peers.tracker import Tracker, truth_keys

__all__ = ["SCENE_PEERS", "ScenePeer", "make_scene_peer", "run_scene"]


_MAKERS: dict[str, Callable[[SceneContext], ScenePeer]] = {
    "DUA": DuaScene,
    "SA(tau)": SaScene,
    **{kind: partial(BroadphaseScene, kind=kind) for kind in BROADPHASES},
    **{f"MuJoCo {m}": partial(MujocoScene, mode=m) for m in ("gap", "speculative")},
}

SCENE_PEERS: tuple[str, ...] = tuple(_MAKERS)
"""Peers of the bundled-scene benchmark."""


class ScenePeer(Protocol):
    """A predictor on a MuJoCo scene: alarms on active geom pairs, read from ``MjData``.

    ``start`` and ``step`` return what ``GhostPeer``'s do, with geom-pair ids instead of sphere
    pairs.

    Attributes:
        name: The peer's name in ``SCENE_PEERS``.
        note: How it works, for the tables.
    """

    name: str
    note: str

    def start(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray | int]:
        """Initial classification: ``(alarms (k,), horizon_steps)``."""
        ...

    def step(
        self, data: mujoco.MjData
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]:
        """One step: ``(alarms (k,), horizon_steps, evaluated, candidates)``."""
        ...


def make_scene_peer(name: str, ctx: SceneContext) -> ScenePeer:
    """The scene peer called ``name`` (one of ``SCENE_PEERS``), sharing ``ctx``."""
    if name not in _MAKERS:
        raise ValueError(f"unknown scene peer {name!r}; choose from {SCENE_PEERS}")
    return _MAKERS[name](ctx)


def run_scene(scene: str, steps: int, seed: int) -> list[SceneRow]:
    """All scene peers watch one rollout; MuJoCo's contacts are the ground truth."""
    from dua_mujoco.models.scenes import SCENES, load_scene, make_controller

    model, data = load_scene(scene)
    ctx = SceneContext(model, SCENES[scene].accel_hint)
    peers = [make_scene_peer(name, ctx) for name in SCENE_PEERS]
    trackers = [Tracker(ctx.npairs) for _ in peers]
    times: list[list[float]] = [[] for _ in peers]
    cands: list[list[float]] = [[] for _ in peers]
    n_alarms = [0 for _ in peers]
    controller = make_controller(model, "random", seed=seed)
    geom_pairs = ctx.predictor.geom_pairs

    def contacts() -> np.ndarray:
        nc = int(data.ncon)
        if nc == 0:
            return np.zeros(0, dtype=np.int64)
        gp = geom_pairs.indices_of(data.contact.geom1[:nc], data.contact.geom2[:nc])
        return np.unique(gp[gp >= 0])

    copies = [p for p in peers if isinstance(p, MujocoScene)]

    def physics_step() -> None:
        controller(model, data)
        for peer in copies:
            peer.set_snapshot(data)
        mujoco.mj_step(model, data)

    # One mj_step so that kinematics and contacts describe one instant (see rollout.run).
    physics_step()
    truth = [contacts()]
    for peer, tr in zip(peers, trackers, strict=True):
        alarms, h = peer.start(data)
        tr.apply(0, alarms, h, None, record=False)
    for k in range(1, steps + 1):
        physics_step()
        now = contacts()
        onset = np.setdiff1d(now, truth[-1], assume_unique=True)
        truth.append(now)
        for idx, (peer, tr) in enumerate(zip(peers, trackers, strict=True)):
            tr.check_onsets(k, onset)
            t0 = time.perf_counter()
            alarms, h, evaluated, cand = peer.step(data)
            dt = time.perf_counter() - t0
            if isinstance(peer, MujocoScene):
                dt = peer.collision_s
            times[idx].append(dt)
            if cand is not None:
                cands[idx].append(cand)
            n_alarms[idx] += int(alarms.size)
            tr.apply(k, alarms, h, evaluated)
    keys = truth_keys(truth)
    rows = []
    for idx, (peer, tr) in enumerate(zip(peers, trackers, strict=True)):
        rows.append(
            SceneRow(
                scene=scene,
                peer=peer.name,
                pairs=ctx.npairs,
                note=peer.note,
                **peer_measures(tr, keys, steps, times[idx], cands[idx], n_alarms[idx], ctx.dt),
            )
        )
    return rows
