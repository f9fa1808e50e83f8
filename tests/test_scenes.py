"""Bundled scenes, the paper world as an MjSpec, and the scene drivers."""

from __future__ import annotations

import io
import itertools
import math
import re
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
import pytest

from dua_mujoco.build.geom_types import CONVEX_TYPES, GEOM_PLANE
from dua_mujoco.exceptions import InvalidChoiceError, InvalidInputError
from dua_mujoco.models.paper_world import _place_spheres, _quat_z_to, _SphereBlocks
from dua_mujoco.models.scenes import (
    DEFAULT_SCENE,
    SCENES,
    CtrlMode,
    MocapCircle,
    SceneController,
    declared_accel_bound,
    load_scene,
    make_controller,
    models_dir,
    paper_world_accel_bound,
    paper_world_model,
    paper_world_spec,
    reset_to_keyframe,
)
from dua_mujoco.progress import Progress

ROLLOUT_SCENES = ("two_arms", "traffic", "clutter", "paper_world:20")


def _contact_pairs(m: mujoco.MjModel, d: mujoco.MjData) -> set[tuple[int, int]]:
    """Weld-group pairs in contact where the two sides differ and one of them moves.

    Weld groups (``body_weldid``) rather than bodies, so that a link touching its own base or a
    geom touching another geom of the same rigid assembly does not count; group 0 is the world
    (tables, walls, floors, static obstacles).
    """
    pairs = set()
    for k in range(d.ncon):
        g1, g2 = (int(g) for g in d.contact.geom[k])
        w1 = int(m.body_weldid[m.geom_bodyid[g1]])
        w2 = int(m.body_weldid[m.geom_bodyid[g2]])
        if w1 != w2:
            pairs.add((min(w1, w2), max(w1, w2)))
    return pairs


@pytest.mark.parametrize("name", [*SCENES, "paper_world:5", "bin_pour:7"])
def test_every_bundled_scene_loads(name: str) -> None:
    m, d = load_scene(name)
    assert m.ngeom > 0 and (m.nu > 0 or name.startswith("bin_pour"))  # the pour: gravity only
    assert np.all(np.isfinite(d.qpos))
    limited = m.actuator_ctrllimited.astype(bool)
    assert limited.all(), "random controls need a ctrlrange on every actuator"
    source = SCENES[name].source if name in SCENES else None
    if isinstance(source, str):
        path = models_dir() / source
        assert path.is_file()
        # Self-contained: loads from the raw path too, with no external assets.
        mujoco.MjModel.from_xml_path(str(path))
        assert "file=" not in path.read_text()


def test_default_scene_is_registered() -> None:
    assert DEFAULT_SCENE == "two_arms"
    assert DEFAULT_SCENE in SCENES


def test_scene_sizes() -> None:
    assert load_scene("two_arms")[0].ngeom >= 30
    m = load_scene("traffic")[0]
    assert 8 <= m.nu <= 16
    assert load_scene("clutter")[0].ngeom >= 50
    assert load_scene("clutter")[0].nmocap == 1
    assert load_scene("paper_world")[0].nbody == 41


@pytest.mark.parametrize("name", ROLLOUT_SCENES)
def test_random_rollout_is_finite_and_collides(name: str) -> None:
    m, d = load_scene(name)
    resting = _contact_pairs(m, d)
    controller = make_controller(m, CtrlMode.RANDOM, seed=0)
    new_pairs: set[tuple[int, int]] = set()
    for _ in range(500):
        controller(m, d)
        mujoco.mj_step(m, d)
        new_pairs |= _contact_pairs(m, d) - resting
    assert np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))
    assert new_pairs, f"{name}: no new contact between distinct bodies in 500 random steps"
    if name in ("traffic", "clutter"):
        # Vehicle-vehicle / object-object, not only against the static world.
        assert any(w1 != 0 for w1, _ in new_pairs)


def test_clutter_has_every_collidable_geom_type() -> None:
    m, _ = load_scene("clutter")
    types = {int(t) for t in m.geom_type}
    assert {GEOM_PLANE, *CONVEX_TYPES} <= types
    free = sum(int(t) == int(mujoco.mjtJoint.mjJNT_FREE) for t in m.jnt_type)
    assert free >= 40


def test_bin_pour_pours_its_objects_into_the_bin_and_they_stay_there() -> None:
    m, d = load_scene("bin_pour:60")
    free = [j for j in range(m.njnt) if int(m.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_FREE)]
    assert len(free) == 60 and m.nu == 0
    walls = [g for g in range(m.ngeom) if (m.geom(g).name or "").startswith("wall")]
    inner = min(
        abs(float(m.geom_pos[g][a])) - float(m.geom_size[g][a])
        for g in walls
        for a in (0, 1)
        if abs(float(m.geom_pos[g][a])) > 0
    )
    top = 2 * float(m.geom_size[walls[0]][2])
    heights = d.xpos[1:, 2].copy()
    assert heights.min() > top  # the hopper is above the bin's walls
    for _ in range(1000):  # 2 s: the pile settles
        mujoco.mj_step(m, d)
    xy, z = d.xpos[1:, :2], d.xpos[1:, 2]
    assert np.all(np.abs(xy) < inner) and np.all(z < top) and np.all(z > 0)
    assert np.all(np.isfinite(d.qvel)) and np.median(np.abs(d.qvel)) < 0.05  # settled (some roll)
    assert load_scene("bin_pour")[0].nbody == 301
    with pytest.raises(InvalidInputError, match="bin_pour:0"):
        load_scene("bin_pour:0")


def test_unknown_scene_lists_the_names() -> None:
    with pytest.raises(InvalidChoiceError) as info:
        load_scene("no_such_scene")
    message = str(info.value)
    for name in SCENES:
        assert repr(name) in message
    assert "paper_world:N" in message
    # A path names no scene: the missing file is the news, not the list of scenes.
    with pytest.raises(InvalidInputError, match=r"^No file at .*missing/scene\.xml'") as info:
        load_scene("missing/scene.xml")
    assert not isinstance(info.value, InvalidChoiceError)
    with pytest.raises(InvalidInputError):
        load_scene("paper_world:zero")


def test_load_scene_accepts_a_path(tmp_path: Path) -> None:
    xml = tmp_path / "ball.xml"
    xml.write_text(
        '<mujoco><worldbody><body><freejoint/><geom size="0.1"/></body></worldbody></mujoco>'
    )
    m, d = load_scene(str(xml))
    assert m.ngeom == 1 and d.qpos.shape == (7,)


def test_reset_to_keyframe() -> None:
    m, d = load_scene("traffic")
    assert np.allclose(d.qvel, m.key_qvel[0])  # first keyframe by default
    d.qvel[:] = 0.0
    reset_to_keyframe(m, d, "rush")
    assert np.allclose(d.qvel, m.key_qvel[0])
    with pytest.raises(InvalidChoiceError, match="rush"):
        reset_to_keyframe(m, d, "nope")
    with pytest.raises(InvalidChoiceError):
        reset_to_keyframe(m, d, 3)
    mc, dc = load_scene("clutter")  # no keyframe: model defaults
    assert mc.nkey == 0 and np.allclose(dc.qpos, mc.qpos0)


def test_paper_world_has_no_initial_overlap() -> None:
    radius, box = 0.05, 0.6
    spec = paper_world_spec(60, seed=3, radius=radius, box_size=box)
    m = spec.compile()
    d = mujoco.MjData(m)
    reset_to_keyframe(m, d, None)
    centres = np.array([d.xpos[m.body(f"sphere{i}").id] for i in range(60)])
    for i, j in itertools.combinations(range(60), 2):
        assert np.linalg.norm(centres[i] - centres[j]) >= 2 * radius
    assert np.all(np.abs(centres) <= box / 2 - radius)
    assert d.ncon == 0
    assert int(m.opt.integrator) == int(mujoco.mjtIntegrator.mjINT_EULER)
    assert m.opt.timestep == pytest.approx(0.002)
    assert np.allclose(m.opt.gravity, 0.0)
    speeds = np.linalg.norm(d.qvel.reshape(-1, 3), axis=1)
    assert np.all(speeds <= 0.5 + 1e-12) and np.any(speeds > 0.0)
    with pytest.raises(InvalidInputError, match="Could not place"):
        paper_world_spec(500, radius=0.1, box_size=0.5)


def _reference_placement(
    n: int, rng: np.random.Generator, half: float, radius: float, clearance: float
) -> np.ndarray:
    """Slow reference for ``_place_spheres``: candidates drawn 64 at a time, each measured
    against every centre accepted before it, one at a time."""
    lo, hi = -half + radius + clearance, half - radius - clearance
    min_dist = 2.0 * radius + clearance
    placed: list[tuple[float, float, float]] = []
    misses = 0
    while len(placed) < n:
        for x, y, z in rng.uniform(lo, hi, size=(64, 3)).tolist():
            if any(
                math.sqrt((px - x) * (px - x) + (py - y) * (py - y) + (pz - z) * (pz - z))
                < min_dist
                for px, py, pz in placed
            ):
                misses += 1
                if misses > 20_000:
                    raise InvalidInputError(f"Could not place (placed {len(placed)})")
                continue
            placed.append((x, y, z))
            misses = 0
            if len(placed) == n:
                break
    return np.array(placed)


@pytest.mark.parametrize(
    ("n", "seed", "half", "radius"),
    [
        (1, 0, 0.5, 0.03),
        (700, 2, 1.1, 0.03),
        (400, 1, 0.5, 0.04),
        (1500, 3, 0.5, 0.02),
        (200, 1, 0.3, 0.05),
        (60, 1, 0.25, 0.05),
    ],
)
def test_placement_judged_by_chunks_is_the_sequential_samplers(
    n: int, seed: int, half: float, radius: float
) -> None:
    """The same centres, the same generator state after them, and the same refusal (with the
    count placed) when the cube is too crowded (the last two), as one candidate at a time."""
    outcomes = []
    for place in (_place_spheres, _reference_placement):
        rng = np.random.default_rng(seed)
        try:
            centres = place(n, rng, half=half, radius=radius, clearance=radius / 4)
            outcomes.append((centres.tobytes(), rng.random()))
        except InvalidInputError as e:
            outcomes.append(tuple(re.findall(r"placed \d+", str(e))))
    assert outcomes[0] == outcomes[1]


def test_paper_world_built_in_chunks_is_laid_out_sphere_by_sphere() -> None:
    # 300 spheres are built by decimal blocks attached to the world: ids, names, the joint and
    # motor of every axis and the keyframe must still run sphere by sphere, as one loop would.
    n, accel_max, mass = 300, 1.5, 0.1
    m = paper_world_spec(n, seed=4, box_size=(n / 40) ** (1 / 3), accel_max=accel_max).compile()
    assert (m.nbody, m.njnt, m.nu, m.ngeom) == (n + 1, 3 * n, 3 * n, n + 6)
    for i in range(n):
        body = m.body(f"sphere{i}")
        assert body.id == i + 1 and m.geom(f"sphere{i}").bodyid[0] == body.id
        for k, axis in enumerate("xyz"):
            joint = m.joint(f"sphere{i}_{axis}")
            assert joint.id == 3 * i + k and joint.bodyid[0] == body.id
            assert np.array_equal(joint.axis, np.eye(3)[k])
            motor = m.actuator(f"sphere{i}_{axis}")
            assert motor.id == 3 * i + k and motor.trnid[0] == joint.id
            assert np.allclose(motor.ctrlrange, [-mass * accel_max, mass * accel_max])
    assert m.key_qvel.shape == (1, 3 * n)


def _paper_world_as_mjcf(n: int, *, seed: int, box_size: float) -> mujoco.MjModel:
    """Slow reference for :func:`paper_world_spec` (default options): the same world written
    as MJCF text, sphere by sphere, from the same draws of the same seed (MuJoCo parses every
    element in time linear in the model: quadratic in all, fine for a few thousand)."""
    rng = np.random.default_rng(seed)
    half, radius = box_size / 2, 0.03
    centres = _place_spheres(n, rng, half=half, radius=radius, clearance=radius / 4)
    direction = rng.normal(size=(n, 3))
    velocity = direction / np.linalg.norm(direction, axis=1, keepdims=True)
    velocity *= rng.uniform(0.0, 0.5, size=(n, 1))
    # Colours are float32 in MuJoCo: written as their float32 values, read back exactly.
    palette = rng.uniform(0.2, 0.9, size=(n, 3)).astype(np.float32).astype(float)

    def row(values: np.ndarray) -> str:
        return " ".join(map(repr, np.asarray(values, dtype=float).ravel().tolist()))

    walls = [
        f'<geom name="{name}" type="plane" pos="{row(-half * np.array(normal))}" '
        f'quat="{row(_quat_z_to(np.array(normal, dtype=float)))}" '
        f'size="{half!r} {half!r} {0.05 * box_size!r}" '
        f'rgba="0.6 0.6 0.7 {1.0 if name == "floor" else 0.08}"/>'
        for name, normal in (
            ("floor", (0, 0, 1)),
            ("ceiling", (0, 0, -1)),
            ("wall_xneg", (1, 0, 0)),
            ("wall_xpos", (-1, 0, 0)),
            ("wall_yneg", (0, 1, 0)),
            ("wall_ypos", (0, -1, 0)),
        )
    ]
    spheres = [
        f'<body name="sphere{i}" pos="{row(centres[i])}">'
        + "".join(
            f'<joint name="sphere{i}_{a}" type="slide" axis="{axis}"/>'
            for a, axis in zip("xyz", ("1 0 0", "0 1 0", "0 0 1"), strict=True)
        )
        + f'<geom name="sphere{i}" size="{radius!r}" mass="0.1" rgba="{row(palette[i])} 1"/>'
        + "</body>"
        for i in range(n)
    ]
    motors = [
        f'<general name="sphere{i}_{a}" joint="sphere{i}_{a}" ctrlrange="-0.1 0.1" '
        'ctrllimited="true"/>'
        for i in range(n)
        for a in "xyz"
    ]
    return mujoco.MjModel.from_xml_string(
        f"""<mujoco model="paper_world_{n}">
  <compiler angle="radian"/>
  <option timestep="0.002" gravity="0 0 0" integrator="Euler"/>
  <statistic center="0 0 0" extent="{box_size!r}"/>
  <visual><global offwidth="1280" offheight="960"/></visual>
  <worldbody>{"".join(walls)}<light pos="0 0 {2 * box_size!r}"/>{"".join(spheres)}</worldbody>
  <actuator>{"".join(motors)}</actuator>
  <custom><numeric name="dua_accel_bound" data="{paper_world_accel_bound(1.0)!r}"/></custom>
  <keyframe><key name="init" qvel="{row(velocity)}"/></keyframe>
</mujoco>"""
    )


def _model_bytes(m: mujoco.MjModel) -> bytes:
    buf = np.empty(mujoco.mj_sizeModel(m), dtype=np.uint8)
    mujoco.mj_saveModel(m, None, buf)
    return buf.tobytes()


@pytest.mark.parametrize("template_digits", [3, 1])
@pytest.mark.parametrize("n", [1, 9, 11, 40, 101, 345, 1234])
def test_paper_world_is_the_world_written_sphere_by_sphere(
    n: int, template_digits: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The generator builds the spheres by decimal blocks, attached and set afterwards; its
    # model must be, byte for byte, the one written sphere by sphere: names, ids, joints,
    # motors, positions, colours and velocities in order. template_digits=1 builds every block
    # of 100 or more anew (as from 20,000 spheres on with the default of 3).
    monkeypatch.setattr(_SphereBlocks, "TEMPLATE_DIGITS", template_digits)
    box = max(1.0, (n / 40) ** (1 / 3))
    generated = paper_world_spec(n, seed=7, box_size=box).compile()
    assert _model_bytes(generated) == _model_bytes(_paper_world_as_mjcf(n, seed=7, box_size=box))


@pytest.mark.parametrize("n", [1, 76, 301])
def test_paper_world_survives_a_round_trip_through_xml(n: int) -> None:
    # `dua-mujoco export paper_world:N out.xml` writes the spec; every chunk's attach must not
    # leave a default class behind twice, which MuJoCo refuses to read back.
    spec = paper_world_spec(n, box_size=max(1.0, (n / 40) ** (1 / 3)))
    m = spec.compile()
    back = mujoco.MjModel.from_xml_string(spec.to_xml())
    assert (back.nbody, back.njnt, back.nu, back.ngeom) == (m.nbody, m.njnt, m.nu, m.ngeom)
    np.testing.assert_allclose(back.body_pos, m.body_pos, atol=1e-6)  # six digits in MJCF
    assert np.array_equal(back.actuator_trnid, m.actuator_trnid)


def test_bundled_paper_world_is_the_generators_output() -> None:
    # models/paper_world.xml says "generated, do not edit": it must still be what the
    # generator writes (its header comment aside).
    path = models_dir() / "paper_world.xml"
    bundled = re.sub(r"\n  <!--.*?-->", "", path.read_text(), flags=re.S)
    assert bundled.strip() == paper_world_spec(40, seed=0).to_xml().strip()


def test_paper_world_is_seeded() -> None:
    a, b = paper_world_model(8, seed=1), paper_world_model(8, seed=1)
    c = paper_world_model(8, seed=2)
    assert np.array_equal(a.body_pos, b.body_pos)
    assert not np.array_equal(a.body_pos, c.body_pos)


def _measured_accel_when_unconstrained(
    m: mujoco.MjModel, d: mujoco.MjData, steps: int, seed: int
) -> np.ndarray:
    """Finite-difference accelerations ``(qvel' - qvel) / h`` of the steps without constraints.

    ``d.nefc`` after ``mj_step`` counts the constraints (contacts, limits) that acted during
    that step, so ``nefc == 0`` selects exactly the steps where only the actuators pushed.
    """
    controller = make_controller(m, CtrlMode.RANDOM, seed=seed, hold_steps=20)
    accels = []
    for _ in range(steps):
        controller(m, d)
        before = d.qvel.copy()
        mujoco.mj_step(m, d)
        if d.nefc == 0:
            accels.append((d.qvel - before) / m.opt.timestep)
    return np.array(accels)


def test_paper_world_acceleration_bound_holds() -> None:
    accel_max = 2.0
    m = paper_world_spec(12, seed=5, accel_max=accel_max, box_size=2.0).compile()
    d = mujoco.MjData(m)
    reset_to_keyframe(m, d, None)
    bound = declared_accel_bound(m)
    assert bound is not None
    assert bound == pytest.approx(paper_world_accel_bound(accel_max))
    acc = _measured_accel_when_unconstrained(m, d, 400, seed=0)
    assert len(acc) > 100, "the stretch should be mostly contact-free"
    per_sphere = np.linalg.norm(acc.reshape(len(acc), -1, 3), axis=2)
    assert per_sphere.max() <= bound * (1 + 1e-9)
    assert np.abs(acc).max() <= accel_max * (1 + 1e-9)
    # Random uniform controls come close to the bound: the bound is tight, not vacuous.
    assert per_sphere.max() > 0.7 * bound


def test_traffic_acceleration_bound_holds() -> None:
    m, d = load_scene("traffic")
    bound = declared_accel_bound(m)
    assert bound is not None
    assert bound == pytest.approx(SCENES["traffic"].accel_hint)
    acc = _measured_accel_when_unconstrained(m, d, 150, seed=1)
    assert len(acc) > 50
    assert np.abs(acc).max() <= bound * (1 + 1e-9)


def _recorded(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    ctrl: SceneController,
    steps: int,
    read: Callable[[mujoco.MjData], np.ndarray],
) -> np.ndarray:
    """``steps`` physics steps under ``ctrl``; ``read(d)`` after each control, stacked."""
    seen = []
    for _ in range(steps):
        ctrl(m, d)
        seen.append(np.copy(read(d)))
        mujoco.mj_step(m, d)
    return np.array(seen)


def test_controller_modes() -> None:
    m, d = load_scene("clutter")
    zero = make_controller(m, "zero")
    zero(m, d)
    assert np.all(d.ctrl == 0.0) and zero.mocap_accel_bound == 0.0
    with pytest.raises(InvalidChoiceError, match="random"):
        make_controller(m, "chaos")
    with pytest.raises(InvalidInputError):
        make_controller(m, CtrlMode.RANDOM, hold_steps=0)

    m, d = load_scene("two_arms")
    ctrl = make_controller(m, CtrlMode.RANDOM, seed=4, hold_steps=5)
    seen_arr = _recorded(m, d, ctrl, 20, lambda d: d.ctrl)
    lo, hi = m.actuator_ctrlrange.T
    assert np.all(seen_arr >= lo) and np.all(seen_arr <= hi)
    assert len({tuple(row) for row in seen_arr}) == 4  # held for 5 steps each
    again = make_controller(m, CtrlMode.RANDOM, seed=4, hold_steps=5)
    reset_to_keyframe(m, d, None)
    again(m, d)
    assert np.array_equal(d.ctrl, seen_arr[0])


def test_mocap_path_respects_its_bounds() -> None:
    m, d = load_scene("clutter")
    circle = MocapCircle(radius=0.08, period=2.0)
    ctrl = make_controller(m, CtrlMode.RANDOM, seed=0, mocap=circle)
    h = m.opt.timestep
    p = _recorded(m, d, ctrl, 300, lambda d: d.mocap_pos)
    assert np.allclose(p[0], m.body_pos[m.body("stirrer").id])  # no jump at t = 0
    speed = np.linalg.norm(np.diff(p, axis=0), axis=2) / h
    accel = np.linalg.norm(p[2:] - 2 * p[1:-1] + p[:-2], axis=2) / h**2
    assert speed.max() <= ctrl.mocap_speed_bound * (1 + 1e-9)
    assert accel.max() <= ctrl.mocap_accel_bound * (1 + 1e-6)
    assert accel.max() > 0.9 * ctrl.mocap_accel_bound


# --------------------------------------------------------------------------------------------------
# Progress display.
# --------------------------------------------------------------------------------------------------


class _Stream(io.StringIO):
    def __init__(self, tty: bool) -> None:
        super().__init__()
        self._tty = tty

    def isatty(self) -> bool:
        return self._tty


@pytest.mark.parametrize("tty", [True, False])
def test_progress_draws_in_place_on_a_terminal_and_lines_elsewhere(tty: bool) -> None:
    stream = _Stream(tty)
    with Progress(200, "job", stream=stream, min_interval=0.0) as bar:
        for _ in range(200):
            bar.update(note="x")
    out = stream.getvalue()
    if tty:
        assert out.count("\r") >= 200 and out.endswith("\n")
        assert out.count("\n") == 1
    else:
        assert "\r" not in out and "\x1b" not in out
        lines = out.splitlines()
        assert [line.split()[1] for line in lines] == [f"{20 * k}/200" for k in range(1, 11)]


def test_progress_disabled_writes_nothing() -> None:
    stream = _Stream(True)
    with Progress(10, "job", stream=stream, enabled=False) as bar:
        bar.update(10)
    assert stream.getvalue() == ""
