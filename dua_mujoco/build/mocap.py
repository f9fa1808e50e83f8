"""Velocities of mocap bodies, which MjData does not give: backward differences, or the user's.

**Mocap bodies** have no velocity in ``MjData`` (their ``cvel`` is zero): a tree rooted at a mocap
body moves rigidly with it, so the kinematics kernel adds the root's twist
(:meth:`MocapVelocityTracker.write_body_velocity`) to every point of the tree.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco._core import difference_poses
from dua_mujoco.exceptions import InvalidChoiceError, ShapeError

__all__ = ["MocapVelocityTracker", "PredictorMocap"]


_NO_TWIST = np.zeros((0, 6))


class MocapVelocityTracker:
    """Velocities of mocap bodies by backward differences, or as given by the user.

    Call :meth:`update` once after every ``mj_step`` (before or after the predictor; the tracker
    only reads). It differences ``d.xpos``/``d.xquat`` of the mocap bodies, not
    ``d.mocap_pos``/``d.mocap_quat``: the former are what ``geom_xpos`` was computed from at the
    last kinematics pass, so velocity and centres describe one instant even if the user already
    wrote the next ``mocap_pos`` (for a step they are equal to the mocap_pos used by that step).

    **Instant.** The differenced velocity at update k is (x_k - x_{k-1}) / (t_k - t_{k-1}), the
    mean velocity over the last interval, attached to the instant of x_k. For a scripted motion
    with |acceleration| <= A it is within A h / 2 of the true velocity at that instant, and it is
    exactly the discrete velocity u_k of ``docs/discrete-time.md``, so D = |u_{k+1} - u_k| <= A h
    and the integrator term delta = A h / 2 covers it. Before two updates the velocity is zero
    (or the user's value): declare a larger ``vel_uncertainty`` for the first step if the body is
    already moving.

    User-supplied velocities (:meth:`set_velocity`) override differencing for that body until
    :meth:`clear_velocity`.
    """

    def __init__(self, model: mujoco.MjModel) -> None:
        """Create a tracker for every mocap body of ``model``.

        Args:
            model: the MuJoCo model.
        """
        self._model = model
        mocapid = np.asarray(model.body_mocapid, dtype=np.int64)
        self.mocap_bodies: np.ndarray = np.flatnonzero(mocapid >= 0)
        """``(nmocap,)`` body ids of mocap bodies, ordered by mocap id."""
        self.mocap_bodies = self.mocap_bodies[np.argsort(mocapid[self.mocap_bodies])]
        n = self.mocap_bodies.size
        self.linear = np.zeros((n, 3))
        """``(nmocap, 3)`` linear velocity of each mocap body's frame origin (world)."""
        self.angular = np.zeros((n, 3))
        """``(nmocap, 3)`` angular velocity of each mocap body (world)."""
        self._user = np.zeros(n, dtype=bool)
        self._prev_pos: np.ndarray | None = None
        self._prev_quat: np.ndarray | None = None
        self._prev_time = 0.0
        self.nupdates = 0
        """Number of :meth:`update` calls that saw a new instant."""

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
        """Use a known velocity for a mocap body instead of differencing.

        Args:
            body: body id or name (must be a mocap body).
            linear: ``(3,)`` world velocity of the body frame origin.
            angular: ``(3,)`` world angular velocity.
        """
        i = self._mocap_index(body)
        self.linear[i] = np.asarray(linear, dtype=np.float64).reshape(3)
        self.angular[i] = np.asarray(angular, dtype=np.float64).reshape(3)
        self._user[i] = True

    def reset(self) -> None:
        """Forget the pose history (a new trajectory starts); user velocities are kept.

        The next :meth:`update` only records the pose: differenced velocities are zero until
        the one after.
        """
        self._prev_pos = None
        self._prev_quat = None
        self._prev_time = 0.0
        self.nupdates = 0
        self.linear[~self._user] = 0.0
        self.angular[~self._user] = 0.0

    def clear_velocity(self, body: int | str) -> None:
        """Go back to differencing for ``body``."""
        self._user[self._mocap_index(body)] = False

    def update(self, data: mujoco.MjData, body_velocity: np.ndarray | None = None) -> None:
        """Difference the mocap poses against the previous call.

        A call at the same ``data.time`` as the previous one keeps the previous velocities
        (no time elapsed, nothing to difference).

        Args:
            data: the MuJoCo data, after ``mj_step`` (or ``mj_forward``/``mj_kinematics``).
            body_velocity: Optional ``(nbody, 6)`` array whose mocap rows receive the new
                velocities, as :meth:`write_body_velocity` writes them (in the same compiled
                call: the predictor does this every step).
        """
        if body_velocity is not None and body_velocity.shape != (self._model.nbody, 6):
            # The compiled differencing writes rows without bounds checks.
            raise ShapeError(
                f"body_velocity has shape {body_velocity.shape}; expected "
                f"({self._model.nbody}, 6), one row per body of the model."
            )
        t = float(data.time)
        first = self._prev_pos is None or self._prev_quat is None
        dt = t - self._prev_time
        if first:
            self._prev_pos = np.array(data.xpos[self.mocap_bodies])
            self._prev_quat = np.array(data.xquat[self.mocap_bodies])
        elif dt > 0.0:
            assert self._prev_pos is not None and self._prev_quat is not None
            # The native core's differencing (the predictor's runtime runs the same), in place.
            difference_poses(
                data,
                self.mocap_bodies,
                self._prev_pos,
                self._prev_quat,
                dt,
                self._user.view(np.uint8),
                self.linear,
                self.angular,
                _NO_TWIST if body_velocity is None else body_velocity,
                self._model,
            )
        if (first or dt <= 0.0) and body_velocity is not None:
            self.write_body_velocity(body_velocity)
        if first or dt > 0.0:
            self._prev_time = t
            self.nupdates += 1

    def body_velocity(self, nbody: int) -> np.ndarray:
        """Spatial velocity [omega; v_origin] per body, zero for non-mocap bodies.

        Returns:
            ``(nbody, 6)`` array; row b of a mocap body holds its angular velocity and the
            linear velocity of its frame origin ``d.xpos[b]``.
        """
        out = np.zeros((nbody, 6))
        self.write_body_velocity(out)
        return out

    def write_body_velocity(self, out: np.ndarray) -> None:
        """Write the mocap rows of a ``(nbody, 6)`` spatial-velocity array in place."""
        out[self.mocap_bodies, :3] = self.angular
        out[self.mocap_bodies, 3:] = self.linear


class PredictorMocap:
    """The mocap velocities a :class:`~dua_mujoco.Predictor` steps with.

    Its native runtime differences the mocap poses at every predictor step (as
    :class:`MocapVelocityTracker` does, with the same kernel); this object reads the runtime's
    velocities and passes the user's on. ``BoundMonitor`` reads it as it reads a tracker.

    Args:
        model: The predictor's model.
        runtime: ``() -> dua_mujoco._core.Runtime``, the predictor's runtime.
    """

    def __init__(self, model: mujoco.MjModel, runtime: Callable[[], Any]) -> None:
        self._bodies = MocapVelocityTracker(model)  # the mocap bodies and their names
        self.mocap_bodies = self._bodies.mocap_bodies
        """``(nmocap,)`` body ids of mocap bodies, ordered by mocap id."""
        self._runtime = runtime

    def set_velocity(
        self, body: int | str, linear: npt.ArrayLike, angular: npt.ArrayLike = (0.0, 0.0, 0.0)
    ) -> None:
        """Use a known velocity for a mocap body instead of differencing (world frame), until
        :meth:`clear_velocity`; a reset keeps it."""
        i = self._bodies._mocap_index(body)
        lin = np.asarray(linear, dtype=np.float64).reshape(3)
        ang = np.asarray(angular, dtype=np.float64).reshape(3)
        self._runtime().set_mocap_velocity(i, lin, ang)

    def clear_velocity(self, body: int | str) -> None:
        """Go back to differencing for ``body``."""
        self._runtime().clear_mocap_velocity(self._bodies._mocap_index(body))

    @property
    def linear(self) -> np.ndarray:
        """``(nmocap, 3)`` linear velocity of each mocap body's frame origin (a copy)."""
        return np.asarray(self._runtime().mocap_velocity[0])

    @property
    def angular(self) -> np.ndarray:
        """``(nmocap, 3)`` angular velocity of each mocap body (a copy)."""
        return np.asarray(self._runtime().mocap_velocity[1])

    @property
    def nupdates(self) -> int:
        """Pose records since the predictor's reset (the reset's one included)."""
        return int(self._runtime().mocap_updates)

    def body_velocity(self, nbody: int) -> np.ndarray:
        """``(nbody, 6)`` spatial velocity [omega; v_origin] per body, zero for the others."""
        out = np.zeros((nbody, 6))
        self.write_body_velocity(out)
        return out

    def write_body_velocity(self, out: np.ndarray) -> None:
        """Write the mocap rows of a ``(nbody, 6)`` spatial-velocity array in place."""
        lin, ang, _ = self._runtime().mocap_velocity
        out[self.mocap_bodies, :3] = ang
        out[self.mocap_bodies, 3:] = lin
