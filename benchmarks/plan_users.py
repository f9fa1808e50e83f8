"""Plans as users make them: a nominal model's rollout, a run whose model differs, a TTC peer.

    python benchmarks/plan_users.py --json docs/img/plans-users.json \\
        --plot docs/img/plans-users.png                                  # docs/plans.md's
    python benchmarks/plan_users.py --robots baxter g1 --horizons 0.05 0.2 --steps 1000
    python benchmarks/plan_users.py --tables docs/img/plans-users.json   # the tables again

Issue 39, item 3. Seven robot models held out from ``benchmarks/plan_horizon.py``'s seven (a
bimanual, two arms, a quadruped with an arm, two floating-base humanoids, a mobile manipulator;
``benchmarks/robots.py``, whose wheels install with the command in its docstring), each driven by
``make_controller(m, "smooth")`` (servo targets linear between random points 250 steps apart).
Per robot, one rollout of :data:`STEPS` physics steps on a **perturbed** copy of the model
(:func:`perturbed`: body masses and inertias x U(0.85, 1.15), joint damping x U(0.7, 1.3),
``mj_setConst``; control noise N(0, 2 % of the control range) added each step), while the user
knows only the **nominal** model:

- **plan**: every :data:`EVERY` steps (25) a plan rolled by the controller (a copy of the driver,
  no noise) on the nominal model from the run's state (:func:`plan_from_controls`), ``R + n + 2``
  knots (``n`` the horizon's steps), its deviation from a pilot with its own draw of the
  perturbation, the noise and the drive (:func:`pilot_profile`: the same plans every
  :data:`PILOT_EVERY` steps, :func:`deviation_profile` by the plan's age, safety 2, and
  :func:`relative_profile` of the same pilot for the pairs of links it frees, its plans cut to
  each horizon's knots);
- **declared** (floating bases only, :data:`DECLARED`): the same plans holding the arms alone,
  the base and legs left to their motion bounds (docs/plans.md, "Floating bases");
- **bounds**: the motion bounds alone (no plan);
- **TTC peer** (:class:`TimeToCollision`): MoveIt Servo's stop-distance check
  (``moveit_servo/src/collision_check.cpp``: the distance's rate of change by a finite difference
  over the period, halt when ``d / -d' < safety * stop time``), per active geom pair: MuJoCo's
  distance (``mj_geomDistance``) less the contact distance on every pair every step, an alarm
  when it is within the contact distance and not opening, or ``d / -d' < H``.

Every predictor uses ``accel="auto"`` from a pilot of the nominal model (the user's), latency 0,
``alarm_horizon=H``, one :class:`~dua_mujoco.measure.monitor.Monitor` each against ``H``, and
they and the peer are stepped on the same ``MjData`` after each ``mj_step``. The costs come from
a replay of that rollout, state by state (:func:`costs`: the same ``MjData`` after every
``mj_step``, the same plans at the same steps) without the monitors, whose Python would evict
the caches ``mj_step`` and the predictors run from: the predictors of one horizon stepped in turn
(the order reversed every step), then the peer alone, each timed in this thread's CPU time
against the ``mj_step`` of its own replay, every interval less what the clock's own reads add
to it (:func:`clock_overhead`). A horizon's deviation and relative rows are the same
for every plan (origin 0): they are made once (``Run.rows``), as a user makes such inputs, and
``set_plan`` is timed on them.

**Columns**: standing over the oracle (geom pairs in alarm against those that do touch within
``H``); contact onsets with less lead than ``H``, split into while every hypothesis held / after a
violation or a plan break / at the start (within ``H`` of it), and for the peer all of its
onsets with less lead than ``H`` (it promises nothing); plan breaks per 1,000 steps (bodies found
beyond their deviation); the predictor's cost over ``mj_step``, ``set_plan`` included
(``(median set_plan + median first step after a plan + (R - 1) median other step) / (R median
mj_step)``, plan_horizon.py's ``_amortised``), and the peer's (median step). Targets (issue 39,
median over robots): standing at most 3x the oracle at 50 ms and 5x at 200 ms, no onset with less
lead than ``H`` while held, the predictor with ``set_plan`` at most 0.5x ``mj_step`` at 200 ms
and 1.5x on any robot.

**Floating bases** (:func:`breaks_of`): for each plan of the run, each body's deviation from it
at each age (the runtime's own measure at the bound points, ``deviation_profile`` on that plan
alone) against the declared one: which body leaves its tube first and at what age, by how much;
the base's drift (the free joint's position, plan against run) at the end of the plan's
period; and the floor contacts.
"""

from __future__ import annotations

import copy
import json
import sys
import time
from pathlib import Path
from typing import Any, NamedTuple

import mujoco
import numpy as np

from dua_mujoco.build.options import PilotOptions
from dua_mujoco.measure.accumulators import Durations
from dua_mujoco.measure.monitor import Monitor
from dua_mujoco.measure.rollout import build_report
from dua_mujoco.models.scenes import SceneController, make_controller
from dua_mujoco.runtime.plans import (
    PilotPlan,
    RelativeProfile,
    deviation_profile,
    plan_deviation,
    plan_from_controls,
    relative_profile,
)
from dua_mujoco.runtime.predictor import Predictor

sys.path.insert(0, str(Path(__file__).parent))
from bench import table
from horizon import PILOT_SEED, ROLLOUT_SEED, alarm_figures, robots_parser
from plan_horizon import CLOCK, _amortised, _ratio
from robots import ROBOTS, load_robot

ROBOT_NAMES = ("baxter", "sawyer", "xarm7", "spot_arm", "g1", "gr1", "tiago")
"""Held out from plan_horizon.py's seven (panda, ur5e, iiwa, aloha, go1, h1, fetch)."""
HORIZONS = (0.05, 0.2, 0.5)
STEPS = 2000
EVERY = 25
"""Physics steps between two plans of the run."""
PILOT_EVERY = 10
"""Physics steps between two plans of the pilot that measures the deviation profile."""
SAFETY = 2.0
HOLD = 250
NOISE = 0.02
"""Control noise: a normal deviate of this share of each actuator's control range a step."""
MASS = (0.85, 1.15)
DAMPING = (0.7, 1.3)
DISTMAX = 10.0
"""mj_geomDistance's search limit for the TTC peer (m): farther pairs read as this far."""
DECLARED: dict[str, tuple[str, ...]] = {
    "spot_arm": ("arm_base",),
    "g1": ("right_arm_mount", "left_arm_mount"),
    "gr1": ("right_arm_mount", "left_arm_mount"),
}
"""Floating bases: the roots of the subtrees a user plans (the arms), the rest (base, legs,
torso) left to its motion bounds."""
SIDES = ("plan", "declared", "bounds")
ALWAYS = 0.95
"""A geom pair in alarm at this share of the steps or more, never touching, stands always."""


# ----------------------------------------------------------------------------- the world


def perturbed(model: mujoco.MjModel, rng: np.random.Generator) -> mujoco.MjModel:
    """A copy of ``model`` whose body masses and inertias are scaled by U(0.85, 1.15) (one
    factor each a body) and joint damping by U(0.7, 1.3) (one a DOF), its derived constants
    recomputed."""
    m = copy.deepcopy(model)
    nb = m.nbody
    m.body_mass[:] *= rng.uniform(*MASS, size=nb)
    m.body_inertia[:] *= rng.uniform(*MASS, size=nb)[:, None]
    m.dof_damping[:] *= rng.uniform(*DAMPING, size=m.nv)
    mujoco.mj_setConst(m, mujoco.MjData(m))
    return m


class NoisyDriver:
    """The smooth drive on the run: the driver's controls plus N(0, 2 % of the range)."""

    def __init__(self, model: mujoco.MjModel, seed: int) -> None:
        self.driver: SceneController = make_controller(model, "smooth", seed=seed, hold_steps=HOLD)
        lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
        limited = model.actuator_ctrllimited.astype(bool)
        self.sigma = np.where(limited, NOISE * (hi - lo), 0.0)
        self.rng = np.random.default_rng(seed + 7_919)

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.driver(model, data)
        data.ctrl[:] += self.rng.normal(0.0, 1.0, size=self.sigma.size) * self.sigma

    def plan(self, nominal: mujoco.MjModel, data: mujoco.MjData, knots: int) -> np.ndarray:
        """The user's plan: the driver (no noise) rolled on the nominal model from ``data``."""
        return plan_from_controls(nominal, data, copy.deepcopy(self.driver), steps=knots - 1)


def start_replay(world: Run, horizon: float) -> tuple[NoisyDriver, mujoco.MjData, Predictor]:
    """A replay of ``world``'s run at its first step: the noisy driver, the run's data one step
    in, and a predictor reset on it (benchmarks/plan_profile.py and plan_cold.py replay it)."""
    drive = NoisyDriver(world.nominal, ROLLOUT_SEED)
    d = mujoco.MjData(world.run)
    mujoco.mj_forward(world.run, d)
    p = Predictor(world.nominal, accel=world.bounds, alarm_horizon=horizon)
    mujoco.mj_step(world.run, d)
    p.reset(d)
    return drive, d, p


def subtree_bodies(model: mujoco.MjModel, roots: tuple[str, ...]) -> np.ndarray:
    """The ids of the bodies in the subtrees of ``roots`` (names)."""
    ids = {model.body(r).id for r in roots}
    out = []
    for b in range(model.nbody):
        a = b
        while a != 0 and a not in ids:
            a = int(model.body_parentid[a])
        if a in ids:
            out.append(b)
    return np.array(out, dtype=np.int64)


def pilot_profile(
    nominal: mujoco.MjModel,
    points: Any,
    knots: int,
    steps: int,
    geom_pairs: Any = None,
    *,
    lengths: tuple[int, ...] = (),
) -> tuple[np.ndarray, np.ndarray, dict[int, RelativeProfile]]:
    """The deviation profile ``(knots, nbody)`` by the plan's age from a pilot with its own draw
    of the perturbation, the noise and the drive, the pilot's ``(T, nq)`` rows, and (with
    ``geom_pairs``, the predictor's active ones) the relative profile of the same pilot for
    plans of each of ``lengths`` knots (each ``<= knots``; default ``knots``).

    One pilot serves every length: a plan of ``n`` knots is the first ``n`` of the longer plan
    rolled from the same state (the driver is copied, no noise), so each length's profiles are
    those of a pilot made for it. ``relative_profile`` keeps the pairs its bound frees at the
    plan's last age, so the pairs a horizon's plans get are chosen at that horizon's length,
    not at the longest one run beside it.
    """
    run = perturbed(nominal, np.random.default_rng(PILOT_SEED))
    drive = NoisyDriver(nominal, PILOT_SEED)
    d = mujoco.MjData(run)
    mujoco.mj_forward(run, d)
    rows, plans = [d.qpos.copy()], []
    for k in range(1, steps + 1):
        if k % PILOT_EVERY == 0:
            plans.append(PilotPlan(len(rows) - 1, drive.plan(nominal, d, knots)))
        drive(run, d)
        mujoco.mj_step(run, d)
        rows.append(d.qpos.copy())
    q = np.array(rows)
    profile = deviation_profile(nominal, q, plans, points=points, safety=SAFETY)
    if geom_pairs is None:
        return profile, q, {}
    rel = {}
    for n in lengths or (knots,):
        if not 1 <= n <= knots:
            raise ValueError(f"lengths holds {n}; expected 1 to knots = {knots}.")
        rel[n] = relative_profile(
            nominal,
            q,
            [PilotPlan(p.start, p.qpos[:n]) for p in plans],
            points=points,
            geom_pairs=(geom_pairs.geom1, geom_pairs.geom2),
            profile=profile[:n],
            safety=SAFETY,
        )
    return profile, q, rel


# ----------------------------------------------------------------------------- the TTC peer


class TimeToCollision:
    """MoveIt Servo's stop-distance check per active geom pair (module docstring).

    ``step(data)`` reads every pair's distance less its contact distance (``mj_geomDistance``
    on ``data``'s geoms: the state MuJoCo's contacts are of), its rate of change since the last
    step, and returns each horizon's alarms: within the contact distance and not opening, or
    closing with ``d / -d' < H``.
    """

    def __init__(self, model: mujoco.MjModel, predictor: Predictor, horizons: tuple[float, ...]):
        gp = predictor.geom_pairs
        self.model = model
        self.pairs = list(
            zip(np.asarray(gp.geom1).tolist(), np.asarray(gp.geom2).tolist(), strict=True)
        )
        g1, g2 = np.asarray(gp.geom1), np.asarray(gp.geom2)
        margin = np.maximum(model.geom_margin[g1], model.geom_margin[g2])
        self.contact = margin - np.maximum(model.geom_gap[g1], model.geom_gap[g2])
        self.horizons = np.asarray(horizons)
        self.h = float(model.opt.timestep)
        self.prev: np.ndarray | None = None

    def step(self, data: mujoco.MjData) -> np.ndarray:
        """``(len(horizons), npair)`` bool alarms."""
        m = self.model
        dist = np.fromiter(
            (mujoco.mj_geomDistance(m, data, a, b, DISTMAX, None) for a, b in self.pairs),
            np.float64,
            len(self.pairs),
        )
        dist -= self.contact
        prev = dist if self.prev is None else self.prev
        self.prev = dist
        rate = (dist - prev) / self.h
        touching = (dist <= 0.0) & (rate <= 0.0)
        closing = rate < 0.0
        return touching[None] | (
            closing[None] & (dist[None] < -rate[None] * self.horizons[:, None])
        )


class Leads:
    """A peer's standing fraction and its onsets' leads over one horizon (the monitor's rules:
    an onset's lead is the time its pair stood in alarm without a break up to the onset).

    ``counts``: the onsets, those whose lead falls short of the horizon (``short``; at the
    start, ``short_start``) and those with no alarm at all (``missed``)."""

    def __init__(self, npair: int, horizon: float, h: float) -> None:
        self.since = np.full(npair, -1, dtype=np.int64)
        self.in_contact = np.zeros(npair, dtype=bool)
        self.horizon, self.h, self.npair = horizon, h, npair
        self.standing, self.steps = 0.0, 0
        self.counts = dict.fromkeys(("onsets", "short", "short_start", "missed"), 0)

    def observe(self, k: int, alarms: np.ndarray, contact: np.ndarray) -> None:
        """Physics step ``k``: the alarms and the pairs in contact (bool masks)."""
        self.since[alarms & (self.since < 0)] = k
        self.since[~alarms] = -1
        self.standing += float(np.count_nonzero(alarms)) / max(self.npair, 1)
        self.steps += 1
        for p in np.flatnonzero(contact & ~self.in_contact):
            self.counts["onsets"] += 1
            lead = 0.0 if self.since[p] < 0 else (k - self.since[p]) * self.h
            self.counts["missed"] += int(self.since[p] < 0)
            if lead < self.horizon * (1 - 1e-9):
                at_start = k * self.h < self.horizon * (1 - 1e-9)
                self.counts["short_start" if at_start else "short"] += 1
        self.in_contact = contact


# ----------------------------------------------------------------------------- floating bases


def breaks_of(
    nominal: mujoco.MjModel,
    rows: np.ndarray,
    plans: list[tuple[int, np.ndarray]],
    declared: np.ndarray,
    points: Any,
    window: int,
    on_floor: list[frozenset[int]],
) -> dict[str, Any]:
    """Why plans break: per plan of the run (its knot 0 at row ``start``), the first age within
    ``window`` knots at which a body's deviation leaves the declared one (the runtime's measure,
    ``deviation_profile`` of that plan alone at safety 1: its running maximum first exceeds a
    non-decreasing bound where the deviation does), which body goes farthest out then and by how
    much, the base's drift (the free joint's position, plan against run) then, and whether the
    bodies touching the floor changed between the plan's start and that age (a foot landing or
    lifting at another instant than the nominal rollout's); the base's drift at the window's end
    for every plan."""
    free = [j for j in range(nominal.njnt) if int(nominal.jnt_type[j]) == 0]
    adr = int(nominal.jnt_qposadr[free[0]]) if free else 0
    first_body: dict[str, int] = {}
    ages, ratios, drift_out, drift_end, contact_changed = [], [], [], [], 0
    for start, q in plans:
        n = min(window, q.shape[0], rows.shape[0] - start)
        if n < 2:
            continue
        prof = deviation_profile(
            nominal, rows[start : start + n], [PilotPlan(0, q[:n])], points=points, safety=1.0
        )
        drift = np.linalg.norm(
            q[:n, adr : adr + 3] - rows[start : start + n, adr : adr + 3], axis=1
        )
        drift_end.append(float(drift[-1]))
        over = prof > declared[: prof.shape[0]]
        if not over.any():
            continue
        age = int(np.flatnonzero(over.any(axis=1))[0])
        out = np.flatnonzero(over[age])
        ratio = prof[age, out] / np.maximum(declared[age, out], 1e-12)
        worst = int(out[np.argmax(ratio)])
        name = nominal.body(worst).name
        first_body[name] = first_body.get(name, 0) + 1
        ages.append(age)
        ratios.append(float(ratio.max()))
        drift_out.append(float(drift[age]))
        contact_changed += int(on_floor[start] != on_floor[start + age])
    return {
        "plans": len(plans),
        "broken_plans": len(ages),
        "first_body": dict(sorted(first_body.items(), key=lambda kv: -kv[1])),
        "age_median": float(np.median(ages)) if ages else None,
        "ratio_median": float(np.median(ratios)) if ratios else None,
        "drift_out_median_m": float(np.median(drift_out)) if drift_out else None,
        "contact_changed": contact_changed,
        "drift_end_median_m": float(np.median(drift_end)) if drift_end else None,
        "drift_end_max_m": float(np.max(drift_end)) if drift_end else None,
    }


# ----------------------------------------------------------------------------- the run


_STATE = int(mujoco.mjtState.mjSTATE_INTEGRATION)


def measure(name: str, horizons: tuple[float, ...], steps: int, every: int) -> list[dict[str, Any]]:
    """One robot: the pilots, the monitored rollout (:func:`monitored`), then its costs
    (:func:`costs`)."""
    t_start = time.perf_counter()
    world = world_of(name, horizons, steps, every)
    pilot_s = time.perf_counter() - t_start
    print(f"{name}: pilots {pilot_s:.0f} s", file=sys.stderr, flush=True)
    rows, record = monitored(world, horizons, steps)
    for row in rows:
        row |= {"robot": name, "pilot_s": pilot_s}
        for key, value in costs(world, row["horizon_s"], record).items():
            row[key] = row[key] | value if isinstance(value, dict) else value
        print(line(row), file=sys.stderr, flush=True)
    return rows


def world_of(name: str, horizons: tuple[float, ...], steps: int, every: int) -> Run:
    """One robot's world: the nominal model and its pilots (bounds ``accel="auto"``, the
    deviation and relative profiles), the perturbed run's model, the plans' knots by horizon
    (also what ``benchmarks/plan_profile.py`` replays)."""
    nominal = load_robot(name)
    h = float(nominal.opt.timestep)
    auto = Predictor(
        nominal,
        pilot=PilotOptions(
            controller=make_controller(nominal, "smooth", seed=PILOT_SEED, hold_steps=HOLD),
            seed=PILOT_SEED,
        ),
    )
    ns = {H: max(round(H / h), 1) for H in horizons}
    knots = {H: every + ns[H] + 2 for H in horizons}
    profile, _, rel = pilot_profile(
        nominal,
        auto.bound_points,
        max(knots.values()),
        max(steps, 2000),
        auto.geom_pairs,
        lengths=tuple(sorted(set(knots.values()))),
    )
    run = perturbed(nominal, np.random.default_rng(ROLLOUT_SEED))
    roots = DECLARED.get(name)
    world = Run(
        nominal=nominal,
        run=run,
        bounds=auto.bounds,
        points=auto.bound_points,
        profile=profile,
        relative={H: rel[n] for H, n in knots.items()},
        knots=knots,
        every=every,
        arms=subtree_bodies(nominal, roots) if roots else None,
    )
    # Every plan of a horizon takes the same deviation and relative rows (its origin is knot 0):
    # made once, as a user makes them, not at each plan in the predictor's timed cost. The
    # declared side's only for a floating base with arms (Run.sides).
    rows = {
        (H, d): (plan_deviation(profile, n), world.relative_rows(H, d))
        for H, n in knots.items()
        for d in ((False, True) if world.arms is not None else (False,))
    }
    return world._replace(rows=rows)


class Run(NamedTuple):
    """What a robot's runs share: the models, the user's bounds and deviation profile, the plans'
    knots by horizon and period, the arms of a floating base (None: not one)."""

    nominal: mujoco.MjModel
    run: mujoco.MjModel
    bounds: Any
    points: Any
    profile: np.ndarray
    knots: dict[float, int]
    every: int
    arms: np.ndarray | None
    relative: dict[float, RelativeProfile] | None = None
    # (horizon, declared): the plans' deviation and relative rows (world_of makes them)
    rows: dict[tuple[float, bool], tuple[np.ndarray, Any]] | None = None

    def sides(self) -> list[str]:
        return [s for s in SIDES if s != "declared" or self.arms is not None]

    def set_plan(self, p: Predictor, side: str, H: float, q: np.ndarray, start: float) -> None:
        declared = side == "declared"
        assert self.rows is not None
        deviation, relative = self.rows[H, declared]
        p.set_plan(
            q[: self.knots[H]],
            deviation=deviation,
            start=start,
            bodies=self.arms if declared else None,
            relative=relative,
        )

    def relative_rows(self, H: float, declared: bool) -> tuple[np.ndarray, np.ndarray] | None:
        """``set_plan``'s relative deviations at horizon ``H``: the pilot's for plans of its
        length, of the pairs both of whose bodies the plan holds."""
        if self.relative is None:
            return None
        pairs, dev = self.relative[H].relative(self.knots[H])
        if declared and self.arms is not None:
            keep = np.isin(pairs, self.arms).all(axis=1)
            pairs, dev = pairs[keep], dev[:, keep]
        return pairs, dev


class Record(NamedTuple):
    """A monitored rollout, replayed by :func:`costs`: the state (``mjSTATE_INTEGRATION``,
    controls included) before each physics step, and the plans by the step after which each
    was made (row 0: before the first)."""

    states: np.ndarray
    plans: dict[int, tuple[float, np.ndarray]]


def monitored(world: Run, horizons: tuple[float, ...], steps: int) -> tuple[list, Record]:
    """The rollout with every predictor, its monitor and the peer: standing, leads, breaks."""
    nominal, run = world.nominal, world.run
    h = float(nominal.opt.timestep)
    drive = NoisyDriver(nominal, ROLLOUT_SEED)
    d = mujoco.MjData(run)
    mujoco.mj_forward(run, d)
    sides = world.sides()
    keys = [(H, s) for H in horizons for s in sides]
    preds = {k: Predictor(nominal, accel=world.bounds, alarm_horizon=k[0]) for k in keys}
    mons = {k: Monitor(preds[k], series=False, warning_horizon=k[0]) for k in keys}
    peer = TimeToCollision(nominal, preds[keys[0]], horizons)
    leads = {H: Leads(len(peer.pairs), H, h) for H in horizons}
    ids = preds[keys[0]]
    # What stands under the plan, geom pair by geom pair: steps in alarm, and ever touching.
    plan_gp = {H: ids.geom_pair_ids(*preds[(H, "plan")].sphere_pair_geoms) for H in horizons}
    stood = {H: np.zeros(len(peer.pairs), dtype=np.int64) for H in horizons}
    touched = np.zeros(len(peer.pairs), dtype=bool)
    longest = max(world.knots.values())
    states = np.empty((steps + 1, mujoco.mj_stateSize(run, _STATE)))
    plans: dict[int, tuple[float, np.ndarray]] = {}
    rows = [d.qpos.copy()]
    floor = [g for g in range(nominal.ngeom) if int(nominal.geom_type[g]) == 0]
    on_floor: list[frozenset[int]] = [frozenset()]

    def replan(k: int) -> None:
        q = drive.plan(nominal, d, longest)
        plans[k] = (float(d.time), q)
        for key in keys:
            if key[1] != "bounds":
                world.set_plan(preds[key], key[1], key[0], q, float(d.time))

    def physics(k: int) -> None:
        drive(run, d)
        mujoco.mj_getState(run, d, states[k], _STATE)
        mujoco.mj_step(run, d)
        rows.append(d.qpos.copy())
        nc = int(d.ncon)
        g1, g2 = d.contact.geom1[:nc], d.contact.geom2[:nc]
        touch = np.concatenate([g2[np.isin(g1, floor)], g1[np.isin(g2, floor)]])
        on_floor.append(frozenset(np.asarray(nominal.geom_bodyid)[touch].tolist()))

    physics(0)
    for mon in mons.values():
        mon.start(d)
    peer.step(d)
    replan(0)
    for k in range(1, steps + 1):
        physics(k)
        alarms = {key: preds[key].step(d) for key in keys}
        peer_alarms = peer.step(d)
        for key in keys:
            mons[key].observe(d, alarms[key])
        nc = int(d.ncon)
        contact = np.zeros(len(peer.pairs), dtype=bool)
        if nc:
            gp = ids.geom_pair_ids(d.contact.geom1[:nc], d.contact.geom2[:nc])
            contact[gp[gp >= 0]] = True
        for i, H in enumerate(horizons):
            leads[H].observe(k, peer_alarms[i], contact)
            standing = preds[(H, "plan")].pair_state().alarm_state()
            stood[H][np.unique(plan_gp[H][standing])] += 1
        touched |= contact
        if k % world.every == 0:
            replan(k)
        if k % 500 == 0:
            print(f"  step {k} of {steps}", file=sys.stderr, flush=True)

    q_rows = np.array(rows)
    floating = any(int(t) == 0 for t in nominal.jnt_type)
    out = []
    for H in horizons:
        n = max(round(H / h), 1)
        row: dict[str, Any] = {
            "horizon_s": H,
            "steps": steps,
            "every": world.every,
            "knots": world.knots[H],
            "floating": floating,
            "floor_contacts_per_step": float(np.mean([len(f) for f in on_floor])),
        }
        for side in sides:
            key = (H, side)
            mons[key].finish()
            rep = build_report(mons[key], "", False, Durations(), Durations(), interrupted=False)
            row[side] = alarm_figures(rep) | {"plan_breaks": preds[key].plan_breaks}
        # Pairs that stand at (nearly) every step and never touch: the deviation sum over the
        # horizon exceeds their gap for the whole run (links a joint or two apart, feet over
        # the floor).
        always = (stood[H] >= ALWAYS * steps) & ~touched
        total = int(stood[H].sum())
        row["always"] = {
            "pairs": int(always.sum()),
            "of": len(peer.pairs),
            "share": float(stood[H][always].sum() / total) if total else 0.0,
        }
        lp = leads[H]
        row["ttc"] = {"standing": lp.standing / max(lp.steps, 1), **lp.counts}
        if floating:
            # The plan made after step k starts at the state after it: row k + 1.
            made = [(k + 1, q) for k, (_, q) in sorted(plans.items())]
            row["breaks"] = breaks_of(
                nominal, q_rows, made, world.profile, world.points, world.every + n + 1, on_floor
            )
        out.append(row)
    return out, Record(states, plans)


def clock_overhead(reads: int = 2000) -> float:
    """What a timed interval adds to what it times, in seconds: the median of ``reads`` empty
    intervals (one clock read's return and the next one's call: 0.56 us here idle, 0.8 under
    load, 3-5 % of a small robot's ``mj_step``). :func:`costs` takes it off every interval it
    times, ``mj_step``'s and the predictors' alike (warm here, so no more than a cold read
    adds)."""
    empty = np.empty(reads)
    for i in range(reads):
        t0 = CLOCK()
        empty[i] = CLOCK() - t0
    return float(np.median(empty))


def costs(world: Run, H: float, record: Record, *, peer: bool = True) -> dict[str, Any]:
    """The costs at horizon ``H``: the monitored rollout replayed state by state (the same
    ``MjData`` after every ``mj_step``, the same plans at the same steps), each timed in CPU
    time, with no monitor in the loop (a monitor's Python evicts the caches ``mj_step`` and the
    predictors run from): the predictors of ``H`` stepped in turn (their A/B), then the peer
    alone (its Python loop over every pair would evict them too), each against the ``mj_step``
    of its own replay (``peer=False``: the predictors only)."""
    nominal, run = world.nominal, world.run
    sides = world.sides()
    d = mujoco.MjData(run)
    steps = record.states.shape[0] - 1

    def replay(step: Any, replan: Any) -> np.ndarray:
        t_mj = np.zeros(steps)
        mujoco.mj_setState(run, d, record.states[0], _STATE)
        mujoco.mj_step(run, d)
        step(0)
        replan(0)
        for k in range(1, steps + 1):
            mujoco.mj_setState(run, d, record.states[k], _STATE)
            t0 = CLOCK()
            mujoco.mj_step(run, d)
            t_mj[k - 1] = CLOCK() - t0
            step(k)
            if k in record.plans:
                replan(k)
        return t_mj

    preds = {s: Predictor(nominal, accel=world.bounds, alarm_horizon=H) for s in sides}
    t_step = {s: np.zeros(steps) for s in sides}
    t_setk = {s: np.zeros(steps) for s in sides}

    def step(k: int) -> None:
        if k == 0:
            for p in preds.values():
                p.reset(d)
            return
        for s in sides if k % 2 else sides[::-1]:
            t0 = CLOCK()
            preds[s].step(d)
            t_step[s][k - 1] = CLOCK() - t0

    def replan(k: int) -> None:
        start, q = record.plans[k]
        for s in sides:
            if s == "bounds":
                continue
            t0 = CLOCK()
            world.set_plan(preds[s], s, H, q, start)
            if k >= 1:
                t_setk[s][k - 1] = CLOCK() - t0

    t_mj = replay(step, replan)
    clock = clock_overhead()

    def net(t: np.ndarray) -> np.ndarray:  # an interval less the clock's part (0: none timed)
        return np.where(t > 0, np.maximum(t - clock, 0.0), 0.0)

    mj = net(t_mj)
    out: dict[str, Any] = {"mj_step_us": float(np.median(mj)) * 1e6, "clock_us": clock * 1e6}
    for s in sides:
        period = world.every if s != "bounds" else 0
        step_s, setk = net(t_step[s]), net(t_setk[s])
        setp = setk[setk > 0]
        out[s] = {
            "median": float(np.median(step_s) / np.median(mj)),
            "set_plan": float(np.median(setp) / np.median(mj)) if setp.size else 0.0,
            "amortised": _amortised(step_s, setk, mj, period),
            # the same with the clock's part left in every interval
            "amortised_raw": _amortised(t_step[s], t_setk[s], t_mj, period),
        }
    if not peer:
        return out
    ttc = TimeToCollision(nominal, preds[sides[0]], (H,))
    t_peer = np.zeros(steps)

    def peer_step(k: int) -> None:
        t0 = CLOCK()
        ttc.step(d)
        if k:
            t_peer[k - 1] = CLOCK() - t0

    t_mj = net(replay(peer_step, lambda k: None))
    out["ttc"] = {"median": float(np.median(net(t_peer)) / np.median(t_mj))}
    return out


# ----------------------------------------------------------------------------- tables


def _x(value: float) -> str:
    if value != value or value == float("inf"):
        return "-"
    return f"{value:.1f}x" if value < 10 else f"{value:.0f}x"


def _peer_ratio(row: dict[str, Any]) -> float:
    o = row["plan"]["oracle"]
    return row["ttc"]["standing"] / o if o > 0 else float("inf")


def _always(row: dict[str, Any]) -> str:
    a = row.get("always")
    if a is None:
        return "-"
    without = _ratio(row["plan"]) * (1.0 - a["share"])
    return f"{a['pairs']} of {a['of']} ({100 * a['share']:.0f} %; {_x(without)})"


def line(row: dict[str, Any]) -> str:
    """One robot and horizon, for the progress output."""
    p, b, t = row["plan"], row["bounds"], row["ttc"]
    dec = row.get("declared")
    return (
        f"{row['robot']:8s} H {1e3 * row['horizon_s']:4.0f} ms: oracle {100 * p['oracle']:.2f} %, "
        f"standing/oracle plan {_x(_ratio(p))}"
        + (f" declared {_x(_ratio(dec))}" if dec else "")
        + f" bounds {_x(_ratio(b))} ttc {_x(_peer_ratio(row))}; short held {p['short_held']}"
        + (f"/{dec['short_held']}" if dec else "")
        + f", ttc late {t['short']}/{t['onsets']}; breaks {p['plan_breaks']}"
        + (f"/{dec['plan_breaks']}" if dec else "")
        + f"; cost plan {p['amortised']:.2f} bounds {b['amortised']:.2f} ttc {t['median']:.2f}"
        + f"; always standing {_always(row)}"
    )


def markdown(rows: list[dict[str, Any]]) -> str:
    """The per-robot table and the medians over robots at each horizon."""
    body = []
    for r in rows:
        p, b, t = r["plan"], r["bounds"], r["ttc"]
        per_k = 1000.0 / r["steps"]
        dec = r.get("declared")
        body.append(
            [
                r["robot"],
                f"{1e3 * r['horizon_s']:g} ms",
                f"{100 * p['oracle']:.2f}",
                " / ".join(
                    [
                        _x(_ratio(p)),
                        _x(_ratio(dec)) if dec else "",
                        _x(_ratio(b)),
                        _x(_peer_ratio(r)),
                    ]
                ),
                str(p["onsets"]),
                f"{p['short_held']} / {p['short_violation']} / {p['short_start']}"
                + (
                    f" ({dec['short_held']} / {dec['short_violation']} / {dec['short_start']})"
                    if dec
                    else ""
                ),
                f"{b['short_held']} / {b['short_violation']} / {b['short_start']}",
                f"{t['short']} + {t['short_start']} of {t['onsets']}",
                f"{p['plan_breaks'] * per_k:.0f}"
                + (f" ({dec['plan_breaks'] * per_k:.0f})" if dec else ""),
                f"{p['amortised']:.2f}"
                + (f" ({dec['amortised']:.2f})" if dec else "")
                + f" / {b['amortised']:.2f} / {t['median']:.1f}",
                f"{p['set_plan']:.2f}",
                _always(r),
            ]
        )
    out = table(
        [
            "robot",
            "H",
            "oracle %",
            "standing / oracle: plan / declared / bounds / TTC",
            "onsets",
            "lead < H, plan: held / after violation or break / at start (declared)",
            "lead < H, bounds: held / after violation / at start",
            "TTC: lead < H + at start, of onsets",
            "plan breaks / 1,000 steps (declared)",
            "cost / mj_step: plan incl. set_plan (declared) / bounds / TTC",
            "set_plan / mj_step",
            "plan: pairs always standing, never touching (share of the alarms; standing without)",
        ],
        body,
    )
    meds = []
    for H in sorted({r["horizon_s"] for r in rows}):
        at = [r for r in rows if r["horizon_s"] == H]

        def med(vals: list[float]) -> float:
            v = [x for x in vals if x == x and x != float("inf")]
            return float(np.median(v)) if v else float("nan")

        meds.append(
            [
                f"{1e3 * H:g} ms",
                " / ".join(_x(med([_ratio(r[s]) for r in at])) for s in ("plan", "bounds"))
                + f" / {_x(med([_peer_ratio(r) for r in at]))}",
                str(sum(r["plan"]["short_held"] for r in at)),
                f"{sum(r['ttc']['short'] for r in at)} of {sum(r['ttc']['onsets'] for r in at)}",
                f"{med([r['plan']['amortised'] for r in at]):.2f}",
                f"{max(r['plan']['amortised'] for r in at):.2f}",
                f"{med([r['bounds']['amortised'] for r in at]):.2f}",
                f"{med([r['ttc']['median'] for r in at]):.1f}",
            ]
        )
    out += "\n\nMedian over robots:\n\n" + table(
        [
            "H",
            "standing / oracle: plan / bounds / TTC",
            "lead < H while held, plan (sum)",
            "TTC lead < H past the start (sum)",
            "plan incl. set_plan / mj_step (median)",
            "(worst robot)",
            "bounds / mj_step",
            "TTC / mj_step",
        ],
        meds,
    )
    floating = [r for r in rows if r.get("breaks")]
    if floating:
        fb = []
        for r in floating:
            br = r["breaks"]
            firsts = ", ".join(f"{k} {v}" for k, v in list(br["first_body"].items())[:3])

            def cm(v: float | None) -> str:
                return "-" if v is None else f"{100 * v:.1f}"

            fb.append(
                [
                    r["robot"],
                    f"{1e3 * r['horizon_s']:g} ms",
                    f"{br['broken_plans']} of {br['plans']}",
                    firsts or "-",
                    "-" if br["age_median"] is None else f"{br['age_median']:.0f}",
                    "-" if br["ratio_median"] is None else f"{br['ratio_median']:.1f}x",
                    cm(br["drift_out_median_m"]),
                    f"{br['contact_changed']} of {br['broken_plans']}",
                    f"{cm(br['drift_end_median_m'])} / {cm(br['drift_end_max_m'])}",
                    f"{r['floor_contacts_per_step']:.1f}",
                ]
            )
        out += (
            "\n\nWhy floating bases break their plans (each plan of the run, over its window):\n\n"
        )
        out += table(
            [
                "robot",
                "H",
                "plans leaving their tube",
                "first body out (plans)",
                "median age out (steps)",
                "deviation / declared then (median)",
                "base drift then, median cm",
                "floor contacts changed by then",
                "base drift at the window's end, median / max cm",
                "bodies on the floor a step",
            ],
            fb,
        )
    return out


def plot(rows: list[dict[str, Any]], path: Path) -> None:
    """Standing over the oracle and the cost per robot and horizon."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    robots = list(dict.fromkeys(r["robot"] for r in rows))
    hs = sorted({r["horizon_s"] for r in rows})
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), dpi=110)
    width = 0.8 / len(hs)
    x = np.arange(len(robots))
    for i, H in enumerate(hs):
        at = {r["robot"]: r for r in rows if r["horizon_s"] == H}
        ratio = [_ratio(at[n]["plan"]) if n in at else np.nan for n in robots]
        bound = [_ratio(at[n]["bounds"]) if n in at else np.nan for n in robots]
        ttc = [_peer_ratio(at[n]) if n in at else np.nan for n in robots]
        cost = [at[n]["plan"]["amortised"] if n in at else np.nan for n in robots]
        off = x + (i - (len(hs) - 1) / 2) * width
        axes[0].bar(off, ratio, width, color=f"C{i}", label=f"plan, {1e3 * H:g} ms")
        axes[0].scatter(off, bound, marker="_", color="k", s=60, zorder=3)
        axes[0].scatter(off, ttc, marker=".", color="r", s=40, zorder=3)
        axes[1].bar(off, cost, width, color=f"C{i}", label=f"{1e3 * H:g} ms")
    axes[0].set_yscale("log")
    axes[0].set_ylabel("standing / oracle (plan bars; bounds -, TTC peer .)")
    axes[1].set_ylabel("predictor incl. set_plan / mj_step")
    axes[1].axhline(0.5, color="grey", ls=":", lw=1)
    axes[1].axhline(1.5, color="grey", ls="--", lw=1)
    for ax in axes:
        ax.set_xticks(x, robots, rotation=30)
        ax.grid(True, axis="y", which="both", alpha=0.3)
    axes[0].legend(fontsize=7)
    axes[1].legend(fontsize=7)
    fig.suptitle("Plans as users make them (nominal model, perturbed run, 2 % noise)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    ap = robots_parser(__doc__, "plans-users.png", ROBOT_NAMES)
    ap.add_argument("--horizons", nargs="+", type=float, default=list(HORIZONS), help="seconds")
    ap.add_argument("--steps", type=int, default=STEPS, help="physics steps a run")
    ap.add_argument("--every", type=int, default=EVERY, help="physics steps between two plans")
    ap.add_argument("--tables", type=Path, default=None, help="print the tables of saved rows")
    args = ap.parse_args(argv)
    if args.tables is not None:
        saved = json.loads(args.tables.read_text())["rows"]
        print(markdown(saved))
        if args.plot is not None:
            plot(saved, args.plot)
        return
    missing = [n for n in args.robots if n not in ROBOTS]
    if missing:
        ap.error(f"unknown robots {missing}; known: {', '.join(ROBOTS)}")
    start = time.perf_counter()
    rows: list[dict[str, Any]] = []
    for name in args.robots:
        try:
            rows += measure(name, tuple(args.horizons), args.steps, args.every)
        except ModuleNotFoundError as exc:
            print(f"{name}: skipped, not installed ({exc})", file=sys.stderr)
            continue
        if args.json is not None:  # a long run keeps what it measured
            args.json.write_text(json.dumps({"rows": rows}, indent=1) + "\n")
    print(markdown(rows))
    print(f"\n{len(rows)} rows in {(time.perf_counter() - start) / 60:.1f} min", flush=True)
    if rows and args.plot is not None:
        plot(rows, args.plot)
        print(f"plot written to {args.plot}")


if __name__ == "__main__":
    main()
