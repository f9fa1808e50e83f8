"""The rollout's view and the evasive failsafe.

A failsafe that reads more than the robot's state (where an obstacle is) must read, in the run,
what its rollout read: the shield calls it there on the rollout's view (``Shield.view``: the
plan's knot, the robot's coordinates the run's), so the run repeats the rollout it verified; a
failsafe reading the live state instead leaves its plans, and the shield's check at every step
catches it (docs/theory.md, section 10, (S2)). The library's evasive failsafe
(:class:`~dua_mujoco.shield.failsafe.Evade`, native) and the same law as a Python policy
(the reference ``tests/reference_evade.py``) decide alike and keep the guarantee on
``mobile_cell``.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np
import pytest
from mjcf import mjcf, motors
from reference_evade import EvadePolicy

from dua_mujoco import Shield, _core
from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.experiments.shield.bench import scene_failsafe, shield_layer
from dua_mujoco.experiments.shield.episodes import NoLayer, SceneSetup, run_episode
from dua_mujoco.experiments.shield.evade import native
from dua_mujoco.models.cells import SHIELD_SCENES
from dua_mujoco.shield.failsafe import Brake, Evade

SEEDS, DURATION = range(8), 4.0

H = 0.002


def _leader(t: float) -> tuple[float, float]:
    """A walker 0.1 m off the base's line, walking ahead of it along +x: from 1 m out, 0.8 m/s^2
    up to 0.4 m/s (within its declared 1 m/s^2, 0.5 m/s)."""
    s = 0.4 * t * t if t < 0.5 else 0.1 + 0.4 * (t - 0.5)
    return (1.0 + s, 0.1)


class Steer:
    """A failsafe policy steering the base away from the walker as it reads it: from the data it
    is given (the rollout's, the view), or from ``live`` (the run's data: the mutant)."""

    def __init__(self, model: mujoco.MjModel, live: mujoco.MjData | None = None) -> None:
        self.brake = Brake(model)
        self.live = live
        self.view: mujoco.MjData | None = None  # the shield's (no cycle through the shield)
        self.run: mujoco.MjData | None = None
        self.views = self.moved = 0  # run calls (on the view), and those it held elsewhere

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """The brake, its planar velocity turned away from the walker."""
        if self.view is not None and data is self.view:
            self.views += 1
            assert self.run is not None
            self.moved += not np.array_equal(data.mocap_pos, self.run.mocap_pos)
        seen = (self.live if self.live is not None else data).mocap_pos[0]
        vx, vy = float(data.qvel[0]), float(data.qvel[1])
        s = max(abs(vx), abs(vy))
        if s <= 0.01:
            return self.brake(model, data)
        gx, gy = data.qpos[0] - seen[0], data.qpos[1] - seen[1]
        n = max(abs(gx), abs(gy))
        return self.brake.toward(data, [0.9 * s * gx / n, 0.9 * s * gy / n])


def _ball() -> mujoco.MjModel:
    """A 10 kg ball on planar slides ("x", "y", velocity actuators) and a walker (mocap)."""
    return mujoco.MjModel.from_xml_string(
        mjcf(
            '<body name="robot"><joint name="x" type="slide" axis="1 0 0" damping="1"/>'
            '<joint name="y" type="slide" axis="0 1 0" damping="1"/>'
            '<geom type="sphere" size="0.2" mass="10"/></body>',
            '<body name="walker" mocap="true" pos="1 0.1 0.3">'
            '<geom type="cylinder" size="0.25 0.5"/></body>',
            option=f'timestep="{H}" gravity="0 0 0"',
            actuator=motors(
                "x", "y", kind="velocity", kv="300", ctrlrange="-2 2", forcerange="-40 40"
            ),
        ),
    )


def _shield(
    model: mujoco.MjModel, failsafe: Evade | Callable[..., Any], rest_speed: float = 0.01
) -> Shield:
    """The walker scene's shield (protect the walker, a period of 5 steps) with ``failsafe``."""
    return Shield(
        model,
        protect=["walker"],
        period=5,
        accel={"walker": 1.0, "*": 10.0},
        speed={"walker": 0.5, "*": 2.0},
        stop_time=0.5,
        rest_speed=rest_speed,
        screen=False,
        failsafe=failsafe,
    )


def _follow(
    failsafe: Callable[[mujoco.MjModel, mujoco.MjData], object],
) -> tuple[Shield, int, object]:
    """A 10 kg ball on planar slides driving +x at 1 m/s behind the leading walker (protected),
    3 s under the shield with the failsafe ``failsafe(model, data)`` makes (the run's data);
    the shield, its guaranteed steps and the failsafe."""
    model = _ball()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    policy = failsafe(model, data)
    shield = _shield(model, policy)  # type: ignore[arg-type]
    if isinstance(policy, Steer):
        policy.view, policy.run = shield.view, data
    shield.reset(data)
    guaranteed = 0
    for k in range(1500):
        data.mocap_pos[0, :2] = _leader(k * H)
        data.ctrl[:] = shield(data, np.array([1.0, 0.0]))
        guaranteed += shield.guaranteed
        mujoco.mj_step(model, data)
    return shield, guaranteed, policy


def _evade(model: mujoco.MjModel, data: mujoco.MjData) -> Evade:
    return Evade(model, planar=("x", "y"), away_from=["walker"])


def _steer(model: mujoco.MjModel, data: mujoco.MjData) -> Steer:
    return Steer(model)


@pytest.mark.parametrize("failsafe", [None, _evade, _steer], ids=["brake", "evade", "policy"])
def test_a_failsafe_reading_the_obstacles_in_its_data_repeats_its_rollouts(
    failsafe: object,
) -> None:
    """The base catches up with the walker and is stopped again and again; a failsafe that reads
    the walker from the data the shield gives it (the native Evade, a Python policy) keeps to its
    verified plans as the brake does: no plan or hold break, every step guaranteed. The policy's
    run calls were on the view, whose walker stood where the rollout had it, not where it was
    (a view holding the live state fails this: mutant ``shield-view-is-the-run``)."""
    make = failsafe if failsafe is not None else (lambda model, data: None)
    shield, guaranteed, policy = _follow(make)  # type: ignore[arg-type]
    counts = shield.counts
    assert counts["interventions"] > 300, counts
    broken = [counts[k] for k in ("plan_breaks", "hold_breaks", "stop_breaks", "unguaranteed")]
    assert broken == [0, 0, 0, 0], counts
    assert guaranteed == 1500
    assert (shield.view is None) == (failsafe is None)
    if isinstance(policy, Steer):
        assert policy.views > 300 and policy.moved > 100, (policy.views, policy.moved)


def test_a_failsafe_reading_the_live_state_leaves_its_plans_and_the_shield_sees_it() -> None:
    """The mutant policy reads the walker where it is now (the run's data) instead of in the
    data it is given: its run leaves the rollouts it was verified on, and the shield's check
    says so at once (plan breaks, steps without a guarantee); a shield that did not check the
    run against its plan would guarantee every step here."""
    shield, guaranteed, _ = _follow(lambda model, data: Steer(model, live=data))
    counts = shield.counts
    assert counts["plan_breaks"] > 0, counts
    assert counts["unguaranteed"] > 0 and guaranteed < 1500, counts


@pytest.mark.parametrize("sideways", [False, True])
def test_the_native_evasive_failsafe_is_the_python_policy(sideways: bool) -> None:
    """On 2,000 random states of mobile_cell (the base anywhere, at any speed, the walkers and
    carts of 50 episodes), the native Evade and the Python policy of tests/reference_evade.py
    give the same controls, bit for bit (steering away or across the velocity); driving +x with
    a walker ahead on +y they brake x as the brake does and push y away (the brake leaves y
    alone); at rest they are the brake."""
    setup = SceneSetup.of("mobile_cell")
    model = setup.model
    fast = native(setup, sideways=sideways)
    slow = EvadePolicy.of(setup, sideways=sideways)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    for i in range(2000):
        setup.scene.episode(model, data, i % 50)
        data.qpos[:3] = rng.uniform(-2.5, 2.5, 3)
        data.qvel[:3] = rng.uniform(-1.0, 1.0, 3)
        mujoco.mj_forward(model, data)
        np.testing.assert_array_equal(fast(model, data), slow(model, data))
    walker = model.body("walker0").mocapid[0]
    data.mocap_pos[:, :2] = [[2.5, 2.0], [-2.5, 2.0], [-2.5, -2.0], [2.5, -2.0]]
    data.mocap_pos[walker, :2] = [0.4, 0.6]
    data.qpos[:3] = 0.0
    data.qvel[:3] = [0.8, 0.0, 0.0]
    mujoco.mj_forward(model, data)
    rolled = copy.deepcopy(model)
    ux, uy = slow.away(0.0, 0.0, data.mocap_pos[slow.mocap, :2].tolist())
    assert uy == -1.0 and ux < 0.0
    ctrl, brake = fast(rolled, data), setup.brake(rolled, data)
    x, y = setup.brake.actuators[:2]
    assert ctrl[x] == pytest.approx(brake[x])  # x at the brake's force limit either way
    assert brake[y] == pytest.approx(0.0, abs=1e-9) and ctrl[y] < -0.1
    data.qvel[:3] = [0.005, -0.005, 0.0]
    np.testing.assert_array_equal(fast(rolled, data), setup.brake(rolled, data))


def test_evade_refuses_what_it_cannot_steer() -> None:
    """Errors name the bad value: a hinge as a planar joint, a gain of 1, another robot's."""
    setup = SceneSetup.of("mobile_cell")
    model = setup.model
    with pytest.raises(InvalidInputError, match="two distinct slide DOFs"):
        Evade(model, planar=("base_x", "base_yaw"), away_from=["walker*"])
    with pytest.raises(InvalidInputError, match=r"gain must be in \[0, 1\)"):
        Evade(model, planar=("base_x", "base_y"), away_from=["walker*"], gain=1.0)
    with pytest.raises(InvalidInputError, match="planar joint 'nope'"):
        Evade(model, planar=("base_x", "nope"), away_from=["walker*"])
    evade = Evade(model, planar=("base_x", "base_y"), away_from=["walker*"], actuators=[0, 1])
    with pytest.raises(InvalidInputError, match="an Evade of actuators"):
        shield_layer(setup, "shield", failsafe=evade)


def _controls(setup: SceneSetup, shield: Shield, seed: int, duration: float) -> np.ndarray:
    """The controls applied at every physics step of an episode under ``shield``."""
    out: list[np.ndarray] = []

    def on_step(data: mujoco.MjData, step: int) -> None:
        out.append(data.ctrl.copy())

    run_episode(setup, shield, "shield", seed, duration=duration, on_step=on_step)
    return np.array(out)


def test_each_scene_shield_has_the_failsafe_a_user_would_give_it() -> None:
    """The benchmark's ``shield`` is the scene's shield as configured (bench.FAILSAFES): on
    mobile_cell the native evasive failsafe steering sideways at gain 0.9, on the arm cells the
    brake; ``shield-brake`` is the brake on every scene, and ``failsafe=`` overrides either."""
    for scene in SHIELD_SCENES:
        setup = SceneSetup.of(scene)
        failsafe = scene_failsafe(setup)
        if scene == "mobile_cell":
            assert isinstance(failsafe, Evade)
            assert failsafe.args[5:] == (0.9, 0.01, True)  # gain, still, sideways
            assert shield_layer(setup, "shield").view is not None  # the run calls it on the view
            assert shield_layer(setup, "shield-noscreen").view is not None
        else:
            assert failsafe is None
            assert shield_layer(setup, "shield").view is None
        assert shield_layer(setup, "shield-brake").view is None
        assert shield_layer(setup, "shield", failsafe=None).view is None
    # In the run: mobile_cell's shield decides as the one given that Evade explicitly, not as
    # the brake nor as the straight-away Evade (seed 1: they part within 2 s).
    setup = SceneSetup.of("mobile_cell")
    ctrl = _controls(setup, shield_layer(setup, "shield"), 1, 2.0)
    sideways = native(setup, gain=0.9, sideways=True)
    given = _controls(setup, shield_layer(setup, "shield-brake", failsafe=sideways), 1, 2.0)
    np.testing.assert_array_equal(ctrl, given)
    brake = _controls(setup, shield_layer(setup, "shield-brake"), 1, 2.0)
    straight = _controls(setup, shield_layer(setup, "shield", failsafe=native(setup)), 1, 2.0)
    assert not np.array_equal(ctrl, brake)
    assert not np.array_equal(ctrl, straight)


@pytest.mark.slow
@pytest.mark.parametrize("form", ["native", "policy", "sideways"])
def test_an_evasive_failsafe_keeps_the_guarantee_and_its_rollouts(form: str) -> None:
    """Over sampled mobile_cell episodes, the shield with the evasive failsafe has no free moving
    contact where the unshielded base has several; in the episodes nothing touched, the run kept
    to its verified plans (no plan, hold or stop break; every step guaranteed)."""
    setup = SceneSetup.of("mobile_cell")
    free = shielded = clean = 0
    for seed in SEEDS:
        free += run_episode(setup, NoLayer(), "none", seed, duration=DURATION).moving_free
        if form == "policy":
            failsafe: Evade | EvadePolicy = EvadePolicy.of(setup)
        else:
            failsafe = native(setup, sideways=form == "sideways")
        shield = shield_layer(setup, "shield", failsafe=failsafe)
        result = run_episode(setup, shield, "evade", seed, duration=DURATION)
        shielded += result.moving_free
        counts = shield.counts
        assert counts["stop_breaks"] == 0, (seed, counts)
        if result.first_touch is None and result.violations == 0:
            clean += 1
            broken = [counts[k] for k in ("plan_breaks", "hold_breaks", "unguaranteed")]
            assert broken == [0, 0, 0], (seed, counts)
            assert counts["interventions"] > 0, seed
    assert free >= 3
    assert shielded == 0
    assert clean >= 2


def test_an_evade_reads_the_robot_from_the_one_brake_it_owns() -> None:
    """An Evade's robot (its actuators, the bodies of the trees they move) is its native brake's,
    the same as a Brake of those actuators gives; it keeps no second brake beside it, and a
    shield given it takes its robot from it."""
    setup = SceneSetup.of("mobile_cell")
    evade = native(setup)
    np.testing.assert_array_equal(evade.actuators, setup.brake.actuators)
    np.testing.assert_array_equal(evade.robot_bodies, setup.brake.bodies)
    assert evade.native.dofs == setup.brake.dofs.tolist()
    assert not hasattr(evade, "brake")
    shield = shield_layer(setup, "shield", failsafe=evade)
    np.testing.assert_array_equal(shield.robot_bodies, setup.brake.bodies)
    np.testing.assert_array_equal(shield.robot_actuators, setup.brake.actuators)


def test_evade_refuses_bad_shapes_naming_them() -> None:
    """planar of three names, room of three values or inverted, radius of the wrong length:
    each refused with the value given (not numpy's reshape or broadcast error, not ignored)."""
    model = _ball()
    with pytest.raises(InvalidInputError, match=r"planar = \('x', 'y', 'x'\) is invalid"):
        Evade(model, planar=("x", "y", "x"), away_from=["walker"])  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match=r"room of shape \(3,\) is invalid"):
        Evade(model, planar=("x", "y"), away_from=["walker"], room=[0, 1, 2])
    for room in ([1, 0, 0, 1], [0, 1, 1, 1]):
        with pytest.raises(InvalidInputError, match=r"xlo < xhi and ylo < yhi"):
            Evade(model, planar=("x", "y"), away_from=["walker"], room=room)
    with pytest.raises(InvalidInputError, match=r"radius of shape \(2,\).*names 1 bodies"):
        Evade(model, planar=("x", "y"), away_from=["walker"], radius=[0.2, 0.3])
    evade = Evade(model, planar=("x", "y"), away_from=["walker"], room=[-5, 5, -5, 5])
    x, y, bodies, radius, room, gain, still, sideways = evade.args
    acts = evade.actuators
    with pytest.raises(InvalidInputError, match="same length, not 1 and 2"):
        _core.Evade(model, acts, H, x, y, bodies, [0.2, 0.3], room, gain, still, sideways)
    with pytest.raises(InvalidInputError, match=r"\(xlo, xhi, ylo, yhi\), not 3 values"):
        _core.Evade(model, acts, H, x, y, bodies, radius, [0.0, 1.0, 2.0], gain, still, sideways)


def test_the_shield_refuses_an_evade_it_cannot_verify() -> None:
    """An Evade that still steers below the shield's rest speed (past the rest knot it must be
    the brake), or one of another model, is refused, naming both values."""
    model = _ball()
    slow = Evade(model, planar=("x", "y"), away_from=["walker"], still=0.01)
    with pytest.raises(InvalidInputError, match=r"still = 0.01 below .* rest_speed = 0.02"):
        _shield(model, slow, rest_speed=0.02)
    _shield(model, slow, rest_speed=0.01)  # still == rest_speed: the brake at the rest knot
    other = mujoco.MjModel.from_xml_string(
        mjcf(
            '<body name="robot"><joint name="x" type="slide" axis="1 0 0"/>'
            '<joint name="y" type="slide" axis="0 1 0"/><geom type="sphere" size="0.2"/></body>'
            '<body name="walker" mocap="true" pos="1 0.1 0.3"><geom type="sphere" size="0.2"/>'
            '</body><body name="post" pos="0 2 0"><geom type="box" size="0.1 0.1 0.1"/></body>',
            actuator=motors("x", "y", kind="velocity", kv="300", ctrlrange="-2 2"),
        ),
    )
    foreign = Evade(other, planar=("x", "y"), away_from=["walker"])
    with pytest.raises(InvalidInputError, match=r"another model \(nbody, nv, nu = \(4, 2, 2\)"):
        _shield(model, foreign)


def test_the_native_shield_refuses_evade_without_a_view() -> None:
    """Evade reads the obstacles from the data it is given; without the rollout's view the
    native shield would run it on the live state in the run, off the rollouts it verified."""
    model = _ball()
    evade = Evade(model, planar=("x", "y"), away_from=["walker"])
    shield = _shield(model, evade)
    native_args = [
        _core.Tables.build(model, shield.predictor.table_arrays),
        model,
        *shield._keep,
        shield.robot_actuators,
        shield.robot_bodies,
        np.ascontiguousarray(shield.pairs[:, 0]),
        np.ascontiguousarray(shield.pairs[:, 1]),
        5, 0.0, 0.01, 0.5, -1.0, False, evade.time_constant, None,
    ]  # fmt: skip
    _core.Shield(*native_args, shield.view, evade.args)  # with the view: accepted
    with pytest.raises(InvalidInputError, match="evade needs the rollout's view"):
        _core.Shield(*native_args, None, evade.args)
