"""``mujoco.rollout`` with the plugin on 8 threads, for ThreadSanitizer (``.ci/sanitize thread``).

Usage: ``python .ci/tsan_rollout.py MODEL.xml...`` (models exported with the plugin). Each model
runs 16 rollouts of random controls on one thread, then on 8; the sensor readings must be equal
(each thread's plugin state is its own ``MjData``'s), and alarms must stand. The process imports
nothing of dua_mujoco but what ``import mujoco`` loads (the plugin library, through the
``mujoco.plugins`` entry point, from ``$DUA_MUJOCO_LIBRARY``).
"""

from __future__ import annotations

import sys

import mujoco
import numpy as np
from mujoco import rollout


def check(path: str, nthread: int = 8, nroll: int = 16, nstep: int = 200) -> None:
    m = mujoco.MjModel.from_xml_path(path)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.zeros(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, d, state, spec)
    initial = np.repeat(state[None], nroll, axis=0)
    ctrl = np.random.default_rng(1).uniform(-1, 1, (nroll, nstep, m.nu))
    _, one = rollout.rollout(m, [mujoco.MjData(m)], initial, ctrl)
    _, many = rollout.rollout(m, [mujoco.MjData(m) for _ in range(nthread)], initial, ctrl)
    np.testing.assert_array_equal(one, many)
    assert one[:, :, 0].max() > 0, "no alarm stood: the plugin did not run"
    print(f"{path}: {nroll} rollouts of {nstep} steps on {nthread} threads = on one")


if __name__ == "__main__":
    for model in sys.argv[1:]:
        check(model)
