"""The Dynamic Urgency Algorithm scheduler and the select-all baselines (SPEC section 4).

Layout. ``M`` pairs, ``L = ceil(log2(M + 1))`` buckets; bucket ``k`` has ``2**k`` slots and starts
at slot ``2**k - 1`` of one flat array of ``2**L - 1`` slots (the last bucket partly empty, ``-1``).

Protocol. ``DUAScheduler(tau0, dt=...)`` is the initial classification (evaluation number 0, at
time 0). Step ``n = 1, 2, ...`` calls ``select()`` then ``update(ids, tau)`` with tau evaluated at
time ``n * dt``. With ``q`` slots per bucket per step (the budget knob, a power of two), bucket
``k`` hands out the ``min(q, 2**k)`` slots ``(n q + j) mod 2**k``, so every slot of bucket ``k`` is
visited exactly every ``I_k = max(1, 2**k / q)`` steps. The ``i``-th most urgent of the evaluated
pairs goes back into the ``i``-th of the withdrawn slots in bucket order, and it raises an alarm if
``tau < (I_k + latency) * dt`` for the bucket ``k`` it lands in. Completeness is proved in
docs/theory.md.

The jitted pieces (``_select``, ``_reinsert``) are shared by the Python protocol and the fused step
``DUAScheduler.step_points``, which evaluates tau inside the same compiled call.
"""

from __future__ import annotations

import enum
import math

import numba as nb
import numpy as np
import numpy.typing as npt

from dua_mujoco.exceptions import (
    InvalidChoiceError,
    InvalidInputError,
    NonFiniteStateError,
    SchedulerError,
    ShapeError,
)
from dua_mujoco.urgency import _PARALLEL_MIN, _per_pair, _vectors, tau_halfspace, tau_speed

__all__ = [
    "DUAScheduler",
    "PairSet",
    "SelectAllScheduler",
    "Urgency",
    "bucket_layout",
]


class Urgency(enum.Enum):
    """What a select-all baseline ranks pairs by."""

    TAU = "tau"
    """Time to collision (SPEC section 2): the paper's SA(tau)."""
    DISTANCE = "distance"
    """Clearance ``|x| - eps``: the paper's SA(d)."""


def bucket_layout(npairs: int) -> tuple[int, int]:
    """Number of buckets ``L`` and of slots ``2**L - 1`` for ``npairs`` pairs."""
    nbuckets = max(1, math.ceil(math.log2(npairs + 1)))
    return nbuckets, (1 << nbuckets) - 1


# --------------------------------------------------------------------------- jitted core


@nb.njit(cache=True)
def _select(slots, active, nbuckets, q, n, out_slots, out_ids):  # pragma: no cover - jitted
    """Withdrawn slots and their pair ids for step ``n``, in bucket order; returns their count."""
    count = 0
    for k in range(nbuckets):
        size = 1 << k
        base = size - 1
        take = min(q, size)
        first = (n * q) % size
        for j in range(take):
            slot = base + (first + j) % size
            pid = slots[slot]
            if pid >= 0 and active[pid]:
                out_slots[count] = slot
                out_ids[count] = pid
                count += 1
    return count


@nb.njit(cache=True, inline="always")
def _bucket_of(slot):  # pragma: no cover - jitted
    k = 0
    while (2 << k) - 1 <= slot:
        k += 1
    return k


@nb.njit(cache=True)
def _reinsert(
    slots, where, last_tau, last_step, horizon, n, w_slots, w_ids, w_tau, count, alarms
):  # pragma: no cover - jitted
    """Sort the evaluated pairs by tau into the withdrawn slots (bucket order); returns #alarms.

    ``w_slots`` is in bucket order, so the i-th smallest tau lands in the i-th smallest bucket
    among those the pairs came from. ``w_tau`` is indexed like ``w_ids``.
    """
    order = np.argsort(w_tau[:count], kind="mergesort")
    nalarm = 0
    for i in range(count):
        src = order[i]
        pid = w_ids[src]
        slot = w_slots[i]
        tau = w_tau[src]
        slots[slot] = pid
        where[pid] = slot
        last_tau[pid] = tau
        last_step[pid] = n
        if tau < horizon[_bucket_of(slot)]:
            alarms[nalarm] = pid
            nalarm += 1
    return nalarm


@nb.njit(cache=True, inline="always")
def _sphere_sphere_tau(ci, vi, cj, vj, p, eps, accel, delta, speed):  # pragma: no cover - jitted
    return tau_speed(
        cj[0] - ci[0],
        cj[1] - ci[1],
        cj[2] - ci[2],
        vj[0] - vi[0],
        vj[1] - vi[1],
        vj[2] - vi[2],
        eps[p],
        accel[p],
        delta[p],
        speed[p],
    )


@nb.njit(cache=True, inline="always")
def _sphere_halfspace_tau(c, v, normal, offset, p, eps, accel, delta):  # pragma: no cover - jitted
    gap = normal[0] * c[0] + normal[1] * c[1] + normal[2] * c[2] - offset - eps[p]
    vn = normal[0] * v[0] + normal[1] * v[1] + normal[2] * v[2]
    return tau_halfspace(gap, vn, accel[p], delta[p])


@nb.njit(cache=True, inline="always")
def _pair_tau(p, geometry):  # pragma: no cover - jitted
    """tau of pair ``p``; ``geometry`` is ``PairSet._geometry``'s tuple."""
    centers, velocities, normals, offsets, first, second, halfspace, eps, accel, delta, speed = (
        geometry
    )
    i = first[p]
    j = second[p]
    if halfspace[p]:
        return _sphere_halfspace_tau(
            centers[i], velocities[i], normals[j], offsets[j], p, eps, accel, delta
        )
    return _sphere_sphere_tau(
        centers[i], velocities[i], centers[j], velocities[j], p, eps, accel, delta, speed
    )


def _tau_pairs(ids: np.ndarray, geometry: tuple) -> np.ndarray:
    """tau of the pairs ``ids``: threads for large batches, serial for small ones."""
    kernel = _tau_pairs_parallel if ids.shape[0] >= _PARALLEL_MIN else _tau_pairs_serial
    return kernel(ids, geometry)


# The serial and threaded kernels differ only in range/prange: numba has no switch for it.
@nb.njit(cache=True)
def _tau_pairs_serial(ids, geometry):  # pragma: no cover - jitted
    out = np.empty(ids.shape[0])
    for k in range(ids.shape[0]):
        out[k] = _pair_tau(ids[k], geometry)
    return out


@nb.njit(cache=True, parallel=True)
def _tau_pairs_parallel(ids, geometry):  # pragma: no cover - jitted
    out = np.empty(ids.shape[0])
    for k in nb.prange(ids.shape[0]):
        out[k] = _pair_tau(ids[k], geometry)
    return out


@nb.njit(cache=True)
def _step_points(
    slots,
    pair_state,
    last_tau,
    horizon,
    active,
    nbuckets,
    q,
    n,
    work,
    w_tau,
    geometry,
):  # pragma: no cover - jitted
    """The fused step on free points (``SphereWorld``); arguments as ``_step_rigid``'s, the
    pairs and their states as ``PairSet._geometry``'s tuple."""
    centers, velocities, _, _, first, second, halfspace, _, _, _, _ = geometry
    where = pair_state[0]
    last_step = pair_state[1]
    w_slots = work[0]
    w_ids = work[1]
    alarms = work[2]
    count = _select(slots, active, nbuckets, q, n, w_slots, w_ids)
    for k in range(count):
        p = w_ids[k]
        i = first[p]
        state = 0.0
        for a in range(3):
            state += centers[i, a] + velocities[i, a]
        if not halfspace[p]:
            j = second[p]
            for a in range(3):
                state += centers[j, a] + velocities[j, a]
        if not math.isfinite(state):
            return count, 0, p
        w_tau[k] = _pair_tau(p, geometry)
    nalarm = _reinsert(
        slots, where, last_tau, last_step, horizon, n, w_slots, w_ids, w_tau, count, alarms
    )
    return count, nalarm, -1


# Column layout of the packed per-pair and per-sphere records read by the rigid fused step: one
# 64-byte row (a cache line) per pair and per sphere instead of one line in each of 7 or 3
# separate arrays, because after mj_step those tables are cold and the step is memory-bound.
(
    PAIR_FIRST,
    PAIR_SECOND,
    PAIR_HALFSPACE,
    PAIR_EPS,
    PAIR_ACCEL,
    PAIR_DELTA,
    PAIR_SPEED,
    PAIR_PLANE_FRAME,
) = range(8)
SPHERE_FRAME, SPHERE_BODY, SPHERE_OFFSET, SPHERE_ROOT = 0, 1, 2, 5  # offset: columns 2, 3, 4


def pack_pairs(pairs: PairSet, plane_frame: npt.ArrayLike | None = None) -> np.ndarray:
    """``(M, 8)`` float64 records ``[first, second, halfspace, eps, accel, delta, speed, plane]``.

    Args:
        pairs: The pair set.
        plane_frame: ``(nplane,)`` frame (geom) of each half-space: ``plane`` is the frame of a
            half-space pair's plane (0 for sphere pairs, and for all pairs if not given).

    Ids are stored as floats: exact below 2**53.
    """
    rec = np.zeros((len(pairs), 8))
    rec[:, PAIR_FIRST] = pairs.first
    rec[:, PAIR_SECOND] = pairs.second
    rec[:, PAIR_HALFSPACE] = pairs.halfspace
    rec[:, PAIR_EPS] = pairs.eps
    rec[:, PAIR_ACCEL] = pairs.accel
    rec[:, PAIR_DELTA] = pairs.vel_uncertainty
    rec[:, PAIR_SPEED] = pairs.speed
    if plane_frame is not None:
        frame = np.asarray(plane_frame, dtype=np.int64)
        h = pairs.halfspace
        rec[h, PAIR_PLANE_FRAME] = frame[pairs.second[h]]
    return rec


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
    frame = np.asarray(sphere_frame)
    body = np.asarray(sphere_body, dtype=np.int64)
    rec = np.zeros((frame.shape[0], 8))
    rec[:, SPHERE_FRAME] = frame
    rec[:, SPHERE_BODY] = body
    rec[:, SPHERE_OFFSET : SPHERE_OFFSET + 3] = np.asarray(sphere_offset, dtype=np.float64)
    rec[:, SPHERE_ROOT] = np.asarray(body_root, dtype=np.int64)[body]
    return rec


@nb.njit(cache=True, inline="always")
def _rigid_point(i, spheres, frame, out):  # pragma: no cover - jitted
    """Centre and velocity of sphere ``i`` attached to a rigid frame (MuJoCo's conventions).

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
    g = int(spheres[i, 0])
    b = int(spheres[i, 1])
    o0 = spheres[i, 2]
    o1 = spheres[i, 3]
    o2 = spheres[i, 4]
    for k in range(3):
        out[k] = (
            frame_pos[g, k]
            + frame_mat[g, 3 * k] * o0
            + frame_mat[g, 3 * k + 1] * o1
            + frame_mat[g, 3 * k + 2] * o2
        )
    r = int(spheres[i, 5])
    dx = out[0] - twist_ref[r, 0]
    dy = out[1] - twist_ref[r, 1]
    dz = out[2] - twist_ref[r, 2]
    out[3] = twist[b, 3] + twist[b, 1] * dz - twist[b, 2] * dy
    out[4] = twist[b, 4] + twist[b, 2] * dx - twist[b, 0] * dz
    out[5] = twist[b, 5] + twist[b, 0] * dy - twist[b, 1] * dx
    mt = root_twist[r]
    if mt[0] != 0.0 or mt[1] != 0.0 or mt[2] != 0.0 or mt[3] != 0.0 or mt[4] != 0.0 or mt[5] != 0.0:
        ex = out[0] - root_origin[r, 0]
        ey = out[1] - root_origin[r, 1]
        ez = out[2] - root_origin[r, 2]
        out[3] += mt[3] + mt[1] * ez - mt[2] * ey
        out[4] += mt[4] + mt[2] * ex - mt[0] * ez
        out[5] += mt[5] + mt[0] * ey - mt[1] * ex


@nb.njit(cache=True)
def _step_rigid(
    slots,
    pair_state,
    last_tau,
    horizon,
    active,
    nbuckets,
    q,
    n,
    work,
    w_tau,
    pairs,
    spheres,
    frame,
):  # pragma: no cover - jitted
    """The fused step on spheres attached to rigid frames; reads only the selected spheres.

    ``pairs`` and ``spheres`` are ``pack_pairs`` / ``pack_spheres`` records. Two passes: first
    every selected pair's state is gathered (independent loads, which the CPU overlaps; the tables
    are cold after ``mj_step``), then tau is computed from that small buffer. Returns
    ``(count, nalarm, bad)``: ``bad`` is the first pair whose state is not finite (-1 if none);
    the step is then abandoned before re-bucketing. ``pair_state`` holds the rows ``where``,
    ``last_step``; ``work`` the rows ``w_slots``, ``w_ids``, ``alarms``.
    """
    where = pair_state[0]
    last_step = pair_state[1]
    w_slots = work[0]
    w_ids = work[1]
    alarms = work[2]
    frame_pos, frame_mat = frame[0], frame[1]
    count = _select(slots, active, nbuckets, q, n, w_slots, w_ids)
    # Row k: sphere i's centre and velocity, then sphere j's (or the plane's normal, offset).
    state = np.empty((count, 12))
    for k in range(count):
        rec = pairs[w_ids[k]]
        _rigid_point(int(rec[0]), spheres, frame, state[k, 0:6])
        if rec[2] != 0.0:
            g = int(rec[7])
            state[k, 6] = frame_mat[g, 2]
            state[k, 7] = frame_mat[g, 5]
            state[k, 8] = frame_mat[g, 8]
            state[k, 9] = (
                state[k, 6] * frame_pos[g, 0]
                + state[k, 7] * frame_pos[g, 1]
                + state[k, 8] * frame_pos[g, 2]
            )
            state[k, 10] = 0.0
            state[k, 11] = 0.0
        else:
            _rigid_point(int(rec[1]), spheres, frame, state[k, 6:12])
    for k in range(count):
        rec = pairs[w_ids[k]]
        s = state[k]
        total = 0.0
        for a in range(12):
            total += s[a]
        if not math.isfinite(total):
            return count, 0, w_ids[k]
        if rec[2] != 0.0:
            gap = s[6] * s[0] + s[7] * s[1] + s[8] * s[2] - s[9] - rec[3]
            vn = s[6] * s[3] + s[7] * s[4] + s[8] * s[5]
            w_tau[k] = tau_halfspace(gap, vn, rec[4], rec[5])
        else:
            w_tau[k] = tau_speed(
                s[6] - s[0],
                s[7] - s[1],
                s[8] - s[2],
                s[9] - s[3],
                s[10] - s[4],
                s[11] - s[5],
                rec[3],
                rec[4],
                rec[5],
                rec[6],
            )
    nalarm = _reinsert(
        slots, where, last_tau, last_step, horizon, n, w_slots, w_ids, w_tau, count, alarms
    )
    return count, nalarm, -1


# --------------------------------------------------------------------------- pair geometry

# Placeholders for pair sets without half-spaces (never read: no pair indexes them).
_NO_NORMALS = np.zeros((1, 3))
_NO_NORMALS.flags.writeable = False
_NO_OFFSETS = np.zeros(1)
_NO_OFFSETS.flags.writeable = False


class PairSet:
    """Sphere-sphere and sphere-half-space pairs with their contact distances and bounds.

    Args:
        first: ``(M,)`` sphere index of each pair.
        second: ``(M,)`` sphere index, or half-space index where ``halfspace`` is set.
        eps: ``(M,)`` or scalar contact distance (radii plus margin; for a half-space pair the
            sphere radius plus margin).
        accel: ``(M,)`` or scalar bound on the relative acceleration norm (``A_i + A_j``).
        halfspace: ``(M,)`` bool, pairs whose ``second`` is a half-space (default none).
        vel_uncertainty: ``(M,)`` or scalar velocity uncertainty ``delta`` (default 0).
        speed: ``(M,)`` or scalar relative speed bound (default ``inf``, none).
    """

    def __init__(
        self,
        first: npt.ArrayLike,
        second: npt.ArrayLike,
        eps: npt.ArrayLike,
        accel: npt.ArrayLike,
        *,
        halfspace: npt.ArrayLike | None = None,
        vel_uncertainty: npt.ArrayLike = 0.0,
        speed: npt.ArrayLike = np.inf,
    ) -> None:
        self.first = _ids("first", first)
        m = self.first.shape[0]
        self.second = _ids("second", second, m)
        self.halfspace = (
            np.zeros(m, dtype=np.bool_)
            if halfspace is None
            else np.ascontiguousarray(np.broadcast_to(np.asarray(halfspace, dtype=np.bool_), (m,)))
        )
        self.eps = np.broadcast_to(_per_pair("eps", eps, m), (m,)).copy()
        self.accel = np.broadcast_to(_per_pair("accel", accel, m), (m,)).copy()
        self.vel_uncertainty = np.broadcast_to(
            _per_pair("vel_uncertainty", vel_uncertainty, m), (m,)
        ).copy()
        self.speed = np.broadcast_to(_per_pair("speed", speed, m, allow_inf=True), (m,)).copy()
        if (self.speed == 0.0).any():
            raise InvalidInputError("speed bounds must be positive; use inf for none.")
        if (self.first < 0).any() or (self.second < 0).any():
            raise InvalidInputError("sphere and half-space indices must be >= 0.")
        # Checked once here so that the per-step state check is O(1).
        spheres = np.concatenate([self.first, self.second[~self.halfspace]])
        self.max_sphere = int(spheres.max(initial=-1))
        self.max_halfspace = int(self.second[self.halfspace].max(initial=-1))
        self.has_halfspace = bool(self.halfspace.any())

    def __len__(self) -> int:
        return int(self.first.shape[0])

    @classmethod
    def all_pairs(
        cls,
        radius: npt.ArrayLike,
        accel: npt.ArrayLike,
        *,
        margin: float = 0.0,
        vel_uncertainty: npt.ArrayLike = 0.0,
        speed: npt.ArrayLike | None = None,
    ) -> PairSet:
        """Every pair ``i < j`` of ``N`` spheres, with per-sphere radii and bounds summed per pair.

        Args:
            radius: ``(N,)`` sphere radii.
            accel: ``(N,)`` or scalar per-sphere acceleration bound.
            margin: Extra contact distance added to every pair.
            vel_uncertainty: ``(N,)`` or scalar per-sphere velocity uncertainty.
            speed: ``(N,)`` or scalar per-sphere speed bound, or None.
        """
        r = np.asarray(radius, dtype=np.float64)
        if r.ndim != 1:
            raise ShapeError(f"radius has shape {r.shape}; expected (N,).")
        n = r.shape[0]
        i, j = np.triu_indices(n, k=1)

        def per_sphere(name: str, value: npt.ArrayLike) -> np.ndarray:
            return np.broadcast_to(_per_pair(name, value, n, allow_inf=True), (n,))

        a = per_sphere("accel", accel)
        d = per_sphere("vel_uncertainty", vel_uncertainty)
        s = (
            np.inf
            if speed is None
            else per_sphere("speed", speed)[i] + per_sphere("speed", speed)[j]
        )
        return cls(
            i,
            j,
            r[i] + r[j] + margin,
            a[i] + a[j],
            vel_uncertainty=d[i] + d[j],
            speed=s,
        )

    def tau(
        self,
        ids: npt.ArrayLike,
        centers: npt.ArrayLike,
        velocities: npt.ArrayLike,
        halfspaces: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
    ) -> np.ndarray:
        """tau of the pairs ``ids`` from sphere states (the vectorised front of the fused step).

        Args:
            ids: ``(n,)`` pair ids.
            centers: ``(nsphere, 3)`` sphere centres.
            velocities: ``(nsphere, 3)`` sphere centre velocities.
            halfspaces: ``(normals (nh, 3), offsets (nh,))``: half-space ``j`` is
                ``{p : normals[j] . p <= offsets[j]}`` seen from outside, i.e. a sphere centre ``c``
                has clearance ``normals[j] . c - offsets[j] - eps``.

        Returns:
            ``(n,)`` tau of each pair.
        """
        idx = _ids("ids", ids)
        if idx.size and (idx.min() < 0 or idx.max() >= len(self)):
            raise InvalidInputError(f"pair ids must be in [0, {len(self)}); got {idx.tolist()}.")
        return np.asarray(_tau_pairs(idx, self._geometry(centers, velocities, halfspaces)))

    def _geometry(
        self,
        centers: npt.ArrayLike,
        velocities: npt.ArrayLike,
        halfspaces: tuple[npt.ArrayLike, npt.ArrayLike] | None,
        *,
        check_finite: bool = True,
    ) -> tuple[np.ndarray, ...]:
        """The tuple the tau kernels read: validated sphere and half-space states, then the pairs.

        ``(centers, velocities, normals, offsets, first, second, halfspace, eps, accel,
        vel_uncertainty, speed)``; one argument instead of eleven through every kernel.
        """
        c = _vectors("centers", centers, check_finite=check_finite)
        v = _vectors("velocities", velocities, c.shape[0], check_finite=check_finite)
        if halfspaces is None:
            nrm, off = _NO_NORMALS, _NO_OFFSETS
            if self.has_halfspace:
                raise InvalidInputError("these pairs include half-spaces: pass halfspaces=(n, o).")
        else:
            nrm = _vectors("halfspace normals", halfspaces[0])
            off = np.ascontiguousarray(np.asarray(halfspaces[1], dtype=np.float64).reshape(-1))
            if off.shape[0] != nrm.shape[0]:
                raise ShapeError(
                    f"halfspace offsets have {off.shape[0]} rows, normals {nrm.shape[0]}."
                )
        if self.max_sphere >= c.shape[0]:
            raise ShapeError(
                f"pairs reference sphere {self.max_sphere} but centers has {c.shape[0]} rows."
            )
        if self.max_halfspace >= nrm.shape[0] and self.has_halfspace:
            raise ShapeError(
                f"pairs reference half-space {self.max_halfspace} but {nrm.shape[0]} were given."
            )
        return (
            c,
            v,
            nrm,
            off,
            self.first,
            self.second,
            self.halfspace,
            self.eps,
            self.accel,
            self.vel_uncertainty,
            self.speed,
        )

    def distance(self, ids: npt.ArrayLike, centers: npt.ArrayLike) -> np.ndarray:
        """Distance urgency ``|c_j - c_i| - eps`` of the sphere-sphere pairs ``ids``, ``(n,)``."""
        idx = _ids("ids", ids)
        c = _vectors("centers", centers)
        return np.asarray(
            np.linalg.norm(c[self.second[idx]] - c[self.first[idx]], axis=1) - self.eps[idx]
        )


def _ids(name: str, value: npt.ArrayLike, m: int | None = None) -> np.ndarray:
    arr = np.asarray(value)
    if arr.ndim != 1 or (m is not None and arr.shape[0] != m):
        want = f"({m},)" if m is not None else "(n,)"
        raise ShapeError(f"{name} has shape {arr.shape}; expected {want}.")
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise InvalidInputError(f"{name} must hold integers; got dtype {arr.dtype}.")
    return np.ascontiguousarray(arr, dtype=np.int64)


def _check_dt(dt: float, latency: int) -> tuple[float, int]:
    if not (isinstance(dt, int | float) and math.isfinite(dt) and dt > 0):
        raise InvalidInputError(f"dt = {dt!r} is invalid: the predictor period must be > 0.")
    if not isinstance(latency, int | np.integer) or latency < 0:
        raise InvalidInputError(
            f"latency = {latency!r} is invalid: it must be an int >= 0 (1 when a verdict takes "
            "one period to compute, 0 when the predictor runs synchronously after each step)."
        )
    return float(dt), int(latency)


def _check_tau(name: str, tau: npt.ArrayLike, m: int | None = None) -> np.ndarray:
    arr = np.asarray(tau, dtype=np.float64)
    if arr.ndim != 1 or (m is not None and arr.shape[0] != m):
        want = f"({m},)" if m is not None else "(M,)"
        raise ShapeError(f"{name} has shape {arr.shape}; expected {want}.")
    bad = np.isnan(arr) | (arr < 0)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InvalidInputError(
            f"{name}[{i}] = {arr[i]} is invalid: urgencies must be >= 0 (inf allowed), not NaN."
        )
    return np.ascontiguousarray(arr)


# --------------------------------------------------------------------------- DUA


class DUAScheduler:
    """The Dynamic Urgency Algorithm (Hayward et al. 1995, sec. 7), with SPEC section 4's rules.

    Args:
        tau0: ``(M,)`` tau of every pair at time 0 (the initial classification).
        dt: Predictor period ``> 0`` (seconds between steps).
        latency: Periods a verdict takes to be delivered (1: the paper's eq. 26; 0: the predictor
            runs synchronously after each physics step).
        slots_per_bucket: Budget knob ``q`` (a power of two): slots evaluated per bucket per step.
            Revisit intervals shrink ``q``-fold; work grows ``q``-fold.
        active: Optional ``(M,)`` bool mask of pairs initially switched on (default all).

    Attributes:
        initial_alarms: ``(k,)`` ids of the pairs the initial classification alarms.
        step_count: Number of completed steps (0 after the initial classification).
    """

    def __init__(
        self,
        tau0: npt.ArrayLike,
        *,
        dt: float,
        latency: int = 1,
        slots_per_bucket: int = 1,
        active: npt.ArrayLike | None = None,
    ) -> None:
        tau = _check_tau("tau0", tau0)
        self.dt, self.latency = _check_dt(dt, latency)
        q = slots_per_bucket
        if not isinstance(q, int | np.integer) or q < 1 or (q & (q - 1)) != 0:
            raise InvalidChoiceError(
                "slots_per_bucket",
                q,
                [1, 2, 4, 8, 16, 32],
                hint="It must be a power of two so that every revisit interval is exact.",
            )
        self.slots_per_bucket = int(q)
        m = tau.shape[0]
        self.npairs = m
        self.nbuckets, nslots = bucket_layout(m)
        sizes = 1 << np.arange(self.nbuckets)
        self.interval = np.maximum(1, sizes // self.slots_per_bucket).astype(np.int64)
        self.horizon = (self.interval + self.latency) * self.dt
        self.active = (
            np.ones(m, dtype=np.bool_)
            if active is None
            else np.ascontiguousarray(np.asarray(active, dtype=np.bool_))
        )
        if self.active.shape != (m,):
            raise ShapeError(f"active has shape {self.active.shape}; expected ({m},).")

        # Initial classification: a partial sort at the bucket boundaries (paper eq. 23).
        bounds = (1 << np.arange(1, self.nbuckets)) - 1
        bounds = bounds[bounds < m]
        order = np.argpartition(tau, bounds) if bounds.size else np.arange(m)
        self.slots = np.full(nslots, -1, dtype=np.int64)
        self.slots[:m] = order
        # ``where`` and ``last_step`` are rows of one array and the work buffers rows of another
        # so that the fused kernels take fewer arguments: numba's dispatch costs ~50 ns per
        # array argument, a sizeable part of a step of a few microseconds.
        self._pair_state = np.zeros((2, m), dtype=np.int64)
        self.where = self._pair_state[0]
        self.where[order] = np.arange(m)
        self.last_step = self._pair_state[1]
        self.last_tau = tau.copy()
        self.step_count = 0
        alarmed = (tau < self.horizon[self.bucket_of_slot(self.where)]) & self.active
        self.initial_alarms = np.flatnonzero(alarmed).astype(np.int64)

        width = int(np.minimum(sizes, self.slots_per_bucket).sum())
        self._work = np.empty((3, width), dtype=np.int64)
        self._w_slots, self._w_ids, self._alarms = self._work
        self._w_tau = np.empty(width)
        self._pending: np.ndarray | None = None
        self._pending_count = 0
        self._last_count = 0
        self._last_extra = np.zeros(0, dtype=np.int64)  # re-activated ids of the latest select()
        self._reactivated: list[int] = []
        self.activation_changes = 0

    # ----------------------------------------------------------------------- introspection

    @staticmethod
    def bucket_of_slot(slot: npt.ArrayLike) -> np.ndarray:
        """Bucket index ``floor(log2(slot + 1))`` of slot indices."""
        s = np.asarray(slot, dtype=np.int64)
        return np.asarray(np.floor(np.log2(s + 1.0)).astype(np.int64))

    def bucket(self, pair: npt.ArrayLike) -> np.ndarray:
        """Bucket index of each pair, shape like ``pair``."""
        return self.bucket_of_slot(self.where[np.asarray(pair)])

    def tau(self, pair: npt.ArrayLike) -> np.ndarray:
        """tau of each pair at its latest evaluation."""
        return np.asarray(self.last_tau[np.asarray(pair)])

    def next_due(self, pair: npt.ArrayLike) -> np.ndarray:
        """Step at which each pair is next evaluated (if it stays switched on)."""
        slot = self.where[np.asarray(pair)]
        k = self.bucket_of_slot(slot)
        offset = slot - ((1 << k) - 1)
        interval = self.interval[k]
        q = self.slots_per_bucket
        size = 1 << k
        # Slot o of bucket k is handed out at the steps n with (n q) mod size == o - o mod q.
        phase = np.where(size <= q, 0, (offset - offset % q) // np.maximum(q, 1))
        n = self.step_count + 1
        return np.asarray(n + (phase - n) % interval)

    def most_urgent(self) -> int:
        """The pair DUA believes most urgent: the occupant of bucket 0 (paper sec. 8.1.4).

        If that pair is switched off, the first active pair in slot order (-1 if none).
        """
        first = int(self.slots[0])
        if first >= 0 and self.active[first]:
            return first
        occupants = self.slots[self.slots >= 0]
        live = occupants[self.active[occupants]]
        return int(live[0]) if live.size else -1

    @property
    def evaluations_per_step(self) -> int:
        """Slots handed out per step: ``sum_k min(q, 2**k)`` (empty or inactive ones skipped)."""
        return int(self._w_slots.shape[0])

    # ----------------------------------------------------------------------- switching

    def set_active(self, pairs: npt.ArrayLike, on: bool) -> None:
        """Switch pairs off (intended contact, paper sec. 6.3) or back on.

        A pair switched back on stands in alarm (its ``last_tau`` is set to 0) until its first
        evaluation, at the next ``select()`` in addition to the regular slots; it then alarms
        against its bucket's horizon and keeps its slot. Nothing is known of its motion while it
        was off, and a predictor step, which evaluates it, can be a whole period away
        (docs/theory.md). ``activation_changes`` counts the calls that switch some pair, so
        that observers of the alarm state (``Monitor``) can tell when to re-read it.
        """
        ids = np.atleast_1d(_ids("pairs", np.atleast_1d(np.asarray(pairs, dtype=np.int64))))
        if ids.size and (ids.min() < 0 or ids.max() >= self.npairs):
            raise InvalidInputError(f"pair ids must be in [0, {self.npairs}); got {ids.tolist()}.")
        if not (self.active[ids] != on).any():
            return  # nothing switches: no stale state to mark, nothing for observers to re-read
        if on:
            new = ids[~self.active[ids]]
            self._reactivated.extend(new.tolist())
            self.last_tau[new] = 0.0
        else:
            drop = set(ids.tolist())
            self._reactivated = [i for i in self._reactivated if i not in drop]
        self.active[ids] = on
        self.activation_changes += 1

    # ----------------------------------------------------------------------- protocol

    def select(self) -> np.ndarray:
        """Pair ids to evaluate this step (one ``update`` must follow), ``(n,)`` int64."""
        if self._pending is not None:
            raise SchedulerError(
                "select() called twice without update(): evaluate the selected pairs and pass "
                "their tau to update() first."
            )
        n = self.step_count + 1
        count = _select(
            self.slots,
            self.active,
            self.nbuckets,
            self.slots_per_bucket,
            n,
            self._w_slots,
            self._w_ids,
        )
        self._pending_count = count
        self._last_count = count
        extra = np.asarray(self._reactivated, dtype=np.int64)
        self._reactivated = []
        self._last_extra = extra
        self._pending = np.concatenate([self._w_ids[:count], extra])
        return self._pending.copy()

    def update(self, ids: npt.ArrayLike, tau: npt.ArrayLike) -> np.ndarray:
        """Re-bucket the pairs selected this step with their new tau; return the alarmed ids.

        Args:
            ids: ``(n,)`` the ids ``select()`` returned, in any order.
            tau: ``(n,)`` their tau at this step's state.

        Returns:
            ``(k,)`` int64 ids of the pairs that raise an alarm.
        """
        if self._pending is None:
            raise SchedulerError("update() without select(): call select() first.")
        idx = _ids("ids", ids)
        t = _check_tau("tau", tau, idx.shape[0])
        expected = self._pending
        if idx.shape != expected.shape or not np.array_equal(np.sort(idx), np.sort(expected)):
            raise SchedulerError(
                f"update() got ids {idx.tolist()[:16]} but this step selected "
                f"{expected.tolist()[:16]}: pass exactly the ids select() returned."
            )
        n = self.step_count + 1
        count = self._pending_count
        # Reorder the caller's tau to the selection order (ids are distinct).
        tau_sel = np.empty(expected.shape[0])
        tau_sel[np.argsort(expected)] = t[np.argsort(idx)]
        self._w_tau[:count] = tau_sel[:count]
        nalarm = _reinsert(
            self.slots,
            self.where,
            self.last_tau,
            self.last_step,
            self.horizon,
            n,
            self._w_slots,
            self._w_ids,
            self._w_tau,
            count,
            self._alarms,
        )
        alarms = [self._alarms[:nalarm]]
        extra = expected[count:]
        if extra.size:
            tau_extra = tau_sel[count:]
            self.last_tau[extra] = tau_extra
            self.last_step[extra] = n
            alarms.append(extra[tau_extra < self.horizon[self.bucket(extra)]])
        self.step_count = n
        self._pending = None
        return np.concatenate(alarms)

    def step_points(
        self,
        pairs: PairSet,
        centers: npt.ArrayLike,
        velocities: npt.ArrayLike,
        halfspaces: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
    ) -> np.ndarray:
        """One fused step: select, evaluate tau from sphere states, sort, reinsert, alarm.

        Same result as ``update(ids, pairs.tau(ids, ...))`` after ``ids = select()``, in one
        compiled call.

        Args:
            pairs: The pair geometry (``len(pairs) == npairs``).
            centers: ``(nsphere, 3)`` sphere centres at this step.
            velocities: ``(nsphere, 3)`` sphere centre velocities at this step.
            halfspaces: ``(normals (nh, 3), offsets (nh,))`` if any pair is a half-space pair.

        Returns:
            ``(k,)`` int64 ids of the alarmed pairs.
        """
        if len(pairs) != self.npairs:
            raise ShapeError(f"pairs has {len(pairs)} pairs; the scheduler has {self.npairs}.")
        if self._pending is not None:
            raise SchedulerError("step_points() between select() and update(): finish the step.")
        if self._reactivated:
            ids = self.select()
            return self.update(ids, pairs.tau(ids, centers, velocities, halfspaces))
        geometry = pairs._geometry(centers, velocities, halfspaces, check_finite=False)
        n = self.step_count + 1
        count, nalarm, bad = _step_points(
            self.slots,
            self._pair_state,
            self.last_tau,
            self.horizon,
            self.active,
            self.nbuckets,
            self.slots_per_bucket,
            n,
            self._work,
            self._w_tau,
            geometry,
        )
        if bad >= 0:
            i, j = int(pairs.first[bad]), int(pairs.second[bad])
            raise NonFiniteStateError(
                f"the state of pair {bad} (spheres {i}, {j}) is not finite: centers or "
                "velocities hold NaN or inf; check that the simulation has not diverged."
            )
        self._last_count = count
        if self._last_extra.size:
            self._last_extra = self._last_extra[:0]
        self.step_count = n
        return self._alarms[:nalarm].copy()

    def step_rigid(self, pair_args: tuple, frame: tuple) -> tuple[np.ndarray, int]:
        """The fused step for spheres attached to rigid frames (used by ``Predictor``).

        Args:
            pair_args: ``(pack_pairs(pairs, plane_frame), pack_spheres(...))``, fixed for a
                model.
            frame: ``(frame_pos (nframe, 3), frame_mat (nframe, 9), twist (nbody, 6),
                twist_ref (nbody, 3), root_twist (nbody, 6), root_origin (nbody, 3))`` at this
                step (``_rigid_point``).

        Returns:
            ``(alarmed ids, bad)`` where ``bad`` is a pair whose state is not finite (the step
            was then not taken) or -1.
        """
        if self._pending is not None:
            raise SchedulerError("step_rigid() between select() and update(): finish the step.")
        if self._reactivated:
            raise SchedulerError("re-activated pairs need select()/update() for one step.")
        n = self.step_count + 1
        pairs, spheres = pair_args
        count, nalarm, bad = _step_rigid(
            self.slots,
            self._pair_state,
            self.last_tau,
            self.horizon,
            self.active,
            self.nbuckets,
            self.slots_per_bucket,
            n,
            self._work,
            self._w_tau,
            pairs,
            spheres,
            frame,
        )
        if bad >= 0:
            return self._alarms[:0].copy(), int(bad)
        self._last_count = count
        if self._last_extra.size:
            self._last_extra = self._last_extra[:0]
        self.step_count = n
        return self._alarms[:nalarm].copy(), -1

    def alarm_state(self, pair: npt.ArrayLike | None = None) -> np.ndarray:
        """Whether each pair's latest evaluation raised an alarm (alarm rule on its last tau)."""
        idx = np.arange(self.npairs) if pair is None else np.asarray(pair, dtype=np.int64)
        k = self.bucket_of_slot(self.where[idx])
        return np.asarray(self.last_tau[idx] < self.horizon[k])

    @property
    def last_selected(self) -> np.ndarray:
        """Ids evaluated by the latest step (slots in selection order, then re-activated ids)."""
        regular = self._w_ids[: self._last_count]
        return (
            np.concatenate([regular, self._last_extra]) if self._last_extra.size else regular.copy()
        )


# --------------------------------------------------------------------------- baselines


class SelectAllScheduler:
    """The select-all baselines: every active pair every step (paper sec. 8: SA(tau), SA(d)).

    Args:
        urgency0: ``(M,)`` initial urgency (tau, or clearance for ``Urgency.DISTANCE``).
        dt: Predictor period ``> 0``.
        urgency: ``Urgency.TAU`` (alarm if ``tau < (1 + latency) dt``) or ``Urgency.DISTANCE``
            (alarm if the clearance is below ``alarm_distance``).
        latency: As for ``DUAScheduler``.
        alarm_distance: Clearance below which SA(d) alarms (default 0: only overlaps).
        active: Optional ``(M,)`` bool mask.
    """

    def __init__(
        self,
        urgency0: npt.ArrayLike,
        *,
        dt: float,
        urgency: Urgency | str = Urgency.TAU,
        latency: int = 1,
        alarm_distance: float = 0.0,
        active: npt.ArrayLike | None = None,
    ) -> None:
        try:
            self.urgency = Urgency(urgency)
        except ValueError:
            raise InvalidChoiceError("urgency", urgency, [u.value for u in Urgency]) from None
        self.dt, self.latency = _check_dt(dt, latency)
        values = np.asarray(urgency0, dtype=np.float64)
        if self.urgency is Urgency.TAU:
            values = _check_tau("urgency0", values)
        elif values.ndim != 1 or np.isnan(values).any():
            raise ShapeError(
                f"urgency0 must be a (M,) array without NaN; got shape {values.shape}."
            )
        self.npairs = values.shape[0]
        self.alarm_distance = float(alarm_distance)
        self.active = (
            np.ones(self.npairs, dtype=np.bool_)
            if active is None
            else np.asarray(active, dtype=np.bool_).copy()
        )
        self.last = values.copy()
        self.step_count = 0
        self.initial_alarms = np.flatnonzero(self._alarmed(values) & self.active)
        self._pending: np.ndarray | None = None

    @property
    def threshold(self) -> float:
        """The alarm threshold on the urgency value."""
        if self.urgency is Urgency.TAU:
            return (1 + self.latency) * self.dt
        return self.alarm_distance

    def _alarmed(self, values: np.ndarray) -> np.ndarray:
        return np.asarray(values < self.threshold)

    @property
    def evaluations_per_step(self) -> int:
        """Active pairs (all evaluated every step)."""
        return int(self.active.sum())

    def set_active(self, pairs: npt.ArrayLike, on: bool) -> None:
        """Switch pairs off or on; as ``DUAScheduler.set_active``, pairs switched on stand in
        alarm until evaluated (the next step here)."""
        ids = np.asarray(pairs, dtype=np.int64)
        if on:
            # Below any threshold, for tau (alarm below a time) and distances (below a distance).
            self.last[ids[~self.active[ids]]] = -np.inf
        self.active[ids] = on

    def select(self) -> np.ndarray:
        """All active pair ids."""
        if self._pending is not None:
            raise SchedulerError("select() called twice without update().")
        self._pending = np.flatnonzero(self.active).astype(np.int64)
        return self._pending.copy()

    def update(self, ids: npt.ArrayLike, values: npt.ArrayLike) -> np.ndarray:
        """Store the new urgencies of the selected ids; return the alarmed ids."""
        if self._pending is None:
            raise SchedulerError("update() without select(): call select() first.")
        idx = _ids("ids", ids)
        vals = np.asarray(values, dtype=np.float64)
        # The ids usually come back in selection order: compare directly before sorting (O(M)).
        same = idx.shape == self._pending.shape and (
            np.array_equal(idx, self._pending) or np.array_equal(np.sort(idx), self._pending)
        )
        if vals.shape != idx.shape or not same:
            raise SchedulerError(
                "update() must get exactly the ids select() returned, with one value each."
            )
        self.last[idx] = vals
        self.step_count += 1
        self._pending = None
        return np.asarray(idx[self._alarmed(vals)])

    def most_urgent(self) -> int:
        """The active pair with the smallest urgency (-1 if none)."""
        masked = np.where(self.active, self.last, np.inf)
        return int(np.argmin(masked)) if self.active.any() else -1
