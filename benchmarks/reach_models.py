"""Reach models against an exact-geometry reference: which reach can meet issue 34's targets.

    python benchmarks/reach_models.py --json out.json      # seven robots, 2000 steps, ~25 min
    python benchmarks/reach_models.py --robots panda go1 --steps 1000
    python benchmarks/reach_models.py --tables out.json    # the tables again, from saved runs

A design experiment, not the predictor: each reach model's floor, measured with exact geometry.
For each robot (``benchmarks/horizon.py``'s seven) one smooth-drive rollout (rollout seed 0, as
horizon.py) and one pilot driven the same way (pilot seed 1_000_003, 2,000 steps, as
``accel="auto"``); every bound below is the pilot's maximum times 2 (auto's safety factor),
measured at the predictor's bound points (``Predictor.bound_points``: the corners of one box a
body, so that a bound on an affine quantity of the motion holds for every point of the body's
geoms). At every physics step ``k`` of the rollout every active geom pair ``(A, B)`` (geoms on
bodies ``a``, ``b``) is judged with ``d = mj_geomDistance`` and ``cd`` the pair's contact
distance; over ``n`` steps, ``t = n h``, it *stands* when

- ``a``:     ``d - cd <= reach_A + reach_B``, ``reach = (|v_c| + |w| r + D) t + A h^2 n(n-1)/2``
  (``v_c`` the geom origin's velocity, ``w`` its body's, ``r`` the geom's radius about its origin
  as the exact level has it, ``D = delta + A h / 2`` the one-step discrepancy: this is exactly
  ``(|v_c| + |w| r + delta) t + A t^2 / 2``, today's reach);
- ``b``:     as ``a`` with each geom's reach capped at ``V t`` (``V`` the pilot's speed maxima,
  chord and reported velocity, every step, as ``estimate_bounds(with_speed=True)``);
- ``c_WH``:  as ``a`` with the second-order term ``min(A h^2 n(n-1)/2, W(n-1) t)``, ``W(s)`` the
  pilot's maximum of ``|u_{k+s} - u_k|`` over lags ``<= s`` (``u`` the chord velocity);
- ``c_int``: as ``c_WH`` with ``h sum_{j<n} W(j)`` (the integral form; it is what the displacement
  obeys: ``|c_{k+n} - c_k - n h w_k| <= n h D + h sum_{j<n} W(j)``);
- ``bc``:    ``c_int`` capped at ``V t`` per geom;
- ``d_a``:   the approach direction: ``min over n' <= n`` of ``d - cd + (n.(v_B - v_A) - |w_a| r_A
  - |w_b| r_B - D_a - D_b) t' - (A_a + A_b) h^2 n'(n'-1)/2 <= 0`` (``n`` the witness direction of
  ``mj_geomDistance``, A to B, ``v`` the geom origins' velocities: the exact level's bound);
- ``d_c``:   ``d_a`` with each body's second-order term ``min(A, W integral)`` as ``c_int``;
- ``e_a``:   relative bounds: ``d - cd <= (|v_B - v_A| + |w_a| r_A + |w_b| r_B + D_a + D_b) t +
  A_ab h^2 n(n-1)/2``, ``A_ab`` the pilot's maximum of ``|a_p - a_q|`` over bound points ``p`` of
  ``a`` and ``q`` of ``b`` (64 corner pairs; a static body's points do not move);
- ``e_c``:   ``e_a`` with ``min(A_ab ..., h sum_{j<n} W_ab(j))``, ``W_ab`` as ``W`` on the
  relative chord velocities ``u_p - u_q``, measured at the lags of :data:`REL_LAGS` and closed
  over the others by subadditivity (``W(s) <= W(s') + W(s - s')``);
- ``e_d``:   the approach direction (``d_a``'s first-order term) with ``e_c``'s second order;
- ``f_hold R=H``, ``f_hold R=H/4``: a flight plan: every ``R`` steps the ``MjData`` is copied
  (``mj_copyData``) and rolled ``R - 1 + n`` steps with ``ctrl`` held; the pair stands when at some
  plan step ``j`` in ``[k, k + n]`` the plan's distance less the two bodies' deviation bounds is
  within ``cd``: ``d_plan(j) - (E_a + E_b) h^2 m(m-1)/2 <= cd``, ``m = j - k0`` the plan's age and
  ``E`` the pilot's maximum second difference of the deviation ``x - x_plan`` over
  ``h^2`` (its plans: ctrl held, one every 20 steps, 200 steps long; a step counts as ``A``'s
  do, free in the rollout and in the plan, with auto's level fallback), times 2. ``R = H/4`` is
  tried from 50 ms on (:data:`QUARTER_FROM`);
- ``f_prof``: the same plans with the deviation bounded by the pilot's largest ``|x - x_plan|``
  at each plan age (every step), times 2, made monotone in the age;
- ``f_seg``: a plan that knows the command up to its next waypoint: a copy of the driver whose
  next random point continues the current segment; exact until the waypoint, then bounded by the
  pilot's largest deviation at each step past it (same plans), times 2 (the command a planner or
  an MPC holds, known for a while, then not);
- ``f_future``: the plan rolled with the drive's own future controls (a copy of the driver: the
  best case of a trajectory passed in). Checked bit-identical to the rollout (qpos, the first
  plans), and the pilot's deviation is then 0, so the plan is the rollout and the pair stands
  when ``min_{j in [k, k+n]} d(j) <= cd`` (the distance oracle);
- ``g`` (panda, ur5e, iiwa): ``a`` with ``A`` from the model (:func:`model_accel`), not the pilot;
  ``g_tau``: its actuator and gravity part alone (not a bound: the velocity products left out).

Every model's pair-steps are counted over the steps ``k`` whose window ``[k, k + n]`` lies in
the rollout (steps 0 to ``K - n``, step 0 the state after the first ``mj_step``, as
``rollout.run``). The oracle is the share of active pairs in MuJoCo's contacts at some step of
``[k, k + n]``. An onset is a pair entering the contacts; its lead under a model is how many
steps the pair had stood without a break up to it (0: missed). An onset with less lead than
``n`` steps is *at the start* when ``k < n``, *after a violation* when either body (the body pair
for ``e``) broke one of the model's hypotheses in the steps ``[k - n - (R - 1), k]``, else *held*
(a model with an onset held is unsound as measured). Hypotheses: ``A`` (the second difference),
``D`` (the discrepancy), ``V``, ``W`` at lags ``<= n``, ``W_ab`` at the grid lags ``<= n``, the
deviation bounds for plans, each body's ``A`` from the model for ``g``. Beside it, the share of
pair-steps whose verdict rests on a broken hypothesis (a break in ``[k - (R - 1), k + n]``): a
model whose bounds break often stands few pairs for no good reason.

Plan costs are counted, not timed (Python): ``(R - 1 + n) / R`` mj_steps a step, and the
``mj_geomDistance`` calls on plan states a step (a pair is asked only where a bounding-sphere
bound does not already put it beyond the deviation bound).
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from dua_mujoco.build.bounds import estimate_bounds, moving_bodies
from dua_mujoco.build.exact import GX_RADIUS
from dua_mujoco.build.kinematics import mjdata_frame, pack_spheres, sphere_states
from dua_mujoco.build.pilot_screen import MotionScreen, PilotMotion, level_maxima
from dua_mujoco.models.scenes import make_controller
from dua_mujoco.runtime.predictor import Predictor

sys.path.insert(0, str(Path(__file__).parent))
from bench import table
from horizon import ROBOT_NAMES, load

HORIZONS_MS = (10, 20, 50, 100, 200)
PILOT_SEED = 1_000_003
ROLLOUT_SEED = 0
PILOT_STEPS = 2000
SAFETY = 2.0
REL_LAGS = (1, 2, 3, 4, 5, 6, 8, 10, 12, 16, 20, 25, 32, 40, 50, 64, 80, 100)
"""Lags (steps) at which the pair bounds ``W_ab`` are measured (closed over the others)."""
PILOT_PLAN_EVERY = 20
PILOT_PLAN_LEN = 200
FUTURE_CHECKS = 3
"""Plans rolled with a copy of the driver and compared bit for bit with the rollout."""
FIXED_ARMS = ("panda", "ur5e", "iiwa")
MODELS = (
    "a",
    "b",
    "c_WH",
    "c_int",
    "bc",
    "d_a",
    "d_c",
    "e_a",
    "e_c",
    "e_d",
    "f_hold R=H",
    "f_hold R=H/4",
    "f_prof R=H",
    "f_prof R=H/4",
    "f_seg R=H",
    "f_seg R=H/4",
    "f_future",
    "g",
    "g_tau",
)
PLAN_KINDS = ("f_hold", "f_prof", "f_seg")
PLAN_ROLL = {"f_hold": "hold", "f_prof": "hold", "f_seg": "seg"}
_BIG = 1 << 30


QUARTER_FROM = 25
"""Plans refreshed every ``H/4`` are tried from this many steps on (50 ms): below, ``H/4`` is one
or two steps, a plan nearly every step."""


def _plan_periods(n: int) -> tuple[int, ...]:
    """The refresh periods tried for a horizon of ``n`` steps: ``H``, and ``H/4`` from 50 ms."""
    return (n, n // 4) if n >= QUARTER_FROM else (n,)


def _period(name: str, n: int) -> int | None:
    periods = _plan_periods(n)
    if name.endswith("R=H"):
        return periods[0]
    return periods[1] if len(periods) > 1 else None


# ----------------------------------------------------------------------------- geometry


@dataclass
class Robot:
    """A robot's pairs, bound points and the index arrays the measures use."""

    name: str
    m: mujoco.MjModel
    h: float
    g1: np.ndarray  # (P,) geoms of the active pairs
    g2: np.ndarray
    cd: np.ndarray  # (P,) contact distance
    b1: np.ndarray  # (P,) bodies
    b2: np.ndarray
    bp: np.ndarray  # (P,) body-pair index
    bp_bodies: np.ndarray  # (nbp, 2)
    pts: np.ndarray  # (npts, 8) packed bound points
    pts_body: np.ndarray  # (npts,)
    body_pts: np.ndarray  # (nbody, 8) point ids of each body (npts: a still point)
    geoms: np.ndarray  # (ngeom, 8) packed geom origins
    radius: np.ndarray  # (ngeom,) the exact level's radius about the origin
    moving: np.ndarray  # (nbody,) bool
    steps_n: tuple[int, ...]  # horizons in steps
    planes: list[tuple[np.ndarray, np.ndarray, np.ndarray]]  # (pair ids, plane geoms, others)
    unbounded: np.ndarray  # (P,) a height field or an SDF: no sphere bound

    @property
    def nbody(self) -> int:
        return int(self.m.nbody)


def robot(name: str) -> Robot:
    m = load(name)
    p = Predictor(m, accel=1.0)  # declared bounds: only its pairs and bound points are read
    assert p.exact is not None
    gp = p.geom_pairs
    g1 = np.asarray(gp.geom1, dtype=np.int64)
    g2 = np.asarray(gp.geom2, dtype=np.int64)
    gb = np.asarray(m.geom_bodyid, dtype=np.int64)
    b1, b2 = gb[g1], gb[g2]
    keys = np.stack([np.minimum(b1, b2), np.maximum(b1, b2)], axis=1)
    bp_bodies, bp = np.unique(keys, axis=0, return_inverse=True)
    pg, pb, po = p.bound_points
    pts = pack_spheres(pg, pb, po, m.body_rootid)
    pts_body = np.asarray(pb, dtype=np.int64)
    npts = pts_body.size
    body_pts = np.full((m.nbody, 8), npts, dtype=np.int64)
    moving = moving_bodies(m)
    for b in range(m.nbody):
        ids = np.flatnonzero(pts_body == b)
        if ids.size > 8:
            raise ValueError(f"{name}: body {b} has {ids.size} bound points, expected 8")
        if ids.size:
            body_pts[b] = np.resize(ids, 8)
        elif moving[b] and (np.isin(b, b1) or np.isin(b, b2)):
            raise ValueError(f"{name}: moving body {b} of a pair has no bound point")
    # Mocap trees move with their root's twist, which this benchmark does not track: they may
    # move the robot (fetch's gripper weld) but must carry no bound point and no pair's geom.
    mocap_tree = (np.asarray(m.body_mocapid) >= 0)[np.asarray(m.body_rootid)]
    if mocap_tree[pb].any() or mocap_tree[b1].any() or mocap_tree[b2].any():
        raise ValueError(f"{name}: a pair or a bound point on a mocap tree is not handled here")
    geoms = pack_spheres(np.arange(m.ngeom), gb, np.zeros((m.ngeom, 3)), m.body_rootid)
    h = float(m.opt.timestep)
    gt = np.asarray(m.geom_type)
    planes = []
    for side, other in ((g1, g2), (g2, g1)):
        ids = np.flatnonzero(gt[side] == int(mujoco.mjtGeom.mjGEOM_PLANE))
        if ids.size:
            planes.append((ids, side[ids], other[ids]))
    odd = [int(mujoco.mjtGeom.mjGEOM_HFIELD), int(mujoco.mjtGeom.mjGEOM_SDF)]
    return Robot(
        name=name,
        m=m,
        h=h,
        g1=g1,
        g2=g2,
        cd=np.asarray(gp.contact_distance, dtype=np.float64),
        b1=b1,
        b2=b2,
        bp=bp.reshape(-1),
        bp_bodies=bp_bodies,
        pts=pts,
        pts_body=pts_body,
        body_pts=body_pts,
        geoms=geoms,
        radius=np.asarray(p.exact.geoms[:, GX_RADIUS], dtype=np.float64),
        moving=moving,
        steps_n=tuple(round(1e-3 * ms / h) for ms in HORIZONS_MS),
        planes=planes,
        unbounded=np.isin(gt[g1], odd) | np.isin(gt[g2], odd),
    )


_TWIST: dict[int, np.ndarray] = {}


def _frame(r: Robot, d: mujoco.MjData) -> tuple[np.ndarray, ...]:
    tw = _TWIST.setdefault(r.nbody, np.zeros((r.nbody, 6)))
    return mjdata_frame(d, tw)


def points(r: Robot, d: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    """Bound points' positions and velocities ``(npts, 3)`` each (the kinematics kernel)."""
    return sphere_states(r.pts, _frame(r, d))


def positions(r: Robot, d: mujoco.MjData) -> np.ndarray:
    """Bound points' positions ``(npts, 3)`` (as :func:`points`, in numpy: the plans' reads)."""
    g = r.pts[:, 0].astype(np.int64)
    mat = d.geom_xmat[g].reshape(-1, 3, 3)
    return d.geom_xpos[g] + np.einsum("pij,pj->pi", mat, r.pts[:, 2:5])


def _per_body(r: Robot, values: np.ndarray) -> np.ndarray:
    """``(..., nbody)`` maxima over each body's points of ``(..., npts)`` values (0: none)."""
    pad = np.concatenate([values, np.zeros((*values.shape[:-1], 1))], axis=-1)
    return pad[..., r.body_pts].max(axis=-1)


def _per_body_pair(r: Robot, delta: np.ndarray) -> np.ndarray:
    """``(L, nbp)`` maxima of ``|delta_p - delta_q|`` over the corner pairs of each body pair,
    from ``(L, npts, 3)`` per-point vectors (a still point's vector is 0)."""
    pad = np.concatenate([delta, np.zeros((delta.shape[0], 1, 3))], axis=1)
    p = pad[:, r.body_pts[r.bp_bodies[:, 0]]]  # (L, nbp, 8, 3)
    q = pad[:, r.body_pts[r.bp_bodies[:, 1]]]
    x = p[:, :, :, None, :] - q[:, :, None, :, :]
    return np.sqrt(np.einsum("lbpqi,lbpqi->lbpq", x, x).max(axis=(2, 3)))


# ----------------------------------------------------------------------------- pilot


@dataclass
class Bounds:
    """The pilot's maxima times the safety factor, and what the reach models derive."""

    A: np.ndarray  # (nbody,) m/s^2
    D: np.ndarray  # (nbody,) one-step discrepancy, m/s
    V: np.ndarray  # (nbody,) m/s
    W: np.ndarray  # (nbody, S+1) m/s, monotone in the lag, W[:, 0] = 0
    Wab: np.ndarray  # (nbp, S+1) m/s, closed over the lags and monotone
    Wab_grid: np.ndarray  # (nbp, len(REL_LAGS)) measured at the grid lags
    E: np.ndarray  # (nbody,) deviation second difference over h^2 (ctrl held), m/s^2
    E_future: float  # the largest deviation with the driver's own future controls, m
    seg_bound: np.ndarray  # (nbody, L+1) 2 max |x - x_plan| by steps past the waypoint
    seg_early: float  # the largest deviation of segment plans before their waypoint, m
    dev_profile: np.ndarray  # (nbody, PILOT_PLAN_LEN + 1) max |x - x_plan| by plan age, m
    dev_bound: np.ndarray  # (nbody, PILOT_PLAN_LEN + 1) the profile times 2, monotone
    qvel_max: np.ndarray  # (nv,) the pilot's joint speeds (for g's velocity terms)
    seconds: float


def pilot(r: Robot) -> Bounds:
    """One pilot rollout measuring every bound (module docstring); its A, D, V are checked
    against ``estimate_bounds``'."""
    t0 = time.perf_counter()
    m, h = r.m, r.h
    S = max(r.steps_n)
    lags = np.arange(1, S + 1)
    rel = np.asarray(REL_LAGS, dtype=np.int64)
    assert rel.max() <= S
    ctrl = make_controller(m, "smooth", seed=PILOT_SEED)
    d = mujoco.MjData(m)
    mujoco.mj_resetData(m, d)
    mujoco.mj_forward(m, d)
    screen = MotionScreen(m)
    nb, nbp, npts = r.nbody, r.bp_bodies.shape[0], r.pts_body.size
    amax, dmax = np.zeros((3, nb)), np.zeros((3, nb))
    measured = np.zeros((3, nb), dtype=bool)
    vmax = np.zeros(nb)
    wmax = np.zeros((3, nb, S + 1))
    wmeas = np.zeros((3, nb, S + 1), dtype=bool)
    rmax = np.zeros((3, nbp, rel.size))
    rmeas = np.zeros((3, nbp, rel.size), dtype=bool)
    run_len = np.zeros((3, nb), dtype=np.int64)
    still = ~r.moving
    hist = np.zeros((S + 1, npts, 3))  # hist[i]: u of i steps ago (ring by roll)
    nhist = 0
    emax_future = 0.0
    prof = np.zeros((nb, PILOT_PLAN_LEN + 1))
    qvel_max = np.zeros(m.nv)
    seg_prof = np.zeros((nb, PILOT_PLAN_LEN + 1))
    seg_early = 0.0  # the largest deviation before the waypoint (0: the plan is exact there)
    plans: list[dict] = []
    emeas = np.zeros((3, nb), dtype=bool)
    emax = np.zeros((3, nb))
    plan_data = mujoco.MjData(m)
    prev_c = prev_w = prev_u = None
    for k in range(1, PILOT_STEPS + 1):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        qvel_max = np.maximum(qvel_max, np.abs(d.qvel))
        free, calm = screen.update(d)
        lv = np.stack([free, calm, np.ones(nb, dtype=bool)])
        c, w = points(r, d)
        cpos = positions(r, d)  # the plans' deviations compare like with like
        vmax = np.maximum(vmax, _per_body(r, np.linalg.norm(w, axis=1)))
        if prev_c is not None:
            u = (c - prev_c) / h
            vmax = np.maximum(vmax, _per_body(r, np.linalg.norm(u, axis=1)))
            if k >= 3 or not m.nmocap:  # as estimate_bounds: after the mocap tracker's third
                disc = _per_body(r, np.linalg.norm(u - prev_w, axis=1))
                dmax = np.maximum(dmax, np.where(lv, disc, 0.0))
            if prev_u is not None:
                acc = _per_body(r, np.linalg.norm(u - prev_u, axis=1)) / h
                amax = np.maximum(amax, np.where(lv, acc, 0.0))
                measured |= lv
                run_len = np.where(lv, run_len + 1, 0)
            hist = np.roll(hist, 1, axis=0)
            hist[0] = u
            nhist = min(nhist + 1, S + 1)
            if nhist >= 2:
                avail = nhist - 1
                delta = u[None] - hist[1 : avail + 1]  # (avail, npts, 3): lags 1..avail
                per = _per_body(r, np.linalg.norm(delta, axis=2))  # (avail, nb)
                valid = (run_len[:, :, None] >= lags[None, None, :avail]) | still[None, :, None]
                wmax[:, :, 1 : avail + 1] = np.maximum(
                    wmax[:, :, 1 : avail + 1], np.where(valid, per.T[None], 0.0)
                )
                wmeas[:, :, 1 : avail + 1] |= valid
                use = rel[rel <= avail]
                if use.size:
                    pr = _per_body_pair(r, delta[use - 1])  # (nuse, nbp)
                    rl = np.where(still[None], _BIG, run_len)  # a still body never breaks
                    both = np.minimum(rl[:, r.bp_bodies[:, 0]], rl[:, r.bp_bodies[:, 1]])
                    ok = both[:, :, None] >= use[None, None, :]
                    j = use.size
                    rmax[:, :, :j] = np.maximum(rmax[:, :, :j], np.where(ok, pr.T[None], 0.0))
                    rmeas[:, :, :j] |= ok
            prev_u = u
        # The deviation from plans: the actual points against the plan's at the same step.
        for plan in plans:
            age = k - plan["k0"]
            e = cpos - plan["c"][age]
            size = _per_body(r, np.linalg.norm(e, axis=1))
            if plan["kind"] == "hold":
                sd = _per_body(r, np.linalg.norm(e - 2.0 * plan["e1"] + plan["e2"], axis=1))
                sd /= h * h
                if age >= 2:
                    # Screened as auto screens A: free in the rollout and in the plan.
                    ok = lv & plan["lv"][age]
                    emax = np.maximum(emax, np.where(ok, sd, 0.0))
                    emeas |= ok
                else:
                    assert sd.max() == 0.0, "a plan's first step must be the rollout's"
                prof[:, age] = np.maximum(prof[:, age], size)
            elif plan["kind"] == "future":
                emax_future = max(emax_future, float(size.max()))
            else:
                q = age - plan["w"]
                if q <= 0:
                    seg_early = max(seg_early, float(size.max()))
                else:
                    seg_prof[:, q] = np.maximum(seg_prof[:, q], size)
            plan["e2"], plan["e1"] = plan["e1"], e
        plans = [p for p in plans if k - p["k0"] < PILOT_PLAN_LEN]
        if k % PILOT_PLAN_EVERY == 0 and k >= 2:
            kinds = ("hold", "seg", "future")[: 3 if k % (5 * PILOT_PLAN_EVERY) == 0 else 2]
            for kind in kinds:
                held = kind == "hold"
                plan = _plan(
                    r, ctrl, d, plan_data, kind, PILOT_PLAN_LEN, cpos,
                    screen if held else None, lv if held else None,
                )  # fmt: skip
                plans.append(plan | {"k0": k})
        prev_c, prev_w = c, w
    motion = PilotMotion.FREE
    A = np.where(r.moving, SAFETY * level_maxima(amax, measured, motion), 0.0)
    D = np.where(r.moving, SAFETY * level_maxima(dmax, measured, motion), 0.0)
    D = np.maximum(D, 0.5 * h * A)  # delta = max(D - A h / 2, 0), as MotionBounds keeps it
    V = np.where(r.moving, SAFETY * vmax, 0.0)
    W = np.zeros((nb, S + 1))
    for s in range(1, S + 1):
        W[:, s] = SAFETY * level_maxima(wmax[:, :, s], wmeas[:, :, s], motion)
    W = np.maximum.accumulate(np.where(r.moving[:, None], W, 0.0), axis=1)
    grid = np.zeros((nbp, rel.size))
    for i in range(rel.size):
        grid[:, i] = SAFETY * level_maxima(rmax[:, :, i], rmeas[:, :, i], motion)
    Wab = _close(grid, rel, S)
    # The reference for A, D, V: auto's own estimate at the same points (checked equal).
    ref = estimate_bounds(
        m,
        steps=PILOT_STEPS,
        seed=PILOT_SEED,
        safety=SAFETY,
        controller=_wrap(make_controller(m, "smooth", seed=PILOT_SEED)),
        spheres=(r.pts[:, 0].astype(np.int64), r.pts_body, r.pts[:, 2:5]),
        with_speed=True,
    )
    assert ref.speed is not None
    for name, mine, theirs in (("A", A, ref.accel), ("D", D, ref.discrepancy), ("V", V, ref.speed)):
        if not np.allclose(mine, theirs, rtol=1e-9, atol=1e-12):
            raise AssertionError(f"{r.name}: pilot {name} differs from estimate_bounds'")
    if not np.allclose(W[:, 1], A * h, rtol=1e-9, atol=1e-12):
        raise AssertionError(f"{r.name}: W(1) is not A h")
    return Bounds(
        A=A,
        D=D,
        V=V,
        W=W,
        Wab=Wab,
        Wab_grid=grid,
        E=np.where(r.moving, SAFETY * level_maxima(emax, emeas, motion), 0.0),
        E_future=SAFETY * emax_future,
        seg_bound=np.maximum.accumulate(
            np.where(r.moving[:, None], SAFETY * seg_prof, 0.0), axis=1
        ),
        seg_early=seg_early,
        dev_profile=prof,
        dev_bound=np.maximum.accumulate(np.where(r.moving[:, None], SAFETY * prof, 0.0), axis=1),
        qvel_max=qvel_max,
        seconds=time.perf_counter() - t0,
    )


def _wrap(ctrl):  # estimate_bounds passes its rng too
    def pilot_ctrl(m: mujoco.MjModel, d: mujoco.MjData, rng: np.random.Generator) -> None:
        ctrl(m, d)

    return pilot_ctrl


class _Continue:
    """A smooth drive's source of random points that continues the current segment instead."""

    def __init__(self, drive) -> None:
        self.drive = drive
        self.delta = drive._to - drive._from

    def uniform(self, low: np.ndarray, high: np.ndarray) -> np.ndarray:
        return self.drive._to + self.delta


def _plan_drive(ctrl, kind: str) -> tuple[Any, int]:
    """The drive of a plan of ``kind`` (None for ``"hold"``: the controls held) and the plan
    step (1-based) whose control is the first the next random point changes (``"seg"``: the
    drive's current segment continued past it; else never, ``_BIG``)."""
    if kind == "hold":
        return None, _BIG
    drive = copy.deepcopy(ctrl)
    if kind != "seg":
        return drive, _BIG
    drive.smooth.rng = _Continue(drive.smooth)
    s, hold = ctrl.smooth._step, ctrl.smooth.hold_steps
    first = s if s % hold == 0 else s + hold - s % hold
    return drive, first - s + 1


def _roll_plan(
    r: Robot, drive, d: mujoco.MjData, plan_data: mujoco.MjData, cp: np.ndarray
) -> Iterator[int]:
    """Roll a plan from ``d``'s state on ``plan_data`` under ``drive`` (None: the controls
    held), writing the bound points' positions at each age ``j >= 1`` into ``cp``
    ``(length+1, npts, 3)``; yields ``j`` once ``plan_data`` is at it."""
    m = r.m
    mujoco.mj_copyData(plan_data, m, d)
    for j in range(1, cp.shape[0]):
        if drive is not None:
            drive(m, plan_data)
        mujoco.mj_step(m, plan_data)
        cp[j] = positions(r, plan_data)
        yield j


def _plan(
    r: Robot,
    ctrl,
    d: mujoco.MjData,
    plan_data: mujoco.MjData,
    kind: str,
    length: int,
    c: np.ndarray,
    screen: MotionScreen | None = None,
    lv: np.ndarray | None = None,
) -> dict:
    """A plan from ``d``: ``"hold"`` (ctrl held), ``"seg"`` (the drive, its current segment
    continued past the next waypoint), ``"future"`` (a copy of the drive): the bound points'
    positions by age ``c`` ``(length+1, npts, 3)``, ``w`` the waypoint's age (seg), and with
    ``screen`` (the rollout's, copied) the pilot's levels along the plan ``lv``
    ``(length+1, 3, nb)`` (``lv``: the rollout's now)."""
    drive, w = _plan_drive(ctrl, kind)
    cp = np.empty((length + 1, r.pts_body.size, 3))
    cp[0] = c
    sc = None if screen is None else copy.deepcopy(screen)
    levels = np.ones((length + 1, 3, r.nbody), dtype=bool)
    if lv is not None:
        levels[0] = lv
    for j in _roll_plan(r, drive, d, plan_data, cp):
        if sc is not None:
            levels[j, 0], levels[j, 1] = sc.update(plan_data)
    zero = np.zeros_like(c)
    return {"kind": kind, "c": cp, "w": w, "e1": zero, "e2": zero, "lv": levels}


def _close(grid: np.ndarray, lags: np.ndarray, S: int) -> np.ndarray:
    """``(n, S+1)`` bounds at every lag from bounds at ``lags``: subadditive closure
    (``|u_t - u_{t-s}| <= |u_t - u_{t-a}| + |u_{t-a} - u_{t-s}|``), then monotone."""
    out = np.full((grid.shape[0], S + 1), np.inf)
    out[:, 0] = 0.0
    for s in range(1, S + 1):
        for i, a in enumerate(lags):
            if a > s:
                break
            out[:, s] = np.minimum(out[:, s], grid[:, i] + out[:, s - a])
    return np.maximum.accumulate(out, axis=1)


# ----------------------------------------------------------------------------- model bounds


def model_accel(r: Robot, qvel_bound: np.ndarray) -> dict[str, np.ndarray]:
    """``(nbody,)`` acceleration bounds of every bound point from the model (fixed-base arms):
    ``"g"`` the bound, ``"g_tau"`` its part without the velocity products (not a bound: what the
    torques alone allow).

    ``|qacc| <= |M^-1| |tau|`` with ``|M^-1|_2 <= 1 / min dof_armature`` (the armature is on
    M's diagonal and the rest of M is positive semi-definite) and ``tau`` bounded per dof by the
    actuators (``gear * gain * max|ctrlrange|``, clipped by ``forcerange`` and
    ``actuatorfrcrange``), gravity (each subtree body's weight times its farthest reach from the
    joint, over all configurations: the sum of the link offsets), damping and the velocity
    products (Coriolis, centrifugal), the last two from a joint speed bound ``qvel_bound``
    (the pilot's, times 2: the model alone gives none for motors); joint limits are left out as
    the pilot's free motion leaves them out. A point ``x`` then accelerates at most
    ``sum_i L_ix |qacc_i| + 2 Omega sum_i L_ix |qd_i|`` (``L_ix`` the reach from joint ``i`` to
    ``x``, ``Omega`` the sum of the joint speeds on its chain).
    """
    m = r.m
    if (np.asarray(m.jnt_type) == int(mujoco.mjtJoint.mjJNT_FREE)).any():
        raise ValueError(f"{r.name}: not a fixed-base arm")
    arm = np.asarray(m.dof_armature)
    if arm.min() <= 0:
        raise ValueError(f"{r.name}: a dof without armature")
    hinge = int(mujoco.mjtJoint.mjJNT_HINGE)
    if not (np.asarray(m.jnt_type) == hinge).all():
        raise ValueError(f"{r.name}: only hinge chains are handled")
    nv, nb = m.nv, m.nbody
    parent = np.asarray(m.body_parentid)
    dof_body = np.asarray(m.dof_bodyid)

    # Reach from the origin of body a to a point of its descendant b: the link offsets on the
    # path; from a joint anchor, plus |jnt_pos|.
    def chain(b: int) -> list[int]:
        out = []
        while b > 0:
            out.append(b)
            b = int(parent[b])
        return out

    link = np.linalg.norm(np.asarray(m.body_pos), axis=1)

    def reach(jb: int, b: int) -> float:  # from jb's origin to b's origin, b below jb
        total = 0.0
        while b != jb:
            total += link[b]
            b = int(parent[b])
        return total

    jpos = np.linalg.norm(np.asarray(m.jnt_pos), axis=1)
    dof_jnt = np.asarray(m.dof_jntid)
    below = [[b for b in range(nb) if int(dof_body[i]) in chain(b)] for i in range(nv)]
    # Actuator torques by dof.
    tau = np.zeros(nv)
    for a in range(m.nu):
        if int(m.actuator_trntype[a]) != int(mujoco.mjtTrn.mjTRN_JOINT):
            raise ValueError(f"{r.name}: actuator {a} is not on a joint")
        j = int(m.actuator_trnid[a, 0])
        lo, hi = m.actuator_ctrlrange[a] if m.actuator_ctrllimited[a] else (-np.inf, np.inf)
        force = abs(float(m.actuator_gainprm[a, 0])) * max(abs(lo), abs(hi))
        if m.actuator_forcelimited[a]:
            force = min(force, float(np.abs(m.actuator_forcerange[a]).max()))
        tau[int(m.jnt_dofadr[j])] += abs(float(m.actuator_gear[a, 0])) * force
    for j in range(m.njnt):
        if m.jnt_actfrclimited[j]:
            i = int(m.jnt_dofadr[j])
            tau[i] = min(tau[i], float(np.abs(m.jnt_actfrcrange[j]).max()))
    if not np.isfinite(tau).all():
        raise ValueError(f"{r.name}: an unlimited actuator")
    g = float(np.linalg.norm(m.opt.gravity))
    mass = np.asarray(m.body_mass)
    ipos = np.linalg.norm(np.asarray(m.body_ipos), axis=1)
    inertia = np.asarray(m.body_inertia).max(axis=1)
    qd = np.asarray(qvel_bound, dtype=np.float64)
    omega = np.array([sum(qd[i] for i in range(nv) if b in below[i]) for b in range(nb)])
    tau_vel = np.zeros(nv)
    for i in range(nv):
        jb = int(dof_body[i])
        anchor = jpos[dof_jnt[i]]
        for b in below[i]:
            lever = anchor + reach(jb, b) + ipos[b]
            # gravity, and the velocity-product force of the body's centre (and its spin).
            av = (
                2.0
                * omega[b]
                * sum(
                    qd[k] * (jpos[dof_jnt[k]] + reach(int(dof_body[k]), b) + ipos[b])
                    for k in range(nv)
                    if b in below[k]
                )
            )
            tau[i] += mass[b] * g * lever
            tau_vel[i] += mass[b] * av * lever + inertia[b] * omega[b] ** 2
        tau_vel[i] += float(m.dof_damping[i]) * qd[i]
    qacc_tau = np.linalg.norm(tau) / arm.min()
    qacc = np.linalg.norm(tau + tau_vel) / arm.min()
    out = np.zeros(nb)
    out_tau = np.zeros(nb)
    off = r.pts[:, 2:5]
    for p in range(r.pts_body.size):
        b = int(r.pts_body[p])
        if not r.moving[b]:
            continue
        geom = int(r.pts[p, 0])
        # |x - origin of its body|: the geom's offset plus the point's offset in it.
        px = float(np.linalg.norm(m.geom_pos[geom])) + float(np.linalg.norm(off[p]))
        levers = np.array(
            [
                jpos[dof_jnt[i]] + reach(int(dof_body[i]), b) + px if b in below[i] else 0.0
                for i in range(nv)
            ]
        )
        a = np.linalg.norm(levers) * qacc + 2.0 * omega[b] * float(levers @ qd)
        out[b] = max(out[b], a)
        out_tau[b] = max(out_tau[b], np.linalg.norm(levers) * qacc_tau)
    return {"g": out, "g_tau": out_tau}


# ----------------------------------------------------------------------------- rollout


@dataclass
class Record:
    """What the rollout measured, step by step (rows: steps 0..K)."""

    dist: np.ndarray  # (K+1, P) mj_geomDistance (a lower bound >= its cap when capped)
    vn: np.ndarray  # (K+1, P) n.(v_B - v_A), origins
    relv: np.ndarray  # (K+1, P) |v_B - v_A|
    spin: np.ndarray  # (K+1, P) |w_a| r_A + |w_b| r_B
    sp1: np.ndarray  # (K+1, P) |v_A| + |w_a| r_A
    sp2: np.ndarray
    contact: np.ndarray  # (K+1, P) bool
    acc: np.ndarray  # (K+1, nbody) max second difference / h over the body's points
    disc: np.ndarray  # (K+1, nbody) max |u_k - w_{k-1}|
    speed: np.ndarray  # (K+1, nbody) max(|u|, |w|)
    w_lag: np.ndarray  # (K+1, nbody) the least lag whose W is broken (_BIG: none)
    wab_lag: np.ndarray  # (K+1, nbp) the least grid lag whose W_ab is broken
    plan_min: dict[tuple[str, int, int], np.ndarray]  # (kind, n, R) -> (K+1, P) window min
    dev_break: dict[tuple[str, int], np.ndarray]  # (kind, R) -> (K+1, nbody) bound broken
    plan_queries: dict[tuple[str, int], np.ndarray]  # (rollout, R) -> geomDistance calls by age
    plan_steps: dict[tuple[str, int], int]  # (rollout, R) -> mj_step calls of plans
    plan_seconds: dict[tuple[str, int], float]
    step_seconds: float  # the rollout's mj_step, total
    future_identical: bool
    seconds: float


def _distances(
    r: Robot, d: mujoco.MjData, cap: np.ndarray, fromto: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, int]:
    """Pairs' distances where a sphere bound does not already put them beyond ``cap`` (there,
    the sphere bound, >= cap), witness directions (rows of zeros where none), and the number of
    ``mj_geomDistance`` calls."""
    xg = d.geom_xpos
    rb = r.m.geom_rbound
    lb = np.linalg.norm(xg[r.g2] - xg[r.g1], axis=1) - rb[r.g1] - rb[r.g2]
    # A plane's rbound is 0 (it is unbounded): the other ball's height above it instead.
    for plane, side, other in r.planes:
        normal_z = d.geom_xmat[side].reshape(-1, 3, 3)[:, :, 2]
        lb[plane] = np.einsum("pi,pi->p", normal_z, xg[other] - xg[side]) - rb[other]
    lb[r.unbounded] = -np.inf
    dist = lb.copy()
    normal = np.zeros((r.g1.size, 3))
    near = np.flatnonzero(lb <= cap)
    ft = np.zeros(6)
    m = r.m
    for i in near:
        dist[i] = mujoco.mj_geomDistance(m, d, int(r.g1[i]), int(r.g2[i]), float(cap[i]), ft)
        if fromto is not None:
            v = ft[3:] - ft[:3]
            norm = float(np.linalg.norm(v))
            if norm > 0.0:
                normal[i] = v / norm
            if dist[i] < 0.0:  # penetrating: the witness points cross
                normal[i] = -normal[i]
    return dist, normal, int(near.size)


def rollout(r: Robot, B: Bounds, steps: int, A_model: dict[str, np.ndarray] | None) -> Record:
    t_start = time.perf_counter()
    m, h = r.m, r.h
    P, nb, nbp = r.g1.size, r.nbody, r.bp_bodies.shape[0]
    S = max(r.steps_n)
    K = steps
    rec = {k: np.zeros((K + 1, P)) for k in ("dist", "vn", "relv", "spin", "sp1", "sp2")}
    contact = np.zeros((K + 1, P), dtype=bool)
    acc = np.zeros((K + 1, nb))
    disc = np.zeros((K + 1, nb))
    speed = np.zeros((K + 1, nb))
    w_lag = np.full((K + 1, nb), _BIG, dtype=np.int64)
    wab_lag = np.full((K + 1, nbp), _BIG, dtype=np.int64)
    rel = np.asarray(REL_LAGS, dtype=np.int64)
    # Plans: the periods R and the longest window each serves.
    uses: dict[int, int] = {}
    for n in r.steps_n:
        for R in _plan_periods(n):
            uses[R] = max(uses.get(R, 0), R - 1 + n)
    plan_min = {
        (kind, n, R): np.full((K + 1, P), np.inf)
        for kind in PLAN_KINDS
        for n in r.steps_n
        for R in _plan_periods(n)
    }
    dev_break = {(kind, R): np.zeros((K + 1, nb), dtype=bool) for kind in PLAN_KINDS for R in uses}
    uses = {(roll, R): length for roll in ("hold", "seg") for R, length in uses.items()}
    plan_queries = {key: np.zeros(length + 1, dtype=np.int64) for key, length in uses.items()}
    plan_steps = dict.fromkeys(uses, 0)
    plan_seconds = dict.fromkeys(uses, 0.0)
    Esum_pair = B.E[r.b1] + B.E[r.b2]
    plans: dict[tuple[str, int], dict] = {}
    plan_data = mujoco.MjData(m)
    Asum = B.A[r.b1] + B.A[r.b2]
    Dsum = B.D[r.b1] + B.D[r.b2]
    Aab = B.Wab[r.bp, 1] / h
    tN = S * h
    a2 = h * h * S * (S - 1) / 2
    ctrl = make_controller(m, "smooth", seed=ROLLOUT_SEED)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    future: list[tuple[int, np.ndarray]] = []  # (step, expected qpos)
    future_ok = True
    checks = 0
    hist = np.zeros((S + 1, r.pts_body.size, 3))
    nhist = 0
    prev_c = prev_w = prev_u = None
    step_s = 0.0
    gb = np.asarray(m.geom_bodyid)
    for k in range(0, K + 1):
        ctrl(m, d)
        t0 = time.perf_counter()
        mujoco.mj_step(m, d)
        step_s += time.perf_counter() - t0
        for item in [f for f in future if f[0] == k]:
            future_ok &= bool(np.array_equal(item[1], d.qpos))
        future = [f for f in future if f[0] > k]
        c, w = points(r, d)
        cpos = positions(r, d)  # the plans' deviations compare like with like
        _, vg = sphere_states(r.geoms, _frame(r, d))
        wb = np.linalg.norm(d.cvel[:, :3], axis=1)
        spin_g = wb[gb] * r.radius
        sp_g = np.linalg.norm(vg, axis=1) + spin_g
        # The largest threshold a non-plan model can use at the longest horizon.
        relv = np.linalg.norm(vg[r.g2] - vg[r.g1], axis=1)
        cap = r.cd + np.maximum(
            (sp_g[r.g1] + sp_g[r.g2] + Dsum) * tN + Asum * a2,
            (relv + spin_g[r.g1] + spin_g[r.g2] + Dsum) * tN + Aab * a2,
        )
        if A_model is not None:
            Am = A_model["g"][r.b1] + A_model["g"][r.b2]
            cap = np.maximum(cap, r.cd + (sp_g[r.g1] + sp_g[r.g2] + Am * h) * tN + Am * a2)
        cap = cap * (1.0 + 1e-9) + 1e-9
        dist, normal, _ = _distances(r, d, cap, np.zeros(6))
        rec["dist"][k] = dist
        rec["vn"][k] = np.einsum("pi,pi->p", normal, vg[r.g2] - vg[r.g1])
        rec["relv"][k] = relv
        rec["spin"][k] = spin_g[r.g1] + spin_g[r.g2]
        rec["sp1"][k] = sp_g[r.g1]
        rec["sp2"][k] = sp_g[r.g2]
        nc = int(d.ncon)
        if nc:
            ga = np.asarray(d.contact.geom1[:nc], dtype=np.int64)
            gbb = np.asarray(d.contact.geom2[:nc], dtype=np.int64)
            lo, hi = np.minimum(ga, gbb), np.maximum(ga, gbb)
            key = lo * m.ngeom + hi
            pk = r.g1 * m.ngeom + r.g2
            contact[k] = np.isin(pk, key)
        # The hypotheses, step by step.
        speed[k] = np.maximum(
            _per_body(r, np.linalg.norm(w, axis=1)),
            0.0 if prev_c is None else _per_body(r, np.linalg.norm((c - prev_c) / h, axis=1)),
        )
        if prev_c is not None:
            u = (c - prev_c) / h
            disc[k] = _per_body(r, np.linalg.norm(u - prev_w, axis=1))
            if prev_u is not None:
                acc[k] = _per_body(r, np.linalg.norm(u - prev_u, axis=1)) / h
            hist = np.roll(hist, 1, axis=0)
            hist[0] = u
            nhist = min(nhist + 1, S + 1)
            if nhist >= 2:
                avail = nhist - 1
                delta = u[None] - hist[1 : avail + 1]
                per = _per_body(r, np.linalg.norm(delta, axis=2))  # (avail, nb)
                broke = per > B.W[:, 1 : avail + 1].T * (1 + 1e-9) + 1e-12
                first_lag = np.where(broke.any(axis=0), broke.argmax(axis=0) + 1, _BIG)
                w_lag[k] = first_lag
                use = rel[rel <= avail]
                if use.size:
                    pr = _per_body_pair(r, delta[use - 1])
                    broke = pr > B.Wab_grid[:, : use.size].T * (1 + 1e-9) + 1e-12
                    wab_lag[k] = np.where(broke.any(axis=0), use[broke.argmax(axis=0)], _BIG)
            prev_u = u
        prev_c, prev_w = c, w
        # Plans: the deviation of the actual points, then new plans.
        for (roll, R), plan in plans.items():
            age = k - plan["k0"]
            e = cpos - plan["c"][age]
            size = _per_body(r, np.linalg.norm(e, axis=1))
            if roll == "hold":
                sd = _per_body(r, np.linalg.norm(e - 2.0 * plan["e1"] + plan["e2"], axis=1))
                dev_break[("f_hold", R)][k] = sd > B.E * h * h * (1 + 1e-9) + 1e-15
                dev_break[("f_prof", R)][k] = size > B.dev_bound[:, age] * (1 + 1e-9) + 1e-15
            else:
                q = max(age - plan["w"], 0)
                dev_break[("f_seg", R)][k] = size > B.seg_bound[:, q] * (1 + 1e-9) + 1e-15
            plan["e2"], plan["e1"] = plan["e1"], e
        for (roll, R), length in uses.items():
            if k % R:
                continue
            t0 = time.perf_counter()
            ages = np.arange(length + 1)
            drive, w = _plan_drive(ctrl, "hold" if roll == "hold" else "seg")
            if roll == "hold":
                devs = {
                    "f_hold": Esum_pair[None, :] * h * h * (ages * (ages - 1))[:, None] / 2,
                    "f_prof": (B.dev_bound[r.b1] + B.dev_bound[r.b2]).T[: length + 1],
                }
            else:
                q = np.maximum(ages - w, 0)
                devs = {"f_seg": (B.seg_bound[r.b1][:, q] + B.seg_bound[r.b2][:, q]).T}
            dev = np.max(np.stack(list(devs.values())), axis=0)
            pd = np.empty((length + 1, P))
            cp = np.empty((length + 1, r.pts_body.size, 3))
            cp[0] = cpos
            pd[0] = dist
            for j in _roll_plan(r, drive, d, plan_data, cp):
                capj = (r.cd + dev[j]) * (1 + 1e-9) + 1e-9
                pd[j], _, nq = _distances(r, plan_data, capj, None)
                plan_queries[(roll, R)][j] += nq
            plan_steps[(roll, R)] += length
            plan_seconds[(roll, R)] += time.perf_counter() - t0
            zero = np.zeros_like(c)
            plans[(roll, R)] = {
                "k0": k,
                "c": cp,
                "w": w,
                "e1": zero,
                "e2": zero,
                **{kind: pd - dv for kind, dv in devs.items()},
            }
        for (kind, n, R), out in plan_min.items():
            plan = plans[(PLAN_ROLL[kind], R)]
            age = k - plan["k0"]
            out[k] = plan[kind][age : age + n + 1].min(axis=0)
        # The future controls: a copy of the driver rolled on a copy of the data.
        if checks < FUTURE_CHECKS and k % 200 == 1:
            checks += 1
            mujoco.mj_copyData(plan_data, m, d)
            drive = copy.deepcopy(ctrl)
            for j in range(1, S + 1):
                drive(m, plan_data)
                mujoco.mj_step(m, plan_data)
                if j in (1, S // 2, S):
                    future.append((k + j, plan_data.qpos.copy()))
    return Record(
        dist=rec["dist"],
        vn=rec["vn"],
        relv=rec["relv"],
        spin=rec["spin"],
        sp1=rec["sp1"],
        sp2=rec["sp2"],
        contact=contact,
        acc=acc,
        disc=disc,
        speed=speed,
        w_lag=w_lag,
        wab_lag=wab_lag,
        plan_min=plan_min,
        dev_break=dev_break,
        plan_queries=plan_queries,
        plan_steps=plan_steps,
        plan_seconds=plan_seconds,
        step_seconds=step_s,
        future_identical=future_ok and checks > 0,
        seconds=time.perf_counter() - t_start,
    )


# ----------------------------------------------------------------------------- evaluation


def _aterm(A: np.ndarray, n: int, h: float) -> np.ndarray:
    return A * h * h * n * (n - 1) / 2


def _window_any(flags: np.ndarray, k: np.ndarray, lo: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Whether ``flags[lo..k, col]`` holds anywhere, per (k, lo, col)."""
    cs = np.concatenate([np.zeros((1, flags.shape[1]), dtype=np.int64), np.cumsum(flags, axis=0)])
    return (cs[k + 1, cols] - cs[lo, cols]) > 0


def standing(
    name: str, r: Robot, B: Bounds, rec: Record, n: int, A_model: dict[str, np.ndarray] | None
) -> np.ndarray:
    """``(K+1, P)`` bool: the pairs model ``name`` stands at each step over ``n`` steps."""
    h, t = r.h, n * r.h
    b1, b2, bp = r.b1, r.b2, r.bp
    gap = rec.dist - r.cd
    F1 = (rec.sp1 + B.D[b1]) * t
    F2 = (rec.sp2 + B.D[b2]) * t
    Dsum = B.D[b1] + B.D[b2]
    Wint = np.concatenate([np.zeros((B.W.shape[0], 1)), r.h * np.cumsum(B.W, axis=1)], axis=1)
    Wab_int = np.concatenate(
        [np.zeros((B.Wab.shape[0], 1)), r.h * np.cumsum(B.Wab, axis=1)], axis=1
    )
    Aab = B.Wab[:, 1] / h

    def second(b: np.ndarray, nn: int, kind: str) -> np.ndarray:
        a = _aterm(B.A[b], nn, h)
        if kind == "a":
            return a
        if kind == "WH":
            return np.minimum(a, B.W[b, max(nn - 1, 0)] * nn * h)
        return np.minimum(a, Wint[b, nn])

    def directional(pair_second) -> np.ndarray:
        rate = rec.vn - rec.spin - Dsum
        best = gap.copy()
        for nn in range(1, n + 1):
            np.minimum(best, gap + rate * nn * h - pair_second(nn), out=best)
        return best <= 0.0

    # Each body's reach by its second-order term (a, WH, int), summed, capped by the speed
    # bound, or along the pair's direction.
    summed = {"a": "a", "c_WH": "WH", "c_int": "int"}
    capped, along = {"b": "a", "bc": "int"}, {"d_a": "a", "d_c": "int"}
    if name in summed:
        return gap <= F1 + second(b1, n, summed[name]) + F2 + second(b2, n, summed[name])
    if name in capped:
        m = capped[name]
        return gap <= np.minimum(F1 + second(b1, n, m), B.V[b1] * t) + np.minimum(
            F2 + second(b2, n, m), B.V[b2] * t
        )
    if name in along:
        return directional(lambda nn: second(b1, nn, along[name]) + second(b2, nn, along[name]))
    first_rel = (rec.relv + rec.spin + Dsum) * t
    if name == "e_a":
        return gap <= first_rel + _aterm(Aab[bp], n, h)
    if name == "e_c":
        return gap <= first_rel + np.minimum(_aterm(Aab[bp], n, h), Wab_int[bp, n])
    if name == "e_d":
        return directional(lambda nn: np.minimum(_aterm(Aab[bp], nn, h), Wab_int[bp, nn]))
    if name.startswith(PLAN_KINDS):
        R = _period(name, n)
        assert R is not None
        return rec.plan_min[(name.split()[0], n, R)] <= r.cd
    if name == "f_future":
        K = rec.dist.shape[0] - 1
        best = rec.dist.copy()
        for j in range(1, n + 1):
            best[: K + 1 - j] = np.minimum(best[: K + 1 - j], rec.dist[j:])
        return best <= r.cd
    if name in ("g", "g_tau"):
        assert A_model is not None
        Am1, Am2 = A_model[name][b1], A_model[name][b2]
        return gap <= (rec.sp1 + Am1 * h) * t + _aterm(Am1, n, h) + (
            rec.sp2 + Am2 * h
        ) * t + _aterm(Am2, n, h)
    raise ValueError(name)


def _breaks(
    name: str, r: Robot, B: Bounds, rec: Record, n: int, A_model: dict[str, np.ndarray] | None
) -> tuple[np.ndarray, np.ndarray, int]:
    """``(K+1, ncol)`` the steps at which a hypothesis of model ``name`` broke, the column of
    each pair (body columns: two, as ``(P, 2)``), and the plan period's extra window."""
    tol = 1 + 1e-9
    body = np.stack([r.b1, r.b2], axis=1)
    accb = rec.acc > B.A * tol + 1e-12
    discb = rec.disc > B.D * tol + 1e-12
    if name in ("a", "d_a"):
        return accb | discb, body, 0
    if name == "b":
        return accb | discb | (rec.speed > B.V * tol + 1e-12), body, 0
    if name in ("c_WH", "c_int", "d_c"):
        return accb | discb | (rec.w_lag <= n), body, 0
    if name == "bc":
        return accb | discb | (rec.w_lag <= n) | (rec.speed > B.V * tol + 1e-12), body, 0
    if name in ("e_a", "e_c", "e_d"):
        lag = 1 if name == "e_a" else n
        pair_break = rec.wab_lag <= lag
        # The discrepancy is per body: fold it into the body pair's column.
        bb = r.bp_bodies
        pair_break = pair_break | discb[:, bb[:, 0]] | discb[:, bb[:, 1]]
        return pair_break, np.stack([r.bp, r.bp], axis=1), 0
    if name.startswith(PLAN_KINDS):
        R = _period(name, n)
        assert R is not None
        return rec.dev_break[(name.split()[0], R)], body, R - 1
    if name == "f_future":
        return np.zeros_like(accb), body, 0
    if name in ("g", "g_tau"):
        assert A_model is not None
        Am = A_model[name]
        return (rec.acc > Am * tol + 1e-12) | (rec.disc > Am * r.h * tol + 1e-12), body, 0
    raise ValueError(name)


def evaluate(r: Robot, B: Bounds, rec: Record, A_model: dict[str, np.ndarray] | None) -> list[dict]:
    rows = []
    K = rec.dist.shape[0] - 1
    contact = rec.contact
    on_k, on_p = np.nonzero(contact[1:] & ~contact[:-1])
    on_k = on_k + 1
    steps_idx = np.arange(K + 1)
    for n in r.steps_n:
        counted = K - n + 1  # steps 0..K-n
        touch = contact.copy()
        for j in range(1, n + 1):
            touch[: K + 1 - j] |= contact[j:]
        oracle = float(touch[:counted].mean())
        for name in MODELS:
            if name.startswith("g") and A_model is None:
                continue
            if name.startswith(PLAN_KINDS) and _period(name, n) is None:
                continue
            st = standing(name, r, B, rec, n, A_model)
            frac = float(st[:counted].mean())
            last_false = np.maximum.accumulate(np.where(st, -1, steps_idx[:, None]), axis=0)
            lead = np.where(st[on_k, on_p], on_k - (last_false[on_k, on_p] + 1), 0)
            short = lead < n
            start = short & (on_k < n)
            brk, cols, extra = _breaks(name, r, B, rec, n, A_model)
            lo = np.maximum(on_k - n - extra, 0)
            viol = _window_any(brk, on_k, lo, cols[on_p, 0]) | _window_any(
                brk, on_k, lo, cols[on_p, 1]
            )
            after = short & ~start & viol
            held = short & ~start & ~viol
            # The verdicts that rest on broken hypotheses: a break of either body (body pair)
            # in the window the verdict relies on, [k - (R - 1), k + n].
            cs = np.concatenate(
                [np.zeros((1, brk.shape[1]), dtype=np.int64), np.cumsum(brk, axis=0)]
            )
            hi = np.minimum(steps_idx + n, K) + 1
            lo_all = np.maximum(steps_idx - extra, 0)
            window = (cs[hi] - cs[lo_all]) > 0
            broken = window[:, cols[:, 0]] | window[:, cols[:, 1]]
            rows.append(
                {
                    "robot": r.name,
                    "model": name,
                    "n": n,
                    "horizon_ms": round(1e3 * n * r.h, 6),
                    "pairs": int(r.g1.size),
                    "standing": frac,
                    "oracle": oracle,
                    "ratio": frac / oracle if oracle > 0 else float("inf"),
                    "onsets": int(on_k.size),
                    "short_held": int(held.sum()),
                    "short_violation": int(after.sum()),
                    "short_start": int(start.sum()),
                    "missed_held": int((held & (lead == 0)).sum()),
                    "broken": float(broken[:counted].mean()),
                    "lead_median_ms": float(1e3 * r.h * np.median(lead)) if lead.size else None,
                }
            )
    return rows


# ----------------------------------------------------------------------------- driver


def _plan_costs(r: Robot, rec: Record) -> list[dict]:
    """Per horizon and plan period, what a plan serving that horizon alone costs a step:
    ``(R - 1 + n) / R`` mj_steps, and the ``mj_geomDistance`` calls on its states (the ages up to
    ``R - 1 + n`` of the shared plans, whose caps are the larger of the hold bounds)."""
    K1 = rec.dist.shape[0]
    out = []
    for n in r.steps_n:
        for R in _plan_periods(n):
            length = R - 1 + n
            for roll in ("hold", "seg"):
                q = rec.plan_queries[(roll, R)]
                out.append(
                    {
                        "roll": roll,
                        "horizon_ms": round(1e3 * n * r.h, 6),
                        "R": R,
                        "mj_steps_per_step": length / R,
                        "queries_per_step": float(q[: length + 1].sum()) / K1,
                    }
                )
    return out


def measure(name: str, steps: int) -> tuple[list[dict], dict]:
    t0 = time.perf_counter()
    r = robot(name)
    B = pilot(r)
    A_model = model_accel(r, SAFETY * B.qvel_max) if name in FIXED_ARMS else None
    rec = rollout(r, B, steps, A_model)
    rows = evaluate(r, B, rec, A_model)
    K1 = steps + 1
    mov = r.moving & np.isin(np.arange(r.nbody), r.pts_body)
    info = {
        "robot": name,
        "pairs": int(r.g1.size),
        "body_pairs": int(r.bp_bodies.shape[0]),
        "A_median": float(np.median(B.A[mov])),
        "V_median": float(np.median(B.V[mov])),
        "E_median": float(np.median(B.E[mov])),
        "E_over_A_median": float(np.median(B.E[mov] / B.A[mov])),
        "E_future": B.E_future,
        "future_identical": rec.future_identical,
        "W_over_AH": {
            str(n): float(np.median(B.W[mov, n] / (B.A[mov] * n * r.h))) for n in r.steps_n
        },
        "Wab_over_sumA": float(
            np.median(B.Wab[:, 1] / r.h / np.maximum(B.A[r.bp_bodies].sum(axis=1), 1e-12))
        ),
        "dev_profile_over_bound": {
            str(n): float(
                np.median(
                    B.dev_profile[mov, n]
                    / np.maximum(B.E[mov] * r.h * r.h * n * (n - 1) / 2, 1e-15)
                )
            )
            for n in r.steps_n
        },
        "A_model_over_A": (
            None if A_model is None else float(np.median(A_model["g"][mov] / B.A[mov]))
        ),
        "A_model_median": None if A_model is None else float(np.median(A_model["g"][mov])),
        "A_tau_over_A": (
            None if A_model is None else float(np.median(A_model["g_tau"][mov] / B.A[mov]))
        ),
        "A_tau_median": None if A_model is None else float(np.median(A_model["g_tau"][mov])),
        "plan": {
            f"{roll} R={R}": {
                "mj_steps_per_step": rec.plan_steps[(roll, R)] / K1,
                "queries_per_step": float(rec.plan_queries[(roll, R)].sum()) / K1,
                "seconds_per_step": rec.plan_seconds[(roll, R)] / K1,
            }
            for roll, R in sorted(rec.plan_steps)
        },
        "plan_costs": _plan_costs(r, rec),
        "seg_early": B.seg_early,
        "seg_bound_over_hold": {
            str(n): float(np.median(B.seg_bound[mov, n] / np.maximum(B.dev_bound[mov, n], 1e-15)))
            for n in r.steps_n
        },
        "mj_step_seconds": rec.step_seconds / K1,
        "pilot_s": B.seconds,
        "rollout_s": rec.seconds,
        "total_s": time.perf_counter() - t0,
    }
    print(
        f"{name}: pilot {B.seconds:.0f} s, rollout {rec.seconds:.0f} s, "
        f"total {info['total_s']:.0f} s",
        file=sys.stderr,
        flush=True,
    )
    return rows, info


def markdown(rows: list[dict], infos: list[dict]) -> str:
    out = []
    robots = list(dict.fromkeys(r["robot"] for r in rows))
    for ms in HORIZONS_MS:
        at = [r for r in rows if abs(r["horizon_ms"] - ms) < 1e-6]
        if not at:
            continue
        out.append(f"\n#### {ms} ms: standing / oracle (short-lead onsets while held)\n")
        body = []
        for name in robots:
            mine = {r["model"]: r for r in at if r["robot"] == name}
            any_row = next(iter(mine.values()))
            cells = [name, f"{100 * any_row['oracle']:.2f}", str(any_row["onsets"])]
            for mdl in MODELS:
                r = mine.get(mdl)
                if r is None:
                    cells.append("")
                    continue
                held = f" ({r['short_held']})" if r["short_held"] else ""
                cells.append(f"{r['ratio']:.1f}{held}")
            body.append(cells)
        med = ["**median**", "", ""]
        for mdl in MODELS:
            ratios = [r["ratio"] for r in at if r["model"] == mdl]
            med.append(f"**{np.median(ratios):.1f}**" if ratios else "")
        body.append(med)
        out.append(table(["robot", "oracle %", "onsets", *MODELS], body))
    out.append(
        "\n#### Pair-steps whose verdict rests on a broken hypothesis (%, median over robots)\n"
    )
    body = []
    for mdl in MODELS:
        cells = [mdl]
        for ms in HORIZONS_MS:
            at = [r for r in rows if r["model"] == mdl and abs(r["horizon_ms"] - ms) < 1e-6]
            cells.append(f"{100 * np.median([r['broken'] for r in at]):.1f}" if at else "")
        body.append(cells)
    out.append(table(["model", *(f"{ms} ms" for ms in HORIZONS_MS)], body))
    out.append("\n#### Onsets with less lead than the horizon (held / after a violation / start)\n")
    body = []
    for mdl in MODELS:
        cells = [mdl]
        for ms in HORIZONS_MS:
            at = [r for r in rows if r["model"] == mdl and abs(r["horizon_ms"] - ms) < 1e-6]
            cells.append(
                f"{sum(r['short_held'] for r in at)} / {sum(r['short_violation'] for r in at)}"
                f" / {sum(r['short_start'] for r in at)}"
            )
        body.append(cells)
    out.append(table(["model", *(f"{ms} ms" for ms in HORIZONS_MS)], body))
    out.append("\n#### Bounds and plan costs\n")
    body = []
    for i in infos:
        cells = [
            i["robot"],
            f"{i['A_median']:.1f}",
            f"{i['V_median']:.2f}",
            " / ".join(f"{v:.2f}" for v in i["W_over_AH"].values()),
            f"{i['Wab_over_sumA']:.2f}",
            f"{i['E_median']:.1f} ({i['E_over_A_median']:.2f})",
            f"{i['E_future']:.1g} ({'bit-identical' if i['future_identical'] else 'DIFFERS'})",
            " / ".join(f"{v:.2f}" for v in i["dev_profile_over_bound"].values()),
            ""
            if i["A_model_over_A"] is None
            else f"{i['A_tau_median']:.0f} ({i['A_tau_over_A']:.1f}x) / "
            f"{i['A_model_median']:.0f} ({i['A_model_over_A']:.0f}x)",
            ", ".join(
                f"{c['roll']} {c['horizon_ms']:g} ms R={c['R']}: "
                f"{c['mj_steps_per_step']:.1f} / {c['queries_per_step']:.0f}"
                for c in i["plan_costs"]
                if c["horizon_ms"] in (50, 200)
            ),
        ]
        body.append(cells)
    out.append(
        table(
            [
                "robot",
                "A median m/s^2",
                "V median m/s",
                "W(n)/(A n h) median, 10..200 ms",
                "A_ab / (A_a + A_b) median",
                "E median m/s^2 (E/A)",
                "E future",
                "max deviation / its bound, 10..200 ms",
                "A model median m/s^2 (x pilot A): torques / with velocity products",
                "plan: mj_steps / distance queries a step",
            ],
            body,
        )
    )
    return "\n".join(out)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", nargs="+", default=list(ROBOT_NAMES))
    ap.add_argument("--steps", type=int, default=2000, help="physics steps a rollout")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument(
        "--tables",
        type=Path,
        nargs="+",
        default=None,
        help="print the tables of saved --json files",
    )
    args = ap.parse_args(argv)
    if args.tables:
        saved = [json.loads(f.read_text()) for f in args.tables]
        print(
            markdown([r for x in saved for r in x["rows"]], [i for x in saved for i in x["robots"]])
        )
        return
    start = time.perf_counter()
    rows: list[dict] = []
    infos: list[dict] = []
    for name in args.robots:
        try:
            more, info = measure(name, args.steps)
        except ModuleNotFoundError as exc:
            print(f"{name}: skipped, not installed ({exc})", file=sys.stderr)
            continue
        rows += more
        infos.append(info)
        if args.json is not None:
            args.json.write_text(json.dumps({"rows": rows, "robots": infos}, indent=1) + "\n")
    print(markdown(rows, infos))
    took = (time.perf_counter() - start) / 60
    print(f"\n{len(infos)} robots, {args.steps} steps a rollout, in {took:.1f} min")


if __name__ == "__main__":
    main()
