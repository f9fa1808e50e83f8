"""Terrain against a plane: standing alarms, misses, work and time (docs/static-shapes.md, 13).

    python benchmarks/terrain.py                      # the table of docs/static-shapes.md
    python benchmarks/terrain.py --steps 500 --seeds 0  # a quick look
    python benchmarks/terrain.py --scenes quadruped   # only the bundled robot

Each robot runs on a height field and on a plane, the same controls and seeds (random held
controls, ``make_controller(..., "random", seed=s)``, seeds 0-4), with the default predictor
(``accel="auto"`` from a pilot of seed 99, the exact level on); the height field once as terrain
(the default, ``hfield="terrain"``) and once covered by its bounding box (``hfield="box"``, the
only way before). Per run: the standing alarm fraction (the mean share of active geom pairs with
a pair in alarm, ``RunReport.standing_alarm_fraction``), the share in MuJoCo contact, the
contact onsets and those missed while the bounds held, the evaluations a step and the
predictor's time over ``mj_step``'s (medians of the runs; the variants of a seed run one after
the other, so load on the machine falls on all of them).

Robots:

* ``quadruped``: the bundled ``rough_terrain`` against ``flat_terrain`` (its plane at the
  terrain's mean height).
* ``dmc/quadruped``: dm_control's quadruped (``suite/quadruped.xml``, loaded raw, walls, ball,
  target and rangefinders removed as its ``make_model`` does), on its height field filled as its
  Escape task fills it (a bowl times smooth random bumps, seed 0; its floor plane removed so
  that the robot meets the terrain alone) against its floor plane (the terrain removed, as its
  Walk task does). Its start height is raised until nothing touches, as Escape does.

Also ``make-terrain`` prints the elevation rows of ``models/rough_terrain.xml``
(:func:`rough_heights`).
"""

from __future__ import annotations

import argparse
import statistics
import sys
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np

from dua_mujoco.build.options import CoveringOptions, PilotOptions
from dua_mujoco.measure.rollout import run
from dua_mujoco.models.scenes import load_scene, make_controller, reset_to_keyframe
from dua_mujoco.runtime.predictor import Predictor

PILOT_SEED = 99


def rough_heights(n: int = 101, half: float = 2.5, seed: int = 7) -> np.ndarray:
    """The bundled terrain's elevation, ``(n, n)`` integers in ``0..255``: rolling ground (six
    waves of 1.5 to 4 m) and bumps (24 of 0.3 to 0.8 m, half as high), rescaled to 0..255."""
    rng = np.random.default_rng(seed)
    x = np.linspace(-half, half, n)
    xx, yy = np.meshgrid(x, x)
    h = np.zeros_like(xx)
    for amp, lo, hi, k in ((1.0, 1.5, 4.0, 6), (0.5, 0.3, 0.8, 24)):
        for _ in range(k):
            wl, th, ph = rng.uniform(lo, hi), rng.uniform(0, 2 * np.pi), rng.uniform(0, 2 * np.pi)
            h += (
                amp / np.sqrt(k) * np.sin(2 * np.pi / wl * (xx * np.cos(th) + yy * np.sin(th)) + ph)
            )
    return np.round(255 * (h - h.min()) / (h.max() - h.min())).astype(int)


def _dmc_spec(terrain: bool) -> mujoco.MjSpec:
    import dm_control

    spec = mujoco.MjSpec.from_file(str(Path(dm_control.__file__).parent / "suite/quadruped.xml"))
    for name in ("wall_px", "wall_py", "wall_nx", "wall_ny", "floor" if terrain else "terrain"):
        spec.delete(spec.geom(name))
    spec.delete(spec.body("ball"))
    spec.delete(spec.site("target"))
    for sensor in list(spec.sensors):
        if sensor.type == mujoco.mjtSensor.mjSENS_RANGEFINDER:
            spec.delete(sensor)
    return spec


def _escape_heights(m: mujoco.MjModel, seed: int = 0) -> np.ndarray:
    """dm_control's Escape terrain (suite/quadruped.py): a sinusoidal bowl times smooth bumps."""
    from scipy import ndimage

    res = int(m.hfield_nrow[0])
    row, col = np.ogrid[-1 : 1 : res * 1j, -1 : 1 : res * 1j]
    radius = np.clip(np.sqrt(col**2 + row**2), 0.04, 1)
    bowl = 0.5 - np.cos(2 * np.pi * radius) / 2
    bump_res = int(2 * m.hfield_size[0, 0] / 2)  # terrain size over its 2 m bump scale
    bumps = np.random.default_rng(seed).uniform(0.15, 1, (bump_res, bump_res))
    return bowl * ndimage.zoom(bumps, res / float(bump_res))


def _dmc(terrain: bool) -> tuple[mujoco.MjModel, mujoco.MjData]:
    m = _dmc_spec(terrain).compile()
    if terrain:
        m.hfield_data[:] = _escape_heights(m).ravel()
    d = mujoco.MjData(m)
    reset_to_keyframe(m, d)
    # Raised until nothing touches (Escape's _find_non_contacting_height, upright).
    while True:
        mujoco.mj_forward(m, d)
        if d.ncon == 0:
            return m, d
        d.qpos[2] += 0.01


SCENES: dict[str, dict[str, Callable[[], tuple[mujoco.MjModel, mujoco.MjData]]]] = {
    "quadruped": {
        "terrain": lambda: load_scene("rough_terrain"),
        "plane": lambda: load_scene("flat_terrain"),
    },
    "dmc/quadruped": {"terrain": lambda: _dmc(True), "plane": lambda: _dmc(False)},
}


def measure(
    load: Callable[[], tuple[mujoco.MjModel, mujoco.MjData]], hfield: str, seed: int, steps: int
) -> dict[str, float]:
    m, d = load()
    p = Predictor(
        m,
        covering=CoveringOptions(hfield=hfield),
        pilot=PilotOptions(controller=make_controller(m, "random", seed=PILOT_SEED)),
    )
    r = run(
        m, d, p, steps=steps, controller=make_controller(m, "random", seed=seed), progress=False
    )
    return {
        "standing": r.standing_alarm_fraction,
        "contact": r.contact_pair_fraction,
        "onsets": r.contact_onsets,
        "missed": r.missed_onsets,
        "missed_valid": r.missed_onsets_valid_bounds,
        "evals": r.evals_per_step,
        "time": r.predictor_us_per_step / r.mj_step_us_per_step,
        "pairs": r.geom_pairs,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("what", nargs="?", default="table", choices=["table", "make-terrain"])
    parser.add_argument("--scenes", nargs="*", default=list(SCENES))
    parser.add_argument("--seeds", nargs="*", type=int, default=[0, 1, 2, 3, 4])
    parser.add_argument("--steps", type=int, default=2000)
    args = parser.parse_args()
    if args.what == "make-terrain":
        for row in rough_heights():
            print(" ".join(str(v) for v in row))
        return
    rows = [("terrain", "terrain"), ("box", "terrain"), ("plane", "plane")]
    print(
        "| robot | ground | geom pairs | standing | x plane | in contact | onsets | missed "
        "(while bounds held) | evaluations / step | predictor / mj_step |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for scene in args.scenes:
        runs: dict[str, list[dict[str, float]]] = {name: [] for name, _ in rows}
        for seed in args.seeds:
            for name, ground in rows:
                hfield = "box" if name == "box" else "terrain"
                runs[name].append(measure(SCENES[scene][ground], hfield, seed, args.steps))
                print(f"  {scene} {name} seed {seed}: {runs[name][-1]}", file=sys.stderr)
        plane = statistics.mean(r["standing"] for r in runs["plane"])
        for name, _ in rows:
            rs = runs[name]
            standing = statistics.mean(r["standing"] for r in rs)
            print(
                f"| {scene} | {name} | {int(rs[0]['pairs'])} | {standing:.3f} | "
                f"{standing / plane:.2f}x | {statistics.mean(r['contact'] for r in rs):.3f} | "
                f"{sum(int(r['onsets']) for r in rs)} | {sum(int(r['missed']) for r in rs)} "
                f"({sum(int(r['missed_valid']) for r in rs)}) | "
                f"{statistics.mean(r['evals'] for r in rs):.2f} | "
                f"{statistics.median(r['time'] for r in rs):.2f}x |",
                flush=True,
            )


if __name__ == "__main__":
    main()
