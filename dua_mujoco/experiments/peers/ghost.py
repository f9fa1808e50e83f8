"""The ghost-world benchmark: every peer watches one recorded trajectory, judged against it."""

from __future__ import annotations

import time
from collections.abc import Callable
from functools import partial
from typing import Protocol

import numpy as np

from dua_mujoco.experiments.peers.broadphase import BroadphaseGhost
from dua_mujoco.experiments.peers.candidates import BROADPHASES
from dua_mujoco.experiments.peers.fcl_tree import FclGhost
from dua_mujoco.experiments.peers.ghost_world import GhostTrajectory
from dua_mujoco.experiments.peers.mujoco_collision import MujocoGhost
from dua_mujoco.experiments.peers.rows import GhostRow, peer_measures
from dua_mujoco.experiments.peers.schedulers import DuaGhost, SaGhost
from dua_mujoco.experiments.peers.tracker import Tracker

__all__ = [
    "COMPLETE_PEERS",
    "GHOST_PEERS",
    "GhostPeer",
    "make_ghost_peer",
    "run_ghost_peer",
]


_MAKERS: dict[str, Callable[[GhostTrajectory], GhostPeer]] = {
    "DUA": DuaGhost,
    "SA(tau)": SaGhost,
    **{kind: partial(BroadphaseGhost, kind=kind) for kind in BROADPHASES},
    **{f"MuJoCo {m}": partial(MujocoGhost, mode=m) for m in ("gap", "speculative", "plain")},
    "FCL": FclGhost,
}

GHOST_PEERS: tuple[str, ...] = tuple(_MAKERS)
"""Peers of the ghost-world benchmark (FCL only when python-fcl is installed)."""

COMPLETE_PEERS: tuple[str, ...] = ("DUA", "SA(tau)", "sweep", "grid", "MuJoCo gap", "FCL")
"""Peers that must miss nothing while the bounds hold."""


class GhostPeer(Protocol):
    """A predictor on the ghost world: alarms from sphere states, step by step.

    Attributes:
        name: The peer's name in ``GHOST_PEERS``.
        note: How it works, for the tables.
    """

    name: str
    note: str

    def start(self, c: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray | int]:
        """Initial classification at centres ``c (n, 3)`` and velocities ``v (n, 3)``.

        Returns:
            ``(alarms (k,), horizon_steps)``: alarmed pair ids (``pair_id`` order) and their
            horizons in steps (one for all, or ``(k,)``).
        """
        ...

    def step(
        self, c: np.ndarray, v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]:
        """One step at centres ``c (n, 3)`` and velocities ``v (n, 3)``.

        Returns:
            ``(alarms (k,), horizon_steps, evaluated, candidates)``: as ``start``, plus the pair
            ids evaluated this step (None: every pair) and the candidates (pair evaluations or
            broadphase candidates; None where the library does not expose them).
        """
        ...


def make_ghost_peer(name: str, world: GhostTrajectory) -> GhostPeer:
    """The ghost-world peer called ``name`` (one of ``GHOST_PEERS``), built for ``world``."""
    if name not in _MAKERS:
        raise ValueError(f"unknown peer {name!r}; choose from {GHOST_PEERS}")
    return _MAKERS[name](world)


def run_ghost_peer(
    name: str, world: GhostTrajectory, steps: int, onsets: list[np.ndarray], truth: np.ndarray
) -> GhostRow:
    """Run one peer on a recorded trajectory and judge its alarms.

    Args:
        name: The peer (``GHOST_PEERS``).
        world: The recording (``steps`` predictor steps plus the extra steps alarms are judged on).
        steps: Predictor steps after the initial one.
        onsets: By step, ``(k,)`` pair ids whose collision starts at that step.
        truth: Sorted collision keys ``pair * S + step`` of the whole recording (``truth_keys``).
    """
    peer = make_ghost_peer(name, world)
    npairs = world.n * (world.n - 1) // 2
    tracker = Tracker(npairs)
    alarms, h = peer.start(world.positions[0], world.velocities[0])
    tracker.apply(0, alarms, h, None, record=False)
    times = np.empty(steps)
    cands: list[float] = []
    n_alarms = 0
    for k in range(1, steps + 1):
        c = world.positions[k]
        v = world.velocities[k]
        tracker.check_onsets(k, onsets[k])
        t0 = time.perf_counter()
        alarms, h, evaluated, cand = peer.step(c, v)
        times[k - 1] = time.perf_counter() - t0
        if isinstance(peer, MujocoGhost):
            times[k - 1] = peer.collision_s
        if cand is not None:
            cands.append(cand)
        elif evaluated is not None:
            cands.append(float(evaluated.size))
        n_alarms += int(alarms.size)
        tracker.apply(k, alarms, h, evaluated)
    return GhostRow(
        peer=name,
        n=world.n,
        pairs=npairs,
        note=peer.note,
        **peer_measures(
            tracker, truth, world.positions.shape[0] - 1, times, cands, n_alarms, world.dt
        ),
    )
