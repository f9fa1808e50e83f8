"""Measuring a plan's deviation bounds on a pilot run, for ``Predictor.set_plan``.

- :func:`deviation_profile` measures, on a pilot run, how far each body strayed from the plans
  made along it, by how many knots past the point where the plan stopped knowing the controls
  (its *origin*: 0 for a plan that knows nothing, the next waypoint for one that knows the
  command up to it), made monotone and multiplied by a safety factor;
- :func:`relative_profile` measures the same for the pose of one body relative to another, for
  the body pairs whose distance it frees from the sum of their deviations (docs/theory.md,
  Lemma 8.2d);
- :func:`plan_deviation` gives a plan of ``n`` knots its ``(n, nbody)`` deviation from such a
  profile.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any, NamedTuple

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco import _core
from dua_mujoco.build.kinematics import pack_spheres
from dua_mujoco.build.tables import check_model
from dua_mujoco.core.validate import check_int, check_number
from dua_mujoco.exceptions import InvalidInputError, ShapeError
from dua_mujoco.runtime.flightplan import finite_rows, float64_array

__all__ = [
    "PilotPlan",
    "RelativeProfile",
    "deviation_profile",
    "plan_deviation",
    "relative_profile",
]


class PilotPlan(NamedTuple):
    """A plan made along a pilot run, for :func:`deviation_profile`.

    Attributes:
        start: The row of the pilot's ``qpos`` at the plan's knot 0.
        qpos: ``(n, nq)`` the plan, row ``j`` at pilot row ``start + j``.
        origin: The knot from which the plan no longer knows the controls: the deviation at knot
            ``j`` is filed under ``max(j - origin, 0)`` knots past it (0: by the plan's age).
    """

    start: int
    qpos: np.ndarray
    origin: int = 0


# ----------------------------------------------------------------------------- deviation


def _check_points(model: mujoco.MjModel, points: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    try:
        geom, body, offset = points
    except (TypeError, ValueError):
        raise InvalidInputError(
            f"points = {points!s:.80} is invalid: pass the predictor's bound points "
            "(Predictor.bound_points: a tuple (geom, body, offset))."
        ) from None
    g = np.asarray(geom).reshape(-1)
    b = np.asarray(body).reshape(-1)
    o = np.asarray(offset, dtype=np.float64)
    if not (np.issubdtype(g.dtype, np.integer) or g.size == 0):
        raise ShapeError(f"points' geom ids have dtype {g.dtype}; expected integers.")
    g = g.astype(np.int64)
    if b.shape != g.shape or o.shape != (g.size, 3):
        raise ShapeError(
            f"points has geom {g.shape}, body {b.shape}, offset {o.shape}; expected (n,), (n,), "
            "(n, 3): pass Predictor.bound_points."
        )
    if g.size and (g.min() < 0 or g.max() >= model.ngeom):
        raise InvalidInputError(
            f"points name geom {int(g.max() if g.max() >= model.ngeom else g.min())}, not one "
            f"of the model's {model.ngeom}: pass the bound points of a predictor of this model."
        )
    body_of = np.asarray(model.geom_bodyid, dtype=np.int64)[g]
    if not np.array_equal(body_of, b.astype(np.int64)):
        raise InvalidInputError(
            "points' bodies are not their geoms' bodies in this model: pass the bound points of "
            "a predictor of this model."
        )
    return g, body_of, o


def _int(name: str, value: object, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise InvalidInputError(f"{name} = {value!r} is invalid: pass an int.")
    if not low <= int(value) <= high:
        raise InvalidInputError(f"{name} = {value} is out of range: it must lie in {low}..{high}.")
    return int(value)


def _poses(
    model: mujoco.MjModel, data: mujoco.MjData, qpos: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Every geom's ``(rows, ngeom, 3)`` positions and ``(rows, ngeom, 9)`` rotations for rows
    of ``qpos`` (``mj_kinematics`` on the scratch ``data``)."""
    pos = np.empty((qpos.shape[0], model.ngeom, 3))
    mat = np.empty((qpos.shape[0], model.ngeom, 9))
    for j, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        pos[j], mat[j] = data.geom_xpos, data.geom_xmat
    return pos, mat


def deviation_profile(
    model: mujoco.MjModel,
    qpos: npt.ArrayLike,
    plans: Iterable[PilotPlan | tuple[int, npt.ArrayLike] | tuple[int, npt.ArrayLike, int]],
    *,
    points: tuple[npt.ArrayLike, npt.ArrayLike, npt.ArrayLike],
    safety: float = 2.0,
) -> np.ndarray:
    """Each body's deviation bound by knots past a plan's origin, from a pilot run.

    For every plan and every knot ``j`` of it that the pilot reached, the distance of each bound
    point from its planned position (both from ``mj_kinematics``; measured by the runtime's own
    measure, the one its check of a plan takes at the same points), its maximum over the body's
    points, filed under ``a = max(j - origin, 0)`` knots past the plan's origin; the maximum
    over plans at each ``a``, made non-decreasing in ``a`` (a deviation seen after ``a`` knots
    may be seen later too), times ``safety``.

    The bound points are the corners of one box a body around every point the predictor covers
    (``Predictor.bound_points``): the distance of a point from its planned position is the norm
    of an affine function of its body coordinates, so its maximum over the box is at a corner,
    and the profile bounds every point of the body's geoms on the pilot's plans.

    Args:
        qpos: ``(T, nq)`` the pilot's joint positions, one row a physics step.
        plans: The plans made along it: :class:`PilotPlan` or ``(start, qpos[, origin])``, with
            row ``j`` of a plan's ``qpos`` at pilot row ``start + j``.
        points: ``(geom, body, offset)`` the bound points, ``Predictor.bound_points``.
        safety: The factor on the measured maxima (``>= 1``; 2 as ``accel="auto"``'s).

    Returns:
        ``(L, nbody)`` metres, row ``a`` the bound ``a`` knots past the origin, ``L`` one more
        than the largest ``a`` measured (knots past the pilot's end are not). Static bodies and
        bodies without bound points get 0.

    Raises:
        ShapeError: ``qpos``, a plan's ``qpos`` or ``points`` has the wrong shape.
        InvalidInputError: A non-finite position, a plan that starts outside the pilot, an
            origin outside the plan, no plan measured, or a bad ``safety`` (the message names
            the value).
    """
    check_model(model)
    geom, body, offset = _check_points(model, points)
    # The runtime's own measure (PoseDeviation: the step's check of a plan takes it at the same
    # points), on the points as sphere records.
    records = pack_spheres(geom, body, offset, model.body_rootid)
    nbody = int(model.nbody)
    cols = _columns(body, nbody, geom.size)
    return _profile(model, qpos, plans, safety, records, cols, _NONE)


def _columns(owner: np.ndarray, nowner: int, npts: int) -> np.ndarray:
    """``(nowner, width)`` each owner's points as columns of an index (``npts``: a padded
    column for owners without points)."""
    counts = np.bincount(owner, minlength=nowner)
    width = max(int(counts.max()) if counts.size else 0, 1)
    order = np.argsort(owner, kind="stable")
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    cols = np.full((nowner, width), npts, dtype=np.int64)
    rank = np.arange(npts) - first[owner[order]]
    cols[owner[order], rank] = order
    return cols


def _profile(
    model: mujoco.MjModel,
    qpos: npt.ArrayLike,
    plans: Iterable[Any],
    safety: float,
    records: np.ndarray,
    cols: np.ndarray,
    frame_of: np.ndarray,
) -> np.ndarray:
    """``(L, nowner)`` the largest deviation of each owner's points (``records``, in the frames
    of geoms ``frame_of``, none: the world; ``cols``: :func:`_columns`, 0 for none) at each age
    past the plans' origins, made non-decreasing in the age and times ``safety``."""
    out = np.zeros((0, cols.shape[0]))
    for ages, act, planned in _pilot(model, qpos, plans, safety):
        dist = _core.plan_deviation(records, *act, *planned, frame_of)  # (n, npts)
        pad = np.concatenate([dist, np.zeros((dist.shape[0], 1))], axis=1)
        if out.shape[0] <= ages[-1]:  # grown to the largest age
            out = np.concatenate([out, np.zeros((int(ages[-1]) + 1 - out.shape[0], cols.shape[0]))])
        np.maximum.at(out, ages, pad[:, cols].max(axis=2))
    return float(safety) * np.maximum.accumulate(out, axis=0)


def _pilot(
    model: mujoco.MjModel, qpos: npt.ArrayLike, plans: Iterable[Any], safety: float
) -> Iterable[tuple[np.ndarray, tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]]:
    """Per plan of a pilot (checked): its knots' ages past its origin, the pilot's geom poses
    at those knots and the plan's (``(n, ngeom, 3)`` and ``(n, ngeom, 9)`` each)."""
    actual = finite_rows("qpos", qpos, model.nq, "nq", "qpos a physics step")
    if check_number("safety", safety) < 1.0:
        raise InvalidInputError(
            f"safety = {safety!r} is invalid: pass a finite factor >= 1 (a factor below 1 "
            "would shrink the deviations measured)."
        )
    scratch = mujoco.MjData(model)
    T = actual.shape[0]
    where = _poses(model, scratch, actual)
    measured = 0
    for i, raw in enumerate(plans):
        plan = raw if isinstance(raw, PilotPlan) else PilotPlan(*raw)
        q = finite_rows(f"plans[{i}].qpos", plan.qpos, model.nq, "nq", "qpos a physics step")
        start = _int(f"plans[{i}].start", plan.start, 0, T - 1)
        origin = _int(f"plans[{i}].origin", plan.origin, 0, q.shape[0])
        n = min(q.shape[0], T - start)
        ages = np.maximum(np.arange(n) - origin, 0)
        planned = _poses(model, scratch, q[:n])
        yield ages, (where[0][start : start + n], where[1][start : start + n]), planned
        measured += 1
    if measured == 0:
        raise InvalidInputError(
            "plans is empty: pass the plans made along the pilot run (PilotPlan(start, qpos, "
            "origin))."
        )


class RelativeProfile(NamedTuple):
    """Relative deviations by knots past a plan's origin (:func:`relative_profile`).

    Attributes:
        pairs: ``(m, 2)`` body pairs ``(a, b)``, ``a < b``.
        deviation: ``(L, m)`` metres, row ``a`` the bound ``a`` knots past the origin on how far
            any point of ``b``'s box strays, in ``a``'s frame, from its planned place there.
    """

    pairs: np.ndarray
    deviation: np.ndarray

    def relative(self, knots: int, *, origin: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """``set_plan``'s ``relative`` for a plan of ``knots`` knots (as :func:`plan_deviation`
        gives its ``deviation``)."""
        return self.pairs, plan_deviation(self.deviation, knots, origin=origin)


def relative_profile(
    model: mujoco.MjModel,
    qpos: npt.ArrayLike,
    plans: Iterable[PilotPlan | tuple[int, npt.ArrayLike] | tuple[int, npt.ArrayLike, int]],
    *,
    points: tuple[npt.ArrayLike, npt.ArrayLike, npt.ArrayLike],
    geom_pairs: tuple[npt.ArrayLike, npt.ArrayLike],
    profile: npt.ArrayLike,
    safety: float = 2.0,
) -> RelativeProfile:
    """Relative deviations of the body pairs whose geoms may meet, from a pilot run.

    Two links that move together carry the whole arm's drift in each of their own deviations
    ``D_a + D_b``, though their distance hardly changes. Distance is invariant under a rigid
    motion, so a pair's distance is also its distance in ``a``'s frame, where ``b`` stands at
    its pose relative to ``a``; against the plan's relative pose, every point of ``b`` moves by
    at most the relative deviation ``D_ab`` (docs/theory.md, Lemma 8.2d). For each body pair
    ``(a, b)`` of two moving bodies with an active geom pair between them, this measures
    ``D_ab`` as :func:`deviation_profile` measures ``D_b`` (the same corner measure at ``b``'s
    bound points, in the frame of ``a``'s, by age, made monotone, times ``safety``). The table
    stays as small as the pairs it frees (each costs its check at every step and at each
    replan): a pair is kept when, at a tenth of the pilot's rows or more (every fifth row,
    MuJoCo's distance of a geom pair between them), its distance lies between ``D_ab`` and
    ``D_a + D_b`` at the largest age measured: nearer than the sum, the sum stands it; farther
    than ``D_ab``, the relative bound does not.

    Args:
        qpos: ``(T, nq)`` the pilot's joint positions.
        plans: The plans made along it, as :func:`deviation_profile` takes them.
        points: ``Predictor.bound_points``.
        geom_pairs: ``(geom1, geom2)`` the predictor's active geom pairs
            (``Predictor.geom_pairs``).
        profile: ``(L, nbody)`` :func:`deviation_profile` of the same pilot and plans.
        safety: The factor on the measured maxima (``>= 1``), as ``profile``'s.

    Returns:
        The pairs kept and their ``(L, m)`` deviations: ``set_plan(...,
        relative=rel.relative(knots))``.

    Raises:
        ShapeError: A shape does not fit the model, or ``profile`` another pilot's ages.
        InvalidInputError: As :func:`deviation_profile`.
    """
    check_model(model)
    geom, body, offset = _check_points(model, points)
    sums = np.asarray(profile, dtype=np.float64)
    if sums.ndim != 2 or sums.shape[1] != model.nbody:
        raise ShapeError(
            f"profile has shape {sums.shape}; expected (L, nbody) = (L, {model.nbody}): "
            "deviation_profile's of the same pilot."
        )
    pilot = finite_rows("qpos", qpos, model.nq, "nq", "qpos a physics step")
    candidates, near, owner_gp = _body_pairs(
        model, geom_pairs, np.unique(body), pilot[::_NEAR_STRIDE], sums[-1]
    )
    # Each body's frame (the geom its points are on) and its points.
    frame = np.full(model.nbody, -1, dtype=np.int64)
    frame[body] = geom
    a, b = candidates[:, 0], candidates[:, 1]
    # b's points once per pair with b second, each measured in the frame of a's geom (its
    # deviation in a's frame: RelativePose, plan.h), one column a pair.
    mine = [np.flatnonzero(body == bb) for bb in b.tolist()]
    point = np.concatenate([*mine, np.zeros(0, np.int64)])
    owner = np.repeat(np.arange(b.size), [m.size for m in mine])
    records = pack_spheres(geom[point], body[point], offset[point], model.body_rootid)
    cols = _columns(owner, b.size, point.size)
    rel = _profile(model, qpos, plans, safety, records, cols, frame[a][owner])
    if rel.shape[0] > sums.shape[0]:
        raise ShapeError(
            f"profile has {sums.shape[0]} ages, the pilot's plans {rel.shape[0]}: pass "
            "deviation_profile of the same pilot and plans."
        )
    # Kept: the pairs the relative bound frees at _FREED of the pilot's rows or more, at the
    # largest age (a geom pair between them farther than D_ab, nearer than D_a + D_b).
    last = rel.shape[0] - 1
    total = sums[last, a] + sums[last, b]
    frees = (near > rel[last, owner_gp]) & (near < total[owner_gp])  # (rows, geom pairs)
    freed = np.zeros((near.shape[0], candidates.shape[0]), dtype=bool)
    np.logical_or.at(freed.T, owner_gp, frees.T)
    kept = freed.mean(axis=0) >= _FREED
    return RelativeProfile(candidates[kept], np.ascontiguousarray(rel[:, kept]))


_NONE = np.zeros(0, np.int64)
"""``plan_deviation``'s ``frame_of`` for deviations in the world frame."""
_NEAR_STRIDE = 5
"""Pilot rows between two of those at which relative_profile asks whether a pair comes near."""
_FREED = 0.1
"""The share of those rows at which the relative bound must free a pair for relative_profile to
keep it (the pairs that stand most of the time: each pair kept costs its check at every step
and its nesting at each replan, about 2 mj_step a plan each on an arm)."""


def _body_pairs(
    model: mujoco.MjModel,
    geom_pairs: tuple[npt.ArrayLike, npt.ArrayLike],
    boxed: np.ndarray,
    rows: np.ndarray,
    largest: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The distinct body pairs ``(a, b)``, ``a < b`` (``(m, 2)``), of the geom pairs whose two
    bodies move outside mocap trees and have bound points (``boxed``) and whose distance at
    some of the pilot's ``rows`` (MuJoCo's) is within ``largest[a] + largest[b]`` (elsewhere
    the sum never stands the pair); those geom pairs' distances at the rows (``(rows, k)``) and
    the body pair each is of (``(k,)``)."""
    g1, g2 = (np.asarray(g, dtype=np.int64).reshape(-1) for g in geom_pairs)
    if g1.shape != g2.shape:
        raise ShapeError(f"geom_pairs has {g1.shape} and {g2.shape} geoms; expected the same.")
    gb = np.asarray(model.geom_bodyid, dtype=np.int64)
    b1, b2 = gb[g1], gb[g2]
    moving = (np.asarray(model.body_weldid) != 0) & (
        np.asarray(model.body_mocapid)[np.asarray(model.body_rootid)] < 0
    )
    ok = np.zeros(model.nbody, dtype=bool)
    ok[boxed] = True
    ok &= moving
    keep = np.flatnonzero(ok[b1] & ok[b2] & (b1 != b2))
    reach = largest[b1[keep]] + largest[b2[keep]]
    dist = np.empty((rows.shape[0], keep.size))
    d = mujoco.MjData(model)
    for r, q in enumerate(rows):  # offline, on the pilot: a few hundred rows
        d.qpos[:] = q
        mujoco.mj_kinematics(model, d)
        for c, i in enumerate(keep.tolist()):
            dist[r, c] = mujoco.mj_geomDistance(
                model, d, int(g1[i]), int(g2[i]), reach[c] + 1e-3, None
            )
    near = (dist < reach).any(axis=0)
    keep, dist = keep[near], dist[:, near]
    both = np.stack([np.minimum(b1, b2), np.maximum(b1, b2)], axis=1)[keep]
    pairs, owner = np.unique(both, axis=0, return_inverse=True)
    return pairs.reshape(-1, 2), dist, owner.reshape(-1)


def plan_deviation(profile: npt.ArrayLike, knots: int, *, origin: int = 0) -> np.ndarray:
    """The deviation of a plan of ``knots`` knots from a :func:`deviation_profile`.

    Args:
        profile: ``(L, nbody)`` the profile.
        knots: The plan's knots (rows of its ``qpos``).
        origin: The knot from which the plan no longer knows the controls (as the profile's
            plans were filed: 0 by age, the next waypoint's knot for a plan that knows the
            command up to it).

    Returns:
        ``(knots, nbody)`` metres, row ``j`` the profile's row ``max(j - origin, 0)``: the
        ``deviation`` of ``Predictor.set_plan``.

    Raises:
        ShapeError: ``profile`` is not 2-D.
        InvalidInputError: The plan needs more rows of the profile than it has (measure longer
            plans in the pilot), or a bad ``knots`` or ``origin``.
    """
    prof = float64_array(profile)
    if prof.ndim != 2 or prof.shape[0] < 1:
        raise ShapeError(
            f"profile has shape {prof.shape}; expected (L, nbody) with L >= 1, as "
            "deviation_profile returns."
        )
    if type(knots) is not int or knots < 1:  # a plain int >= 1 needs no more (a replan's)
        knots = check_int("knots", knots, 1, " (the plan's rows)")
    o = 0 if type(origin) is int and origin == 0 else _int("origin", origin, 0, knots)
    need = max(knots - 1 - o, 0)
    if need >= prof.shape[0]:
        raise InvalidInputError(
            f"the plan reaches {need} knots past its origin, the profile only "
            f"{prof.shape[0] - 1}: measure longer plans in the pilot (or shorten the plan)."
        )
    return prof[:knots].copy() if o == 0 else prof[np.maximum(np.arange(knots) - o, 0)]
