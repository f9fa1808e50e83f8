"""The evasive failsafe of ``dua_mujoco/experiments/shield/evade.py`` under the shield on
``mobile_cell``: verified as the brake is (docs/theory.md, section 10), so the guarantee holds;
and the run repeats its rollouts only because the policy steers by the obstacles as the rollout
saw them (a policy reading where they are now leaves its plans: (S2) broken, caught by the
shield's check at every step)."""

from __future__ import annotations

import copy

import mujoco
import numpy as np
import pytest

from dua_mujoco.experiments.shield.bench import shield_layer
from dua_mujoco.experiments.shield.episodes import NoLayer, SceneSetup, run_episode
from dua_mujoco.experiments.shield.evade import Evade

SEEDS, DURATION = range(8), 4.0


class EvadeNow(Evade):
    """The mutant: in the run too, the obstacles where they are now (no memory of the rollout's
    view)."""

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """The policy as if every call were a rollout's."""
        self.model = None  # type: ignore[assignment]
        return super().__call__(model, data)


def _run(setup: SceneSetup, policy: Evade, seed: int) -> tuple[int, dict[str, int], bool]:
    shield = shield_layer(setup, "shield", failsafe=policy)
    result = run_episode(setup, shield, "evade", seed, duration=DURATION)
    clean = result.first_touch is None and result.violations == 0
    return result.moving_free, shield.counts, clean


@pytest.mark.slow
def test_an_evasive_failsafe_keeps_the_guarantee_and_its_rollouts() -> None:
    """Over sampled episodes, the shield with the evasive failsafe has no free moving contact
    where the unshielded base has several; in the episodes nothing touched, the run kept to its
    verified plans (no plan, hold or stop break; every step guaranteed), and the policy steered
    (its run found every moving state it was called at among its rollouts' knots)."""
    setup = SceneSetup.of("mobile_cell")
    free = shielded = clean = 0
    for seed in SEEDS:
        free += run_episode(setup, NoLayer(), "none", seed, duration=DURATION).moving_free
        policy = Evade.of(setup)
        moving, counts, untouched = _run(setup, policy, seed)
        shielded += moving
        assert counts["stop_breaks"] == 0, (seed, counts)
        if untouched:
            clean += 1
            broken = [counts[k] for k in ("plan_breaks", "hold_breaks", "unguaranteed")]
            assert broken == [0, 0, 0], (seed, counts)
            assert policy.misses == 0, seed
            assert counts["interventions"] > 0, seed
    assert free >= 3
    assert shielded == 0
    assert clean >= 2


@pytest.mark.slow
def test_a_failsafe_steering_by_the_obstacles_now_leaves_its_plans() -> None:
    """The mutant that reads the obstacles' current positions in the run: the shield finds the
    run off its plans (plan breaks, steps without a guarantee) in episodes nothing touched."""
    setup = SceneSetup.of("mobile_cell")
    breaks = 0
    for seed in SEEDS:
        _, counts, untouched = _run(setup, EvadeNow.of(setup), seed)
        if untouched:
            breaks += counts["plan_breaks"]
    assert breaks > 0


def test_the_evasive_failsafe_steers_away_while_it_brakes_and_is_the_brake_at_rest() -> None:
    """Driving along +x with a walker ahead on +y, the policy brakes x as the brake does and
    pushes y away from the walker (the brake leaves y alone); at rest it is the brake."""
    setup = SceneSetup.of("mobile_cell")
    model = setup.model
    data = mujoco.MjData(model)
    setup.scene.episode(model, data, 0)
    policy = Evade.of(setup)
    walker = model.body("walker0").mocapid[0]
    data.mocap_pos[:, :2] = [[2.5, 2.0], [-2.5, 2.0], [-2.5, -2.0], [2.5, -2.0]]
    data.mocap_pos[walker, :2] = [0.4, 0.6]
    data.qpos[:3] = 0.0
    data.qvel[:3] = [0.8, 0.0, 0.0]
    mujoco.mj_forward(model, data)
    rolled = copy.deepcopy(model)  # as the shield's rollouts call it
    ux, uy = policy.away(0.0, 0.0, data.mocap_pos[policy.mocap, :2].tolist())
    assert uy == -1.0 and ux < 0.0
    ctrl, brake = policy(rolled, data), policy.brake(rolled, data)
    x, y = policy.brake.native.actuators[:2]
    assert ctrl[x] == pytest.approx(brake[x])  # x at the brake's force limit either way
    assert brake[y] == pytest.approx(0.0, abs=1e-9) and ctrl[y] < -0.1
    # The run at the same state steers by what the rollout saw, wherever the walker is now.
    data.mocap_pos[walker, :2] = [-0.4, -0.6]
    np.testing.assert_array_equal(policy(model, data), ctrl)
    data.qvel[:3] = [0.005, -0.005, 0.0]
    np.testing.assert_array_equal(policy(rolled, data), policy.brake(rolled, data))
