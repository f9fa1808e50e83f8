"""A slow reference of when a plan may touch (docs/theory.md, section 8), for the tests: MuJoCo's
distance of two geoms at each knot's poses (``mj_kinematics``), not the runtime's walk."""

from __future__ import annotations

import mujoco
import numpy as np

from dua_mujoco.runtime.predictor import Predictor


def first_knot_within(
    m: mujoco.MjModel, qpos: np.ndarray, geom1: str, geom2: str, distance: float
) -> int | None:
    """The first knot of ``qpos`` ``(n, nq)`` at which the two geoms are within ``distance``
    (None: at none)."""
    d = mujoco.MjData(m)
    g1, g2 = int(m.geom(geom1).id), int(m.geom(geom2).id)
    for j, q in enumerate(qpos):
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        if mujoco.mj_geomDistance(m, d, g1, g2, 10.0, None) <= distance:
            return j
    return None


def last_taus(m: mujoco.MjModel, p: Predictor, geom1: str, geom2: str) -> np.ndarray:
    """The last taus of the predictor's sphere pairs of the two geoms."""
    g = {int(m.geom(geom1).id), int(m.geom(geom2).id)}
    pairs = zip(p.tables.geom1.tolist(), p.tables.geom2.tolist(), strict=True)
    ids = [i for i, (a, b) in enumerate(pairs) if {a, b} == g]
    assert ids, (geom1, geom2)
    return p.pair_state().last_tau_of(np.array(ids))
