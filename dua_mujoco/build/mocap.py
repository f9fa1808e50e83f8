"""Velocities of mocap bodies, which MjData does not give: backward differences, or the user's.

A tree rooted at a mocap body moves rigidly with it (its ``cvel`` is zero), so the kinematics
kernel adds the root's twist (:attr:`twist <MocapVelocityTracker.twist>`) to every point of the
tree. The state and the differencing are native (``csrc/src/mocap.h``), one for the predictor's
runtime and for the trackers here. The poses differenced are ``d.xpos``/``d.xquat``, those
``geom_xpos`` was computed from (one instant with the centres, even if the user already wrote
the next ``mocap_pos``); the backward difference is the chord velocity of docs/discrete-time.md,
so ``delta = A h / 2`` covers it. Before two records the velocity is zero (or the user's):
declare a larger ``vel_uncertainty`` for the first step if the body is already moving.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco import _core
from dua_mujoco.exceptions import InvalidChoiceError

__all__ = ["MocapVelocityTracker", "PredictorMocap"]


class PredictorMocap:
    """The mocap velocities a :class:`~dua_mujoco.Predictor` steps with: its native runtime
    differences the mocap poses at every predictor step; this object reads them and passes the
    user's on. ``BoundMonitor`` reads it as it reads a :class:`MocapVelocityTracker`.

    Args:
        model: The predictor's model.
        runtime: ``() -> dua_mujoco._core.Runtime``, the predictor's runtime.
    """

    def __init__(self, model: mujoco.MjModel, runtime: Callable[[], Any]) -> None:
        self._model = model
        self._runtime = runtime
        mocapid = np.asarray(model.body_mocapid, dtype=np.int64)
        bodies = np.flatnonzero(mocapid >= 0)
        self.mocap_bodies: np.ndarray = bodies[np.argsort(mocapid[bodies])]
        """``(nmocap,)`` body ids of mocap bodies, ordered by mocap id."""

    def _native(self) -> _core.Mocap:
        return self._runtime().mocap

    def _mocap_index(self, body: int | str) -> int:
        if isinstance(body, str):
            bid = mujoco.mj_name2id(self._model, int(mujoco.mjtObj.mjOBJ_BODY), body)
        else:
            bid = int(body)
        hits = np.flatnonzero(self.mocap_bodies == bid)
        if hits.size == 0:
            names = [self._model.body(int(b)).name for b in self.mocap_bodies]
            raise InvalidChoiceError("mocap body", body, names)
        return int(hits[0])

    def set_velocity(
        self, body: int | str, linear: npt.ArrayLike, angular: npt.ArrayLike = (0.0, 0.0, 0.0)
    ) -> None:
        """Use a known velocity for a mocap body instead of differencing (world frame), until
        :meth:`clear_velocity`; a reset keeps it.

        Args:
            body: body id or name (must be a mocap body).
            linear: ``(3,)`` world velocity of the body frame origin.
            angular: ``(3,)`` world angular velocity.
        """
        lin = np.asarray(linear, dtype=np.float64).reshape(3)
        ang = np.asarray(angular, dtype=np.float64).reshape(3)
        self._native().set_velocity(self._mocap_index(body), lin, ang)

    def clear_velocity(self, body: int | str) -> None:
        """Go back to differencing for ``body``."""
        self._native().clear_velocity(self._mocap_index(body))

    @property
    def linear(self) -> np.ndarray:
        """``(nmocap, 3)`` linear velocity of each mocap body's frame origin (world; a copy)."""
        return np.asarray(self._native().linear)

    @property
    def angular(self) -> np.ndarray:
        """``(nmocap, 3)`` angular velocity of each mocap body (world; a copy)."""
        return np.asarray(self._native().angular)

    @property
    def twist(self) -> np.ndarray:
        """``(nbody, 6)`` spatial velocity ``[omega; v_origin]`` of each mocap body, zero for the
        others: what the kinematics kernel adds to the points of their trees (a read-only view,
        current until the next update)."""
        return np.asarray(self._native().twist)

    @property
    def nupdates(self) -> int:
        """Pose records since the last reset (its own included)."""
        return int(self._native().updates)

    def body_velocity(self, nbody: int) -> np.ndarray:
        """``(nbody, 6)`` spatial velocity [omega; v_origin] per body, zero for the others (a
        copy of :attr:`twist`)."""
        return np.array(self.twist[:nbody])


class MocapVelocityTracker(PredictorMocap):
    """Velocities of mocap bodies by backward differences, or as given by the user, for a
    rollout without a predictor (the pilot, a monitor, tests).

    Call :meth:`update` once after every ``mj_step`` (before or after the predictor; the tracker
    only reads). User-supplied velocities (:meth:`set_velocity`) override differencing for that
    body until :meth:`clear_velocity`.
    """

    def __init__(self, model: mujoco.MjModel) -> None:
        super().__init__(model, lambda: None)
        self._state = _core.Mocap(model)

    def _native(self) -> _core.Mocap:
        return self._state

    def update(self, data: mujoco.MjData) -> None:
        """Difference the mocap poses of ``data`` (after ``mj_step``, ``mj_forward`` or
        ``mj_kinematics``) against the previous call's (the first call records them). A call at
        the same ``data.time`` as the previous one keeps the previous velocities (no time
        elapsed, nothing to difference)."""
        self._native().update(data)

    def reset(self) -> None:
        """Forget the pose history (a new trajectory starts); user velocities are kept.

        The next :meth:`update` only records the pose: differenced velocities are zero until
        the one after.
        """
        self._native().reset()
