"""An episode of a shield scene without the shield (left) and with it (right), side by side.

    python docs/examples/shield_video.py                         # docs/img/shield-person.gif
    python docs/examples/shield_video.py --scene mobile_cell --seed 11 --out /tmp/mobile.gif

The same seed (the others' motion, the targets) on both sides; the robot is tinted red at the
physics steps at which the shield runs its failsafe, and a protected body turns magenta for a
moment at a contact that finds the robot moving (over 1 cm/s) with nothing touching it the second
before (the benchmark's *free* moving contacts; one after a touch at rest, the person pushing the
stopped arm, is not marked). The script prints what each side counted.
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco
import numpy as np
from video_args import video_parser

from dua_mujoco.experiments.shield.bench import shield_layer
from dua_mujoco.experiments.shield.episodes import (
    REST_SPEED,
    NoLayer,
    SceneSetup,
    body_speeds,
    run_episode,
)
from dua_mujoco.render import VideoWriter

RED = (0.9, 0.15, 0.1, 1.0)
MAGENTA = (1.0, 0.0, 1.0, 1.0)
CAMERAS = {  # lookat, distance, azimuth, elevation
    "person_cell": ((0.3, 0.0, 0.9), 3.2, 150.0, -30.0),
    "arm_pair": ((0.0, 0.0, 0.9), 2.6, 90.0, -40.0),
    "mobile_cell": ((0.0, 0.0, 0.0), 9.0, 90.0, -60.0),
}


def frames(setup: SceneSetup, shielded: bool, seed: int, every: int, size: tuple[int, int]):
    """The episode's frames (every ``every``-th physics step) and its result."""
    model = setup.model
    layer = shield_layer(setup, "shield") if shielded else NoLayer()
    robot = np.isin(np.asarray(model.geom_bodyid), setup.brake.bodies)
    protected = np.isin(np.asarray(model.geom_bodyid), setup.protected) & ~robot
    rgba = np.array(model.geom_rgba)
    pair_set = {tuple(sorted(p)) for p in setup.pairs.tolist()}
    cam = mujoco.MjvCamera()
    look, cam.distance, cam.azimuth, cam.elevation = CAMERAS[setup.scene.name]
    cam.lookat[:] = look
    out: list[np.ndarray] = []
    hit_until = -1
    last_touch = -np.inf
    with mujoco.Renderer(model, height=size[1], width=size[0]) as renderer:

        def on_step(data: mujoco.MjData, k: int) -> None:
            nonlocal hit_until, last_touch
            touched = False
            for c in data.contact[: data.ncon] if data.ncon else []:
                pair = tuple(sorted((int(c.geom1), int(c.geom2))))
                if pair in pair_set:
                    touched = True
                    body = next(int(model.geom_bodyid[g]) for g in pair if robot[g])
                    speed = body_speeds(model, data, [body], setup.radius)[0]
                    if speed > REST_SPEED and float(data.time) - last_touch > 1.0 + 1e-9:
                        hit_until = k + 25 * every
            if touched:
                last_touch = float(data.time)
            if k % every:
                return
            model.geom_rgba[:] = rgba
            if shielded and layer.native.intervening:  # type: ignore[attr-defined]
                model.geom_rgba[robot] = RED
            if k <= hit_until:
                model.geom_rgba[protected] = MAGENTA
            renderer.update_scene(data, cam)
            out.append(renderer.render().copy())
            model.geom_rgba[:] = rgba

        result = run_episode(setup, layer, "shield" if shielded else "none", seed, on_step=on_step)
    return out, result


def main(argv: list[str] | None = None) -> None:
    ap = video_parser(__doc__, "shield-person.gif", fps=20.0)
    ap.add_argument("--scene", default="person_cell")
    ap.add_argument("--seed", type=int, default=12)
    args = ap.parse_args(argv)
    setup = SceneSetup.of(args.scene)
    every = round(1.0 / (args.fps * setup.model.opt.timestep))
    left, free = frames(setup, False, args.seed, every, (320, 240))
    right, shielded = frames(setup, True, args.seed, every, (320, 240))
    with VideoWriter(args.out, fps=args.fps) as video:
        for a, b in zip(left, right, strict=True):
            video.add(np.concatenate([a, np.full((240, 4, 3), 255, np.uint8), b], axis=1))
    for r in (free, shielded):
        print(
            f"{r.layer:6s}: {r.moving_free} moving contacts (free), {r.moving_excused} excused, "
            f"{r.at_rest} at rest, {r.reached} targets, {r.interventions} steps intervened"
        )
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
