"""Gymnasium wrappers for any MuJoCo-based env: ``PredictCollisions`` predicts collisions and
puts a cost into ``info``; ``SafetyShield`` shields the env's actions (:class:`~dua_mujoco.Shield`).
docs/integrations.md has an example and the measured cost over an episode.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any, SupportsFloat

import mujoco
import numpy as np

try:
    import gymnasium
except ModuleNotFoundError as exc:  # an optional dependency: say which extra brings it
    raise ModuleNotFoundError(
        "dua_mujoco.gym needs gymnasium: pip install 'dua_mujoco[gym]'", name=exc.name
    ) from exc

from dua_mujoco.core.validate import check_int, check_number
from dua_mujoco.exceptions import InvalidChoiceError, InvalidInputError
from dua_mujoco.runtime.predictor import Predictor
from dua_mujoco.shield.shield import Shield

__all__ = [
    "COSTS",
    "COST_KEY",
    "SHIELD_COST_KEY",
    "PredictCollisions",
    "SafetyShield",
    "find_mujoco",
]

COSTS = ("alarm", "new", "horizon")
"""The choices of ``PredictCollisions(cost=...)``."""

COST_KEY = "cost_predicted_collision"
"""The ``info`` key of this wrapper's cost term (safety-gymnasium's ``cost_<name>``)."""

SHIELD_COST_KEY = "cost_protected_contact"
"""The ``info`` key of :class:`SafetyShield`'s cost term."""

IgnoreSpec = str | tuple[str, str]


def find_mujoco(env: gymnasium.Env) -> tuple[mujoco.MjModel, mujoco.MjData, int]:
    """The ``MjModel``, ``MjData`` and ``frame_skip`` of a MuJoCo-based env.

    Looks on ``env.unwrapped`` for ``model`` and ``data`` (gymnasium's ``MujocoEnv`` and the envs
    built on it) and for ``frame_skip`` (physics steps per ``env.step``).

    Raises:
        InvalidInputError: The env holds no ``MjModel``/``MjData`` there, or no ``frame_skip``.
    """
    inner = env.unwrapped
    model = getattr(inner, "model", None)
    data = getattr(inner, "data", None)
    if not isinstance(model, mujoco.MjModel) or not isinstance(data, mujoco.MjData):
        raise InvalidInputError(
            f"{type(inner).__name__} holds no mujoco.MjModel and MjData as env.unwrapped.model "
            "and env.unwrapped.data: wrap a MuJoCo-based env (gymnasium's MujocoEnv, e.g. "
            "gym.make('Ant-v5')), or give such an env those two attributes."
        )
    frame_skip = getattr(inner, "frame_skip", None)
    fix = " (the physics steps one env.step takes: set env.unwrapped.frame_skip)"
    return model, data, check_int(f"{type(inner).__name__}.frame_skip", frame_skip, 1, fix)


class PredictCollisions(gymnasium.Wrapper, gymnasium.utils.RecordConstructorArgs):
    """Steps a collision predictor after every ``env.step``; alarms and a cost go into ``info``.

    The predictor (:class:`~dua_mujoco.Predictor`) runs on the env's own ``MjData`` with the
    env's ``frame_skip`` as its period; ``reset`` re-classifies after the env's reset. ``info``
    gets ``"alarm_pairs"`` (the counted geom pairs standing in alarm, sorted ``(name1, name2)``,
    ``geom<id>`` for unnamed geoms), ``"min_tau"`` (the least time to collision, s, the
    predictor still vouches for over the counted pairs: each one's latest tau less the time
    since; 0 for a pair in alarm with tau 0, ``inf`` for none), and the cost of the step as
    ``"cost_predicted_collision"``, added to ``"cost"`` (the env's own, if any:
    safety-gymnasium's conventions, a float a step, 0 when safe). While the declared bounds
    hold, every contact of a counted pair is preceded by its alarm (docs/theory.md); resting
    contact the task wants (feet on the floor) stands in alarm for good: ``ignore`` it.

    Args:
        env: A MuJoCo-based env (:func:`find_mujoco` finds its model, data and ``frame_skip``).
        cost: ``"alarm"``: 1.0 when a counted geom pair stands in alarm after the step, else
            0.0 (safety-gymnasium's ``constrain_indicator``); ``"new"``: the number of counted
            geom pairs whose alarm started at the step; ``"horizon"``: 1.0 when
            ``min_tau < cost_horizon``, else 0.0.
        cost_horizon: Seconds; required by, and only by, ``cost="horizon"``.
        terminate_on_alarm: End the episode (``terminated=True``) at a step whose cost is > 0.
        ignore: Geom names or ``(name, name)`` geom pairs whose alarms count for nothing (left
            out of ``alarm_pairs``, ``min_tau`` and the cost; still predicted). A single name
            ignores every pair of that geom.
        **predictor_options: Passed to :class:`~dua_mujoco.Predictor` as they are (``accel``,
            ``schedule=ScheduleOptions(...)``, ``pilot=PilotOptions(...)``, ...), except
            ``period``: it is the env's ``frame_skip``.

    Attributes:
        predictor: The predictor, built once for the env's model.

    Raises:
        InvalidInputError: Not a MuJoCo-based env, ``period`` passed, or a bad
            ``cost_horizon``.
        InvalidChoiceError: Unknown ``cost`` or geom name in ``ignore``.
    """

    def __init__(
        self,
        env: gymnasium.Env,
        *,
        cost: str = "alarm",
        cost_horizon: float | None = None,
        terminate_on_alarm: bool = False,
        ignore: Iterable[IgnoreSpec] = (),
        **predictor_options: Any,
    ) -> None:
        ignore = (ignore,) if isinstance(ignore, str) else tuple(ignore)
        gymnasium.utils.RecordConstructorArgs.__init__(
            self,
            cost=cost,
            cost_horizon=cost_horizon,
            terminate_on_alarm=terminate_on_alarm,
            ignore=ignore,
            **predictor_options,
        )
        gymnasium.Wrapper.__init__(self, env)
        if cost not in COSTS:
            raise InvalidChoiceError("cost", cost, COSTS)
        if (cost == "horizon") != (cost_horizon is not None):
            raise InvalidInputError(
                f"cost_horizon = {cost_horizon!r} with cost = {cost!r}: pass cost_horizon "
                "(seconds) with cost='horizon', and only then."
            )
        if cost_horizon is not None:
            cost_horizon = check_number("cost_horizon", cost_horizon, unit=" of seconds")
        model, self._data, frame_skip = find_mujoco(env)
        if "period" in predictor_options:
            raise InvalidInputError(
                f"period = {predictor_options['period']!r}: here the predictor period is the "
                f"env's frame_skip ({frame_skip} physics steps per env.step): drop period."
            )
        self._cost, self._cost_horizon = cost, cost_horizon
        self.terminate_on_alarm = bool(terminate_on_alarm)
        self.predictor = Predictor(model, period=frame_skip, **predictor_options)
        self._names = [str(n) for n in self.predictor.tables.geom_names]
        geoms, keys = self._ignored(ignore)
        ignored = np.zeros(model.ngeom, dtype=np.uint8)
        ignored[geoms] = 1
        # The runtime keeps what info needs up to date as it steps (counted geom pairs standing,
        # those started, the least expiry) and writes info itself: one native call a step.
        self._runtime = self.predictor._rt
        self._runtime.watch(ignored, keys)
        self._runtime.watch_info(self._names, cost, cost_horizon or 0.0, COST_KEY)
        self._step_info = self._runtime.step_info

    @property
    def cost(self) -> str:
        """What ``info["cost"]`` counts, as constructed (the runtime writes it: read-only)."""
        return self._cost

    @property
    def cost_horizon(self) -> float | None:
        """Seconds, for ``cost="horizon"``, as constructed (read-only)."""
        return self._cost_horizon

    def _ignored(self, ignore: tuple[IgnoreSpec, ...]) -> tuple[np.ndarray, np.ndarray]:
        """The geoms and the geom-pair keys ``(g1 << 32) | g2`` that ``ignore`` names."""
        ids = {name: g for g, name in enumerate(self._names)}
        geoms: list[int] = []
        keys: list[int] = []

        def geom(name: object) -> int:
            if not isinstance(name, str) or name not in ids:
                raise InvalidChoiceError(
                    "geom",
                    name,
                    self._names,
                    "ignore takes geom names (geom<id> for unnamed ones) or pairs of them.",
                )
            return ids[name]

        for item in ignore:
            if isinstance(item, str):
                geoms.append(geom(item))
                continue
            if not (isinstance(item, tuple | list) and len(item) == 2):
                raise InvalidInputError(
                    f"ignore entry {item!r} is invalid: pass a geom name or a (name, name) pair."
                )
            a, b = sorted((geom(item[0]), geom(item[1])))
            if self.predictor.geom_pair_ids([a], [b])[0] < 0:
                raise InvalidInputError(
                    f"ignore entry {tuple(item)!r} is not a geom pair MuJoCo can put in contact "
                    "(its collision filter leaves it out): nothing to ignore; drop it."
                )
            keys.append((a << 32) | b)
        return np.array(geoms, dtype=np.int64), np.array(keys, dtype=np.int64)

    # ------------------------------------------------------------------- gymnasium

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Reset the env, then classify every pair afresh; ``info`` gets ``alarm_pairs`` and
        ``min_tau`` of that classification (no cost: nothing happened yet)."""
        obs, info = self.env.reset(seed=seed, options=options)
        _, self._data, _ = find_mujoco(self.env)  # an env may build a new MjData on reset
        self.predictor.reset(self._data)
        self._runtime.observe_info(info)
        return obs, info

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Step the env and the predictor; ``info`` gets the alarms and the cost."""
        out = self.env.step(action)
        # The predictor's step and info's alarms, min_tau and cost in one native call
        # (Runtime.step_info; the standing pairs named again only when their set changes): the
        # wrapper's own Python was more instructions a step than the predictor's step. The
        # env's tuple is passed on as it is unless the step terminates the episode.
        cost = self.predictor._native_step(self._data, self._step_info, out[4])
        if cost and self.terminate_on_alarm:
            return out[0], out[1], True, out[3], out[4]
        return out


class SafetyShield(gymnasium.Wrapper, gymnasium.utils.RecordConstructorArgs):
    """Shields a MuJoCo env's actions: :class:`~dua_mujoco.Shield` between the action and every
    physics step of ``env.step``.

    The env's own simulation step (gymnasium's ``MujocoEnv._step_mujoco_simulation``: the
    action as ``data.ctrl`` for ``frame_skip`` physics steps) is replaced on the wrapped env by
    one that asks the shield for the controls of each physics step; the shield's control period
    is ``frame_skip``, so the action is its intended controls for the period. The reward is the
    env's own, on the motion that happened. ``info`` gets:

    - ``"shield"``: whether the shield overrode the action at some physics step of this
      ``env.step`` (its failsafe ran);
    - ``"cost_protected_contact"``: the protected geom pairs (``shield.pairs``) found in contact
      at some physics step of this ``env.step``, as a float; ``"cost"`` adds it to the env's own
      ``info["cost"]`` if it has one (safety-gymnasium's convention).

    The shield's guarantee (docs/theory.md, section 10) makes every protected contact find the
    robot at rest while the protected bodies keep their declared bounds; the cost counts every
    contact, at rest or not (the environment may still push into the robot).

    Args:
        env: A MuJoCo-based env whose simulation step is gymnasium's ``MujocoEnv``'s.
        protect: The bodies the robot must not move into (``Shield``'s ``protect``).
        active: False lets every action through unshielded, the cost counted the same (the
            baseline of an A/B).
        **shield_options: Passed to :class:`~dua_mujoco.Shield` (``accel`` is required; ``robot``,
            ``failsafe``, ``stop_time``, ...), except ``period``: it is the env's ``frame_skip``.
            The shield made is the attribute ``shield``.

    Raises:
        InvalidInputError: Not a MuJoCo-based env, ``period`` passed, or a bad shield option.
    """

    def __init__(
        self, env: gymnasium.Env, *, protect: Any, active: bool = True, **shield_options: Any
    ) -> None:
        gymnasium.utils.RecordConstructorArgs.__init__(
            self, protect=protect, active=active, **shield_options
        )
        gymnasium.Wrapper.__init__(self, env)
        model, self._data, frame_skip = find_mujoco(env)
        if "period" in shield_options:
            raise InvalidInputError(
                f"period = {shield_options['period']!r}: here the shield's period is the env's "
                f"frame_skip ({frame_skip} physics steps per env.step): drop period."
            )
        inner = env.unwrapped
        if not callable(getattr(inner, "_step_mujoco_simulation", None)):
            raise InvalidInputError(
                f"{type(inner).__name__} has no _step_mujoco_simulation(ctrl, n_frames): the "
                "shield steps the physics in its place; wrap a gymnasium MujocoEnv."
            )
        if not isinstance(active, bool):
            raise InvalidInputError(f"active = {active!r} is invalid: pass True or False.")
        self.shield = Shield(model, protect=protect, period=frame_skip, **shield_options)
        self.active = active
        self._model = model
        ngeom = int(model.ngeom)
        pairs = self.shield.pairs
        self._ngeom = ngeom
        self._keys = np.unique(pairs.min(axis=1) * ngeom + pairs.max(axis=1))
        self._touched = np.zeros(0, dtype=np.int64)
        # The env's physics step, shielded (an instance attribute shadows the method).
        inner._step_mujoco_simulation = self._simulate  # type: ignore[attr-defined]

    def _simulate(self, ctrl: Any, n_frames: int) -> None:
        """The env's simulation step: each physics step's controls from the shield."""
        model, data = self._model, self._data
        intended = np.asarray(ctrl, dtype=np.float64)
        touched = []
        ngeom = self._ngeom
        for _ in range(int(n_frames)):
            data.ctrl[:] = self.shield(data, intended) if self.active else intended
            mujoco.mj_step(model, data)
            if data.ncon:
                g = np.asarray(data.contact.geom)[: data.ncon]
                keys = np.minimum(g[:, 0], g[:, 1]) * ngeom + np.maximum(g[:, 0], g[:, 1])
                touched.append(keys[np.isin(keys, self._keys)])
        self._touched = np.unique(np.concatenate(touched)) if touched else self._touched[:0]
        mujoco.mj_rnePostConstraint(model, data)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Reset the env, then the shield at its state."""
        obs, info = self.env.reset(seed=seed, options=options)
        _, self._data, _ = find_mujoco(self.env)  # an env may build a new MjData on reset
        self.shield.reset(self._data)
        return obs, info

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Step the env with each physics step shielded; ``info`` gets ``shield`` and the
        cost."""
        before = self.shield.interventions
        obs, reward, terminated, truncated, info = self.env.step(action)
        cost = float(self._touched.size)
        info["shield"] = self.shield.interventions > before
        info[SHIELD_COST_KEY] = cost
        info["cost"] = float(info.get("cost", 0.0)) + cost
        return obs, reward, terminated, truncated, info
