"""Two-level urgency (dua_mujoco.mj.refine; docs/static-shapes.md, section 12).

The refined tau of a pair is ``max(bounding tau, min over the fine sub-pairs)`` when the bounding
tau is urgent, the bounding tau otherwise; checked against a slow reference built from the fine
covering's own sphere pairs and ``PairSet.tau``, and by rollouts without a miss.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from rollouts import predictor_rollout

from dua_mujoco.core.pairset import PairSet
from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.mj.filter import sphere_pairs
from dua_mujoco.mj.kinematics import mjdata_frame, sphere_states
from dua_mujoco.mj.monitor import run
from dua_mujoco.mj.predictor import Predictor
from dua_mujoco.mj.scenes import load_scene, make_controller
from dua_mujoco.mj.tables import static_shapes


def _reference(p: Predictor, d: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    """(bounding tau, refined tau) of every pair, slowly: the fine covering's own sphere pairs."""
    ref = p.refinement
    assert ref is not None
    ps = p.pair_set
    c, v = p.sphere_states(d)
    shapes = static_shapes(p.model, p.covering.shape_geom, d)
    shapes_arg = shapes if p.covering.nshape else None
    coarse = ps.tau(np.arange(len(ps)), c, v, p.halfspaces(d), shapes=shapes_arg)
    # One bounding pair per geom pair: the fine sub-pairs take its bounds.
    of_geom_pair = np.full(p.geom_pairs.npair, -1)
    of_geom_pair[p.sphere_pairs.geom_pair] = np.arange(len(ps))
    fsp = sphere_pairs(ref.fine, p.geom_pairs)
    parent = of_geom_pair[fsp.geom_pair]
    fine = PairSet(
        fsp.first,
        fsp.second,
        fsp.eps,
        ps.accel[parent],
        kind=fsp.kind,
        vel_uncertainty=ps.vel_uncertainty[parent],
        speed=ps.speed[parent],
    )
    twist = np.zeros((p.model.nbody, 6))
    if p.mocap is not None:
        p.mocap.write_body_velocity(twist)
    fc, fv = sphere_states(ref.spheres, mjdata_frame(d, twist))
    tau_fine = fine.tau(np.arange(len(fine)), fc, fv, p.halfspaces(d), shapes=shapes_arg)
    best = np.full(len(ps), np.inf)
    np.minimum.at(best, parent, tau_fine)
    refined = np.where(coarse < ref.refine_below, np.maximum(coarse, best), coarse)
    return coarse, refined


def _check_against_reference(
    m: mujoco.MjModel, d: mujoco.MjData, ctrl, steps: int = 40, speed: float | None = None
) -> None:
    # The refined level against its reference: no exact level on top.
    p = Predictor(
        m, accel=10.0, speed=speed, schedule="select-all", refine=6, refine_below=0.5, exact=False
    )
    raised = 0
    for k in predictor_rollout(m, d, p, ctrl, steps):
        sched = p.scheduler
        assert sched is not None
        coarse, want = _reference(p, d)
        np.testing.assert_allclose(sched.last_tau, want, rtol=1e-12, atol=0.0)
        if k > 0:
            assert (sched.last_tau >= coarse).all()
            raised += int(np.sum(sched.last_tau > coarse))
    assert raised > 0  # the refinement did tighten some urgent pairs


@pytest.mark.parametrize("scene", ["two_arms", "traffic", "clutter"])
def test_refined_tau_equals_reference(scene: str) -> None:
    m, d = load_scene(scene)
    _check_against_reference(m, d, make_controller(m, "random", seed=2, hold_steps=10))


MARGINS = """<mujoco>
  <default><geom margin=".02" gap=".01"/></default>
  <worldbody>
    <geom type="plane" size="3 3 .1"/>
    <geom name="table" type="box" size=".6 .4 .02" pos="0 0 .4" euler="0 5 10"/>
    <body pos="-.1 0 .55"><freejoint/><geom type="box" size=".3 .04 .03"/></body>
    <body pos=".15 .05 .7" euler="0 80 0"><freejoint/><geom type="capsule" size=".03 .25"/></body>
    <body pos="1 0 .2"><freejoint/><geom type="cylinder" size=".05 .2"/></body>
  </worldbody>
</mujoco>"""


def test_refined_tau_with_margins_and_gaps() -> None:
    # Nonzero margins and gaps: the fine sub-pairs must add the pair's contact distance; a speed
    # bound: the sphere sub-pairs must use it.
    m = mujoco.MjModel.from_xml_string(MARGINS)
    d = mujoco.MjData(m)
    d.qvel[:] = np.random.default_rng(0).normal(size=m.nv) * 0.5
    mujoco.mj_forward(m, d)
    _check_against_reference(m, d, None, steps=60, speed=1.5)


def test_refinement_options() -> None:
    m, _ = load_scene("two_arms")
    with pytest.raises(InvalidInputError, match='covering="bounding"'):
        Predictor(m, accel=5.0, covering="multi", refine=4)
    with pytest.raises(InvalidInputError, match="refine_below"):
        Predictor(m, accel=5.0, refine=4, refine_below=0.0)
    p = Predictor(m, accel=5.0, refine=4)
    assert p.refinement is not None and p.refinement.fine.nsphere > p.nsphere
    assert Predictor(m, accel=5.0).refinement is None


@pytest.mark.slow
@pytest.mark.parametrize("scene", ["two_arms", "traffic", "clutter"])
def test_rollout_with_refinement_misses_nothing(scene: str) -> None:
    m, d = load_scene(scene)
    p = Predictor(m, refine=8, pilot_controller=make_controller(m, "random", seed=99))
    r = run(m, d, p, steps=2000, controller=make_controller(m, "random", seed=0), progress=False)
    assert r.missed_onsets_valid_bounds == 0, [x for x in r.misses if x.bounds_held][:5]
    assert r.unfiltered_contacts == 0
    assert r.predicted_onsets + r.missed_onsets == r.contact_onsets
    assert r.contact_onsets > 0
