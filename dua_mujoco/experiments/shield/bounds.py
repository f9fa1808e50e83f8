"""Measured motion bounds of the shield scenes' bodies: arm_pair's arm B (the body its shield
bounds and does not plan) and each scene's robot (what the shield's screen assumes).

Each body's points are measured at the corners of its geoms' boxes (which bound every point of
the geom: docs/theory.md, section 6), at every physics step: the chord speed
``|p_k - p_{k-1}| / h``, the discrete acceleration ``|u_k - u_{k-1}| / h`` and the one-step
discrepancy ``|u_{k+1} - w_k|`` (``w_k`` the point's velocity MuJoCo reports); each body's
largest over many seeds. Arm B runs its task alone (arm A folded away and held, so nothing
touches B); ``dua_mujoco.models.cells.ARM_B_BOUNDS`` declares its maxima times 1.5. A robot
runs its task with the scripted bodies out of the way, and the brake of the shield's failsafe
cut in at random times for random spells (the screen's bounds must hold while it brakes);
``ROBOT_BOUNDS`` declares their maxima times 1.5.

    python -m dua_mujoco.experiments.shield.bounds --episodes 200
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

import mujoco
import numpy as np

from dua_mujoco.build.exact import corner_points
from dua_mujoco.build.kinematics import PointMotion, pack_spheres
from dua_mujoco.models.cells import SHIELD_SCENES
from dua_mujoco.progress import Progress
from dua_mujoco.shield.failsafe import Brake

__all__ = ["measure_arm_b", "measure_robot"]

FOLDED = [0.0, -0.6, 2.4, 0.8, 0.0, 0.0]
"""Arm A's pose while B is measured: folded over its base, out of B's reach."""

Bounds = dict[str, tuple[float, float, float]]
Drive = Callable[[mujoco.MjData, int, np.ndarray], np.ndarray]


def _measure(
    scene_name: str, bodies: list[int], seeds: range, start: Drive, drive: Drive
) -> Bounds:
    """Each body's largest ``(speed, accel, discrepancy)`` at its geoms' box corners over the
    seeds' episodes: ``start(data, seed, ctrl)`` sets an episode up after the scene's reset,
    ``drive(data, k, ctrl)`` gives the controls of physics step ``k``."""
    scene = SHIELD_SCENES[scene_name]
    model = scene.model()
    data = mujoco.MjData(model)
    h = float(model.opt.timestep)
    geoms = [g for g in range(model.ngeom) if int(model.geom_bodyid[g]) in bodies]
    gid, body, local = corner_points(model, geoms)
    worst = np.zeros((len(bodies), 3))
    of_body = [body == b for b in bodies]
    no_twist = np.zeros((model.nbody, 6))  # the scripted (mocap) bodies are not measured
    with Progress(len(seeds), f"{scene_name} bounds") as bar:
        for seed in seeds:
            episode = scene.episode(model, data, seed)
            if episode.script is not None:  # the scripted bodies out of the way
                data.mocap_pos[:] = 20.0 + 3.0 * np.arange(model.nmocap)[:, None]
            ctrl = start(data, seed, episode.policy(model, data))
            mujoco.mj_forward(model, data)
            # The runtime's own measure (the pilot's): speed, discrepancy and acceleration
            # of each corner, from the second update (the acceleration from the third).
            motion = PointMotion(pack_spheres(gid, body, local, model.body_rootid))
            for k in range(round(scene.duration / h)):
                if k % scene.period == 0:
                    ctrl = episode.policy(model, data)
                data.ctrl[:] = drive(data, k, ctrl)
                mujoco.mj_step(model, data)
                motion.update(data, no_twist, h)
                values = motion.values[
                    :, [PointMotion.SPEED, PointMotion.ACCEL, PointMotion.DISCREPANCY]
                ]
                for i, mine in enumerate(of_body):
                    worst[i] = np.maximum(worst[i], values[mine].max(axis=0))
            bar.update()
    return {model.body(b).name: tuple(worst[i]) for i, b in enumerate(bodies)}


def measure_arm_b(episodes: int, *, first_seed: int = 0) -> Bounds:
    """Each of arm B's bodies' largest ``(speed, accel, discrepancy)`` over the episodes."""
    model = SHIELD_SCENES["arm_pair"].model()
    bodies = [b for b in range(model.nbody) if model.body(b).name.startswith("b_link")]
    bodies += [model.body("b_hand").id]
    a_adr = model.joint("a_j1").qposadr[0]
    a_act = model.actuator("a_j1").id

    def fold(data: mujoco.MjData, seed: int, ctrl: np.ndarray) -> np.ndarray:
        data.qpos[a_adr : a_adr + 6] = FOLDED
        return ctrl

    def drive(data: mujoco.MjData, k: int, ctrl: np.ndarray) -> np.ndarray:
        ctrl = ctrl.copy()
        ctrl[a_act : a_act + 6] = FOLDED
        return ctrl

    return _measure("arm_pair", bodies, range(first_seed, first_seed + episodes), fold, drive)


def measure_robot(scene_name: str, episodes: int, *, first_seed: int = 0) -> Bounds:
    """Each of the scene's robot bodies' largest ``(speed, accel, discrepancy)`` under its task,
    the brake cutting in 0-4 times an episode for 0.05-0.5 s each (from random states of the
    task, as the shield's failsafe does)."""
    scene = SHIELD_SCENES[scene_name]
    model = scene.model()
    brake = Brake(model, actuators=scene.robot_actuators(model))
    h = float(model.opt.timestep)
    spells: list[tuple[int, int]] = []

    def start(data: mujoco.MjData, seed: int, ctrl: np.ndarray) -> np.ndarray:
        rng = np.random.default_rng([seed, 15066])
        steps = round(scene.duration / h)
        spells[:] = []
        for _ in range(int(rng.integers(0, 5))):
            first = int(rng.integers(0, steps))
            spells.append((first, first + round(rng.uniform(0.05, 0.5) / h)))
        return ctrl

    def drive(data: mujoco.MjData, k: int, ctrl: np.ndarray) -> np.ndarray:
        if any(a <= k < b for a, b in spells):
            out = ctrl.copy()
            out[brake.actuators] = brake(model, data)[brake.actuators]
            return out
        return ctrl

    bodies = [int(b) for b in brake.bodies if model.body(int(b)).name]
    return _measure(scene_name, bodies, range(first_seed, first_seed + episodes), start, drive)


def main() -> None:
    parser = argparse.ArgumentParser(description="the shield scenes' measured bounds")
    parser.add_argument("--episodes", type=int, default=200)
    args = parser.parse_args()
    results = {"arm B": measure_arm_b(args.episodes)}
    for name in SHIELD_SCENES:
        results[f"{name}'s robot"] = measure_robot(name, args.episodes)
    for label, measured in results.items():
        print(label)
        for name, (speed, accel, disc) in measured.items():
            print(
                f"  {name:10s} speed {speed:6.3f} m/s  accel {accel:7.2f} m/s^2  "
                f"discrepancy {disc:.4f} m/s"
            )


if __name__ == "__main__":
    main()
