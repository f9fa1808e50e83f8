"""Two-level urgency: bounding spheres first, the geoms' finer coverings only where urgent.

Each pair of the bounding covering (one sphere per geom) is evaluated as usual. Only when its
tau is below ``refine_below`` seconds is it refined: the minimum of tau over the sub-pairs of the
two geoms' finer (``multi``) coverings, each with ``eps = r_a + r_b + d`` (``d`` the geom pair's
contact distance; ``r_a + d`` against a half-space or a static shape), is a lower bound on the
time to contact of the two geoms too, and the pair's tau is the larger of the two bounds. Fine
coverings thus cost work only where it matters. Proof in docs/static-shapes.md, section 12.

The fine states are read through the same ``rigid_point`` as the bounding spheres, so the
motion bounds must hold for the fine sphere centres as well: ``Predictor(accel="auto")`` runs its
pilot over both coverings.
"""

from __future__ import annotations

import dataclasses
import math

import numba as nb
import numpy as np

from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.mj.covering import Covering
from dua_mujoco.mj.filter import GeomPairs, SpherePairs
from dua_mujoco.mj.kinematics import (
    REFINE_A0,
    REFINE_A1,
    REFINE_B0,
    REFINE_B1,
    REFINE_DIST,
    REFINE_NCOL,
    fine_buffer,
    fine_tau,
    pack_spheres,
)

__all__ = ["Refinement", "build_refinement", "no_refinement", "refine_taus"]


@dataclasses.dataclass(frozen=True)
class Refinement:
    """The fine coverings and per-pair records the two-level urgency reads.

    Attributes:
        fine: The finer covering (``multi``) of the same model.
        spheres: ``(nfine, 8)`` ``pack_spheres`` records of ``fine``.
        records: ``(npair, 8)`` per bounding pair ``[a0, a1, b0, b1, d, 0, 0, 0]``.
        refine_below: Refine pairs whose bounding tau is below this (seconds).
        max_fine: Largest number of fine spheres of one geom.
    """

    fine: Covering
    spheres: np.ndarray
    records: np.ndarray
    refine_below: float
    max_fine: int

    @property
    def args(self) -> tuple:
        """The ``refine`` tuple of ``step_rigid_kernel`` and :func:`refine_taus`."""
        radius = np.ascontiguousarray(self.fine.sphere_radius, dtype=np.float64)
        return (self.spheres, radius, self.records, float(self.refine_below), self.max_fine)


def no_refinement() -> tuple:
    """The ``refine`` tuple that never refines (one placeholder row each)."""
    return (np.zeros((1, 8)), np.zeros(1), np.zeros((1, REFINE_NCOL)), -1.0, 1)


def build_refinement(
    model_root: np.ndarray,
    coarse: Covering,
    fine: Covering,
    sphere_pairs: SpherePairs,
    geom_pairs: GeomPairs,
    refine_below: float,
) -> Refinement:
    """Per-pair refinement records of ``sphere_pairs`` (over the bounding ``coarse`` covering).

    Args:
        model_root: ``(nbody,)`` ``model.body_rootid``.
        coarse: The bounding covering the pairs were built from (one sphere per covered geom).
        fine: A finer covering of the same model with the same static shapes and planes.
        sphere_pairs: The pairs of ``coarse``.
        geom_pairs: The active geom pairs.
        refine_below: Refine pairs whose tau is below this many seconds (``> 0``).

    Raises:
        InvalidInputError: ``coarse`` is not one sphere per geom, or the two coverings differ
            in their shapes or planes, or ``refine_below`` is not positive.
    """
    if not (isinstance(refine_below, float | int) and math.isfinite(refine_below)) or not (
        refine_below > 0.0
    ):
        raise InvalidInputError(
            f"refine_below = {refine_below!r} is invalid: pass a positive number of seconds."
        )
    counts = np.diff(coarse.geom_sphere_start)
    if counts.max(initial=0) > 1:
        raise InvalidInputError(
            "refinement refines the bounding covering (one sphere per geom): build the "
            'Predictor with covering="bounding" to use refine=.'
        )
    if not (
        np.array_equal(coarse.shape_geom, fine.shape_geom)
        and np.array_equal(coarse.plane_geom, fine.plane_geom)
    ):
        raise InvalidInputError(
            "the fine covering holds other static shapes or planes than the bounding one: build "
            "both with the same static= and hfield= options."
        )
    start = np.asarray(fine.geom_sphere_start, dtype=np.int64)
    first = np.asarray(sphere_pairs.first, dtype=np.int64)
    g1 = coarse.sphere_geom[first]
    two = ~(np.asarray(sphere_pairs.is_halfspace) | np.asarray(sphere_pairs.is_shape))
    second = np.asarray(sphere_pairs.second, dtype=np.int64)
    g2 = np.where(two, coarse.sphere_geom[np.where(two, second, 0)], -1)
    rec = np.zeros((first.shape[0], REFINE_NCOL))
    rec[:, REFINE_A0] = start[g1]
    rec[:, REFINE_A1] = start[g1 + 1]
    rec[two, REFINE_B0] = start[g2[two]]
    rec[two, REFINE_B1] = start[g2[two] + 1]
    rec[:, REFINE_DIST] = np.asarray(geom_pairs.contact_distance)[sphere_pairs.geom_pair]
    spheres = pack_spheres(fine.sphere_geom, fine.sphere_body, fine.sphere_offset, model_root)
    return Refinement(
        fine=fine,
        spheres=spheres,
        records=rec,
        refine_below=float(refine_below),
        max_fine=max(int(np.diff(start).max(initial=1)), 1),
    )


@nb.njit(cache=True)
def _refine_all(tau, ids, pairs, frame, shapes, refine):  # pragma: no cover - jitted
    buf = fine_buffer(refine)
    below = refine[3]
    for k in range(ids.shape[0]):
        p = ids[k]
        if tau[k] < below:
            tau[k] = fine_tau(p, pairs[p], tau[k], frame, shapes, refine, buf)


def refine_taus(
    tau: np.ndarray,
    ids: np.ndarray,
    pairs: np.ndarray,
    frame: tuple,
    shapes: np.ndarray,
    refine: tuple,
) -> np.ndarray:
    """Refine the bounding taus ``tau`` of pairs ``ids`` in place (the reset's vectorised path).

    Args:
        tau: ``(n,)`` bounding tau of each pair in ``ids`` (overwritten).
        ids: ``(n,)`` pair ids.
        pairs: ``pack_pairs`` records.
        frame: ``mjdata_frame`` tuple.
        shapes: Static shape records.
        refine: :attr:`Refinement.args`.

    Returns:
        ``tau``.
    """
    _refine_all(tau, np.ascontiguousarray(ids, dtype=np.int64), pairs, frame, shapes, refine)
    return tau
