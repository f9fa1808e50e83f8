"""The shield's failsafe (dua_mujoco.shield.failsafe): a brake to rest within the actuators'
limits on every shield scene's robot, any affine actuator, and a clear refusal of the others."""

from __future__ import annotations

import itertools

import mujoco
import numpy as np
import pytest
from reference_brake import ReferenceBrake, bounded_lstsq

from dua_mujoco.exceptions import InvalidInputError, ShapeError
from dua_mujoco.experiments.shield.episodes import body_reach_radius, body_speeds
from dua_mujoco.models.cells import SHIELD_SCENES
from dua_mujoco.shield.failsafe import Brake

STOP_TIME = {"person_cell": 0.06, "arm_pair": 0.06, "mobile_cell": 0.45}
"""The longest stop from the task's speeds, with a margin (measured over 100 states each:
person_cell 38 ms, arm_pair 30 ms, mobile_cell 386 ms)."""

FOLDED = [0.0, -0.6, 2.4, 0.8, 0.0, 0.0]


def _random_state(
    scene: str, model: mujoco.MjModel, data: mujoco.MjData, brake: Brake, seed: int
) -> None:
    """A state the task visits, with every robot DOF at a random speed within the task's."""
    sc = SHIELD_SCENES[scene]
    rng = np.random.default_rng(seed)
    episode = sc.episode(model, data, seed)
    if model.nmocap:  # the scripted bodies out of the way
        data.mocap_pos[:] = 20.0 + 3.0 * np.arange(model.nmocap)[:, None]
    ctrl = data.ctrl.copy()
    for k in range(int(rng.integers(0, 1500))):
        if k % sc.period == 0:
            ctrl = episode.policy(model, data)
        data.ctrl[:] = ctrl
        mujoco.mj_step(model, data)
    if scene == "arm_pair":  # arm B folded and held, out of A's way
        data.qpos[6:12] = FOLDED
        data.qvel[6:12] = 0.0
        data.ctrl[6:12] = FOLDED
    data.qvel[brake.dofs] = rng.uniform(-1, 1, brake.dofs.size) * np.array(sc.task_speed)


@pytest.mark.parametrize("scene", list(SHIELD_SCENES))
def test_the_brake_stops_each_scene_robot_and_holds_it(scene: str) -> None:
    """From random states within the task's speeds, every robot body's points come to at most
    1 cm/s within the scene's stop time, and stay there for half a second; the controls stay
    within their ranges."""
    sc = SHIELD_SCENES[scene]
    model = sc.model()
    data = mujoco.MjData(model)
    brake = Brake(model, actuators=sc.robot_actuators(model))
    radius = body_reach_radius(model)
    lo, hi = model.actuator_ctrlrange.T
    stops = []
    for seed in range(12):
        _random_state(scene, model, data, brake, seed)
        start = float(data.time)
        stop = None
        while data.time - start < STOP_TIME[scene] + 0.5:
            ctrl = brake(model, data)
            assert np.all((ctrl >= lo - 1e-12) & (ctrl <= hi + 1e-12))
            data.ctrl[:] = ctrl
            mujoco.mj_step(model, data)
            speed = body_speeds(model, data, brake.bodies, radius).max()
            if stop is None and speed <= 0.01:
                stop = float(data.time) - start
            elif stop is not None:
                assert speed <= 0.01, (seed, data.time - start)
        assert stop is not None and stop <= STOP_TIME[scene], (seed, stop)
        stops.append(stop)
    assert max(stops) > 0.3 * STOP_TIME[scene]  # the states do move the robot


def test_the_brake_holds_gravity_where_the_servos_alone_sag() -> None:
    """An arm at rest, its servos' targets left where they were: the arm sags under gravity
    until the servos catch it. The brake holds it still from the first step."""
    model = SHIELD_SCENES["person_cell"].model()
    data = mujoco.MjData(model)
    brake = Brake(model, actuators=np.arange(6))
    radius = body_reach_radius(model)
    for use_brake in (True, False):
        mujoco.mj_resetData(model, data)
        data.mocap_pos[:] = 20.0
        data.qpos[:6] = [0.3, 1.2, 0.2, 0.5, 0.0, 0.0]  # reaching out, heavy on the shoulder
        data.ctrl[:6] = 0.0  # servo targets far from the pose
        worst = 0.0
        for _ in range(100):
            if use_brake:
                data.ctrl[:] = brake(model, data)
            mujoco.mj_step(model, data)
            worst = max(worst, body_speeds(model, data, brake.bodies, radius).max())
        if use_brake:
            assert worst <= 0.01
        else:
            assert worst > 0.1


def test_toward_drives_the_base_to_a_velocity() -> None:
    sc = SHIELD_SCENES["mobile_cell"]
    model = sc.model()
    data = mujoco.MjData(model)
    sc.episode(model, data, 0)
    data.mocap_pos[:] = 20.0
    brake = Brake(model, actuators=sc.robot_actuators(model))
    target = np.array([0.5, -0.3, 0.2])
    for _ in range(300):
        data.ctrl[:] = brake.toward(data, target)
        mujoco.mj_step(model, data)
    assert np.allclose(data.qvel[brake.dofs], target, atol=1e-3)
    with pytest.raises(ShapeError, match=r"shape \(3,\)"):
        brake.toward(data, np.zeros(2))


ACTUATED = """
<mujoco>
  <option timestep="0.002" integrator="{integrator}"/>
  <worldbody>
    <body name="link1" pos="0 0 1">
      <joint name="j1" type="hinge" axis="0 1 0" damping="0.5" armature="0.01"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04"/>
      <body name="link2" pos="0.4 0 0">
        <joint name="j2" type="hinge" axis="0 1 0" armature="0.01"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
      </body>
    </body>
  </worldbody>
  <actuator>{actuators}</actuator>
</mujoco>
"""

AFFINE = {
    "motor": '<motor joint="j1" gear="2" ctrlrange="-30 30"/>'
    '<motor joint="j2" ctrlrange="-20 20"/>',
    "position": '<position joint="j1" kp="300" kv="20" ctrlrange="-3 3" forcerange="-60 60"/>'
    '<position joint="j2" kp="100" kv="5" ctrlrange="-3 3" forcerange="-20 20"/>',
    "velocity": '<velocity joint="j1" kv="50" ctrlrange="-5 5" forcerange="-60 60"/>'
    '<velocity joint="j2" kv="20" ctrlrange="-5 5" forcerange="-20 20"/>',
    "general": '<general joint="j1" gainprm="40 0 0" biasprm="0 -40 -4" ctrlrange="-3 3"/>'
    '<general joint="j2" gaintype="affine" gainprm="20 0 0" biastype="affine"'
    ' biasprm="0 -20 -2" ctrlrange="-3 3" forcerange="-15 15"/>',
    # Both actuators on one joint, and a second joint driven through the first's tendon:
    # a moment matrix that is not the identity.
    "coupled": '<motor joint="j1" ctrlrange="-30 30"/><motor joint="j1" gear="-1"'
    ' ctrlrange="-30 30"/><motor joint="j2" ctrlrange="-20 20"/>',
}


@pytest.mark.parametrize(
    ("kind", "integrator"),
    list(itertools.product(AFFINE, ["Euler", "implicitfast", "RK4", "implicit"])),
)
def test_the_brake_takes_every_affine_actuator_and_integrator(kind: str, integrator: str) -> None:
    model = mujoco.MjModel.from_xml_string(
        ACTUATED.format(integrator=integrator, actuators=AFFINE[kind])
    )
    data = mujoco.MjData(model)
    brake = Brake(model)
    radius = body_reach_radius(model)
    rng = np.random.default_rng(0)
    for _ in range(5):
        mujoco.mj_resetData(model, data)
        data.qpos[:] = rng.uniform(-1, 1, 2)
        data.qvel[:] = rng.uniform(-3, 3, 2)
        for _ in range(500):
            data.ctrl[:] = brake(model, data)
            mujoco.mj_step(model, data)
        assert body_speeds(model, data, brake.bodies, radius).max() <= 0.01


def test_the_brake_counts_what_gravity_compensation_already_holds() -> None:
    """Bodies with ``gravcomp``: MuJoCo's passive force holds their weight, so the brake must
    not add it again (it reads ``qfrc_passive``)."""
    xml = ACTUATED.format(integrator="Euler", actuators=AFFINE["motor"])
    xml = xml.replace(
        '<body name="link1" pos="0 0 1">', '<body name="link1" pos="0 0 1" gravcomp="1">'
    )
    xml = xml.replace(
        '<body name="link2" pos="0.4 0 0">', '<body name="link2" pos="0.4 0 0" gravcomp="1">'
    )
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    brake = Brake(model)
    radius = body_reach_radius(model)
    data.qpos[:] = [0.3, -0.5]
    for _ in range(250):
        data.ctrl[:] = brake(model, data)
        mujoco.mj_step(model, data)
        assert body_speeds(model, data, brake.bodies, radius).max() <= 0.01


def _applied(model: mujoco.MjModel, data: mujoco.MjData, ctrl: np.ndarray) -> np.ndarray:
    """The joint forces ``ctrl`` applies at ``data``'s state (``qfrc_actuator``)."""
    probe = mujoco.MjData(model)
    probe.qpos[:], probe.qvel[:], probe.ctrl[:] = data.qpos, data.qvel, ctrl
    mujoco.mj_forward(model, probe)
    return np.array(probe.qfrc_actuator)


@pytest.mark.parametrize(
    ("kind", "integrator"),
    list(itertools.product(AFFINE, ["Euler", "implicitfast", "RK4", "implicit"])),
)
def test_the_native_brake_is_the_reference_brake(kind: str, integrator: str) -> None:
    """The native brake (csrc/src/brake.cc) applies the joint forces of the numpy reference
    (tests/reference_brake.py), braking and driving toward a velocity, from random states with
    random last controls. Where two actuators act alike ("coupled") the forces split between
    them are not unique, the joint forces are."""
    model = mujoco.MjModel.from_xml_string(
        ACTUATED.format(integrator=integrator, actuators=AFFINE[kind])
    )
    data = mujoco.MjData(model)
    native, reference = Brake(model), ReferenceBrake(model)
    lo, hi = model.actuator_ctrlrange.T
    rng = np.random.default_rng(3)
    for _ in range(20):
        data.qpos[:] = rng.uniform(-1, 1, 2)
        data.qvel[:] = rng.uniform(-3, 3, 2)
        data.ctrl[:] = rng.uniform(lo, hi)
        target = rng.uniform(-2, 2, native.dofs.size)
        for mine, theirs in [
            (native(model, data), reference(model, data)),
            (native.toward(data, target), reference.toward(data, target)),
        ]:
            if kind != "coupled":
                assert np.allclose(mine, theirs, rtol=1e-7, atol=1e-9)
            want, got = _applied(model, data, theirs), _applied(model, data, mine)
            assert np.allclose(got, want, rtol=1e-7, atol=1e-7)


@pytest.mark.parametrize("scene", list(SHIELD_SCENES))
def test_the_native_brake_is_the_reference_brake_on_each_scene(scene: str) -> None:
    sc = SHIELD_SCENES[scene]
    model = sc.model()
    data = mujoco.MjData(model)
    acts = sc.robot_actuators(model)
    native, reference = Brake(model, actuators=acts), ReferenceBrake(model, actuators=acts)
    assert np.array_equal(native.bodies, reference.bodies)
    assert np.array_equal(native.dofs, reference.dofs)
    for seed in range(4):
        _random_state(scene, model, data, native, seed)
        assert np.allclose(native(model, data), reference(model, data), rtol=1e-7, atol=1e-9)


REFUSED = {
    "muscle": '<muscle joint="j1" lengthrange="-1 1"/>',
    "filter": '<position joint="j1" kp="100" timeconst="0.05"/>',
    "intvelocity": '<intvelocity joint="j1" kp="100" actrange="-1 1"/>',
    "integrator": '<general joint="j1" dyntype="integrator" gainprm="10" actrange="-1 1"/>',
}


@pytest.mark.parametrize("kind", list(REFUSED))
def test_other_actuators_are_refused_by_name_and_type(kind: str) -> None:
    model = mujoco.MjModel.from_xml_string(
        ACTUATED.format(integrator="Euler", actuators=REFUSED[kind] + '<motor joint="j2"/>')
    )
    with pytest.raises(
        InvalidInputError, match=r"not: .*dyntype (muscle|filter|integrator)"
    ) as err:
        Brake(model)
    assert "j2" not in str(err.value)  # the motor is fine; only the bad one is listed
    Brake(model, actuators=[1])  # the motor alone is a robot it can brake


def test_bad_arguments_are_refused() -> None:
    model = mujoco.MjModel.from_xml_string(
        ACTUATED.format(integrator="Euler", actuators=AFFINE["motor"])
    )
    with pytest.raises(InvalidInputError, match="actuators"):
        Brake(model, actuators=[5])
    with pytest.raises(InvalidInputError, match="time_constant"):
        Brake(model, time_constant=0.0)


def test_the_bounded_least_squares_is_optimal() -> None:
    """Against the KKT conditions and a brute force over the faces of the box."""
    rng = np.random.default_rng(1)
    for _ in range(200):
        m, n = rng.integers(1, 6), rng.integers(1, 5)
        a = rng.normal(size=(m, n))
        b = rng.normal(size=m) * 3
        lo = -rng.uniform(0, 2, n)
        hi = rng.uniform(0, 2, n)
        lo[rng.random(n) < 0.1] = -np.inf
        x = bounded_lstsq(a, b, lo, hi)
        assert np.all((x >= lo - 1e-12) & (x <= hi + 1e-12))
        best = np.inf
        for face in itertools.product((-1, 0, 1), repeat=n):
            fixed = np.array(face)
            z = np.where(fixed < 0, lo, np.where(fixed > 0, hi, 0.0))
            free = fixed == 0
            if np.any(~free & ~np.isfinite(z)):
                continue
            if free.any():
                z[free] = np.linalg.lstsq(a[:, free], b - a[:, ~free] @ z[~free], rcond=None)[0]
            if np.all((z >= lo - 1e-9) & (z <= hi + 1e-9)):
                best = min(best, float(np.sum((a @ z - b) ** 2)))
        assert np.sum((a @ x - b) ** 2) <= best + 1e-8
