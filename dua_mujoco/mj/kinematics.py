"""Rigid-body kinematics of covering spheres: the one kernel that turns ``MjData`` into sphere
centres and velocities, and the MuJoCo layer's fused step that uses it.

Every reader of sphere states (the predictor's fused step and its full reads, the bound checks,
the pilot that estimates bounds, the overlays) calls :func:`rigid_point`, through
:func:`sphere_states` when it wants arrays.

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

from dua_mujoco.exceptions import ShapeError

__all__ = [
    "SPHERE_BODY",
    "SPHERE_FRAME",
    "SPHERE_OFFSET",
    "SPHERE_ROOT",
    "mjdata_frame",
    "pack_spheres",
    "rigid_point",
    "rigid_point_at",
    "sphere_states",
]

# Columns of the packed per-sphere records: one 64-byte row (a cache line) per sphere.
SPHERE_FRAME, SPHERE_BODY, SPHERE_OFFSET, SPHERE_ROOT = 0, 1, 2, 5  # offset: columns 2, 3, 4


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
    rec = np.zeros((n, 8))
    rec[:, SPHERE_FRAME] = frame
    rec[:, SPHERE_BODY] = body
    rec[:, SPHERE_OFFSET : SPHERE_OFFSET + 3] = offset
    rec[:, SPHERE_ROOT] = np.asarray(body_root, dtype=np.int64)[body]
    return rec


@nb.njit(cache=True, inline="always")
def rigid_point(i, spheres, frame, out):  # pragma: no cover - jitted
    """Centre and velocity of sphere ``i`` attached to a rigid frame: the one kinematics kernel.

    ``spheres`` holds ``pack_spheres`` records; ``frame`` is ``(frame_pos (nframe, 3),
    frame_mat (nframe, 9), twist (nbody, 6), twist_ref (nbody, 3), root_twist (nbody, 6),
    root_origin (nbody, 3))``, read from ``MjData`` as ``(geom_xpos, geom_xmat, cvel,
    subtree_com, mocap root twists, xpos)``. Writes ``out[0:3]`` (centre) and ``out[3:6]``
    (velocity), without allocating. Centre: ``frame_pos[g] + frame_mat[g] @ offset``. Velocity:
    the body twist ``[omega; v_ref]`` about the point ``twist_ref[rootid[b]]`` (MuJoCo's
    ``cvel`` about ``subtree_com`` of the root), plus the twist of the tree's root about
    ``root_origin`` for trees MuJoCo treats as static (mocap roots), which is zero elsewhere.
    """
    frame_pos, frame_mat, twist, twist_ref, root_twist, root_origin = frame
    rigid_point_at(i, spheres, frame_pos, frame_mat, twist, twist_ref, root_twist, root_origin, out)


@nb.njit(cache=True, inline="always")
def rigid_point_at(  # pragma: no cover - jitted
    i, spheres, frame_pos, frame_mat, twist, twist_ref, root_twist, root_origin, out
):
    """:func:`rigid_point` with the ``frame`` tuple's arrays passed one by one: for loops that
    unpack the tuple once (numba reference-counts every array taken out of a tuple, and in a
    loop with branches that is not pruned: 0.1 us a pair in the exact level, measured)."""
    g = int(spheres[i, SPHERE_FRAME])
    b = int(spheres[i, SPHERE_BODY])
    o0 = spheres[i, SPHERE_OFFSET]
    o1 = spheres[i, SPHERE_OFFSET + 1]
    o2 = spheres[i, SPHERE_OFFSET + 2]
    for k in range(3):
        out[k] = (
            frame_pos[g, k]
            + frame_mat[g, 3 * k] * o0
            + frame_mat[g, 3 * k + 1] * o1
            + frame_mat[g, 3 * k + 2] * o2
        )
    r = int(spheres[i, SPHERE_ROOT])
    dx = out[0] - twist_ref[r, 0]
    dy = out[1] - twist_ref[r, 1]
    dz = out[2] - twist_ref[r, 2]
    out[3] = twist[b, 3] + twist[b, 1] * dz - twist[b, 2] * dy
    out[4] = twist[b, 4] + twist[b, 2] * dx - twist[b, 0] * dz
    out[5] = twist[b, 5] + twist[b, 0] * dy - twist[b, 1] * dx
    # Indexed, not a row view: a view is reference-counted, which costs more than the rest.
    w0 = root_twist[r, 0]
    w1 = root_twist[r, 1]
    w2 = root_twist[r, 2]
    u0 = root_twist[r, 3]
    u1 = root_twist[r, 4]
    u2 = root_twist[r, 5]
    if w0 != 0.0 or w1 != 0.0 or w2 != 0.0 or u0 != 0.0 or u1 != 0.0 or u2 != 0.0:
        ex = out[0] - root_origin[r, 0]
        ey = out[1] - root_origin[r, 1]
        ez = out[2] - root_origin[r, 2]
        out[3] += u0 + w1 * ez - w2 * ey
        out[4] += u1 + w2 * ex - w0 * ez
        out[5] += u2 + w0 * ey - w1 * ex


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
    for k in range(ids.shape[0]):
        rigid_point(ids[k], spheres, frame, out[k])


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
