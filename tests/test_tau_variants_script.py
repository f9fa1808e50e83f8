"""benchmarks/tau_variants.py's ceiling of a geom-pair tau: the contact distance it gives a sphere
pair reproduces the geoms' own gap, so that the same root prices the pair from its geoms."""

from __future__ import annotations

import mujoco
import numpy as np
from benchmark_scripts import script

from dua_mujoco import Predictor
from dua_mujoco.core.urgency import time_to_collision

# Two spheres 0.3 m apart, and two parallel capsules (half-length 0.2, radius 0.03) 0.15 m
# apart, whose covering spheres (radius 0.23) overlap although the capsules are 9 cm apart.
XML = """
<mujoco><worldbody>
  <body pos="0 0 1"><freejoint/><geom type="sphere" size="0.05"/></body>
  <body pos="0.3 0 1"><freejoint/><geom type="sphere" size="0.07"/></body>
  <body pos="0 0.5 1"><freejoint/><geom type="capsule" size="0.03" fromto="-.2 0 0 .2 0 0"/></body>
  <body pos="0 0.65 1"><freejoint/><geom type="capsule" size="0.03" fromto="-.2 0 0 .2 0 0"/></body>
</worldbody></mujoco>
"""


def test_the_geoms_gap_replaces_the_spheres_and_never_lowers_tau() -> None:
    m = mujoco.MjModel.from_xml_string(XML)
    d = mujoco.MjData(m)
    d.qvel[[0, 6, 12, 18]] = [0.4, -0.4, 0.1, -0.1]  # along x: the pairs approach or slide
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
    assert spheres.sum() == capsules.sum() == 1
    # A sphere geom is its own covering: the same contact distance.
    np.testing.assert_allclose(eps_g[spheres], eps[spheres], rtol=0, atol=1e-12)
    # The capsules' gap is that of their segments less both radii: eps is the two radii.
    assert eps[capsules] > np.linalg.norm(x[capsules], axis=1)  # the spheres overlap
    np.testing.assert_allclose(eps_g[capsules], 0.06, rtol=0, atol=1e-12)
    # The geoms' gap is never below the spheres', so neither is the tau it gives.
    assert np.all(eps_g <= eps + 1e-12)
    tau = time_to_collision(x, v, eps, pairs.accel)
    tau_g = time_to_collision(x, v, eps_g, pairs.accel)
    assert tau[capsules] == 0.0 < tau_g[capsules]
    assert np.all(tau_g >= tau)
