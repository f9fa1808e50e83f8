"""Motion bounds: declared or estimated per body, the discrete-time term, and violation checks.

A sphere pair's urgency uses ``A = A_i + A_j`` and ``delta = delta_i + delta_j`` (relative
accelerations and velocity discrepancies are sums of per-sphere ones). The guarantee is stated
on the positions MuJoCo produces at its steps: with ``u_k = (c_k - c_{k-1}) / h`` the chord
velocity of a sphere centre on body ``b`` and ``w_k`` the velocity read with ``c_k``, the
hypotheses are ``|u_{k+1} - u_k| <= A_b h``, ``|u_{k+1} - w_k| <= delta_b + A_b h / 2`` and
optionally ``|u_k| <= V_b`` (docs/discrete-time.md); :class:`BoundMonitor` checks exactly these.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Literal

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco.build.kinematics import PointMotion, pack_spheres
from dua_mujoco.build.mocap import MocapVelocityTracker
from dua_mujoco.build.pilot_screen import MotionScreen, PilotMotion, level_maxima
from dua_mujoco.core.validate import as_choice
from dua_mujoco.exceptions import (
    InvalidBoundError,
    InvalidChoiceError,
    InvalidInputError,
    PilotWarning,
)

__all__ = [
    "DIVERGENCE_WARNINGS",
    "BoundSpec",
    "MotionBounds",
    "PilotMotion",
    "default_spheres",
    "discrete_velocity_uncertainty",
    "estimate_bounds",
    "moving_bodies",
    "resolve_bounds",
    "with_speed",
]

BoundSpec = float | Mapping[str, float]
"""A bound given as one scalar for every moving body, or a dict by body name (``"*"``: default)."""


def moving_bodies(model: mujoco.MjModel) -> np.ndarray:
    """``(nbody,)`` bool, True for the bodies that can move.

    A body is static when it is welded to the world (``body_weldid == 0``) and its tree is not
    rooted at a mocap body. The world body is static.
    """
    weld = np.asarray(model.body_weldid)
    root = np.asarray(model.body_rootid)
    mocap_root = np.asarray(model.body_mocapid)[root] >= 0
    return (weld != 0) | mocap_root


def _body_names(model: mujoco.MjModel) -> list[str]:
    return [model.body(b).name for b in range(model.nbody)]


def _resolve(model: mujoco.MjModel, spec: BoundSpec, what: str) -> np.ndarray:
    """Turn a scalar/dict bound into ``(nbody,)``, validated; static bodies get 0."""
    moving = moving_bodies(model)
    names = _body_names(model)
    out = np.zeros(model.nbody)
    if isinstance(spec, Mapping):
        lookup = {n: i for i, n in enumerate(names) if n}
        for key in spec:
            if key != "*" and key not in lookup:
                raise InvalidChoiceError(
                    "body name",
                    key,
                    [n for n in names if n] + ["*"],
                    hint=f"Use one of these as a key of the {what} dict ('*' for a default).",
                )
        default = spec.get("*")
        for b in np.flatnonzero(moving):
            name = names[b]
            if name in spec:
                val = spec[name]
            elif default is not None:
                val = default
            else:
                missing = [
                    names[i] or f"<body {i}>"
                    for i in np.flatnonzero(moving)
                    if names[i] not in spec
                ]
                raise InvalidBoundError(
                    f"No {what} bound for moving bodies {missing}. Give every moving body a "
                    f"value, or add a '*' key as the default."
                )
            out[b] = _check_value(val, what, name or f"<body {b}>")
        # Values given for static bodies are checked but not used: they cannot move (so a
        # speed of 0 is fine there).
        moving_names = {names[b] for b in np.flatnonzero(moving)}
        for key, val in spec.items():
            if key != "*":
                _check_value(val, what, key, moving=key in moving_names)
        if default is not None:
            _check_value(default, what, "*", moving=False)
    else:
        val = _check_value(spec, what, None)
        out[moving] = val
    return out


# The keyword a scalar bound is given by (Predictor(accel=...), MotionBounds.declare(...)).
_KEYWORD = {"acceleration": "accel", "velocity uncertainty": "vel_uncertainty"}


def _check_value(value: object, what: str, body: str | None, *, moving: bool = True) -> float:
    """One bound, as a float: finite and >= 0; a speed bound may be inf (none), and must be
    > 0 for a moving body. ``body`` is None for a scalar bound (every moving body's): the
    message names the keyword then, not a body."""
    scalar = f"{_KEYWORD.get(what, what)} = {value!r} is invalid:" if body is None else ""
    bad_type = isinstance(value, str | bytes | bool | np.bool_)  # float() takes "5" and True
    try:
        val = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        bad_type = True
    if bad_type:
        raise InvalidBoundError(
            f"{scalar} it is not a number; pass a number, or a dict by body name ('*' for the "
            "default)."
            if scalar
            else f"The {what} bound of body {body!r} is {value!r}, not a number: pass a number "
            "for every body, or a dict by body name ('*' for the default)."
        )
    if what == "speed":
        if not (val > 0 or (val == 0 and not moving)):  # NaN too
            raise InvalidBoundError(
                f"{scalar} a speed bound must be > 0 (inf for none)."
                if scalar
                else f"The speed bound of body {body!r} is {value!r}; it must be > 0 (inf for "
                "no speed bound on that body)."
            )
    elif not np.isfinite(val) or val < 0:
        hint = " (use 0 for a body that does not accelerate)" if what == "acceleration" else ""
        raise InvalidBoundError(
            f"{scalar} a{'n' if what[0] in 'aeiou' else ''} {what} bound must be finite and "
            f">= 0{hint}."
            if scalar
            else f"The {what} bound of body {body!r} is {value!r}; it must be finite and "
            f">= 0{hint}."
        )
    return val


def discrete_velocity_uncertainty(
    model: mujoco.MjModel, accel: npt.ArrayLike, *, velocity_accel: npt.ArrayLike | None = None
) -> np.ndarray:
    """The velocity-uncertainty term delta that makes tau valid at MuJoCo's step times.

    ``delta = (A + C) h / 2`` (derivation in docs/discrete-time.md): it bounds the one-step
    discrepancy between the next chord velocity and the velocity ``MjData`` reports, tight for
    the Euler, implicit and implicitfast integrators and conservative (by about ``A h / 2``) for
    RK4. ``C >= |a_v|`` bounds the velocity-product (centripetal/Coriolis) acceleration of the
    points: 0 is exact for slide-only chains and right to first order for one hinge; chains and
    ball or free joints need it given, or :func:`estimate_bounds`, which measures the discrepancy.

    Args:
        model: the MuJoCo model (its integrator and timestep).
        accel: ``(nbody,)`` acceleration bounds A.
        velocity_accel: ``(nbody,)`` bounds C on the velocity-product acceleration of sphere
            centres; None for 0.

    Returns:
        ``(nbody,)`` delta per body.
    """
    A = np.asarray(accel, dtype=np.float64).reshape(-1)
    if A.shape[0] != model.nbody:
        raise InvalidInputError(f"accel must have shape ({model.nbody},); got {A.shape}.")
    C = (
        np.zeros_like(A)
        if velocity_accel is None
        else np.broadcast_to(np.asarray(velocity_accel, dtype=np.float64), A.shape)
    )
    h = float(model.opt.timestep)
    integ = int(model.opt.integrator)
    known = {
        int(mujoco.mjtIntegrator.mjINT_EULER),
        int(mujoco.mjtIntegrator.mjINT_IMPLICIT),
        int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST),
        int(mujoco.mjtIntegrator.mjINT_RK4),
    }
    if integ not in known:
        raise InvalidChoiceError("integrator", integ, sorted(known))
    # Same expression for all four: tight for the semi-implicit ones, conservative for RK4.
    return 0.5 * h * (A + C)


@dataclass(frozen=True)
class MotionBounds:
    """Per-body motion bounds for the covering-sphere centres of each body.

    Attributes:
        accel: ``(nbody,)`` bound A on the (discrete) acceleration norm of every sphere centre
            of the body; 0 for static bodies.
        speed: ``(nbody,)`` bound V on the chord speed |c_k - c_{k-1}| / h of every sphere
            centre (inf: none for that body), or None.
        vel_uncertainty: ``(nbody,)`` delta: discrete-time term (plus any user term).
        source: ``"declared"`` or ``"auto"`` (estimated by a pilot rollout).
        timestep: the model timestep h these bounds were made for.
    """

    accel: np.ndarray
    speed: np.ndarray | None
    vel_uncertainty: np.ndarray
    source: Literal["declared", "auto"] = "declared"
    timestep: float = 0.0
    body_names: tuple[str, ...] = field(default=(), compare=False)

    def __post_init__(self) -> None:
        """Validate shapes and values."""
        n = self.accel.shape[0]
        arrays = {"accel": self.accel, "vel_uncertainty": self.vel_uncertainty}
        if self.speed is not None:
            arrays["speed"] = self.speed
        for name, arr in arrays.items():
            if arr.shape != (n,):
                raise InvalidInputError(f"MotionBounds.{name} must have shape ({n},).")
            # A speed bound may be inf (none for that body); NaN never is a bound.
            finite = ~np.isnan(arr) if name == "speed" else np.isfinite(arr)
            bad = ~finite | (arr < 0)
            if bad.any():
                b = int(np.flatnonzero(bad)[0])
                label = self.body_names[b] if b < len(self.body_names) else str(b)
                rule = ">= 0 (inf for none)" if name == "speed" else "finite, >= 0"
                raise InvalidBoundError(
                    f"MotionBounds.{name} of body {label!r} is {arr[b]!r}; must be {rule}."
                )

    @property
    def discrepancy(self) -> np.ndarray:
        """``(nbody,)`` D = delta + A h / 2: the largest one-step discrepancy the bounds allow."""
        return self.vel_uncertainty + 0.5 * self.timestep * self.accel

    @classmethod
    def declare(
        cls,
        model: mujoco.MjModel,
        accel: BoundSpec,
        *,
        speed: BoundSpec | None = None,
        vel_uncertainty: BoundSpec | None = None,
        velocity_accel: BoundSpec | None = None,
        integrator_term: bool = True,
    ) -> MotionBounds:
        """Bounds declared by the user.

        Args:
            accel: A, a scalar for every moving body or a dict by body name (``"*"`` default).
            speed: V in the same forms, or None.
            vel_uncertainty: extra velocity uncertainty (e.g. sensor noise), added to the
                integrator term.
            velocity_accel: C, a bound on the velocity-product (centripetal/Coriolis)
                acceleration of sphere centres, for :func:`discrete_velocity_uncertainty`.
            integrator_term: add the discrete-time term. Turn it off only for continuous-time
                use (e.g. a kinematic world sampled exactly).

        Returns:
            The bounds, ``source="declared"``.

        Raises:
            InvalidChoiceError: a dict key is not a body name (the message lists them).
            InvalidBoundError: a value is not a number, is negative, NaN or inf (a speed bound
                may be inf, but not 0 for a moving body), or a moving body has no value.
        """
        A = _resolve(model, accel, "acceleration")
        V = None if speed is None else _resolve(model, speed, "speed")
        delta = np.zeros(model.nbody)
        if integrator_term:
            C = (
                None
                if velocity_accel is None
                else _resolve(model, velocity_accel, "velocity_accel")
            )
            delta += discrete_velocity_uncertainty(model, A, velocity_accel=C)
        if vel_uncertainty is not None:
            delta += _resolve(model, vel_uncertainty, "velocity uncertainty")
        return cls(
            accel=A,
            speed=V,
            vel_uncertainty=delta,
            source="declared",
            timestep=float(model.opt.timestep),
            body_names=tuple(_body_names(model)),
        )


def default_spheres(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One sphere per geom at the geom origin (the bounding covering's centres).

    Returns:
        ``(sphere_geom (ngeom,), sphere_body (ngeom,), sphere_offset (ngeom, 3))``.
    """
    g = np.arange(model.ngeom, dtype=np.int64)
    return g, np.asarray(model.geom_bodyid, dtype=np.int64)[g], np.zeros((model.ngeom, 3))


class _PerBodyMax:
    """``(nbody,)`` the largest of per-sphere values on each body (0 where none), by one sorted
    reduction (``np.maximum.at`` took a third of the pilot's time on swarms)."""

    def __init__(self, sphere_body: np.ndarray, nbody: int) -> None:
        self._order = np.argsort(sphere_body, kind="stable")
        bodies = sphere_body[self._order]
        self._starts = (
            np.flatnonzero(np.r_[True, bodies[1:] != bodies[:-1]]) if bodies.size else bodies
        )
        self._bodies = bodies[self._starts]
        self._nbody = nbody

    def __call__(self, values: np.ndarray) -> np.ndarray:
        out = np.zeros(self._nbody)
        if self._starts.size:
            out[self._bodies] = np.maximum(
                np.maximum.reduceat(values[self._order], self._starts), 0.0
            )
        return out


Controller = Callable[[mujoco.MjModel, mujoco.MjData, np.random.Generator], None]

# MuJoCo's answer to a diverged state: warn, then mj_resetData (the state jumps back).
DIVERGENCE_WARNINGS = (
    mujoco.mjtWarning.mjWARN_BADQPOS,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQACC,
)


def estimate_bounds(
    model: mujoco.MjModel,
    *,
    steps: int,
    seed: int,
    safety: float = 2.0,
    controller: Controller | None = None,
    init: Controller | None = None,
    spheres: tuple[npt.ArrayLike, npt.ArrayLike, npt.ArrayLike] | None = None,
    with_speed: bool = True,
    motion: PilotMotion | str = PilotMotion.FREE,
) -> MotionBounds:
    """Estimate bounds from a pilot rollout (its own ``MjData``, its own seed).

    Measures, per body and over its sphere centres, what ``BoundMonitor`` checks
    (:class:`~dua_mujoco.build.kinematics.PointMotion`): the discrete acceleration
    |u_{k+1} - u_k| / h, the one-step discrepancy |u_{k+1} - w_k| and the speed (the larger of
    |u_k| and |w_k|); multiplies each by ``safety``. The guarantee then rests on the monitored
    run staying within them: use a :class:`BoundMonitor`.

    Args:
        steps: number of pilot steps (>= 3).
        seed: seed of the pilot's random generator (controls, initial state).
        safety: factor (>= 1) applied to every measured maximum.
        controller: called before every step as ``controller(model, data, rng)``; None drives
            actuators with uniform random controls in their ``ctrlrange`` (or [-1, 1]).
        init: called once after ``mj_resetData`` as ``init(model, data, rng)``.
        spheres: ``(sphere_geom, sphere_body, sphere_offset)``; None for :func:`default_spheres`.
        with_speed: also return a speed bound.
        motion: which steps are measured (:class:`PilotMotion`).

    Returns:
        The bounds, ``source="auto"``.
    """
    if steps < 3:
        raise InvalidInputError(f"steps must be >= 3 to difference twice; got {steps}.")
    if not np.isfinite(safety) or safety < 1.0:
        raise InvalidInputError(f"safety must be >= 1; got {safety}.")
    motion = as_choice(PilotMotion, motion, "pilot motion")
    rng = np.random.default_rng(seed)
    sgeom, sbody, soff = default_spheres(model) if spheres is None else spheres
    sgeom = np.asarray(sgeom, dtype=np.int64)
    sbody = np.asarray(sbody, dtype=np.int64)
    soff = np.asarray(soff, dtype=np.float64).reshape(-1, 3)
    d = mujoco.MjData(model)
    mujoco.mj_resetData(model, d)
    if init is not None:
        init(model, d, rng)
    mujoco.mj_forward(model, d)
    tracker = MocapVelocityTracker(model)
    points = PointMotion(pack_spheres(sgeom, sbody, soff, model.body_rootid))
    speed, disc, acc = points.values[:, 0], points.values[:, 1], points.values[:, 2]

    def default_controller(m: mujoco.MjModel, dd: mujoco.MjData, g: np.random.Generator) -> None:
        if m.nu:
            lo, hi = np.asarray(m.actuator_ctrlrange, dtype=np.float64).T
            limited = np.asarray(m.actuator_ctrllimited, dtype=bool)
            lo = np.where(limited, lo, -1.0)
            hi = np.where(limited, hi, 1.0)
            dd.ctrl[:] = g.uniform(lo, hi)

    ctrl = controller if controller is not None else default_controller
    h = float(model.opt.timestep)
    nb = model.nbody
    vmax = np.zeros(nb)
    per_body_max = _PerBodyMax(sbody, nb)
    screen = MotionScreen(model)
    amax, dmax = np.zeros((3, nb)), np.zeros((3, nb))
    measured = np.zeros((3, nb), dtype=bool)
    mocap_start = (np.array(d.mocap_pos), np.array(d.mocap_quat))
    mocap_moved = np.zeros(model.nmocap, dtype=bool)
    for k in range(steps):
        ctrl(model, d, rng)
        mujoco.mj_step(model, d)
        tracker.update(d)
        mocap_moved |= (d.mocap_pos != mocap_start[0]).any(axis=1)
        mocap_moved |= (d.mocap_quat != mocap_start[1]).any(axis=1)
        free, calm = screen.update(d)
        levels = (free[sbody], calm[sbody], np.ones(len(sbody), dtype=bool))
        points.update(d, tracker.twist, h)
        if with_speed:
            vmax = np.maximum(vmax, per_body_max(np.linalg.norm(points.rows[:, 3:6], axis=1)))
        if k == 0:
            continue
        # The hypothesis is on the chord (BoundMonitor); the larger of the two is kept.
        if with_speed:
            vmax = np.maximum(vmax, per_body_max(speed))
        if tracker.nupdates >= 3 or not tracker.mocap_bodies.size:
            for j, mask in enumerate(levels):
                dmax[j] = np.maximum(dmax[j], per_body_max(disc * mask))
        if k >= 2:
            for j, mask in enumerate(levels):
                amax[j] = np.maximum(amax[j], per_body_max(acc * mask))
                measured[j, sbody[mask]] = True
    # A body the chosen level never measured (a foot always on the ground: free motion; a body
    # starting contacts at every step) takes the next level's maxima.
    amax, dmax = level_maxima(amax, measured, motion), level_maxima(dmax, measured, motion)
    moving = moving_bodies(model)
    A = np.where(moving, safety * amax, 0.0)
    D = np.where(moving, safety * dmax, 0.0)
    V = np.where(moving, safety * vmax, 0.0) if with_speed else None
    diverged = [w.name for w in DIVERGENCE_WARNINGS if d.warning[int(w)].number]
    if diverged or not (np.isfinite(A).all() and np.isfinite(D).all()):
        # MuJoCo resets a diverged state itself: the jump would pass for a huge acceleration.
        raise InvalidBoundError(
            f"The pilot rollout diverged ({', '.join(diverged) or 'NaN/inf'}): reduce the "
            "timestep, or check the model and the pilot's controls."
        )
    if not mocap_moved.all():
        still = [model.body(int(b)).name or str(int(b)) for b in tracker.mocap_bodies[~mocap_moved]]
        warnings.warn(
            f"the pilot never moved mocap bod{'y' if len(still) == 1 else 'ies'} {still}, so "
            "their bounds are 0: if the run moves them, every step breaks those bounds and "
            "their pairs are evaluated at every step. Give the pilot a controller that moves "
            "them as the run will (PilotOptions(controller=...)), or declare their bounds.",
            PilotWarning,
            stacklevel=3,
        )
    return MotionBounds(
        accel=A,
        speed=V,
        vel_uncertainty=np.maximum(D - 0.5 * h * A, 0.0),
        source="auto",
        timestep=h,
        body_names=tuple(_body_names(model)),
    )


def resolve_bounds(
    model: mujoco.MjModel,
    accel: float | Mapping[str, float] | MotionBounds | str,
    *,
    speed: float | Mapping[str, float] | None = None,
    velocity_accel: float | Mapping[str, float] | None = None,
) -> MotionBounds:
    """The ``MotionBounds`` a ``Predictor``'s declared ``accel`` argument stands for.

    A scalar or a dict by body name is declared (``MotionBounds.declare``, with ``speed`` and
    ``velocity_accel``); ready ``MotionBounds`` must be this model's (``"auto"`` is
    ``pilot_bounds``'s).
    """
    if isinstance(accel, MotionBounds):
        if accel.accel.shape != (model.nbody,):
            raise InvalidInputError(
                f"the MotionBounds have {accel.accel.shape[0]} bodies but the model has "
                f"{model.nbody}: build them for this model (MotionBounds.declare(model, ...))."
            )
        return accel
    if isinstance(accel, str):
        raise InvalidInputError(
            f"accel = {accel!r} is invalid: pass 'auto', a number, a dict by body name "
            "or MotionBounds."
        )
    return MotionBounds.declare(model, accel, speed=speed, velocity_accel=velocity_accel)


def with_speed(
    model: mujoco.MjModel, bounds: MotionBounds, speed: float | Mapping[str, float] | None
) -> MotionBounds:
    """``bounds`` with a declared speed bound on top (estimated accelerations keep it)."""
    if speed is None:
        return bounds
    declared = MotionBounds.declare(model, 0.0, speed=speed, integrator_term=False)
    return replace(bounds, speed=declared.speed)
