"""Pair geometry: which spheres (or half-spaces) form each pair, and the pair's bounds.

``PairSet`` holds the pairs of sphere ids with their contact distance ``eps``, acceleration
bound, velocity uncertainty and speed bound; ``tau`` evaluates pairs from sphere states, and
``pair_tau`` is the compiled evaluation the schedules' fused step on free spheres calls.
``pack_pairs`` packs the same data into one row per pair (named ``PAIR_*`` columns) for the
MuJoCo layer's fused step, which reads cold tables after ``mj_step``.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import numpy.typing as npt

from dua_mujoco.core.urgency import PARALLEL_MIN, tau_halfspace, tau_speed
from dua_mujoco.core.validate import as_ids, as_vectors, per_pair
from dua_mujoco.exceptions import InvalidBoundError, InvalidInputError, ShapeError

__all__ = [
    "PAIR_ACCEL",
    "PAIR_DELTA",
    "PAIR_EPS",
    "PAIR_FIRST",
    "PAIR_HALFSPACE",
    "PAIR_PLANE_FRAME",
    "PAIR_SECOND",
    "PAIR_SPEED",
    "PairSet",
    "pack_pairs",
    "pair_tau",
]


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
def pair_tau(p, geometry):  # pragma: no cover - jitted
    """tau of pair ``p``; ``geometry`` is ``PairSet.geometry``'s tuple."""
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
    kernel = _tau_pairs_parallel if ids.shape[0] >= PARALLEL_MIN else _tau_pairs_serial
    return kernel(ids, geometry)


# The serial and threaded kernels differ only in range/prange: numba has no switch for it.
@nb.njit(cache=True)
def _tau_pairs_serial(ids, geometry):  # pragma: no cover - jitted
    out = np.empty(ids.shape[0])
    for k in range(ids.shape[0]):
        out[k] = pair_tau(ids[k], geometry)
    return out


@nb.njit(cache=True, parallel=True)
def _tau_pairs_parallel(ids, geometry):  # pragma: no cover - jitted
    out = np.empty(ids.shape[0])
    for k in nb.prange(ids.shape[0]):
        out[k] = pair_tau(ids[k], geometry)
    return out


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
        self.first = as_ids("first", first)
        m = self.first.shape[0]
        self.second = as_ids("second", second, m)
        self.halfspace = (
            np.zeros(m, dtype=np.bool_)
            if halfspace is None
            else np.ascontiguousarray(np.broadcast_to(np.asarray(halfspace, dtype=np.bool_), (m,)))
        )
        self.eps = np.broadcast_to(per_pair("eps", eps, m), (m,)).copy()
        self.accel = np.broadcast_to(per_pair("accel", accel, m), (m,)).copy()
        self.vel_uncertainty = np.broadcast_to(
            per_pair("vel_uncertainty", vel_uncertainty, m), (m,)
        ).copy()
        self.speed = np.broadcast_to(per_pair("speed", speed, m, allow_inf=True), (m,)).copy()
        if (self.speed == 0.0).any():
            raise InvalidBoundError(
                "speed bounds must be positive: a zero speed bound is invalid; use inf for none."
            )
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
            return np.broadcast_to(per_pair(name, value, n, allow_inf=True), (n,))

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
        idx = as_ids("ids", ids)
        if idx.size and (idx.min() < 0 or idx.max() >= len(self)):
            raise InvalidInputError(f"pair ids must be in [0, {len(self)}); got {idx.tolist()}.")
        return np.asarray(_tau_pairs(idx, self.geometry(centers, velocities, halfspaces)))

    def geometry(
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
        c = as_vectors("centers", centers, check_finite=check_finite)
        v = as_vectors("velocities", velocities, c.shape[0], check_finite=check_finite)
        if halfspaces is None:
            nrm, off = _NO_NORMALS, _NO_OFFSETS
            if self.has_halfspace:
                raise InvalidInputError("these pairs include half-spaces: pass halfspaces=(n, o).")
        else:
            nrm = as_vectors("halfspace normals", halfspaces[0])
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
        idx = as_ids("ids", ids)
        c = as_vectors("centers", centers)
        return np.asarray(
            np.linalg.norm(c[self.second[idx]] - c[self.first[idx]], axis=1) - self.eps[idx]
        )
