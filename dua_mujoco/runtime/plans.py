"""Making flight plans for ``Predictor.set_plan``: the planned motion and its deviation bound.

A *flight plan* (Kim, Guibas and Shin, Algorithmica 2005) is the motion the robot is expected to
make over the coming steps: joint positions ``qpos`` at each physics step (a *knot*), and for
every body a bound on how far any point of it may stray from where the plan puts it at each
knot (its *deviation*). While a plan holds, the predictor asks the plan's geometry whether a pair
may touch, not an acceleration bound, so an alarm horizon of 100-500 ms stays tight
(docs/plans.md). This module makes both halves offline, in Python:

- :func:`plan_from_controls` rolls a copy of the state under the controls the robot will be
  given (an MPC's or a planner's open-loop controls, or a feedback policy): the plan is then
  what MuJoCo will compute under those controls, bit for bit, and its deviation 0 for as long as
  the controls are known;
- :func:`deviation_profile` measures, on a pilot run, how far each body strayed from the plans
  made along it, by how many knots past the point where the plan stopped knowing the controls
  (its *origin*: 0 for a plan that knows nothing, the next waypoint for one that knows the
  command up to it), made monotone and multiplied by a safety factor;
- :func:`plan_deviation` gives a plan of ``n`` knots its ``(n, nbody)`` deviation from such a
  profile;
- :class:`Replanner` wraps a controller: every ``R`` physics steps it rolls a plan from a copy of
  it and gives it to a predictor, then runs the controller (what ``dua-mujoco run --plan
  trajectory`` does).
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any, NamedTuple

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco import _core
from dua_mujoco.build.kinematics import pack_spheres
from dua_mujoco.build.tables import check_model
from dua_mujoco.core.validate import check_int, check_number
from dua_mujoco.exceptions import InvalidInputError, ShapeError
from dua_mujoco.runtime.flightplan import Bodies, Relative, finite_rows

if TYPE_CHECKING:
    from dua_mujoco.runtime.predictor import Predictor

__all__ = [
    "PilotPlan",
    "RelativeProfile",
    "Replanner",
    "deviation_profile",
    "plan_deviation",
    "plan_from_controls",
    "relative_profile",
]

Policy = Callable[[mujoco.MjModel, mujoco.MjData], npt.ArrayLike | None]
"""``policy(model, data)``: the controls of the coming step, returned (``(nu,)``) or written to
``data.ctrl`` (returning None), as a controller passed to ``dua_mujoco.run``."""

_S = mujoco.mjtState
# What a step reads beside the integrated state, held at the data's values during a plan.
_HELD = int(
    _S.mjSTATE_CTRL
    | _S.mjSTATE_QFRC_APPLIED
    | _S.mjSTATE_XFRC_APPLIED
    | _S.mjSTATE_EQ_ACTIVE
    | _S.mjSTATE_MOCAP_POS
    | _S.mjSTATE_MOCAP_QUAT
)
_FULL = int(_S.mjSTATE_FULLPHYSICS)


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


# ----------------------------------------------------------------------------- plans


def _check_model_data(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    check_model(model, ": pass the model the data was made for")
    if not isinstance(data, mujoco.MjData):
        raise InvalidInputError(
            f"data must be a mujoco.MjData, got {type(data).__name__}: pass the simulation's "
            "data (it is copied, not stepped)."
        )
    if data.qpos.shape != (model.nq,) or data.ctrl.shape != (model.nu,):
        raise InvalidInputError(
            f"data was made for another model (nq {data.qpos.shape[0]}, nu {data.ctrl.shape[0]}; "
            f"the model has nq {model.nq}, nu {model.nu}): pass mujoco.MjData(model)."
        )


def plan_from_controls(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    controls: npt.ArrayLike | Policy,
    *,
    steps: int | None = None,
) -> np.ndarray:
    """The plan of ``data``'s state under future ``controls``: ``qpos`` at every physics step.

    A copy of the state is stepped (``data`` itself is not touched). With an array the steps run
    in MuJoCo's native ``mujoco.rollout`` from the full physics state and ``qacc_warmstart``; with
    a policy, ``mj_copyData`` and ``mj_step`` in a loop. Either way the plan is what ``mj_step``
    computes from ``data`` under the same controls, bit for bit. Everything else a step reads
    (``qfrc_applied``, ``xfrc_applied``, mocap poses, active equality constraints) is held at its
    value in ``data``.

    Args:
        model: The model.
        data: The state to plan from (its ``time`` is the time of knot 0).
        controls: ``(steps, nu)`` the ``ctrl`` of each coming step, or a policy
            ``policy(model, data)`` called before each step on the copy, returning the step's
            ``(nu,)`` controls or writing ``data.ctrl`` (a copy of a stateful controller:
            ``copy.deepcopy(controller)``, so that the real one does not advance).
        steps: Physics steps to plan (a policy only; an array's rows say it).

    Returns:
        ``(steps + 1, nq)`` planned joint positions, row ``j`` at ``data.time + j *
        model.opt.timestep`` (row 0 is ``data.qpos``): the ``qpos`` of
        ``Predictor.set_plan(plan, deviation=..., start=data.time)``.

    Raises:
        InvalidInputError: A bad model, data, step count or control (the message names it).
        ShapeError: ``controls`` is not ``(steps, nu)``, or a policy returned another shape.
    """
    _check_model_data(model, data)
    if steps is not None:
        steps = check_int("steps", steps, 1, " (the physics steps to plan)")
    if callable(controls):
        if steps is None:
            raise InvalidInputError(
                "steps is missing: a policy has no length, pass steps=<physics steps to plan>."
            )
        return _plan_policy(model, data, controls, steps)
    u = finite_rows("controls", controls, model.nu, "nu", "ctrl a physics step")
    if steps is not None and steps != u.shape[0]:
        raise InvalidInputError(
            f"steps = {steps} disagrees with the {u.shape[0]} rows of controls: leave steps out "
            "for an array."
        )
    n = u.shape[0]
    from mujoco import rollout

    scratch = mujoco.MjData(model)
    mujoco.mj_copyData(scratch, model, data)
    state0 = np.empty(mujoco.mj_stateSize(model, _FULL))
    mujoco.mj_getState(model, data, state0, _FULL)
    held = np.empty(mujoco.mj_stateSize(model, _HELD))
    mujoco.mj_getState(model, data, held, _HELD)
    control = np.tile(held, (n, 1))
    control[:, : model.nu] = u  # ctrl is the lowest bit of the spec: its columns come first
    state, _ = rollout.rollout(
        model,
        scratch,
        state0,
        control[None],
        control_spec=_HELD,
        initial_warmstart=np.array(data.qacc_warmstart),
    )
    if any(int(w.number) for w in scratch.warning):
        # rollout stops at MuJoCo's first warning and repeats that state; mj_step goes on.
        return _plan_policy(model, data, _Rows(u), n)
    out = np.empty((n + 1, model.nq))
    out[0] = data.qpos
    out[1:] = state[0, :, 1 : 1 + model.nq]  # after the time
    return out


class _Rows:
    """A policy giving the rows of an array in turn."""

    def __init__(self, u: np.ndarray) -> None:
        self.u, self.j = u, 0

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        self.j += 1
        return self.u[self.j - 1]


def _plan_policy(model: mujoco.MjModel, data: mujoco.MjData, policy: Policy, n: int) -> np.ndarray:
    copy = mujoco.MjData(model)
    mujoco.mj_copyData(copy, model, data)
    out = np.empty((n + 1, model.nq))
    out[0] = data.qpos
    for j in range(1, n + 1):
        u = policy(model, copy)
        if u is not None:
            ctrl = np.asarray(u, dtype=np.float64)
            if ctrl.shape != (model.nu,):
                raise ShapeError(
                    f"the policy returned controls of shape {ctrl.shape} at step {j - 1}; "
                    f"expected ({model.nu},), or None after writing data.ctrl."
                )
            copy.ctrl[:] = ctrl
        mujoco.mj_step(model, copy)
        out[j] = copy.qpos
    return out


Planner = Callable[[mujoco.MjModel, mujoco.MjData, int], np.ndarray]
"""``planner(model, data, steps)``: the ``(steps + 1, nq)`` plan from ``data``'s state, as
:func:`plan_from_controls` returns it."""


class Replanner:
    """A controller that gives a predictor a flight plan every ``every`` physics steps.

    Call it before each ``mj_step``, as the controller it wraps (``dua_mujoco.run`` does): when a
    plan is due it rolls one from the data's state, gives it to the predictor (``set_plan``, knot 0
    the data's time: the state the next predictor step reads), then runs the controller. A plan is
    due once the predictor has been reset, at every reset after (a reset drops the plan), and
    ``every`` steps after the last. By default the plan is :func:`plan_from_controls` of a copy of
    the controller (``copy.deepcopy``: a stateful controller's copy knows its own future, random
    draws included), so with ``deviation=0`` it is exact in simulation until something the
    rollout did not have (a contact with a body the plan does not hold, a push) moves the bodies
    off it: the predictor counts that as a plan break and follows their bounds until the next
    plan (docs/plans.md).

    Args:
        predictor: The predictor to give the plans to.
        controller: ``controller(model, data)``, called before each step.
        every: Physics steps between two plans (None: the alarm horizon and latency, at least
            50 ms, as docs/plans.md's trajectory planner).
        deviation: ``set_plan``'s deviation (metres: one number, ``(knots,)`` or
            ``(knots, nbody)``).
        bodies: The bodies the plan holds (``set_plan``'s ``bodies``; None: every moving body
            outside mocap trees). The others follow their bounds.
        planner: ``planner(model, data, steps)`` returning the plan (:data:`Planner`), e.g. a
            rollout of the robot's own controller on a model where people do not collide; None
            for :func:`plan_from_controls` of a copy of ``controller``.
        relative: ``set_plan``'s relative deviations (:func:`relative_profile`; None: none).

    Attributes:
        knots: Knots a plan: ``every`` plus the horizon's physics steps (alarm horizon and
            latency) plus the predictor's period and one, so that every step until the next plan
            is covered with its horizon.
        plans: Plans given so far.
        planner_seconds: CPU time spent making plans (the planner's; an MPC pays it anyway).
        set_plan_seconds: CPU time spent in ``set_plan`` (the predictor's).
    """

    def __init__(
        self,
        predictor: Predictor,
        controller: Callable[[mujoco.MjModel, mujoco.MjData], Any],
        *,
        every: int | None = None,
        deviation: npt.ArrayLike = 0.0,
        bodies: Bodies = None,
        planner: Planner | None = None,
        relative: Relative = None,
    ) -> None:
        h = float(predictor.model.opt.timestep)
        ahead = (predictor.alarm_periods + predictor.latency) * predictor.period
        if every is None:
            every = max(ahead, round(0.05 / h), 1)
        self.every = _int("every", every, 1, 2**31 - 1)
        self.knots = self.every + ahead + predictor.period + 1
        self.predictor = predictor
        self.controller = controller
        self.deviation = deviation
        self.bodies = bodies
        self.relative = relative
        self.planner: Planner = planner or (
            lambda m, d, steps: plan_from_controls(m, d, copy.deepcopy(controller), steps=steps)
        )
        self.plans = 0
        self.planner_seconds = 0.0
        self.set_plan_seconds = 0.0
        self._since = 0
        self._resets = 0

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Give a plan if one is due, then run the controller."""
        p = self.predictor
        if p.resets and (p.resets != self._resets or self._since >= self.every):
            t0 = time.thread_time()
            qpos = self.planner(model, data, self.knots - 1)
            t1 = time.thread_time()
            p.set_plan(
                qpos,
                deviation=self.deviation,
                bodies=self.bodies,
                start=float(data.time),
                relative=self.relative,
            )
            self.set_plan_seconds += time.thread_time() - t1
            self.planner_seconds += t1 - t0
            self.plans += 1
            self._since, self._resets = 0, p.resets
        self._since += 1
        self.controller(model, data)


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


class _Poses:
    """Every geom's pose for rows of qpos (``mj_kinematics`` on a scratch data)."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.data = mujoco.MjData(model)

    def __call__(self, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(rows, ngeom, 3)`` positions and ``(rows, ngeom, 9)`` rotations."""
        m, d = self.model, self.data
        pos = np.empty((qpos.shape[0], m.ngeom, 3))
        mat = np.empty((qpos.shape[0], m.ngeom, 9))
        for j, q in enumerate(qpos):
            d.qpos[:] = q
            mujoco.mj_kinematics(m, d)
            pos[j], mat[j] = d.geom_xpos, d.geom_xmat
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
        model: The model.
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
    profile = np.zeros((0, nbody))
    for ages, (act_pos, act_mat), planned in _pilot(model, qpos, plans, safety):
        dist = _core.plan_deviation(records, act_pos, act_mat, *planned)  # (n, npts)
        profile = _file(profile, ages, _per_column(dist, cols))
    return float(safety) * np.maximum.accumulate(profile, axis=0)


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


def _per_column(dist: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``(n, nowner)`` the largest of each owner's points' ``(n, npts)`` distances (0: none)."""
    pad = np.concatenate([dist, np.zeros((dist.shape[0], 1))], axis=1)
    return np.asarray(pad[:, cols].max(axis=2))


def _file(profile: np.ndarray, ages: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``profile`` (grown to the largest age) raised to ``rows`` at their ``ages``."""
    length = int(ages[-1]) + 1
    if profile.shape[0] < length:
        more = np.zeros((length - profile.shape[0], profile.shape[1]))
        profile = np.concatenate([profile, more])
    np.maximum.at(profile, ages, rows)
    return profile


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
    poses = _Poses(model)
    T = actual.shape[0]
    where = poses(actual)
    measured = 0
    for i, raw in enumerate(plans):
        plan = raw if isinstance(raw, PilotPlan) else PilotPlan(*raw)
        q = finite_rows(f"plans[{i}].qpos", plan.qpos, model.nq, "nq", "qpos a physics step")
        start = _int(f"plans[{i}].start", plan.start, 0, T - 1)
        origin = _int(f"plans[{i}].origin", plan.origin, 0, q.shape[0])
        n = min(q.shape[0], T - start)
        ages = np.maximum(np.arange(n) - origin, 0)
        yield ages, (where[0][start : start + n], where[1][start : start + n]), poses(q[:n])
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
        model: The model.
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
    rel = np.zeros((0, candidates.shape[0]))
    a, b = candidates[:, 0], candidates[:, 1]
    # b's points once per pair with b second, their frame column the pair's (the poses below
    # are b's relative to a's frame, one column a pair).
    mine = [np.flatnonzero(body == bb) for bb in b.tolist()]
    point = np.concatenate([*mine, np.zeros(0, np.int64)])
    owner = np.repeat(np.arange(b.size), [m.size for m in mine])
    records = pack_spheres(owner, body[point], offset[point], model.body_rootid)
    cols = _columns(owner, b.size, point.size)
    for ages, act, planned in _pilot(model, qpos, plans, safety):
        here = _relative_poses(*act, frame[a], frame[b])
        there = _relative_poses(*planned, frame[a], frame[b])
        dist = _core.plan_deviation(records, *here, *there)
        rel = _file(rel, ages, _per_column(dist, cols))
    if rel.shape[0] > sums.shape[0]:
        raise ShapeError(
            f"profile has {sums.shape[0]} ages, the pilot's plans {rel.shape[0]}: pass "
            "deviation_profile of the same pilot and plans."
        )
    rel = float(safety) * np.maximum.accumulate(rel, axis=0)
    # Kept: the pairs the relative bound frees at _FREED of the pilot's rows or more, at the
    # largest age (a geom pair between them farther than D_ab, nearer than D_a + D_b).
    last = rel.shape[0] - 1
    total = sums[last, a] + sums[last, b]
    frees = (near > rel[last, owner_gp]) & (near < total[owner_gp])  # (rows, geom pairs)
    freed = np.zeros((near.shape[0], candidates.shape[0]), dtype=bool)
    np.logical_or.at(freed.T, owner_gp, frees.T)
    kept = freed.mean(axis=0) >= _FREED
    return RelativeProfile(candidates[kept], np.ascontiguousarray(rel[:, kept]))


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


def _relative_poses(
    pos: np.ndarray, mat: np.ndarray, fa: np.ndarray, fb: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(n, m, 3)`` and ``(n, m, 9)``: geom ``fb[i]``'s pose in geom ``fa[i]``'s frame at each
    row (``Ra^T (pb - pa)``, ``Ra^T Rb``: RelativePose, plan.h)."""
    ra = mat[:, fa].reshape(-1, fa.size, 3, 3)
    rb = mat[:, fb].reshape(-1, fb.size, 3, 3)
    p = np.einsum("nmki,nmk->nmi", ra, pos[:, fb] - pos[:, fa])
    r = np.einsum("nmki,nmkj->nmij", ra, rb).reshape(-1, fa.size, 9)
    return np.ascontiguousarray(p), np.ascontiguousarray(r)


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
    prof = np.asarray(profile, dtype=np.float64)
    if prof.ndim != 2 or prof.shape[0] < 1:
        raise ShapeError(
            f"profile has shape {prof.shape}; expected (L, nbody) with L >= 1, as "
            "deviation_profile returns."
        )
    knots = check_int("knots", knots, 1, " (the plan's rows)")
    o = _int("origin", origin, 0, knots)
    need = max(knots - 1 - o, 0)
    if need >= prof.shape[0]:
        raise InvalidInputError(
            f"the plan reaches {need} knots past its origin, the profile only "
            f"{prof.shape[0] - 1}: measure longer plans in the pilot (or shorten the plan)."
        )
    return prof[np.maximum(np.arange(knots) - o, 0)]
