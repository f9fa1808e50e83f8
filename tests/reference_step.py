"""An independent slow reference of the step: the earliest contact a declared motion allows.

A sound tau never exceeds the earliest time at which the declared motion model *allows* a
contact. This module bounds that time from above, for a pair of geoms at a state of ``MjData``,
by constructing one explicit motion the model allows and finding, with MuJoCo's own
``mj_geomDistance`` on the moved poses, the first time it brings the two geoms within their
contact distance. Whatever the runtime computes, its tau for the pair must not be later (up to
rounding): the motion is a counterexample to any later tau. It shares no code with the package:
MuJoCo's positions (``geom_xpos``, ``geom_xmat``), velocities (``mj_objectVelocity``), distances
(``mj_geomDistance``) and the model's numbers, with numpy.

The motion model (docs/theory.md, section 1; docs/discrete-time.md): every point of a moving
body ``b``'s geoms accelerates at most ``A_b``, moves at most ``V_b`` fast (when a speed bound is
declared), and its velocity may differ from the one MuJoCo reports by ``delta_b``; ``delta_b =
A_b h / 2`` is the discrete-time term of docs/discrete-time.md (a continuous motion with these
bounds, sampled at the step times, keeps the discrete hypotheses (H1)-(H3) with ``D = delta_b +
A_b h / 2``). Bodies welded to the world do not move.

The motion of a geom ``g`` of body ``b`` (``rigid_motion``): the body keeps rotating at its
measured angular velocity ``w`` about ``g``'s origin, whose velocity is the measured one plus
``delta_b`` along a unit direction ``n``, and which accelerates at ``a`` along ``n``. A point at
``r`` from the origin then accelerates by ``a n + w x (w x r)``, at most ``a + |w|^2 r``: with
``r_max`` the farthest point of the body's geoms from ``g``'s origin, ``a = A_b - |w|^2 r_max``
keeps every point of the body within its bound (a body spinning so fast that ``a < 0`` has no
such motion: its pairs are left out). With a speed bound the acceleration stops once the
origin's speed plus ``|w| r_max`` reaches ``V_b``. The two geoms of a pair move towards each
other, the first along ``n`` and the second along ``-n``, ``n`` from the first to the second:
``PairReference`` tries the witness direction of MuJoCo's distance now, and the one between the
geoms where their measured motion alone puts them at the tau checked (for two spheres, the
direction of the extremal motion when that tau is right).

Contact: MuJoCo lists a contact when the signed distance is at most ``margin + gap`` (the pair's
own, or the two geoms' sums; docs/covering-and-pairs.md): ``contact_distance``. A motion counts
as in contact only when MuJoCo's distance is below that by more than its convex distances' error
(``PairReference``'s ``depth``). A tau is late when a motion is in contact at the time checked,
just below it, or, by conservative advancement, at any earlier time: the distance falls no
faster than the two geoms' points move apart (their origins' speeds, with the acceleration up
to the end, plus ``|w| rbound``), so a step of the distance over that speed never steps over a
contact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

_GEOM = int(mujoco.mjtObj.mjOBJ_GEOM)
UNSUPPORTED = {int(mujoco.mjtGeom.mjGEOM_HFIELD), int(mujoco.mjtGeom.mjGEOM_SDF)}


@dataclass(frozen=True)
class Declared:
    """The declared motion model, per body (``(nbody,)`` each).

    Attributes:
        accel: ``A_b``, a bound on the acceleration of every point of the body's geoms.
        delta: ``delta_b``, how far the true velocity may be from the one MuJoCo reports.
        speed: ``V_b`` (None: no speed bound).
    """

    accel: np.ndarray
    delta: np.ndarray
    speed: np.ndarray | None = None


def moving(model: mujoco.MjModel) -> np.ndarray:
    """``(nbody,)`` bool: bodies not welded to the world, and bodies of a mocap tree."""
    weld = np.asarray(model.body_weldid)
    mocap_root = np.asarray(model.body_mocapid)[np.asarray(model.body_rootid)] >= 0
    return (weld != 0) | mocap_root


def declared(model: mujoco.MjModel, accel: float, speed: float | None = None) -> Declared:
    """One acceleration bound (and speed bound) for every moving body, with the discrete-time
    term ``delta = A h / 2`` of an Euler-type integrator (docs/discrete-time.md, section 3)."""
    on = moving(model).astype(float)
    a = accel * on
    v = None if speed is None else np.where(on > 0, speed, 0.0)
    return Declared(accel=a, delta=a * float(model.opt.timestep) / 2, speed=v)


def contact_distance(model: mujoco.MjModel, g1: int, g2: int) -> float:
    """The signed distance at or below which MuJoCo lists a contact of ``g1`` and ``g2``:
    an explicit ``<pair>``'s margin + gap, else the sums of the geoms' (the override's margin
    when ``mjENBL_OVERRIDE`` is on)."""
    for k in range(model.npair):
        if {int(model.pair_geom1[k]), int(model.pair_geom2[k])} == {g1, g2}:
            return float(model.pair_margin[k] + model.pair_gap[k])
    margin = float(model.geom_margin[g1] + model.geom_margin[g2])
    if model.opt.enableflags & int(mujoco.mjtEnableBit.mjENBL_OVERRIDE):
        margin = float(model.opt.o_margin)
    return margin + float(model.geom_gap[g1] + model.geom_gap[g2])


def _rotation(w: np.ndarray, t: float) -> np.ndarray:
    """exp(t [w]x), Rodrigues."""
    angle = float(np.linalg.norm(w)) * t
    if angle == 0.0:
        return np.eye(3)
    k = w / np.linalg.norm(w)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * kx + (1.0 - math.cos(angle)) * (kx @ kx)


@dataclass
class GeomState:
    """A geom's pose and motion as MuJoCo reports them, and what its body may add."""

    geom: int
    pos: np.ndarray  # (3,) origin
    mat: np.ndarray  # (3, 3)
    omega: np.ndarray  # (3,) body angular velocity, world frame
    vel: np.ndarray  # (3,) origin velocity, world frame
    rbound: float  # farthest point of the geom from its origin
    static: bool
    accel: float  # what the body may add along a direction (A_b - |w|^2 r_max), < 0: none
    delta: float
    speed: float  # inf: none; the origin's speed cap (V_b - |w| r_max)

    @property
    def feasible(self) -> bool:
        """Whether the motion keeps the body's bounds: its rotation leaves room for the
        acceleration, and its origin starts within the speed cap."""
        if self.static:
            return True
        start = float(np.linalg.norm(self.vel)) + self.delta
        return self.accel >= 0.0 and start <= self.speed


def geom_state(model: mujoco.MjModel, data: mujoco.MjData, g: int, bounds: Declared) -> GeomState:
    """MuJoCo's pose and velocity of geom ``g`` and the room its body's bounds leave."""
    b = int(model.geom_bodyid[g])
    pos = np.array(data.geom_xpos[g])
    mat = np.array(data.geom_xmat[g]).reshape(3, 3)
    rb = float(model.geom_rbound[g])
    if not moving(model)[b]:
        zero = np.zeros(3)
        return GeomState(g, pos, mat, zero, zero, rb, True, 0.0, 0.0, math.inf)
    res = np.zeros(6)
    mujoco.mj_objectVelocity(model, data, _GEOM, g, res, 0)  # [omega; v(origin)], world
    omega, vel = res[:3].copy(), res[3:].copy()
    # The farthest point of the body's geoms from this origin.
    others = np.flatnonzero(np.asarray(model.geom_bodyid) == b)
    r_max = max(
        float(np.linalg.norm(np.asarray(data.geom_xpos[k]) - pos) + model.geom_rbound[k])
        for k in others
    )
    w2 = float(omega @ omega)
    accel = float(bounds.accel[b]) - w2 * r_max
    speed = math.inf
    if bounds.speed is not None:
        speed = float(bounds.speed[b]) - math.sqrt(w2) * r_max
    return GeomState(g, pos, mat, omega, vel, rb, False, accel, float(bounds.delta[b]), speed)


def rigid_motion(s: GeomState, n: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """The pose ``(pos, mat)`` at time ``t`` of the motion that pushes ``s`` along unit ``n``
    (module docstring): the rotation kept, the origin's velocity off by ``delta n`` and
    accelerating at ``accel n`` until its speed reaches the cap."""
    if s.static:
        return s.pos, s.mat
    u0 = s.vel + s.delta * n
    a = max(s.accel, 0.0)
    t_acc = t
    if math.isfinite(s.speed) and a > 0.0:
        # First time |u0 + a n t| reaches the cap (the acceleration stops there).
        b, c = float(u0 @ n), float(u0 @ u0) - s.speed**2
        disc = b * b - c
        t_cap = (-b + math.sqrt(disc)) / a if disc >= 0.0 else 0.0
        t_acc = min(t, max(t_cap, 0.0))
    pos = s.pos + u0 * t + a * n * (t_acc * t - 0.5 * t_acc * t_acc)
    return pos, _rotation(s.omega, t) @ s.mat


def _speed_bound(s: GeomState, t_end: float) -> float:
    """A bound on the speed of any point of the geom over [0, t_end] under ``rigid_motion``."""
    if s.static:
        return 0.0
    origin = min(float(np.linalg.norm(s.vel)) + s.delta + max(s.accel, 0.0) * t_end, s.speed)
    return origin + float(np.linalg.norm(s.omega)) * s.rbound


class PairProbe:
    """Distances of a geom pair along explicit motions, in a scratch copy of ``MjData``."""

    def __init__(self, model: mujoco.MjModel, scratch: mujoco.MjData) -> None:
        self.model = model
        self.scratch = scratch
        self.queries = 0
        self._fromto = np.zeros(6)

    def distance(
        self, a: GeomState, pa: tuple[np.ndarray, np.ndarray], b: GeomState, pb: tuple
    ) -> tuple[float, np.ndarray]:
        """MuJoCo's signed distance of the two geoms at poses ``pa``, ``pb``, and the unit
        direction from the first's witness point to the second's (zeros if none)."""
        d = self.scratch
        for s, (pos, mat) in ((a, pa), (b, pb)):
            d.geom_xpos[s.geom] = pos
            d.geom_xmat[s.geom] = mat.reshape(9)
        reach = float(np.linalg.norm(pb[0] - pa[0])) + a.rbound + b.rbound + 1.0
        self.queries += 1
        dist = mujoco.mj_geomDistance(self.model, d, a.geom, b.geom, reach, self._fromto)
        step = self._fromto[3:] - self._fromto[:3]
        norm = float(np.linalg.norm(step))
        direction = step / norm if norm > 1e-12 else np.zeros(3)
        if dist < 0.0:
            direction = -direction  # MuJoCo's segment points the other way in penetration
        return float(dist), direction


@dataclass(frozen=True)
class Verdict:
    """What the motions towards each other say about a pair, against the runtime's tau.

    Attributes:
        before: A time at which a motion the model allows has the pair in contact, earlier than
            the tau it was checked against (a counterexample), or None.
        at_horizon: A motion has the pair in contact now or at the horizon's step time.
        tight: A motion has the pair in contact at ``(1 + slack)`` times the tau (so a tau
            raised by that much would be a counterexample).
        covered: The advancement covered [0, tau] (else it crept near a touch and gave up).
    """

    before: float | None
    at_horizon: bool
    tight: bool
    covered: bool


class PairReference:
    """Checks a pair's tau against explicit motions (module docstring).

    Args:
        probe: Distances in a scratch ``MjData``.
        horizon: The alarm horizon (s): a contact at it must stand in alarm.
        t_max: Motions are followed this long at most.
        slack: ``Verdict.tight``'s factor.
        depth: A motion is in contact when MuJoCo's distance is this far below the contact
            distance (default: ten times the model's ``ccd_tolerance``, the accuracy of
            MuJoCo's convex distances; its analytic ones, box-box among them, err by far less).
    """

    def __init__(
        self,
        probe: PairProbe,
        horizon: float,
        t_max: float = 0.25,
        slack: float = 0.5,
        depth: float | None = None,
    ) -> None:
        self.probe = probe
        self.horizon = horizon
        self.t_max = t_max
        self.slack = slack
        self.depth = 10.0 * float(probe.model.opt.ccd_tolerance) if depth is None else depth

    def _gap(self, a: GeomState, b: GeomState, n: np.ndarray, m: float, t: float) -> float:
        """MuJoCo's distance along the motion at ``t``, less the contact distance and ``depth``
        (<= 0: in contact, surely)."""
        pa, pb = rigid_motion(a, n, t), rigid_motion(b, -n, t)
        return self.probe.distance(a, pa, b, pb)[0] - m + self.depth

    def _directions(self, a: GeomState, b: GeomState, n0: np.ndarray, guess: float) -> list:
        """MuJoCo's witness direction now, and the one between the geoms where their measured
        motion alone puts them at ``guess`` (the direction of the extremal motion of two
        spheres, when ``guess`` is their tau)."""
        out = [n0]
        if 0.0 < guess < math.inf:
            still = [GeomState(**{**s.__dict__, "accel": 0.0, "delta": 0.0}) for s in (a, b)]
            zero = np.zeros(3)
            pa, pb = rigid_motion(still[0], zero, guess), rigid_motion(still[1], zero, guess)
            out.append(self.probe.distance(a, pa, b, pb)[1])
        units = []
        for n in out:
            if not n.any():
                n = b.pos - a.pos
            norm = float(np.linalg.norm(n))
            if norm > 0.0:
                units.append(n / norm)
        return units

    def _first(self, a: GeomState, b: GeomState, n: np.ndarray, m: float, t_end: float):
        """A time in [0, t_end] at which the motion along ``n`` is in contact, or None, and
        whether [0, t_end] was covered. The end first (the motions approach), then
        conservative advancement for a pass through before it."""
        if self._gap(a, b, n, m, t_end) <= 0.0:
            return t_end, True
        speed = _speed_bound(a, t_end) + _speed_bound(b, t_end)
        t = 0.0
        for _ in range(60):
            gap = self._gap(a, b, n, m, t)
            if gap <= 0.0:
                return t, True
            if speed == 0.0 or t + gap / speed >= t_end:
                return None, True
            t += gap / speed
        return None, False

    def check(
        self,
        a: GeomState,
        b: GeomState,
        m: float,
        tau: float,
        rtol: float = 1e-9,
        atol: float = 1e-12,
    ) -> Verdict:
        """The pair ``(a, b)`` (contact distance ``m``) against the runtime's ``tau``: a
        contact earlier than ``tau`` up to rounding (``rtol``, ``atol``) is a counterexample."""
        gap0, n0 = self.probe.distance(a, (a.pos, a.mat), b, (b.pos, b.mat))
        t_check = tau / (1.0 + rtol) - atol
        if gap0 - m + self.depth <= 0.0:
            return Verdict(0.0 if t_check > 0.0 else None, True, True, True)
        before, at_horizon, tight, covered = None, False, False, True
        t_end = min(t_check, self.t_max)
        for n in self._directions(a, b, n0, min(tau, self.t_max)):
            if t_end > 0.0:
                t, whole = self._first(a, b, n, m, t_end)
                covered &= whole
                if t is not None and (before is None or t < before):
                    before = t
            at_horizon |= self._gap(a, b, n, m, self.horizon) <= 0.0
            far = (1.0 + self.slack) * tau
            tight |= far <= self.t_max and self._gap(a, b, n, m, far) <= 0.0
        return Verdict(before, at_horizon, tight, covered)
