"""Pair geometry: which spheres, half-spaces or static shapes form each pair, and its bounds.

``PairSet`` holds the pairs with their kind (``PairKind``: sphere-sphere, sphere-half-space,
sphere-static-shape), contact distance ``eps``, acceleration bound, velocity uncertainty and
speed bound, packed into one record per pair (named ``PAIR_*`` columns, ``pack_pairs``, the
layout of the native core: ``dua_mujoco._core.LAYOUT``); ``tau`` evaluates pairs from sphere
states with the native core's evaluation, the one the schedules' fused step on free spheres
runs and the MuJoCo layer's step runs on rigid bodies.
"""

from __future__ import annotations

import enum

import numpy as np
import numpy.typing as npt

import dua_mujoco._core as _core
from dua_mujoco.core.shapes import SHAPE_NCOL, shape_table
from dua_mujoco.core.validate import as_ids, as_vectors, per_pair, per_sphere
from dua_mujoco.exceptions import (
    InvalidBoundError,
    InvalidInputError,
    NonFiniteStateError,
    ShapeError,
)

__all__ = [
    "KIND_HALFSPACE",
    "KIND_SHAPE",
    "KIND_SPHERE",
    "PAIR_ACCEL",
    "PAIR_DELTA",
    "PAIR_EPS",
    "PAIR_FIRST",
    "PAIR_KIND",
    "PAIR_NCOL",
    "PAIR_OTHER",
    "PAIR_SECOND",
    "PAIR_SPEED",
    "PairKind",
    "PairSet",
    "pack_pairs",
]

_LAYOUT = _core.LAYOUT


class PairKind(enum.IntEnum):
    """What the second member of a pair is; the first is always a sphere."""

    SPHERE = _LAYOUT["PairKind.SPHERE"]
    """Another sphere: ``second`` is a sphere id."""
    HALFSPACE = _LAYOUT["PairKind.HALFSPACE"]
    """A half-space (a plane): ``second`` is a half-space id."""
    SHAPE = _LAYOUT["PairKind.SHAPE"]
    """A static convex shape (``dua_mujoco.core.shapes``): ``second`` is a shape record row."""


# Plain ints, for comparisons with arrays.
KIND_SPHERE = int(PairKind.SPHERE)
KIND_HALFSPACE = int(PairKind.HALFSPACE)
KIND_SHAPE = int(PairKind.SHAPE)

# Columns of the packed per-pair records (one 64-byte row, a cache line, per pair: the native
# step reads cold tables after mj_step and is memory-bound).
PAIR_FIRST: int = _LAYOUT["PAIR_FIRST"]
PAIR_SECOND: int = _LAYOUT["PAIR_SECOND"]
PAIR_KIND: int = _LAYOUT["PAIR_KIND"]
PAIR_EPS: int = _LAYOUT["PAIR_EPS"]
PAIR_ACCEL: int = _LAYOUT["PAIR_ACCEL"]
PAIR_DELTA: int = _LAYOUT["PAIR_DELTA"]
PAIR_SPEED: int = _LAYOUT["PAIR_SPEED"]
PAIR_OTHER: int = _LAYOUT["PAIR_OTHER"]
PAIR_NCOL: int = _LAYOUT["PAIR_NCOL"]


def pack_pairs(pairs: PairSet, plane_frame: npt.ArrayLike | None = None) -> np.ndarray:
    """``(M, 8)`` float64 records ``[first, second, kind, eps, accel, delta, speed, other]``.

    ``kind`` is the ``PairKind`` code; ``other`` is the frame (geom) of a half-space pair's plane
    and the shape record row of a shape pair (0 for sphere pairs).

    Args:
        pairs: The pair set.
        plane_frame: ``(nplane,)`` frame (geom) of each half-space (``other`` of half-space pairs
            is 0 if not given).

    Ids are stored as floats: exact below 2**53.
    """
    rec = pairs.records.copy()
    if plane_frame is not None:
        frame = np.asarray(plane_frame, dtype=np.int64)
        h = pairs.halfspace
        rec[h, PAIR_OTHER] = frame[pairs.second[h]]
    return rec


def _read_only(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


# Placeholders for pair sets without half-spaces or shapes (never read: no pair indexes them).
_NO_PLANES = _read_only(np.zeros((1, 4)))
_NO_SHAPES = _read_only(np.zeros((1, SHAPE_NCOL)))

# Bounds: views of the records' columns, changed in place (pairs.eps[:] = ...).
_BOUNDS = frozenset(("eps", "accel", "vel_uncertainty", "speed"))
# Indices and what follows from them: read-only (the records and the index checks hold them).
_INDICES = frozenset(("first", "second", "kind", "halfspace", "shape", "records"))


class PairSet:
    """Pairs of a sphere and a sphere, a half-space or a static shape, with their bounds.

    Args:
        first: ``(M,)`` sphere index of each pair.
        second: ``(M,)`` sphere index, half-space index or shape record row, by ``kind``.
        eps: ``(M,)`` or scalar contact distance (radii plus margin; for a half-space or shape
            pair the sphere radius plus margin).
        accel: ``(M,)`` or scalar bound on the relative acceleration norm (``A_i + A_j``).
        halfspace: ``(M,)`` bool, pairs whose ``second`` is a half-space (default none). Kept
            for pair sets without shapes; give ``kind`` instead to have both.
        kind: ``(M,)`` ``PairKind`` codes (default: from ``halfspace``, else all spheres).
        vel_uncertainty: ``(M,)`` or scalar velocity uncertainty ``delta`` (default 0).
        speed: ``(M,)`` or scalar relative speed bound (default ``inf``, none); for half-space
            and shape pairs the sphere's own.
        shapes: ``(nshape, 16)`` static shape records (``dua_mujoco.core.shapes.pack_shapes``)
            that shape pairs index, or None; held as ``PairSet.shapes`` (static shapes do not
            move, so ``tau`` and ``inputs`` use them unless given others).

    Attributes:
        records: ``(M, 8)`` float64 records (``PAIR_*`` columns, ``other`` 0 for half-space
            pairs): what the native core evaluates. ``eps``, ``accel``, ``vel_uncertainty`` and
            ``speed`` are views of its columns (change them in place); ``first``, ``second``
            and ``kind`` are read-only copies of the others.
        kind: ``(M,)`` int8 ``PairKind`` codes.
        halfspace: ``(M,)`` bool, ``kind == HALFSPACE``.
        shape: ``(M,)`` bool, ``kind == SHAPE``.
    """

    def __init__(
        self,
        first: npt.ArrayLike,
        second: npt.ArrayLike,
        eps: npt.ArrayLike,
        accel: npt.ArrayLike,
        *,
        halfspace: npt.ArrayLike | None = None,
        kind: npt.ArrayLike | None = None,
        vel_uncertainty: npt.ArrayLike = 0.0,
        speed: npt.ArrayLike = np.inf,
        shapes: npt.ArrayLike | None = None,
    ) -> None:
        first_ = as_ids("first", first).copy()
        m = first_.shape[0]
        second_ = as_ids("second", second, m).copy()
        kind_ = _as_kind(halfspace, kind, m).copy()
        rec = np.zeros((m, PAIR_NCOL))
        rec[:, PAIR_FIRST] = first_
        rec[:, PAIR_SECOND] = second_
        rec[:, PAIR_KIND] = kind_
        rec[:, PAIR_EPS] = per_pair("eps", eps, m)
        rec[:, PAIR_ACCEL] = per_pair("accel", accel, m)
        rec[:, PAIR_DELTA] = per_pair("vel_uncertainty", vel_uncertainty, m)
        rec[:, PAIR_SPEED] = per_pair("speed", speed, m, allow_inf=True)
        shape = kind_ == KIND_SHAPE
        rec[shape, PAIR_OTHER] = second_[shape]
        self.first = _read_only(first_)
        self.second = _read_only(second_)
        self.kind = _read_only(kind_)
        self.halfspace = _read_only(kind_ == KIND_HALFSPACE)
        self.shape = _read_only(shape)
        self.records = rec
        self.eps = rec[:, PAIR_EPS]
        self.accel = rec[:, PAIR_ACCEL]
        self.vel_uncertainty = rec[:, PAIR_DELTA]
        self.speed = rec[:, PAIR_SPEED]
        if (self.speed == 0.0).any():
            raise InvalidBoundError(
                "speed bounds must be positive: a zero speed bound is invalid; use inf for none."
            )
        if (self.first < 0).any() or (self.second < 0).any():
            raise InvalidInputError("sphere, half-space and shape indices must be >= 0.")
        # Checked once here so that the per-step state check is O(1).
        spheres = np.concatenate([self.first, self.second[self.kind == KIND_SPHERE]])
        self.max_sphere = int(spheres.max(initial=-1))
        self.max_halfspace = int(self.second[self.halfspace].max(initial=-1))
        self.max_shape = int(self.second[self.shape].max(initial=-1))
        self.has_halfspace = bool(self.halfspace.any())
        self.has_shape = bool(self.shape.any())
        self.shapes: np.ndarray | None = None if shapes is None else shape_table(shapes)

    def __setattr__(self, name: str, value: object) -> None:
        # The arrays are fixed: the records hold them, so a new array would be ignored.
        if name in _BOUNDS and name in self.__dict__:
            raise InvalidInputError(
                f"PairSet.{name} is fixed at construction: change its values in place "
                f"(pairs.{name}[:] = ...) or build a new PairSet."
            )
        if name in _INDICES and name in self.__dict__:
            raise InvalidInputError(
                f"PairSet.{name} is fixed at construction (the records and the index checks "
                "hold it): build a new PairSet."
            )
        if name == "shapes" and value is not None:
            value = shape_table(value)  # type: ignore[arg-type]
        super().__setattr__(name, value)

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
        a = per_sphere("accel", accel, n, allow_inf=True)
        d = per_sphere("vel_uncertainty", vel_uncertainty, n, allow_inf=True)
        v = np.full(n, np.inf) if speed is None else per_sphere("speed", speed, n, allow_inf=True)
        s = np.inf if speed is None else v[i] + v[j]
        return cls(i, j, r[i] + r[j] + margin, a[i] + a[j], vel_uncertainty=d[i] + d[j], speed=s)

    def tau(
        self,
        ids: npt.ArrayLike,
        centers: npt.ArrayLike,
        velocities: npt.ArrayLike,
        halfspaces: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
        *,
        shapes: npt.ArrayLike | None = None,
    ) -> np.ndarray:
        """tau of the pairs ``ids`` from sphere states (the vectorised front of the fused step).

        Args:
            ids: ``(n,)`` pair ids.
            centers: ``(nsphere, 3)`` sphere centres.
            velocities: ``(nsphere, 3)`` sphere centre velocities.
            halfspaces: ``(normals (nh, 3), offsets (nh,))``: half-space ``j`` is
                ``{p : normals[j] . p <= offsets[j]}`` seen from outside, i.e. a sphere centre ``c``
                has clearance ``normals[j] . c - offsets[j] - eps``.
            shapes: ``(nshape, 16)`` static shape records (``dua_mujoco.core.shapes.pack_shapes``)
                if any pair is a shape pair; default ``PairSet.shapes``.

        Returns:
            ``(n,)`` tau of each pair.
        """
        idx = as_ids("ids", ids)  # each in range: the native call names one that is not
        c, v, planes, recs = self.inputs(centers, velocities, halfspaces, shapes=shapes)
        tau, bad = _core.tau_pairs(self.records, idx, c, v, planes, recs)
        if bad >= 0:  # pragma: no cover - inputs() checked the state finite
            raise NonFiniteStateError(f"the state of pair {int(idx[bad])} is not finite.")
        return np.asarray(tau)

    def arrays(self) -> tuple[np.ndarray, ...]:
        """``(first, second, kind, eps, accel, vel_uncertainty, speed)``, fixed at construction."""
        return (
            self.first,
            self.second,
            self.kind,
            self.eps,
            self.accel,
            self.vel_uncertainty,
            self.speed,
        )

    def inputs(
        self,
        centers: npt.ArrayLike,
        velocities: npt.ArrayLike,
        halfspaces: tuple[npt.ArrayLike, npt.ArrayLike] | None,
        *,
        shapes: npt.ArrayLike | None = None,
        check_finite: bool = True,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(centers, velocities, planes, shapes)`` validated against the pairs: ``planes``
        ``(nh, 4)`` rows ``[normal, offset]``, ``shapes`` ``(nshape, 16)`` records (this set's
        own unless others are given); placeholders where the pairs have none."""
        c = as_vectors("centers", centers, check_finite=check_finite)
        v = as_vectors("velocities", velocities, c.shape[0], check_finite=check_finite)
        planes = _NO_PLANES
        if halfspaces is None:
            if self.has_halfspace:
                raise InvalidInputError("these pairs include half-spaces: pass halfspaces=(n, o).")
        else:
            nrm = as_vectors("halfspace normals", halfspaces[0])
            off = np.asarray(halfspaces[1], dtype=np.float64).reshape(-1)
            if off.shape[0] != nrm.shape[0]:
                raise ShapeError(
                    f"halfspace offsets have {off.shape[0]} rows, normals {nrm.shape[0]}."
                )
            planes = np.ascontiguousarray(np.column_stack([nrm, off]))
        recs = _NO_SHAPES
        if shapes is None and self.shapes is not None:
            recs = self.shapes
        elif shapes is None:
            if self.has_shape:
                raise InvalidInputError(
                    "these pairs include static shapes: pass shapes=records (pack_shapes)."
                )
        else:
            recs = shape_table(shapes)
        if self.max_sphere >= c.shape[0]:
            raise ShapeError(
                f"pairs reference sphere {self.max_sphere} but centers has {c.shape[0]} rows."
            )
        if self.has_halfspace and self.max_halfspace >= planes.shape[0]:
            raise ShapeError(
                f"pairs reference half-space {self.max_halfspace} but {planes.shape[0]} were given."
            )
        if self.has_shape and self.max_shape >= recs.shape[0]:
            raise ShapeError(
                f"pairs reference shape {self.max_shape} but shapes has {recs.shape[0]} rows."
            )
        return c, v, planes, recs


def _as_kind(halfspace: npt.ArrayLike | None, kind: npt.ArrayLike | None, m: int) -> np.ndarray:
    """``(m,)`` int8 ``PairKind`` codes from either ``kind`` or the ``halfspace`` mask."""
    if kind is not None and halfspace is not None:
        raise InvalidInputError(
            "pass either kind= (PairKind codes) or halfspace= (a mask), not both: kind holds the "
            "half-spaces too (PairKind.HALFSPACE)."
        )
    if kind is None:
        if halfspace is None:
            return np.zeros(m, dtype=np.int8)
        h = np.broadcast_to(np.asarray(halfspace, dtype=np.bool_), (m,))
        return np.where(h, KIND_HALFSPACE, KIND_SPHERE).astype(np.int8)
    k = np.asarray(kind)
    if k.size and not np.issubdtype(k.dtype, np.integer):
        raise InvalidInputError(f"kind must hold integer PairKind codes; got dtype {k.dtype}.")
    k = np.broadcast_to(k, (m,))
    valid = [int(x) for x in PairKind]
    bad = ~np.isin(k, valid)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InvalidInputError(
            f"kind[{i}] = {int(k[i])} is not a PairKind code; valid: "
            + ", ".join(f"{x.name}={int(x)}" for x in PairKind)
            + "."
        )
    return np.ascontiguousarray(k, dtype=np.int8)
