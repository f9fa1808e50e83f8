"""Rigid-body kinematics of covering spheres: the one kernel that turns ``MjData`` into sphere
centres and velocities (the native core's ``dua_rigid_point``), and sphere states.

Every reader of sphere states (the predictor's step and its full reads, the bound checks, the
pilot that estimates bounds, the overlays) runs one kernel, the native core's
``dua_rigid_point``: the step directly, the others through :func:`rigid_point` (and
:func:`sphere_states` when they want arrays).

**Which instant.** After ``mj_step`` with the Euler, implicit and implicitfast integrators,
``d.geom_xpos``, ``d.geom_xmat``, ``d.cvel`` and ``d.subtree_com`` were computed at the *start* of
that step (from the ``qpos``/``qvel`` the step began with), while ``d.qpos``/``d.qvel`` hold the
integrated state. Centres and velocities read here therefore describe one consistent instant. With
RK4, ``mj_step`` leaves the kinematics of its last stage in ``MjData`` (``qpos0 + h * k3``), which
agrees with the end-of-step state to O(h^5) but is not exactly it; it is still one consistent
instant for positions and velocities (docs/discrete-time.md).

**Velocity of a point.** ``d.cvel[b]`` is the spatial velocity ``[omega; v_ref]`` of body ``b`` in
the world frame, whose linear part is the velocity of the point of ``b`` (rigidly extended) at
``d.subtree_com[m.body_rootid[b]]``; hence ``v(p) = v_ref + omega x (p - p_ref)``. A tree rooted
at a mocap body moves with that body, which ``cvel`` treats as static: its twist is added.
"""

from __future__ import annotations

import mujoco
import numba as nb
import numpy as np
import numpy.typing as npt

from dua_mujoco.core.native_kernels import frame_view, rigid_point_c
from dua_mujoco.exceptions import ShapeError

__all__ = [
    "SPHERE_BODY",
    "SPHERE_FRAME",
    "SPHERE_NCOL",
    "SPHERE_OFFSET",
    "SPHERE_ROOT",
    "mjdata_frame",
    "pack_spheres",
    "rigid_point",
    "sphere_states",
]

# Columns of the packed per-sphere records: one 64-byte row (a cache line) per sphere.
SPHERE_FRAME, SPHERE_BODY, SPHERE_OFFSET, SPHERE_ROOT = 0, 1, 2, 5  # offset: columns 2, 3, 4
SPHERE_NCOL = 8


def pack_spheres(
    sphere_frame: npt.ArrayLike,
    sphere_body: npt.ArrayLike,
    sphere_offset: npt.ArrayLike,
    body_root: npt.ArrayLike,
) -> np.ndarray:
    """``(nsphere, 8)`` float64 records ``[frame, body, ox, oy, oz, root, 0, 0]``.

    Args:
        sphere_frame: ``(nsphere,)`` frame (geom) each sphere is attached to.
        sphere_body: ``(nsphere,)`` body of that frame.
        sphere_offset: ``(nsphere, 3)`` centre in the frame.
        body_root: ``(nbody,)`` root body of each body (``MjModel.body_rootid``).
    """
    frame = np.asarray(sphere_frame, dtype=np.int64).reshape(-1)
    n = frame.shape[0]
    body = np.asarray(sphere_body, dtype=np.int64)
    offset = np.asarray(sphere_offset, dtype=np.float64)
    if body.shape != (n,):
        raise ShapeError(f"sphere_body has shape {body.shape}; expected ({n},).")
    if offset.shape != (n, 3):
        raise ShapeError(f"sphere_offset has shape {offset.shape}; expected ({n}, 3).")
    rec = np.zeros((n, SPHERE_NCOL))
    rec[:, SPHERE_FRAME] = frame
    rec[:, SPHERE_BODY] = body
    rec[:, SPHERE_OFFSET : SPHERE_OFFSET + 3] = offset
    rec[:, SPHERE_ROOT] = np.asarray(body_root, dtype=np.int64)[body]
    return rec


@nb.njit(cache=True, inline="always")
def rigid_point(i, spheres, view, out):  # pragma: no cover - jitted
    """Centre and velocity of sphere ``i`` attached to a rigid frame: the one kinematics kernel
    (native: ``dua_rigid_point``).

    ``spheres`` holds ``pack_spheres`` records; ``view`` is the :func:`frame_view` of a
    ``frame`` tuple ``(frame_pos (nframe, 3), frame_mat (nframe, 9), twist (nbody, 6),
    twist_ref (nbody, 3), root_twist (nbody, 6), root_origin (nbody, 3))``, read from ``MjData``
    as ``(geom_xpos, geom_xmat, cvel, subtree_com, mocap root twists, xpos)`` (take it once for a
    loop over many points). Writes ``out[0:3]`` (centre) and ``out[3:6]`` (velocity), ``out``
    contiguous. Centre: ``frame_pos[g] + frame_mat[g] @ offset``. Velocity: the body twist
    ``[omega; v_ref]`` about the point ``twist_ref[rootid[b]]`` (MuJoCo's ``cvel`` about
    ``subtree_com`` of the root), plus the twist of the tree's root about ``root_origin`` for
    trees MuJoCo treats as static (mocap roots), which is zero elsewhere.
    """
    rigid_point_c(i, spheres.ctypes, view.ctypes, out.ctypes)


def mjdata_frame(data: mujoco.MjData, root_twist: np.ndarray) -> tuple[np.ndarray, ...]:
    """The ``frame`` tuple :func:`rigid_point` reads, as views of ``data``'s buffers.

    Args:
        data: The MuJoCo data (kinematics computed).
        root_twist: ``(nbody, 6)`` twist ``[omega; v_origin]`` of each mocap root (zero rows
            elsewhere; see ``MocapVelocityTracker.write_body_velocity``).
    """
    return (data.geom_xpos, data.geom_xmat, data.cvel, data.subtree_com, root_twist, data.xpos)


@nb.njit(cache=True)
def _states(spheres, frame, ids, out):  # pragma: no cover - jitted
    view = frame_view(frame)
    for k in range(ids.shape[0]):
        rigid_point(ids[k], spheres, view, out[k])


def sphere_states(
    spheres: np.ndarray, frame: tuple[np.ndarray, ...], ids: npt.ArrayLike | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Centres and velocities of spheres ``ids`` (all when None), through :func:`rigid_point`.

    Args:
        spheres: ``(nsphere, 8)`` records from :func:`pack_spheres`.
        frame: As built by :func:`mjdata_frame`.
        ids: ``(n,)`` sphere ids.

    Returns:
        ``(centers (n, 3), velocities (n, 3))``, float64.
    """
    nsphere = spheres.shape[0]
    sel = (
        np.arange(nsphere, dtype=np.int64)
        if ids is None
        else np.ascontiguousarray(np.asarray(ids, dtype=np.int64).reshape(-1))
    )
    if sel.size and (sel.min() < 0 or sel.max() >= nsphere):
        raise ShapeError(f"sphere ids must lie in [0, {nsphere}); got [{sel.min()}, {sel.max()}].")
    _check_frame(spheres, frame)
    out = np.empty((sel.shape[0], 6))
    _states(spheres, frame, sel, out)
    return out[:, :3], out[:, 3:]


def _check_frame(spheres: np.ndarray, frame: tuple[np.ndarray, ...]) -> None:
    """The kernel reads without bounds checks: the records must index inside the frame."""
    if spheres.shape[0] == 0:
        return
    nframe, nbody = frame[0].shape[0], frame[2].shape[0]
    if spheres[:, SPHERE_FRAME].max() >= nframe or spheres[:, SPHERE_BODY].max() >= nbody:
        raise ShapeError(
            f"the sphere records reference frame {int(spheres[:, SPHERE_FRAME].max())} and body "
            f"{int(spheres[:, SPHERE_BODY].max())} but the data has {nframe} frames and {nbody} "
            "bodies: pass the MjData of the model the spheres were built for."
        )
