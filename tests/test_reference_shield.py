"""The reference shield (tests/reference_shield.py): its check on cases worked out by hand, its
pair filter against the package's, and its loop on the shield scenes' episodes."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from reference_shield import (
    SLACK,
    OtherBound,
    Verdict,
    protected_pairs,
    shield_for,
    verify,
)

from dua_mujoco.build.filter import active_geom_pairs
from dua_mujoco.experiments.shield.episodes import NoLayer, SceneSetup, run_episode
from dua_mujoco.models.cells import SHIELD_SCENES
from dua_mujoco.shield.failsafe import Brake


@pytest.mark.parametrize("scene", list(SHIELD_SCENES))
def test_the_reference_filter_matches_the_package_filter(scene: str) -> None:
    """The reference's own transcription of MuJoCo's pair filter gives the pairs the package's
    (tested against MuJoCo itself in tests/test_pairs.py) gives between robot and protected."""
    setup = SceneSetup.of(scene)
    mine = protected_pairs(setup.model, setup.brake.bodies, setup.protected)
    theirs = {tuple(sorted(p)) for p in setup.pairs.tolist()}
    assert {tuple(sorted((p.robot, p.other))) for p in mine} == theirs
    active = active_geom_pairs(setup.model)
    for p in mine:
        k = active.index_of(p.robot, p.other)
        assert p.contact_distance == active.contact_distance[k]


def _base_toward_walker(gap_x: float) -> tuple[mujoco.MjModel, mujoco.MjData, Brake, list]:
    """mobile_cell's base at the origin driving +x at 0.5 m/s; walker0 ``gap_x`` ahead (centre
    to centre), the other obstacles far away. Pairs: the base's geoms against walker0."""
    sc = SHIELD_SCENES["mobile_cell"]
    model = sc.model()
    data = mujoco.MjData(model)
    brake = Brake(model, actuators=sc.robot_actuators(model))
    data.mocap_pos[:] = [[20.0, 20.0 + 3 * i, 0.0] for i in range(model.nmocap)]
    walker = model.body("walker0")
    data.mocap_pos[walker.mocapid[0]] = [gap_x, 0.0, 0.0]
    data.qvel[0] = 0.5
    data.ctrl[:] = [0.5, 0.0, 0.0]
    mujoco.mj_forward(model, data)
    pairs = protected_pairs(model, brake.bodies, [walker.id])
    return model, data, brake, pairs


def _check(gap_x: float, speed: float, accel: float, v0: float) -> Verdict:
    model, data, brake, pairs = _base_toward_walker(gap_x)
    walker = model.body("walker0").id
    return verify(
        model,
        data,
        data.ctrl.copy(),
        period=10,
        failsafe=brake,
        robot_bodies=brake.bodies,
        pairs=pairs,
        bounds={walker: OtherBound(speed, accel)},
        velocities={walker: np.array([0.0, 0.0, 0.0, v0, 0.0, 0.0])},
    )


def test_the_gaps_are_the_distance_less_the_others_reach() -> None:
    """Two upright cylinders: the base's (radius 0.3) at its rolled position, the walker's
    (radius 0.25) where it was read; the gap is their horizontal distance less the walker's
    reach ``min(V t, (|v| + a h / 2) t + a t^2 / 2)`` and the slack, at every knot."""
    model, _, brake, pairs = _base_toward_walker(1.0)
    verdict = _check(1.0, speed=1.6, accel=2.0, v0=-1.0)
    assert verdict.safe
    base = int(np.flatnonzero(brake.bodies == model.body("base").id)[0])
    k = next(i for i, p in enumerate(pairs) if model.geom(p.robot).name == "base")
    h = float(model.opt.timestep)
    gaps = verdict.gaps[:, k]
    x = verdict.body_pos[:, base, 0]
    t = np.arange(gaps.size) * h
    reach = np.minimum(1.6 * t, (1.0 + 2.0 * h / 2) * t + t * t)
    # Knots the bounding spheres already cleared carry inf; the others, MuJoCo's distance.
    seen = np.isfinite(gaps)
    assert seen.sum() > gaps.size / 2
    assert np.all((1.0 - x - 0.55 - reach - SLACK)[~seen] > 0)
    assert np.allclose(gaps[seen], ((1.0 - x) - 0.55 - reach - SLACK)[seen], atol=1e-9)
    # It rolled the intended 10 steps, then braked to rest.
    assert verdict.rest > 10
    assert x[verdict.rest] - x[10] > 0.01


def test_the_verdict_turns_with_the_others_motion() -> None:
    """The same robot motion, the walker 0.8 m away: safe while it stands (its reach over the
    stop is a few cm), unsafe when it walks in at 1.6 m/s, safe again at 1.2 m."""
    assert _check(0.8, speed=1.6, accel=2.0, v0=0.0).safe
    unsafe = _check(0.8, speed=1.6, accel=2.0, v0=-1.6)
    assert not unsafe.safe
    assert unsafe.unsafe_knot > 0
    assert _check(1.2, speed=1.6, accel=2.0, v0=-1.6).safe
    # Without a speed bound the acceleration reach alone decides: larger, unsafe at 1.2 m too.
    assert not _check(1.2, speed=np.inf, accel=50.0, v0=-1.6).safe


def test_a_robot_at_rest_may_be_touched() -> None:
    model, data, brake, pairs = _base_toward_walker(0.56)  # 1 cm apart
    data.qvel[:] = 0.0
    data.ctrl[:] = 0.0
    walker = model.body("walker0").id
    check = {
        "period": 10,
        "failsafe": brake,
        "robot_bodies": brake.bodies,
        "pairs": pairs,
        "bounds": {walker: OtherBound(1.6, 2.0)},
    }
    velocity = {walker: np.array([0.0, 0.0, 0.0, -1.6, 0.0, 0.0])}
    verdict = verify(model, data, data.ctrl.copy(), velocities=velocity, **check)
    assert verdict.safe and verdict.rest == 10
    with pytest.raises(ValueError, match="needs its velocity"):
        verify(model, data, data.ctrl.copy(), **check)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("scene", "seed", "duration"),
    [("person_cell", 3, 4.5), ("arm_pair", 0, 3.0), ("mobile_cell", 6, 2.0)],
)
def test_the_reference_shield_keeps_the_robot_from_moving_into_what_it_protects(
    scene: str, seed: int, duration: float
) -> None:
    """Episodes in which, without a shield, the robot moves into a protected body: under the
    reference shield every protected contact finds the robot at rest, and the robot keeps to
    its plan until then. The same loop with the others' reach taken away (their bounds 0: as if
    they stood still) lets the robot move into them: the reach is what the check rests on."""
    setup = SceneSetup.of(scene)
    free = run_episode(setup, NoLayer(), "none", seed, duration=duration)
    assert free.moving_free >= 1
    shield = shield_for(setup)
    shielded = run_episode(setup, shield, "reference", seed, duration=duration)
    assert shielded.moving_free == 0
    assert shielded.interventions > 0
    if shielded.first_touch is None:
        assert shield.max_deviation <= 1e-9  # never touched: the run is the plan
    blind = {b: OtherBound(0.0, 0.0, 0.0) for b in setup.bounds}
    assert (
        run_episode(setup, shield_for(setup, blind), "blind", seed, duration=duration).moving_free
        >= 1
    )
