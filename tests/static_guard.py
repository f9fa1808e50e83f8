"""A static geom moved under a built predictor: what every ``reset`` must refuse."""

from __future__ import annotations

import mujoco
import pytest

from dua_mujoco import Predictor
from dua_mujoco.exceptions import InvalidInputError


def assert_reset_refuses_a_moved_static_body(m: mujoco.MjModel, body: int, geom: str) -> None:
    """Lifts static ``body`` (carrying geom ``geom``) under a predictor built before: ``reset``
    refuses it before ``mj_forward`` (data stale) and after (the tables stale, which would miss
    its contacts); a predictor built for the edited model takes it."""
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    p = Predictor(m, accel=5.0)
    p.reset(d)
    m.body_pos[body] += [0.0, 0.0, 0.3]
    with pytest.raises(InvalidInputError, match=rf"'{geom}'.*mj_forward"):
        p.reset(d)
    mujoco.mj_forward(m, d)
    with pytest.raises(InvalidInputError, match=rf"'{geom}'.*edited.*new Predictor"):
        p.reset(d)
    Predictor(m, accel=5.0).reset(d)
