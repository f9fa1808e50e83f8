"""``Shield``: between a controller and ``mj_step``, it applies the intended controls only where
the robot can still be stopped before anything it protects may reach it (docs/shield.md; the
proof: docs/theory.md, section 10).

Each control period (every ``period`` physics steps) the native shield (``csrc/src/shield.h``)
screens the period with the predictor's verdicts on motion bounds, or rolls the intended
controls out for the period followed by the failsafe until the robot is at rest and asks the
predictor's plan query whether a protected pair may touch before that rest; a period that
passes neither runs the failsafe of the last plan that passed. Between period starts it checks
the run against that plan at every step. This module checks the arguments, builds the
predictor's tables, the rollout model and the pairs, and hands them to it.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Iterable, Mapping

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco import _core
from dua_mujoco.build.filter import active_geom_pairs
from dua_mujoco.core.validate import check_int, check_number
from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.runtime.flightplan import body_mask
from dua_mujoco.runtime.predictor import BoundsLike, Predictor
from dua_mujoco.shield.failsafe import Brake, Evade

__all__ = ["Policy", "Shield"]

Policy = Callable[[mujoco.MjModel, mujoco.MjData], np.ndarray]
"""A failsafe of the user's: ``policy(model, data) -> (nu,)`` controls at ``data``'s state
(as ``mj_step1`` leaves it: kinematics, collisions, velocities; ``data.ctrl`` the controls
applied last). The shield calls it with the rollout's model (its protected bodies collide with
nothing) and the rollout's data: in its rollouts, and in the run on the *rollout's view*
(``Shield.view``), the plan's knot for the step with the robot's coordinates the run's, so
every other body (a mocap obstacle, another arm) is where the verified rollout had it, not where
it is now. Read the obstacles from ``data``: a run on its plan then repeats the rollout."""

Names = str | Iterable[str | int]


def robot_actuators(model: mujoco.MjModel, bodies: np.ndarray) -> np.ndarray:
    """Ids of the actuators whose transmission moves a DOF of ``bodies`` (a mask), read from
    the moment arms at ``qpos0``."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    moment = np.zeros((model.nu, model.nv))
    mujoco.mju_sparse2dense(
        moment, data.actuator_moment, data.moment_rownnz, data.moment_rowadr, data.moment_colind
    )
    dofs = bodies[np.asarray(model.dof_bodyid)].astype(bool)
    return np.flatnonzero(np.any(moment[:, dofs] != 0.0, axis=1))


class Shield:
    """A safety shield for the robot of a MuJoCo model.

    Args:
        protect: the bodies the robot must not move into: names or fnmatch patterns (``"person*"``,
            a mocap person, another arm, walls). Their pairs with the robot's geoms that MuJoCo can
            collide are protected; a robot body named here is protected against the robot's
            other bodies named here (self-collision), and only then.
        robot: the robot's bodies (names or patterns); default: every body moved by an
            actuator. Its actuators are those whose transmission moves them; the failsafe
            drives those, every other control passes through.
        period: physics steps per control period: the intended controls are read at each
            period's first step and held for the period (a gymnasium env's ``frame_skip``).
        failsafe: None (a :class:`~dua_mujoco.shield.failsafe.Brake` of the robot's
            actuators), a ``Brake`` of them with another time constant, an
            :class:`~dua_mujoco.shield.failsafe.Evade` of them (native, a mobile base braking
            while it steers away from obstacles), or a ``policy(model, data) -> (nu,)`` of your
            own (:data:`Policy`: called from the rollouts too, slower).
        deviation: how far every point of the robot may stray from a rollout of its controls
            (m): 0 in simulation, the tracking error on a real robot.
        rest_speed: a robot body at most this fast at every point is at rest (m/s; ISO/TS
            15066's contact with the robot stopped).
        stop_time: the failsafe's longest stop (s): a rollout that does not bring the robot to
            rest within it after the period fails; the screen covers the period and this.
        stop_distance: the failsafe's stop envelope (m; None: none): how far any point of the
            robot may move while the failsafe stops it (ISO 13855's stopping distance). With
            one, each period rolls out only the intended controls and trusts the envelope
            after them, checked on every failsafe rolled out (a far cheaper rollout where
            stops are long); without, each period rolls the failsafe out to rest.
        accel: the motion bounds of every moving body as :class:`~dua_mujoco.Predictor` takes
            them (m/s^2: a number, a dict by body name with ``"*"`` the rest, or
            ``MotionBounds``): the protected bodies' bound their reach; the robot's are what the
            screen assumes (checked every period).
        speed: speed bounds in the same forms (m/s), or None.
        screen: accept a period without a rollout when the predictor's verdicts on everyone's
            motion bounds rule contact out for the period and ``stop_time`` after it.

    Raises:
        InvalidInputError: a bad value (named, with the choices), a robot actuator the brake
            cannot take, or no protected pair.
        InvalidBoundError: a moving body without a bound.

    Attributes:
        pairs: ``(k, 2)`` the protected geom pairs, robot geom first.
        robot_bodies, robot_actuators: the robot.
        predictor: the :class:`~dua_mujoco.Predictor` whose tables the shield runs.
        view: the rollout's view the run calls a policy or ``Evade`` failsafe on (an ``MjData``
            of the rollout model; None for the brake, which reads the robot's state only).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        protect: Names,
        *,
        robot: Names | None = None,
        period: int = 1,
        failsafe: Brake | Policy | None = None,
        deviation: float = 0.0,
        rest_speed: float = 0.01,
        stop_time: float = 1.0,
        stop_distance: float | None = None,
        accel: BoundsLike,
        speed: float | Mapping[str, float] | None = None,
        screen: bool = True,
    ) -> None:
        period = check_int("period", period, 1, " (steps)")
        if not isinstance(screen, bool):
            raise InvalidInputError(f"screen = {screen!r} is invalid: pass True or False.")
        h = float(model.opt.timestep)
        deviation = check_number("deviation", deviation, zero=True)
        rest_speed = check_number("rest_speed", rest_speed)
        stop_time = check_number("stop_time", stop_time)
        reach = -1.0  # no stop envelope
        if stop_distance is not None:
            reach = check_number("stop_distance", stop_distance, zero=True)
        if stop_time < h:
            raise InvalidInputError(
                f"stop_time = {stop_time} is invalid: pass at least one timestep ({h} s)."
            )
        if robot is None:
            acts = np.arange(model.nu)
        else:
            named = body_mask(model, robot, what="robot")
            acts = robot_actuators(model, named)
            if acts.size == 0:
                raise InvalidInputError(
                    f"robot = {robot!r}: no actuator moves these bodies; name the bodies the "
                    "robot's actuators move."
                )
        evade = None
        if isinstance(failsafe, Evade):
            given = (failsafe.model.nbody, failsafe.model.nv, failsafe.model.nu)
            if failsafe.model is not model and given != (model.nbody, model.nv, model.nu):
                raise InvalidInputError(
                    f"failsafe: an Evade of another model (nbody, nv, nu = {given}; the "
                    f"shield's are {(model.nbody, model.nv, model.nu)}): make it "
                    "Evade(model, ...) of the shield's model."
                )
            if failsafe.still < rest_speed:
                raise InvalidInputError(
                    f"failsafe: an Evade with still = {failsafe.still} below the shield's "
                    f"rest_speed = {rest_speed}: pass Evade(..., still={rest_speed}) or more "
                    "(past the rest knot it must be the brake, docs/theory.md)."
                )
            robot_ids = (failsafe.actuators, failsafe.robot_bodies)
            tc, policy, evade = failsafe.time_constant, None, failsafe.args
        elif failsafe is None or isinstance(failsafe, Brake):
            tc = h if failsafe is None else failsafe.time_constant
            brake = Brake(model, actuators=acts, time_constant=tc)
            robot_ids, policy = (brake.actuators, brake.bodies), None
        elif callable(failsafe):
            brake, tc, policy = Brake(model, actuators=acts), h, failsafe
            robot_ids = (brake.actuators, brake.bodies)
        else:
            raise InvalidInputError(
                f"failsafe = {failsafe!r} is invalid: pass None, a Brake, or a callable "
                "policy(model, data) -> (nu,) controls."
            )
        if isinstance(failsafe, Brake | Evade) and not np.array_equal(failsafe.actuators, acts):
            kind = type(failsafe).__name__
            raise InvalidInputError(
                f"failsafe: {'an' if kind == 'Evade' else 'a'} {kind} of actuators "
                f"{failsafe.actuators.tolist()}; the robot's are {acts.tolist()}: make it "
                f"{kind}(model, actuators=...) of those."
            )
        self.model = model
        self.robot_actuators, self.robot_bodies = robot_ids
        is_robot = np.zeros(model.nbody, dtype=bool)
        is_robot[self.robot_bodies] = True
        prot = body_mask(model, protect, what="protect").astype(bool)
        self.pairs = self._pairs(model, is_robot, prot)
        self.predictor = Predictor(
            model,
            accel=accel,
            speed=speed,
            period=period,
            alarm_horizon=period * h + stop_time,
            pairs="all",
        )
        tables = _core.Tables.build(model, self.predictor.table_arrays)
        # The rollout's model: the protected bodies' geoms collide with nothing there (a
        # future of the robot that leans on where a body nobody plans stands is no future).
        rolled = copy.deepcopy(model)
        bodies = np.flatnonzero(prot & ~is_robot)
        others = np.isin(np.asarray(model.geom_bodyid), bodies)
        rolled.geom_contype[others] = 0
        rolled.geom_conaffinity[others] = 0
        # And their bodies' (the compiler's union of their geoms'): the broadphase drops them
        # before the geoms' filter would, which finds the same contacts (fewer pairs tried).
        rolled.body_contype[bodies] = 0
        rolled.body_conaffinity[bodies] = 0
        self._keep = (rolled, mujoco.MjData(rolled), mujoco.MjData(model))
        # The rollout's view, for a failsafe that reads more than the robot (a policy, the
        # evasive one): the run calls it there, on the plan's knot (shield.h, Failsafe).
        self.view = mujoco.MjData(rolled) if policy is not None or evade is not None else None
        self.native = _core.Shield(
            tables,
            model,
            *self._keep,
            self.robot_actuators,
            self.robot_bodies,
            np.ascontiguousarray(self.pairs[:, 0]),
            np.ascontiguousarray(self.pairs[:, 1]),
            period,
            deviation,
            rest_speed,
            stop_time,
            reach,
            screen,
            tc,
            policy,
            self.view,
            evade,
        )
        self.period = period
        # Called with the controller's array as it is; a TypeError (not a C-contiguous float
        # array) retries on a converted copy.
        self._control = self.native.control

    @staticmethod
    def _pairs(model: mujoco.MjModel, is_robot: np.ndarray, prot: np.ndarray) -> np.ndarray:
        """``(k, 2)`` the protected geom pairs MuJoCo can collide, robot geom first."""
        active = active_geom_pairs(model)
        body = np.asarray(model.geom_bodyid)
        g1, g2 = np.asarray(active.geom1), np.asarray(active.geom2)
        b1, b2 = body[g1], body[g2]
        # A robot geom against a protected body's, or two robot bodies both named in protect.
        first = is_robot[b1] & prot[b2] & (~is_robot[b2] | prot[b1])
        second = is_robot[b2] & prot[b1] & ~is_robot[b1]
        pairs = np.concatenate(
            [np.stack([g1[first], g2[first]], 1), np.stack([g2[second], g1[second]], 1)]
        )
        if pairs.size == 0:
            raise InvalidInputError(
                "protect names no body the robot's geoms can touch (MuJoCo's collision filter "
                "rejects every pair): name the bodies to keep the robot out of, with geoms whose "
                "contype/conaffinity meet the robot's."
            )
        explicit = np.concatenate([model.pair_geom1, model.pair_geom2])
        if np.isin(pairs[:, 1], explicit).any():
            raise InvalidInputError(
                "a protected geom is in an explicit <pair> element: the shield's rollouts cannot "
                "take it out of the contacts; protect bodies outside <contact><pair>."
            )
        return pairs.astype(np.int64)

    def reset(self, data: mujoco.MjData) -> None:
        """Start over at ``data``'s state (after ``mj_resetData`` and the scripts' first poses):
        the predictor classifies, the plan is dropped, and the first period runs the failsafe
        when the protected side has mocap bodies (their velocities are differenced from the
        next period on)."""
        self.native.reset(data)

    def __call__(self, data: mujoco.MjData, intended: npt.ArrayLike) -> np.ndarray:
        """The controls for the physics step about to start from ``data``: ``(nu,)``.

        Call it right before each ``mj_step`` (after moving mocap bodies), with the controls
        the controller wants; they are read at each period's first step and held for it.
        """
        try:  # a (nu,) float64 array, as a controller's: no copy, no conversion
            return self._control(data, intended)  # type: ignore[arg-type]
        except TypeError:
            return self._control(data, np.ascontiguousarray(intended, dtype=np.float64))

    @property
    def interventions(self) -> int:
        """Physics steps since the reset at which the failsafe's controls were applied."""
        return int(self.native.interventions)

    @property
    def guaranteed(self) -> bool:
        """Whether the guarantee holds for the step last decided (False after a broken
        hypothesis, until a check passes)."""
        return bool(self.native.guaranteed)

    @property
    def counts(self) -> dict[str, int]:
        """What the shield did since the reset: steps, interventions, unguaranteed steps,
        periods, screened, accepted and rejected periods, rollouts and their steps, knots at
        rest the failsafe cannot hold (``unheld``: no rest knot there), and the hypotheses
        found broken (``bound_events``, ``robot_events``, ``plan_breaks``, ``hold_breaks``,
        ``stop_breaks``, ``unverified``)."""
        return dict(self.native.counts)
