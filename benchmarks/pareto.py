"""Alarms worth acting on: standing alarm fraction against work, every scheduler and peer.

    python benchmarks/pareto.py                      # the section of docs/benchmarks.md
    python benchmarks/pareto.py --quick              # smoke run: 200 steps, two scenes
    python benchmarks/pareto.py --scenes two_arms gym/ant --steps 500 --out /tmp/img

One rollout per configuration (pilot seed 99, rollout seed 0, ``accel="auto"``, period 1) on
each scene; every configuration of a scene sees the same controls, hence the same trajectory.
Configurations: ``dua`` (slots_per_bucket 1, 4, 16, 64), ``deadline`` (the default: no cap,
alarm backoff 8; then backoff 1, which gives select-all's alarms exactly; caps 16 and 64),
``select-all``, each with the old urgency (``static="sphere"``), the new (``static="shape"``,
and the exact level on top (``exact=True``, the default now); then the swept-sphere
broadphase (sort-and-sweep) and MuJoCo's gap-inflated collision, on the old and new coverings.

The standing alarm fraction of a predictor is ``RunReport.standing_alarm_fraction``; that of a
peer is the mean over steps of (geom pairs it flags at that step) / (active geom pairs). Peers
have no tau evaluations; their cost is the median microseconds of their step (``mj_collision``
alone for MuJoCo's, as in ``dua_mujoco.experiments.peers``). Timings are medians; ratios mean
more than single figures on a shared machine. Prints markdown tables and writes
``<out>/pareto-<scene>.png``.
"""

from __future__ import annotations

import argparse
import importlib.resources
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from dua_mujoco.experiments.peers.broadphase import BroadphaseScene
from dua_mujoco.experiments.peers.mujoco_collision import MujocoScene
from dua_mujoco.experiments.peers.scene_context import SceneContext
from dua_mujoco.measure.rollout import run
from dua_mujoco.models.scenes import load_scene, make_controller
from dua_mujoco.runtime.predictor import Predictor

sys.path.insert(0, str(Path(__file__).parent))
from bench import bare_loop, table

from dua_mujoco.build.options import CoveringOptions, PilotOptions, ScheduleOptions, UrgencyOptions

SCENES = ("two_arms", "traffic", "clutter", "gym/humanoid", "gym/ant", "dmc/humanoid_CMU")
QUICK_SCENES = ("two_arms", "gym/ant")
PILOT_SEED = 99
ROLLOUT_SEED = 0

# Urgency variants: label -> Predictor options.
URGENCIES: dict[str, dict] = {
    "old (sphere)": {
        "covering": CoveringOptions(static="sphere"),
        "urgency": UrgencyOptions(exact=False),
    },
    "new (shape)": {"urgency": UrgencyOptions(exact=False)},
    "exact": {},
}
# Scheduler configurations: label -> Predictor options.
SCHEDULES: dict[str, dict] = {
    "dua q=1": {"schedule": ScheduleOptions(kind="dua", slots_per_bucket=1)},
    "dua q=4": {"schedule": ScheduleOptions(kind="dua", slots_per_bucket=4)},
    "dua q=16": {"schedule": ScheduleOptions(kind="dua", slots_per_bucket=16)},
    "dua q=64": {"schedule": ScheduleOptions(kind="dua", slots_per_bucket=64)},
    "deadline": {"schedule": "deadline"},
    "deadline backoff=1": {"schedule": ScheduleOptions(alarm_backoff=1)},
    "deadline cap=64": {"schedule": ScheduleOptions(max_evals_per_step=64)},
    "deadline cap=16": {"schedule": ScheduleOptions(max_evals_per_step=16)},
    "select-all": {"schedule": "select-all"},
}
DEFAULT = "deadline"  # the Predictor's default schedule


def _external(name: str) -> str:
    group, stem = name.split("/")
    if group == "gym":
        return str(importlib.resources.files("gymnasium") / "envs/mujoco/assets" / f"{stem}.xml")
    import dm_control

    return str(Path(dm_control.__file__).parent / "suite" / f"{stem}.xml")


def _load(scene: str) -> tuple[mujoco.MjModel, mujoco.MjData]:
    return load_scene(scene if "/" not in scene else _external(scene))


@dataclass
class Row:
    scene: str
    config: str
    urgency: str
    fraction: float
    evals: float | None  # tau evaluations a step (None for peers)
    us: float  # median microseconds a step
    candidates: float | None = None  # broadphase candidates a step
    deferred: float = 0.0  # pairs a capped deadline step left waiting, mean a step
    misses_valid: int = 0
    unfiltered: int = 0
    pairs: int = 0
    mj_us: float = 0.0
    pareto_evals: bool = False
    pareto_us: bool = False


# ----------------------------------------------------------------------------- predictors


def measure_predictor(
    scene: str, config: str, urgency: str, steps: int, bounds: dict
) -> tuple[Row, Predictor]:
    """One monitored rollout of one scheduler configuration with one urgency."""
    m, d = _load(scene)
    opts = dict(URGENCIES[urgency], **SCHEDULES[config])
    # The pilot depends only on the covering (bounds are per body, measured on its sphere
    # centres): run it once per urgency and hand the same bounds to the other schedules.
    accel = bounds.get(urgency, "auto")
    p = Predictor(
        m,
        accel=accel,
        **opts,
        pilot=PilotOptions(controller=make_controller(m, "random", seed=PILOT_SEED)),
    )
    bounds.setdefault(urgency, p.bounds)
    # RunReport.evals_per_step counts the pairs whose verdict a step renewed, which for a
    # capped deadline includes the pairs it deferred without evaluating: count tau evaluations
    # from the scheduler instead (the sphere level only: the exact looks show in
    # the microseconds, not here).
    sums = {"deferred": 0, "evals": 0}

    def on_step(k: int, data: mujoco.MjData, alarms: object, monitor: object) -> None:
        if alarms is not None:
            sums["deferred"] += int(alarms.deferred)  # type: ignore[attr-defined]
            sums["evals"] += p.evaluations_per_step

    rep = run(
        m,
        d,
        p,
        steps=steps,
        controller=make_controller(m, "random", seed=ROLLOUT_SEED),
        progress=False,
        series=False,
        on_step=on_step,
    )
    row = Row(
        scene=scene,
        config=config,
        urgency=urgency,
        fraction=rep.standing_alarm_fraction,
        evals=sums["evals"] / max(rep.predictor_steps, 1),
        us=rep.predictor_us_per_step,
        deferred=sums["deferred"] / max(rep.predictor_steps, 1),
        misses_valid=rep.missed_onsets_valid_bounds,
        unfiltered=rep.unfiltered_contacts,
        pairs=rep.geom_pairs,
        mj_us=rep.mj_step_us_per_step,
    )
    return row, p


# ----------------------------------------------------------------------------- peers


def measure_peers(scene: str, urgency: str, steps: int, bounds: dict) -> list[Row]:
    """The broadphase and MuJoCo's gap-inflated collision watch one rollout on one covering."""
    m, d = _load(scene)
    accel = bounds.get(urgency, "auto")
    p = Predictor(
        m,
        accel=accel,
        **URGENCIES[urgency],
        pilot=PilotOptions(controller=make_controller(m, "random", seed=PILOT_SEED)),
    )
    bounds.setdefault(urgency, p.bounds)
    # The peers get this predictor's pairs and horizon (latency 0: like with like); static
    # geoms as shapes are tested directly by the broadphase, as planes are.
    ctx = SceneContext(m, predictor=p)
    sweep = BroadphaseScene(ctx, "sweep")
    gap = MujocoScene(ctx, "gap")
    ctrl = make_controller(m, "random", seed=ROLLOUT_SEED)
    ctrl(m, d)
    mujoco.mj_step(m, d)
    p.reset(d)  # binds the static shapes' records to this data
    npair = max(ctx.npairs, 1)
    frac = {"sweep": 0.0, "gap": 0.0}
    t_sweep, t_gap, cands = [], [], []
    for _ in range(steps):
        ctrl(m, d)
        gap.set_snapshot(d)
        mujoco.mj_step(m, d)
        t0 = time.perf_counter()
        flagged, _, _, cand = sweep.step(d)
        t_sweep.append(time.perf_counter() - t0)
        cands.append(cand)
        frac["sweep"] += flagged.size / npair
        frac["gap"] += gap.step(d)[0].size / npair
        t_gap.append(gap.collision_s)
    return [
        Row(
            scene,
            "sweep broadphase",
            urgency,
            frac["sweep"] / steps,
            None,
            float(np.median(t_sweep) * 1e6),
            candidates=float(np.mean([c or 0.0 for c in cands])),
            pairs=ctx.npairs,
        ),
        Row(
            scene,
            "MuJoCo gap",
            urgency,
            frac["gap"] / steps,
            None,
            float(np.median(t_gap) * 1e6),
            pairs=ctx.npairs,
        ),
    ]


# ----------------------------------------------------------------------------- analysis


def mark_pareto(rows: list[Row]) -> None:
    """Flag rows that no other row beats on both the fraction and the work (evals, us)."""

    def front(xs: list[float]) -> list[bool]:
        out = []
        for i, r in enumerate(rows):
            xi = xs[i]
            out.append(
                not any(
                    (xs[j] <= xi and o.fraction <= r.fraction)
                    and (xs[j] < xi or o.fraction < r.fraction)
                    for j, o in enumerate(rows)
                    if j != i and not np.isnan(xs[j])
                )
                and not np.isnan(xi)
            )
        return out

    ev = [r.evals if r.evals is not None else np.nan for r in rows]
    for r, f in zip(rows, front(ev), strict=True):
        r.pareto_evals = f
    for r, f in zip(rows, front([r.us for r in rows]), strict=True):
        r.pareto_us = f


def scene_table(rows: list[Row]) -> str:
    body = []
    for r in rows:
        work = (
            f"{r.evals:.1f}"
            if r.evals is not None
            else (f"({r.candidates:.0f} candidates)" if r.candidates is not None else "")
        )
        front = "/".join(n for n, f in (("evals", r.pareto_evals), ("us", r.pareto_us)) if f)
        body.append(
            [
                r.config,
                r.urgency,
                f"{r.fraction:.4f}",
                work,
                f"{r.us:.1f}",
                f"{r.deferred:.1f}" if r.evals is not None else "",
                str(r.misses_valid) if r.evals is not None else "",
                front or "",
            ]
        )
    return table(
        [
            "configuration",
            "urgency",
            "standing alarm fraction",
            "tau evals/step",
            "us/step (median)",
            "deferred/step",
            "valid-bound misses",
            "Pareto front",
        ],
        body,
    )


def plot(scene: str, rows: list[Row], out: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    colors = {"old (sphere)": "tab:red", "new (shape)": "tab:blue", "exact": "tab:green"}
    markers = {"dua": "o", "deadline": "s", "select-all": "*", "sweep": "^", "MuJoCo": "v"}
    # A fraction of 0 has no place on a log axis: draw it at the floor and say so.
    floor = 1e-4
    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    for r in rows:
        marker = markers[r.config.split()[0]]
        y = max(r.fraction, floor)
        label = r.config.replace("deadline ", "").replace("dua ", "")
        for ax, x in ((axes[0], r.evals), (axes[1], r.us)):
            if x is None:
                continue  # peers evaluate no tau
            ax.scatter(x, y, c=colors[r.urgency], marker=marker, s=70, edgecolors="k", lw=0.5)
            ax.annotate(label, (x, y), fontsize=7, xytext=(4, 3), textcoords="offset points")
    for ax, xlabel in (
        (axes[0], "tau evaluations per step"),
        (axes[1], "microseconds per step (median; peers: their own step)"),
    ):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(f"standing alarm fraction (0 drawn at {floor:g})")
        ax.grid(True, which="both", alpha=0.3)
    handles = [
        plt.Line2D([], [], ls="", marker="o", color=c, label=u) for u, c in colors.items()
    ] + [plt.Line2D([], [], ls="", marker=mk, color="gray", label=n) for n, mk in markers.items()]
    axes[1].legend(handles=handles, fontsize=8, loc="best")
    fig.suptitle(f"{scene}: {rows[0].pairs} active geom pairs, {len(rows)} configurations")
    fig.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"pareto-{scene.replace('/', '-')}.png"
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def targets(by_scene: dict[str, list[Row]], bare: dict[str, tuple[float, float]]) -> str:
    body = []

    def find(rows: list[Row], config: str, urgency: str) -> Row | None:
        return next((r for r in rows if r.config == config and r.urgency == urgency), None)

    new, old = "new (shape)", "old (sphere)"
    for scene, rows in by_scene.items():
        dl, sa = find(rows, DEFAULT, new), find(rows, "select-all", new)
        if dl is None or sa is None or dl.pairs < 400:
            continue
        ratio = dl.fraction / sa.fraction if sa.fraction > 0 else np.inf
        share = dl.evals / sa.evals if sa.evals else np.inf  # type: ignore[operator]
        body.append(
            [
                f"{scene} ({dl.pairs} pairs): default standing fraction <= 1.5x select-all's, "
                "at <= 15 % of its tau evaluations",
                f"{dl.fraction:.4f} / {sa.fraction:.4f} = {ratio:.2f}x at "
                f"{dl.evals:.1f} / {sa.evals:.0f} = {100 * share:.1f} %",
                "met" if ratio <= 1.5 and share <= 0.15 else "**not met**",
            ]
        )
    for scene, need in (("two_arms", 3.0), ("traffic", 1.5), ("clutter", 1.5)):
        rows = by_scene.get(scene)
        if not rows:
            continue
        sa_old, sa_new = find(rows, "select-all", old), find(rows, "select-all", new)
        if sa_old is None or sa_new is None:
            continue
        cut = sa_old.fraction / sa_new.fraction if sa_new.fraction > 0 else np.inf
        body.append(
            [
                f"{scene}: select-all floor cut >= {need:g}x by the new urgency",
                f"{sa_old.fraction:.4f} -> {sa_new.fraction:.4f} = {cut:.2f}x",
                "met" if cut >= need else "**not met**",
            ]
        )
    for scene, rows in by_scene.items():
        preds = [r for r in rows if r.evals is not None]
        misses = sum(r.misses_valid for r in preds)
        unf = sum(r.unfiltered for r in preds)
        body.append(
            [
                f"{scene}: 0 valid-bound misses, 0 contacts outside the active pairs "
                f"({len(preds)} predictor runs)",
                f"{misses} misses, {unf} contacts outside",
                "met" if misses == 0 and unf == 0 else "**not met**",
            ]
        )
    for scene, (pred, mj) in bare.items():
        body.append(
            [
                f"{scene}: default predictor <= 40 % of mj_step (bare loop, medians)",
                f"{pred:.1f} / {mj:.1f} us = {100 * pred / mj:.0f} %",
                "met" if pred <= 0.4 * mj else "**not met**",
            ]
        )
    return table(["target", "measured", ""], body)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="200 steps, two scenes")
    parser.add_argument("--steps", type=int, default=1000, help="physics steps per rollout")
    parser.add_argument("--scenes", nargs="*", default=None)
    parser.add_argument("--out", type=Path, default=Path("docs/img"))
    args = parser.parse_args()
    steps = 200 if args.quick else args.steps
    scenes = args.scenes or list(QUICK_SCENES if args.quick else SCENES)
    urgencies = list(URGENCIES)
    # The pilot's bound estimate and the stiff scenes warn; the figures are what matter here.
    warnings.simplefilter("ignore")
    t_start = time.perf_counter()
    by_scene: dict[str, list[Row]] = {}
    for scene in scenes:
        t0 = time.perf_counter()
        bounds: dict = {}
        rows = []
        for urgency in urgencies:
            for config in SCHEDULES:
                rows.append(measure_predictor(scene, config, urgency, steps, bounds)[0])
        for urgency in ("old (sphere)", "new (shape)"):
            rows += measure_peers(scene, urgency, steps, bounds)
        mark_pareto(rows)
        by_scene[scene] = rows
        print(
            f"### {scene} ({rows[0].pairs} active geom pairs, {steps} steps, "
            f"monitored mj_step (median) {np.median([r.mj_us for r in rows if r.mj_us]):.1f} us; "
            f"{time.perf_counter() - t0:.0f} s)\n",
            flush=True,
        )
        print(scene_table(rows) + "\n", flush=True)
        print(f"![{scene}]({plot(scene, rows, args.out)})\n", flush=True)
    bare: dict[str, tuple[float, float]] = {}
    for scene in ("two_arms", "clutter"):
        if scene not in scenes:
            continue
        m, _ = _load(scene)
        p = Predictor(
            m, pilot=PilotOptions(controller=make_controller(m, "random", seed=PILOT_SEED))
        )
        bare[scene] = bare_loop(scene, p, max(steps, 1000) if not args.quick else steps)
    print("### Targets\n")
    print(targets(by_scene, bare) + "\n")
    print(f"total {time.perf_counter() - t_start:.0f} s")


if __name__ == "__main__":
    main()
