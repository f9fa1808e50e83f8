"""The exact level against the sphere urgency, an exact-geometry reference and MuJoCo's gap peer.

    python benchmarks/exact.py                       # the section of docs/benchmarks.md
    python benchmarks/exact.py --quick               # smoke run: 200 steps, two scenes
    python benchmarks/exact.py --scenes two_arms gym/ant --steps 500

One rollout per scene and configuration (pilot seed 99, rollout seed 0, ``accel="auto"``,
default options otherwise), every configuration on the same controls and the same bounds (the
exact level's, measured over the geoms' box corners), so the trajectories are the same:

- ``spheres``: the urgency of the bounding spheres and static shapes only (``exact=False``);
- ``exact``: the default, with the exact level;
- ``reference``: every active geom pair judged at every step by ``mj_geomDistance`` against the
  two geoms' reach over one predictor period ``H`` with the predictor's own bounds,
  ``(|v_c| + |w| r + delta) H + A H^2 / 2`` each: what a gap-inflated ``mj_collision`` flags;
- ``gap peer``: MuJoCo's collision with every geom's gap inflated by its reach
  (``dua_mujoco.experiments.peers``), as in benchmarks/pareto.py.

The standing fraction of a predictor is ``RunReport.standing_alarm_fraction``; of the reference
and the peer the mean over steps of (geom pairs flagged) / (active geom pairs). Times are medians
of the step (the predictor's ``step``, ``mj_step``); read ratios, not single figures.
Robot models come from ``benchmarks/robots.py`` when their packages are installed.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

from dua_mujoco.build.pairbounds import body_vel_uncertainty
from dua_mujoco.exceptions import DuaError
from dua_mujoco.experiments.peers.mujoco_collision import MujocoScene
from dua_mujoco.experiments.peers.scene_context import SceneContext
from dua_mujoco.measure.rollout import run
from dua_mujoco.models.scenes import make_controller
from dua_mujoco.runtime.predictor import Predictor

sys.path.insert(0, str(Path(__file__).parent))
from bench import table
from pareto import _load

from dua_mujoco.build.options import PilotOptions, UrgencyOptions

SCENES = ("two_arms", "traffic", "clutter", "gym/ant", "gym/humanoid", "dmc/humanoid_CMU")
PILOT_SEED = 99
ROLLOUT_SEED = 0


def _load_any(scene: str) -> tuple[mujoco.MjModel, mujoco.MjData]:
    if scene.startswith("robot/"):
        from robots import load_robot

        m = load_robot(scene.split("/", 1)[1])
        return m, mujoco.MjData(m)
    return _load(scene)


def reference_fraction(p: Predictor, scene: str, steps: int) -> float:
    """Mean fraction of active geom pairs whose exact distance is within their reach over one
    period (module docstring), on the rollout every configuration sees."""
    m, d = _load_any(scene)
    gp = p.geom_pairs
    g1 = np.asarray(gp.geom1)
    g2 = np.asarray(gp.geom2)
    dist = np.asarray(gp.contact_distance)
    body = np.asarray(m.geom_bodyid)
    accel = p.bounds.accel[body]
    delta = body_vel_uncertainty(m, p.bounds, period=p.period, mocap=p.mocap)[body]
    rbound = np.asarray(m.geom_rbound)
    plane = np.asarray(m.geom_type) == int(mujoco.mjtGeom.mjGEOM_PLANE)
    H = (1 + p.latency) * p.dt
    vel = np.empty(6)
    ctrl = make_controller(m, "random", seed=ROLLOUT_SEED)
    ctrl(m, d)
    mujoco.mj_step(m, d)
    total = 0.0
    for _ in range(steps):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        speed = np.empty(m.ngeom)
        for g in range(m.ngeom):
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_GEOM, g, vel, 0)
            speed[g] = np.linalg.norm(vel[3:]) + np.linalg.norm(vel[:3]) * rbound[g]
        reach = (speed + delta) * H + accel * H * H / 2
        need = dist + reach[g1] + reach[g2]
        # Bounding spheres first (planes have none): a pair whose balls are out of reach is.
        centre = np.linalg.norm(d.geom_xpos[g1] - d.geom_xpos[g2], axis=1)
        maybe = plane[g1] | plane[g2] | (centre - rbound[g1] - rbound[g2] < need)
        flagged = 0
        for k in np.flatnonzero(maybe):
            if mujoco.mj_geomDistance(m, d, int(g1[k]), int(g2[k]), need[k] + 1.0, None) < need[k]:
                flagged += 1
        total += flagged / max(len(g1), 1)
    return total / steps


def gap_fraction(p: Predictor, scene: str, steps: int) -> tuple[float, float]:
    """MuJoCo's gap-inflated collision: mean flagged fraction and median microseconds."""
    m, d = _load_any(scene)
    ctx = SceneContext(m, predictor=p)
    gap = MujocoScene(ctx, "gap")
    ctrl = make_controller(m, "random", seed=ROLLOUT_SEED)
    ctrl(m, d)
    mujoco.mj_step(m, d)
    p.reset(d)
    npair = max(ctx.npairs, 1)
    frac, times = 0.0, []
    for _ in range(steps):
        ctrl(m, d)
        gap.set_snapshot(d)
        mujoco.mj_step(m, d)
        frac += gap.step(d)[0].size / npair
        times.append(gap.collision_s)
    return frac / steps, float(np.median(times) * 1e6)


def measure(scene: str, steps: int) -> list[list[str]]:
    m, _ = _load_any(scene)
    pilot = make_controller(m, "random", seed=PILOT_SEED)
    base = Predictor(
        m, pilot=PilotOptions(controller=pilot)
    )  # the default: bounds over the geoms' corners
    rows = []
    for label, exact in (("spheres", False), ("exact", True)):
        m, d = _load_any(scene)
        p = Predictor(m, accel=base.bounds, urgency=UrgencyOptions(exact=exact))
        rep = run(
            m,
            d,
            p,
            steps=steps,
            controller=make_controller(m, "random", seed=ROLLOUT_SEED),
            progress=False,
            series=False,
        )
        rows.append(
            [
                scene,
                label,
                str(rep.geom_pairs),
                f"{100 * rep.standing_alarm_fraction:.2f} %",
                f"{rep.evals_per_step:.1f}",
                f"{rep.predictor_us_per_step:.1f}",
                f"{rep.mj_step_us_per_step:.1f}",
                f"{rep.predictor_us_per_step / rep.mj_step_us_per_step:.2f}",
                f"{rep.missed_onsets_valid_bounds} / {rep.missed_onsets} / {rep.contact_onsets}",
                str(rep.unfiltered_contacts),
            ]
        )
    t0 = time.perf_counter()
    ref = reference_fraction(base, scene, steps)
    rows.append([scene, "reference", "", f"{100 * ref:.2f} %", "", "", "", "", "", ""])
    frac, us = gap_fraction(base, scene, steps)
    rows.append([scene, "gap peer", "", f"{100 * frac:.2f} %", "", f"{us:.1f}", "", "", "", ""])
    print(f"  {scene}: reference and peer in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    return rows


HEADER = [
    "scene",
    "urgency",
    "geom pairs",
    "standing",
    "evals/step",
    "us/step",
    "mj_step us",
    "/ mj_step",
    "missed (bounds held / all / onsets)",
    "contacts outside pairs",
]


def add_scene_options(ap: argparse.ArgumentParser) -> None:
    """The scenes a table measures: ``--scenes``, ``--steps``, ``--quick``, ``--robots``."""
    ap.add_argument("--scenes", nargs="*", default=None)
    ap.add_argument("--steps", type=int, default=1500)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--robots", action="store_true", help="add every installed robot model")


def chosen_scenes(args: argparse.Namespace, scenes: tuple[str, ...]) -> list[str]:
    """:func:`add_scene_options`' scenes: those given, or ``scenes`` (two with ``--quick``),
    and every installed robot model with ``--robots``."""
    out = list(scenes[:2] if args.quick else scenes) if args.scenes is None else list(args.scenes)
    if args.robots:
        from robots import available

        out += [f"robot/{name}" for name in available()]
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_scene_options(ap)
    args = ap.parse_args(argv)
    scenes = chosen_scenes(args, SCENES)
    steps = 200 if args.quick else args.steps
    rows: list[list[str]] = []
    for scene in scenes:
        print(f"{scene} ...", file=sys.stderr)
        try:
            rows += measure(scene, steps)
        except DuaError as exc:  # a model that diverges under random controls: say so, go on
            rows.append(
                [scene, f"not measured: {exc}".split(":")[0] + ": " + type(exc).__name__]
                + [""] * (len(HEADER) - 2)
            )
            print(f"  {scene}: {exc}", file=sys.stderr)
    print(table(HEADER, rows))


if __name__ == "__main__":
    main()
