"""Velocities of mocap bodies, which MjData does not give: backward differences, or the user's.

**Mocap bodies** have no velocity in ``MjData`` (their ``cvel`` is zero): a tree rooted at a mocap
body moves rigidly with it, so the kinematics kernel adds the root's twist
(:meth:`MocapVelocityTracker.write_body_velocity`) to every point of the tree.
"""

from __future__ import annotations

import mujoco
import numba as nb
import numpy as np
import numpy.typing as npt

from dua_mujoco.core.native_kernels import difference_poses_c
from dua_mujoco.exceptions import InvalidChoiceError, ShapeError

__all__ = ["MocapVelocityTracker"]


_NO_TWIST = np.zeros((0, 6))


@nb.njit(cache=True)
def _difference_poses(
    xpos, xquat, bodies, prev_pos, prev_quat, dt, user, linear, angular, twist
):  # pragma: no cover - jitted
    """Backward-difference velocities of ``bodies``; updates the previous poses in place
    (native: ``dua_difference_poses``, which the plugin runs too; every array C-contiguous).

    Angular velocity: rotation vector of ``q_now * conj(q_prev)`` (world frame), taken the short
    way round, divided by ``dt``. If ``twist`` has rows, row ``bodies[i]`` receives
    ``[angular[i]; linear[i]]`` (what ``write_body_velocity`` does, without a second call).
    """
    difference_poses_c(
        xpos.ctypes,
        xquat.ctypes,
        bodies.ctypes,
        bodies.shape[0],
        prev_pos.ctypes,
        prev_quat.ctypes,
        dt,
        user.ctypes,
        linear.ctypes,
        angular.ctypes,
        twist.ctypes,
        twist.shape[0],
    )


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
            # Called every predictor step: jitted, in place, no temporaries.
            _difference_poses(
                data.xpos,
                data.xquat,
                self.mocap_bodies,
                self._prev_pos,
                self._prev_quat,
                dt,
                self._user,
                self.linear,
                self.angular,
                _NO_TWIST if body_velocity is None else body_velocity,
            )
        if (first or dt <= 0.0) and body_velocity is not None:
            self.write_body_velocity(body_velocity)
        if first or dt > 0.0:
            self._prev_time = t
            self.nupdates += 1

    def load_compiled(self, data: mujoco.MjData, body_velocity: np.ndarray) -> None:
        """Run the compiled differencing once on copies (loads it; changes no state)."""
        n = self.mocap_bodies.size
        _difference_poses(
            data.xpos,
            data.xquat,
            self.mocap_bodies,
            np.array(data.xpos[self.mocap_bodies]),
            np.array(data.xquat[self.mocap_bodies]),
            1.0,
            self._user.copy(),
            np.zeros((n, 3)),
            np.zeros((n, 3)),
            np.zeros_like(body_velocity),
        )

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
