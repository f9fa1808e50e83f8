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
- :func:`deviation_profile`, :func:`relative_profile` and :func:`plan_deviation`
  (:mod:`dua_mujoco.runtime.profiles`, imported here too) measure the deviation on a pilot run
  and give a plan its bounds;
- :class:`Replanner` wraps a controller: every ``R`` physics steps it rolls a plan from a copy of
  it and gives it to a predictor, then runs the controller (what ``dua-mujoco run --plan
  trajectory`` does).
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco.build.tables import check_model
from dua_mujoco.core.validate import check_int
from dua_mujoco.exceptions import InvalidInputError, ShapeError
from dua_mujoco.runtime.flightplan import Bodies, Relative, finite_rows
from dua_mujoco.runtime.profiles import (
    PilotPlan,
    RelativeProfile,
    deviation_profile,
    plan_deviation,
    relative_profile,
)

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
        self.every = check_int("every", every, 1, " (physics steps between two plans)")
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
