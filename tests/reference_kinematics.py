"""Sphere centres and velocities from MuJoCo's own ``mj_objectVelocity``: the independent reference.

Written differently from ``dua_mujoco.build.kinematics`` on purpose (a per-sphere Python loop over
MuJoCo's function, no ``cvel``/``subtree_com`` arithmetic), so that tests that hold the package's
kernel to it can fail.
"""

from __future__ import annotations

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco.build.mocap import MocapVelocityTracker

_GEOM = int(mujoco.mjtObj.mjOBJ_GEOM)


def reference_states(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    sphere_geom: npt.ArrayLike,
    sphere_offset: npt.ArrayLike,
    mocap: MocapVelocityTracker | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``(centers (n, 3), velocities (n, 3))`` of spheres fixed at ``sphere_offset`` in geoms."""
    geoms = np.asarray(sphere_geom, dtype=np.int64)
    offsets = np.asarray(sphere_offset, dtype=np.float64).reshape(-1, 3)
    twist = mocap.body_velocity(model.nbody) if mocap is not None else None
    centers = np.zeros((geoms.size, 3))
    velocities = np.zeros((geoms.size, 3))
    res = np.zeros(6)
    for i, g in enumerate(geoms.tolist()):
        origin = np.array(data.geom_xpos[g])
        centers[i] = origin + np.array(data.geom_xmat[g]).reshape(3, 3) @ offsets[i]
        mujoco.mj_objectVelocity(model, data, _GEOM, g, res, 0)  # [omega; v(origin)], world
        velocities[i] = res[3:] + np.cross(res[:3], centers[i] - origin)
        root = int(model.body_rootid[model.geom_bodyid[g]])
        if twist is not None and twist[root].any():
            # A mocap root moves its tree rigidly; MuJoCo reports it at rest.
            omega, v_root = twist[root, :3], twist[root, 3:]
            velocities[i] += v_root + np.cross(omega, centers[i] - np.array(data.xpos[root]))
    return centers, velocities
