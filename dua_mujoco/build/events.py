"""Violations as events: a body whose motion broke its bounds makes its pairs due at once.

Every verdict assumes the bounds hold from its instant on; a contact's impulse breaks them. So
the step (natively: ``dua_mujoco/csrc/src/step.cc``) first checks, per moving body, the
hypotheses of the discrete-time derivation over the last period (those ``BoundMonitor``
checks), and every held pair of a body that broke them is made due now: its verdict withdrawn,
it is evaluated again this very step. The check runs on one box a body around every point the
bounds limit (its corners are the predictor's ``bound_points``), screened from the box's centre
and axes, the corners looked at only when the screen fails. docs/theory.md, section 6, states
the hypotheses over a period (E1-E3), the screen (Lemma 6.2) and what this restores.
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco._core import LAYOUT
from dua_mujoco.build.bounds import MotionBounds, moving_bodies

__all__ = ["BodyBoxes", "EventTable", "body_boxes", "build_events", "no_events"]

# Columns of a body record (the check's state is the runtime's: csrc/src/step.cc).
B_FRAME, B_BODY, B_ROOT = LAYOUT["B_FRAME"], LAYOUT["B_BODY"], LAYOUT["B_ROOT"]
B_CENTER = LAYOUT["B_CENTER"]  # 3 columns: the box's centre in the frame
B_HALF = LAYOUT["B_HALF"]  # 3 columns: its half extents
B_ACCEL, B_DISC, B_SPEED = LAYOUT["B_ACCEL"], LAYOUT["B_DISC"], LAYOUT["B_SPEED"]
NB_REC = LAYOUT["NB_REC"]
# The signs of a box's eight corners, one row a corner.
_SIGNS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)


class BodyBoxes(NamedTuple):
    """One box a body around its bound points, in the frame of one of its geoms.

    Attributes:
        frame: ``(nb,)`` the geom whose frame holds the box.
        body: ``(nb,)`` body id.
        center: ``(nb, 3)`` centre of the box in that frame.
        half: ``(nb, 3)`` half extents.
    """

    frame: np.ndarray
    body: np.ndarray
    center: np.ndarray
    half: np.ndarray

    def corners(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(geom (8 nb,), body (8 nb,), offset (8 nb, 3))``: the eight corners of every box,
        the layout of a covering's ``(sphere_geom, sphere_body, sphere_offset)``."""
        offset = self.center[:, None, :] + _SIGNS[None] * self.half[:, None, :]
        return np.repeat(self.frame, 8), np.repeat(self.body, 8), offset.reshape(-1, 3)


def _quat_mats(quat: np.ndarray) -> np.ndarray:
    """``(n, 3, 3)`` rotation matrices of unit quaternions ``(n, 4)`` (w, x, y, z)."""
    w, x, y, z = quat.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=1,
    )


def body_boxes(
    model: mujoco.MjModel, points: tuple[npt.ArrayLike, npt.ArrayLike, npt.ArrayLike]
) -> BodyBoxes:
    """The box of each body around its ``points`` (``(geom, body, offset)``, offsets in the
    geom's frame), in the frame of the body's lowest-numbered geom among them. O(points)."""
    geom = np.asarray(points[0], dtype=np.int64).reshape(-1)
    body = np.asarray(model.geom_bodyid, dtype=np.int64)[geom]
    offset = np.asarray(points[2], dtype=np.float64).reshape(-1, 3)
    if geom.size == 0:
        z = np.zeros(0, dtype=np.int64)
        return BodyBoxes(z, z, np.zeros((0, 3)), np.zeros((0, 3)))
    mats = _quat_mats(np.asarray(model.geom_quat, dtype=np.float64))
    gpos = np.asarray(model.geom_pos, dtype=np.float64)
    in_body = gpos[geom] + np.einsum("nij,nj->ni", mats[geom], offset)
    bodies, inverse = np.unique(body, return_inverse=True)
    ref = np.full(bodies.size, np.iinfo(np.int64).max)
    np.minimum.at(ref, inverse, geom)
    # Into the reference geom's frame: R_ref^T (p - pos_ref).
    local = np.einsum("nji,nj->ni", mats[ref[inverse]], in_body - gpos[ref[inverse]])
    lo = np.full((bodies.size, 3), np.inf)
    hi = np.full((bodies.size, 3), -np.inf)
    np.minimum.at(lo, inverse, local)
    np.maximum.at(hi, inverse, local)
    return BodyBoxes(ref, bodies, 0.5 * (lo + hi), 0.5 * (hi - lo))


class EventTable:
    """The violation check's tables for one predictor: a record a checked body and the check's
    parameters (its state, and which held pairs each body has, are the native runtime's).

    Args:
        boxes: The bodies to check (:func:`body_boxes`).
        bounds: Their bounds.
        period: The predictor's period in physics steps.
        rtol: Relative tolerance of every comparison (``BoundMonitor``'s).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        boxes: BodyBoxes,
        bounds: MotionBounds,
        *,
        period: int,
        rtol: float = 1e-9,
    ) -> None:
        n = boxes.body.size
        h = float(model.opt.timestep)
        rec = np.zeros((n, NB_REC))
        rec[:, B_FRAME] = boxes.frame
        rec[:, B_BODY] = boxes.body
        rec[:, B_ROOT] = np.asarray(model.body_rootid, dtype=np.int64)[boxes.body]
        rec[:, B_CENTER : B_CENTER + 3] = boxes.center
        rec[:, B_HALF : B_HALF + 3] = boxes.half
        accel = bounds.accel[boxes.body]
        rec[:, B_ACCEL] = accel
        rec[:, B_DISC] = bounds.discrepancy[boxes.body] + 0.5 * accel * h * (period - 1)
        # A mocap body's velocity is its tracker's, the chord over the last period: one step on,
        # it is off by D_K = A h (K + 1) / 2 (discrete-time.md, section 3), A h (K - 1) / 2
        # more than a body whose velocity MuJoCo reports; (E2)'s mean over the period adds that.
        mocap = np.asarray(model.body_mocapid)[np.asarray(model.body_rootid)[boxes.body]] >= 0
        rec[mocap, B_DISC] += 0.5 * accel[mocap] * h * (period - 1)
        rec[:, B_SPEED] = np.inf if bounds.speed is None else bounds.speed[boxes.body]
        self.records = rec
        """``(nbody_checked, NB_REC)`` one record a checked body."""
        self.params = np.array([period * h, rtol])
        """``(2,)`` the period (seconds) and the relative tolerance."""

    @property
    def nbody(self) -> int:
        """Bodies checked."""
        return int(self.records.shape[0])


def no_events() -> EventTable:
    """The tables of a predictor that checks no body."""
    table = EventTable.__new__(EventTable)
    table.records = np.zeros((0, NB_REC))
    table.params = np.array([1.0, 0.0])
    return table


def build_events(
    model: mujoco.MjModel, boxes: BodyBoxes, bounds: MotionBounds, *, period: int
) -> EventTable:
    """The :class:`EventTable` of the moving bodies among ``boxes``."""
    moving = (bounds.accel[boxes.body] > 0) | moving_bodies(model)[boxes.body]
    kept = BodyBoxes(*(a[moving] for a in boxes))
    return EventTable(model, kept, bounds, period=period)
