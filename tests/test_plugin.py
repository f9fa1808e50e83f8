"""The MuJoCo plugin ``dua_mujoco.predictor``: the predictor inside ``mj_step``, per-``MjData``
state, exported models, C++ without Python.

The plugin and ``Predictor.step`` run one runtime (docs/theory.md, section 7), so the tests that
compare them step by step (``test_plugin_round_trips_...``) are round-trip tests: they check
that the tables survive the model's text fields, that the plugin reads the instant and keeps the
state the proofs assume, and that it switches, prunes and classifies as the Python caller does;
they cannot catch a bug of the step itself, which both would share. The step is held to
independent references elsewhere (tests/test_reference_step.py and the tests of section 4)."""

from __future__ import annotations

import base64
import gc
import subprocess
import sys
import time
from pathlib import Path

import gymnasium
import mujoco
import numpy as np
import pytest
from mujoco import rollout
from rollouts import periodic_rollout, python_standing

from dua_mujoco.build.options import ScheduleOptions, UrgencyOptions
from dua_mujoco.exceptions import InvalidChoiceError, InvalidInputError
from dua_mujoco.models.scenes import load_spec, make_controller
from dua_mujoco.plugin import (
    attach,
    deactivate_contacts,
    plugin_outputs,
    set_active_bodies,
    standing_pairs,
)
from dua_mujoco.runtime.predictor import Predictor

ANT = str(Path(gymnasium.__file__).parent / "envs/mujoco/assets/ant.xml")


def _attached(scene: str, **options: object) -> tuple[mujoco.MjModel, Predictor]:
    spec = load_spec(scene)
    if spec.option.integrator == mujoco.mjtIntegrator.mjINT_RK4:
        # After an RK4 mj_step, MjData holds its last stage's kinematics, which Predictor.step
        # reads; the plugin reads the state the step starts from (docs/plugin.md). Both are
        # valid instants but not the same one: compare them on Euler.
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_EULER
    p = attach(spec, **{"accel": 30.0, **options})
    return spec.compile(), p


def _run_side_by_side(
    m: mujoco.MjModel,
    p: Predictor,
    steps: int,
    seed: int = 0,
    switch: dict[int, tuple[int, int | None, bool]] | None = None,
    resting: int | None = None,
) -> int:
    """Step the plugin's model and the Python predictor on it together; assert equal standing
    pairs after every predictor step (after ``switch[k] = (body_a, body_b, on)`` at step ``k``,
    in both; at step ``resting``, the pairs in contact switched off in both). Returns the steps
    with some pair standing."""
    d = mujoco.MjData(m)
    ctrl = make_controller(m, "random", seed=seed)
    busy = 0
    for k in periodic_rollout(m, d, p, ctrl, steps):
        if switch and k in switch:
            a, b, on = switch[k]
            assert set_active_bodies(m, d, a, b, on=on) == p.set_active_bodies(a, b, on=on) > 0
        if k == resting:
            assert deactivate_contacts(m, d) == p.deactivate_contacts(d) > 0
        want = python_standing(p)
        np.testing.assert_array_equal(standing_pairs(m, d), want, err_msg=f"step {k}")
        out = plugin_outputs(m, d)
        assert out.standing == want.shape[0]
        # The same pairs held and due: as many evaluations (a classification evaluates all).
        assert out.evaluated == p.evaluations_per_step, f"step {k}"
        busy += want.shape[0] > 0
    return busy


@pytest.mark.parametrize(
    ("scene", "steps"),
    [("two_arms", 300), ("traffic", 1500), ("clutter", 300), ("paper_world", 300),
     ("bin_pour:30", 300), ("rough_terrain", 300), (ANT, 300)],
    ids=["two_arms", "traffic", "clutter", "paper_world", "bin_pour", "rough_terrain", "gym-ant"],
)  # fmt: skip
def test_plugin_round_trips_the_predictor_on_every_scene(scene: str, steps: int) -> None:
    """A round trip (module docstring): on every bundled scene (clutter's mocap body included)
    and a robot, the pairs standing in alarm after each mj_step are the Python predictor's after
    its step on the same state."""
    m, p = _attached(scene)
    assert _run_side_by_side(m, p, steps) > 10  # the comparison is not of empty steps


@pytest.mark.parametrize(
    "options",
    [
        {"period": 3},
        {"schedule": ScheduleOptions(kind="select-all")},
        {"schedule": ScheduleOptions(kind="dua", slots_per_bucket=2)},
        {"urgency": UrgencyOptions(exact=False)},
        {"schedule": ScheduleOptions(max_evals_per_step=4, alarm_backoff=1)},
        {"latency": 1},
        # (Pruned and capped differ: the plugin knows every pair from the start, in another
        # order than the pairs the Python predictor learns, so a cap defers other pairs.)
        {"pairs": "pruned", "period": 3},
    ],
    ids=["period", "select-all", "dua", "no-exact", "capped", "latency", "pruned-period"],
)  # fmt: skip
def test_plugin_round_trips_the_predictor_under_options(options: dict) -> None:
    """A round trip (module docstring) under each option the tables carry."""
    m, p = _attached("two_arms", **options)
    assert _run_side_by_side(m, p, 240, seed=3) > 10


@pytest.mark.parametrize(
    ("scene", "accel", "steps"),
    [("bin_pour:60", 5.0, 300), ("clutter", 30.0, 300), ("swarm:300", 2.0, 200),
     ("swarm:1500", 2.0, 120)],
    ids=["bin_pour", "clutter", "swarm", "swarm-1.1M-pairs"],
)  # fmt: skip
def test_plugin_round_trips_the_pruned_predictor(scene: str, accel: float, steps: int) -> None:
    """A round trip (module docstring) with ``pairs="pruned"``: the plugin holds the pairs a
    pruned ``Predictor`` holds, rebuilt every stride and renewed for the spheres an impact lets
    escape, learning the pairs it meets
    (objects poured into a bin, a mocap body, swarms: one of 1.1 million active pairs, more
    than ``pairs="all"`` takes): the same standing pairs and evaluations after every step."""
    m, p = _attached(scene, accel=accel, pairs="pruned")
    assert p.stride > 0
    # The model carries the pairs held always, not every active pair.
    adr = m.text_adr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TEXT, "dua:pairs")]
    assert m.text_data[adr:].split(b" ", 1)[0] == str(8 * p.universe.npair).encode()
    busy = _run_side_by_side(m, p, steps)
    assert p.rebuilds >= steps // p.stride - 1
    if not scene.startswith("swarm"):
        assert busy > 10 and p.renewals > 5


def test_plugin_round_trips_pruned_switches_and_classifications() -> None:
    """A round trip (module docstring) of pruned pairs with intended contact and latency: pairs
    switched off stay off when a rebuild or a renewal holds them again; a reset classifies from
    scratch."""
    from dua_mujoco.build.options import PairOptions

    m, p = _attached("two_arms", pairs=PairOptions(mode="pruned", horizon=0.02), latency=1)
    box = int(m.geom_bodyid[m.geom("loose_box").id])
    table = int(m.geom_bodyid[m.geom("table_top").id])
    link = int(m.geom_bodyid[m.geom("a_link1").id])
    switch: dict[int, tuple[int, int | None, bool]] = {
        20: (box, table, False), 90: (box, table, True), 120: (link, None, False),
    }  # fmt: skip
    assert _run_side_by_side(m, p, 200, seed=5, switch=switch, resting=150) > 10
    assert p.rebuilds > 10  # the switched-off pairs went through rebuilds


def test_plugin_round_trips_switched_bodies() -> None:
    """A round trip (module docstring) of intended contact: the pairs between a loose box and
    the table switched off, back on (standing in alarm until evaluated), every pair of an arm's
    link, then every pair in contact: the same standing pairs as the Python predictor's after
    every step."""
    m, p = _attached("two_arms")
    box = int(m.geom_bodyid[m.geom("loose_box").id])
    table = int(m.geom_bodyid[m.geom("table_top").id])
    link = int(m.geom_bodyid[m.geom("a_link1").id])
    switch: dict[int, tuple[int, int | None, bool]] = {
        50: (box, table, False), 120: (box, table, True), 150: (link, None, False),
        200: (link, None, True),
    }  # fmt: skip
    assert _run_side_by_side(m, p, 260, seed=5, switch=switch, resting=230) > 10
    d = mujoco.MjData(m)
    with pytest.raises(InvalidInputError, match="mj_step"):
        set_active_bodies(m, d, box, table, on=False)


def _standing_sequence(m: mujoco.MjModel, d: mujoco.MjData, ctrl: np.ndarray) -> list[tuple]:
    """After each step: the standing pairs and the sensor's outputs (the least tau among them,
    which any stale state read for a pair would change)."""
    out = []
    for u in ctrl:
        d.ctrl[:] = u
        mujoco.mj_step(m, d)
        out.append((standing_pairs(m, d).tolist(), plugin_outputs(m, d)))
    return out


SUBTREE_XML = """
<mujoco>
  <worldbody>
    <geom type="plane" size="2 2 0.1"/>
    <body name="arm" pos="0 0 0.5">
      <joint name="shoulder" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.05"/>
      <body pos="0.4 0 0">
        <joint type="hinge" axis="0 1 0"/>
        <geom type="box" size="0.1 0.05 0.05" pos="0.1 0 0"/>
      </body>
    </body>
    <body name="ball" pos="0.3 0.02 1.2">
      <freejoint/>
      <geom type="sphere" size="0.08"/>
    </body>
  </worldbody>
  <actuator><motor joint="shoulder" gear="5"/></actuator>
  {sensors}
</mujoco>
"""


@pytest.mark.parametrize("subtree_sensors", [True, False])
def test_the_plugin_leaves_the_physics_and_the_subtree_velocities_as_they_were(
    subtree_sensors: bool,
) -> None:
    """The plugin's passive call applies no force, and marks the subtree velocities computed
    (sparing the mj_subtreeVel MuJoCo would run for it) only when nothing in the model reads
    them: subtree sensors read what they read without the plugin, and the flag is cleared
    again after the sensors."""
    sensors = (
        "<sensor><subtreelinvel body='arm'/><subtreeangmom body='ball'/></sensor>"
        if subtree_sensors
        else ""
    )
    xml = SUBTREE_XML.format(sensors=sensors)
    plain = mujoco.MjModel.from_xml_string(xml)
    spec = mujoco.MjSpec.from_string(xml)
    attach(spec, accel=30.0)
    with_plugin = spec.compile()
    d0, d1 = mujoco.MjData(plain), mujoco.MjData(with_plugin)
    for k in range(300):
        d0.ctrl[:] = d1.ctrl[:] = np.sin(0.05 * k)
        mujoco.mj_step(plain, d0)
        mujoco.mj_step(with_plugin, d1)
        np.testing.assert_array_equal(d1.qpos, d0.qpos, err_msg=f"step {k}")
        np.testing.assert_array_equal(d1.qvel, d0.qvel, err_msg=f"step {k}")
        np.testing.assert_array_equal(d1.sensordata[: plain.nsensordata], d0.sensordata)
    # Spared only where nothing reads them (MuJoCo computes them for the sensors otherwise),
    # and the flag says after the step what it says without the plugin: computed or not.
    assert d1.flg_subtreevel == d0.flg_subtreevel == int(subtree_sensors)
    if not subtree_sensors:
        assert not d1.subtree_linvel.any()  # never computed, as without the plugin


def _copied_halfway(
    m: mujoco.MjModel, seed: int, steps: int
) -> tuple[list[tuple], mujoco.MjData, mujoco.MjData, np.ndarray, np.ndarray]:
    """One run of `steps` random controls (the reference), and another stopped halfway and
    copied: (the reference's standing pairs, the original, its copy, the controls, half as many
    other controls)."""
    rng = np.random.default_rng(seed)
    ctrl = rng.uniform(-1, 1, (steps, m.nu))
    other = rng.uniform(-1, 1, (steps // 2, m.nu))
    reference = _standing_sequence(m, mujoco.MjData(m), ctrl)
    d = mujoco.MjData(m)
    _standing_sequence(m, d, ctrl[: steps // 2])
    copy = mujoco.MjData(m)
    mujoco.mj_copyData(copy, m, d)
    return reference, d, copy, ctrl, other


def test_copies_and_resets_keep_their_own_state() -> None:
    """``mj_copyData`` carries the plugin's state into the copy, and the two then run apart;
    ``mj_resetData`` starts the predictor over, as a fresh ``MjData`` does."""
    m, _ = _attached("two_arms")
    reference, d, copy, ctrl, other = _copied_halfway(m, 0, 400)
    np.testing.assert_array_equal(standing_pairs(m, copy), standing_pairs(m, d))
    # The copy goes its own way; the original must not notice.
    _standing_sequence(m, copy, other)
    assert _standing_sequence(m, d, ctrl[200:]) == reference[200:]
    mujoco.mj_resetData(m, d)
    assert standing_pairs(m, d).shape == (0, 2)  # nothing until the first compute
    assert _standing_sequence(m, d, ctrl) == reference


@pytest.mark.parametrize("pairs", ["all", "pruned"])
def test_a_copy_steps_on_its_own_buffers_once_the_original_is_gone(pairs: str) -> None:
    """The step's arguments point at the runtime's buffers and are kept between steps (Bind
    rewrites only what can change): a copy must point at its own. The original is destroyed
    and another run allocates over its buffers while the copy goes on; the copy's standing
    pairs are those of one run that never copied."""
    m, _ = _attached("two_arms", pairs=pairs)
    reference, d, copy, ctrl, other = _copied_halfway(m, 2, 300)
    del d
    gc.collect()
    _standing_sequence(m, mujoco.MjData(m), other)  # new buffers, maybe where d's were
    assert _standing_sequence(m, copy, ctrl[150:]) == reference[150:]


def test_a_jump_of_the_clock_classifies_from_the_state_alone() -> None:
    """After a jump of the clock the plugin evaluates every pair again from the current state,
    as a fresh ``MjData`` at that state does: nothing read at an earlier step (the sphere
    states a batch keeps, the schedule) may leak into it. The exact level is off: the
    directions it keeps per pair carry over on purpose (they change which lower bound it
    finds, never whether it is one: docs/theory.md, section 5)."""
    m, _ = _attached("two_arms", urgency=UrgencyOptions(exact=False))
    rng = np.random.default_rng(1)
    ctrl = rng.uniform(-1, 1, (300, m.nu))
    d = mujoco.MjData(m)
    _standing_sequence(m, d, ctrl[:150])
    fresh = mujoco.MjData(m)
    spec = int(mujoco.mjtState.mjSTATE_INTEGRATION)
    state = np.empty(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, d, state, spec)
    mujoco.mj_setState(m, fresh, state, spec)
    d.time += 1.0  # the jump: the plugin's next compute classifies
    fresh.time = d.time
    assert _standing_sequence(m, d, ctrl[150:]) == _standing_sequence(m, fresh, ctrl[150:])


@pytest.mark.parametrize("pairs", ["all", "pruned"])
def test_rollout_on_two_threads_gives_one_threads_alarms(pairs: str) -> None:
    m, _ = _attached("two_arms", pairs=pairs)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.zeros(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, d, state, spec)
    rng = np.random.default_rng(1)
    initial = np.repeat(state[None], 6, axis=0)
    ctrl = rng.uniform(-1, 1, (6, 250, m.nu))
    _, one = rollout.rollout(m, [mujoco.MjData(m)], initial, ctrl)
    _, two = rollout.rollout(m, [mujoco.MjData(m), mujoco.MjData(m)], initial, ctrl)
    np.testing.assert_array_equal(one, two)
    # Alarms stand, and the six controls gave six runs (the evaluations and tau differ).
    assert one[:, :, 0].max() > 0 and len({one[i].tobytes() for i in range(6)}) == 6


@pytest.mark.parametrize("suffix", [".xml", ".mjb"])
def test_exported_model_runs_the_plugin_after_a_round_trip(tmp_path: Path, suffix: str) -> None:
    """``dua-mujoco export`` writes what ``MjModel.from_xml_path`` (or the binary loader) reads
    back into the predictor a Python ``Predictor`` of the same options builds for the model read
    back: the tables were computed for the geometry the file holds, and survive exactly."""
    from dua_mujoco.cli import main

    out = tmp_path / f"clutter{suffix}"
    assert main(["export", "clutter", str(out), "--accel", "30"]) == 0
    loaded = (
        mujoco.MjModel.from_xml_path(str(out))
        if suffix == ".xml"
        else mujoco.MjModel.from_binary_path(str(out))
    )
    assert _run_side_by_side(loaded, Predictor(loaded, accel=30.0, pairs="all"), 300) > 10


def test_the_overlay_draws_the_standing_pairs_into_any_scene() -> None:
    """``visualize`` adds to an ``mjvScene`` (``mujoco.Renderer``'s, the viewer's and
    simulate's alike) a ball on every moving geom of a standing pair and a line for every
    standing pair of two moving geoms; ``overlay=false`` adds nothing."""
    added = []
    for overlay in (True, False):
        spec = load_spec("two_arms")
        attach(spec, accel=30.0, overlay=overlay)
        m = spec.compile()
        d = mujoco.MjData(m)
        for _ in range(50):
            mujoco.mj_step(m, d)
        scene = mujoco.MjvScene(m, maxgeom=1000)
        mujoco.mjv_updateScene(
            m, d, mujoco.MjvOption(), None, mujoco.MjvCamera(), mujoco.mjtCatBit.mjCAT_ALL, scene
        )
        decor = [g for g in scene.geoms[: scene.ngeom] if g.objid == -1 and g.rgba[0] > 0.9]
        balls = sum(int(g.type) == int(mujoco.mjtGeom.mjGEOM_SPHERE) for g in decor)
        added.append((balls, len(decor) - balls))
        pairs = standing_pairs(m, d)
    moving = np.asarray(m.body_weldid)[np.asarray(m.geom_bodyid)] != 0
    both = moving[pairs[:, 0]] & moving[pairs[:, 1]]
    hot = np.unique(pairs[moving[pairs].reshape(pairs.shape)])
    (balls, lines), hidden = added
    assert len(pairs) > 0 and balls == hot.size > 0 and lines == int(both.sum())
    assert hidden == (0, 0)


def test_attach_refuses_what_the_plugin_cannot_run() -> None:
    spec = load_spec("two_arms")
    with pytest.raises(InvalidInputError, match="MjSpec"):
        attach(mujoco.MjModel.from_xml_string("<mujoco/>"))  # type: ignore[arg-type]
    with pytest.raises(InvalidChoiceError, match="pairs"):
        attach(spec, accel=30.0, pairs="some")
    with pytest.raises(InvalidInputError, match="schedule='deadline'"):
        attach(spec, accel=30.0, pairs="pruned", schedule="dua")
    with pytest.raises(InvalidInputError, match="prefix"):
        attach(spec, prefix="a b", accel=30.0)
    with pytest.raises(InvalidInputError, match="pairs='pruned'"):  # 4.5 million pairs
        attach(load_spec("swarm:3000"), accel=2.0, pairs="all")
    attach(spec, accel=30.0)
    with pytest.raises(InvalidInputError, match="already holds a predictor under prefix 'dua'"):
        attach(spec, accel=30.0)
    attach(spec, prefix="second", accel=30.0)  # two instances side by side
    m = spec.compile()
    d = mujoco.MjData(m)
    for _ in range(20):
        mujoco.mj_step(m, d)
    np.testing.assert_array_equal(standing_pairs(m, d), standing_pairs(m, d, prefix="second"))
    with pytest.raises(InvalidInputError, match="no predictor sensor 'nope'"):
        standing_pairs(m, d, prefix="nope")


def test_a_model_with_broken_tables_names_what_is_wrong() -> None:
    """The plugin's errors reach Python through MuJoCo's: a missing table and an attribute that
    does not parse are named."""
    spec = load_spec("traffic")
    attach(spec, accel=4.0)
    spec.delete(next(t for t in spec.texts if t.name == "dua:pairs"))
    with pytest.raises(Exception, match="dua:pairs"):
        mujoco.MjData(spec.compile())
    spec = load_spec("traffic")
    attach(spec, accel=4.0)
    spec.plugins[0].config = {"prefix": "dua", "overlay": "maybe"}
    with pytest.raises(Exception, match="'overlay' = 'maybe'"):
        mujoco.MjData(spec.compile())
    # A spec edited after attach: the tables would index the wrong geoms.
    spec = load_spec("traffic")
    attach(spec, accel=4.0)
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.1, 0, 0], pos=[0, 0, 5])
    with pytest.raises(Exception, match="attach last"):
        mujoco.MjData(spec.compile())
    # Pruned pairs: a reach that is not a number (a hand-edited table) is refused, named.
    from dua_mujoco.plugin import _encode

    spec = load_spec("traffic")
    attach(spec, accel=4.0, pairs="pruned")
    text = next(t for t in spec.texts if t.name == "dua:reach")
    reach = np.frombuffer(base64.b64decode(text.data.split(" ", 1)[1]), dtype="<f8").copy()
    reach[1] = np.nan
    text.data = _encode(reach)
    with pytest.raises(Exception, match="the reach table's values"):
        mujoco.MjData(spec.compile())


def test_tables_parsed_once_are_never_served_to_an_edited_model(
    capfd: pytest.CaptureFixture,
) -> None:
    """The plugin keeps a model's tables after its last MjData goes (parsed once per model); a
    model edited in place since then is read afresh, and refused for what the edit broke."""
    spec = load_spec("clutter")
    attach(spec, accel=4.0)
    m = spec.compile()
    standing = []
    for _ in range(2):  # the second MjData reads the tables the first one parsed
        d = mujoco.MjData(m)
        for _ in range(50):
            mujoco.mj_step(m, d)
        standing.append(standing_pairs(m, d))
        del d
    np.testing.assert_array_equal(standing[0], standing[1])
    capfd.readouterr()
    m.opt.timestep *= 2
    with pytest.raises(Exception, match="init failed"):
        mujoco.MjData(m)
    assert "timestep" in capfd.readouterr().err
    m.opt.timestep /= 2
    # Another body for a geom: the same tables would index the wrong bodies.
    body = int(m.geom_bodyid[m.ngeom - 1])
    m.geom_bodyid[m.ngeom - 1] = 0 if body else 1
    with pytest.raises(Exception, match="init failed"):
        mujoco.MjData(m)
    assert "dua:" in capfd.readouterr().err
    m.geom_bodyid[m.ngeom - 1] = body
    mujoco.MjData(m)
    assert "dua_mujoco" not in capfd.readouterr().err


_PASSIVE = """
import time
import mujoco, mujoco.viewer
import numpy as np
import dua_mujoco
spec = mujoco.MjSpec.from_string({xml!r})
dua_mujoco.attach(spec, accel=5e4, overlay={overlay})
m = spec.compile()
d = mujoco.MjData(m)
rng = np.random.default_rng(0)
with mujoco.viewer.launch_passive(m, d, show_left_ui=False, show_right_ui=False) as viewer:
    start = time.monotonic()
    while viewer.is_running() and time.monotonic() - start < 120:
        d.ctrl[:] = rng.uniform(-1, 1, m.nu)
        mujoco.mj_step(m, d)
        viewer.sync()
        time.sleep(0.005)
"""


def test_mujocos_own_viewer_shows_the_overlay(tmp_path: Path, xvfb) -> None:
    """MuJoCo's passive viewer draws the plugin's overlay with no code of ours in its loop: two
    grey boxes standing in alarm get translucent red balls and a red line (red pixels, bright
    over the boxes, dim over the black background); with ``overlay=false`` the boxes stay grey
    (measured: 2,900 bright and 780 dim red pixels against none)."""
    from screens import reddish
    from test_view import BOXES

    halos = []
    for overlay in (True, False):
        screen = tmp_path / f"screen{overlay}"
        screen.mkdir()
        with xvfb(screen) as display:
            env = display.env()
            env.pop("MUJOCO_GL", None)  # the viewer opens a GLFW window
            code = _PASSIVE.format(xml=BOXES, overlay=overlay)
            proc = subprocess.Popen(
                [sys.executable, "-c", code], env=env, stderr=subprocess.PIPE, text=True
            )
            try:
                # The boxes on screen, drawn for a second.
                display.wait_for(lambda shot: np.count_nonzero(shot.max(axis=-1) > 30) > 1000)
                time.sleep(1.0)
                shot = display.screenshot()
                halos.append(reddish(shot) + reddish(shot, dim=True))
            finally:
                proc.kill()
                proc.wait(timeout=60)
    shown, hidden = halos
    assert shown > 1000 and hidden < shown / 20, halos


def test_export_refuses_an_unknown_format(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    from dua_mujoco.cli import main

    assert main(["export", "traffic", str(tmp_path / "out.txt"), "--accel", "4"]) == 2
    err = capsys.readouterr().err
    assert "'.txt'" in err and ".xml or .mjb" in err
    assert not (tmp_path / "out.txt").exists()
