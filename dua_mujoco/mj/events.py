"""Violations as events: a body whose motion broke its bounds makes its pairs due at once.

Every verdict assumes the bounds hold from its instant on. A contact's impulse breaks them, and
a pair whose verdict came before the impulse would keep it until its deadline: the collisions
that follow the impulse would be missed. So the compiled step first checks, per moving body, the
hypotheses of the discrete-time derivation over the last predictor period (docs/discrete-time.md;
the same ones ``BoundMonitor`` checks), and every held pair of a body that broke them is made
due now: its verdict is withdrawn (it stands in alarm, as a pair switched on does) and this very
step evaluates it again from the new state. docs/theory.md, section 6, proves what this restores.

**One box a body.** The acceleration, the one-step discrepancy and the chord speed of a point of
a rigid body are norms of affine functions of its body coordinates, so over a box their maxima
lie at the box's corners. Each body gets one box, in the frame of one of its geoms, around every
point whose motion the bounds limit (covering centres, the exact level's geom corners): its
eight corners are the predictor's ``bound_points``, which the pilot measures and
``BoundMonitor`` checks point by point. The step checks the same corners in O(1) a body from
the box's centre and axes: with ``c`` the centre and ``E = R diag(half)`` the axes, a corner is
``c + E s`` for ``s`` in ``{-1, 1}^3``, and each hypothesis reads ``max_s |a + M s| <= bound``
for an ``a`` and ``M`` built from two or three instants. ``|a| + sum_j |M_j|`` screens it; the
eight corners are looked at only when the screen fails.

**Over a period.** With ``period = p`` the step sees the state every ``H = p h`` seconds. From
the physics-step hypotheses, the chords ``U`` over a period obey ``|U_k - U_{k-1}| <= A H``,
``|U_k - w_{k-1}| <= D + A h (p - 1) / 2`` and ``|U_k| <= V``: that is what is checked. For
``p = 1`` these are the hypotheses themselves; for ``p > 1`` a violation that leaves no trace at
the ends of its period is not seen (docs/theory.md, section 6).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import mujoco
import numba as nb
import numpy as np
import numpy.typing as npt

from dua_mujoco.core.schedules.kernels import make_due
from dua_mujoco.mj.bounds import MotionBounds

__all__ = [
    "BodyBoxes",
    "EventTable",
    "body_boxes",
    "build_events",
    "check_bodies",
    "no_events",
    "reset_events",
    "violation_pass",
]

# Columns of a body record.
B_FRAME, B_BODY, B_ROOT = 0, 1, 2
B_CENTER = 3  # 3..5: the box's centre in the frame
B_HALF = 6  # 6..8: its half extents
B_ACCEL, B_DISC, B_SPEED = 9, 10, 11
NB_REC = 12

# Columns of a body's state at the last step (and of the scratch row of this step).
S_C = 0  # 0..2: the box's centre
S_E = 3  # 3..11: its three axes, axis j at 3 + 3 j
S_U = 12  # 12..14: the centre's chord over the last period
S_UE = 15  # 15..23: the axes' chords
S_V = 24  # 24..26: the centre's velocity read from MjData
S_W = 27  # 27..29: the body's angular velocity (with its mocap root's)
S_SCALE = 30  # a bound on the corners' coordinates
NB_STATE = 31

# Entries of the int64 ``meta`` array.
M_NPREV = 0  # states recorded since the reset, up to 2
M_COUNT = 1  # bodies that broke a bound at the latest step
M_TOTAL = 2  # body-steps that broke a bound since the reset

_EPS = float(np.finfo(float).eps)


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
        signs = np.array(
            [[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float
        )
        offset = self.center[:, None, :] + signs[None] * self.half[:, None, :]
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
    """The violation check's tables and state for one predictor.

    Args:
        model: The model.
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
        rec[:, B_SPEED] = np.inf if bounds.speed is None else bounds.speed[boxes.body]
        self.records = rec
        self.state = np.zeros((n, NB_STATE))
        self.meta = np.zeros(3, dtype=np.int64)
        self.flagged = np.zeros(max(n, 1), dtype=np.int64)
        self.params = np.array([period * h, rtol])
        self._row = np.full(model.nbody, -1, dtype=np.int64)
        self._row[boxes.body] = np.arange(n)
        self._geom_body = np.asarray(model.geom_bodyid, dtype=np.int64)
        self.start = np.zeros(n + 1, dtype=np.int64)
        self.members = np.zeros(0, dtype=np.int64)

    def hold(self, geom1: np.ndarray, geom2: np.ndarray) -> None:
        """Index the held pairs (``geom1``, ``geom2`` of each, ``-1`` for none) by body."""
        k = geom1.shape[0]
        rows = []
        for g in (geom1, geom2):
            b = np.where(g >= 0, self._geom_body[np.maximum(g, 0)], 0)
            rows.append(np.where(g >= 0, self._row[b], -1))
        row = np.concatenate(rows)
        pos = np.concatenate([np.arange(k), np.arange(k)])
        keep = row >= 0
        row, pos = row[keep], pos[keep]
        order = np.argsort(row, kind="stable")
        self.members = np.ascontiguousarray(pos[order])
        self.start = np.searchsorted(row[order], np.arange(self.records.shape[0] + 1))

    @property
    def nbody(self) -> int:
        """Bodies checked."""
        return int(self.records.shape[0])

    @property
    def violated(self) -> np.ndarray:
        """``(k,)`` ids of the bodies that broke a bound at the latest step."""
        rows = self.flagged[: int(self.meta[M_COUNT])]
        return self.records[rows, B_BODY].astype(np.int64)

    @property
    def total(self) -> int:
        """Body-steps that broke a bound since the reset."""
        return int(self.meta[M_TOTAL])

    def args(self) -> tuple:
        """The compiled step's ``events`` tuple."""
        return (
            self.records,
            self.state,
            self.meta,
            self.flagged,
            self.start,
            self.members,
            self.params,
        )


def no_events() -> tuple:
    """The ``events`` tuple of a predictor that checks no body."""
    return (
        np.zeros((0, NB_REC)),
        np.zeros((0, NB_STATE)),
        np.zeros(3, dtype=np.int64),
        np.zeros(1, dtype=np.int64),
        np.zeros(1, dtype=np.int64),
        np.zeros(0, dtype=np.int64),
        np.array([1.0, 0.0]),
    )


def build_events(
    model: mujoco.MjModel, boxes: BodyBoxes, bounds: MotionBounds, *, period: int
) -> EventTable:
    """The :class:`EventTable` of the moving bodies among ``boxes``."""
    moving = bounds.accel[boxes.body] > 0
    moving |= (np.asarray(model.body_weldid)[boxes.body] != 0) | (
        np.asarray(model.body_mocapid)[np.asarray(model.body_rootid)[boxes.body]] >= 0
    )
    kept = BodyBoxes(*(a[moving] for a in boxes))
    return EventTable(model, kept, bounds, period=period)


@nb.njit(cache=True, inline="always")
def _exceeds12(a0, a1, a2, x0, x1, x2, y0, y1, y2, z0, z1, z2, bound):  # pragma: no cover
    """Whether ``max_s |a + s_0 x + s_1 y + s_2 z|`` over ``s`` in ``{-1, 1}^3`` exceeds
    ``bound``. Two screens first, each an upper bound of the maximum: ``2 sqrt(sum of the four
    squared norms)`` (no root taken) and ``|a| + |x| + |y| + |z|``; the corners only when both
    fail."""
    na = a0 * a0 + a1 * a1 + a2 * a2
    nx = x0 * x0 + x1 * x1 + x2 * x2
    ny = y0 * y0 + y1 * y1 + y2 * y2
    nz = z0 * z0 + z1 * z1 + z2 * z2
    if 4.0 * (na + nx + ny + nz) <= bound * bound:
        return False
    if math.sqrt(na) + math.sqrt(nx) + math.sqrt(ny) + math.sqrt(nz) <= bound:
        return False
    worst = 0.0
    for sx in (-1.0, 1.0):
        for sy in (-1.0, 1.0):
            for sz in (-1.0, 1.0):
                u = a0 + sx * x0 + sy * y0 + sz * z0
                v = a1 + sx * x1 + sy * y1 + sz * z1
                w = a2 + sx * x2 + sy * y2 + sz * z2
                worst = max(worst, u * u + v * v + w * w)
    return math.sqrt(worst) > bound


@nb.njit(cache=True, inline="always")
def _exceeds(q, bound):  # pragma: no cover - jitted
    """:func:`_exceeds12` on ``q = [a, x, y, z]`` (twelve entries)."""
    return _exceeds12(
        q[0], q[1], q[2], q[3], q[4], q[5], q[6], q[7], q[8], q[9], q[10], q[11], bound
    )


@nb.njit(cache=True)
def check_bodies(events, frame):  # pragma: no cover - jitted
    """Record every body's state and check the hypotheses over the last period; returns the
    number of bodies that broke one (their rows in ``flagged``). Scalars throughout: the
    values stay in registers (measured: 2x faster than through scratch rows)."""
    rec, prev, meta, flagged, _, _, params = events
    frame_pos, frame_mat, twist, twist_ref, root_twist, root_origin = frame
    h, rtol = params[0], params[1]
    inv_h = 1.0 / h  # a product per chord, not a division (the loop's slowest operation)
    nprev = meta[M_NPREV]
    count = 0
    for i in range(rec.shape[0]):
        g = int(rec[i, B_FRAME])
        b = int(rec[i, B_BODY])
        r = int(rec[i, B_ROOT])
        r0, r1, r2 = frame_mat[g, 0], frame_mat[g, 1], frame_mat[g, 2]
        r3, r4, r5 = frame_mat[g, 3], frame_mat[g, 4], frame_mat[g, 5]
        r6, r7, r8 = frame_mat[g, 6], frame_mat[g, 7], frame_mat[g, 8]
        o0, o1, o2 = rec[i, B_CENTER], rec[i, B_CENTER + 1], rec[i, B_CENTER + 2]
        h0, h1, h2 = rec[i, B_HALF], rec[i, B_HALF + 1], rec[i, B_HALF + 2]
        # The box's centre and its axes (columns of R diag(half)).
        cx = frame_pos[g, 0] + r0 * o0 + r1 * o1 + r2 * o2
        cy = frame_pos[g, 1] + r3 * o0 + r4 * o1 + r5 * o2
        cz = frame_pos[g, 2] + r6 * o0 + r7 * o1 + r8 * o2
        xx, xy, xz = r0 * h0, r3 * h0, r6 * h0
        yx, yy, yz = r1 * h1, r4 * h1, r7 * h1
        zx, zy, zz = r2 * h2, r5 * h2, r8 * h2
        # Bounds every corner's coordinates: the scale of the differences' round-off.
        scale = max(
            abs(cx) + abs(xx) + abs(yx) + abs(zx),
            abs(cy) + abs(xy) + abs(yy) + abs(zy),
            abs(cz) + abs(xz) + abs(yz) + abs(zz),
        )
        # The centre's velocity as rigid_point reads a point's: the body twist about cvel's
        # reference point, plus the twist of a mocap root (zero elsewhere).
        w0, w1, w2 = twist[b, 0], twist[b, 1], twist[b, 2]
        dx, dy, dz = cx - twist_ref[r, 0], cy - twist_ref[r, 1], cz - twist_ref[r, 2]
        m0, m1, m2 = root_twist[r, 0], root_twist[r, 1], root_twist[r, 2]
        ex, ey, ez = cx - root_origin[r, 0], cy - root_origin[r, 1], cz - root_origin[r, 2]
        vx = twist[b, 3] + w1 * dz - w2 * dy + root_twist[r, 3] + m1 * ez - m2 * ey
        vy = twist[b, 4] + w2 * dx - w0 * dz + root_twist[r, 4] + m2 * ex - m0 * ez
        vz = twist[b, 5] + w0 * dy - w1 * dx + root_twist[r, 5] + m0 * ey - m1 * ex
        broken = False
        if nprev >= 1:
            ucx, ucy, ucz = (
                (cx - prev[i, 0]) * inv_h,
                (cy - prev[i, 1]) * inv_h,
                (cz - prev[i, 2]) * inv_h,
            )
            uxx, uxy, uxz = (
                (xx - prev[i, 3]) * inv_h,
                (xy - prev[i, 4]) * inv_h,
                (xz - prev[i, 5]) * inv_h,
            )
            uyx, uyy, uyz = (
                (yx - prev[i, 6]) * inv_h,
                (yy - prev[i, 7]) * inv_h,
                (yz - prev[i, 8]) * inv_h,
            )
            uzx, uzy, uzz = (
                (zx - prev[i, 9]) * inv_h,
                (zy - prev[i, 10]) * inv_h,
                (zz - prev[i, 11]) * inv_h,
            )
            tol_a = 8.0 * _EPS * (scale + prev[i, S_SCALE]) / (h * h)
            speed = rec[i, B_SPEED]
            if speed < math.inf:
                broken |= _exceeds12(
                    ucx, ucy, ucz, uxx, uxy, uxz, uyx, uyy, uyz, uzx, uzy, uzz,
                    speed * (1.0 + rtol) + 0.5 * tol_a * h,
                )  # fmt: skip
            # The discrepancy U_k - w_{k-1} at the corners, w_{k-1} from the last state.
            px, py, pz = prev[i, S_W], prev[i, S_W + 1], prev[i, S_W + 2]
            qvx, qvy, qvz = prev[i, S_V], prev[i, S_V + 1], prev[i, S_V + 2]
            tol_d = tol_a * h + 8.0 * _EPS * (abs(qvx) + abs(qvy) + abs(qvz))
            broken |= _exceeds12(
                ucx - qvx, ucy - qvy, ucz - qvz,
                uxx - (py * prev[i, 5] - pz * prev[i, 4]),
                uxy - (pz * prev[i, 3] - px * prev[i, 5]),
                uxz - (px * prev[i, 4] - py * prev[i, 3]),
                uyx - (py * prev[i, 8] - pz * prev[i, 7]),
                uyy - (pz * prev[i, 6] - px * prev[i, 8]),
                uyz - (px * prev[i, 7] - py * prev[i, 6]),
                uzx - (py * prev[i, 11] - pz * prev[i, 10]),
                uzy - (pz * prev[i, 9] - px * prev[i, 11]),
                uzz - (px * prev[i, 10] - py * prev[i, 9]),
                rec[i, B_DISC] * (1.0 + rtol) + tol_d,
            )  # fmt: skip
            if nprev >= 2:
                broken |= _exceeds12(
                    (ucx - prev[i, 12]) * inv_h,
                    (ucy - prev[i, 13]) * inv_h,
                    (ucz - prev[i, 14]) * inv_h,
                    (uxx - prev[i, 15]) * inv_h,
                    (uxy - prev[i, 16]) * inv_h,
                    (uxz - prev[i, 17]) * inv_h,
                    (uyx - prev[i, 18]) * inv_h,
                    (uyy - prev[i, 19]) * inv_h,
                    (uyz - prev[i, 20]) * inv_h,
                    (uzx - prev[i, 21]) * inv_h,
                    (uzy - prev[i, 22]) * inv_h,
                    (uzz - prev[i, 23]) * inv_h,
                    rec[i, B_ACCEL] * (1.0 + rtol) + tol_a,
                )
            prev[i, 12], prev[i, 13], prev[i, 14] = ucx, ucy, ucz
            prev[i, 15], prev[i, 16], prev[i, 17] = uxx, uxy, uxz
            prev[i, 18], prev[i, 19], prev[i, 20] = uyx, uyy, uyz
            prev[i, 21], prev[i, 22], prev[i, 23] = uzx, uzy, uzz
        prev[i, 0], prev[i, 1], prev[i, 2] = cx, cy, cz
        prev[i, 3], prev[i, 4], prev[i, 5] = xx, xy, xz
        prev[i, 6], prev[i, 7], prev[i, 8] = yx, yy, yz
        prev[i, 9], prev[i, 10], prev[i, 11] = zx, zy, zz
        prev[i, S_V], prev[i, S_V + 1], prev[i, S_V + 2] = vx, vy, vz
        prev[i, S_W], prev[i, S_W + 1], prev[i, S_W + 2] = w0 + m0, w1 + m1, w2 + m2
        prev[i, S_SCALE] = scale
        if broken:
            flagged[count] = i
            count += 1
    meta[M_NPREV] = min(nprev + 1, 2)
    meta[M_COUNT] = count
    meta[M_TOTAL] += count
    return count


@nb.njit(cache=True)
def reset_events(events, frame):  # pragma: no cover - jitted
    """Start the check over at ``frame``'s instant: its state is recorded, nothing checked."""
    events[2][M_NPREV] = 0
    events[2][M_TOTAL] = 0
    check_bodies(events, frame)
    events[2][M_TOTAL] = 0


@nb.njit(cache=True)
def violation_pass(st, n, events, frame):  # pragma: no cover - jitted
    """The step's first pass: check every body, and make every held pair of a body that broke
    its bounds due at step ``n`` (``kernels.make_due``). Returns the number of such bodies."""
    count = check_bodies(events, frame)
    flagged, start, members = events[3], events[4], events[5]
    for k in range(count):
        i = flagged[k]
        for m in range(start[i], start[i + 1]):
            make_due(st, members[m], n)
    return count
