"""Rigid-body kinematics of covering spheres: the one kernel that turns ``MjData`` into sphere
centres and velocities (the native core's ``dua_rigid_point``), and sphere states.

Every reader of sphere states (the predictor's step and its full reads, the bound checks, the
pilot that estimates bounds, the overlays) runs that kernel: the step directly, the others
through :func:`sphere_states` or :class:`PointMotion`. A point's centre is ``geom_xpos[g] +
geom_xmat[g] @ offset`` (:func:`mjdata_frame` has the instant it reads). After ``mj_step``
the kinematics in ``MjData`` (``geom_xpos``, ``cvel``, ``subtree_com``) are one consistent
instant, the start of the step (RK4: its last stage; docs/discrete-time.md). ``d.cvel[b]`` is
``[omega; v_ref]`` with ``v_ref`` the velocity at ``subtree_com`` of ``b``'s root, so
``v(p) = v_ref + omega x (p - p_ref)``; a tree rooted at a mocap body, which ``cvel`` treats
as static, gets that body's twist added.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco._core import LAYOUT, check_groups, check_points, rigid_points
from dua_mujoco.exceptions import ShapeError

__all__ = [
    "SPHERE_BODY",
    "SPHERE_FRAME",
    "SPHERE_NCOL",
    "SPHERE_OFFSET",
    "SPHERE_ROOT",
    "PointMotion",
    "mjdata_frame",
    "pack_spheres",
    "sphere_states",
]

# Columns of the packed per-sphere records: one 64-byte row (a cache line) per sphere (the
# offset takes three columns).
SPHERE_FRAME, SPHERE_BODY = LAYOUT["SPHERE_FRAME"], LAYOUT["SPHERE_BODY"]
SPHERE_OFFSET, SPHERE_ROOT = LAYOUT["SPHERE_OFFSET"], LAYOUT["SPHERE_ROOT"]
SPHERE_NCOL = LAYOUT["SPHERE_NCOL"]
# Columns of the screened check's group records (the centre takes three).
_GROUP = {k: LAYOUT[f"GROUP_{k}"] for k in ("CENTRE", "RADIUS", "FRAME", "BODY", "ROOT", "NCOL")}
_GROUP_BOUNDS = [LAYOUT[f"GROUP_{k}"] for k in ("ACCEL", "DISC", "SPEED")]
_FRAME_ROW_LEN = LAYOUT["FRAME_ROW_LEN"]  # a group's kept frame rows, two updates of them


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


Frame = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def mjdata_frame(data: mujoco.MjData, root_twist: np.ndarray) -> Frame:
    """The instant the kinematics kernel reads, as views of ``data``'s buffers: ``(geom_xpos
    (ngeom, 3), geom_xmat (ngeom, 9), cvel (nbody, 6), subtree_com (nbody, 3), root_twist
    (nbody, 6), xpos (nbody, 3))``.

    Args:
        data: The MuJoCo data (kinematics computed).
        root_twist: ``(nbody, 6)`` twist ``[omega; v_origin]`` of each mocap root (zero rows
            elsewhere; ``MocapVelocityTracker.twist``).
    """
    return (data.geom_xpos, data.geom_xmat, data.cvel, data.subtree_com, root_twist, data.xpos)


def sphere_states(
    spheres: np.ndarray, frame: Frame, ids: npt.ArrayLike | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Centres and velocities of spheres ``ids`` (all when None) on ``frame``: the native
    core's kinematics kernel (``dua_rigid_point``), the one every reader of sphere states runs.

    Args:
        spheres: ``(nsphere, 8)`` records from :func:`pack_spheres`.
        frame: As built by :func:`mjdata_frame`.
        ids: ``(n,)`` sphere ids.

    Returns:
        ``(centers (n, 3), velocities (n, 3))``, float64.

    Raises:
        InvalidInputError: A sphere id is out of range, or a record indexes outside ``frame``
            (the MjData of another model).
    """
    sel = np.asarray(np.arange(spheres.shape[0]) if ids is None else ids, np.int64).reshape(-1)
    pos, mat, twist, twist_ref, root_twist, root_origin = frame
    out = rigid_points(spheres, pos, mat, twist, twist_ref, root_twist, root_origin, sel)
    return out[:, :3], out[:, 3:]


class PointMotion:
    """What the bounds of ``docs/discrete-time.md`` limit, measured at points every update: the
    chord speed |u_k|, the one-step discrepancy |u_k - w_{k-1}| and the discrete acceleration
    |u_k - u_{k-1}| / h, u_k = (c_k - c_{k-1}) / h, in one native pass (``dua_check_points``)
    that also flags the values above given bounds. The pilot measures with it
    (``estimate_bounds``), ``BoundMonitor`` checks with it.

    Args:
        points: ``(n, 8)`` records from :func:`pack_spheres`.
        accel: ``(n,)`` bound on the discrete acceleration of each point (None: 0).
        discrepancy: ``(n,)`` bound on the one-step discrepancy (None: 0).
        speed: ``(n,)`` bound on the chord speed; None for none.
        rtol: relative tolerance of every comparison (the round-off of the differences is
            tolerated besides).
        screen: Measure only the points a screen in O(1) a group cannot clear (a group: a run of
            consecutive points on one frame with the same bounds; ``dua_check_groups``), from
            the third update on. :attr:`broken` and the count are the same as without it
            (docs/theory.md, "The monitor's screen"); :attr:`rows` and :attr:`values` are then
            current only for the groups measured (the run monitor reads the broken points'
            values; the pilot, which reads all, does not screen).
    """

    SPEED, DISCREPANCY, ACCEL = 0, 1, 2
    """Columns of :attr:`values` and :attr:`broken`."""

    def __init__(
        self,
        points: np.ndarray,
        accel: np.ndarray | None = None,
        discrepancy: np.ndarray | None = None,
        speed: np.ndarray | None = None,
        rtol: float = 0.0,
        *,
        screen: bool = False,
    ) -> None:
        n = points.shape[0]
        self._points = points
        self._accel, self._disc = (
            np.zeros(n) if b is None else np.ascontiguousarray(b, dtype=np.float64)
            for b in (accel, discrepancy)
        )
        self._speed = np.zeros(0) if speed is None else np.ascontiguousarray(speed, np.float64)
        self._rtol = rtol
        self.rows = np.zeros((n, 9))
        """``(n, 9)`` ``[c, w, u]`` of each point at the latest update (u zero at the first)."""
        self._prev = np.zeros((n, 9))
        self.updates = 0
        """Updates so far."""
        self.values = np.zeros((n, 3))
        """``(n, 3)`` speed, discrepancy and acceleration of each point at the latest update
        (zero until measured: the speed and discrepancy from the second update, the
        acceleration from the third)."""
        self.broken = np.zeros((n, 3), dtype=np.bool_)
        """``(n, 3)`` which of :attr:`values` broke their bound at the latest update."""
        self._no_check = np.zeros(n, dtype=np.bool_)
        self._groups = (
            _point_groups(points, self._accel, self._disc, self._speed) if screen else None
        )
        if self._groups is not None:
            ngroup = self._groups[0].size - 1
            self._frames = np.zeros((ngroup, 2, _FRAME_ROW_LEN))
            self._computed = np.full(ngroup, -1, dtype=np.int64)
        self._h_prev = 1.0

    @property
    def measured_groups(self) -> int:
        """How many groups the latest update measured point by point (``screen``; every
        group before the third update)."""
        if self._groups is None:
            return 0
        return int(np.count_nonzero(self._computed == self.updates - 1))

    def update(
        self,
        data: mujoco.MjData,
        root_twist: np.ndarray,
        h: float,
        check_discrepancy: np.ndarray | None = None,
    ) -> int:
        """Measure the state of ``data`` against the previous update's, ``h`` seconds before.

        Args:
            data: The MuJoCo data (kinematics computed).
            root_twist: ``(nbody, 6)`` as for :func:`mjdata_frame`.
            h: The time since the previous update.
            check_discrepancy: ``(n,)`` bool, the points whose discrepancy is held to its bound
                (None: none).

        Returns:
            How many (point, bound) pairs broke.
        """
        self.rows, self._prev = self._prev, self.rows
        check = self._no_check if check_discrepancy is None else check_discrepancy
        names = ("pos", "mat", "twist", "twist_ref", "root_twist", "root_origin")
        args: dict[str, Any] = dict(zip(names, mjdata_frame(data, root_twist), strict=True))
        args.update(prev=self._prev, cur=self.rows, nprev=min(self.updates, 2), h=h)
        args.update(accel=self._accel, disc=self._disc, speed=self._speed, rtol=self._rtol)
        args.update(check_disc=check.view(np.uint8), values=self.values)
        args.update(broken=self.broken.view(np.uint8))
        if self._groups is None:
            nbroken = check_points(self._points, **args)
        else:
            start, groups = self._groups
            args.update(frames=self._frames, computed=self._computed, update=self.updates)
            nbroken = check_groups(
                self._points, group_start=start, groups=groups, h_prev=self._h_prev, **args
            )
            self._h_prev = h
        self.updates += 1
        return int(nbroken)


def _point_groups(
    points: np.ndarray, accel: np.ndarray, disc: np.ndarray, speed: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The screened check's groups: runs of consecutive points on one frame (body, root) with the
    same bounds, as ``(group_start (ngroup + 1,), groups (ngroup, GROUP_NCOL))``: each group's
    record holds a ball around its offsets in the frame (centred on their box), the frame, body
    and root, and the bounds (speed inf: none)."""
    n = points.shape[0]
    speed = speed if speed.size else np.full(n, np.inf)
    ids = points[:, [SPHERE_FRAME, SPHERE_BODY, SPHERE_ROOT]]
    key = np.column_stack([ids, accel, disc, speed])
    differs = (key[1:] != key[:-1]).any(axis=1)
    start = np.concatenate([[0], np.flatnonzero(differs) + 1, [n] if n else []]).astype(np.int64)
    first = start[:-1]
    offset = points[:, SPHERE_OFFSET : SPHERE_OFFSET + 3]
    groups = np.zeros((first.size, _GROUP["NCOL"]))
    if n:
        centre = (np.minimum.reduceat(offset, first) + np.maximum.reduceat(offset, first)) / 2
        member = np.repeat(np.arange(first.size), np.diff(start))
        radius = np.zeros(first.size)
        np.maximum.at(radius, member, np.linalg.norm(offset - centre[member], axis=1))
        groups[:, _GROUP["CENTRE"] : _GROUP["CENTRE"] + 3] = centre
        groups[:, _GROUP["RADIUS"]] = radius
        groups[:, [_GROUP["FRAME"], _GROUP["BODY"], _GROUP["ROOT"]]] = ids[first]
        groups[:, _GROUP_BOUNDS] = key[first, 3:]
    return start, groups
