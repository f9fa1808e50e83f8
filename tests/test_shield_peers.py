"""The shield's peers (dua_mujoco.experiments.shield.peers) and the benchmark's table."""

from __future__ import annotations

import itertools

import mujoco
import numpy as np

from dua_mujoco.experiments.shield.bench import PEERS, peer_layer, run_many, summary
from dua_mujoco.experiments.shield.episodes import SceneSetup
from dua_mujoco.experiments.shield.peers import Hildreth, TtcHalt, VelocityDamper


def test_hildreth_projects_onto_the_polyhedron() -> None:
    """Feasible, and no farther from the point than any feasible vertex of the active sets."""
    rng = np.random.default_rng(0)
    project = Hildreth(sweeps=2000, tol=1e-13)
    for _ in range(100):
        n, k = rng.integers(1, 5), rng.integers(1, 4)
        g = rng.normal(size=(k, n))
        h = g @ rng.normal(size=n) + rng.uniform(0, 1, k)  # feasible
        x0 = rng.normal(size=n) * 2
        x = project(x0, g, h)
        assert np.all(g @ x <= h + 1e-7)
        for active in itertools.product((False, True), repeat=k):
            rows = np.array(active)
            if not rows.any():
                z = x0
            else:
                a = g[rows]
                z = x0 - a.T @ np.linalg.lstsq(a @ a.T, a @ x0 - h[rows], rcond=None)[0]
            if np.all(g @ z <= h + 1e-9):
                assert np.linalg.norm(x - x0) <= np.linalg.norm(z - x0) + 1e-6


def _approach(setup: SceneSetup, gap: float) -> tuple[mujoco.MjData, int]:
    """mobile_cell's base at the origin driving +x at 0.5 m/s toward walker0 ``gap`` apart."""
    model = setup.model
    data = mujoco.MjData(model)
    data.mocap_pos[:] = [[20.0, 20.0 + 3 * i, 0.0] for i in range(model.nmocap)]
    walker = model.body("walker0")
    data.mocap_pos[walker.mocapid[0]] = [0.55 + gap, 0.0, 0.0]
    data.qvel[0] = 0.5
    mujoco.mj_forward(model, data)
    return data, walker.id


def test_the_damper_rows_are_the_distance_rate() -> None:
    """The row ``n . (J2 - J1)`` times a joint velocity is the rate of the pair's distance (a
    finite difference of ``mj_geomDistance``); the damper leaves a motion away alone and slows
    one toward the walker to ``gain (d - d_min) / dt``."""
    setup = SceneSetup.of("mobile_cell")
    model = setup.model
    data, _ = _approach(setup, 0.008)
    damper = VelocityDamper(model, brake=setup.brake, pairs=setup.pairs, period=10)
    g, h = damper._rows(data)
    assert g.shape == (1, 3)
    pair = next(p for p in setup.pairs if model.geom(int(p[0])).name == "base")
    dq = np.array([0.3, -0.2, 0.5])
    d0 = mujoco.mj_geomDistance(model, data, int(pair[0]), int(pair[1]), 1.0, None)
    eps = 1e-6
    moved = mujoco.MjData(model)
    mujoco.mj_copyData(moved, model, data)
    mujoco.mj_integratePos(model, moved.qpos, dq, eps)
    mujoco.mj_forward(model, moved)
    d1 = mujoco.mj_geomDistance(model, moved, int(pair[0]), int(pair[1]), 1.0, None)
    assert np.isclose(-(g @ dq)[0], (d1 - d0) / eps, rtol=1e-4, atol=1e-6)
    assert np.isclose(h[0], 0.85 * (0.008 - 0.005) / 0.02)
    # Toward the walker at 0.5 m/s: slowed to what the row allows.
    damper.reset(data)
    intended = np.array([0.5, 0.0, 0.0])
    damper(data, intended)
    assert damper.target is not None and np.isclose(g[0] @ damper.target, h[0])
    # Away from it: left alone.
    damper.reset(data)
    data.qvel[0] = -0.5
    assert np.array_equal(damper(data, -intended), -intended) and damper.interventions == 0


def test_the_ttc_halt_halts_when_closing_and_not_when_opening() -> None:
    setup = SceneSetup.of("mobile_cell")
    model = setup.model
    ttc = TtcHalt(
        model,
        brake=setup.brake,
        pairs=setup.pairs,
        period=10,
        accel_limits=setup.scene.task_accel,
        safety_factor=1.0,
    )
    assert ttc.every == 50  # MoveIt's 10 Hz at a 2 ms step
    for closing, halts in ((True, True), (False, False)):
        data, walker = _approach(setup, 0.2)
        ttc.reset(data)
        intended = np.array([0.5, 0.0, 0.0])
        ttc(data, intended)  # the first check: no derivative yet
        for _ in range(49):
            ttc(data, intended)
        # 0.1 s later the walker came 0.1 m closer (d / |d'| = 0.1 s, under the worst stop,
        # 0.5 / 1.5 = 0.33 s), or went away.
        data.mocap_pos[model.body(walker).mocapid[0], 0] += -0.1 if closing else 0.1
        mujoco.mj_forward(model, data)
        out = ttc(data, intended)
        assert (ttc.scale == 0.0) is halts
        assert np.array_equal(out, intended) is not halts


def test_every_peer_runs_an_episode_of_every_scene_and_the_table_has_their_rows() -> None:
    results = run_many(
        ["person_cell", "arm_pair", "mobile_cell"], PEERS, [0], jobs=1, progress=False
    )
    assert len(results) == 3 * len(PEERS)
    text = summary(results)
    for scene, layer in itertools.product(["person_cell", "arm_pair", "mobile_cell"], PEERS):
        assert f"| {scene} | {layer} |" in text
    assert all(r.steps > 0 and r.step_seconds > 0 for r in results)
    assert peer_layer(SceneSetup.of("person_cell"), "none").interventions == 0
