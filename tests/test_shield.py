"""``dua_mujoco.Shield``: the guarantee on sampled episodes of the three shield scenes, what it
counts, and its errors.

The guarantee (docs/theory.md, section 10): while the protected bodies keep their declared
bounds and the robot keeps within its deviation of what the shield rolled out, every protected
contact finds the robot's body in the pair at rest (every point at most 1 cm/s). The episodes'
scripted bodies move within their declared bounds (tests/test_shield_scenes.py); arm_pair's arm B
breaks its bounds only when arm A is in its way, and a contact after that, or within a second
after a touch (the robot pushed off its rollout), is excused (``moving_excused``), as in
docs/shield.md. ``moving_free`` counts the others: the guarantee says there are none.
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np
import pytest
from mjcf import mjcf, motors

import dua_mujoco
from dua_mujoco import Shield
from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.experiments.shield.bench import shield_layer
from dua_mujoco.experiments.shield.episodes import NoLayer, SceneSetup, run_episode
from dua_mujoco.models.cells import SHIELD_SCENES

# Seeds and a shortened episode per scene: enough approaches that the unshielded robot moves
# into a protected body several times (asserted below, so that the shield's 0 means something).
EPISODES = {
    "person_cell": (range(16), 6.0),
    "arm_pair": (range(16), 3.0),
    "mobile_cell": (range(16), 4.0),
}


@pytest.mark.slow
@pytest.mark.parametrize(
    ("scene", "layer"),
    [pytest.param(scene, "shield", id=scene) for scene in SHIELD_SCENES]
    + [pytest.param("mobile_cell", "shield-brake", id="mobile_cell-brake")],
)
def test_every_protected_contact_finds_the_robot_at_rest(scene: str, layer: str) -> None:
    """Over sampled episodes (the others' motion drawn within their declared bounds), the
    shielded robot is never moving at a protected contact the guarantee covers, while the same
    episodes unshielded have such contacts; the shield's run is its verified plans (no plan,
    hold or stop break) and it intervened. The scene's shield (mobile_cell's with its evasive
    failsafe), and mobile_cell's with the brake."""
    setup = SceneSetup.of(scene)
    seeds, duration = EPISODES[scene]
    free = shielded = interventions = 0
    for seed in seeds:
        free += run_episode(setup, NoLayer(), "none", seed, duration=duration).moving_free
        shield = shield_layer(setup, layer)
        result = run_episode(setup, shield, layer, seed, duration=duration)
        shielded += result.moving_free
        interventions += result.interventions
        counts = shield.counts
        assert counts["stop_breaks"] == 0, (seed, counts)
        if result.first_touch is None and result.violations == 0:
            # Nothing pushed the robot and every bound held: the run kept to the verified
            # plans and every step was guaranteed.
            broken = [counts[k] for k in ("plan_breaks", "hold_breaks", "unguaranteed")]
            assert broken == [0, 0, 0], (seed, counts)
    assert free >= 5
    assert shielded == 0
    assert interventions > 0


@pytest.mark.slow
def test_without_the_screen_every_period_is_rolled_out_and_the_guarantee_holds() -> None:
    """shield-noscreen (a rollout and a plan query every period) on person_cell's episodes."""
    setup = SceneSetup.of("person_cell")
    seeds, duration = EPISODES["person_cell"]
    total = 0
    for seed in seeds[:6]:
        shield = shield_layer(setup, "shield-noscreen")
        total += run_episode(setup, shield, "noscreen", seed, duration=duration).moving_free
        assert shield.counts["screened"] == 0
        assert shield.counts["accepted"] > 0
    assert total == 0


def _arm() -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = SHIELD_SCENES["person_cell"].model()
    return model, mujoco.MjData(model)


def _shield(model: mujoco.MjModel, **options: object) -> Shield:
    kwargs: dict[str, object] = {"protect": ["person*"], "period": 10, "accel": 5.0}
    kwargs.update(options)
    return Shield(model, **kwargs)  # type: ignore[arg-type]


def test_the_shield_is_exported_and_counts_what_it_did() -> None:
    """``dua_mujoco.Shield`` is the shield; far from the person the intended controls pass
    untouched, and a reset starts the counts over."""
    assert "Shield" in dua_mujoco.__all__ and dua_mujoco.Shield is Shield
    model, data = _arm()
    data.mocap_pos[:] = [[20.0, 20.0, 0.0], [20.0, 25.0, 0.0]]  # the person far away
    mujoco.mj_forward(model, data)
    shield = _shield(model)
    assert shield.pairs.shape[1] == 2 and len(shield.pairs) > 0
    assert set(np.asarray(model.geom_bodyid)[shield.pairs[:, 0]].tolist()) <= set(
        shield.robot_bodies.tolist()
    )
    shield.reset(data)
    intended = data.ctrl.copy()
    for _ in range(30):
        ctrl = shield(data, intended)
        data.ctrl[:] = ctrl
        mujoco.mj_step(model, data)
    # The first period after a reset runs the failsafe (the mocap velocities are not known yet).
    assert shield.interventions == 10
    assert shield.counts["steps"] == 30
    np.testing.assert_array_equal(ctrl, intended)
    # Any array-like of controls: a list and a float32 array are converted.
    np.testing.assert_array_equal(shield(data, intended.tolist()), intended)
    np.testing.assert_array_equal(shield(data, intended.astype(np.float32)), intended)
    shield.reset(data)
    assert shield.interventions == 0 and shield.counts["steps"] == 0


_PAIRED = """
<mujoco>
  <worldbody>
    <body name="arm">
      <joint name="hinge" axis="0 0 1"/>
      <geom name="link" type="capsule" fromto="0 0 0 0.5 0 0" size="0.05"/>
    </body>
    <body name="person" mocap="true" pos="1 0 0">
      <geom name="torso" type="capsule" size="0.1 0.5"/>
    </body>
  </worldbody>
  <contact><pair geom1="link" geom2="torso"/></contact>
  <actuator><motor joint="hinge"/></actuator>
</mujoco>
"""


def test_bad_input_is_named_with_its_fix() -> None:
    model, data = _arm()
    with pytest.raises(InvalidInputError, match=r"protect: 'persn\*' names no body.*person_arm"):
        _shield(model, protect=["persn*"])
    with pytest.raises(InvalidInputError, match=r"robot: 'arm\?' names no body"):
        _shield(model, robot=["arm?"])
    with pytest.raises(InvalidInputError, match=r"period = 0 is invalid"):
        _shield(model, period=0)
    with pytest.raises(InvalidInputError, match=r"deviation = -0.1 is invalid"):
        _shield(model, deviation=-0.1)
    with pytest.raises(InvalidInputError, match=r"stop_time = 1e-05 is invalid"):
        _shield(model, stop_time=1e-5)
    with pytest.raises(InvalidInputError, match=r"failsafe = 3 is invalid"):
        _shield(model, failsafe=3)
    with pytest.raises(InvalidInputError, match=r"protect names no body the robot's geoms can"):
        _shield(model, protect=["arm_link1"])
    # A <pair> element with a protected geom: the rollouts could not take it out of the contacts.
    paired = mujoco.MjModel.from_xml_string(_PAIRED)
    with pytest.raises(InvalidInputError, match=r"a protected geom is in an explicit <pair>"):
        Shield(paired, protect="person", accel=5.0)
    model.opt.integrator = int(mujoco.mjtIntegrator.mjINT_RK4)
    with pytest.raises(InvalidInputError, match=r"integrator is RK4.*use Euler, implicit"):
        _shield(model)
    model.opt.integrator = int(mujoco.mjtIntegrator.mjINT_EULER)
    shield = _shield(model)
    shield.reset(data)
    with pytest.raises(Exception, match=r"one control per actuator"):
        shield(data, np.zeros(model.nu + 1))


# A 1 kg box on one joint (a hinge about z with the box 0.3 m out, or a slide along x) and a
# post on the x axis; a 1 N m / 1 N motor.
_ONE_JOINT = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <body name="robot">
      <joint name="joint" type="{joint}" axis="{axis}"/>
      <geom type="box" size="0.05 0.05 0.05" pos="{offset} 0 0" mass="1"/>
    </body>
    <body name="post" pos="{post} 0 0"><geom type="box" size="0.1 0.1 0.1"/></body>
  </worldbody>
  <actuator><motor joint="joint" ctrlrange="-1 1"/></actuator>
</mujoco>
"""


def _first_period(
    joint: str, offset: float, post: float, speed: float, **options: Any
) -> dict[str, int]:
    """The counts after the first period (one step) of the shield on ``_ONE_JOINT`` with the
    joint at ``speed`` (the box ``offset`` m out along x, the post at x = ``post``)."""
    axis = "0 0 1" if joint == "hinge" else "1 0 0"
    xml = _ONE_JOINT.format(joint=joint, axis=axis, offset=offset, post=post)
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qvel[0] = speed
    mujoco.mj_forward(model, data)
    shield = Shield(model, protect=["post"], robot=["robot"], period=1, accel=5.0, **options)
    shield.reset(data)
    shield(data, data.ctrl.copy())
    return shield.counts


def test_a_robot_spinning_in_place_is_not_at_rest() -> None:
    """A link turning about a hinge through its frame origin has that origin still, but its
    geom, 0.3 m out, moves at 0.6 m/s: the rest test counts every point (the turn times the
    body's reach), so the first period's rollout brakes it (1 N m: about 0.2 s) instead of
    finding it at rest one step in (as a test on the origin's speed alone would)."""
    counts = _first_period("hinge", 0.3, 2.0, 2.0)
    assert counts["rollout_steps"] > 50, counts


def _cart_period(deviation: float, stop_distance: float | None = None) -> dict[str, int]:
    """The counts after the first period of a 1 kg cart at 0.3 m/s toward a post 0.15 m away
    (its 1 N motor stops it in 4.5 cm), the screen off: that period's candidate rolled out."""
    return _first_period(
        "slide", 0.0, 0.3, 0.3, deviation=deviation, stop_distance=stop_distance, screen=False
    )


@pytest.mark.parametrize(("deviation", "accepted"), [(0.0, True), (0.16, False)])
def test_a_candidate_whose_deviation_reaches_the_protected_body_is_refused(
    deviation: float, accepted: bool
) -> None:
    """The cart comes to rest about 0.1 m from the post: its rollout passes as it is, and is
    refused when the robot may stray 0.16 m from it (the deviation reaches the post before the
    rest knot)."""
    counts = _cart_period(deviation)
    assert (counts["accepted"], counts["rejected"]) == (int(accepted), int(not accepted)), counts


@pytest.mark.parametrize(
    ("deviation", "stop_distance", "accepted"), [(0.0, 0.05, True), (0.05, 0.06, False)]
)
def test_the_stop_envelope_counts_twice_the_deviation(
    deviation: float, stop_distance: float, accepted: bool
) -> None:
    """With a stop envelope the candidate rolls the brake one period and trusts the envelope
    after it: the robot within 2 deviation + stop_distance of that pose (within D of the plan
    when the failsafe starts, within D of the failsafe after). 2 * 0.05 + 0.06 reaches the post
    0.15 m away before rest; D + stop_distance (0.11) would not."""
    counts = _cart_period(deviation, stop_distance)
    assert (counts["accepted"], counts["rejected"]) == (int(accepted), int(not accepted)), counts


@pytest.mark.parametrize(
    ("deviation", "stop_distance", "holds"),
    [(0.0, 0.04, False), (0.01, 0.03, False), (0.0, 0.05, True)],
)
def test_a_failsafe_leaving_its_stop_envelope_is_a_stop_break(
    deviation: float, stop_distance: float, holds: bool
) -> None:
    """The cart coasts at 0.3 m/s toward the post and brakes in 4.5 cm. Declared a stop
    envelope a little short of that (0.04 m, or 0.03 m + D = 0.01 m), the candidates pass until
    the envelope reaches the post; the failsafe then rolled out leaves the envelope by about
    5 mm before rest, and its own query finds the post: a stop break, the steps after it not
    guaranteed (the cart does touch the post, moving, with 0.04 m). An envelope that holds
    (0.05 m) has none, and the cart stops short of the post."""
    xml = _ONE_JOINT.format(joint="slide", axis="1 0 0", offset=0.0, post=0.3)
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qvel[0] = 0.3
    mujoco.mj_forward(model, data)
    shield = Shield(
        model, protect=["post"], robot=["robot"], period=1, accel=5.0, deviation=deviation,
        stop_distance=stop_distance, screen=False,
    )  # fmt: skip
    shield.reset(data)
    for _ in range(400):
        data.ctrl[:] = shield(data, [0.0])
        mujoco.mj_step(model, data)
    counts = shield.counts
    assert counts["rejected"] > 0, counts
    assert (counts["stop_breaks"], counts["unguaranteed"] == 0) == (int(not holds), holds), counts


# A 1 kg ball on a slide along x and a wall at x = 0.3 (its face at 0.25); a 1 N motor.
_BALL = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <body name="ball"><joint name="x" type="slide" axis="1 0 0"/><geom size="0.05" mass="1"/></body>
    <body name="wall" pos="0.3 0 0"><geom type="box" size="0.05 0.5 0.5"/></body>
  </worldbody>
  <actuator><motor joint="x" ctrlrange="-1 1"/></actuator>
</mujoco>
"""


@pytest.mark.parametrize(("start", "speed", "push"), [(0.2, 0.0, 1.0), (0.202, -0.2, -1.0)])
def test_a_robot_touching_a_protected_body_is_refused_without_a_rollout(
    start: float, speed: float, push: float
) -> None:
    """Every candidate's knot 0 is the state read: the ball touching the wall (at rest and
    pushing, or leaving it) is refused whatever it intends, before any candidate is rolled out;
    the one rollout is the failsafe's from there, none when the ball is at rest already (that
    state is the failsafe's rest knot). 0.1 m off, the candidate is rolled out and passes."""
    model = mujoco.MjModel.from_xml_string(_BALL)
    for x, refused in ((start, True), (start - 0.1, False)):
        data = mujoco.MjData(model)
        data.qpos[0], data.qvel[0] = x, speed
        mujoco.mj_forward(model, data)
        shield = Shield(model, protect=["wall"], robot=["ball"], period=1, accel=5.0, screen=False)
        shield.reset(data)
        shield(data, [push])
        counts = shield.counts
        assert (counts["rejected"], counts["accepted"]) == (int(refused), int(not refused)), counts
        assert counts["rollouts"] == int(not refused or speed != 0.0), counts


def test_a_velocity_that_is_not_a_number_is_no_rest() -> None:
    """The ball touching the wall at rest is refused and held at its own rest knot (knot 0);
    every step past it checks that it still is at rest (the hold). A velocity that is not a
    number there is a hold break, the guarantee dropped, not a speed under 1 cm/s (a NaN
    compares false with the bound either way: Shield::Speed reads it as no rest)."""
    model = mujoco.MjModel.from_xml_string(_BALL)
    data = mujoco.MjData(model)
    data.qpos[0] = 0.2
    mujoco.mj_forward(model, data)
    shield = Shield(model, protect=["wall"], robot=["ball"], period=5, accel=5.0, screen=False)
    shield.reset(data)
    guaranteed = []
    for k in range(4):
        if k == 2:
            data.qvel[0] = np.nan
        shield(data, [1.0])
        guaranteed.append(shield.guaranteed)
    counts = shield.counts
    assert (counts["rejected"], counts["rollouts"]) == (1, 0), counts  # knot 0 at rest
    assert guaranteed == [True, True, False, False], counts
    assert counts["hold_breaks"] == 1, counts


# _BALL's ball, free to spin about z as well (a hinge through its centre, radius 0.05 m).
_SPINNING_BALL = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <body name="ball">
      <joint name="x" type="slide" axis="1 0 0"/><joint name="spin" type="hinge" axis="0 0 1"/>
      <geom size="0.05" mass="1"/>
    </body>
    <body name="wall" pos="0.3 0 0"><geom type="box" size="0.05 0.5 0.5"/></body>
  </worldbody>
  <actuator>
    <motor joint="x" ctrlrange="-1 1"/><motor joint="spin" ctrlrange="-1 1"/>
  </actuator>
</mujoco>
"""


def _at_most(rest: float, radius: float) -> float:
    """The largest spin w whose speed at ``radius``, w * radius in floating point, is at most
    ``rest``."""
    w = rest / radius
    while w * radius > rest:
        w = math.nextafter(w, 0.0)
    while math.nextafter(w, math.inf) * radius <= rest:
        w = math.nextafter(w, math.inf)
    return w


@pytest.mark.parametrize("past", [False, True], ids=["at", "past"])
@pytest.mark.parametrize("dof", ["slide", "spin"])
def test_a_held_robot_breaks_its_hold_one_ulp_past_rest_speed(dof: str, past: bool) -> None:
    """The ball touching the wall at rest is refused and held at its own rest knot; every step
    past it checks that the robot is still at rest: every point at most ``rest_speed`` (here
    2 cm/s), ``|v| + |w| r`` with ``r`` the body's reach (0.05 m). Exactly at ``rest_speed``
    (sliding at 0.02 m/s, or spinning at the largest ``w`` with ``w * 0.05 <= 0.02``) it is at
    rest and the guarantee stands; one ulp past it (the next double's speed) is a hold break, the
    guarantee dropped. A strict comparison fails the first; a looser bound, or a rest test
    without the turn's term, the second."""
    rest = 0.02
    model = mujoco.MjModel.from_xml_string(_SPINNING_BALL)
    data = mujoco.MjData(model)
    data.qpos[0] = 0.2
    mujoco.mj_forward(model, data)
    shield = Shield(
        model,
        protect=["wall"],
        robot=["ball"],
        period=5,
        accel=5.0,
        screen=False,
        rest_speed=rest,
    )
    shield.reset(data)
    speed = rest if dof == "slide" else _at_most(rest, 0.05)
    guaranteed = []
    for k in range(3):
        if k == 2:
            data.qvel[0 if dof == "slide" else 1] = math.nextafter(speed, 1.0) if past else speed
        shield(data, [1.0, 0.0])
        guaranteed.append(shield.guaranteed)
    counts = shield.counts
    assert (counts["rejected"], counts["rollouts"]) == (1, 0), counts  # knot 0 at rest
    assert guaranteed == [True, True, not past], counts
    assert counts["hold_breaks"] == int(past), counts


def _sliding(name: str, x: float) -> str:
    """A 1 kg ball ``name`` resting on the floor at ``x``, on slides along x and z."""
    return (
        f'<body name="{name}" pos="{x} 0 0.05"><joint name="x{name}" type="slide" axis="1 0 0"/>'
        f'<joint name="z{name}" type="slide" axis="0 0 1"/><geom size="0.05" mass="1"/></body>'
    )


# Two balls resting on the floor under gravity, each pushed along x by a motor.
_RESTING = mjcf(
    '<geom name="floor" type="plane" size="2 2 0.1"/>',
    _sliding("b1", 0.0),
    _sliding("b2", 0.5),
    option='timestep="0.002"',
    actuator=motors("xb1", "xb2", ctrlrange="-1 1"),
)


def test_protected_robot_bodies_keep_their_contacts_in_the_rollout() -> None:
    """Two robot bodies named in protect (their pair is protected) stay in the rollout's
    contacts: only bodies nobody plans are taken out of it (their geoms and, for the
    broadphase, their bodies). The floor holds both balls in every rollout, so each gentle push
    passes at its first knot at rest; taken out, the balls would fall through the floor in
    every rollout and every candidate be refused."""
    model = mujoco.MjModel.from_xml_string(_RESTING)
    data = mujoco.MjData(model)
    for _ in range(200):  # settled on the floor
        mujoco.mj_step(model, data)
    shield = Shield(model, protect=["b1", "b2"], period=1, accel=5.0, screen=False)
    shield.reset(data)
    for _ in range(20):
        data.ctrl[:] = shield(data, [0.5, 0.0])
        mujoco.mj_step(model, data)
    counts = shield.counts
    assert (counts["accepted"], counts["rollout_steps"]) == (20, 20), counts


def _sagging(
    torque: float, post: float = 0.25, **options: Any
) -> tuple[mujoco.MjModel, mujoco.MjData, Shield]:
    """A 1 kg box 0.3 m out on a hinge about y, horizontal, its motor at most ``torque`` N m
    (gravity's is 2.9 N m); a post ``post`` m along x, 0.35 m down (0.25: below the box's arc,
    0.1 m under it). Its shield (the box the robot, the post protected; ``options`` more), reset
    on the box at rest."""
    model = mujoco.MjModel.from_xml_string(
        mjcf(
            '<body name="robot" pos="0 0 1"><joint name="joint" type="hinge" axis="0 1 0"/>'
            '<geom type="box" size="0.05 0.05 0.05" pos="0.3 0 0" mass="1"/></body>',
            f'<body name="post" pos="{post} 0 0.65"><geom type="box" size="0.1 0.1 0.1"/></body>',
            option='timestep="0.002"',
            actuator=motors("joint", ctrlrange=f"{-torque} {torque}"),
        )
    )
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    shield = Shield(
        model, protect=["post"], robot=["robot"], period=1, accel=5.0, screen=False, **options
    )
    shield.reset(data)
    return model, data, shield


def _pull_up(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """A failsafe policy for the box: its motor's whole torque against gravity."""
    return np.array([-1.0])


def _compensate(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """A failsafe policy for the box: gravity compensated (the motor's torque is its control)."""
    return np.array(data.qfrc_bias[:1])


@pytest.mark.parametrize("failsafe", [None, _pull_up])
def test_a_robot_its_failsafe_cannot_hold_is_never_guaranteed(failsafe: Any) -> None:
    """The box starts at rest, but the motor cannot hold it there: at rest is no rest knot
    unless the failsafe holds the robot (Shield::Holds: at the pose with the velocities 0, the
    brake's controls and the constraint forces leave it an acceleration of rounding size), so
    no failsafe rolled out has one before the post (the box swings past it in the rollouts,
    where the protected post collides with nothing) and the shield never claims a guarantee:
    the contact at about 1.7 m/s is an unguaranteed one. Without the check, the state read is
    the failsafe's rest knot 0 and the first step is guaranteed: the box falls, a hold break
    drops the guarantee a step later, and no hypothesis (S1)-(S4) breaks (theory.md section
    10's (S5) is the one). A failsafe policy is asked the same (its controls at the pose with
    the velocities 0)."""
    model, data, shield = _sagging(1.0, failsafe=failsafe, stop_time=0.3)
    post = model.body("post").id
    guaranteed = []
    for _ in range(200):
        data.ctrl[:] = shield(data, [0.0])
        guaranteed.append(shield.guaranteed)
        mujoco.mj_step(model, data)
        if (model.geom_bodyid[np.asarray(data.contact.geom)[: data.ncon]] == post).any():
            break  # the first protected contact
    counts = shield.counts
    assert data.ncon > 0, counts  # the box reaches the post, moving
    assert not any(guaranteed), counts
    assert counts["unheld"] > 0 and counts["hold_breaks"] == 0, counts


def test_a_rollout_goes_on_past_a_knot_its_failsafe_cannot_hold() -> None:
    """The box far from the post: the failsafe rolled out from its start at rest passes knots at
    rest it cannot hold (the start, each apex of its swing) and goes on from each as the run
    does (Shield::Holds puts the knot's state and mj_step1's values back), so the run that
    follows that failsafe keeps to it knot for knot (no plan break) until the brake has it at
    rest hanging down, held: from there the steps are guaranteed."""
    model, data, shield = _sagging(1.0, post=2.0)
    guaranteed = []
    for _ in range(150):
        data.ctrl[:] = shield(data, [0.0])
        guaranteed.append(shield.guaranteed)
        mujoco.mj_step(model, data)
    counts = shield.counts
    assert counts["unheld"] > 0, counts
    assert (counts["plan_breaks"], counts["hold_breaks"]) == (0, 0), counts
    assert not guaranteed[0] and guaranteed[-1], counts


@pytest.mark.parametrize("failsafe", [None, _compensate])
def test_a_robot_its_failsafe_holds_at_rest_is_guaranteed_there(failsafe: Any) -> None:
    """The box on a 5 N m motor: held at rest (gravity's 2.9 N m within its limits, by the brake
    or by a policy compensating gravity), its knots at rest are rest knots and every step is
    guaranteed (the brake's candidates pass; the policy, which does not damp, refuses them and
    holds the box at the state read, its rest knot 0)."""
    model, data, shield = _sagging(5.0, failsafe=failsafe)
    for _ in range(20):
        data.ctrl[:] = shield(data, [0.0])
        assert shield.guaranteed, shield.counts
        mujoco.mj_step(model, data)
    counts = shield.counts
    assert (counts["unheld"], counts["hold_breaks"]) == (0, 0), counts


@pytest.mark.parametrize("ratio", [0.999, 1.001])
def test_a_failsafe_holds_a_knot_only_while_its_pull_stays_under_rest_speed_over_stop_time(
    ratio: float,
) -> None:
    """Shield::Holds's tolerance: a knot at rest is held when the failsafe leaves every point of
    the robot an acceleration a with a * stop_time <= rest_speed (it would take at least
    stop_time to leave rest). The ball at rest far from the wall, a failsafe policy pushing it
    with a constant force (1 kg, no gravity along the slide: a = the force): just under that
    acceleration, the candidate's first knot at rest is its rest knot and the step is
    guaranteed; just over, no knot at rest is held (the check counts them unheld) and no step
    is guaranteed. A tolerance twice as wide would hold the second."""
    model = mujoco.MjModel.from_xml_string(_BALL)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rest_speed, stop_time = 0.01, 0.5
    force = ratio * rest_speed / stop_time

    def push(m: mujoco.MjModel, d: mujoco.MjData) -> np.ndarray:
        return np.array([force])

    shield = Shield(
        model, protect=["wall"], robot=["ball"], period=1, accel=5.0, screen=False,
        rest_speed=rest_speed, stop_time=stop_time, failsafe=push,
    )  # fmt: skip
    shield.reset(data)
    shield(data, [0.0])
    counts = shield.counts
    held = ratio < 1.0
    assert (counts["unheld"] == 0, shield.guaranteed) == (held, held), counts
    assert (counts["accepted"], counts["rejected"]) == (int(held), int(not held)), counts
