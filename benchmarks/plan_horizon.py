"""Warning time with flight plans: a planner feeding ``Predictor.set_plan``, against no plan.

    python benchmarks/plan_horizon.py --json plans.json     # docs/plans.md's tables and plot
    python benchmarks/plan_horizon.py --robots panda go1 --horizons 0.05 0.2 --steps 1000
    python benchmarks/plan_horizon.py --tables plans.json   # the tables again, from saved rows

For each robot (``benchmarks/horizon.py``'s seven), protocol and alarm horizon ``H`` (one
predictor period, then 10 to 500 ms), one rollout (rollout seed 0, 2,000 steps) stepped by two
predictors built alike (``accel="auto"`` from the pilot horizon.py uses, ``alarm_horizon=H``,
latency 0), each with its own :class:`~dua_mujoco.mj.monitor.Monitor` measuring against ``H``:

- **A** follows plans: every ``R = max(H/4, 1 step)`` physics steps the *planner* makes one and
  gives it with ``set_plan``;
- **B** follows the motion bounds alone (today's predictor).

The two are stepped in turn on the same ``MjData``, their order swapped every step, each timed
with ``mj_step``: their costs are an A/B in one run. ``set_plan``'s own time is A's (the runtime
builds the plan's kinematics and evaluates every pair again at the next step).

**The planner** knows the command up to its next waypoint and nothing after: a copy of the
driver whose next random point continues the current segment (``smooth``) or holds the current
control (``random``), rolled with :func:`~dua_mujoco.mj.plans.plan_from_controls` from the
current state for ``R + n + 2`` knots (``n`` the horizon's steps: the plan covers every step
until the next plan and its horizon). Up to the waypoint it is the simulation bit for bit
(deviation 0); past it, each body's deviation is the pilot's largest at that many steps past a
waypoint (:func:`~dua_mujoco.mj.plans.deviation_profile` at the predictor's bound points), made
monotone, times 2. The pilot runs the same planner, one plan every :data:`PILOT_EVERY` steps, on
the pilot's own seed (``1_000_003``, the rollout's is 0). The planner's time (the copy, the
rollout, the deviation rows) is reported apart and labelled the planner's: an MPC or a planner
pays it anyway.

**Measured** (each monitor's report against ``H``): the standing fraction (geom pairs in alarm),
the oracle (geom pairs that do touch within ``H``: the floor), their ratio, the onsets with less
lead than ``H`` split into while the bounds held / after a violation / at the start (a plan's
deviation broken counts as a violation of the body that broke it, from the step the runtime
found it), the plan breaks, and the costs: predictor over ``mj_step`` (median a step; and the
mean with ``set_plan``, which a median hides when ``R > 2``), the planner's over ``mj_step``
(mean).

Models with mocap bodies (fetch) are refused by ``set_plan``: their A runs without a plan (the
rows say so). Targets of issue 34 (smooth protocol): at 50 ms median standing/oracle <= 5x and
predictor <= 0.5x ``mj_step``, at 200 ms <= 10x, no onset with less lead than ``H`` while the
bounds held. The random-held protocol is reported beside, not targeted.
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
import time
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from dua_mujoco.mj.accumulators import Durations
from dua_mujoco.mj.monitor import Monitor
from dua_mujoco.mj.options import PilotOptions
from dua_mujoco.mj.plans import PilotPlan, deviation_profile, plan_deviation, plan_from_controls
from dua_mujoco.mj.predictor import Predictor
from dua_mujoco.mj.report import build_report
from dua_mujoco.mj.scenes import SceneController, make_controller

sys.path.insert(0, str(Path(__file__).parent))
from bench import table
from horizon import EXTRA, HOLD, PILOT_SEED, ROBOT_NAMES, ROLLOUT_SEED, load
from robots import ROBOTS

HORIZONS = (None, 0.010, 0.020, 0.050, 0.100, 0.200, 0.500)
"""Alarm horizons (s); None is one predictor period."""
PROTOCOLS = ("smooth", "random")
SAFETY = 2.0
PILOT_STEPS = 2000
PILOT_EVERY = 10
"""Physics steps between two plans of the planner's pilot."""
PLOTTED = ("panda", "ur5e", "go1", "h1")


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
    model: mujoco.MjModel, data: mujoco.MjData, driver: SceneController, knots: int
) -> tuple[np.ndarray, int]:
    """The plan of ``knots`` knots from ``data`` knowing ``driver``'s command up to its next
    waypoint, and the waypoint's knot (the last knot the plan is exact at)."""
    policy = copy.deepcopy(driver)
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
            q, origin = segment_plan(model, d, driver, knots)
            plans.append(PilotPlan(len(rows) - 1, q, origin))
        driver(model, d)
        mujoco.mj_step(model, d)
        rows.append(d.qpos.copy())
    profile = deviation_profile(model, np.array(rows), plans, points=points, safety=SAFETY)
    return profile, time.perf_counter() - t0


# ----------------------------------------------------------------------------- the runs


def _knots(n: int) -> tuple[int, int]:
    """``(R, knots)`` for a horizon of ``n`` steps."""
    every = max(n // 4, 1)
    return every, every + n + 2


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
    profile: np.ndarray | None,
    reference: bool = False,
) -> dict[str, Any]:
    """One rollout, predictors A (plans) and B (none) interleaved (module docstring); with
    ``reference``, A's plans judged with exact geometry too (:class:`ExactReference`)."""
    h = float(model.opt.timestep)
    n = max(round(horizon / h), 1)
    every, knots = _knots(n)
    d = mujoco.MjData(model)
    mujoco.mj_forward(model, d)
    driver = make_controller(model, protocol, seed=ROLLOUT_SEED, hold_steps=HOLD[protocol])
    preds = [Predictor(model, accel=bounds, alarm_horizon=horizon) for _ in range(2)]
    mons = [Monitor(p, series=False, warning_horizon=horizon) for p in preds]
    a = preds[0]
    ref = ExactReference(model, a, n) if reference and profile is not None else None
    driver(model, d)
    mujoco.mj_step(model, d)
    for mon in mons:
        mon.start(d)
    t_mj = np.zeros(steps)
    t_step = np.zeros((2, steps))
    t_set = t_planner = 0.0
    plans = 0
    ok = np.ones(model.nbody, dtype=bool)

    def replan() -> tuple[float, float]:
        t0 = time.perf_counter()
        q, origin = segment_plan(model, d, driver, knots)
        assert profile is not None
        dev = plan_deviation(profile, knots, origin=origin)
        t1 = time.perf_counter()
        a.set_plan(q, deviation=dev, start=float(d.time))
        t2 = time.perf_counter()
        if ref is not None:
            ref.plan(q, dev, mons[0].physics_step)
        return t1 - t0, t2 - t1

    if profile is not None:
        t_planner, t_set = replan()
        plans += 1
    for k in range(1, steps + 1):
        driver(model, d)
        t0 = time.perf_counter()
        mujoco.mj_step(model, d)
        t_mj[k - 1] = time.perf_counter() - t0
        alarms: list[Any] = [None, None]
        for i in (0, 1) if k % 2 else (1, 0):
            t0 = time.perf_counter()
            alarms[i] = preds[i].step(d)
            t_step[i, k - 1] = time.perf_counter() - t0
        if profile is not None:
            # A body beyond its deviation is a violation of its hypotheses from this step on
            # (the monitor counts the step it observes next).
            now = np.asarray(a._rt.plan_ok, dtype=bool)
            broke = np.flatnonzero(ok & ~now)
            if broke.size:
                mons[0].last_violation[broke] = mons[0].physics_step + 1
            ok = now
        if ref is not None:
            ref.step(mons[0].physics_step)
        for mon, al in zip(mons, alarms, strict=True):
            mon.observe(d, al)
        if profile is not None and k % every == 0:
            dp, ds = replan()
            t_planner += dp
            t_set += ds
            plans += 1
            ok = np.ones(model.nbody, dtype=bool)
    row: dict[str, Any] = {
        "horizon_s": horizon,
        "steps_horizon": n,
        "plan_every": every if profile is not None else None,
        "plan_knots": knots if profile is not None else None,
        "plans": plans,
        "plan_breaks": a.plan_breaks,
        "plan_queries_per_step": int(a._rt.plan_queries) / steps,
        "mj_step_us": float(np.median(t_mj)) * 1e6,
        "planner_mean": t_planner / float(t_mj.sum()),
        "set_plan_us": t_set / max(plans, 1) * 1e6,
        "reference_standing": None if ref is None else ref.standing,
    }
    for i, tag in enumerate(("A", "B")):
        mons[i].finish()
        dur_mj, dur_p = Durations(), Durations()
        for x in t_mj:
            dur_mj.add(float(x))
        for x in t_step[i]:
            dur_p.add(float(x))
        rep = build_report(mons[i], "", False, dur_mj, dur_p, interrupted=False)
        extra = t_set if i == 0 else 0.0
        row[tag] = {
            "standing": rep.standing_alarm_fraction,
            "oracle": rep.oracle_fraction,
            "onsets": rep.contact_onsets,
            "missed": rep.missed_onsets,
            "missed_valid": rep.missed_onsets_valid_bounds,
            "short": rep.short_lead_onsets,
            "short_held": rep.short_lead_bounds_held,
            "short_violation": rep.short_lead_after_violation,
            "short_start": rep.short_lead_at_start,
            "lead_p10_s": rep.lead_p10_s,
            "lead_median_s": rep.lead_median_s,
            "violations": rep.bound_violations,
            "evals_per_step": rep.evals_per_step,
            "median": float(np.median(t_step[i]) / np.median(t_mj)),
            "mean": float((t_step[i].sum() + extra) / t_mj.sum()),
        }
    return row


def measure(
    name: str,
    protocol: str,
    horizons: tuple[float | None, ...],
    steps: int,
    reference: bool = False,
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
    profile, profile_s = (
        pilot_profile(m, protocol, points, _knots(longest)[1]) if plannable else (None, 0.0)
    )
    rows = []
    for h in horizons:
        horizon = ts if h is None else h
        t0 = time.perf_counter()
        row = run_ab(m, bounds, protocol, horizon, steps, profile, reference)
        row |= {
            "robot": name,
            "protocol": protocol,
            "one_period": h is None,
            "plannable": plannable,
            "pilot_s": pilot_s,
            "profile_s": profile_s,
            "profile_max_m": None if profile is None else float(profile.max()),
            "seconds": time.perf_counter() - t0,
        }
        rows.append(row)
        a, b = row["A"], row["B"]
        print(
            f"{name:6s} {protocol:6s} H {1e3 * horizon:5.1f} ms: standing A "
            f"{100 * a['standing']:6.2f} % B {100 * b['standing']:6.2f} %, oracle "
            f"{100 * a['oracle']:5.2f} %, short held "
            f"A {a['short_held']} B {b['short_held']}, breaks {row['plan_breaks']}, cost A "
            f"{a['median']:.2f} B {b['median']:.2f} planner {row['planner_mean']:.2f}, "
            f"{row['seconds']:.1f} s"
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


def _short(side: dict[str, Any]) -> str:
    return (
        f"{side['short']} ({side['short_held']} / {side['short_violation']} / "
        f"{side['short_start']})"
    )


def markdown(rows: list[dict[str, Any]], protocol: str) -> str:
    """One protocol: the per-robot table, then the medians over robots at each horizon."""
    mine = [r for r in rows if r["protocol"] == protocol]
    body = []
    for r in mine:
        a, b = r["A"], r["B"]
        body.append(
            [
                r["robot"] + ("" if r["plannable"] else " (no plan: mocap)"),
                _label(r),
                f"{100 * a['oracle']:.2f}",
                f"{100 * a['standing']:.1f} / {100 * b['standing']:.1f}",
                f"{_x(_ratio(a))} / {_x(_ratio(b))}",
                str(a["onsets"]),
                f"{_short(a)} / {_short(b)}",
                str(r["plan_breaks"]),
                f"{a['median']:.2f} / {b['median']:.2f}",
                f"{a['mean']:.2f}",
                f"{r['planner_mean']:.1f}" if r["plannable"] else "",
            ]
        )
    out = table(
        [
            "robot",
            "horizon",
            "oracle %",
            "standing % plan / none",
            "standing / oracle plan / none",
            "onsets",
            "lead < horizon (held / violation / start) plan / none",
            "plan breaks",
            "predictor / mj_step median plan / none",
            "plan mean with set_plan",
            "planner / mj_step (planner's)",
        ],
        body,
    )
    medians = []
    for label in dict.fromkeys(_label(r) for r in mine):
        at = [r for r in mine if _label(r) == label]
        planned = [r for r in at if r["plannable"]]

        def med(rs: list[dict[str, Any]], tag: str, key: str) -> float:
            vals = [_ratio(r[tag]) if key == "ratio" else r[tag][key] for r in rs]
            vals = [v for v in vals if v != float("inf")]
            return float(np.median(vals)) if vals else float("nan")

        medians.append(
            [
                label,
                f"{_x(med(at, 'A', 'ratio'))} ({_x(med(planned, 'A', 'ratio'))})",
                _x(med(at, "B", "ratio")),
                f"{med(at, 'A', 'median'):.2f} ({med(planned, 'A', 'median'):.2f})",
                f"{med(at, 'B', 'median'):.2f}",
                f"{med(planned, 'A', 'mean'):.2f}",
                f"{float(np.median([r['planner_mean'] for r in planned])):.1f}" if planned else "",
                str(sum(r["A"]["short_held"] for r in at)),
                str(sum(r["B"]["short_held"] for r in at)),
                str(sum(r["A"]["short_violation"] for r in at)),
            ]
        )
    out += "\n\nMedian over robots (in brackets: the robots with a plan only):\n\n" + table(
        [
            "horizon",
            "standing / oracle, plan",
            "standing / oracle, none",
            "predictor / mj_step, plan",
            "predictor / mj_step, none",
            "plan mean with set_plan",
            "planner / mj_step (planner's)",
            "onsets short while held, plan (all robots)",
            "onsets short while held, none",
            "onsets short after a violation, plan",
        ],
        medians,
    )
    return out


def plot(rows: list[dict[str, Any]], path: Path, robots: tuple[str, ...]) -> None:
    """Standing with a plan, without, and the oracle against the horizon (log-log)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.8), dpi=120)
    mine = [r for r in rows if r["protocol"] == "smooth"]
    for i, name in enumerate(robots):
        at = sorted((r for r in mine if r["robot"] == name), key=lambda r: r["horizon_s"])
        if not at:
            continue
        h = [1e3 * r["horizon_s"] for r in at]
        c = f"C{i}"
        ax.plot(h, [100 * r["A"]["standing"] for r in at], "-o", color=c, label=f"{name} plan")
        ax.plot(
            h, [100 * r["B"]["standing"] for r in at], ":^", color=c, alpha=0.7, label="no plan"
        )
        ax.plot(
            h,
            [max(100 * r["A"]["oracle"], 1e-3) for r in at],
            "--s",
            color=c,
            alpha=0.6,
            markersize=3,
            label="oracle",
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("alarm horizon (ms)")
    ax.set_ylabel("% of active geom pairs (mean over steps)")
    ax.set_title("Standing in alarm with a plan (solid), without (dotted), oracle (dashed)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=len(robots), loc="lower right")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", nargs="+", default=list(ROBOT_NAMES))
    ap.add_argument("--horizons", nargs="+", type=float, default=None, help="seconds")
    ap.add_argument("--steps", type=int, default=2000, help="physics steps a run")
    ap.add_argument("--no-random", action="store_true", help="skip the random-held protocol")
    ap.add_argument("--json", type=Path, default=None, help="write the rows here")
    ap.add_argument(
        "--reference", action="store_true", help="judge the plans with exact geometry too"
    )
    ap.add_argument("--tables", type=Path, default=None, help="print the tables of saved rows")
    ap.add_argument(
        "--plot",
        type=Path,
        default=Path(__file__).resolve().parent.parent / "docs" / "img" / "plans-standing.png",
    )
    args = ap.parse_args(argv)
    if args.tables is not None:
        saved = json.loads(args.tables.read_text())
        rows = saved["rows"]
        for protocol in dict.fromkeys(r["protocol"] for r in rows):
            print(f"\n### {protocol} ({saved.get('steps', '?')} steps a run)\n")
            print(markdown(rows, protocol))
        plot(rows, args.plot, tuple(n for n in PLOTTED if any(r["robot"] == n for r in rows)))
        return
    horizons = HORIZONS if args.horizons is None else tuple(args.horizons)
    protocols = PROTOCOLS[:1] if args.no_random else PROTOCOLS
    missing = [n for n in args.robots if n not in ROBOTS and n not in EXTRA]
    if missing:
        ap.error(f"unknown robots {missing}; known: {', '.join([*ROBOTS, *EXTRA])}")
    start = time.perf_counter()
    rows = []
    for name in args.robots:
        for protocol in protocols:
            try:
                rows += measure(name, protocol, horizons, args.steps, args.reference)
            except ModuleNotFoundError as exc:
                print(f"{name}: skipped, not installed ({exc})", file=sys.stderr)
                break
            if args.json is not None:  # a long run keeps what it measured
                args.json.write_text(json.dumps({"rows": rows, "steps": args.steps}) + "\n")
    took = time.perf_counter() - start
    for protocol in protocols:
        print(f"\n### {protocol} ({args.steps} steps a run)\n")
        print(markdown(rows, protocol))
    print(f"\n{len(rows)} runs in {took / 60:.1f} min", flush=True)
    if args.json is not None:
        args.json.write_text(
            json.dumps({"rows": rows, "steps": args.steps, "minutes": took / 60}, indent=1) + "\n"
        )
    if rows:
        plot(rows, args.plot, tuple(n for n in PLOTTED if n in args.robots) or tuple(args.robots))
        print(f"plot written to {args.plot}")


if __name__ == "__main__":
    main()
