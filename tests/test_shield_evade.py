"""The evasive failsafe of ``dua_mujoco/experiments/shield/evade.py`` under the shield on
``mobile_cell``: verified as the brake is (docs/theory.md, section 10), so the guarantee holds;
and the run repeats its rollouts only because the policy steers by the obstacles as the rollout
saw them (a policy reading where they are now leaves its plans: (S2) broken, caught by the
shield's check at every step)."""

from __future__ import annotations

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
