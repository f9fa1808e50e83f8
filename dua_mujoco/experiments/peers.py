"""DUA against its peers (issue 5): the same worlds, the same metrics, one run.

Peers. Each is a *predictor*: at every step it looks at the current state and names the pairs
that may collide soon ("alarms"). All of them are complete under the same hypotheses as DUA
(bounded accelerations) except MuJoCo's speculative contacts, which extrapolate the pre-step
velocity over one step and ignore acceleration by design.

* ``DUA``: :class:`~dua_mujoco.core.schedules.DUAScheduler`, ``L = ceil(log2(M + 1))`` tau evaluations
  per step (fused ``step_points`` in the ghost world, :class:`~dua_mujoco.mj.predictor.Predictor` on
  MuJoCo scenes).
* ``SA(tau)``: :class:`~dua_mujoco.core.schedules.SelectAllScheduler`, every pair every step.
* ``sweep`` / ``grid``: a swept-sphere broadphase. Each sphere is inflated by the distance it can
  travel within the horizon ``H = (1 + latency) dt``,
  ``reach = |v| H + A H^2 / 2 + delta H``, and every pair whose inflated spheres overlap is an
  alarm. Candidates come from sort-and-sweep on the axis of largest spread (``sweep``) or from a
  uniform grid of cell ``2 max R`` (``grid``); both vectorised numpy, O(N log N + candidates).
* ``MuJoCo gap``: ``mj_collision`` on a copy of the state with ``geom_gap`` set per geom to its
  reach over ``H``. MuJoCo >= 3.9 reports contacts at ``dist < margin + gap`` (margins and gaps
  summed per pair) and generates force only below ``margin``, so the inflated contacts are
  inactive (``efc_address = -1``) and the dynamics are untouched; the reported contacts are the
  alarms.
* ``MuJoCo speculative``: ``mj_collision`` with ``mjENBL_SPECULATIVE`` (MuJoCo 4.0) on a copy of
  the state. It sweeps fast geoms (one step's travel larger than their thickness) along
  ``qvel * dt`` only; its contacts are the alarms for the next step.
* ``MuJoCo plain``: ``mj_collision`` without inflation, the cost the simulation pays anyway.
* ``FCL``: python-fcl's ``DynamicAABBTreeCollisionManager`` on the inflated spheres (optional).

Metrics (per peer, per world size). A *collision onset* is a pair in contact at step ``k`` and not
at ``k - 1``. It is *predicted* when the pair stands alarmed from an evaluation strictly before
``k`` (for DUA, the pair's latest evaluation before ``k`` alarmed), so every predicted onset has a
lead time of at least one period and a latency-1 verdict is ready in time; ``latency = 1``
throughout so that a complete predictor must predict every onset. An alarm raised at step ``n``
with horizon ``h`` steps (``1 + latency`` for the select-all peers and broadphases, the bucket's
``I_k + latency`` for DUA, 1 for speculative contacts) is *false* if the pair does not collide at
any step in ``[n, n + h]``; when ``n + h`` lies past the recorded trajectory and no collision was
seen, the alarm is *open* (not judged). Time per step is the median wall time of the peer's own
call (for the MuJoCo peers ``mj_collision`` only: kinematics is shared with the simulation).

Worlds. The ghost world is :class:`~dua_mujoco.core.worlds.SphereWorld` (exact kinematics, bounds hold
exactly) with the box grown as ``(N / 40)^(1/3)`` so that the density of the paper's 40-sphere
unit cube is kept at every N (a fixed cube at N = 2000 would be 23 % spheres by volume). The
bundled scenes run MuJoCo with random controls; MuJoCo's contacts are the ground truth there.

Run it with ``dua-mujoco peers [--quick] [--json PATH] [--out DIR]``.
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import os
import subprocess
import sys
import time
import tracemalloc
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Protocol

import mujoco
import numpy as np

from dua_mujoco.progress import Progress
from dua_mujoco.core.schedules import DUAScheduler, PairSet, SelectAllScheduler
from dua_mujoco.core.worlds import SphereWorld

__all__ = [
    "GHOST_PEERS",
    "SCENE_PEERS",
    "GhostRow",
    "MemoryRow",
    "SceneRow",
    "TunnelRow",
    "add_arguments",
    "fcl_available",
    "grid_candidates",
    "main",
    "run_peers",
    "sweep_candidates",
]

LATENCY = 1
"""Verdict latency in periods for every peer (the paper's): a verdict computed at the collision
instant is useless, so prediction means an alarm from an earlier evaluation."""

GHOST_PEERS: tuple[str, ...] = (
    "DUA",
    "SA(tau)",
    "sweep",
    "grid",
    "MuJoCo gap",
    "MuJoCo speculative",
    "MuJoCo plain",
    "FCL",
)
"""Peers of the ghost-world benchmark (FCL only when python-fcl is installed)."""

SCENE_PEERS: tuple[str, ...] = (
    "DUA",
    "SA(tau)",
    "sweep",
    "grid",
    "MuJoCo gap",
    "MuJoCo speculative",
)
"""Peers of the bundled-scene benchmark."""

COMPLETE_PEERS: tuple[str, ...] = ("DUA", "SA(tau)", "sweep", "grid", "MuJoCo gap", "FCL")
"""Peers that must miss nothing while the bounds hold."""

_PAPER_DENSITY_N = 40  # the paper's world: 40 spheres in a unit cube


# --------------------------------------------------------------------------- result rows


@dataclass(frozen=True)
class GhostRow:
    """One peer at one N in the ghost world.

    Attributes:
        peer: Peer name (``GHOST_PEERS``).
        n: Spheres.
        pairs: Sphere pairs ``n (n - 1) / 2``.
        steps: Predictor steps after the initial one.
        time_us: Median wall time of one step (microseconds).
        time_us_p90: 90th percentile of the same.
        candidates_per_step: Pair evaluations (DUA, SA) or broadphase candidates per step
            (None where the library does not expose them).
        alarms_per_step: Alarmed pairs per step (what the exact stage must check).
        initial_alarms: Alarms of the initial classification (step 0; not judged).
        onsets: Collision onsets during the run.
        missed: Onsets not predicted.
        false_alarms: Alarms not followed by a collision within their horizon.
        open_alarms: Alarms whose horizon ends after the recorded trajectory, no collision seen.
        judged_alarms: Alarms whose horizon ends inside the recorded trajectory.
        lead_time_mean_s: Mean lead time of the predicted onsets (None if none).
        note: Anything the numbers need to be read right.
    """

    peer: str
    n: int
    pairs: int
    steps: int
    time_us: float
    time_us_p90: float
    candidates_per_step: float | None
    alarms_per_step: float
    initial_alarms: int
    onsets: int
    missed: int
    false_alarms: int
    open_alarms: int
    judged_alarms: int
    lead_time_mean_s: float | None
    note: str = ""


@dataclass(frozen=True)
class SceneRow:
    """One peer on one bundled MuJoCo scene (units are active geom pairs).

    Attributes mirror :class:`GhostRow`; ``scene`` is the bundled scene name, ``pairs`` the active
    geom pairs and ``contacts_onsets`` the onsets of MuJoCo's own contacts.
    """

    scene: str
    peer: str
    pairs: int
    steps: int
    time_us: float
    time_us_p90: float
    candidates_per_step: float | None
    alarms_per_step: float
    initial_alarms: int
    onsets: int
    missed: int
    false_alarms: int
    open_alarms: int
    judged_alarms: int
    lead_time_mean_s: float | None
    note: str = ""


@dataclass(frozen=True)
class MemoryRow:
    """Memory and set-up cost of one peer's data structures at one N (measured in a subprocess).

    Attributes:
        peer: Peer name.
        n: Spheres.
        pairs: Sphere pairs.
        traced_mb: Peak of Python/numpy allocations while building and stepping (tracemalloc).
        rss_mb: Growth of the process's peak resident set over the build and the steps
            (includes C allocations tracemalloc cannot see, e.g. MuJoCo's and FCL's).
        build_s: Time to build the structure (DUA and SA: the initial classification).
        step_us: Median time of a step after the build.
        note: How the number was obtained.
    """

    peer: str
    n: int
    pairs: int
    traced_mb: float | None
    rss_mb: float
    build_s: float
    step_us: float
    note: str = ""


@dataclass(frozen=True)
class TunnelRow:
    """One case of the speculative-contact demonstration (a sphere driven at a thin plate).

    Attributes:
        case: Short description.
        accel: Applied acceleration (m/s^2) along +x.
        speed0: Initial speed (m/s) along +x.
        clearance: Initial surface distance between sphere and plate (m).
        crossing_step: The step during which the sphere's path reaches the plate.
        plain: Outcome without speculative contacts (``stopped``, ``tunneled``: no contact ever,
            ``penetrated``: a contact came too late).
        speculative: Outcome with ``mjENBL_SPECULATIVE``.
        speculative_contact_step: First step with a sphere-plate contact (speculative run;
            -1 if never).
        dua_alarm_step: Instant of DUA's first alarm on the sphere-plate pair (-1 if none).
        dua_lead_s: Time from DUA's first alarm to the crossing (None if no alarm).
    """

    case: str
    accel: float
    speed0: float
    clearance: float
    crossing_step: int
    plain: str
    speculative: str
    speculative_contact_step: int
    dua_alarm_step: int
    dua_lead_s: float | None


# --------------------------------------------------------------------------- broadphases


def _expand(start: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All ``(i, j)`` with ``start[i] <= j < end[i]``, vectorised (the repeat/arange trick)."""
    count = np.maximum(end - start, 0)
    total = int(count.sum())
    owner = np.repeat(np.arange(start.shape[0], dtype=np.int64), count)
    # Position of each output inside its owner's run, added to the owner's start.
    first = np.cumsum(count) - count
    offset = np.arange(total, dtype=np.int64) - np.repeat(first, count)
    return owner, np.repeat(start, count) + offset


def sweep_candidates(centers: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sort-and-sweep on one axis: pairs of spheres whose intervals overlap on that axis.

    The axis is the one of largest spread (fewest overlaps for isotropic boxes). O(N log N)
    for the sort plus the candidates.

    Args:
        centers: ``(n, 3)`` sphere centres.
        radii: ``(n,)`` (inflated) radii.

    Returns:
        ``(a, b)`` int64 sphere indices with ``a != b``, each unordered pair once.
    """
    axis = int(np.argmax(np.ptp(centers, axis=0))) if centers.shape[0] else 0
    lo = centers[:, axis] - radii
    hi = centers[:, axis] + radii
    order = np.argsort(lo, kind="stable")
    lo_s = lo[order]
    hi_s = hi[order]
    # In sorted order, j > i overlaps i iff lo_j <= hi_i: a contiguous run after i.
    end = np.searchsorted(lo_s, hi_s, side="right")
    start = np.arange(1, order.shape[0] + 1, dtype=np.int64)
    a, b = _expand(start, end.astype(np.int64))
    return order[a], order[b]


# Half of the 26 neighbour offsets: each unordered pair of cells is visited once.
_HALF_NEIGHBOURS = np.array(
    [
        (dx, dy, dz)
        for dx in (-1, 0, 1)
        for dy in (-1, 0, 1)
        for dz in (-1, 0, 1)
        if (dx, dy, dz) > (0, 0, 0)
    ],
    dtype=np.int64,
)


def grid_candidates(centers: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Uniform-grid broadphase: pairs of spheres in the same or adjacent cells.

    The cell edge is ``2 max(radii)``, so two overlapping spheres are always in the same or in
    adjacent cells. Spheres are sorted by cell key; each cell's neighbours are found with
    ``searchsorted``, all vectorised.

    Args:
        centers: ``(n, 3)`` sphere centres.
        radii: ``(n,)`` (inflated) radii.

    Returns:
        ``(a, b)`` int64 sphere indices with ``a != b``, each unordered pair once.
    """
    n = centers.shape[0]
    if n < 2:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty
    cell = 2.0 * float(radii.max())
    if not cell > 0:
        cell = 1.0
    low = centers.min(axis=0)
    idx = np.floor((centers - low) / cell).astype(np.int64)
    # One padding cell on each side so that neighbour offsets never wrap around.
    idx += 1
    dims = idx.max(axis=0) + 2
    strides = np.array([dims[1] * dims[2], dims[2], 1], dtype=np.int64)
    key = idx @ strides
    order = np.argsort(key, kind="stable")
    key_s = key[order]
    pos = np.arange(n, dtype=np.int64)
    # Same cell: the later members of the run.
    run_end = np.searchsorted(key_s, key_s, side="right")
    parts_a = []
    parts_b = []
    a, b = _expand(pos + 1, run_end.astype(np.int64))
    parts_a.append(a)
    parts_b.append(b)
    for off in _HALF_NEIGHBOURS:
        nb = key_s + int(off @ strides)
        lo = np.searchsorted(key_s, nb, side="left")
        hi = np.searchsorted(key_s, nb, side="right")
        a, b = _expand(lo.astype(np.int64), hi.astype(np.int64))
        parts_a.append(a)
        parts_b.append(b)
    a = np.concatenate(parts_a)
    b = np.concatenate(parts_b)
    return order[a], order[b]


_BROADPHASES: dict[str, Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]] = {
    "sweep": sweep_candidates,
    "grid": grid_candidates,
}


def _reach(
    speed: np.ndarray, accel: np.ndarray | float, delta: np.ndarray | float, horizon: float
) -> np.ndarray:
    """Distance a point can travel within ``horizon``: ``|v| H + A H^2 / 2 + delta H``."""
    return np.asarray(speed * horizon + 0.5 * accel * horizon * horizon + delta * horizon)


def fcl_available() -> bool:
    """Whether python-fcl can be imported (``pip install python-fcl``)."""
    try:
        import fcl  # noqa: F401
    except ImportError:
        return False
    return True


# --------------------------------------------------------------------------- alarm bookkeeping


class _Tracker:
    """Standing alarms, onsets, lead times and alarm events of one peer (not timed).

    A pair *stands alarmed* when its latest evaluation alarmed. Peers that evaluate every pair
    each step pass ``evaluated=None``: pairs alarmed at the previous step and not now stand down.
    """

    def __init__(self, npairs: int) -> None:
        self.since = np.full(npairs, -1, dtype=np.int64)
        self.prev = np.zeros(0, dtype=np.int64)
        self.event_step: list[np.ndarray] = []
        self.event_pair: list[np.ndarray] = []
        self.event_horizon: list[np.ndarray] = []
        self.onsets = 0
        self.missed = 0
        self.leads: list[np.ndarray] = []
        self.initial = 0

    def check_onsets(self, k: int, onset_pairs: np.ndarray) -> None:
        """Count the onsets at step ``k`` against the alarms standing from steps ``< k``."""
        if onset_pairs.size == 0:
            return
        since = self.since[onset_pairs]
        hit = since >= 0
        self.onsets += int(onset_pairs.size)
        self.missed += int((~hit).sum())
        self.leads.append(k - since[hit])

    def apply(
        self,
        n: int,
        alarmed: np.ndarray,
        horizon_steps: np.ndarray | int,
        evaluated: np.ndarray | None,
        *,
        record: bool = True,
    ) -> None:
        """Apply step ``n``'s alarms (unique ids); ``record`` them as events to be judged.

        The initial classification (step 0) stands like any evaluation but is not recorded:
        DUA's alarms almost every pair there (every pair of a large bucket has tau below the
        bucket's horizon), which says nothing about the steady state.
        """
        alarmed = np.asarray(alarmed, dtype=np.int64)
        if evaluated is None:
            dropped = np.setdiff1d(self.prev, alarmed, assume_unique=True)
            self.prev = alarmed
        else:
            dropped = np.setdiff1d(evaluated, alarmed, assume_unique=True)
        self.since[dropped] = -1
        cur = self.since[alarmed]
        self.since[alarmed] = np.where(cur >= 0, cur, n)
        if not record:
            self.initial = int(alarmed.size)
            return
        self.event_step.append(np.full(alarmed.size, n, dtype=np.int64))
        self.event_pair.append(alarmed)
        self.event_horizon.append(
            np.broadcast_to(np.asarray(horizon_steps, dtype=np.int64), alarmed.shape).copy()
        )

    def judge(self, truth_keys: np.ndarray, last_step: int) -> tuple[int, int, int, int]:
        """``(alarms, false, open, judged)`` against the sorted collision keys ``pair * S + step``.

        ``S = last_step + 1``; an alarm at ``n`` with horizon ``h`` is true if the pair collides at
        a step in ``[n, min(n + h, last_step)]``.
        """
        if not self.event_step:
            return 0, 0, 0, 0
        step = np.concatenate(self.event_step)
        pair = np.concatenate(self.event_pair)
        h = np.concatenate(self.event_horizon)
        stride = last_step + 1
        end = np.minimum(step + h, last_step)
        lo = np.searchsorted(truth_keys, pair * stride + step, side="left")
        hi = np.searchsorted(truth_keys, pair * stride + end, side="right")
        true = hi > lo
        beyond = step + h > last_step
        false = int((~true & ~beyond).sum())
        open_ = int((~true & beyond).sum())
        return int(step.size), false, open_, int((~beyond).sum())

    def lead_mean(self, dt: float) -> float | None:
        if not self.leads:
            return None
        lead = np.concatenate(self.leads)
        return float(lead.mean() * dt) if lead.size else None


def _onsets_by_step(keys_per_step: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Pairs colliding at step ``k`` and not at ``k - 1`` (step 0 has no onsets)."""
    out = [np.zeros(0, dtype=np.int64)]
    for k in range(1, len(keys_per_step)):
        out.append(np.setdiff1d(keys_per_step[k], keys_per_step[k - 1], assume_unique=True))
    return out


def _truth_keys(keys_per_step: Sequence[np.ndarray]) -> np.ndarray:
    stride = len(keys_per_step)
    parts = [p * stride + k for k, p in enumerate(keys_per_step)]
    return np.sort(np.concatenate(parts)) if parts else np.zeros(0, dtype=np.int64)


# --------------------------------------------------------------------------- ghost world peers


def _pair_id(i: np.ndarray, j: np.ndarray, n: int) -> np.ndarray:
    """Index of the unordered pair ``(i, j)`` in ``np.triu_indices(n, 1)`` order."""
    a = np.minimum(i, j).astype(np.int64)
    b = np.maximum(i, j).astype(np.int64)
    return np.asarray(a * n - a * (a + 1) // 2 + (b - a - 1))


@dataclass(frozen=True)
class _Ghost:
    """A recorded ghost-world trajectory and its constants."""

    n: int
    dt: float
    radius: np.ndarray
    accel: float
    positions: np.ndarray  # (steps + 1, n, 3)
    velocities: np.ndarray  # (steps + 1, n, 3)


class _GhostPeer(Protocol):
    name: str
    note: str

    def start(self, c: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray | int]: ...

    def step(
        self, c: np.ndarray, v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]: ...


class _DuaGhost:
    name = "DUA"
    note = "fused step_points (select, tau, sort, reinsert in one compiled call)"

    def __init__(self, world: _Ghost) -> None:
        self.pairs = PairSet.all_pairs(world.radius, world.accel)
        self.dt = world.dt
        self.sched: DUAScheduler | None = None

    def start(self, c: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray | int]:
        tau0 = self.pairs.tau(np.arange(len(self.pairs)), c, v)
        self.sched = DUAScheduler(tau0, dt=self.dt, latency=LATENCY)
        ids = self.sched.initial_alarms
        return ids, self._horizon(ids)

    def _horizon(self, ids: np.ndarray) -> np.ndarray:
        assert self.sched is not None
        return np.asarray(self.sched.interval[self.sched.bucket(ids)] + LATENCY)

    def step(
        self, c: np.ndarray, v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]:
        assert self.sched is not None
        alarms = self.sched.step_points(self.pairs, c, v)
        return alarms, self._horizon(alarms), self.sched.last_selected, None


class _SaGhost:
    name = "SA(tau)"
    note = "tau of every pair every step (numba, threaded)"

    def __init__(self, world: _Ghost) -> None:
        self.pairs = PairSet.all_pairs(world.radius, world.accel)
        self.dt = world.dt
        self.sched: SelectAllScheduler | None = None

    def start(self, c: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray | int]:
        tau0 = self.pairs.tau(np.arange(len(self.pairs)), c, v)
        self.sched = SelectAllScheduler(tau0, dt=self.dt, latency=LATENCY)
        return self.sched.initial_alarms, 1 + LATENCY

    def step(
        self, c: np.ndarray, v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]:
        assert self.sched is not None
        ids = self.sched.select()
        alarms = self.sched.update(ids, self.pairs.tau(ids, c, v))
        return alarms, 1 + LATENCY, None, float(ids.size)


class _BroadphaseGhost:
    """Swept-sphere broadphase on the ghost world: inflated spheres, candidates, overlap test."""

    def __init__(self, world: _Ghost, kind: str) -> None:
        self.name = kind
        self.note = {
            "sweep": "sort-and-sweep on the axis of largest spread",
            "grid": "uniform grid, cell = 2 max inflated radius",
        }[kind]
        self.candidates = _BROADPHASES[kind]
        self.n = world.n
        self.radius = world.radius
        self.accel = np.full(world.n, world.accel)
        self.horizon = (1 + LATENCY) * world.dt

    def _alarms(self, c: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, int]:
        grown = self.radius + _reach(np.linalg.norm(v, axis=1), self.accel, 0.0, self.horizon)
        a, b = self.candidates(c, grown)
        d = c[a] - c[b]
        reach = grown[a] + grown[b]
        hit = np.einsum("ij,ij->i", d, d) <= reach * reach
        return np.unique(_pair_id(a[hit], b[hit], self.n)), int(a.size)

    def start(self, c: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray | int]:
        return self._alarms(c, v)[0], 1 + LATENCY

    def step(
        self, c: np.ndarray, v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]:
        alarms, cand = self._alarms(c, v)
        return alarms, 1 + LATENCY, None, float(cand)


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


class _MujocoGhost:
    """``mj_collision`` on the ghost state: gap-inflated, speculative, or plain."""

    def __init__(self, world: _Ghost, mode: str) -> None:
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
            m.geom_gap[:] = _reach(np.linalg.norm(v, axis=1), self.accel, 0.0, self.horizon)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_comVel(m, d)
        t0 = time.perf_counter()
        mujoco.mj_collision(m, d)
        self.collision_s = time.perf_counter() - t0
        nc = int(d.ncon)
        if nc == 0:
            return np.zeros(0, dtype=np.int64)
        # Geom g is sphere g (the world body has no geoms).
        return np.unique(_pair_id(d.contact.geom1[:nc], d.contact.geom2[:nc], self.n))

    def start(self, c: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray | int]:
        return self._alarms(c, v), self.h_steps

    def step(
        self, c: np.ndarray, v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]:
        return self._alarms(c, v), self.h_steps, None, None


class _FclGhost:
    """python-fcl's DynamicAABBTree on the inflated spheres.

    python-fcl exposes no batch update: radii and translations are set one object at a time and
    candidates come back through a Python callback, so this measures FCL *through its Python
    binding* (an upper bound on the C++ library's cost).
    """

    name = "FCL"
    note = "DynamicAABBTreeCollisionManager via python-fcl (per-object Python calls)"

    def __init__(self, world: _Ghost) -> None:
        import fcl

        self.fcl = fcl
        self.n = world.n
        self.radius = world.radius
        self.accel = np.full(world.n, world.accel)
        self.horizon = (1 + LATENCY) * world.dt
        self.geoms = [fcl.Sphere(float(r)) for r in world.radius]
        self.objs = [fcl.CollisionObject(g, fcl.Transform(np.zeros(3))) for g in self.geoms]
        self.index = {id(g): i for i, g in enumerate(self.geoms)}
        self.manager = fcl.DynamicAABBTreeCollisionManager()
        self.manager.registerObjects(self.objs)
        self.manager.setup()
        self.request = fcl.CollisionRequest(num_max_contacts=1, enable_contact=False)

    def _alarms(self, c: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, int]:
        fcl = self.fcl
        grown = self.radius + _reach(np.linalg.norm(v, axis=1), self.accel, 0.0, self.horizon)
        for g, o, r, p in zip(self.geoms, self.objs, grown.tolist(), c, strict=True):
            g.radius = r
            g.computeLocalAABB()  # without it the tree keeps the old AABB
            o.setTranslation(p)
        self.manager.update()
        data = fcl.CollisionData(request=fcl.CollisionRequest(num_max_contacts=10**7))
        count = [0]

        def callback(o1: Any, o2: Any, cdata: Any) -> bool:
            count[0] += 1
            return bool(fcl.defaultCollisionCallback(o1, o2, cdata))

        self.manager.collide(data, callback)
        contacts = data.result.contacts
        if not contacts:
            return np.zeros(0, dtype=np.int64), count[0]
        idx = np.array(
            [(self.index[id(ct.o1)], self.index[id(ct.o2)]) for ct in contacts], dtype=np.int64
        )
        return np.unique(_pair_id(idx[:, 0], idx[:, 1], self.n)), count[0]

    def start(self, c: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray | int]:
        return self._alarms(c, v)[0], 1 + LATENCY

    def step(
        self, c: np.ndarray, v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]:
        alarms, cand = self._alarms(c, v)
        return alarms, 1 + LATENCY, None, float(cand)


def _make_ghost_peer(name: str, world: _Ghost) -> _GhostPeer:
    if name == "DUA":
        return _DuaGhost(world)
    if name == "SA(tau)":
        return _SaGhost(world)
    if name in _BROADPHASES:
        return _BroadphaseGhost(world, name)
    if name.startswith("MuJoCo "):
        return _MujocoGhost(world, name.split(" ", 1)[1])
    if name == "FCL":
        return _FclGhost(world)
    raise ValueError(f"unknown peer {name!r}; choose from {GHOST_PEERS}")


def _record_ghost(n: int, steps: int, extra: int, seed: int) -> _Ghost:
    """Roll the ghost world out for ``steps + extra`` steps (exact states at every step)."""
    box = (n / _PAPER_DENSITY_N) ** (1.0 / 3.0)
    world = SphereWorld(n, seed=seed, box=box)
    total = steps + extra + 1
    pos = np.empty((total, n, 3))
    vel = np.empty((total, n, 3))
    for k in range(total):
        pos[k] = world.positions
        vel[k] = world.velocities
        world.step()
    return _Ghost(n, world.dt, world.radius, world.accel_bound, pos, vel)


def _ghost_truth(world: _Ghost) -> list[np.ndarray]:
    """Colliding pair ids at every recorded step: ``|c_i - c_j| <= r_i + r_j`` (grid + exact)."""
    out = []
    r = world.radius
    for c in world.positions:
        # The grid is exact here: candidates are then tested with the plain sphere distance.
        a, b = grid_candidates(c, r)
        d = c[a] - c[b]
        s = r[a] + r[b]
        hit = np.einsum("ij,ij->i", d, d) <= s * s
        out.append(np.unique(_pair_id(a[hit], b[hit], world.n)))
    return out


def _run_ghost_peer(
    name: str, world: _Ghost, steps: int, onsets: list[np.ndarray], truth: np.ndarray
) -> GhostRow:
    peer = _make_ghost_peer(name, world)
    npairs = world.n * (world.n - 1) // 2
    tracker = _Tracker(npairs)
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
        if isinstance(peer, _MujocoGhost):
            times[k - 1] = peer.collision_s
        if cand is not None:
            cands.append(cand)
        elif evaluated is not None:
            cands.append(float(evaluated.size))
        n_alarms += int(alarms.size)
        tracker.apply(k, alarms, h, evaluated)
    _, false, open_, judged = tracker.judge(truth, world.positions.shape[0] - 1)
    return GhostRow(
        peer=name,
        n=world.n,
        pairs=npairs,
        steps=steps,
        time_us=float(np.median(times) * 1e6),
        time_us_p90=float(np.percentile(times, 90) * 1e6),
        candidates_per_step=float(np.mean(cands)) if cands else None,
        alarms_per_step=n_alarms / steps,
        initial_alarms=tracker.initial,
        onsets=tracker.onsets,
        missed=tracker.missed,
        false_alarms=false,
        open_alarms=open_,
        judged_alarms=judged,
        lead_time_mean_s=tracker.lead_mean(world.dt),
        note=peer.note,
    )


# --------------------------------------------------------------------------- scene peers


class _ScenePeer(Protocol):
    name: str
    note: str

    def start(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray | int]: ...

    def step(
        self, data: mujoco.MjData
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]: ...


class _SceneContext:
    """A scene's predictor (covering, active pairs, bounds), shared by all peers."""

    def __init__(self, model: mujoco.MjModel, accel: float) -> None:
        from dua_mujoco.mj.predictor import Predictor

        self.model = model
        self.predictor = Predictor(model, accel=accel, latency=LATENCY)
        p = self.predictor
        gp = p.sphere_pairs.geom_pair
        # With the bounding covering every geom is one sphere (planes: one half-space), so
        # sphere pairs and active geom pairs correspond one to one.
        if not np.array_equal(np.sort(gp), np.arange(p.geom_pairs.npair)):
            raise ValueError("peers on scenes need one covering sphere per geom (bounding)")
        self.to_geom_pair = np.asarray(gp, dtype=np.int64)
        self.npairs = p.geom_pairs.npair
        self.dt = p.dt
        self.horizon = (1 + LATENCY) * p.dt
        cov = p.covering
        pairs = p.pairs
        self.sphere_accel = p.bounds.accel[cov.sphere_body]
        self.sphere_delta = p.bounds.vel_uncertainty[cov.sphere_body]
        self.radius = np.asarray(cov.sphere_radius, dtype=np.float64)
        self.nsphere = int(cov.nsphere)
        ss = ~pairs.halfspace
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


class _DuaScene:
    name = "DUA"
    note = "Predictor.step (fused rigid step, reads only the scheduled spheres)"

    def __init__(self, ctx: _SceneContext) -> None:
        self.ctx = ctx

    def _out(self, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        sched = self.ctx.predictor.scheduler
        assert sched is not None
        return self.ctx.to_geom_pair[ids], np.asarray(sched.interval[sched.bucket(ids)] + LATENCY)

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


class _SaScene:
    name = "SA(tau)"
    note = "tau of every active sphere pair every step"

    def __init__(self, ctx: _SceneContext) -> None:
        self.ctx = ctx
        self.sched: SelectAllScheduler | None = None

    def _tau(self, data: mujoco.MjData, ids: np.ndarray) -> np.ndarray:
        p = self.ctx.predictor
        c, v = p.sphere_states(data)
        return p.pairs.tau(ids, c, v, p.halfspaces(data))

    def start(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray | int]:
        tau0 = self._tau(data, np.arange(len(self.ctx.predictor.pairs)))
        self.sched = SelectAllScheduler(tau0, dt=self.ctx.dt, latency=LATENCY)
        return self.ctx.to_geom_pair[self.sched.initial_alarms], 1 + LATENCY

    def step(
        self, data: mujoco.MjData
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]:
        assert self.sched is not None
        ids = self.sched.select()
        alarms = self.sched.update(ids, self._tau(data, ids))
        return np.unique(self.ctx.to_geom_pair[alarms]), 1 + LATENCY, None, float(ids.size)


class _BroadphaseScene:
    """Swept spheres of the covering; candidates filtered to MuJoCo's active pairs."""

    def __init__(self, ctx: _SceneContext, kind: str) -> None:
        self.ctx = ctx
        self.name = kind
        self.note = "covering spheres inflated by reach over H; half-spaces tested directly"
        self.candidates = _BROADPHASES[kind]

    def _alarms(self, data: mujoco.MjData) -> tuple[np.ndarray, int]:
        ctx = self.ctx
        p = ctx.predictor
        c, v = p.sphere_states(data)
        reach = _reach(np.linalg.norm(v, axis=1), ctx.sphere_accel, ctx.sphere_delta, ctx.horizon)
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
            pairs = p.pairs
            normals, offsets = p.halfspaces(data)
            i = pairs.first[ctx.hs_ids]
            j = pairs.second[ctx.hs_ids]
            gap = np.einsum("ij,ij->i", normals[j], c[i]) - offsets[j] - pairs.eps[ctx.hs_ids]
            alarms.append(ctx.hs_ids[gap <= reach[i]])
        ids = np.concatenate(alarms)
        return np.unique(ctx.to_geom_pair[ids]), int(a.size + ctx.hs_ids.size)

    def start(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray | int]:
        return self._alarms(data)[0], 1 + LATENCY

    def step(
        self, data: mujoco.MjData
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]:
        alarms, cand = self._alarms(data)
        return alarms, 1 + LATENCY, None, float(cand)


class _MujocoScene:
    """``mj_collision`` on a copy of the scene's state: gap-inflated or speculative."""

    def __init__(self, ctx: _SceneContext, mode: str) -> None:
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
        # After mj_step, data.contact and geom_xpos describe the state *before* integration
        # while data.qpos is already the next one (SPEC section 6): copy the pre-step snapshot
        # so that these contacts and MuJoCo's own describe the same instant.
        qpos, qvel, mocap_pos, mocap_quat = self.snapshot
        d.qpos[:] = qpos
        d.qvel[:] = qvel
        d.mocap_pos[:] = mocap_pos
        d.mocap_quat[:] = mocap_quat
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_comVel(m, d)
        if self.mode == "gap":
            # Every point of geom g moves at most |v_c| + |w| rbound (v_c: the covering
            # sphere's centre velocity, mocap twists included).
            _, v = ctx.predictor.sphere_states(data)
            g = self.sphere_geom
            w = np.linalg.norm(np.asarray(data.cvel)[self.geom_body[g], :3], axis=1)
            speed = np.linalg.norm(v, axis=1) + w * self.rbound[g]
            gap = self.base_gap.copy()
            gap[g] += _reach(speed, ctx.sphere_accel, ctx.sphere_delta, ctx.horizon)
            m.geom_gap[:] = gap
        t0 = time.perf_counter()
        mujoco.mj_collision(m, d)
        self.collision_s = time.perf_counter() - t0
        nc = int(d.ncon)
        if nc == 0:
            return np.zeros(0, dtype=np.int64)
        gp = ctx.predictor.geom_pairs.indices_of(d.contact.geom1[:nc], d.contact.geom2[:nc])
        return np.unique(gp[gp >= 0])

    def start(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray | int]:
        return self._alarms(data), self.h_steps

    def step(
        self, data: mujoco.MjData
    ) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None, float | None]:
        return self._alarms(data), self.h_steps, None, None


def _make_scene_peer(name: str, ctx: _SceneContext) -> _ScenePeer:
    if name == "DUA":
        return _DuaScene(ctx)
    if name == "SA(tau)":
        return _SaScene(ctx)
    if name in _BROADPHASES:
        return _BroadphaseScene(ctx, name)
    if name == "MuJoCo gap":
        return _MujocoScene(ctx, "gap")
    if name == "MuJoCo speculative":
        return _MujocoScene(ctx, "speculative")
    raise ValueError(f"unknown scene peer {name!r}; choose from {SCENE_PEERS}")


def _run_scene(scene: str, steps: int, seed: int) -> list[SceneRow]:
    """All scene peers watch one rollout; MuJoCo's contacts are the ground truth."""
    from dua_mujoco.mj.scenes import SCENES, load_scene, make_controller

    model, data = load_scene(scene)
    ctx = _SceneContext(model, SCENES[scene].accel_hint)
    peers = [_make_scene_peer(name, ctx) for name in SCENE_PEERS]
    trackers = [_Tracker(ctx.npairs) for _ in peers]
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

    copies = [p for p in peers if isinstance(p, _MujocoScene)]

    def physics_step() -> None:
        controller(model, data)
        for peer in copies:
            peer.set_snapshot(data)
        mujoco.mj_step(model, data)

    # One mj_step so that kinematics and contacts describe one instant (see monitor.run).
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
            if isinstance(peer, _MujocoScene):
                dt = peer.collision_s
            times[idx].append(dt)
            if cand is not None:
                cands[idx].append(cand)
            n_alarms[idx] += int(alarms.size)
            tr.apply(k, alarms, h, evaluated)
    keys = _truth_keys(truth)
    rows = []
    for idx, (peer, tr) in enumerate(zip(peers, trackers, strict=True)):
        _, false, open_, judged = tr.judge(keys, steps)
        t = np.asarray(times[idx])
        rows.append(
            SceneRow(
                scene=scene,
                peer=peer.name,
                pairs=ctx.npairs,
                steps=steps,
                time_us=float(np.median(t) * 1e6),
                time_us_p90=float(np.percentile(t, 90) * 1e6),
                candidates_per_step=float(np.mean(cands[idx])) if cands[idx] else None,
                alarms_per_step=n_alarms[idx] / steps,
                initial_alarms=tr.initial,
                onsets=tr.onsets,
                missed=tr.missed,
                false_alarms=false,
                open_alarms=open_,
                judged_alarms=judged,
                lead_time_mean_s=tr.lead_mean(ctx.dt),
                note=peer.note,
            )
        )
    return rows


# --------------------------------------------------------------------------- speculative demo

_TUNNEL_RADIUS = 0.01
_TUNNEL_HALF_THICKNESS = 0.002
_TUNNEL_DT = 0.002
_TUNNEL_HALF_WIDTH = 0.05


def _tunnel_model(clearance: float, speculative: bool) -> mujoco.MjModel:
    """A free sphere at the origin and a thin static plate ahead of it along +x (no gravity)."""
    spec = mujoco.MjSpec()
    spec.option.gravity = [0.0, 0.0, 0.0]
    spec.option.timestep = _TUNNEL_DT
    plate_x = _TUNNEL_RADIUS + clearance + _TUNNEL_HALF_THICKNESS
    spec.worldbody.add_geom(
        name="plate",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        pos=[plate_x, 0.0, 0.0],
        size=[_TUNNEL_HALF_THICKNESS, _TUNNEL_HALF_WIDTH, _TUNNEL_HALF_WIDTH],
    )
    body = spec.worldbody.add_body(name="ball")
    body.add_freejoint()
    body.add_geom(
        name="ball", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[_TUNNEL_RADIUS, 0, 0], mass=0.1
    )
    model = spec.compile()
    if speculative:
        model.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_SPECULATIVE)
    return model


def _tunnel_case(case: str, accel: float, speed0: float, clearance: float) -> TunnelRow:
    """Drive the sphere at the plate with and without speculative contacts; run DUA alongside.

    The push (a constant applied force) stops at the first contact, so a detected impact ends
    with the sphere stopped; "tunneled" means no contact was ever generated and the sphere ended
    beyond the plate, "penetrated" that a contact came too late to stop it.

    Instants: after ``mj_step`` number ``k``, ``qpos`` is instant ``k`` while ``geom_xpos`` and the
    contacts are instant ``k - 1`` (SPEC section 6), so an alarm returned there is from instant
    ``k - 1``. The sphere reaches the plate during step ``crossing`` (between instants
    ``crossing - 1`` and ``crossing``); an alarm is in time if its instant is ``< crossing``.
    """
    from dua_mujoco.mj.predictor import Predictor

    far_face = _TUNNEL_RADIUS + clearance + 2 * _TUNNEL_HALF_THICKNESS
    near_face = _TUNNEL_RADIUS + clearance
    steps = 400
    outcomes = []
    first_contact = -1
    crossing = -1
    dua_instant = -1
    for speculative in (False, True):
        model = _tunnel_model(clearance, speculative)
        data = mujoco.MjData(model)
        body = model.body("ball").id
        data.qvel[0] = speed0
        data.xfrc_applied[body, 0] = accel * float(model.body_mass[body])
        mujoco.mj_forward(model, data)
        predictor = None
        if not speculative:
            # Exact bound: the only force is the applied one until contact.
            # Multi-sphere covering: the plate's single bounding sphere (radius 71 mm) would
            # swallow the ball and alarm from the first instant.
            predictor = Predictor(
                model,
                accel=accel * 1.000001 + 1e-9,
                latency=LATENCY,
                covering="multi",
                max_spheres_per_geom=64,
            )
            if len(predictor.reset(data)):
                dua_instant = 0
        touched = False
        for k in range(1, steps + 1):
            mujoco.mj_step(model, data)
            if predictor is not None:
                alarms = predictor.step(data)
                if dua_instant < 0 and len(alarms):
                    dua_instant = k - 1
            x = float(data.qpos[0])
            if not speculative and crossing < 0 and x + _TUNNEL_RADIUS >= near_face:
                crossing = k
            if int(data.ncon) > 0:
                if not touched:
                    data.xfrc_applied[body, 0] = 0.0  # the push ends at impact
                touched = True
                if speculative and first_contact < 0:
                    first_contact = k
            if x - _TUNNEL_RADIUS > far_face:
                break
        beyond = float(data.qpos[0]) - _TUNNEL_RADIUS > far_face
        outcomes.append("stopped" if not beyond else ("penetrated" if touched else "tunneled"))
    lead = None
    if 0 <= dua_instant < crossing:
        lead = (crossing - dua_instant) * _TUNNEL_DT
    return TunnelRow(
        case=case,
        accel=accel,
        speed0=speed0,
        clearance=clearance,
        crossing_step=crossing,
        plain=outcomes[0],
        speculative=outcomes[1],
        speculative_contact_step=first_contact,
        dua_alarm_step=dua_instant,
        dua_lead_s=lead,
    )


def _tunnel_cases() -> list[TunnelRow]:
    h = _TUNNEL_DT
    thick = 2 * _TUNNEL_RADIUS + 2 * _TUNNEL_HALF_THICKNESS  # 24 mm to jump over
    return [
        _tunnel_case("slow, constant speed", 0.0, 0.5, 0.05),
        _tunnel_case("fast, constant speed (3 x thickness per step)", 0.0, 3 * thick / h, 0.05),
        # From rest: first-step displacement a h^2 jumps clearance + thickness.
        _tunnel_case("from rest, one-step jump", 2 * (0.005 + thick) / h**2, 0.0, 0.005),
        # From rest, hard push: the velocity term lags a h^2 behind every step.
        _tunnel_case("from rest, a = 1e4 m/s^2, 0.5 m away", 1e4, 0.0, 0.5),
        _tunnel_case("from rest, a = 1e5 m/s^2", 1e5, 0.0, 0.2),
        _tunnel_case("moving 2 m/s, a = 1e5 m/s^2", 1e5, 2.0, 0.05),
    ]


def _tunnel_sweep(accels: Sequence[float], clearances: Sequence[float]) -> list[dict[str, Any]]:
    """Fraction of starts (at rest) that tunnel, per acceleration, over a range of clearances."""
    out = []
    for a in accels:
        rows = [_tunnel_case("sweep", a, 0.0, g) for g in clearances]
        out.append(
            {
                "accel": a,
                "starts": len(rows),
                "plain_tunneled": sum(r.plain == "tunneled" for r in rows),
                "plain_penetrated": sum(r.plain == "penetrated" for r in rows),
                "speculative_tunneled": sum(r.speculative == "tunneled" for r in rows),
                "speculative_penetrated": sum(r.speculative == "penetrated" for r in rows),
                "dua_alarmed_before_crossing": sum(
                    0 <= r.dua_alarm_step < r.crossing_step for r in rows
                ),
            }
        )
    return out


# --------------------------------------------------------------------------- memory at large N


def _rss_mb(field: str = "VmRSS") -> float:
    """``VmRSS`` (current) or ``VmHWM`` (peak) of this process in MB, from /proc."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def _reset_peak_rss() -> bool:
    """Reset the kernel's peak-RSS counter (Linux ``clear_refs`` 5); False if not allowed."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        return False
    return True


def _memory_probe(peer: str, n: int) -> dict[str, Any]:
    """Build one peer's structures at ``n`` spheres in this process and measure them.

    Meant to run in a fresh subprocess (``python -c``) so that peak RSS belongs to one peer.
    The jitted kernels are compiled first on a tiny world (LLVM's memory is not the peer's);
    allocations are traced during the build and a few steps, then steps are timed without
    tracing (tracemalloc slows every numpy allocation down).
    """
    _single_thread()
    world = _record_ghost(n, 6, 0, seed=0)
    c, v = world.positions, world.velocities
    tiny = _record_ghost(8, 2, 0, seed=0)
    warm = _make_ghost_peer(peer, tiny)
    warm.start(tiny.positions[0], tiny.velocities[0])
    warm.step(tiny.positions[1], tiny.velocities[1])
    del warm
    reset = _reset_peak_rss()
    base_rss = _rss_mb()
    tracemalloc.start()
    t0 = time.perf_counter()
    p = _make_ghost_peer(peer, world)
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
    peak_rss = _rss_mb("VmHWM") if reset else _rss_mb()
    return {
        "peer": peer,
        "n": n,
        "pairs": n * (n - 1) // 2,
        "traced_mb": peak / 2**20,
        "rss_mb": peak_rss - base_rss,
        "build_s": build,
        "step_us": float(np.median(times) * 1e6),
        "peak_reset": reset,
    }


def _memory_row(peer: str, n: int) -> MemoryRow:
    code = (
        "import json, sys\n"
        "from dua_mujoco.experiments.peers import _memory_probe\n"
        f"print(json.dumps(_memory_probe({peer!r}, {n})))\n"
    )
    env = dict(os.environ)
    root = str(Path(__file__).resolve().parents[2])
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
        note += " (peak RSS could not be reset: RSS growth is the current RSS)"
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


# --------------------------------------------------------------------------- orchestration


def _single_thread() -> int:
    """Run numba kernels on one thread; returns the previous thread count.

    Every other peer is single-threaded, and numba's thread pool collapses when the machine is
    oversubscribed (a barrier per call), so one thread is the fair and the reproducible choice.
    """
    import numba

    previous = int(numba.get_num_threads())
    numba.set_num_threads(1)
    return previous


@dataclass(frozen=True)
class _Plan:
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


def _plan(quick: bool) -> _Plan:
    if quick:
        return _Plan(
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
    return _Plan(
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


def run_peers(
    *,
    quick: bool = False,
    out_dir: Path | None = None,
    json_path: Path | None = None,
    progress: bool = True,
    sizes: Sequence[int] | None = None,
    steps: int | None = None,
    scenes: Sequence[str] | None = None,
    scene_steps: int | None = None,
    memory: bool = True,
    seed: int = 0,
) -> dict[str, Any]:
    """Measure DUA against its peers; write ``peers.md``, plots and JSON.

    Args:
        quick: Small sizes and short runs (under two minutes).
        out_dir: Folder for ``peers.md``, ``peers.json`` and ``peers_*.png`` (None: write nothing
            there).
        json_path: Also write the JSON here.
        progress: Draw a progress line on stderr.
        sizes: Override the ghost-world sphere counts.
        steps: Override the ghost-world predictor steps.
        scenes: Override the bundled scenes (empty: none).
        scene_steps: Override the physics steps per scene.
        memory: Run the large-N memory probes (subprocesses).
        seed: Seed of the worlds and controls.

    Returns:
        A JSON-ready dict with ``ghost``, ``scenes``, ``memory``, ``tunnel``, ``tunnel_sweep``
        (lists of row dicts), ``meta`` and ``runtime_s``.
    """
    start = time.perf_counter()
    load_before = os.getloadavg()
    threads = _single_thread()
    try:
        result = _run(quick, progress, sizes, steps, scenes, scene_steps, memory, seed)
    finally:
        import numba

        numba.set_num_threads(threads)
    result["meta"]["load_average"] = [load_before[0], os.getloadavg()[0]]
    result["runtime_s"] = time.perf_counter() - start
    result = _jsonable(result)
    if out_dir is not None:
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / "peers.json").write_text(json.dumps(result, indent=2))
        (out_dir / "peers.md").write_text(markdown(result))
        _plots(result, out_dir)
    if json_path is not None:
        json_path = Path(json_path)
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(result, indent=2))
    return result


def _run(
    quick: bool,
    progress: bool,
    sizes: Sequence[int] | None,
    steps: int | None,
    scenes: Sequence[str] | None,
    scene_steps: int | None,
    memory: bool,
    seed: int,
) -> dict[str, Any]:
    plan = _plan(quick)
    sizes = tuple(sizes) if sizes is not None else plan.sizes
    steps = int(steps) if steps is not None else plan.steps
    extra = plan.extra if steps == plan.steps else steps
    scene_list = tuple(scenes) if scenes is not None else plan.scenes
    scene_steps = int(scene_steps) if scene_steps is not None else plan.scene_steps
    has_fcl = fcl_available()
    ghost_peers = [p for p in GHOST_PEERS if p != "FCL" or has_fcl]
    notes = []
    if not has_fcl:
        notes.append("python-fcl is not installed (pip install python-fcl): FCL rows skipped.")
    units = len(sizes) * len(ghost_peers) + len(scene_list) + 2
    if memory:
        units += len(plan.memory_peers)
    ghost_rows: list[GhostRow] = []
    scene_rows: list[SceneRow] = []
    memory_rows: list[MemoryRow] = []
    with Progress(units, "peers", enabled=progress) as bar:
        for n in sizes:
            world = _record_ghost(n, steps, extra, seed)
            truth_steps = _ghost_truth(world)
            onsets = _onsets_by_step(truth_steps[: steps + 1])
            keys = _truth_keys(truth_steps)
            for name in ghost_peers:
                bar.update(0, note=f"N={n} {name}")
                if name == "SA(tau)" and n > plan.sa_max_n:
                    bar.update()
                    continue
                ghost_rows.append(_run_ghost_peer(name, world, steps, onsets, keys))
                bar.update(note=f"N={n} {name}")
        for scene in scene_list:
            bar.update(0, note=f"scene {scene}")
            scene_rows.extend(_run_scene(scene, scene_steps, seed))
            bar.update(note=f"scene {scene}")
        bar.update(0, note="speculative demo")
        tunnel = _tunnel_cases()
        bar.update()
        sweep = _tunnel_sweep(plan.tunnel_accels, plan.tunnel_clearances)
        bar.update()
        if memory:
            for peer in plan.memory_peers:
                if peer == "FCL" and not has_fcl:
                    bar.update()
                    continue
                bar.update(0, note=f"memory N={plan.memory_n} {peer}")
                memory_rows.append(_memory_row(peer, plan.memory_n))
                bar.update()
    result: dict[str, Any] = {
        "meta": {
            "quick": quick,
            "latency": LATENCY,
            "ghost_steps": steps,
            "ghost_truth_steps": steps + extra,
            "scene_steps": scene_steps,
            "seed": seed,
            "density": "paper's: 40 spheres per unit volume; box = (N/40)^(1/3)",
            "mujoco": mujoco.__version__,
            "fcl": has_fcl,
            "cpus": os.cpu_count(),
            "numba_threads": 1,
            "notes": notes,
        },
        "ghost": [asdict(r) for r in ghost_rows],
        "scenes": [asdict(r) for r in scene_rows],
        "memory": [asdict(r) for r in memory_rows],
        "tunnel": [asdict(r) for r in tunnel],
        "tunnel_sweep": sweep,
    }
    return result


def _jsonable(x: Any) -> Any:
    """NaN and inf become None so the JSON is strict."""
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, np.generic):
        return _jsonable(x.item())
    return x


# --------------------------------------------------------------------------- reporting


def _fmt(x: Any, digits: int = 1) -> str:
    if x is None:
        return "n/a"
    if isinstance(x, float):
        if abs(x) >= 1e5:
            return f"{x:.3g}"
        return f"{x:.{digits}f}"
    return str(x)


def _table(header: Sequence[str], body: Sequence[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(row) + " |" for row in body]
    return "\n".join(lines)


def _lead_ms(x: float | None) -> str:
    return "n/a" if x is None else f"{x * 1e3:.0f}"


# The columns shared by the ghost-world and scene tables (GhostRow / SceneRow fields).
_PEER_HEADER = (
    "peer",
    "us/step",
    "candidates/step",
    "alarms/step",
    "initial alarms",
    "onsets",
    "missed",
    "false",
    "open",
    "lead ms",
)


def _peer_cells(r: dict[str, Any]) -> list[str]:
    """The ``_PEER_HEADER`` cells of one ``GhostRow`` or ``SceneRow`` (as a JSON dict)."""
    return [
        r["peer"],
        _fmt(r["time_us"]),
        _fmt(r["candidates_per_step"]),
        _fmt(r["alarms_per_step"], 2),
        str(r["initial_alarms"]),
        str(r["onsets"]),
        str(r["missed"]),
        str(r["false_alarms"]),
        str(r["open_alarms"]),
        _lead_ms(r["lead_time_mean_s"]),
    ]


def markdown(result: dict[str, Any]) -> str:
    """The tables of a :func:`run_peers` result as markdown."""
    meta = result["meta"]
    out = [
        "# DUA against its peers",
        "",
        f"Run: {'quick' if meta['quick'] else 'full'}, latency {meta['latency']}, "
        f"MuJoCo {meta['mujoco']}, {meta['cpus']} CPUs (every peer on one thread; load average "
        f"{meta['load_average'][0]:.1f} -> {meta['load_average'][1]:.1f}), "
        f"{result['runtime_s']:.0f} s.",
        "",
    ]
    out += [f"Note: {n}" for n in meta["notes"]]
    out += [
        "## Ghost world (SphereWorld, the paper's density)",
        "",
        f"{meta['ghost_steps']} predictor steps of 10 ms; alarms judged on "
        f"{meta['ghost_truth_steps']} recorded steps. Time: median per step (us). "
        "Candidates: pair evaluations (DUA, SA) or broadphase candidates per step. Initial alarms: "
        "those of the step-0 classification (not judged). False / open: alarms of steps >= 1 with "
        "no collision within their horizon / horizon past the recording.",
        "",
    ]
    body = [[str(r["n"]), *_peer_cells(r)] for r in result["ghost"]]
    out.append(_table(["N", *_PEER_HEADER], body))
    if result["scenes"]:
        out += [
            "",
            "## Bundled MuJoCo scenes",
            "",
            f"{meta['scene_steps']} physics steps, random controls; units are active geom pairs; "
            "ground truth: MuJoCo's contacts. Bounds: each scene's accel hint.",
            "",
        ]
        body = [[r["scene"], *_peer_cells(r)] for r in result["scenes"]]
        out.append(_table(["scene", *_PEER_HEADER], body))
    if result["memory"]:
        n = result["memory"][0]["n"]
        out += ["", f"## Memory at N = {n}", ""]
        body = [
            [
                r["peer"],
                str(r["pairs"]),
                _fmt(r["traced_mb"]),
                _fmt(r["rss_mb"]),
                _fmt(r["build_s"], 2),
                _fmt(r["step_us"]),
                r["note"],
            ]
            for r in result["memory"]
        ]
        out.append(
            _table(
                ["peer", "pairs", "traced MB", "peak RSS growth MB", "build s", "us/step", "what"],
                body,
            )
        )
    out += [
        "",
        "## Speculative contacts: a sphere driven at a 4 mm plate",
        "",
        f"Sphere radius {_TUNNEL_RADIUS * 1e3:.0f} mm, plate {2 * _TUNNEL_HALF_THICKNESS * 1e3:.0f}"
        f" mm thick ({2 * _TUNNEL_HALF_WIDTH * 1e3:.0f} mm square), timestep "
        f"{_TUNNEL_DT * 1e3:.0f} ms, constant push along +x until the first contact, gravity off. "
        "DUA (multi-sphere covering, exact acceleration bound, latency 1) watches the plain "
        "simulation; its alarm instant must precede the step during which the sphere reaches "
        "the plate.",
        "",
    ]
    body = [
        [
            r["case"],
            _fmt(r["accel"], 0),
            _fmt(r["speed0"], 2),
            _fmt(r["clearance"] * 1e3, 1),
            str(r["crossing_step"]),
            r["plain"],
            r["speculative"],
            str(r["speculative_contact_step"]),
            str(r["dua_alarm_step"]),
            _lead_ms(r["dua_lead_s"]),
        ]
        for r in result["tunnel"]
    ]
    out.append(
        _table(
            [
                "case",
                "a m/s^2",
                "v0 m/s",
                "clearance mm",
                "reaches plate at step",
                "plain",
                "speculative",
                "spec. contact step",
                "DUA alarm step",
                "DUA lead ms",
            ],
            body,
        )
    )
    out += ["", "Starts from rest over a range of clearances:", ""]
    body = [
        [
            _fmt(s["accel"], 0),
            str(s["starts"]),
            f"{s['plain_tunneled']} / {s['plain_penetrated']}",
            f"{s['speculative_tunneled']} / {s['speculative_penetrated']}",
            str(s["dua_alarmed_before_crossing"]),
        ]
        for s in result["tunnel_sweep"]
    ]
    out.append(
        _table(
            [
                "a m/s^2",
                "starts",
                "plain: tunneled / penetrated",
                "speculative: tunneled / penetrated",
                "DUA alarmed before reaching the plate",
            ],
            body,
        )
    )
    return "\n".join(out) + "\n"


def _plots(result: dict[str, Any], out_dir: Path) -> None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # plots are optional
        return
    rows = result["ghost"]
    peers = list(dict.fromkeys(r["peer"] for r in rows))
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for p in peers:
        pts = [(r["n"], r["time_us"]) for r in rows if r["peer"] == p]
        if pts:
            x, y = zip(*pts, strict=True)
            ax.loglog(x, y, marker="o", label=p)
    ax.set_xlabel("spheres N")
    ax.set_ylabel("median time per step (us)")
    ax.set_title("Time per step, ghost world")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_dir / "peers_time.png", dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for p in peers:
        pts = [
            (r["n"], (r["false_alarms"] + r["open_alarms"]) / r["steps"])
            for r in rows
            if r["peer"] == p
        ]
        if pts:
            x, y = zip(*pts, strict=True)
            ax.loglog(x, np.maximum(y, 1e-3), marker="o", label=p)
    ax.set_xlabel("spheres N")
    ax.set_ylabel("false (+ open) alarms per step")
    ax.set_title("False alarms, ghost world (floor 1e-3 = none)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_dir / "peers_false_alarms.png", dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for p in peers:
        pts = [(r["n"], r["candidates_per_step"]) for r in rows if r["peer"] == p]
        pts = [(x, y) for x, y in pts if y is not None]
        if pts:
            x, y = zip(*pts, strict=True)
            ax.loglog(x, y, marker="o", label=p)
    ax.set_xlabel("spheres N")
    ax.set_ylabel("pair evaluations / candidates per step")
    ax.set_title("Work per step, ghost world")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_dir / "peers_candidates.png", dpi=110)
    plt.close(fig)


# --------------------------------------------------------------------------- CLI


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``dua-mujoco peers``."""
    parser.add_argument("--quick", action="store_true", help="small run (< 2 min)")
    parser.add_argument("--json", type=Path, default=None, metavar="PATH", help="write JSON here")
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("out/peers"),
        metavar="DIR",
        help="folder for peers.md, peers.json and plots (default out/peers)",
    )
    parser.add_argument("--no-memory", action="store_true", help="skip the large-N memory probes")
    parser.add_argument("--no-progress", action="store_true", help="no progress line on stderr")


def main(args: argparse.Namespace) -> int:
    """Run ``dua-mujoco peers``; prints the markdown tables. Returns the exit code."""
    result = run_peers(
        quick=bool(args.quick),
        out_dir=args.out,
        json_path=args.json,
        progress=not args.no_progress,
        memory=not getattr(args, "no_memory", False),
    )
    print(markdown(result))
    if args.out is not None:
        print(f"tables, plots and JSON written to {args.out}")
    bad = [r for r in result["ghost"] if r["peer"] in COMPLETE_PEERS and r["missed"]]
    if bad:
        print(f"warning: complete peers missed collisions: {bad}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":  # pragma: no cover
    _parser = argparse.ArgumentParser(prog="python -m dua_mujoco.experiments.peers")
    add_arguments(_parser)
    raise SystemExit(main(_parser.parse_args()))
