"""The shield's scenes (dua_mujoco.models.cells): scripts within their declared bounds, tasks
that make progress, protect lists that name bodies, arm B's measured bounds."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from dua_mujoco.experiments.shield.bounds import measure_arm_b
from dua_mujoco.experiments.shield.episodes import NoLayer, SceneSetup, run_episode
from dua_mujoco.models.cells import ARM_ACCEL, ARM_B_BOUNDS, ARM_SPEED, SHIELD_SCENES, ArmTask
from dua_mujoco.models.motion import Move, Timeline, trapezoid
from dua_mujoco.models.people import PERSON_BOUNDS, Crowd, PersonScript, declared_bounds


def _discrete(positions: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Chord speeds and discrete accelerations (second differences over h^2) of (n, 3) rows."""
    chord = np.diff(positions, axis=0) / h
    return np.linalg.norm(chord, axis=1), np.linalg.norm(np.diff(chord, axis=0), axis=1) / h


def test_a_move_keeps_its_caps_and_arrives() -> None:
    for length, vmax, amax in [(3.0, 1.6, 2.0), (0.05, 1.6, 2.0), (1.0, 2.0, 5.0)]:
        move = Move.make([0.0, 0.0, 0.0], [length, 0.0, 0.0], 0.3, vmax, amax)
        t = np.arange(0.0, move.t1 + 0.5, 0.002)
        pos = np.array([move.state(x)[0] for x in t])
        vel = np.array([move.state(x)[1] for x in t])
        speed, accel = _discrete(pos, 0.002)
        assert speed.max() <= vmax * (1 + 1e-9)
        assert accel.max() <= amax * (1 + 1e-6)
        assert np.allclose(pos[-1], [length, 0, 0]) and not vel[-1].any()
        # The reported velocity is the derivative of the position.
        assert np.allclose(np.gradient(pos[:, 0], t), vel[:, 0], atol=amax * 0.002)
    assert trapezoid(0.05, 1.6, 2.0)[1] == 0.0  # too short to cruise: a triangle


def test_a_timeline_refuses_overlapping_moves() -> None:
    line = Timeline([0.0])
    end = line.go([1.0], at=0.0, vmax=1.0, amax=1.0)
    with pytest.raises(ValueError, match="overlap"):
        line.go([2.0], at=end - 0.1, vmax=1.0, amax=1.0)


@pytest.mark.parametrize("scene", ["person_cell", "mobile_cell"])
def test_the_scripts_never_exceed_their_declared_bounds(scene: str) -> None:
    """Finite differences at the physics step of every scripted body's pose, many seeds: the
    chord speed and the second difference stay within the declared bounds (ISO 13855's 1.6 m/s
    walking and 2.0 m/s reaching for the person)."""
    model = SHIELD_SCENES[scene].model()
    h = float(model.opt.timestep)
    seen = {}
    for seed in range(60):
        script = (
            PersonScript(model, seed) if scene == "person_cell" else Crowd(model, seed, duration=12)
        )
        bounds = declared_bounds(list(script.timelines))
        t = np.arange(0.0, script.t_end + 0.2, h)
        for name in script.timelines:
            pos = np.array([script.state(name, x)[0] for x in t])
            speed, accel = _discrete(pos, h)
            assert speed.max() <= bounds[name].speed * (1 + 1e-9), (seed, name)
            assert accel.max() <= bounds[name].accel * (1 + 1e-6), (seed, name)
            seen[name] = max(seen.get(name, 0.0), speed.max() / bounds[name].speed)
    # The scripts use their bounds (not a vacuous test): each body comes within 20 % of its speed.
    assert min(seen.values()) > 0.8


def test_the_person_walks_in_reaches_into_the_workspace_and_leaves() -> None:
    model = SHIELD_SCENES["person_cell"].model()
    for seed in range(20):
        script = PersonScript(model, seed)
        start = script.state("person", 0.0)[0]
        assert 3.0 <= start[0] <= 4.0
        # At the end of the reach, the hand's tip is at the drawn point of the workspace.
        arm = script.timelines["person_arm"]
        t_reached = arm.moves[0].t1
        tip = script.state("person_arm", t_reached)[0] + np.array([-0.55, 0.0, -0.375])
        assert np.allclose(tip, script.reach_to)
        assert 0.1 <= tip[0] <= 0.5 and abs(tip[1]) <= 0.45
        assert script.state("person", script.t_end)[0][0] >= 3.0
    assert PERSON_BOUNDS["person"].speed == 1.6 and PERSON_BOUNDS["person_arm"].speed == 2.0


@pytest.mark.parametrize("scene", list(SHIELD_SCENES))
def test_each_scene_runs_makes_progress_and_names_its_bodies(scene: str) -> None:
    """Without any layer: the robot reaches targets, the protect list and the bounds name
    bodies of the model, and every protected body that moves has a declared bound."""
    setup = SceneSetup.of(scene)
    model = setup.model
    assert setup.protected.size and setup.pairs.size
    moving = [
        b
        for b in setup.protected.tolist()
        if b and (model.body_mocapid[b] >= 0 or model.body_dofnum[model.body_weldid[b]] > 0)
    ]
    assert sorted(moving) == sorted(setup.bounds)
    result = run_episode(setup, NoLayer(), "none", 0)
    assert result.reached >= 1
    assert result.interventions == 0


def test_the_arms_task_trajectories_keep_the_task_caps() -> None:
    model = SHIELD_SCENES["person_cell"].model()
    data = mujoco.MjData(model)
    task = ArmTask(model, "", [[0.5, 1.0, 0.6, 1.5, 0.0, 0.5]], seed=0)
    data.qpos[:6] = [0.0, -0.2, 2.0, 1.2, 0.0, 0.0]
    ctrl = np.zeros(model.nu)
    task(model, data, ctrl)
    assert task.move is not None
    t = np.arange(0.0, task.move.t1 + 0.1, 0.002)
    q = np.array([task.move.state(x)[0] for x in t])
    speed = np.abs(np.diff(q, axis=0)) / 0.002
    accel = np.abs(np.diff(q, 2, axis=0)) / 0.002**2
    assert np.all(speed <= ARM_SPEED * (1 + 1e-9))
    assert np.all(accel <= ARM_ACCEL * (1 + 1e-6))


def test_arm_b_stays_within_its_declared_bounds_when_nothing_touches_it() -> None:
    """A fresh measurement (other seeds than the declaration's) stays within the declared
    bounds, with room: arm B's bounds are honest for its controller."""
    for name, (speed, accel, disc) in measure_arm_b(4, first_seed=10_000).items():
        bound = ARM_B_BOUNDS[name]
        assert speed <= bound.speed and accel <= bound.accel, name
        assert bound.delta is not None and disc <= bound.delta, name


def test_in_arm_pair_arm_b_breaks_its_bounds_only_once_touched() -> None:
    setup = SceneSetup.of("arm_pair")
    touched = 0
    for seed in range(6):
        result = run_episode(setup, NoLayer(), "none", seed)
        if result.first_violation is not None:
            assert result.first_touch is not None
            assert result.first_violation >= result.first_touch
        touched += result.first_touch is not None
    assert touched  # the arms do meet without a shield
