"""A person walks into an arm's cell and reaches while the arm works: alarms at a 200 ms horizon
with the arm's flight plan (left) and with the motion bounds alone (right).

    python docs/examples/person_cell.py                     # docs/img/person-cell.gif
    python docs/examples/person_cell.py --frames /tmp/f     # and a PNG of every 10th frame

The bundled scene ``person_cell`` driven by its own driver (``CellDriver``; seed 12: the person's
hand ends up on the arm's wrist). Two predictors with the scene's declared bounds (the person's
after ISO 13855: 1.6 m/s walking, 2.0 m/s reaching in; the arm's measured) and
``alarm_horizon=0.2`` watch the same run:

- left, the arm is given its flight plan every 200 ms (:class:`dua_mujoco.runtime.plans.Replanner`
  with ``CellDriver.plan``: the arm's task rolled ahead on a copy of the state where the person
  does not collide, ``bodies=("arm_*",)``, deviation 0); the person is left to its bounds, and an
  arm-person pair is judged by the planned arm against the person's reach;
- right, the motion bounds alone: within 200 ms every link may reach much of the cell.

Pairs standing in alarm are tinted by their urgency and joined by red lines. The script prints,
for the first arm-person contact, how long its pair had stood in alarm before it.
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco
import numpy as np
from video_args import video_parser

from dua_mujoco import Predictor, load_scene
from dua_mujoco.models.person_cell import ARM, CellDriver, declared_bounds
from dua_mujoco.render import OverlayRenderer, VideoWriter
from dua_mujoco.runtime.plans import Replanner

HORIZON = 0.2
SEED = 12
START, END = 1.0, 6.2  # seconds of the run the video shows


def standing(predictor: Predictor, pairs: np.ndarray) -> int:
    """How many of the sphere pairs ``pairs`` (a mask) stand in alarm."""
    state = predictor.pair_state()
    return int((state.alarm_state() & state.active & pairs).sum())


def camera() -> mujoco.MjvCamera:
    cam = mujoco.MjvCamera()
    cam.lookat[:] = (0.35, 0.0, 0.95)  # from the side: the arm left, the person walks in right
    cam.distance, cam.azimuth, cam.elevation = 2.8, 90.0, -20.0
    return cam


def main(argv: list[str] | None = None) -> None:
    ap = video_parser(__doc__, "person-cell.gif", fps=20.0, frames=10)
    ap.add_argument("--size", type=int, nargs=2, default=(320, 240), metavar=("W", "H"))
    args = ap.parse_args(argv)

    m, d = load_scene("person_cell")
    # The arm in light grey: the tints (red, orange, yellow) stand out on it.
    for g in range(m.ngeom):
        if m.body(int(m.geom_bodyid[g])).name.startswith("arm_"):
            m.geom_rgba[g] = (0.8, 0.8, 0.82, 1.0)
    bounds = declared_bounds(m)
    planned = Predictor(m, accel=bounds, alarm_horizon=HORIZON)
    alone = Predictor(m, accel=bounds, alarm_horizon=HORIZON)
    driver = CellDriver(m, SEED)
    replan = Replanner(planned, driver, planner=driver.plan, bodies=ARM)
    person = np.asarray(m.body_mocapid)[np.asarray(m.geom_bodyid)] >= 0
    g1, g2 = planned.sphere_pair_geoms
    arm_person = person[g1] | person[g2]
    h = float(m.opt.timestep)
    per_frame = round(1.0 / (args.fps * h))
    since = touch = None
    counts: list[list[int]] = [[], []]  # pairs in alarm at each frame, each side
    if args.frames is not None:
        args.frames.mkdir(parents=True, exist_ok=True)

    replan(m, d)
    mujoco.mj_step(m, d)
    alarms = [p.reset(d) for p in (planned, alone)]
    cam = camera()
    w, hgt = args.size
    with (
        OverlayRenderer(planned, width=w, height=hgt) as left,
        OverlayRenderer(alone, width=w, height=hgt) as right,
        VideoWriter(args.out, fps=args.fps) as video,
    ):
        for k in range(1, round(END / h) + 1):
            replan(m, d)
            mujoco.mj_step(m, d)
            alarms = [p.step(d) for p in (planned, alone)]
            up = standing(planned, arm_person)
            if touch is None:
                since = None if not up else float(d.time) if since is None else since
                for c in d.contact[: d.ncon]:
                    if person[int(c.geom1)] != person[int(c.geom2)]:
                        touch = float(d.time)
            if k % per_frame or d.time < START:
                continue
            sides = []
            for r, p, a, name, count in zip(
                (left, right),
                (planned, alone),
                alarms,
                ("arm planned", "bounds alone"),
                counts,
                strict=True,
            ):
                state = p.pair_state()
                total = int((state.alarm_state() & state.active).sum())
                count.append(total)
                text = f"{name}  t = {d.time:.2f} s\npairs in alarm {total}"
                text += f"  arm-person {standing(p, arm_person)}"
                if touch is not None:
                    text += "\nthe hand touched the arm"
                sides.append(r.render(d, a, camera=cam, text=text))
            frame = np.concatenate(sides, axis=1)
            video.add(frame)
            if args.frames is not None and (k // per_frame) % 10 == 0:
                import PIL.Image

                PIL.Image.fromarray(frame).save(args.frames / f"frame_{k:05d}.png")
    print(f"written {args.out} ({args.out.stat().st_size / 1e6:.1f} MB)")
    for name, count in zip(("with the plan", "bounds alone"), counts, strict=True):
        print(f"{name}: {min(count)}-{max(count)} of {g1.size} pairs in alarm in the video")
    if touch is None or since is None:
        print("no arm-person contact in the video's span")
    else:
        print(
            f"first arm-person contact at t = {touch:.3f} s; with the plan, an arm-person pair "
            f"stood in alarm without a break from t = {since:.3f} s ({1e3 * (touch - since):.0f} "
            f"ms of warning; the horizon is {1e3 * HORIZON:.0f} ms)"
        )


if __name__ == "__main__":
    main()
