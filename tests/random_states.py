"""Random joint states for the tests that hold kinematics to MuJoCo at arbitrary configurations."""

from __future__ import annotations

import mujoco
import numpy as np


def random_joint_state(
    m: mujoco.MjModel, d: mujoco.MjData, rng: np.random.Generator, *, velocity_scale: float
) -> None:
    """Random joint positions (unit quaternions for free and ball joints) and velocities.

    Writes ``d.qpos`` and ``d.qvel`` only: the caller runs ``mj_forward``.

    Args:
        m: The model.
        d: Its data.
        rng: Source of the draws.
        velocity_scale: Standard deviation of every ``qvel`` entry.
    """
    for j in range(m.njnt):
        adr = int(m.jnt_qposadr[j])
        kind = int(m.jnt_type[j])
        if kind == int(mujoco.mjtJoint.mjJNT_FREE):
            d.qpos[adr : adr + 3] = rng.uniform(-1, 1, 3)
            q = rng.normal(size=4)
            d.qpos[adr + 3 : adr + 7] = q / np.linalg.norm(q)
        elif kind == int(mujoco.mjtJoint.mjJNT_BALL):
            q = rng.normal(size=4)
            d.qpos[adr : adr + 4] = q / np.linalg.norm(q)
        else:
            d.qpos[adr] = rng.uniform(-2, 2)
    d.qvel[:] = rng.normal(scale=velocity_scale, size=m.nv)
