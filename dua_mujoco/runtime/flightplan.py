"""Flight plans as the native runtime reads them: checked joint positions and deviation bounds.

A plan is the motion the caller expects over the coming physics steps (an MPC's or a planner's
trajectory, or a rollout of known controls: :mod:`dua_mujoco.runtime.plans` makes them) and a bound
on how far every point of each body may stray from where the plan puts it. While it holds, a
pair's verdict follows the plan instead of the motion bounds (docs/theory.md, section 8).
"""

from __future__ import annotations

import fnmatch
from collections.abc import Callable, Iterable
from typing import Any, NamedTuple

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco.build.filter import body_id
from dua_mujoco.exceptions import InvalidInputError, ShapeError

__all__ = [
    "PlanArrays",
    "PlanFollowing",
    "Relative",
    "body_mask",
    "finite_rows",
    "plan_arrays",
    "relative_arrays",
]


_F64 = np.dtype(np.float64)


# The empty arrays of a plan without mocap poses, held bodies or relative pairs: one of each,
# shared by every call (no entry to write; writeable, as numpy's DLPack export, which nanobind
# tries first, refuses read-only arrays and the fallback costs an exception each).
_NO_MOCAP = np.zeros(0)
_NO_BODIES = np.zeros(0, np.uint8)
_NO_PAIRS = np.zeros((0, 2), np.int64)


def float64_array(value: npt.ArrayLike) -> np.ndarray:
    """``value`` as a float64 array: itself when it is one (no numpy call), else converted."""
    if type(value) is np.ndarray and value.dtype is _F64:
        return value
    return np.asarray(value, dtype=np.float64)


def finite_rows(
    name: str, value: npt.ArrayLike, ncol: int, cols: str, rows: str, *, finite: bool = True
) -> np.ndarray:
    """``value`` as a checked ``(n, ncol)`` float64 array, ``n >= 1``, every entry finite
    (``finite`` False: the caller's callee checks the values, as the runtime checks a plan's).
    ``name`` (``plans[2].qpos``), ``cols`` (``nq``) and ``rows`` (``joint positions per physics
    step``) say in the errors what the array, its columns and a row are.

    Raises:
        ShapeError: Not ``(n, ncol)`` with ``n >= 1``.
        InvalidInputError: An entry is not finite (the first is named).
    """
    if type(value) is np.ndarray and value.dtype is _F64 and value.flags.c_contiguous:
        a = value  # as it is: no numpy call
    else:
        a = np.ascontiguousarray(value, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != ncol or a.shape[0] < 1:
        raise ShapeError(
            f"{name} has shape {a.shape}; expected (n, {cols}) = (n, {ncol}) with n >= 1: one "
            f"row of {rows}."
        )
    if not finite:
        return a
    bad = np.argwhere(~np.isfinite(a))
    if bad.size:
        j, i = (int(x) for x in bad[0])
        raise InvalidInputError(
            f"{name}[{j}, {i}] = {float(a[j, i])} is not finite: pass finite values."
        )
    return a


def _rows(dev: np.ndarray, n: int, ncol: int, *, per_row: bool) -> np.ndarray | None:
    """A deviation ``dev`` (one number, one a row (``per_row``: ``(n,)``) or a column
    (``(ncol,)``), or ``(n, ncol)``) as a C-contiguous ``(n, ncol)`` array, ``dev`` itself when
    it is one; None when its shape fits none of these."""
    if dev.shape == (n, ncol):
        return dev if dev.flags.c_contiguous else np.ascontiguousarray(dev)
    if dev.ndim == 0 or (dev.ndim == 1 and dev.shape[0] == (n if per_row else ncol)):
        column = per_row and dev.ndim == 1
        return np.ascontiguousarray(
            np.broadcast_to(dev.reshape(-1, 1) if column else dev, (n, ncol))
        )
    return None


Bodies = Iterable[str | int] | str | int | None
"""The bodies a plan holds: names, fnmatch patterns or ids (None: the default)."""


class PlanArrays(NamedTuple):
    """A plan's arguments as the runtime reads them (``_core.Runtime.set_plan``'s, in order).

    Attributes:
        qpos: ``(n, nq)`` planned joint positions.
        deviation: ``(n, nbody)`` metres.
        start: The time of ``qpos[0]``'s state (seconds).
        bodies: ``(nbody,)`` uint8, 1 for the bodies the plan holds; ``(0,)`` for the default.
        mocap_pos: ``(n, nmocap, 3)``, or ``(0,)`` when mocap bodies are not planned.
        mocap_quat: ``(n, nmocap, 4)``, or ``(0,)``.
        rel_bodies: ``(nrel, 2)`` int64 body pairs with a relative deviation, ``(0, 2)`` for none.
        rel_deviation: ``(n, nrel)`` metres.
    """

    qpos: np.ndarray
    deviation: np.ndarray
    start: float
    bodies: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray
    rel_bodies: np.ndarray
    rel_deviation: np.ndarray


Relative = tuple[npt.ArrayLike, npt.ArrayLike] | None
"""Relative deviations: ``(pairs, deviation)``, ``(nrel, 2)`` body pairs (ids or names) and
metres, one number, ``(nrel,)``, or ``(n, nrel)`` (None: none)."""


def relative_arrays(
    model: mujoco.MjModel, relative: Relative, n: int
) -> tuple[np.ndarray, np.ndarray]:
    """``relative`` (:data:`Relative`) as ``(nrel, 2)`` int64 body ids and ``(n, nrel)``
    metres, their shapes checked, names made ids (the runtime checks the values: ids of two
    distinct bodies the plan holds, each pair once, finite deviations >= 0)."""
    if relative is None:
        return _NO_PAIRS, np.zeros((n, 0))
    try:
        raw_pairs, raw_dev = relative
    except (TypeError, ValueError):
        raise InvalidInputError(
            f"relative = {relative!s:.80} is invalid: pass (pairs, deviation), (nrel, 2) body "
            "pairs and their relative deviations (relative_profile's)."
        ) from None
    items = raw_pairs if type(raw_pairs) is np.ndarray else np.asarray(raw_pairs)
    if items.ndim != 2 or items.shape[1] != 2:
        raise ShapeError(
            f"relative pairs have shape {items.shape}; expected (nrel, 2): body pairs (a, b)."
        )
    if items.dtype.kind in "iu":  # ids (relative_profile's): the runtime's to check
        pairs = np.ascontiguousarray(items, dtype=np.int64)  # no copy when they are already
    else:  # names (or ids mixed with them)
        pairs = np.array(
            [[body_id(model, item) for item in row] for row in items.tolist()], dtype=np.int64
        ).reshape(-1, 2)
    nrel = pairs.shape[0]
    dev = _rows(float64_array(raw_dev), n, nrel, per_row=False)
    if dev is None:
        raise ShapeError(
            f"relative deviation has shape {np.shape(raw_dev)}; pass one number, ({nrel},) (one "
            f"per pair) or ({n}, {nrel}) (one per knot and pair)."
        )
    return pairs, dev


def body_mask(
    model: mujoco.MjModel,
    bodies: Iterable[str | int] | str | int,
    mocap: bool = True,
    what: str = "bodies",
) -> np.ndarray:
    """``(nbody,)`` uint8 mask of the bodies named (names, fnmatch patterns or ids); ``mocap``
    False refuses bodies in mocap trees; ``what`` names the argument in the errors."""
    names = [
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or "" for b in range(model.nbody)
    ]
    out = np.zeros(model.nbody, dtype=np.uint8)
    for item in [bodies] if isinstance(bodies, str | int | np.integer) else list(bodies):
        if isinstance(item, str):
            hit = [b for b, name in enumerate(names) if name and fnmatch.fnmatchcase(name, item)]
            if not hit:
                raise InvalidInputError(
                    f"{what}: {item!r} names no body of the model (names or fnmatch patterns, "
                    f"e.g. 'arm_*'; the bodies: {', '.join(n for n in names if n)})."
                )
            out[hit] = 1
        elif isinstance(item, int | np.integer) and not isinstance(item, bool):
            if not 0 <= int(item) < model.nbody:
                raise InvalidInputError(
                    f"{what}: id {item} is out of range: the model has {model.nbody} bodies."
                )
            out[int(item)] = 1
        else:
            raise InvalidInputError(
                f"{what}: {item!r} is neither a body name, a pattern nor an id."
            )
    in_mocap = np.asarray(model.body_mocapid)[np.asarray(model.body_rootid)] >= 0
    bad = np.flatnonzero(out.astype(bool) & in_mocap)
    if bad.size and not mocap:
        raise InvalidInputError(
            f"bodies: {names[int(bad[0])]!r} is in a mocap tree, whose poses a plan of qpos does "
            "not hold: give mocap_pos and mocap_quat to plan it, or leave it out (it then "
            "follows its motion bounds)."
        )
    return out


def _mocap(
    model: mujoco.MjModel, name: str, value: npt.ArrayLike, n: int, width: int
) -> np.ndarray:
    a = np.ascontiguousarray(value, dtype=np.float64)
    if a.shape != (n, model.nmocap, width):
        raise ShapeError(
            f"{name} has shape {a.shape}; expected (n, nmocap, {width}) = ({n}, {model.nmocap}, "
            f"{width}): the mocap bodies' poses at each knot."
        )
    return a


def plan_arrays(
    model: mujoco.MjModel,
    qpos: npt.ArrayLike,
    deviation: npt.ArrayLike,
    start: float,
    bodies: Bodies = None,
    mocap_pos: npt.ArrayLike | None = None,
    mocap_quat: npt.ArrayLike | None = None,
    relative: Relative = None,
) -> PlanArrays:
    """A plan's arguments as the runtime reads them, their shapes checked (their values are the
    runtime's to check: ``Plan::Build`` refuses a value that is not finite, or a negative
    deviation, naming the knot, the entry and the body). The arguments are
    :meth:`PlanFollowing.set_plan`'s, ``start`` given; ``set_plan``'s one call of it (the
    plugin's and the predictor's) passes them in order.

    Raises:
        ShapeError: The arrays do not fit the model or each other.
        InvalidInputError: A body named is not the model's, or a mocap tree is held without
            mocap poses.
    """
    q = finite_rows("qpos", qpos, model.nq, "nq", "joint positions per physics step", finite=False)
    n, nbody = q.shape[0], model.nbody
    dev = _rows(float64_array(deviation), n, nbody, per_row=True)
    if dev is None:
        raise ShapeError(
            f"deviation has shape {np.shape(deviation)}; pass one number, ({n},) (one per "
            f"knot) or ({n}, {nbody}) (one per knot and body)."
        )
    if mocap_pos is None and mocap_quat is None:
        mp = mq = _NO_MOCAP
    elif mocap_pos is None or mocap_quat is None:
        raise InvalidInputError(
            "mocap_pos and mocap_quat go together: pass both, (n, nmocap, 3) and (n, nmocap, 4), "
            "or neither (mocap bodies then follow their motion bounds)."
        )
    else:
        mp = _mocap(model, "mocap_pos", mocap_pos, n, 3)
        mq = _mocap(model, "mocap_quat", mocap_quat, n, 4)
    held = _NO_BODIES if bodies is None else body_mask(model, bodies, mp.size > 0)
    rb, rd = relative_arrays(model, relative, n)
    return PlanArrays(q, dev, float(start), held, mp, mq, rb, rd)


class PlanFollowing:
    """The flight plan methods of :class:`~dua_mujoco.runtime.predictor.Predictor` (one runtime, the
    native ``_core.Runtime``, follows the plan; docs/theory.md, section 8)."""

    model: mujoco.MjModel
    _rt: Any
    _data: mujoco.MjData | None
    _require_reset: Callable[[], None]
    _bind: Callable[[mujoco.MjData], None]

    def set_plan(
        self,
        qpos: npt.ArrayLike,
        *,
        deviation: npt.ArrayLike,
        start: float | None = None,
        bodies: Bodies = None,
        mocap_pos: npt.ArrayLike | None = None,
        mocap_quat: npt.ArrayLike | None = None,
        relative: Relative = None,
    ) -> np.ndarray:
        """Follow a flight plan: the motion expected over the coming physics steps.

        A pair of two bodies the plan holds (static bodies count, deviation 0) is judged by the
        plan: the time to the first knot at which the plan's geometry, less both deviations,
        may touch. A pair of a planned body and one it does not hold (a person, a mocap body,
        another robot) is judged by the planned geom, less its deviation, against the other's
        reach from where it is now under its own bounds (``accel``, ``speed``). Every pair is
        evaluated again at the next step. A body found farther from its plan than its deviation
        follows its bounds until the next plan, and so does everything past the last knot: give
        the next plan before this one runs out by the alarm horizon. The plan replaced is still
        checked over the span its verdicts cover. docs/plans.md; docs/theory.md, section 8.

        Args:
            qpos: ``(n, nq)`` joint positions, row ``j`` the state ``j * model.opt.timestep``
                after ``start`` (:func:`dua_mujoco.runtime.plans.plan_from_controls` rolls them).
            deviation: Metres: a bound on the distance of every point of a body's geoms from
                where the plan puts it, one number, ``(n,)`` or ``(n, nbody)``; 0 where the plan
                is exact (a rollout of the controls that will be applied, in simulation).
            start: The time of ``qpos[0]``'s state (default: the bound data's ``time``). The
                plan must cover the state the next step reads (one timestep before its time).
            bodies: The bodies the plan holds: names, fnmatch patterns (``"arm_*"``) or ids
                (None: every moving body outside mocap trees, and those too with mocap poses).
            mocap_pos: ``(n, nmocap, 3)`` planned mocap positions (None: mocap bodies follow
                their bounds), with ``mocap_quat`` ``(n, nmocap, 4)``.
            mocap_quat: The planned mocap orientations.
            relative: ``(pairs, deviation)``: for ``(nrel, 2)`` pairs ``(a, b)`` of bodies the
                plan holds (ids or names), a bound in metres (one number, ``(nrel,)`` or ``(n,
                nrel)``) on how far any point of ``b``'s box may stray, in ``a``'s frame, from
                where the plan puts it relative to ``a``
                (:func:`dua_mujoco.runtime.plans.relative_profile` measures it). A pair of geoms
                on ``a`` and ``b`` then takes ``min(D_a + D_b, D_ab)`` off its planned gap; a
                pair found beyond it is a plan break for those pairs, which take ``D_a + D_b``
                until the next plan (docs/theory.md, Lemma 8.2d).

        Returns:
            ``(nbody,)`` for each body the replaced plan held, the first state time at which
            this plan leaves its deviation tube within the span its verdicts cover (``inf``:
            never): a replan that departs within the alarm horizon buys less warning.

        Raises:
            SchedulerError: ``reset`` was not called.
            ShapeError: ``qpos``, ``deviation`` or the mocap poses do not fit the model.
            InvalidInputError: A value is not finite or negative, a body named is not the
                model's, or the plan does not cover the next step.
        """
        args = self._plan_args(qpos, deviation, start, bodies, mocap_pos, mocap_quat, relative)
        return self._rt.set_plan(*args)  # a new numpy array, the departures

    def _plan_args(
        self,
        qpos: npt.ArrayLike,
        deviation: npt.ArrayLike,
        start: float | None,
        bodies: Bodies,
        mocap_pos: npt.ArrayLike | None,
        mocap_quat: npt.ArrayLike | None,
        relative: Relative = None,
    ) -> PlanArrays:
        """A plan's arguments to the runtime, checked."""
        self._require_reset()
        assert self._data is not None
        start = self._data.time if start is None else start
        return plan_arrays(
            self.model, qpos, deviation, start, bodies, mocap_pos, mocap_quat, relative
        )

    def check_plan(self, data: mujoco.MjData) -> np.ndarray:
        """Check the plan at ``data``'s state between two steps (``period > 1``: after each
        ``mj_step`` the predictor does not step on). A body beyond its deviation is a plan
        break, its pairs evaluated at the next step under its bounds; without these calls a
        break undone before the next step is not seen (the plugin checks every physics step
        itself). Returns the bodies found."""
        self._require_reset()
        if data is not self._data:
            self._bind(data)
        return np.asarray(self._rt.check_plan())

    def plan_contact_knots(
        self,
        qpos: npt.ArrayLike,
        geom_pairs: npt.ArrayLike,
        *,
        deviation: npt.ArrayLike,
        **plan: Any,
    ) -> np.ndarray:
        """For a candidate plan (:meth:`set_plan`'s arguments, ``start``, ``bodies`` and the
        mocap poses in ``plan``; it is not followed), each of the ``(k, 2)`` geom pairs' first
        knot at which its contact cannot be excluded, judged as the step would judge it under
        that plan from the bound data's state: the candidate's knot count when never, -1 when
        it plans neither body, -2 when MuJoCo's filter rejects the pair. A shield's question (is
        the intended motion, then a brake, clear of the reach of everything else?); changes
        nothing."""
        keys = ("start", "bodies", "mocap_pos", "mocap_quat", "relative")
        if set(plan) - set(keys):
            raise InvalidInputError(
                f"plan_contact_knots got {sorted(set(plan) - set(keys))}: pass set_plan's "
                f"arguments ({', '.join(keys)})."
            )
        args = self._plan_args(qpos, deviation, *(plan.get(k) for k in keys))
        pairs = np.asarray(geom_pairs, dtype=np.int64).reshape(-1, 2)
        return np.asarray(self._rt.plan_query(*args, pairs[:, 0], pairs[:, 1]))

    def clear_plan(self) -> None:
        """Stop following the plan: every pair is evaluated again at the next step, under the
        motion bounds."""
        self._rt.clear_plan()

    @property
    def has_plan(self) -> bool:
        """Whether a plan is followed (it ends past its last knot, or when cleared)."""
        return bool(self._rt.has_plan)

    def beyond_plan(self) -> np.ndarray | None:
        """The bodies of the bound data's state beyond their deviation, of the plan and of the
        plans it replaced over their spans (None: no plan covers the state); checks only."""
        out = self._rt.plan_broken()
        return None if out is None else np.asarray(out)

    def beyond_plan_relative(self) -> np.ndarray:
        """``(n, 2)`` the relative pairs (body ids ``a < b``) of the bound data's state beyond
        their relative deviation, of the plan and of the plans it replaced over their spans;
        checks only (the monitor's, as :meth:`beyond_plan`)."""
        return np.asarray(self._rt.plan_broken_relative()).reshape(-1, 2)

    def verdict_basis(self, pairs: npt.ArrayLike) -> np.ndarray:
        """``(n, 2)`` uint8, what each sphere pair's latest verdict and the one before rested on:
        bit 0 (1) set when its first (second) geom's body was judged by the plan, clear by its
        bounds (0 for a pair not held: left out on both bodies' reach); bit 2 (4) set when it
        rested on the relative deviation of its two bodies too."""
        return np.asarray(self._rt.basis_of(np.asarray(pairs, dtype=np.int64).reshape(-1)))

    @property
    def plan_tolerance(self) -> float:
        """Metres the current plan added to every deviation it was given (three times it to a
        relative one): how far the knots' poses may lie from MuJoCo's, their hinges' sines and
        cosines taken by polynomials (docs/plans.md). The model's, the same for every plan; 0
        without a plan, or where no planned geom's body turns on a hinge. A run that is the plan
        stays within it, so an exact plan (deviation 0) never breaks."""
        return float(self._rt.plan_tolerance)

    @property
    def plan_breaks(self) -> int:
        """Bodies found farther from the plan than their deviation, over the plans so far: their
        pairs followed the motion bounds from then until the next plan."""
        return int(self._rt.plan_breaks)
