"""Warning time with flight plans: a planner feeding ``Predictor.set_plan``, against no plan.

    python benchmarks/plan_horizon.py --json plans.json --plot plans.png  # tables and figure
    python benchmarks/plan_horizon.py --robots panda go1 --horizons 0.05 0.2 --steps 1000
    python benchmarks/plan_horizon.py --tables plans.json   # the tables again, from saved rows

For each robot (``benchmarks/horizon.py``'s seven), protocol and alarm horizon ``H`` (one
predictor period, then 10 to 500 ms), one rollout (rollout seed 0, 2,000 steps) stepped by three
predictors built alike (``accel="auto"`` from the pilot horizon.py uses, ``alarm_horizon=H``,
latency 0), each with its own :class:`~dua_mujoco.measure.monitor.Monitor` measuring against ``H``:

- **A** follows the plans of a planner that knows the driver's command up to its next waypoint
  and nothing after: a copy of the driver whose next random point continues the current segment
  (``smooth``) or holds the current control (``random``). Up to the waypoint the plan is the
  simulation bit for bit (deviation 0); past it, each body's deviation is the pilot's largest at
  that many steps past a waypoint (:func:`~dua_mujoco.runtime.plans.deviation_profile` at the
  predictor's bound points), made monotone, times 2. It replans every ``R = max(H/4, 50 ms)``;
- **T** follows the plans of a planner that knows the driver's whole trajectory (a copy of the
  driver with its random source: the waypoints are drawn in advance, as a trajectory planner or
  an MPC hands them over). Its deviation is measured the same way (0 on every pilot: the plan is
  the run), and it replans every ``R = max(H, 50 ms)``;
- **B** follows the motion bounds alone (today's predictor).

Plans are rolled with :func:`~dua_mujoco.runtime.plans.plan_from_controls` from the current state
for ``R + n + 2`` knots (``n`` the horizon's steps: the plan covers every step until the next plan
and its horizon). Each profile comes from a pilot running the same planner, one plan every
:data:`PILOT_EVERY` steps, on the pilot's own seed (``1_000_003``; the rollout's is 0). The three
are stepped in turn on the same ``MjData`` (order reversed every step), each timed like
``mj_step``: their costs are an A/B in one run. ``set_plan``'s own time is counted in its
predictor's cost (the runtime builds the plan's kinematics, and every pair is evaluated again at
the next step). The planner's time (the copy, the rollout, the deviation rows) is reported apart
and labelled the planner's: an MPC or a planner pays it anyway.

**Measured** (each monitor's report against ``H``): the standing fraction (geom pairs in alarm),
the oracle (geom pairs that do touch within ``H``: the floor), their ratio, the onsets with less
lead than ``H`` split into while the bounds held / after a violation / at the start (a plan's
deviation broken counts as a violation of the body that broke it, from the step the runtime
found it), the plan breaks, and the costs: predictor over ``mj_step`` (median a step; and the
cost a step with ``set_plan`` and the step after it amortised over the plan period, from
medians, :func:`_amortised`), the planner's over ``mj_step`` (a plan's median time over ``R``
median ``mj_step``). Costs are this thread's CPU time (:data:`CLOCK`): the machine is shared.

Models with mocap bodies (fetch) run without a plan here, as the tables below were measured
(a plan now holds their other bodies, the mocap ones following their bounds: issue 39's benchmark
plans them). Targets of issue 34 (smooth protocol): at 50 ms median standing/oracle <= 5x and
predictor <= 0.5x ``mj_step``, at 200 ms <= 10x, no onset with less lead than ``H`` while the
bounds held. The random-held protocol is reported beside, not targeted.
"""

from __future__ import annotations

import copy
import json
import sys
import time
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from dua_mujoco.build.options import PilotOptions
from dua_mujoco.measure.accumulators import Durations
from dua_mujoco.measure.monitor import Monitor
from dua_mujoco.measure.rollout import build_report
from dua_mujoco.models.scenes import SceneController, make_controller
from dua_mujoco.runtime.plans import (
    PilotPlan,
    deviation_profile,
    plan_deviation,
    plan_from_controls,
)
from dua_mujoco.runtime.predictor import Predictor

sys.path.insert(0, str(Path(__file__).parent))
from bench import table
from horizon import (
    HOLD,
    PILOT_SEED,
    ROLLOUT_SEED,
    Line,
    alarm_figures,
    load,
    over_robots,
    plot_against_horizon,
    report,
    robots_parser,
)
from timing import Column, by_label, columns_table

HORIZONS = (None, 0.010, 0.020, 0.050, 0.100, 0.200, 0.500)
"""Alarm horizons (s); None is one predictor period."""
PROTOCOLS = ("smooth", "random")
SAFETY = 2.0
PILOT_STEPS = 2000
PILOT_EVERY = 10
"""Physics steps between two plans of the planner's pilot."""
PLOTTED = ("panda", "ur5e", "go1", "h1")
CLOCK = time.thread_time
"""The costs' clock: this thread's CPU time, blind to the other processes of a shared machine
(wall-clock time charges a long call, a plan or ``set_plan``, with the slices others took)."""


# ----------------------------------------------------------------------------- the planner


class _Continue:
    """A smooth drive's source of random points that continues the current segment."""

    def __init__(self, drive: Any) -> None:
        self.drive = drive
        self.delta = drive._to - drive._from

    def uniform(self, low: np.ndarray, high: np.ndarray) -> np.ndarray:
        return self.drive._to + self.delta


class _Hold:
    """A random driver's source of controls that holds the current one."""

    def __init__(self, driver: SceneController) -> None:
        self.driver = driver

    def uniform(self, low: np.ndarray, high: np.ndarray) -> np.ndarray:
        return self.driver._ctrl


def segment_plan(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    driver: SceneController,
    knots: int,
    knows: str = "waypoint",
) -> tuple[np.ndarray, int]:
    """The plan of ``knots`` knots from ``data`` and the last knot it is exact at.

    ``knows="waypoint"``: the planner knows ``driver``'s command up to its next waypoint and
    continues the segment (or holds the control) past it. ``"trajectory"``: it knows the
    driver's whole pre-planned trajectory (the driver's copy keeps its random source: the
    waypoints a trajectory planner or an MPC would hand over), so the plan is the run.
    """
    policy = copy.deepcopy(driver)
    if knows == "trajectory":
        return plan_from_controls(model, data, policy, steps=knots - 1), knots - 1
    if policy.smooth is not None:
        policy.smooth.rng = _Continue(policy.smooth)  # type: ignore[assignment]
        count = policy.smooth._step
    else:
        policy.rng = _Hold(policy)  # type: ignore[assignment]
        count = policy._step
    hold = driver.hold_steps
    # The driver's call `first` draws the next point: its step leaves the state of knot
    # first - count + 1 the first one the plan may get wrong.
    first = count if count % hold == 0 else count + hold - count % hold
    qpos = plan_from_controls(model, data, policy, steps=knots - 1)
    return qpos, min(first - count, knots - 1)


def pilot_profile(
    model: mujoco.MjModel,
    protocol: str,
    points: tuple[np.ndarray, np.ndarray, np.ndarray],
    knots: int,
    knows: str = "waypoint",
    steps: int = PILOT_STEPS,
) -> tuple[np.ndarray, float]:
    """The planner's deviation profile (by steps past a waypoint) from a pilot, and its
    seconds."""
    t0 = time.perf_counter()
    driver = make_controller(model, protocol, seed=PILOT_SEED, hold_steps=HOLD[protocol])
    d = mujoco.MjData(model)
    mujoco.mj_forward(model, d)
    driver(model, d)
    mujoco.mj_step(model, d)
    rows = [d.qpos.copy()]
    plans = []
    for k in range(1, steps + 1):
        if k % PILOT_EVERY == 0:
            q, origin = segment_plan(model, d, driver, knots, knows)
            plans.append(PilotPlan(len(rows) - 1, q, origin))
        driver(model, d)
        mujoco.mj_step(model, d)
        rows.append(d.qpos.copy())
    profile = deviation_profile(model, np.array(rows), plans, points=points, safety=SAFETY)
    return profile, time.perf_counter() - t0


# ----------------------------------------------------------------------------- the runs


EVERY = {"A": 0.25, "T": 1.0}
"""Replanning period as a fraction of the horizon (``R = max(round(f * n), 1)`` steps) of each
planner: the waypoint planner's deviation grows with the knots past the waypoint, so it replans
often; the trajectory planner's plan is exact to its end, so it replans once a horizon."""
SIDES = {"A": "waypoint", "T": "trajectory", "B": None}
"""The predictors of one run: A's planner knows the next waypoint, T's the trajectory, B none."""


EVERY_MIN = 0.05
"""The shortest replanning period (s): below it a plan's fixed cost (its checks, every pair
evaluated at the next step) outweighs what a fresher plan gains (a short horizon's window ends
well before the waypoint's deviation grows)."""


def _knots(n: int, every: float, timestep: float) -> tuple[int, int]:
    """``(R, knots)`` for a horizon of ``n`` steps."""
    r = max(round(every * n), round(EVERY_MIN / timestep), 1)
    return r, r + n + 2


class ExactReference:
    """The plans judged with exact geometry, offline: at each predictor step the share of A's
    geom pairs with a knot in ``[s, s + n]`` (``s`` the state the step reads) whose planned
    ``mj_geomDistance`` less the two deviations is within the pair's contact distance."""

    def __init__(self, model: mujoco.MjModel, predictor: Predictor, n: int) -> None:
        gp = predictor.geom_pairs
        self.model, self.n = model, n
        self.g1 = np.asarray(gp.geom1, dtype=np.int64)
        self.g2 = np.asarray(gp.geom2, dtype=np.int64)
        body = np.asarray(model.geom_bodyid, dtype=np.int64)
        self.b1, self.b2 = body[self.g1], body[self.g2]
        margin = np.maximum(model.geom_margin[self.g1], model.geom_margin[self.g2])
        self.cd = margin - np.maximum(model.geom_gap[self.g1], model.geom_gap[self.g2])
        self.scratch = mujoco.MjData(model)
        self.free: np.ndarray | None = None  # (knots, P) planned margin less the deviations
        self.start = 0
        self.sum = 0.0
        self.steps = 0

    def plan(self, qpos: np.ndarray, deviation: np.ndarray, start: int) -> None:
        """A plan whose knot 0 is the state of physics step ``start``."""
        m, d = self.model, self.scratch
        gap = np.empty((qpos.shape[0], self.g1.size))
        for j, q in enumerate(qpos):
            d.qpos[:] = q
            mujoco.mj_kinematics(m, d)
            for i, (a, b) in enumerate(zip(self.g1.tolist(), self.g2.tolist(), strict=True)):
                gap[j, i] = mujoco.mj_geomDistance(m, d, a, b, 10.0, None)
        self.free = gap - self.cd - deviation[:, self.b1] - deviation[:, self.b2]
        self.start = start

    def step(self, state: int) -> None:
        """The predictor step reading the state of physics step ``state``."""
        if self.free is None or not self.g1.size:
            return
        j = state - self.start
        window = self.free[j : j + self.n + 1]
        self.sum += float(np.count_nonzero((window <= 0.0).any(axis=0))) / self.g1.size
        self.steps += 1

    @property
    def standing(self) -> float:
        return self.sum / max(self.steps, 1)


def run_ab(
    model: mujoco.MjModel,
    bounds: Any,
    protocol: str,
    horizon: float,
    steps: int,
    profiles: dict[str, np.ndarray | None],
    reference: bool = False,
    every_frac: dict[str, float] | None = None,
    floor: float = 0.0,
) -> dict[str, Any]:
    """One rollout, predictors A, T (plans) and B (none) interleaved (module docstring); with
    ``reference``, A's plans judged with exact geometry too (:class:`ExactReference`)."""
    h = float(model.opt.timestep)
    n = max(round(horizon / h), 1)
    fracs = EVERY if every_frac is None else every_frac
    every = {t: _knots(n, f, h)[0] for t, f in fracs.items()}
    knots = {t: _knots(n, f, h)[1] for t, f in fracs.items()}
    d = mujoco.MjData(model)
    mujoco.mj_forward(model, d)
    driver = make_controller(model, protocol, seed=ROLLOUT_SEED, hold_steps=HOLD[protocol])
    tags = list(SIDES)
    planned = [t for t in tags if SIDES[t] is not None and profiles.get(t) is not None]
    preds = {t: Predictor(model, accel=bounds, alarm_horizon=horizon) for t in tags}
    mons = {t: Monitor(preds[t], series=False, warning_horizon=horizon) for t in tags}
    ref = ExactReference(model, preds["A"], n) if reference and "A" in planned else None
    driver(model, d)
    mujoco.mj_step(model, d)
    for mon in mons.values():
        mon.start(d)
    t_mj = np.zeros(steps)
    t_step = {t: np.zeros(steps) for t in tags}
    t_set = dict.fromkeys(tags, 0.0)
    t_setk = {t: np.zeros(steps) for t in tags}  # set_plan's time after each step
    t_plan_calls: dict[str, list[float]] = {t: [] for t in tags}
    t_planner = dict.fromkeys(tags, 0.0)
    plans = dict.fromkeys(tags, 0)

    def replan(tag: str, k: int = 0) -> None:
        t0 = CLOCK()
        q, origin = segment_plan(model, d, driver, knots[tag], str(SIDES[tag]))
        profile = profiles[tag]
        assert profile is not None
        dev = plan_deviation(profile, knots[tag], origin=origin) + floor
        t1 = CLOCK()
        preds[tag].set_plan(q, deviation=dev, start=float(d.time))
        t2 = CLOCK()
        t_planner[tag] += t1 - t0
        t_plan_calls[tag].append(t1 - t0)
        t_set[tag] += t2 - t1
        if k >= 1:
            t_setk[tag][k - 1] = t2 - t1
        plans[tag] += 1
        if ref is not None and tag == "A":
            ref.plan(q, dev, mons[tag].physics_step)

    for t in planned:
        replan(t)
    for k in range(1, steps + 1):
        driver(model, d)
        t0 = CLOCK()
        mujoco.mj_step(model, d)
        t_mj[k - 1] = CLOCK() - t0
        alarms: dict[str, Any] = {}
        for t in tags if k % 2 else tags[::-1]:
            t0 = CLOCK()
            alarms[t] = preds[t].step(d)
            t_step[t][k - 1] = CLOCK() - t0
        if ref is not None:
            ref.step(mons["A"].physics_step)
        for t in tags:
            mons[t].observe(d, alarms[t])
        for t in planned:
            if k % every[t] == 0:
                replan(t, k)
    row: dict[str, Any] = {
        "horizon_s": horizon,
        "steps_horizon": n,
        "mj_step_us": float(np.median(t_mj)) * 1e6,
        "reference_standing": None if ref is None else ref.standing,
    }
    for t in tags:
        mons[t].finish()
        dur_mj, dur_p = Durations(), Durations()
        for x in t_mj:
            dur_mj.add(float(x))
        for x in t_step[t]:
            dur_p.add(float(x))
        rep = build_report(mons[t], "", False, dur_mj, dur_p, interrupted=False)
        row[t] = {
            "knows": SIDES[t] if t in planned else None,
            **alarm_figures(rep),
            "plan_every": every[t] if t in planned else None,
            "plan_knots": knots[t] if t in planned else None,
            "plans": plans[t],
            "plan_breaks": preds[t].plan_breaks,
            "plan_queries_per_step": int(preds[t]._rt.plan_queries) / steps,
            "set_plan_us": t_set[t] / max(plans[t], 1) * 1e6 if t in planned else None,
            "planner_mean": t_planner[t] / float(t_mj.sum()),
            # A plan's median time over R median mj_steps: robust to stalls.
            "planner": (
                float(np.median(t_plan_calls[t])) / (every[t] * float(np.median(t_mj)))
                if t_plan_calls[t]
                else 0.0
            ),
            "median": float(np.median(t_step[t]) / np.median(t_mj)),
            "mean": float((t_step[t].sum() + t_set[t]) / t_mj.sum()),
            "amortised": _amortised(t_step[t], t_setk[t], t_mj, every[t] if t in planned else 0),
        }
    return row


def _amortised(step: np.ndarray, setp: np.ndarray, mj: np.ndarray, period: int) -> float:
    """The predictor's cost a step over ``mj_step``'s, ``set_plan`` amortised over the plan
    period ``R`` (0: no plan), from medians: ``(median set_plan + median first step after a
    plan + (R - 1) median other step) / (R median mj_step)``. The first step after a plan
    evaluates every pair; a median over all steps would hide it, a mean would carry stalls."""
    if period <= 0:
        return float(np.median(step) / np.median(mj))
    first = np.zeros(step.size, dtype=bool)
    first[0::period] = True  # the step after the plan given after steps 0, R, 2R, ...
    calls = setp[setp > 0]
    cost = (
        (float(np.median(calls)) if calls.size else 0.0)
        + float(np.median(step[first]))
        + (period - 1) * float(np.median(step[~first]))
    )
    return cost / (period * float(np.median(mj)))


def measure(
    name: str,
    protocol: str,
    horizons: tuple[float | None, ...],
    steps: int,
    reference: bool = False,
    every_frac: dict[str, float] | None = None,
    floor: float = 0.0,
) -> list[dict[str, Any]]:
    """Every horizon of one robot and protocol."""
    m = load(name)
    ts = float(m.opt.timestep)
    t0 = time.perf_counter()
    pilot = make_controller(m, protocol, seed=PILOT_SEED, hold_steps=HOLD[protocol])
    auto = Predictor(m, pilot=PilotOptions(controller=pilot, seed=PILOT_SEED))
    bounds, points = auto.bounds, auto.bound_points
    pilot_s = time.perf_counter() - t0
    plannable = m.nmocap == 0
    longest = max(max(round((ts if h is None else h) / ts), 1) for h in horizons)
    fracs = EVERY if every_frac is None else every_frac
    profiles: dict[str, np.ndarray | None] = {}
    profile_s: dict[str, float] = {}
    for tag, knows in SIDES.items():
        if knows is not None and plannable:
            profiles[tag], profile_s[tag] = pilot_profile(
                m, protocol, points, _knots(longest, fracs[tag], ts)[1], knows
            )
    rows = []
    for h in horizons:
        horizon = ts if h is None else h
        t0 = time.perf_counter()
        row = run_ab(m, bounds, protocol, horizon, steps, profiles, reference, every_frac, floor)
        row |= {
            "robot": name,
            "protocol": protocol,
            "one_period": h is None,
            "plannable": plannable,
            "every_frac": fracs,
            "floor_m": floor,
            "pilot_s": pilot_s,
            "profile_s": profile_s,
            "profile_max_m": {t: float(v.max()) for t, v in profiles.items() if v is not None},
            "seconds": time.perf_counter() - t0,
        }
        rows.append(row)
        a, tr, b = row["A"], row["T"], row["B"]
        print(
            f"{name:6s} {protocol:6s} H {1e3 * horizon:5.1f} ms: oracle {100 * a['oracle']:5.2f} %"
            f", standing A {100 * a['standing']:6.2f} % T {100 * tr['standing']:6.2f} % B "
            f"{100 * b['standing']:6.2f} %, short held A {a['short_held']} T "
            f"{tr['short_held']} B {b['short_held']}, breaks A {a['plan_breaks']} T "
            f"{tr['plan_breaks']}, cost A {_cost(a):.2f} T {_cost(tr):.2f} B "
            f"{_cost(b):.2f}, planner A {a.get('planner', 0.0):.1f}, {row['seconds']:.1f} s"
            + (
                ""
                if row["reference_standing"] is None
                else f", exact reference {100 * row['reference_standing']:.2f} %"
            ),
            file=sys.stderr,
            flush=True,
        )
    return rows


# ----------------------------------------------------------------------------- tables


def _ratio(side: dict[str, Any]) -> float:
    return side["standing"] / side["oracle"] if side["oracle"] > 0 else float("inf")


def _x(value: float) -> str:
    if value == float("inf"):
        return "inf"
    return f"{value:.1f}x" if value < 10 else f"{value:.0f}x"


def _label(row: dict[str, Any]) -> str:
    ms = f"{1e3 * row['horizon_s']:g} ms"
    return f"1 step ({ms})" if row["one_period"] else ms


def _cost(side: dict[str, Any]) -> float:
    """The predictor's cost with ``set_plan`` amortised (:func:`_amortised`; the mean over the
    run for rows measured before that was kept)."""
    return float(side.get("amortised", side["mean"]))


def _planner(side: dict[str, Any]) -> float:
    """The planner's cost over ``mj_step`` (a plan's median time over its period)."""
    return float(side.get("planner", side["planner_mean"]))


def _three(r: dict[str, Any], f: Any) -> str:
    return " / ".join(f(r[t]) for t in SIDES)


def _med(rs: list[dict[str, Any]], tag: str, key: str) -> float:
    """The median over the rows ``rs`` of one side's (``tag``'s) ``key``, infinities left out
    (``"ratio"``, ``"cost"`` and ``"planner"``: :func:`_ratio`, :func:`_cost`, :func:`_planner`)."""
    of = {"ratio": _ratio, "cost": _cost, "planner": _planner}.get(key, lambda side: side[key])
    vals = [v for v in (of(r[tag]) for r in rs) if v != float("inf")]
    return float(np.median(vals)) if vals else float("nan")


def _planned(rs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [r for r in rs if r["plannable"]]


def _sums(rs: list[dict[str, Any]], f: Any, sides: tuple[str, ...] = SIDES) -> str:
    return " / ".join(str(sum(f(r[t]) for r in rs)) for t in sides)


_ROBOT_COLUMNS: list[Column] = [
    ("robot", lambda r: r["robot"] + ("" if r["plannable"] else " (no plan: mocap)")),
    ("horizon", _label),
    ("oracle %", lambda r: f"{100 * r['A']['oracle']:.2f}"),
    ("standing %", lambda r: _three(r, lambda s: f"{100 * s['standing']:.1f}")),
    ("standing / oracle", lambda r: _three(r, lambda s: _x(_ratio(s)))),
    ("onsets", lambda r: str(r["A"]["onsets"])),
    ("lead < H, bounds held", lambda r: _three(r, lambda s: str(s["short_held"]))),
    (
        "lead < H, after violation + at start",
        lambda r: _three(r, lambda s: f"{s['short_violation']}+{s['short_start']}"),
    ),
    ("plan breaks", lambda r: f"{r['A']['plan_breaks']} / {r['T']['plan_breaks']}"),
    ("predictor / mj_step (incl. set_plan)", lambda r: _three(r, lambda s: f"{_cost(s):.2f}")),
    ("predictor / mj_step (median step)", lambda r: _three(r, lambda s: f"{s['median']:.2f}")),
    (
        "planner / mj_step (planner's)",
        lambda r: f"{_planner(r['A']):.1f} / {_planner(r['T']):.1f}" if r["plannable"] else "",
    ),
]
"""The per-robot table: one row a run; a cell of three values reads: planner knows the next
waypoint / knows the trajectory / no plan."""

_MEDIAN_COLUMNS: list[Column] = [
    ("horizon", lambda g: g[0]),
    (
        "standing / oracle, all robots",
        lambda g: " / ".join(_x(_med(g[1], t, "ratio")) for t in SIDES),
    ),
    (
        "standing / oracle, robots with a plan",
        lambda g: " / ".join(_x(_med(_planned(g[1]), t, "ratio")) for t in SIDES),
    ),
    (
        "predictor / mj_step (incl. set_plan)",
        lambda g: " / ".join(f"{_med(g[1], t, 'cost'):.2f}" for t in SIDES),
    ),
    (
        "predictor / mj_step (median step)",
        lambda g: " / ".join(f"{_med(g[1], t, 'median'):.2f}" for t in SIDES),
    ),
    (
        "planner / mj_step (planner's)",
        lambda g: " / ".join(f"{_med(_planned(g[1]), t, 'planner'):.1f}" for t in ("A", "T")),
    ),
    ("lead < H while held (sum)", lambda g: _sums(g[1], lambda s: s["short_held"])),
    (
        "lead < H after violation + at start (sum)",
        lambda g: _sums(g[1], lambda s: s["short_violation"] + s["short_start"]),
    ),
    ("plan breaks (sum)", lambda g: _sums(g[1], lambda s: s["plan_breaks"], ("A", "T"))),
]
"""The medians over robots: one row a horizon, ``(label, its runs)``."""


def markdown(rows: list[dict[str, Any]], protocol: str) -> str:
    """One protocol: the per-robot table, then the medians over robots at each horizon.

    Each cell with three values reads: planner knows the next waypoint / knows the trajectory /
    no plan."""
    mine = [r for r in rows if r["protocol"] == protocol]
    return (
        columns_table(_ROBOT_COLUMNS, mine)
        + "\n\nMedian over robots (each cell: knows the next waypoint / knows the trajectory / no "
        "plan):\n\n" + columns_table(_MEDIAN_COLUMNS, by_label(mine, _label))
    )


def horizon_table(rows: list[dict[str, Any]], protocol: str) -> str:
    """Standing over the oracle by robot (rows) and horizon (columns), each cell: knows the
    trajectory / knows the next waypoint / no plan; and the oracle (%) under each horizon."""
    mine = [r for r in rows if r["protocol"] == protocol]
    labels = list(dict.fromkeys(_label(r) for r in sorted(mine, key=lambda r: r["horizon_s"])))
    body = []
    for name in dict.fromkeys(r["robot"] for r in mine):
        at = {_label(r): r for r in mine if r["robot"] == name}
        body.append(
            [name]
            + [
                (
                    " / ".join(_x(_ratio(at[lb][t])) for t in ("T", "A", "B"))
                    + f" ({100 * at[lb]['A']['oracle']:.2g} %)"
                )
                if lb in at
                else ""
                for lb in labels
            ]
        )
    meds = ["median"]
    for lb in labels:
        rs = [r for r in mine if _label(r) == lb]
        vals = [
            float(np.median([v for v in (_ratio(r[t]) for r in rs) if v != float("inf")]))
            for t in ("T", "A", "B")
        ]
        meds.append(" / ".join(_x(v) for v in vals))
    return table(["robot", *labels], [*body, meds])


def plot(rows: list[dict[str, Any]], path: Path, robots: tuple[str, ...]) -> None:
    """Standing with a plan, without, and the oracle against the horizon (log-log)."""
    lines: list[Line] = [
        (lambda r: 100 * r["T"]["standing"], "-o", lambda n: f"{n} trajectory", {}),
        (lambda r: 100 * r["A"]["standing"], "-.x", lambda n: "waypoint", {"alpha": 0.8}),
        (lambda r: 100 * r["B"]["standing"], ":^", lambda n: "no plan", {"alpha": 0.7}),
        (
            lambda r: max(100 * r["A"]["oracle"], 1e-3),
            "--s",
            lambda n: "oracle",
            {"alpha": 0.6, "markersize": 3},
        ),
    ]
    title = (
        "Standing in alarm: plan knows the trajectory (solid), the next waypoint (dash-dot), "
        "no plan (dotted), oracle (dashed)"
    )
    legend = {"ncol": len(robots), "loc": "upper center", "bbox_to_anchor": (0.5, -0.14)}
    plot_against_horizon(rows, path, robots, lines, title, figsize=(7.5, 5.8), legend=legend)


def main(argv: list[str] | None = None) -> None:
    ap = robots_parser(__doc__, "plans-standing.png")
    ap.add_argument("--horizons", nargs="+", type=float, default=None, help="seconds")
    ap.add_argument("--steps", type=int, default=2000, help="physics steps a run")
    ap.add_argument("--no-random", action="store_true", help="skip the random-held protocol")
    ap.add_argument("--protocols", nargs="+", choices=PROTOCOLS, default=None)
    ap.add_argument(
        "--every",
        type=float,
        nargs=2,
        default=(EVERY["A"], EVERY["T"]),
        metavar=("WAYPOINT", "TRAJECTORY"),
        help="each planner's replanning period, a fraction of the horizon",
    )
    ap.add_argument(
        "--reference", action="store_true", help="judge the plans with exact geometry too"
    )
    ap.add_argument(
        "--floor",
        type=float,
        default=0.0,
        help="metres added to every planned deviation (a tracking error declared on top)",
    )
    ap.add_argument(
        "--tables", type=Path, nargs="+", default=None, help="print the tables of saved rows"
    )
    args = ap.parse_args(argv)
    if args.tables is not None:
        rows = []
        for path in args.tables:
            saved = json.loads(path.read_text())
            print(f"\n## {path.name} ({saved.get('steps', '?')} steps a run)")
            for protocol in dict.fromkeys(r["protocol"] for r in saved["rows"]):
                floor = saved["rows"][0].get("floor_m", 0.0)
                extra = f", {1e3 * floor:g} mm added to every deviation" if floor else ""
                print(f"\n### {protocol}{extra}\n")
                print(markdown(saved["rows"], protocol))
                if len({r["horizon_s"] for r in saved["rows"]}) > 2:
                    print(
                        "\nStanding / oracle, trajectory / waypoint / none (oracle):\n\n"
                        + horizon_table(saved["rows"], protocol)
                    )
            if not saved["rows"][0].get("floor_m", 0.0):
                rows += saved["rows"]
        if args.plot is not None:
            robots = tuple(n for n in PLOTTED if any(r["robot"] == n for r in rows))
            plot(rows, args.plot, robots)
        return
    horizons = HORIZONS if args.horizons is None else tuple(args.horizons)
    protocols = (
        tuple(args.protocols) if args.protocols else PROTOCOLS[:1] if args.no_random else PROTOCOLS
    )
    every = dict(zip("AT", args.every, strict=True))

    def keep(rows: list[dict]) -> None:
        if args.json is not None:
            args.json.write_text(json.dumps({"rows": rows, "steps": args.steps}) + "\n")

    rows = over_robots(
        ap,
        args,
        protocols,
        lambda name, protocol: measure(
            name, protocol, horizons, args.steps, args.reference, every, args.floor
        ),
        keep,
    )
    report(args, rows, protocols, markdown, lambda rows, robots: plot(rows, args.plot, robots))


if __name__ == "__main__":
    main()
