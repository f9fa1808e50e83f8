"""Pruned pairs that forget (issue 35): a plugin ``MjData`` forgets the geom pairs it has not
held for ``forget`` rebuilds, and holds what a predictor that never forgets holds (docs/theory.md,
Lemma 7.1): the same standing pairs and evaluations after every step, a forgotten pair met again
and flagged before it collides, and the pairs known bounded while the pairs met keep growing.

Both sides run one runtime (docs/theory.md, section 7): the comparisons are round trips that
check forgetting against not forgetting, not the step itself (tests/test_reference_step.py)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from rollouts import periodic_rollout, predictor_rollout, python_standing

from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.models.scenes import load_spec, make_controller
from dua_mujoco.plugin import attach, known_pairs, plugin_outputs, standing_pairs
from dua_mujoco.runtime.predictor import Predictor


def _swarm(n: int, forget: int | None) -> tuple[mujoco.MjModel, mujoco.MjData, Predictor]:
    spec = load_spec(f"swarm:{n}")
    p = attach(spec, accel=2.0, pairs="pruned", forget=forget)
    m = spec.compile()
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)  # the swarm's random initial velocities
    return m, d, p


def _rows(a: np.ndarray) -> set[tuple[int, int]]:
    return {(int(g1), int(g2)) for g1, g2 in a}


def test_a_forgotten_pair_is_met_again_and_flagged_before_it_collides() -> None:
    """The plugin forgetting every pair the latest rebuild did not hold (``forget=0``) against
    the pruned Python predictor, which never forgets, on the same states: the same standing
    pairs and evaluations after every step; geom pairs are forgotten, come back, and each
    forgotten pair that later collides stands in alarm at the step before its first contact
    and at the contact (one alarm episode that reaches it, begun at least the alarm horizon
    ahead: docs/theory.md, Theorem 3), unless one of its bodies broke its bounds at the
    contact's own step (Theorem 4: then the contact's own evaluation flags it)."""
    m, d, p = _swarm(300, forget=0)
    ctrl = make_controller(m, "random", seed=7)
    body = np.asarray(m.geom_bodyid)
    known_before: set[tuple[int, int]] = set()
    forgotten: set[tuple[int, int]] = set()  # forgotten at least once, not yet in contact
    before: set[tuple[int, int]] = set()  # standing after the previous step
    collided = flagged = excused = 0
    for k in predictor_rollout(m, d, p, ctrl, 2999):
        want = _rows(python_standing(p))
        assert _rows(standing_pairs(m, d)) == want, f"step {k}"
        assert plugin_outputs(m, d).evaluated == p.evaluations_per_step, f"step {k}"
        known = _rows(known_pairs(m, d).geom_pairs)
        forgotten |= known_before - known
        known_before = known
        broke = set(p.violated_bodies.tolist()) if k else set()
        nc = int(d.ncon)
        for a, b in zip(d.contact.geom1[:nc], d.contact.geom2[:nc], strict=True):
            gp = (int(min(a, b)), int(max(a, b)))
            if gp in forgotten and gp in known:  # came back, now collides
                forgotten.discard(gp)
                if broke & {int(body[gp[0]]), int(body[gp[1]])}:
                    excused += 1
                    continue
                collided += 1
                flagged += gp in before and gp in want
        before = want
    kp = known_pairs(m, d)
    assert kp.compactions > 10 and kp.forgotten > 300
    assert collided >= 5  # the run meets what it claims
    assert flagged == collided, (flagged, collided, excused)


def test_forgetting_among_geoms_of_many_spheres_round_trips_what_python_holds() -> None:
    """Objects poured into a bin (geoms of many spheres, impacts that renew spheres between
    rebuilds, a mocap body), the plugin forgetting every pair the latest rebuild did not hold:
    the same standing pairs and evaluations as the pruned Python predictor after every step. A
    round trip of one runtime through two callers that differ in forgetting alone (Lemma 7.1):
    it catches a forgetting that loses a pair, not a bug of the step both share."""
    spec = load_spec("bin_pour:60")
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_EULER  # as test_plugin compares them
    p = attach(spec, accel=5.0, pairs="pruned", forget=0)
    m = spec.compile()
    d = mujoco.MjData(m)
    ctrl = make_controller(m, "random", seed=0)
    busy = 0
    first: int | None = None
    for k in periodic_rollout(m, d, p, ctrl, 600):
        want = _rows(python_standing(p))
        assert _rows(standing_pairs(m, d)) == want, f"step {k}"
        assert plugin_outputs(m, d).evaluated == p.evaluations_per_step, f"step {k}"
        busy += bool(want)
        if first is None and known_pairs(m, d).compactions:
            first = k
    assert first is not None and first < 300  # compared for 300 steps after pairs were forgotten
    assert known_pairs(m, d).forgotten > 100 and p.renewals > 5 and busy > 10


def test_pairs_known_stay_bounded_while_the_pairs_met_grow() -> None:
    """A swarm whose spheres keep meeting new neighbours: without forgetting the pairs known
    grow with the run; with ``forget=2`` they stay within the bound of Lemma 7.1 (twice the
    geom pairs held at the last ``forget + 1`` rebuilds, each at most the most ever held), and
    both runs report the same after every step."""
    runs = [_swarm(100, forget=None), _swarm(100, forget=2)]
    base = runs[0][2].universe.npair  # the model's own pairs (walls), held always
    ctrls = [make_controller(m, "random", seed=3) for m, _, _ in runs]
    most_held = 0
    learnt: list[list[int]] = [[], []]
    for k in range(6000):
        outs = []
        for (m, d, _), ctrl, grown in zip(runs, ctrls, learnt, strict=True):
            ctrl(m, d)
            mujoco.mj_step(m, d)
            outs.append((standing_pairs(m, d).tolist(), plugin_outputs(m, d)))
            kp = known_pairs(m, d)
            grown.append(kp.npair - base)
        assert outs[0] == outs[1], f"step {k}"
        most_held = max(most_held, known_pairs(*runs[1][:2]).held - base)
    bound = 2 * (2 + 1 + 1) * most_held  # forget + 1 rebuilds, and the one learning now
    assert max(learnt[1]) <= bound
    assert learnt[0][-1] > 2 * bound  # what it would have grown to: the bound is not vacuous
    assert max(learnt[1][3000:]) <= max(learnt[1][:3000]) + most_held


def test_forget_must_be_a_count_of_rebuilds() -> None:
    spec = load_spec("swarm:20")
    for bad in (-1, 1.5, True):
        with pytest.raises(InvalidInputError, match="forget must be a whole number"):
            attach(spec, accel=2.0, pairs="pruned", forget=bad)  # type: ignore[arg-type]
