"""benchmarks/tau_variants.py's ceiling of a geom-pair tau: the contact distance it gives a sphere
pair reproduces the geoms' own gap, so that the same root prices the pair from its geoms."""

from __future__ import annotations

import mujoco
import numpy as np
from benchmark_scripts import script

from dua_mujoco import Predictor
from dua_mujoco.core.urgency import time_to_collision

# Two spheres 0.3 m apart; two parallel capsules (half-length 0.2, radius 0.03, margin 1 cm)
# 0.15 m apart, whose covering spheres (radius 0.23) overlap although the capsules are 9 cm
# apart; two spheres 2 cm into each other.
CAPSULE = 'type="capsule" size="0.03" fromto="-.2 0 0 .2 0 0" margin="0.01"'
XML = f"""
<mujoco><worldbody>
  <body pos="0 0 1"><freejoint/><geom type="sphere" size="0.05"/></body>
  <body pos="0.3 0 1"><freejoint/><geom type="sphere" size="0.07"/></body>
  <body pos="0 0.5 1"><freejoint/><geom {CAPSULE}/></body>
  <body pos="0 0.65 1"><freejoint/><geom {CAPSULE}/></body>
  <body pos="0 1 1"><freejoint/><geom type="sphere" size="0.05"/></body>
  <body pos="0.08 1 1"><freejoint/><geom type="sphere" size="0.05"/></body>
</worldbody></mujoco>
"""


def test_the_geoms_gap_replaces_the_spheres_and_never_lowers_tau() -> None:
    m = mujoco.MjModel.from_xml_string(XML)
    d = mujoco.MjData(m)
    d.qvel[[0, 6, 12, 18, 24]] = [0.4, -0.4, 0.1, -0.1, 0.2]  # along x: approach or slide
    mujoco.mj_forward(m, d)
    p = Predictor(m, accel=10.0)
    pairs, cov = p.pair_set, p.covering
    i, j = pairs.first, pairs.second
    c, u = p.sphere_states(d)
    x, v = c[j] - c[i], u[j] - u[i]
    radius = np.asarray(cov.sphere_radius)
    eps = np.broadcast_to(pairs.eps, (len(pairs),))
    geom = np.asarray(cov.sphere_geom)
    margin = eps - radius[i] - radius[j]
    eps_g = script("tau_variants").geom_gap_eps(m, d, geom[i], geom[j], x, margin)

    spheres = (geom[i] == 0) & (geom[j] == 1)
    capsules = (geom[i] == 2) & (geom[j] == 3)
    into = (geom[i] == 4) & (geom[j] == 5)
    assert spheres.sum() == capsules.sum() == into.sum() == 1
    # A sphere geom is its own covering: the same contact distance.
    np.testing.assert_allclose(eps_g[spheres], eps[spheres], rtol=0, atol=1e-12)
    # The capsules' gap is that of their segments less both radii and the pair's margin (the sum
    # of the two geoms', as MuJoCo's): eps is the two radii and the margin.
    np.testing.assert_allclose(margin[capsules], 0.02, rtol=0, atol=1e-12)
    assert eps[capsules] > np.linalg.norm(x[capsules], axis=1)  # the spheres overlap
    np.testing.assert_allclose(eps_g[capsules], 0.08, rtol=0, atol=1e-12)
    # Geoms already in each other: no gap, so eps is the centres' distance and tau is 0.
    np.testing.assert_allclose(eps_g[into], np.linalg.norm(x[into], axis=1), rtol=0, atol=0)
    # The geoms' gap is never below the spheres', so neither is the tau it gives.
    assert np.all(eps_g <= eps + 1e-12)
    tau = time_to_collision(x, v, eps, pairs.accel)
    tau_g = time_to_collision(x, v, eps_g, pairs.accel)
    assert tau[capsules] == 0.0 < tau_g[capsules]
    assert tau_g[into] == 0.0
    # (A sphere geom's contact distance comes back through a subtraction: within an ulp or two.)
    assert np.all(tau_g >= tau * (1 - 1e-12))
