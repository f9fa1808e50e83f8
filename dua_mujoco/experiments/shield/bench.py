"""Many episodes of the shield's scenes under several layers, in parallel, and their table.

Every layer runs the same seeds of every scene (A/B on the same episodes); the work is split
over processes by (scene, seed), each running every layer on its episode in turn, so that all
layers see the same machine load. The layers are made by a factory ``make(setup, name)``:
:func:`peer_layer` makes ``none``, ``ttc`` (MoveIt Servo's stop-distance halt), ``ttc-scale``
(its threshold-distance velocity scaling) and ``damper`` (mink's limit); :func:`shield_layer`
makes ``shield`` (:class:`dua_mujoco.Shield` as a user would configure it on the scene: its
declared bounds, its robot's, its brake's stop time and the scene's failsafe,
:data:`FAILSAFES`), ``shield-brake`` (the same with the brake as its failsafe on every scene,
``Shield``'s default) and ``shield-noscreen`` (``shield`` without the screen: a rollout every
period); a caller adds its own (``benchmarks/shield.py`` adds the reference shield of
``tests/``).
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Sequence

import numpy as np

from dua_mujoco.build.bounds import MotionBounds
from dua_mujoco.experiments.report import table
from dua_mujoco.experiments.shield.episodes import (
    EpisodeResult,
    Layer,
    NoLayer,
    SceneSetup,
    run_episode,
)
from dua_mujoco.experiments.shield.evade import native
from dua_mujoco.experiments.shield.peers import TtcHalt, VelocityDamper
from dua_mujoco.models.cells import ROBOT_BOUNDS
from dua_mujoco.progress import Progress
from dua_mujoco.shield.failsafe import Evade
from dua_mujoco.shield.shield import Shield

__all__ = [
    "FAILSAFES",
    "PEERS",
    "SHIELDS",
    "peer_layer",
    "run_many",
    "scene_failsafe",
    "shield_layer",
    "summary",
]

PEERS = ("none", "ttc", "ttc-scale", "damper")
"""The layers :func:`peer_layer` makes."""
SHIELDS = ("shield", "shield-brake", "shield-noscreen")
"""The layers :func:`shield_layer` makes."""

FAILSAFES: dict[str, Callable[[SceneSetup], Evade]] = {
    # The base brakes while steering across its velocity, away from the walkers, carts and
    # walls: 85.0 % of the unshielded progress over 334 seeds where the brake keeps 76 %
    # (docs/shield.md, "An evasive failsafe").
    "mobile_cell": lambda setup: native(setup, gain=0.9, sideways=True),
}
"""The shield's failsafe on each scene where it is not the brake (``Shield``'s default, kept
on person_cell and arm_pair): a factory of the scene's setup."""

Factory = Callable[[SceneSetup, str], Layer]


def peer_layer(setup: SceneSetup, name: str) -> Layer:
    """The layer ``name`` (one of :data:`PEERS`) for a scene, with its source's defaults."""
    scene, model, brake, pairs = setup.scene, setup.model, setup.brake, setup.pairs
    if name == "none":
        return NoLayer()
    if name in ("ttc", "ttc-scale"):
        mode = "stop_distance" if name == "ttc" else "threshold_distance"
        return TtcHalt(
            model,
            brake=brake,
            pairs=pairs,
            period=scene.period,
            accel_limits=scene.task_accel,
            mode=mode,
        )
    if name == "damper":
        return VelocityDamper(model, brake=brake, pairs=pairs, period=scene.period)
    raise ValueError(f"unknown layer {name!r}; known: {', '.join(PEERS)}")


def scene_failsafe(setup: SceneSetup) -> Evade | None:
    """The scene's failsafe (:data:`FAILSAFES`; None: the brake)."""
    make = FAILSAFES.get(setup.scene.name)
    return None if make is None else make(setup)


def shield_layer(setup: SceneSetup, name: str, **options: object) -> Shield:
    """The shield ``name`` (one of :data:`SHIELDS`) for a scene: its protected bodies, every
    moving body's declared bounds (the others' and the robot's, ``ROBOT_BOUNDS``), its control
    period, its brake's stop time, and its failsafe (the scene's, :func:`scene_failsafe`; the
    brake for ``shield-brake``); ``options`` override :class:`Shield`'s arguments (another
    failsafe, ``failsafe=None`` the brake, another period or stop time)."""
    if name not in SHIELDS:
        raise ValueError(f"unknown shield {name!r}; known: {', '.join(SHIELDS)}")
    model = setup.model
    names = {b: model.body(b).name for b in setup.bounds}
    robot = ROBOT_BOUNDS[setup.scene.name]
    accel = {names[b]: v.accel for b, v in setup.bounds.items()} | {"*": robot.accel}
    speed = {names[b]: v.speed for b, v in setup.bounds.items()} | {"*": robot.speed}
    delta = {names[b]: v.delta or 0.0 for b, v in setup.bounds.items()} | {"*": 0.0}
    bounds = MotionBounds.declare(model, accel, speed=speed, vel_uncertainty=delta)
    args: dict = {
        "protect": list(setup.scene.protect),
        "robot": [model.body(int(b)).name for b in setup.brake.bodies],
        "period": setup.scene.period,
        "accel": bounds,
        "stop_time": setup.scene.stop_time,
        "screen": name != "shield-noscreen",
    }
    if name != "shield-brake" and "failsafe" not in options:
        args["failsafe"] = scene_failsafe(setup)
    return Shield(model, **(args | options))


def any_layer(setup: SceneSetup, name: str) -> Layer:
    """A peer (:func:`peer_layer`) or a shield (:func:`shield_layer`)."""
    return shield_layer(setup, name) if name in SHIELDS else peer_layer(setup, name)


_SETUPS: dict[str, SceneSetup] = {}
_JOB: dict[str, object] = {}


def _work(task: tuple[str, int]) -> list[EpisodeResult]:
    scene, seed = task
    setup = _SETUPS.get(scene)
    if setup is None:
        setup = _SETUPS[scene] = SceneSetup.of(scene)
    make: Factory = _JOB["make"]  # type: ignore[assignment]
    layers: Sequence[str] = _JOB["layers"]  # type: ignore[assignment]
    return [run_episode(setup, make(setup, name), name, seed) for name in layers]


def run_many(
    scenes: Sequence[str],
    layers: Sequence[str],
    seeds: Sequence[int],
    *,
    make: Factory = any_layer,
    jobs: int = 2,
    progress: bool = True,
) -> list[EpisodeResult]:
    """Every layer on every seed of every scene.

    Args:
        scenes: scene names (:data:`dua_mujoco.models.cells.SHIELD_SCENES`).
        layers: layer names ``make`` knows.
        seeds: the episodes' seeds (the same for every scene and layer).
        make: the layer factory.
        jobs: worker processes (1: in this process).
        progress: draw a progress bar on stderr.

    Returns:
        One result per (scene, seed, layer).
    """
    _JOB.update(make=make, layers=list(layers))
    tasks = [(s, seed) for s in scenes for seed in seeds]
    out: list[EpisodeResult] = []
    with Progress(len(tasks), "shield episodes", enabled=progress) as bar:
        if jobs <= 1:
            for task in tasks:
                out += _work(task)
                bar.update()
        else:
            # fork: the workers inherit the factory (a caller's closure included).
            ctx = multiprocessing.get_context("fork")
            with ctx.Pool(jobs) as pool:
                for chunk in pool.imap_unordered(_work, tasks):
                    out += chunk
                    bar.update()
    return sorted(out, key=lambda r: (r.scene, r.layer, r.seed))


def summary(results: Sequence[EpisodeResult]) -> str:
    """The results table: a row per scene and layer (markdown)."""
    header = [
        "scene",
        "layer",
        "episodes",
        "moving contacts (free)",
        "episodes with one",
        "moving, excused",
        "of them unguaranteed",
        "at rest",
        "targets / min",
        "vs none",
        "interventions",
        "cost / mj_step (median)",
        "bound violations",
    ]
    rows = []
    keys = sorted({(r.scene, r.layer) for r in results})
    base: dict[str, float] = {}
    for scene, layer in keys:
        group = [r for r in results if (r.scene, r.layer) == (scene, layer)]
        if layer == "none":
            base[scene] = float(np.mean([r.progress for r in group]))
    for scene, layer in keys:
        group = [r for r in results if (r.scene, r.layer) == (scene, layer)]
        progress = float(np.mean([r.progress for r in group]))
        ref = base.get(scene)
        steps = sum(r.steps for r in group)
        rows.append(
            [
                scene,
                layer,
                str(len(group)),
                str(sum(r.moving_free for r in group)),
                str(sum(r.moving_free > 0 for r in group)),
                str(sum(r.moving_excused for r in group)),
                str(sum(r.moving_unguaranteed for r in group)),
                str(sum(r.at_rest for r in group)),
                f"{progress:.1f}",
                f"{progress / ref:.0%}" if ref else "-",
                f"{sum(r.interventions for r in group) / steps:.1%}",
                f"{float(np.median([r.cost for r in group])):.2f}x",
                str(sum(r.violations for r in group)),
            ]
        )
    return table(header, rows)
