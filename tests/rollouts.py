"""Physics rollouts that a predictor follows, for the tests that check it at every step."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import mujoco
import numpy as np

from dua_mujoco.runtime.predictor import Predictor


def predictor_rollout(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    p: Predictor,
    ctrl: Callable[[mujoco.MjModel, mujoco.MjData], None] | None,
    steps: int,
) -> Iterator[int]:
    """Step the physics under ``ctrl`` (None: none) with ``p`` following every step.

    The first physics step is followed by ``p.reset``, each of the next ``steps`` by ``p.step``.

    Yields:
        ``0`` after the reset, then ``1 .. steps`` after each predictor step.
    """
    for k in range(steps + 1):
        if ctrl is not None:
            ctrl(m, d)
        mujoco.mj_step(m, d)
        if k == 0:
            p.reset(d)
        else:
            p.step(d)
        yield k


def periodic_rollout(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    p: Predictor,
    ctrl: Callable[[mujoco.MjModel, mujoco.MjData], None],
    physics_steps: int,
) -> Iterator[int]:
    """Step the physics ``physics_steps`` times under ``ctrl`` with ``p`` following as the
    plugin does: ``p.reset`` after the first physics step, ``p.step`` after every
    ``p.period``-th.

    Yields:
        The physics step's index ``k`` after each of ``p``'s calls.
    """
    for k in range(physics_steps):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        if k == 0:
            p.reset(d)
        elif k % p.period == 0:
            p.step(d)
        else:
            continue
        yield k


def python_standing(p: Predictor) -> np.ndarray:
    """The Python predictor's geom pairs standing in alarm, as ``standing_pairs`` gives them."""
    assert p.scheduler is not None
    ids = p.held_pairs[p.scheduler.alarm_state()]
    g1, g2 = p.sphere_pair_geoms
    rows = np.sort(np.stack([g1[ids], g2[ids]], axis=1), axis=1)
    return np.unique(rows, axis=0).reshape(-1, 2)


def held_control_states(m: mujoco.MjModel, d: mujoco.MjData, steps: int) -> np.ndarray:
    """``(steps + 1, nq)``: d's qpos and the ``steps`` states after it under the controls ``d``
    holds (a copy is stepped; ``d`` is left as it is): a plan of the motion as it goes on."""
    c = mujoco.MjData(m)
    mujoco.mj_copyData(c, m, d)
    states = [c.qpos.copy()]
    for _ in range(steps):
        mujoco.mj_step(m, c)
        states.append(c.qpos.copy())
    return np.array(states)
