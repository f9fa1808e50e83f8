"""``dua_mujoco.gym.PredictCollisions`` on gymnasium's MuJoCo envs, alone and vectorised."""

from __future__ import annotations

import warnings
from collections import UserDict

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from dua_mujoco import PilotOptions, ScheduleOptions
from dua_mujoco.exceptions import InvalidChoiceError, InvalidInputError
from dua_mujoco.gym import COST_KEY, PredictCollisions, find_mujoco

# Short pilots: the bounds only need to exist, not to be tight.
FAST = {"pilot": PilotOptions(steps=300)}

ANT_ANKLES = ["left_ankle_geom", "right_ankle_geom", "third_ankle_geom", "fourth_ankle_geom"]
HUMANOID_FEET = [("floor", "left_foot"), ("floor", "right_foot")]
# Pusher's object (an unnamed geom) rests on the table from the start.
PUSHER_OBJECT = ("table", "geom18")
# An arm's link (unnamed) a little above the table at the start: within two periods' reach (the
# horizon in effect at frame_skip 5, the taus being on the predictor's grid: docs/theory.md,
# section 8), so it stands in alarm from the first step.
PUSHER_LINK = ("table", "geom13")


def _make(env_id: str, **kwargs) -> PredictCollisions:
    make = {"terminate_when_unhealthy": False} if env_id in ("Ant-v5", "Humanoid-v5") else {}
    return PredictCollisions(gym.make(env_id, **make), **FAST, **kwargs)


def _contacts(env: PredictCollisions) -> set[tuple[str, str]]:
    """The geom pairs in ``data.contact`` now, named as ``info["alarm_pairs"]`` names them."""
    d = env.unwrapped.data  # type: ignore[attr-defined]
    names = [str(n) for n in env.predictor.tables.geom_names]
    pairs = zip(d.contact.geom1[: d.ncon].tolist(), d.contact.geom2[: d.ncon].tolist(), strict=True)
    return {(names[min(a, b)], names[max(a, b)]) for a, b in pairs}


@pytest.mark.parametrize("env_id", ["Ant-v5", "Humanoid-v5", "Pusher-v5"])
def test_check_env_passes_and_info_holds_alarms_and_cost(env_id: str) -> None:
    env = PredictCollisions(gym.make(env_id), **FAST)
    with warnings.catch_warnings():
        # Wrapped env, infinite observation bounds: the checker's advice about the env itself.
        warnings.simplefilter("ignore", UserWarning)
        check_env(env, skip_render_check=True)
    model, _, frame_skip = find_mujoco(env)
    assert frame_skip > 1 and env.predictor.period == frame_skip
    assert env.predictor.dt == pytest.approx(frame_skip * model.opt.timestep)
    _, info = env.reset(seed=3)
    assert "cost" not in info and isinstance(info["min_tau"], float)
    env.action_space.seed(3)
    for _ in range(5):  # the predictor's clock check passes at every env step
        _, _, _, _, info = env.step(env.action_space.sample())
    assert info["alarm_pairs"] == _read_alarms(env)
    assert info["cost"] == info[COST_KEY] == float(bool(info["alarm_pairs"]))
    assert info["min_tau"] == _read_min_tau(env)
    if info["alarm_pairs"]:  # a pair in alarm: its tau is below one period
        assert info["min_tau"] < env.predictor.dt


def _read_alarms(env: PredictCollisions) -> tuple[tuple[str, str], ...]:
    """The geom pairs standing in alarm, read from the whole predictor state (the wrapper
    follows them incrementally), in the order of the model's geom pairs."""
    state = env.predictor.pair_state()
    standing = np.flatnonzero(state.alarm_state() & state.active)
    names = [str(n) for n in env.predictor.tables.geom_names]
    g1, g2 = env.predictor.sphere_pair_geoms
    pairs = zip(g1[standing].tolist(), g2[standing].tolist(), strict=True)
    ids = sorted({(min(a, b), max(a, b)) for a, b in pairs})
    return tuple((names[a], names[b]) for a, b in ids)


def _read_min_tau(env: PredictCollisions) -> float:
    state = env.predictor.pair_state()
    ids = np.flatnonzero(state.active)
    left = state.last_tau_of(ids) - env.predictor.dt * (state.step_count - state.last_step_of(ids))
    return max(float(np.min(left, initial=np.inf)), 0.0)


@pytest.mark.parametrize(
    "options",
    [
        {},
        {"schedule": ScheduleOptions(kind="dua")},
        {"schedule": ScheduleOptions(kind="select-all")},
        {"pairs": "pruned"},
    ],
    ids=["default", "schedule=dua", "schedule=select-all", "pairs=pruned"],
)
def test_alarms_and_min_tau_follow_the_predictor_at_every_step(options: dict) -> None:
    """What the wrapper follows step by step equals a full read of the predictor's state, also
    across switches of pairs between steps and rebuilds of pruned pairs."""
    env = _make("Humanoid-v5", **options)
    _, info = env.reset(seed=4)
    assert info["alarm_pairs"] == _read_alarms(env) and info["min_tau"] == _read_min_tau(env)
    env.action_space.seed(4)
    for k in range(40):
        if k == 20:
            assert env.predictor.set_active_bodies("left_thigh", on=False) > 0
        _, _, _, _, info = env.step(env.action_space.sample())
        assert info["alarm_pairs"] == _read_alarms(env)
        assert info["min_tau"] == pytest.approx(_read_min_tau(env), abs=1e-12)


@pytest.mark.parametrize(
    ("env_id", "ignore"), [("Ant-v5", ANT_ANKLES), ("Humanoid-v5", HUMANOID_FEET)]
)
def test_every_contact_onset_of_a_counted_pair_was_alarmed(env_id: str, ignore: list) -> None:
    """The guarantee seen through the wrapper: a counted geom pair that comes into contact at
    an env step stands in ``info["alarm_pairs"]`` at that step; ignored pairs never show."""
    env = _make(env_id, ignore=ignore)
    ignored = {frozenset(p) for p in ignore if isinstance(p, tuple)}
    ignored_geoms = {p for p in ignore if isinstance(p, str)}

    def counted(pair: tuple[str, str]) -> bool:
        return frozenset(pair) not in ignored and not set(pair) & ignored_geoms

    _, info = env.reset(seed=0)
    env.action_space.seed(0)
    before = _contacts(env)
    onsets = 0
    for _ in range(60):
        _, _, _, _, info = env.step(env.action_space.sample())
        alarmed = set(info["alarm_pairs"])
        assert all(counted(p) for p in alarmed)
        now = _contacts(env)
        for pair in now - before:
            if not counted(pair):
                continue
            onsets += 1
            assert pair in alarmed, f"{pair} touched with no standing alarm"
        before = now
    assert onsets > 0  # the assertion above was exercised


def test_ignore_drops_resting_contact_from_the_alarms_and_the_cost() -> None:
    plain = _make("Pusher-v5")
    _, info = plain.reset(seed=0)
    assert PUSHER_OBJECT in info["alarm_pairs"]  # the object rests on the table
    quiet = _make("Pusher-v5", ignore=[PUSHER_OBJECT, PUSHER_LINK])
    _, info = quiet.reset(seed=0)
    assert PUSHER_OBJECT not in info["alarm_pairs"]
    _, _, _, _, info = quiet.step(np.zeros(quiet.action_space.shape, dtype=np.float32))
    assert info["alarm_pairs"] == () and info["cost"] == 0.0 and info["min_tau"] > 0.0
    # A single name ignores every pair of that geom; the env's spec rebuilds the wrapper.
    everything = _make("Pusher-v5", ignore="table")
    _, info = everything.reset(seed=0)
    assert info["alarm_pairs"] == ()
    assert everything.spec is not None
    again = everything.spec.make()
    assert isinstance(again, PredictCollisions)
    assert again.reset(seed=0)[1]["alarm_pairs"] == ()


def test_cost_new_counts_pairs_whose_alarm_started() -> None:
    env = _make("Humanoid-v5", cost="new", ignore=HUMANOID_FEET)
    _, info = env.reset(seed=1)
    env.action_space.seed(1)
    previous = set(info["alarm_pairs"])
    total = 0.0
    for _ in range(30):
        _, _, _, _, info = env.step(env.action_space.sample())
        now = set(info["alarm_pairs"])
        assert info["cost"] == float(len(now - previous))
        total += info["cost"]
        previous = now
    assert total > 0


def test_cost_horizon_is_min_tau_below_the_horizon() -> None:
    horizon = 0.03  # between two of the grid's taus (whole periods of 50 ms, shaved)
    env = _make("Ant-v5", cost="horizon", cost_horizon=horizon, ignore=ANT_ANKLES)
    env.reset(seed=2)
    env.action_space.seed(2)
    seen = set()
    for _ in range(40):
        _, _, _, _, info = env.step(env.action_space.sample())
        assert info["cost"] == float(info["min_tau"] < horizon)
        seen.add(info["cost"])
    assert seen == {0.0, 1.0}
    # The runtime writes the cost as constructed: changing it afterwards would be silently ignored.
    assert (env.cost, env.cost_horizon) == ("horizon", horizon)
    with pytest.raises(AttributeError):
        env.cost = "alarm"  # type: ignore[misc]


def test_terminate_on_alarm_ends_the_episode_at_the_first_cost() -> None:
    env = _make("Pusher-v5", ignore=[PUSHER_OBJECT, PUSHER_LINK], terminate_on_alarm=True)
    free = _make("Pusher-v5", ignore=[PUSHER_OBJECT, PUSHER_LINK])
    for e in (env, free):
        e.reset(seed=2)
        e.action_space.seed(2)
    quiet_steps = 0
    for _ in range(100):
        action = env.action_space.sample()
        _, _, terminated, _, info = env.step(action)
        _, _, free_terminated, _, free_info = free.step(action)
        assert not free_terminated
        assert info["cost"] == free_info["cost"]  # the option changes nothing else
        if info["cost"] > 0:
            assert terminated
            break
        assert not terminated
        quiet_steps += 1
    else:
        pytest.fail("no alarm in 100 steps: the test needs one")
    assert quiet_steps > 0  # steps without an alarm did not end the episode


class _CostlyEnv(gym.Wrapper):
    """An env that reports a cost of its own, as safety-gymnasium's do, in an info of type
    ``mapping`` (the wrapper writes info natively: a dict, or any mapping)."""

    def __init__(self, env: gym.Env, mapping: type) -> None:
        super().__init__(env)
        self.mapping = mapping

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        info = self.mapping(info)
        info["cost"] = np.float32(0.5)
        return obs, reward, terminated, truncated, info


@pytest.mark.parametrize("mapping", [dict, UserDict])
def test_cost_adds_to_a_cost_the_env_reports(mapping: type) -> None:
    env = PredictCollisions(_CostlyEnv(gym.make("Pusher-v5"), mapping), **FAST)  # object on table
    env.reset(seed=0)
    _, _, _, _, info = env.step(env.action_space.sample())
    assert isinstance(info, mapping) and info["alarm_pairs"] and info["min_tau"] == 0.0
    assert info[COST_KEY] == 1.0 and info["cost"] == 1.5 and type(info["cost"]) is float


def test_vector_env_steps_a_predictor_per_env_and_resets_them() -> None:
    envs = gym.vector.SyncVectorEnv(
        [lambda: _make("Ant-v5", ignore=ANT_ANKLES, terminate_on_alarm=True) for _ in range(2)]
    )
    _, infos = envs.reset(seed=[0, 1])
    assert infos["min_tau"].shape == (2,)
    envs.action_space.seed(0)
    ended = resets = 0
    for _ in range(60):
        _, _, terminated, _, infos = envs.step(envs.action_space.sample())
        if "cost" in infos:
            assert infos["cost"].shape == (2,) and infos["cost"].dtype == float
            assert infos["alarm_pairs"].dtype == object
            for i in np.flatnonzero(infos["_cost"]):
                assert infos["cost"][i] == float(bool(infos["alarm_pairs"][i]))
        # Autoreset: the step after a termination resets that env (its info has no cost);
        # the re-classified predictor then steps on without a clock error.
        resets += int(np.count_nonzero(infos["_min_tau"] & ~infos.get("_cost", False)))
        ended += int(np.count_nonzero(terminated))
    envs.close()
    assert ended > 0 and resets > 0


def test_bad_input_is_refused_with_the_fix() -> None:
    with pytest.raises(InvalidInputError, match=r"unwrapped\.model"):
        PredictCollisions(gym.make("CartPole-v1"))
    pusher = gym.make("Pusher-v5")
    with pytest.raises(InvalidInputError, match="frame_skip"):
        PredictCollisions(pusher, period=2)
    with pytest.raises(InvalidChoiceError, match="'alarm', 'new', 'horizon'"):
        PredictCollisions(pusher, cost="contacts")
    with pytest.raises(InvalidInputError, match="cost_horizon"):
        PredictCollisions(pusher, cost="horizon")
    with pytest.raises(InvalidInputError, match="cost_horizon"):
        PredictCollisions(pusher, cost="alarm", cost_horizon=0.1)
    with pytest.raises(InvalidInputError, match="finite"):
        PredictCollisions(pusher, cost="horizon", cost_horizon=-1.0)
    with pytest.raises(InvalidChoiceError, match="'table'"):
        PredictCollisions(pusher, ignore=["tabel"], **FAST)
    with pytest.raises(InvalidInputError, match="collision filter"):
        PredictCollisions(pusher, ignore=[("e1", "e2")], **FAST)
    with pytest.raises(InvalidInputError, match="name, name"):
        PredictCollisions(pusher, ignore=[("table",)], **FAST)


# ---------------------------------------------------------------------------- SafetyShield

# Pusher's arm pressed down (its shoulder lift at full control) drives the wrist into the table.
PUSH_DOWN = np.array([0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0])


def test_the_safety_shield_keeps_pushers_arm_off_the_table() -> None:
    """Pressed down, Pusher's arm hits the table unshielded (``active=False``: the cost counted,
    nothing shielded); under ``SafetyShield`` (the table protected) no step's cost is > 0, the
    shield intervened, and every physics step ran under the guarantee. ``check_env`` passes on
    the wrapper."""
    from dua_mujoco.gym import SHIELD_COST_KEY, SafetyShield

    env = SafetyShield(gym.make("Pusher-v5"), protect=["world"], accel=100.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        check_env(env, skip_render_check=True)
    plain = SafetyShield(gym.make("Pusher-v5"), protect=["world"], accel=100.0, active=False)
    plain.reset(seed=0)
    steps = [plain.step(PUSH_DOWN)[4] for _ in range(100)]
    assert sum(info["cost"] for info in steps) > 0 and not any(info["shield"] for info in steps)
    _, info = env.reset(seed=0)
    assert env.shield.counts["steps"] == 0
    costs, shielded = [], []
    for _ in range(100):
        _, _, _, _, info = env.step(PUSH_DOWN)
        costs.append(info["cost"])
        shielded.append(info["shield"])
        assert info[SHIELD_COST_KEY] == info["cost"]
    assert max(costs) == 0.0
    assert any(shielded) and not all(shielded)
    counts = env.shield.counts
    assert counts["interventions"] > 0 and counts["unguaranteed"] == 0
    assert counts["steps"] == 100 * env.unwrapped.frame_skip  # type: ignore[attr-defined]


def test_the_safety_shield_cost_counts_protected_contacts() -> None:
    """A failsafe that does not stop (it keeps pressing down): no rollout comes to rest, so the
    shield runs that failsafe, unguaranteed, and the arm hits the table: the cost counts it."""
    from dua_mujoco.gym import SafetyShield

    env = SafetyShield(
        gym.make("Pusher-v5"),
        protect=["world"],
        accel=100.0,
        failsafe=lambda model, data: PUSH_DOWN.copy(),  # a "failsafe" that does not stop
    )
    env.reset(seed=0)
    cost = sum(env.step(PUSH_DOWN)[4]["cost"] for _ in range(100))
    assert cost > 0.0
    assert env.shield.counts["unguaranteed"] > 0


def test_the_safety_shield_takes_its_period_from_the_env() -> None:
    from dua_mujoco.gym import SafetyShield

    with pytest.raises(InvalidInputError, match="drop period"):
        SafetyShield(gym.make("Pusher-v5"), protect=["world"], accel=100.0, period=3)
    with pytest.raises(InvalidInputError, match="protect: 'tabel' names no body"):
        SafetyShield(gym.make("Pusher-v5"), protect=["tabel"], accel=100.0)
    env = SafetyShield(gym.make("Pusher-v5"), protect=["world"], accel=100.0)
    assert env.shield.period == env.unwrapped.frame_skip  # type: ignore[attr-defined]


def test_a_failed_wrapped_step_raises_the_predictors_error() -> None:
    """The wrapper steps the runtime itself (one native call): a step that fails raises what
    Predictor.step raises, naming the cause, not the native core's bare error."""
    from dua_mujoco.exceptions import SchedulerError

    env = _make("Pusher-v5")
    env.reset(seed=0)
    env.unwrapped.data.time += 1.0  # type: ignore[attr-defined]
    with pytest.raises(SchedulerError, match=r"data\.time advanced"):
        env.step(env.action_space.sample())


def test_terminate_on_alarm_set_after_construction_takes_effect() -> None:
    """The step reads the option as it stands, not as it was built."""
    env = _make("Pusher-v5")  # the object rests on the table: cost 1 from the first step
    env.reset(seed=0)
    assert not env.step(env.action_space.sample())[2]
    env.terminate_on_alarm = True
    _, _, terminated, _, info = env.step(env.action_space.sample())
    assert info["cost"] > 0 and terminated and env.terminate_on_alarm is True


def test_an_info_kept_from_an_earlier_step_does_not_change() -> None:
    """Each step's info is the env's own new dict with new values in it: a user who keeps one
    (a replay buffer) sees the values of its step after later steps."""
    env = _make("Pusher-v5", cost="new", ignore=[PUSHER_OBJECT, PUSHER_LINK])
    env.reset(seed=1)
    env.action_space.seed(1)
    kept = []
    for _ in range(40):
        info = env.step(env.action_space.sample())[4]
        kept.append((info, dict(info)))
    assert len({id(info) for info, _ in kept}) == len(kept)
    for info, snapshot in kept:
        assert info == snapshot
    assert len({info["min_tau"] for info, _ in kept}) > 1  # the values did move


def test_a_wrapped_step_goes_back_to_the_envs_mjdata() -> None:
    """The wrapper's step binds the env's MjData again when its predictor was reset on another
    one in between (the predictor is public): the step reads the env's state and clock, not the
    other MjData's (whose time stands still: a clock error)."""
    import mujoco

    env = _make("Pusher-v5")
    env.reset(seed=0)
    model = env.unwrapped.model  # type: ignore[attr-defined]
    other = mujoco.MjData(model)
    mujoco.mj_forward(model, other)
    env.predictor.reset(other)
    env.action_space.seed(0)
    for _ in range(3):
        _, _, _, _, info = env.step(env.action_space.sample())
    assert info["alarm_pairs"] == _read_alarms(env)
    assert env.predictor._data is env.unwrapped.data  # type: ignore[attr-defined]
