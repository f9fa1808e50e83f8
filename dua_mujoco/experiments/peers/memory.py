"""Memory and set-up cost of the peers' structures at large N, one subprocess per peer."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np

from dua_mujoco.experiments.peers.ghost import make_ghost_peer
from dua_mujoco.experiments.peers.ghost_world import record_ghost
from dua_mujoco.experiments.peers.rows import MemoryRow

__all__ = ["memory_probe", "memory_row", "reset_peak", "rss"]


def rss(field: str = "VmRSS") -> int:
    """This process's ``VmRSS`` (current) or ``VmHWM`` (peak) resident size from /proc, bytes."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1]) * 1024
    raise RuntimeError(f"no {field} in /proc/self/status")


def reset_peak() -> tuple[int, bool]:
    """Reset the kernel's peak resident size (Linux ``clear_refs`` 5) where allowed.

    Returns:
        The size to measure the peak's growth from (the current size, or the earlier peak if
        the reset is refused: weaker, but still far below an O(N^2) footprint), and whether the
        reset was made.
    """
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        return rss("VmHWM"), False
    return rss("VmRSS"), True


def memory_probe(peer: str, n: int) -> dict[str, Any]:
    """Build one peer's structures at ``n`` spheres in this process and measure them.

    Meant to run in a fresh subprocess (``python -c``) so that peak RSS belongs to one peer.
    Each peer runs once first on a tiny world (what loading its code costs is not the peer's);
    allocations are traced during the build and a few steps (``tracemalloc`` sees numpy's, not
    the native core's: a schedule's state and the grid's work arrays count in the resident
    size only), then steps are timed without tracing (tracemalloc slows every numpy allocation
    down).
    """
    world = record_ghost(n, 6, 0, seed=0)
    c, v = world.positions, world.velocities
    tiny = record_ghost(8, 2, 0, seed=0)
    warm = make_ghost_peer(peer, tiny)
    warm.start(tiny.positions[0], tiny.velocities[0])
    warm.step(tiny.positions[1], tiny.velocities[1])
    del warm
    base_rss, reset = reset_peak()
    tracemalloc.start()
    t0 = time.perf_counter()
    p = make_ghost_peer(peer, world)
    p.start(c[0], v[0])
    build = time.perf_counter() - t0
    p.step(c[1], v[1])
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    times = []
    for k in range(2, c.shape[0]):
        t1 = time.perf_counter()
        p.step(c[k], v[k])
        times.append(time.perf_counter() - t1)
    return {
        "peer": peer,
        "n": n,
        "pairs": n * (n - 1) // 2,
        "traced_mb": peak / 2**20,
        "rss_mb": (rss("VmHWM") - base_rss) / 2**20,
        "build_s": build,
        "step_us": float(np.median(times) * 1e6),
        "peak_reset": reset,
    }


def memory_row(peer: str, n: int) -> MemoryRow:
    """``memory_probe(peer, n)`` in a fresh interpreter, so that its peak RSS is the peer's own."""
    code = (
        "import json, sys\n"
        "from dua_mujoco.experiments.peers.memory import memory_probe\n"
        f"print(json.dumps(memory_probe({peer!r}, {n})))\n"
    )
    env = dict(os.environ)
    root = str(Path(__file__).resolve().parents[3])
    env["PYTHONPATH"] = root + os.pathsep + env.get("PYTHONPATH", "")
    res = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=False
    )
    if res.returncode != 0:
        tail = res.stderr.strip().splitlines()[-1:] or ["?"]
        return MemoryRow(
            peer,
            n,
            n * (n - 1) // 2,
            None,
            float("nan"),
            float("nan"),
            float("nan"),
            note=f"failed: {tail[0]}",
        )
    out = json.loads(res.stdout.strip().splitlines()[-1])
    note = {
        "DUA": "PairSet (6 arrays of M) + slots, where, last_tau, last_step",
        "SA(tau)": "PairSet + last urgency + one step's tau and ids",
        "sweep": "per-step temporaries only (O(N + candidates))",
        "grid": "per-step temporaries only (O(N + candidates))",
        "MuJoCo gap": "model + MjData arena (C; in RSS, not traced)",
        "FCL": "tree and objects (C++; in RSS, not traced)",
    }.get(peer, "")
    traced = None if peer in ("MuJoCo gap", "FCL") else float(out["traced_mb"])
    if not out.get("peak_reset", False):
        note += " (peak RSS could not be reset: growth above the earlier peak)"
    return MemoryRow(
        peer,
        n,
        out["pairs"],
        traced,
        float(out["rss_mb"]),
        float(out["build_s"]),
        float(out["step_us"]),
        note,
    )
