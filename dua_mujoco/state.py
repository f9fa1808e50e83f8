"""Sphere centres and velocities from ``MjData``, vectorised, for selected spheres.

The array functions (:func:`sphere_centers`, :func:`point_velocities`, :func:`sphere_velocities`)
take plain arrays so that a numba kernel can mirror them one to one; :class:`SphereState` is the
convenience front that reads them from ``(MjModel, MjData)``.

**Which instant.** After ``mj_step`` with the Euler, implicit and implicitfast integrators,
``d.geom_xpos``, ``d.geom_xmat``, ``d.cvel`` and ``d.subtree_com`` were computed at the *start* of
that step (from the ``qpos``/``qvel`` the step began with), while ``d.qpos``/``d.qvel`` hold the
integrated state. Centres and velocities read here therefore describe one consistent instant. With
RK4, ``mj_step`` leaves the kinematics of its last stage in ``MjData`` (``qpos0 + h * k3``), which
agrees with the end-of-step state to O(h^5) but is not exactly it; it is still one consistent
instant for positions and velocities (see ``docs/discrete-time.md``).

**Mocap bodies** have no velocity in ``MjData`` (their ``cvel`` is zero):
:class:`MocapVelocityTracker` supplies it by backward differences, or from the user.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import mujoco
import numba as nb
import numpy as np
import numpy.typing as npt

from dua_mujoco.exceptions import InvalidChoiceError, NonFiniteStateError, ShapeError

__all__ = [
    "MocapVelocityTracker",
    "SphereState",
    "mocap_sphere_velocities",
    "point_velocities",
    "sphere_centers",
    "sphere_velocities",
]


def _select(ids: npt.ArrayLike | None, n: int) -> np.ndarray:
    """Return sphere ids as an int64 array (all ``n`` spheres when ``ids`` is None)."""
    if ids is None:
        return np.arange(n, dtype=np.int64)
    out = np.asarray(ids, dtype=np.int64).reshape(-1)
    if out.size and (out.min() < 0 or out.max() >= n):
        raise ShapeError(f"sphere ids must lie in [0, {n}); got range [{out.min()}, {out.max()}].")
    return out


def sphere_centers(
    geom_xpos: npt.ArrayLike,
    geom_xmat: npt.ArrayLike,
    sphere_geom: npt.ArrayLike,
    sphere_offset: npt.ArrayLike,
    ids: npt.ArrayLike | None = None,
) -> np.ndarray:
    """World positions of sphere centres.

    centre_i = geom_xpos[g] + R_g @ sphere_offset[i], g = sphere_geom[i].

    Args:
        geom_xpos: ``(ngeom, 3)`` geom positions (``d.geom_xpos``).
        geom_xmat: ``(ngeom, 9)`` or ``(ngeom, 3, 3)`` row-major geom rotations (``d.geom_xmat``).
        sphere_geom: ``(nsphere,)`` geom id of every sphere.
        sphere_offset: ``(nsphere, 3)`` sphere centre in its geom's frame.
        ids: ``(n,)`` sphere ids to evaluate; None for all spheres.

    Returns:
        ``(n, 3)`` float64 centres, in the order of ``ids``.
    """
    xpos = np.asarray(geom_xpos, dtype=np.float64)
    xmat = np.asarray(geom_xmat, dtype=np.float64).reshape(-1, 3, 3)
    sgeom = np.asarray(sphere_geom, dtype=np.int64)
    offset = np.asarray(sphere_offset, dtype=np.float64).reshape(-1, 3)
    if offset.shape[0] != sgeom.shape[0]:
        raise ShapeError(
            f"sphere_offset has {offset.shape[0]} rows but sphere_geom has {sgeom.shape[0]}."
        )
    sel = _select(ids, sgeom.shape[0])
    g = sgeom[sel]
    # einsum over the selection only: row-major R @ offset for every selected sphere.
    return xpos[g] + np.einsum("nij,nj->ni", xmat[g], offset[sel])


def point_velocities(
    cvel: npt.ArrayLike,
    subtree_com: npt.ArrayLike,
    body_rootid: npt.ArrayLike,
    body: npt.ArrayLike,
    points: npt.ArrayLike,
) -> np.ndarray:
    """World-frame linear velocities of points fixed to bodies.

    ``d.cvel[b]`` is the spatial velocity [omega; v_ref] of body ``b`` in the global frame, whose
    linear part is the velocity of the point of ``b`` (rigidly extended) located at
    ``d.subtree_com[m.body_rootid[b]]``; hence v(p) = v_ref + omega x (p - p_ref).

    Args:
        cvel: ``(nbody, 6)`` ``d.cvel``.
        subtree_com: ``(nbody, 3)`` ``d.subtree_com``.
        body_rootid: ``(nbody,)`` ``m.body_rootid``.
        body: ``(n,)`` body id of every point.
        points: ``(n, 3)`` world positions of the points.

    Returns:
        ``(n, 3)`` float64 velocities.
    """
    cv = np.asarray(cvel, dtype=np.float64).reshape(-1, 6)
    com = np.asarray(subtree_com, dtype=np.float64).reshape(-1, 3)
    root = np.asarray(body_rootid, dtype=np.int64)
    b = np.asarray(body, dtype=np.int64).reshape(-1)
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if p.shape[0] != b.shape[0]:
        raise ShapeError(f"points has {p.shape[0]} rows but body has {b.shape[0]} entries.")
    omega = cv[b, :3]
    return cv[b, 3:] + np.cross(omega, p - com[root[b]])


def sphere_velocities(
    cvel: npt.ArrayLike,
    subtree_com: npt.ArrayLike,
    body_rootid: npt.ArrayLike,
    sphere_body: npt.ArrayLike,
    centers: npt.ArrayLike,
    ids: npt.ArrayLike | None = None,
) -> np.ndarray:
    """Velocities of sphere centres (bodies moved by joints; mocap bodies read zero here).

    Args:
        cvel: ``(nbody, 6)`` ``d.cvel``.
        subtree_com: ``(nbody, 3)`` ``d.subtree_com``.
        body_rootid: ``(nbody,)`` ``m.body_rootid``.
        sphere_body: ``(nsphere,)`` body id of every sphere.
        centers: ``(n, 3)`` centres of the spheres ``ids`` (from :func:`sphere_centers`).
        ids: ``(n,)`` sphere ids; None for all spheres.

    Returns:
        ``(n, 3)`` float64 velocities, in the order of ``ids``.
    """
    sbody = np.asarray(sphere_body, dtype=np.int64)
    sel = _select(ids, sbody.shape[0])
    return point_velocities(cvel, subtree_com, body_rootid, sbody[sel], centers)


_NO_TWIST = np.zeros((0, 6))


@nb.njit(cache=True)
def _difference_poses(
    xpos, xquat, bodies, prev_pos, prev_quat, dt, user, linear, angular, twist
):  # pragma: no cover - jitted
    """Backward-difference velocities of ``bodies``; updates the previous poses in place.

    Angular velocity: rotation vector of ``q_now * conj(q_prev)`` (world frame), taken the short
    way round, divided by ``dt``. If ``twist`` has rows, row ``bodies[i]`` receives
    ``[angular[i]; linear[i]]`` (what ``write_body_velocity`` does, without a second call).
    """
    for i in range(bodies.shape[0]):
        b = bodies[i]
        aw, ax, ay, az = xquat[b, 0], xquat[b, 1], xquat[b, 2], xquat[b, 3]
        bw, bx, by, bz = prev_quat[i, 0], -prev_quat[i, 1], -prev_quat[i, 2], -prev_quat[i, 3]
        w = aw * bw - ax * bx - ay * by - az * bz
        x = aw * bx + ax * bw + ay * bz - az * by
        y = aw * by - ax * bz + ay * bw + az * bx
        z = aw * bz + ax * by - ay * bx + az * bw
        if w < 0.0:
            w, x, y, z = -w, -x, -y, -z
        s = math.sqrt(x * x + y * y + z * z)
        scale = 2.0 * math.atan2(s, w) / s if s > 1e-12 else 2.0
        if not user[i]:
            for k in range(3):
                linear[i, k] = (xpos[b, k] - prev_pos[i, k]) / dt
            angular[i, 0] = x * scale / dt
            angular[i, 1] = y * scale / dt
            angular[i, 2] = z * scale / dt
        for k in range(3):
            prev_pos[i, k] = xpos[b, k]
        for k in range(4):
            prev_quat[i, k] = xquat[b, k]
        if twist.shape[0] > 0:
            for k in range(3):
                twist[b, k] = angular[i, k]
                twist[b, 3 + k] = linear[i, k]


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


def mocap_sphere_velocities(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    tracker: MocapVelocityTracker,
    sphere_body: npt.ArrayLike,
    centers: npt.ArrayLike,
    ids: npt.ArrayLike | None = None,
) -> np.ndarray:
    """Velocity contribution of mocap motion to sphere centres.

    For a sphere in a kinematic tree rooted at a mocap body m (the mocap body itself, or a
    descendant), ``cvel`` treats m as static, so the true velocity is the cvel one plus the rigid
    velocity field of m: v_m + omega_m x (p - x_m). Spheres outside mocap trees get zero.

    Args:
        model: the MuJoCo model.
        data: the MuJoCo data (for ``d.xpos`` of the mocap roots).
        tracker: an up-to-date :class:`MocapVelocityTracker`.
        sphere_body: ``(nsphere,)`` body id of every sphere.
        centers: ``(n, 3)`` centres of spheres ``ids``.
        ids: ``(n,)`` sphere ids; None for all.

    Returns:
        ``(n, 3)`` velocities to add to :func:`sphere_velocities`.
    """
    sbody = np.asarray(sphere_body, dtype=np.int64)
    sel = _select(ids, sbody.shape[0])
    p = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    root = np.asarray(model.body_rootid, dtype=np.int64)[sbody[sel]]
    bv = tracker.body_velocity(model.nbody)[root]
    origin = np.asarray(data.xpos)[root]
    return bv[:, 3:] + np.cross(bv[:, :3], p - origin)


@dataclass(frozen=True)
class SphereState:
    """Centres and velocities of selected spheres at one instant.

    Attributes:
        ids: ``(n,)`` sphere ids.
        centers: ``(n, 3)`` world centres.
        velocities: ``(n, 3)`` world velocities of the centres.
        time: ``d.time`` when read (after ``mj_step`` the kinematics are one step older, see the
            module docstring).
    """

    ids: np.ndarray
    centers: np.ndarray
    velocities: np.ndarray
    time: float

    @classmethod
    def from_data(
        cls,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        sphere_geom: npt.ArrayLike,
        sphere_body: npt.ArrayLike | None,
        sphere_offset: npt.ArrayLike,
        ids: npt.ArrayLike | None = None,
        *,
        mocap: MocapVelocityTracker | None = None,
        check_finite: bool = True,
    ) -> SphereState:
        """Read sphere centres and velocities from ``data``.

        Args:
            model: the MuJoCo model.
            data: the MuJoCo data (kinematics and velocities computed).
            sphere_geom: ``(nsphere,)`` geom id of every sphere.
            sphere_body: ``(nsphere,)`` body id of every sphere; None for
                ``model.geom_bodyid[sphere_geom]``.
            sphere_offset: ``(nsphere, 3)`` centre in the geom frame.
            ids: ``(n,)`` sphere ids to read; None for all.
            mocap: tracker supplying mocap velocities; None leaves mocap-driven spheres at the
                (zero) velocity MjData reports.
            check_finite: raise :class:`~dua_mujoco.exceptions.NonFiniteStateError` on NaN/inf.

        Returns:
            The state of spheres ``ids``.
        """
        sgeom = np.asarray(sphere_geom, dtype=np.int64)
        sbody = (
            np.asarray(model.geom_bodyid, dtype=np.int64)[sgeom]
            if sphere_body is None
            else np.asarray(sphere_body, dtype=np.int64)
        )
        sel = _select(ids, sgeom.shape[0])
        c = sphere_centers(data.geom_xpos, data.geom_xmat, sgeom, sphere_offset, sel)
        v = sphere_velocities(data.cvel, data.subtree_com, model.body_rootid, sbody, c, sel)
        if mocap is not None and mocap.mocap_bodies.size:
            v = v + mocap_sphere_velocities(model, data, mocap, sbody, c, sel)
        if check_finite and not (np.isfinite(c).all() and np.isfinite(v).all()):
            raise NonFiniteStateError(
                "Sphere centres or velocities are NaN/inf: the simulation diverged or "
                "mj_forward/mj_step was not called. Reset the data or reduce the timestep."
            )
        return cls(ids=sel, centers=c, velocities=v, time=float(data.time))

    def as_dict(self) -> dict[str, Any]:
        """Plain-dict view (for logging)."""
        return {"ids": self.ids, "centers": self.centers, "velocities": self.velocities}
