"""DUA against its peers: the same worlds, the same metrics, one run.

Peers. Each is a *predictor*: at every step it looks at the current state and names the pairs
that may collide soon ("alarms"). All of them are complete under the same hypotheses as DUA
(bounded accelerations) except MuJoCo's speculative contacts, which extrapolate the pre-step
velocity over one step and ignore acceleration by design.

* ``DUA``: :class:`~dua_mujoco.DUAScheduler`, ``L = ceil(log2(M + 1))`` tau evaluations
  per step (fused ``step_points`` in the ghost world, :class:`~dua_mujoco.Predictor` on
  MuJoCo scenes).
* ``SA(tau)``: :class:`~dua_mujoco.SelectAllScheduler`, every pair every step.
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

Worlds. The ghost world is :class:`~dua_mujoco.SphereWorld` (exact kinematics, bounds hold
exactly) with the box grown as ``(N / 40)^(1/3)`` so that the density of the paper's 40-sphere
unit cube is kept at every N (a fixed cube at N = 2000 would be 23 % spheres by volume). The
bundled scenes run MuJoCo with random controls; MuJoCo's contacts are the ground truth there.

Run it with ``dua-mujoco peers [--quick] [--json PATH] [--out DIR]``; docs/peers.md discusses the
results. ``run_peers`` (``benchmark``) drives ``ghost`` and ``scene``; the peers live in
``schedulers``, ``broadphase``, ``mujoco_collision`` and ``fcl_tree``.
"""

from __future__ import annotations

from dua_mujoco.experiments.peers.benchmark import run_peers
from dua_mujoco.experiments.peers.candidates import grid_candidates, sweep_candidates
from dua_mujoco.experiments.peers.cli import add_arguments, main
from dua_mujoco.experiments.peers.fcl_tree import fcl_available
from dua_mujoco.experiments.peers.ghost import COMPLETE_PEERS, GHOST_PEERS
from dua_mujoco.experiments.peers.markdown import markdown
from dua_mujoco.experiments.peers.rows import GhostRow, MemoryRow, SceneRow, TunnelRow
from dua_mujoco.experiments.peers.scene import SCENE_PEERS

__all__ = [
    "COMPLETE_PEERS",
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
    "markdown",
    "run_peers",
    "sweep_candidates",
]
