"""Sizes of a benchmark run (full or quick).

Every peer runs on one thread: the native core's batches that could split over two are given
in batches below ``PARALLEL_MIN`` rows (``schedulers.serial_tau``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Plan", "make_plan"]


@dataclass(frozen=True)
class Plan:
    """Sizes of one benchmark run.

    Attributes:
        sizes: Ghost-world sphere counts.
        steps: Ghost-world predictor steps.
        extra: Further recorded steps on which the last alarms are judged.
        scenes: Bundled scenes.
        scene_steps: Physics steps per scene.
        memory_n: Sphere count of the memory probes.
        memory_peers: Peers probed for memory.
        tunnel_accels: Accelerations of the tunnel sweep (m/s^2).
        tunnel_clearances: Clearances of the tunnel sweep (m).
        sa_max_n: Largest N at which SA(tau) runs.
    """

    sizes: tuple[int, ...]
    steps: int
    extra: int
    scenes: tuple[str, ...]
    scene_steps: int
    memory_n: int
    memory_peers: tuple[str, ...]
    tunnel_accels: tuple[float, ...]
    tunnel_clearances: tuple[float, ...]
    sa_max_n: int


def make_plan(quick: bool) -> Plan:
    """The full run's plan, or the ``quick`` one (under two minutes)."""
    if quick:
        return Plan(
            sizes=(10, 50, 200),
            steps=60,
            extra=60,
            scenes=("paper_world", "traffic"),
            scene_steps=200,
            memory_n=1000,
            memory_peers=("DUA", "sweep", "grid"),
            tunnel_accels=(1e3, 1e5),
            tunnel_clearances=(0.002, 0.02, 0.2),
            sa_max_n=200,
        )
    return Plan(
        sizes=(10, 20, 50, 100, 200, 500, 1000, 2000),
        steps=200,
        extra=200,
        scenes=("two_arms", "traffic", "clutter", "paper_world"),
        scene_steps=1000,
        memory_n=5000,
        memory_peers=("DUA", "SA(tau)", "sweep", "grid", "MuJoCo gap", "FCL"),
        tunnel_accels=(1e2, 1e3, 1e4, 3e4, 1e5, 1e6),
        tunnel_clearances=tuple(np.geomspace(0.001, 0.5, 12).round(4).tolist()),
        sa_max_n=2000,
    )
