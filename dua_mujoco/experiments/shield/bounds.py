"""Measured motion bounds of ``arm_pair``'s arm B, the body its shield bounds and does not plan.

Arm B runs its task alone (arm A folded away and held, so nothing touches B) for many seeds; at
every physics step, at the corners of each of B's geoms' boxes (which bound every point of the
geom: docs/theory.md, section 5), it measures the chord speed ``|p_k - p_{k-1}| / h``, the
discrete acceleration ``|u_k - u_{k-1}| / h`` and the one-step discrepancy
``|u_{k+1} - w_k|`` (``w_k`` the point's velocity MuJoCo reports), and keeps each body's
largest. ``dua_mujoco.models.cells.ARM_B_BOUNDS`` declares them times 1.5.

    python -m dua_mujoco.experiments.shield.bounds --episodes 200
"""

from __future__ import annotations

import argparse

import mujoco
import numpy as np

from dua_mujoco.models.cells import SHIELD_SCENES

__all__ = ["measure_arm_b"]

FOLDED = [0.0, -0.6, 2.4, 0.8, 0.0, 0.0]
"""Arm A's pose while B is measured: folded over its base, out of B's reach."""


def measure_arm_b(episodes: int, *, first_seed: int = 0) -> dict[str, tuple[float, float, float]]:
    """Each of arm B's bodies' largest ``(speed, accel, discrepancy)`` over the episodes."""
    scene = SHIELD_SCENES["arm_pair"]
    model = scene.model()
    data = mujoco.MjData(model)
    h = float(model.opt.timestep)
    bodies = [b for b in range(model.nbody) if model.body(b).name.startswith("b_link")]
    bodies += [model.body("b_hand").id]
    geoms = [g for g in range(model.ngeom) if int(model.geom_bodyid[g]) in bodies]
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    aabb = np.asarray(model.geom_aabb)[geoms]
    local = (aabb[:, None, :3] + signs[None] * aabb[:, None, 3:]).reshape(-1, 3)
    gid = np.repeat(np.array(geoms), 8)
    body = np.asarray(model.geom_bodyid)[gid]
    worst = np.zeros((len(bodies), 3))
    a_adr = model.joint("a_j1").qposadr[0]
    a_act = model.actuator("a_j1").id
    vel = np.empty(6)
    for seed in range(first_seed, first_seed + episodes):
        episode = scene.episode(model, data, seed)
        data.qpos[a_adr : a_adr + 6] = FOLDED
        mujoco.mj_forward(model, data)
        last = chord = reported = None
        for k in range(round(scene.duration / h)):
            if k % scene.period == 0:
                ctrl = episode.policy(model, data)
                ctrl[a_act : a_act + 6] = FOLDED
            data.ctrl[:] = ctrl
            mujoco.mj_step(model, data)
            mats = np.asarray(data.geom_xmat)[gid].reshape(-1, 3, 3)
            offset = np.einsum("nij,nj->ni", mats, local)
            points = np.asarray(data.geom_xpos)[gid] + offset
            twist = np.empty((len(geoms), 6))
            for i, g in enumerate(geoms):
                mujoco.mj_objectVelocity(model, data, int(mujoco.mjtObj.mjOBJ_GEOM), g, vel, 0)
                twist[i] = vel
            twist = np.repeat(twist, 8, axis=0)
            now = twist[:, 3:] + np.cross(twist[:, :3], offset)
            if last is not None:
                u = (points - last) / h
                stats = [np.linalg.norm(u, axis=1)]
                stats.append(
                    np.linalg.norm(u - chord, axis=1) / h if chord is not None else 0 * stats[0]
                )
                stats.append(np.linalg.norm(u - reported, axis=1))
                for i, b in enumerate(bodies):
                    mine = body == b
                    worst[i] = np.maximum(worst[i], [float(s[mine].max()) for s in stats])
                chord = u
            last, reported = points, now
    return {model.body(b).name: tuple(worst[i]) for i, b in enumerate(bodies)}


def main() -> None:
    parser = argparse.ArgumentParser(description="arm_pair's arm B: measured bounds")
    parser.add_argument("--episodes", type=int, default=200)
    args = parser.parse_args()
    for name, (speed, accel, disc) in measure_arm_b(args.episodes).items():
        print(
            f"{name:8s} speed {speed:6.3f} m/s  accel {accel:7.2f} m/s^2  "
            f"discrepancy {disc:.4f} m/s"
        )


if __name__ == "__main__":
    main()
