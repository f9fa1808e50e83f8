"""An arm reaching past an obstacle, alarms at a 200 ms horizon with a flight plan and without.

    python docs/examples/plan_reach.py                     # docs/img/plan-reach.gif
    python docs/examples/plan_reach.py --frames /tmp/f     # and a PNG of every 2nd frame

Arm A of the bundled ``two_arms`` scene follows a scripted reach: its servos' targets move by
minimum-jerk segments from the side, past the green post (its fingers brush it), to the other
side. Two predictors with ``alarm_horizon=0.2`` watch the same run:

- left, one given a flight plan every 50 ms: :func:`dua_mujoco.plan_from_controls` rolls a copy
  of the script from the current state (the plan is what the simulation will do, bit for bit),
  with a deviation of 1 cm (what a plan a real robot follows would be known to);
- right, the motion bounds alone (``accel=80``, the scene's hint): within 200 ms nearly every
  link may reach nearly everything, so nearly every pair stands in alarm all the time.

The script prints, for the pair that touches, when it first stood in alarm and when it touched.
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco
import numpy as np
from video_args import video_parser

from dua_mujoco import Predictor, load_scene, plan_from_controls
from dua_mujoco.render import OverlayRenderer, VideoWriter

HORIZON = 0.2
EVERY = 25  # physics steps between two plans (H / 4)
DEVIATION = 0.01  # metres
# Arm A's joint targets (j1 yaw, j2 shoulder, j3 elbow, j4 wrist, j5 roll) at the waypoints, and
# the seconds each segment takes: from the side, past the post (the fingers brush it), beyond.
WAYPOINTS = np.array(
    [
        [-0.9, 0.2, 1.2, 0.5, 1.57],
        [-0.9, 0.2, 1.2, 0.5, 1.57],
        [0.0, 0.68, 1.1, 1.5, 0.0],
        [0.9, 0.45, 1.3, 0.6, 1.57],
        [0.9, 0.45, 1.3, 0.6, 1.57],
    ]
)
DURATIONS = (0.3, 1.2, 1.0, 0.5)


class Reach:
    """Servo targets by minimum-jerk segments through :data:`WAYPOINTS`, read off ``data.time``
    (stateless: a plan rolls the same script); arm B holds its start."""

    def __init__(self, park: np.ndarray) -> None:
        self.park = park
        self.ends = np.cumsum(DURATIONS)

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        t = float(data.time)
        k = min(int(np.searchsorted(self.ends, t, side="right")), len(DURATIONS) - 1)
        start = self.ends[k] - DURATIONS[k]
        s = np.clip((t - start) / DURATIONS[k], 0.0, 1.0)
        blend = s**3 * (10.0 - 15.0 * s + 6.0 * s * s)
        arm = WAYPOINTS[k] + (WAYPOINTS[k + 1] - WAYPOINTS[k]) * blend
        return np.concatenate([arm, self.park])


def standing_pairs(predictor: Predictor) -> set[tuple[int, int]]:
    """The geom pairs standing in alarm, ``(g1, g2)`` with ``g1 < g2``."""
    state = predictor.pair_state()
    ids = np.flatnonzero(state.alarm_state() & state.active)
    gp = np.unique(predictor.sphere_pairs.geom_pair[ids])
    g1 = np.asarray(predictor.geom_pairs.geom1)[gp]
    g2 = np.asarray(predictor.geom_pairs.geom2)[gp]
    return {(int(min(a, b)), int(max(a, b))) for a, b in zip(g1, g2, strict=True)}


def camera() -> mujoco.MjvCamera:
    cam = mujoco.MjvCamera()
    cam.lookat[:] = (-0.15, 0.0, 0.93)
    cam.distance, cam.azimuth, cam.elevation = 1.2, 120.0, -35.0
    return cam


def main(argv: list[str] | None = None) -> None:
    ap = video_parser(__doc__, "plan-reach.gif", fps=25.0, frames=2)
    args = ap.parse_args(argv)

    m, d = load_scene("two_arms")
    # Arm A in light grey: the tints (red, orange, yellow) stand out on it.
    for g in range(m.ngeom):
        if m.body(int(m.geom_bodyid[g])).name.startswith("a_"):
            m.geom_rgba[g] = (0.8, 0.8, 0.82, 1.0)
    script = Reach(np.array(d.qpos[5:10]))
    d.qpos[:5] = WAYPOINTS[0]
    mujoco.mj_forward(m, d)
    planned = Predictor(m, accel=80.0, alarm_horizon=HORIZON)
    bounds = Predictor(m, accel=80.0, alarm_horizon=HORIZON)
    steps = round(sum(DURATIONS) / m.opt.timestep)
    knots = EVERY + round(HORIZON / m.opt.timestep) + 2
    per_frame = round(1.0 / (args.fps * m.opt.timestep))
    hand = {m.geom(n).id for n in ("a_finger_l", "a_finger_r", "a_palm", "a_wrist")}
    post = m.geom("post").id
    first_alarm = touch = since = None
    was_near = False
    if args.frames is not None:
        args.frames.mkdir(parents=True, exist_ok=True)

    def give_plan() -> None:
        plan = plan_from_controls(m, d, script, steps=knots - 1)
        planned.set_plan(plan, deviation=DEVIATION)

    d.ctrl[:] = script(m, d)
    mujoco.mj_step(m, d)
    alarms = [p.reset(d) for p in (planned, bounds)]
    give_plan()
    cam = camera()
    with (
        OverlayRenderer(planned, width=320, height=240) as left,
        OverlayRenderer(bounds, width=320, height=240) as right,
        VideoWriter(args.out, fps=args.fps) as video,
    ):
        for k in range(1, steps + 1):
            d.ctrl[:] = script(m, d)
            mujoco.mj_step(m, d)
            alarms = [p.step(d) for p in (planned, bounds)]
            standing = [standing_pairs(p) for p in (planned, bounds)]
            near = any(post in p and (p[0] in hand or p[1] in hand) for p in standing[0])
            if near and first_alarm is None:
                first_alarm = float(d.time)
            if near and not was_near and touch is None:
                since = float(d.time)  # the start of the alarm the touch comes in
            was_near = near
            near_b = any(post in p and (p[0] in hand or p[1] in hand) for p in standing[1])
            contact = any(
                {int(c.geom1), int(c.geom2)} & hand and post in (c.geom1, c.geom2)
                for c in d.contact[: d.ncon]
            )
            if contact and touch is None:
                touch = float(d.time)
            if k % per_frame == 0:
                # Before the next plan: set_plan withdraws every verdict until the next step.
                sides = []
                for r, a, pairs, name, flag in zip(
                    (left, right),
                    alarms,
                    standing,
                    ("plan", "no plan"),
                    (near, near_b),
                    strict=True,
                ):
                    text = f"{name}  t = {d.time:.2f} s  pairs in alarm {len(pairs)}"
                    text += "\nhand-post: " + ("ALARM" if flag else "clear")
                    if touch is not None:
                        text += "  (touching)" if contact else "  (touched)"
                    sides.append(r.render(d, a, camera=cam, text=text))
                frame = np.concatenate(sides, axis=1)
                video.add(frame)
                if args.frames is not None and (k // per_frame) % 2 == 0:
                    import PIL.Image

                    PIL.Image.fromarray(frame).save(args.frames / f"frame_{k:05d}.png")
            if k % EVERY == 0:
                give_plan()
    print(f"written {args.out}")
    if touch is None:
        print(f"no touch between the hand and the post; first alarm at {first_alarm}")
    else:
        lead = None if since is None else 1e3 * (touch - since)
        print(
            f"hand-post with the plan: first alarm at t = {first_alarm:.3f} s, in alarm without "
            f"a break from t = {since:.3f} s, touch at t = {touch:.3f} s ({lead:.0f} ms of "
            f"warning; the horizon is {1e3 * HORIZON:.0f} ms)"
            if lead is not None and first_alarm is not None and since is not None
            else "no alarm before the touch"
        )


if __name__ == "__main__":
    main()
