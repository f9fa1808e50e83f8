"""dua_mujoco.build.bounds: declared bounds, the discrete-time term on rollouts, the bound
checks."""

from __future__ import annotations

from collections.abc import Callable

import mujoco
import numpy as np
import pytest
from reference_bounds import ReferenceBoundMonitor
from reference_kinematics import reference_states

from dua_mujoco.build.bounds import (
    MotionBounds,
    default_spheres,
    discrete_velocity_uncertainty,
    estimate_bounds,
    moving_bodies,
)
from dua_mujoco.build.mocap import MocapVelocityTracker
from dua_mujoco.exceptions import InvalidBoundError, InvalidChoiceError, InvalidInputError
from dua_mujoco.measure.checks import BoundMonitor
from dua_mujoco.models.scenes import declared_accel_bound, load_scene, make_controller

H = 0.002
KMAX = 200

TWO_BODIES = """<mujoco><option timestep="0.002"/><worldbody>
<geom name="floor" type="plane" size="2 2 .1"/>
<body name="static_shelf" pos="0 0 .5"><geom type="box" size=".2 .2 .01"/></body>
<body name="ball" pos="0 0 1"><freejoint/><geom type="sphere" size=".1"/></body>
<body name="link" pos="1 0 1"><joint type="hinge" axis="0 1 0"/>
  <geom type="capsule" fromto="0 0 0 .5 0 0" size=".02"/></body>
</worldbody></mujoco>"""

FREE_FORCE = """<mujoco><option integrator="{I}" gravity="0 0 0" timestep="0.002"/><worldbody>
<body name="ball"><freejoint/><geom type="sphere" size=".1" mass="{M}"/></body>
</worldbody></mujoco>"""

PENDULUM = """<mujoco><option integrator="{I}" timestep="0.002"/><worldbody>
<body name="link" pos="0 0 1"><joint type="hinge" axis="0 1 0"/>
  <geom type="capsule" fromto="0 0 0 .5 0 0" size=".02"/>
  <geom name="tip" type="sphere" pos=".5 0 0" size=".05"/></body></worldbody></mujoco>"""

CHAIN = """<mujoco><option integrator="{I}" timestep="0.002"/><worldbody>
<body name="a" pos="0 0 1"><joint type="ball"/>
  <geom type="capsule" fromto="0 0 0 .4 0 0" size=".02"/>
<body name="b" pos=".4 0 0"><joint type="hinge" axis="0 1 .3"/>
  <geom type="capsule" fromto="0 0 0 .4 .1 0" size=".02"/>
  <geom type="sphere" size=".03" pos=".4 .1 0"/></body></body></worldbody></mujoco>"""

# Free body spinning torque-free about its COM = frame origin (isotropic inertia: omega constant).
SPIN = """<mujoco><option integrator="{I}" gravity="0 0 0" timestep="0.002"/><worldbody>
<body name="top"><freejoint/><inertial pos="0 0 0" mass="1" diaginertia=".01 .01 .01"/>
  <geom type="sphere" size=".05" pos=".3 .1 .05" contype="0" conaffinity="0"/></body>
</worldbody></mujoco>"""

# Same, but the COM sits 0.3 m from the frame origin and the sphere sits at the COM.
SPIN_COM_OFFSET = """<mujoco><option integrator="{I}" gravity="0 0 0" timestep="0.002"/><worldbody>
<body name="top"><freejoint/><inertial pos=".3 0 0" mass="1" diaginertia=".01 .01 .01"/>
  <geom type="sphere" size=".05" pos=".3 0 0" contype="0" conaffinity="0"/></body>
</worldbody></mujoco>"""


def _model(xml: str, integrator: str = "Euler", mass: float = 2.0) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(xml.replace("{I}", integrator).replace("{M}", str(mass)))


Driver = Callable[[mujoco.MjModel, mujoco.MjData, int], None]


def _rollout(
    m: mujoco.MjModel, steps: int, drive: Driver | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Centres c_k and velocities w_k of one sphere per geom, read after every mj_step.

    Returns:
        ``(steps, ngeom, 3)`` centres and velocities.
    """
    d = mujoco.MjData(m)
    if drive is not None:
        drive(m, d, -1)
    mujoco.mj_forward(m, d)
    sg = np.arange(m.ngeom)
    C, W = [], []
    for k in range(steps):
        if drive is not None:
            drive(m, d, k)
        mujoco.mj_step(m, d)
        c, w = reference_states(m, d, sg, np.zeros((m.ngeom, 3)))
        C.append(c)
        W.append(w)
    return np.array(C), np.array(W)


def _excess(C: np.ndarray, W: np.ndarray, A: np.ndarray, delta: np.ndarray, h: float) -> np.ndarray:
    """max over start steps s and k in 1..KMAX of |c_{s+k} - c_s - k h w_s| - bound, per sphere.

    Positive means the ball B(c_s + w_s t, delta t + A t^2/2) missed c_{s+k} somewhere.
    """
    n = C.shape[0]
    starts = np.arange(0, n - KMAX, 5)
    k = np.arange(1, KMAX + 1)
    t = k * h
    idx = starts[:, None] + k[None, :]
    dev = C[idx] - C[starts][:, None] - t[None, :, None, None] * W[starts][:, None]
    err = np.linalg.norm(dev, axis=-1)  # (starts, k, nsphere)
    bound = delta[None, None, :] * t[None, :, None] + 0.5 * A[None, None, :] * t[None, :, None] ** 2
    # 1e-12 relative slack for round-off, plus an absolute 1e-13 for positions of size ~1.
    return (err - bound * (1 + 1e-12) - 1e-13).max(axis=(0, 1))


def _measured(C: np.ndarray, W: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Discrete acceleration bound A and one-step discrepancy D of a rollout, per sphere."""
    U = np.diff(C, axis=0) / h
    A = np.linalg.norm(np.diff(U, axis=0), axis=-1).max(axis=0) / h
    D = np.linalg.norm(U - W[:-1], axis=-1).max(axis=0)
    return A, D


def _random_force(fmax: float, seed: int, hold: int = 40) -> Driver:
    rng = np.random.default_rng(seed)
    f = np.zeros(3)

    def drive(m: mujoco.MjModel, d: mujoco.MjData, k: int) -> None:
        nonlocal f
        if k >= 0 and k % hold == 0:
            f = rng.normal(size=3)
            f *= fmax * rng.uniform(0.2, 1.0) / np.linalg.norm(f)
        d.xfrc_applied[1, :3] = f
        if k == -1:
            d.qvel[:3] = rng.normal(size=3)

    return drive


def _kick(seed: int, scale: float = 3.0) -> Driver:
    rng = np.random.default_rng(seed)

    def drive(m: mujoco.MjModel, d: mujoco.MjData, k: int) -> None:
        if k == -1:
            d.qvel[:] = rng.normal(size=m.nv) * scale

    return drive


# ---------------------------------------------------------------------------- declared bounds


def test_declare_scalar_static_bodies_zero() -> None:
    m = _model(TWO_BODIES)
    b = MotionBounds.declare(m, 5.0, speed=2.0)
    moving = moving_bodies(m)
    assert moving.tolist() == [False, False, True, True]
    np.testing.assert_array_equal(b.accel, np.where(moving, 5.0, 0.0))
    assert b.speed is not None
    np.testing.assert_array_equal(b.speed, np.where(moving, 2.0, 0.0))
    np.testing.assert_allclose(b.vel_uncertainty, b.accel * H / 2)
    np.testing.assert_allclose(b.discrepancy, b.accel * H)
    assert b.source == "declared"


def test_declare_dict_and_default() -> None:
    m = _model(TWO_BODIES)
    b = MotionBounds.declare(m, {"ball": 9.81, "link": 3.0})
    assert b.accel.tolist() == [0.0, 0.0, 9.81, 3.0]
    b = MotionBounds.declare(m, {"ball": 1.0, "*": 7.0}, vel_uncertainty={"*": 0.1})
    assert b.accel.tolist() == [0.0, 0.0, 1.0, 7.0]
    np.testing.assert_allclose(b.vel_uncertainty[2:], [H / 2 + 0.1, 7 * H / 2 + 0.1])
    b = MotionBounds.declare(m, 2.0, integrator_term=False, velocity_accel=5.0)
    np.testing.assert_array_equal(b.vel_uncertainty, 0.0)
    b = MotionBounds.declare(m, 2.0, velocity_accel=5.0)
    np.testing.assert_allclose(b.vel_uncertainty[2:], 7.0 * H / 2)


def test_declare_unknown_body_lists_names() -> None:
    m = _model(TWO_BODIES)
    with pytest.raises(InvalidChoiceError) as exc:
        MotionBounds.declare(m, {"bal": 1.0, "*": 1.0})
    msg = str(exc.value)
    assert "'bal'" in msg
    for name in ("world", "ball", "link", "static_shelf"):
        assert repr(name) in msg


@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf")])
def test_declare_bad_values_name_body_and_value(bad: float) -> None:
    m = _model(TWO_BODIES)
    with pytest.raises(InvalidBoundError, match="'link'") as exc:
        MotionBounds.declare(m, {"ball": 1.0, "link": bad})
    assert repr(bad) in str(exc.value)
    with pytest.raises(InvalidBoundError, match=repr(bad)):
        MotionBounds.declare(m, bad)
    if bad != float("inf"):  # inf is a valid speed bound: none for that body
        with pytest.raises(InvalidBoundError, match="'ball'"):
            MotionBounds.declare(m, 1.0, speed={"ball": bad, "link": 1.0})


def test_speed_bound_for_some_bodies_only() -> None:
    m = _model(TWO_BODIES)
    b = MotionBounds.declare(m, 1.0, speed={"ball": 2.0, "*": float("inf")})
    assert b.speed is not None
    assert b.speed.tolist() == [0.0, 0.0, 2.0, float("inf")]  # static bodies: 0
    with pytest.raises(InvalidBoundError, match=r"'link' is 0\.0; it must be > 0 \(inf for no"):
        MotionBounds.declare(m, 1.0, speed={"ball": 2.0, "link": 0.0})


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (
            {"accel": -1.0},
            "accel = -1.0 is invalid: an acceleration bound must be finite and >= 0 (use 0 for a "
            "body that does not accelerate).",
        ),
        (
            {"accel": 1.0, "speed": 0.0},
            "speed = 0.0 is invalid: a speed bound must be > 0 (inf for none).",
        ),
        (
            {"accel": [1.0]},
            "accel = [1.0] is invalid: it is not a number; pass a number, or a dict by body "
            "name ('*' for the default).",
        ),
    ],
    ids=["accel", "speed", "not-a-number"],
)
def test_a_scalar_bound_is_named_by_its_keyword_not_by_a_body(
    options: dict[str, object], message: str
) -> None:
    """One number is every moving body's bound: the message names the keyword, no body (it
    said "body 'all bodies'")."""
    from dua_mujoco.runtime.predictor import Predictor

    m = _model(TWO_BODIES)
    with pytest.raises(InvalidInputError) as info:
        Predictor(m, **options)  # type: ignore[arg-type]
    assert str(info.value) == message
    with pytest.raises(InvalidBoundError) as info:
        Predictor(m, accel={"ball": -1.0, "*": 1.0})
    assert str(info.value).startswith("The acceleration bound of body 'ball' is -1.0;")


def test_speed_zero_is_fine_for_static_bodies_only() -> None:
    m = _model(TWO_BODIES)
    b = MotionBounds.declare(m, 1.0, speed={"ball": 2.0, "link": 2.0, "static_shelf": 0.0})
    assert b.speed is not None and b.speed[2:].tolist() == [2.0, 2.0]


def test_pilot_divergence_is_an_error() -> None:
    """MuJoCo resets a diverged state itself; the pilot must not take the jump for motion."""
    m = mujoco.MjModel.from_xml_string(
        """<mujoco><option timestep="0.01"/><worldbody>
        <body><joint type="hinge" axis="0 1 0" stiffness="1e9"/>
        <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02" mass=".001"/></body>
        </worldbody><keyframe><key qpos="0.5"/></keyframe></mujoco>"""
    )

    def kick(model: mujoco.MjModel, data: mujoco.MjData, rng: np.random.Generator) -> None:
        data.qpos[0] = 0.5  # far from the spring's rest: the explicit integrator blows up

    with pytest.raises(InvalidBoundError, match="pilot rollout diverged"):
        estimate_bounds(m, steps=50, seed=0, init=kick)


@pytest.mark.parametrize("bad", [[1.0, 2.0], None, "fast", "5", True])
def test_declare_non_numbers_are_named(bad: object) -> None:
    m = _model(TWO_BODIES)
    with pytest.raises(InvalidBoundError, match="not a number"):
        MotionBounds.declare(m, bad)  # type: ignore[arg-type]
    with pytest.raises(InvalidBoundError, match=r"'link'.*not a number"):
        MotionBounds.declare(m, {"ball": 1.0, "link": bad})  # type: ignore[dict-item]


def test_declare_missing_bodies() -> None:
    m = _model(TWO_BODIES)
    with pytest.raises(InvalidBoundError, match="link"):
        MotionBounds.declare(m, {"ball": 1.0})
    # Static bodies need no value.
    MotionBounds.declare(m, {"ball": 1.0, "link": 1.0})


def test_motionbounds_validates_arrays() -> None:
    with pytest.raises(InvalidInputError):
        MotionBounds(accel=np.zeros(3), speed=None, vel_uncertainty=np.zeros(2))
    with pytest.raises(InvalidBoundError):
        MotionBounds(accel=np.array([0.0, -1.0]), speed=None, vel_uncertainty=np.zeros(2))


@pytest.mark.parametrize("integrator", ["Euler", "implicit", "implicitfast", "RK4"])
def test_discrete_term_per_integrator(integrator: str) -> None:
    m = _model(PENDULUM, integrator)
    A = np.array([0.0, 4.0])
    np.testing.assert_allclose(discrete_velocity_uncertainty(m, A), A * H / 2)
    np.testing.assert_allclose(
        discrete_velocity_uncertainty(m, A, velocity_accel=[0.0, 2.0]), [0.0, 6.0 * H / 2]
    )
    with pytest.raises(InvalidInputError):
        discrete_velocity_uncertainty(m, [1.0])


# ------------------------------------------------------------------ the derivation on rollouts


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_euler_free_sphere_bounded_force(seed: int) -> None:
    """A = Fmax / m, delta = A h / 2 (the declared rule): valid at every step, k <= 200."""
    fmax, mass = 10.0, 2.0
    m = _model(FREE_FORCE, "Euler", mass)
    C, W = _rollout(m, 800, _random_force(fmax, seed))
    bounds = MotionBounds.declare(m, fmax / mass)
    A, delta = bounds.accel[m.geom_bodyid], bounds.vel_uncertainty[m.geom_bodyid]
    assert (_excess(C, W, A, delta, H) <= 0).all()
    # Translation under Euler: the velocity in MjData is the backward discrete velocity, D = A h.
    A_meas, D_meas = _measured(C, W, H)
    assert A_meas[0] <= fmax / mass * (1 + 1e-9)
    assert D_meas[0] <= fmax / mass * H * (1 + 1e-9)


def test_without_delta_the_bound_fails() -> None:
    """Constant force: |c_k - c_0 - k h w_0| = A t^2/2 + A h t/2 > A t^2/2 at every step."""
    m = _model(FREE_FORCE, "Euler", 1.0)

    def drive(m: mujoco.MjModel, d: mujoco.MjData, k: int) -> None:
        d.xfrc_applied[1, :3] = [3.0, 0.0, 4.0]  # |F| = 5 N on 1 kg

    C, W = _rollout(m, 600, drive)
    A = np.array([5.0])
    assert (_excess(C, W, A, np.zeros(1), H) > 0).all()
    assert (_excess(C, W, A, A * H / 2, H) <= 0).all()
    # And it is tight: the deviation equals A h^2 k(k+1)/2.
    k = np.arange(1, KMAX + 1)
    dev = np.linalg.norm(C[100 + k, 0] - C[100, 0] - (k * H)[:, None] * W[100, 0], axis=1)
    np.testing.assert_allclose(dev, 5.0 * H**2 * k * (k + 1) / 2, rtol=1e-6)


@pytest.mark.parametrize("seed", [0, 1])
def test_euler_hinge_pendulum(seed: int) -> None:
    """A single hinge: the rule delta = A h / 2 (C = 0) holds with A the measured acceleration."""
    m = _model(PENDULUM, "Euler")
    C, W = _rollout(m, 800, _kick(seed))
    A, D = _measured(C, W, H)
    assert (D <= A * H * (1 + 1e-6)).all()  # first-order claim for one hinge
    delta = discrete_velocity_uncertainty(m, np.zeros(m.nbody) + A.max())[m.geom_bodyid]
    assert (_excess(C, W, np.full(m.ngeom, A.max()), delta, H) <= 0).all()
    # Per sphere with its own measured A and D as well.
    assert (_excess(C, W, A, np.maximum(D - A * H / 2, 0), H) <= 0).all()


def test_euler_spinning_free_body() -> None:
    """Torque-free spin about the frame origin: A = |omega|^2 r_perp, delta = A h / 2."""
    m = _model(SPIN, "Euler")
    omega = np.array([3.0, -5.0, 20.0])

    def drive(m: mujoco.MjModel, d: mujoco.MjData, k: int) -> None:
        if k == -1:
            d.qvel[3:] = omega  # body frame = world frame at qpos0

    C, W = _rollout(m, 800, drive)
    r = m.geom_pos[0]
    w = omega / np.linalg.norm(omega)
    r_perp = np.linalg.norm(r - (r @ w) * w)
    A_true = float(omega @ omega) * r_perp
    A, D = _measured(C, W, H)
    assert A[0] <= A_true * (1 + 1e-9)
    assert D[0] <= A_true * H
    assert (_excess(C, W, np.array([A_true]), np.array([A_true * H / 2]), H) <= 0).all()


def test_euler_spin_with_com_offset_needs_velocity_term() -> None:
    """COM away from the frame origin: tangent vs chord costs (h/2)|omega|^2 r, not A h.

    The sphere at the COM barely accelerates, yet Euler's positions drift from the reported
    velocity. C = 0 fails; velocity_accel = |omega|^2 r restores the bound; the monitor flags C=0.
    """
    m = _model(SPIN_COM_OFFSET, "Euler")
    omega = np.array([0.0, 2.0, 20.0])

    def drive(m: mujoco.MjModel, d: mujoco.MjData, k: int) -> None:
        if k == -1:
            d.qvel[3:] = omega

    C, W = _rollout(m, 800, drive)
    A, D = _measured(C, W, H)
    C_va = float(omega @ omega) * 0.3
    assert D[0] > 100 * A[0] * H  # the rotation term dominates
    A_decl = np.array([max(A[0], 0.05)])
    assert (_excess(C, W, A_decl, A_decl * H / 2, H) > 0).all()
    delta_c = discrete_velocity_uncertainty(m, [0.0, A_decl[0]], velocity_accel=[0.0, C_va])
    assert (_excess(C, W, A_decl, delta_c[1:], H) <= 0).all()
    # The monitor catches the broken discrepancy hypothesis with C = 0.
    mon = BoundMonitor(m, MotionBounds.declare(m, float(A_decl[0])))
    d = mujoco.MjData(m)
    drive(m, d, -1)
    for _ in range(5):
        mujoco.mj_step(m, d)
        mon.update(m, d)
    assert any(v.kind == "discrepancy" for v in mon.violations)
    mon = BoundMonitor(m, MotionBounds.declare(m, float(A_decl[0]), velocity_accel=C_va))
    d = mujoco.MjData(m)
    drive(m, d, -1)
    for _ in range(50):
        mujoco.mj_step(m, d)
        mon.update(m, d)
    assert mon.bounds_held()


def _velocity_product_accel(m: mujoco.MjModel, qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
    """|a_v| per geom centre: second derivative of p(q (+) s qvel) at s = 0 (central difference).

    This is the acceleration at zero joint acceleration along MuJoCo's own position update (the
    quantity C of docs/discrete-time.md).
    """
    d = mujoco.MjData(m)
    s = 1e-4
    out = []
    for sign in (-1.0, 0.0, 1.0):
        q = qpos.copy()
        mujoco.mj_integratePos(m, q, qvel, sign * s)
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        out.append(d.geom_xpos.copy())
    return np.linalg.norm(out[0] - 2 * out[1] + out[2], axis=1) / s**2


@pytest.mark.parametrize("integrator", ["RK4", "implicitfast", "implicit", "Euler"])
@pytest.mark.parametrize("scene", ["pendulum", "chain", "force"])
def test_other_integrators_measured_term(integrator: str, scene: str) -> None:
    """With the measured A and D (delta = max(D - A h/2, 0)) the bound holds at every step.

    And the declared rule delta = (A + C) h / 2 covers the measured term, with C = 0 for the
    pendulum and the pushed sphere, and C = max |a_v| for the ball-hinge chain (where C = 0 is
    not enough under the semi-implicit integrators).
    """
    if scene == "force":
        m = _model(FREE_FORCE, integrator, 2.0)
        C, W = _rollout(m, 700, _random_force(10.0, 3))
    else:
        m = _model(PENDULUM if scene == "pendulum" else CHAIN, integrator)
        C, W = _rollout(m, 700, _kick(7))
    A, D = _measured(C, W, H)
    delta_meas = np.maximum(D - A * H / 2, 0)
    assert (_excess(C, W, A, delta_meas, H) <= 0).all()
    Cva = np.zeros(m.ngeom)
    if scene == "chain":
        d = mujoco.MjData(m)
        _kick(7)(m, d, -1)
        for _ in range(700):
            Cva = np.maximum(Cva, _velocity_product_accel(m, d.qpos, d.qvel))
            mujoco.mj_step(m, d)
    rule = 0.5 * H * (A + Cva)
    assert (delta_meas <= rule * 1.01).all()
    if integrator == "RK4":
        # RK4: D ~ A h / 2 (measured 0.50-0.52), so the needed term is ~0 (second order).
        assert (D <= A * H * 0.6).all()
    elif scene == "chain":
        # Semi-implicit family on a ball joint chain: the rotation term is needed (C = 0 fails).
        assert (D > A * H * 1.2).any()


# ------------------------------------------------------------------------------- estimation


def test_estimate_bounds_then_monitor_holds() -> None:
    m = _model(CHAIN, "Euler")

    def init(m: mujoco.MjModel, d: mujoco.MjData, rng: np.random.Generator) -> None:
        d.qvel[:] = rng.normal(size=m.nv) * 2

    b = estimate_bounds(m, steps=600, seed=0, safety=2.0, init=init)
    assert b.source == "auto"
    assert b.accel[0] == 0 and (b.accel[1:] > 0).all()
    assert b.speed is not None and (b.speed[1:] > 0).all()
    # Same motion family, another seed: the monitor sees no violation.
    mon = BoundMonitor(m, b)
    d = mujoco.MjData(m)
    d.qvel[:] = np.random.default_rng(11).normal(size=m.nv) * 2
    for _ in range(300):
        mujoco.mj_step(m, d)
        assert mon.update(m, d).size == 0
    assert mon.bounds_held() and len(mon.held) == 300
    # safety 1 vs 2 scales everything.
    b1 = estimate_bounds(m, steps=600, seed=0, safety=1.0, init=init)
    np.testing.assert_allclose(b.accel, 2 * b1.accel)


def test_estimate_bounds_errors_and_controller() -> None:
    m = _model(PENDULUM)
    with pytest.raises(InvalidInputError):
        estimate_bounds(m, steps=2, seed=0)
    with pytest.raises(InvalidInputError):
        estimate_bounds(m, steps=10, seed=0, safety=0.5)
    calls = []

    def controller(m: mujoco.MjModel, d: mujoco.MjData, rng: np.random.Generator) -> None:
        calls.append(d.time)

    b = estimate_bounds(m, steps=20, seed=0, controller=controller, with_speed=False)
    assert len(calls) == 20 and b.speed is None


# ---------------------------------------------------------------------------------- monitor


def test_monitor_quiet_when_bounds_hold_and_flags_impulse() -> None:
    fmax, mass = 10.0, 2.0
    m = _model(FREE_FORCE, "Euler", mass)
    bounds = MotionBounds.declare(m, fmax / mass, speed=50.0)
    mon = BoundMonitor(m, bounds)
    d = mujoco.MjData(m)
    drive = _random_force(fmax, 5)
    drive(m, d, -1)
    for k in range(300):
        drive(m, d, k)
        if k == 200:
            d.xfrc_applied[1, :3] = [0.0, 0.0, 500.0]  # an impulse far above Fmax
        mujoco.mj_step(m, d)
        bad = mon.update(m, d)
        if k < 200:
            assert bad.size == 0, k
    assert not mon.bounds_held()
    assert mon.bounds_held(0, 200)
    kinds = {(v.body, v.kind) for v in mon.violations}
    assert (1, "accel") in kinds
    first = min(v.step for v in mon.violations)
    # The impulse at step 200 shows in the positions read after step 202 (kinematics lag 1).
    assert 200 <= first <= 203
    v = next(v for v in mon.violations if v.kind == "accel")
    assert v.value > 100 and v.bound == fmax / mass


def test_monitor_flags_contact() -> None:
    m = _model(TWO_BODIES, "Euler")
    g = float(np.linalg.norm(m.opt.gravity))
    bounds = MotionBounds.declare(m, {"ball": g * 1.001, "link": 100.0}, speed=100.0)
    mon = BoundMonitor(m, bounds)
    d = mujoco.MjData(m)
    d.qpos[:3] = [0.5, 0.5, 0.3]  # above the floor, clear of the shelf
    flagged = []
    for _ in range(400):
        mujoco.mj_step(m, d)
        flagged.extend(mon.update(m, d).tolist())
    ball = mujoco.mj_name2id(m, int(mujoco.mjtObj.mjOBJ_BODY), "ball")
    assert ball in flagged  # the floor contact decelerates far beyond g
    first = min(v.step for v in mon.violations)
    assert first > 50  # free fall from 0.2 m: no false violations before the contact


def test_monitor_speed_bound() -> None:
    m = _model(FREE_FORCE, "Euler", 1.0)
    mon = BoundMonitor(m, MotionBounds.declare(m, 0.0, speed=1.0))
    d = mujoco.MjData(m)
    d.qvel[:3] = [2.0, 0.0, 0.0]
    mujoco.mj_step(m, d)
    assert mon.update(m, d).tolist() == []  # one position: no chord yet
    mujoco.mj_step(m, d)
    assert mon.update(m, d).tolist() == [1]
    assert mon.violations[0].kind == "speed"
    assert mon.violations[0].value == pytest.approx(2.0)


# ------------------------------------------------------------------ kernel against reference


def _same_updates(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    bounds: MotionBounds,
    steps: int,
    drive: Callable[[mujoco.MjModel, mujoco.MjData, int], None],
    spheres: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    mocap: MocapVelocityTracker | None = None,
) -> BoundMonitor:
    """Step, then hold ``BoundMonitor`` to the numpy reference at every update."""
    # Every violation is compared: keep them all.
    fast = BoundMonitor(m, bounds, spheres, mocap=mocap, max_violations=10**9)
    ref = ReferenceBoundMonitor(m, bounds, spheres, mocap=mocap)
    for k in range(steps):
        drive(m, d, k)
        mujoco.mj_step(m, d)
        if mocap is not None:
            mocap.update(d)
        np.testing.assert_array_equal(fast.update(m, d), ref.update(m, d), err_msg=f"step {k}")
    assert fast.held == ref.held
    assert len(fast.violations) == len(ref.violations)
    for a, b in zip(fast.violations, ref.violations, strict=True):
        assert (a.step, a.body, a.kind, a.bound) == (b.step, b.body, b.kind, b.bound)
        assert a.value == pytest.approx(b.value, rel=1e-9, abs=1e-12)
    return fast


@pytest.mark.parametrize("scene", ["traffic", "two_arms", "clutter"])
def test_monitor_kernel_matches_numpy_reference_on_scenes(scene: str) -> None:
    """Every verdict and value of the compiled checks equals the numpy reference's, on rollouts
    that break bounds (contacts, impulses) and, for clutter, carry a mocap body."""
    m, d = load_scene(scene)
    ctrl = make_controller(m, "random", seed=4)
    mocap = MocapVelocityTracker(m) if m.nmocap else None
    accel = declared_accel_bound(m) or 5.0
    bounds = MotionBounds.declare(m, accel, speed=8.0)
    mon = _same_updates(m, d, bounds, 600, lambda m, d, k: ctrl(m, d), mocap=mocap)
    assert mon.violations, "the rollout should break a bound somewhere (else the test is weak)"
    if mocap is not None:
        assert mocap.nupdates > 0


def test_monitor_memory_stays_bounded_when_bounds_break_every_step() -> None:
    """Clutter's stirrer breaks a bound nearly every step: the monitor keeps the first
    ``max_violations`` violations, the worst of each body and kind, and runs of broken
    updates, and answers ``bounds_held`` over any window as the per-update record would."""
    m, d = load_scene("clutter")
    ctrl = make_controller(m, "random", seed=4)
    mocap = MocapVelocityTracker(m)
    bounds = MotionBounds.declare(m, 5.0, speed=8.0)
    mon = BoundMonitor(m, bounds, mocap=mocap, max_violations=7)
    full = BoundMonitor(m, bounds, mocap=mocap, max_violations=10**9)
    for _ in range(400):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        mocap.update(d)
        np.testing.assert_array_equal(mon.update(m, d), full.update(m, d))
    assert mon.nviolations == full.nviolations == len(full.violations) > 7
    assert mon.violations == full.violations[:7]
    for (body, kind), v in mon.worst.items():
        assert v.value == max(w.value for w in full.violations if (w.body, w.kind) == (body, kind))
    assert set(mon.worst) == {(v.body, v.kind) for v in full.violations}
    held = mon.held
    assert len(held) == mon.nupdates == 400 and not all(held) and any(held)
    rng = np.random.default_rng(0)
    for start, stop in rng.integers(0, 420, size=(300, 2)):
        assert mon.bounds_held(int(start), int(stop)) == all(held[start:stop])
    assert mon.bounds_held(0, 0) and mon.bounds_held(400)


def test_monitor_kernel_matches_reference_with_offsets_and_impulse() -> None:
    fmax, mass = 10.0, 2.0
    m = _model(FREE_FORCE, "Euler", mass)
    d = mujoco.MjData(m)
    drive = _random_force(fmax, 5)
    drive(m, d, -1)
    sg, sb, _ = default_spheres(m)
    so = np.random.default_rng(2).normal(scale=0.2, size=(sg.size, 3))  # off-centre spheres

    def kick(m: mujoco.MjModel, d: mujoco.MjData, k: int) -> None:
        drive(m, d, k)
        if k == 100:
            d.xfrc_applied[1, :3] = [0.0, 0.0, 500.0]

    bounds = MotionBounds.declare(m, fmax / mass, speed=3.0)
    mon = _same_updates(m, d, bounds, 200, kick, spheres=(sg, sb, so))
    assert {v.kind for v in mon.violations} >= {"accel"}


def test_monitor_rejects_bad_spheres_and_foreign_data() -> None:
    m = _model(FREE_FORCE, "Euler", 1.0)
    b = MotionBounds.declare(m, 1.0)
    sg, sb, so = default_spheres(m)
    with pytest.raises(InvalidInputError, match="geom ids must lie in"):
        BoundMonitor(m, b, (sg + m.ngeom, sb, so))
    with pytest.raises(InvalidInputError, match=r"must have shapes"):
        BoundMonitor(m, b, (sg, sb[:0], so))
    other = _model(CHAIN, "Euler")
    with pytest.raises(InvalidInputError, match="pass the MjData of its model"):
        BoundMonitor(m, b).update(other, mujoco.MjData(other))


def test_monitor_tolerates_round_off_of_uniform_motion() -> None:
    """A body coasting far from the origin has zero acceleration, but second differences of its
    positions carry round-off of ~eps |c| / h^2: the check must not call that a violation."""
    m = _model(FREE_FORCE, "Euler", 1.0)
    d = mujoco.MjData(m)
    d.qpos[:3] = [1234.5, -987.6, 555.5]
    d.qvel[:3] = [3.1, -7.3, 2.9]
    d.qvel[3:6] = [0.7, -0.4, 1.1]
    mon = BoundMonitor(m, MotionBounds.declare(m, 0.0, velocity_accel=2.0))
    for _ in range(200):
        mujoco.mj_step(m, d)
        mon.update(m, d)
    assert mon.bounds_held(), mon.violations[:3]


MOCAP_CIRCLE = """<mujoco><option timestep="0.002" gravity="0 0 0"/><worldbody>
<body name="m" mocap="true"><geom type="sphere" size=".05"/></body>
<body name="ball" pos="2 0 0"><freejoint/><geom type="sphere" size=".05"/></body>
</worldbody></mujoco>"""


@pytest.mark.parametrize("period", [2, 4, 8])
def test_monitor_checks_mocap_discrepancy_at_prediction_instants(period: int) -> None:
    """A mocap body on a circle (|a| = r w^2 = 8 m/s^2), its tracker updated every ``period``
    steps as a predictor does: the tracker's velocity lags, by design, and the predictor allows
    for it. The monitor must check the same hypothesis (at prediction instants, with the same
    allowance), not flag the lag; checking every step against the plain D does flag it. (The
    first updates are skipped: a tracker's first velocity is zero, a true discrepancy of a body
    that starts in motion.)"""
    m = mujoco.MjModel.from_xml_string(MOCAP_CIRCLE)
    h = m.opt.timestep
    bounds = MotionBounds.declare(m, {"m": 8.5, "*": 0.0})

    def rollout(mocap_period: int) -> BoundMonitor:
        d = mujoco.MjData(m)
        tracker = MocapVelocityTracker(m)
        mon = BoundMonitor(m, bounds, mocap=tracker, mocap_period=mocap_period)
        for k in range(600):
            t = (k + 1) * h
            d.mocap_pos[0] = [0.5 * np.cos(4 * t), 0.5 * np.sin(4 * t), 0.0]
            mujoco.mj_step(m, d)
            if k % period == 0:
                tracker.update(d)
            mon.update(m, d)
        return mon

    warm = 2 * period + 1
    assert rollout(period).bounds_held(warm)
    assert any(v.kind == "discrepancy" and v.step >= warm for v in rollout(1).violations)


def test_monitor_of_a_predictor_with_period_and_mocap_holds() -> None:
    from dua_mujoco.measure.monitor import Monitor
    from dua_mujoco.runtime.predictor import Predictor

    m = mujoco.MjModel.from_xml_string(MOCAP_CIRCLE)
    d = mujoco.MjData(m)
    h = m.opt.timestep
    p = Predictor(m, accel={"m": 8.5, "*": 0.0}, period=4)
    mon = Monitor(p)
    mujoco.mj_step(m, d)
    mon.start(d)
    for k in range(1, 601):
        t = (k + 1) * h
        d.mocap_pos[0] = [0.5 * np.cos(4 * t), 0.5 * np.sin(4 * t), 0.0]
        mujoco.mj_step(m, d)
        mon.observe(d, p.step(d) if k % 4 == 0 else None)
    assert mon.bound_checks is not None and mon.bound_checks.bounds_held(9)


@pytest.mark.parametrize("period", [2, 4, 10])
def test_the_steps_check_takes_the_mocap_trackers_lag(period: int) -> None:
    """The step's own check of (E2) on a mocap body within its bounds (the circle, 8 of 8.5
    m/s^2): its tracker's velocity is the chord over the last period, which the period's chord
    differs from by up to A h p (discrete-time.md, section 3, averaged over the period as in
    Lemma 6.3), and the check allows for it. (Its table held D + A h (p - 1) / 2 of a body whose
    velocity MuJoCo reports, and flagged this body at nearly every step: the shield read each as
    a broken bound.)"""
    from dua_mujoco.runtime.predictor import Predictor

    m = mujoco.MjModel.from_xml_string(MOCAP_CIRCLE)
    d = mujoco.MjData(m)
    h = m.opt.timestep
    p = Predictor(m, accel={"m": 8.5, "*": 0.0}, period=period)
    mujoco.mj_step(m, d)
    p.reset(d)
    flagged = []
    for k in range(1, 601):
        t = (k + 1) * h
        d.mocap_pos[0] = [0.5 * np.cos(4 * t), 0.5 * np.sin(4 * t), 0.0]
        mujoco.mj_step(m, d)
        if k % period == 0:
            p.step(d)
            if k > 2 * period:  # the tracker's first velocity is zero: a true discrepancy
                flagged += p.violated_bodies.tolist()
    assert flagged == []


# --------------------------------------------------------------------------------------------------
# What the pilot measures (PilotOptions(motion=...)).
# --------------------------------------------------------------------------------------------------


def test_pilot_levels_are_nested() -> None:
    """Free motion is a subset of the steps without impacts, which are a subset of all steps:
    the bounds can only shrink from one level to the next, body by body (a body a level never
    measures takes the next level's value)."""
    from dua_mujoco.build.bounds import PilotMotion

    m, _ = load_scene("paper_world:20")

    def measure(motion: PilotMotion) -> np.ndarray:
        ctrl = make_controller(m, "random", seed=4)  # the same rollout at every level

        def pilot(mm: mujoco.MjModel, dd: mujoco.MjData, rng: np.random.Generator) -> None:
            ctrl(mm, dd)

        return estimate_bounds(m, steps=600, seed=3, controller=pilot, motion=motion).accel

    accel = {motion: measure(motion) for motion in PilotMotion}
    assert np.all(accel[PilotMotion.FREE] <= accel[PilotMotion.NO_IMPACTS])
    assert np.all(accel[PilotMotion.NO_IMPACTS] <= accel[PilotMotion.ALL])
    # The spheres collide: impacts and contacts are what the lower levels leave out.
    assert accel[PilotMotion.ALL].max() > 5 * accel[PilotMotion.FREE].max()
    with pytest.raises(InvalidChoiceError, match="free"):
        estimate_bounds(m, steps=10, seed=3, motion="smooth")


SCREENED = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <body name="ball" pos="0 0 0.03"><freejoint/><geom type="sphere" size="0.01"/></body>
    <body name="far" pos="0.5 0 0.2"><freejoint/><geom type="sphere" size="0.01"/></body>
    <body name="arm" pos="-0.5 0 0.5">
      <joint type="hinge" axis="0 1 0" range="-20 20"/>
      <geom type="capsule" fromto="0 0 0 0.1 0 0" size="0.01" contype="0" conaffinity="0"/>
      <body name="hand" pos="0.1 0 0"><geom type="sphere" size="0.01" contype="0"/></body>
    </body>
  </worldbody>
</mujoco>
"""


def test_motion_screen_matches_the_last_three_steps_contacts_and_limits() -> None:
    """The pilot's screen, against its definition read off the recorded history: a tree is free
    when none of the last three steps had a contact or joint limit on it, and calm when none had
    a contact that the step before did not. A ball lands and rests, another lands later, an arm
    swings onto its limit and stays; each case occurs, and every step and body agrees."""
    from dua_mujoco.build.pilot_screen import MotionScreen

    m = mujoco.MjModel.from_xml_string(SCREENED)
    d = mujoco.MjData(m)
    root = np.asarray(m.body_rootid)
    geom_root = root[m.geom_bodyid]
    screen = MotionScreen(m)
    history: list[tuple[set[tuple[int, int]], set[int]]] = []
    seen = set()
    for _ in range(250):
        mujoco.mj_step(m, d)
        free, calm = screen.update(d)
        contacts = {(int(c.geom1), int(c.geom2)) for c in d.contact[: d.ncon]}
        limited = {
            int(root[m.jnt_bodyid[d.efc_id[i]]])
            for i in range(d.nefc)
            if d.efc_type[i] == int(mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT)
        }
        history.append((contacts, limited))
        window = range(max(0, len(history) - 3), len(history))
        for body in range(m.nbody):
            tree = int(root[body])
            held = any(
                tree in history[k][1] or any(tree in geom_root[list(c)] for c in history[k][0])
                for k in window
            )
            fresh = any(
                tree in geom_root[list(c)]
                for k in window
                for c in history[k][0] - (history[k - 1][0] if k else set())
            )
            assert calm[body] == (not fresh), (len(history), body)
            assert free[body] == (not fresh and not held), (len(history), body)
            seen.add((m.body(body).name, bool(free[body]), bool(calm[body])))
    # Resting (calm, not free), landing (neither), before landing (both), on the limit; the
    # hand is screened with its arm's tree.
    for case in [("ball", False, True), ("ball", False, False), ("far", True, True),
                 ("far", False, False), ("hand", False, True), ("hand", True, True)]:  # fmt: skip
        assert case in seen, case


def test_motion_screen_marks_only_the_geoms_tree_of_a_flex_contact() -> None:
    """A flex's contact names geom -1 on the flex's side: the screen marks the geom's tree (the
    floor's, static) and no other. Read as an index, -1 was the last geom, whose ball falls free
    far above and was screened out at every step the cloth touched the floor."""
    from dua_mujoco.build.pilot_screen import MotionScreen

    m = mujoco.MjModel.from_xml_string("""
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 .1"/>
    <flexcomp name="cloth" type="grid" count="3 3 1" spacing=".04 .04 .04" pos="0 0 .05" dim="2"
              radius=".01" mass=".05"><edge equality="true"/></flexcomp>
    <body name="ball" pos="1 1 5"><freejoint/><geom type="sphere" size=".05"/></body>
  </worldbody>
</mujoco>
""")
    d = mujoco.MjData(m)
    screen = MotionScreen(m)
    ball = m.body("ball").id
    flex_contacts = 0
    for _ in range(150):
        mujoco.mj_step(m, d)
        free, calm = screen.update(d)
        flex_contacts += int(np.count_nonzero(np.asarray(d.contact.geom)[: d.ncon] < 0))
        assert free[ball] and calm[ball]
    assert flex_contacts > 0 and m.geom_bodyid[-1] == ball


def test_free_motion_bounds_of_a_landing_ball_are_its_free_fall() -> None:
    """Free motion leaves the landing and the rest out: a ball that falls, lands and rests gets
    its fall's bound (safety x g), though its landing's second differences are several times
    that (the bound on every step shows them)."""
    from dua_mujoco.build.bounds import PilotMotion

    m = mujoco.MjModel.from_xml_string(SCREENED)
    ball = m.body("ball").id
    g = float(np.linalg.norm(m.opt.gravity))
    free = estimate_bounds(m, steps=200, seed=0, motion=PilotMotion.FREE).accel[ball]
    every = estimate_bounds(m, steps=200, seed=0, motion=PilotMotion.ALL).accel[ball]
    assert free == pytest.approx(2.0 * g, rel=1e-6)
    assert every > 3 * free


def test_pilot_warns_about_a_mocap_body_it_never_moved() -> None:
    """Random controls do not move clutter's stirrer (the scene's controller does): its bounds
    would be 0 and every step of a run that moves it would break them. The pilot says so."""
    from dua_mujoco.exceptions import PilotWarning

    m, _ = load_scene("clutter")
    with pytest.warns(PilotWarning, match="'stirrer'"):
        estimate_bounds(m, steps=50, seed=3)
    ctrl = make_controller(m, "random", seed=4)

    def pilot(mm: mujoco.MjModel, dd: mujoco.MjData, rng: np.random.Generator) -> None:
        ctrl(mm, dd)

    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", PilotWarning)
        bounds = estimate_bounds(m, steps=50, seed=3, controller=pilot)
    assert bounds.accel[m.body("stirrer").id] > 0
