"""The run monitor's screened bound check (``PointMotion(screen=True)``, ``dua_check_groups``;
docs/theory.md, "The monitor's screen"): it measures only the groups a screen cannot clear, and
flags exactly what the full pass flags, with the same values at the flagged points.

Held on random frames (rotations, mocap twists, bounds drawn at, just under and just over the
values the full pass measures) and on rollouts (a swarm with contacts, a spinning box whose
corners break an acceleration bound its centre keeps).
"""

from __future__ import annotations

from types import SimpleNamespace

import mujoco
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from mjcf import free, mjcf

from dua_mujoco.build.bounds import MotionBounds
from dua_mujoco.build.events import BodyBoxes
from dua_mujoco.build.kinematics import PointMotion, pack_spheres
from dua_mujoco.measure.checks import BoundMonitor
from dua_mujoco.models.scenes import load_scene, make_controller
from dua_mujoco.runtime.predictor import Predictor

NBODY = 3


def _rotation(axis_angle: np.ndarray) -> np.ndarray:
    """Rodrigues' rotation of a (3,) axis times angle."""
    angle = float(np.linalg.norm(axis_angle))
    if angle == 0.0:
        return np.eye(3)
    k = axis_angle / angle
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx


def _frames(rng: np.random.Generator, updates: int, h: float) -> list[SimpleNamespace]:
    """``updates`` instants of NBODY bodies (one geom each; body 2 a child of body 1, a mocap
    root with a twist at some instants), moving and spinning with jumps in between."""
    pos = rng.normal(scale=3.0, size=(NBODY, 3))
    rot = [_rotation(rng.normal(size=3)) for _ in range(NBODY)]
    vel = rng.normal(size=(NBODY, 3))
    spin = rng.normal(scale=rng.choice([0.0, 1.0, 20.0]), size=(NBODY, 3))
    out = []
    for _ in range(updates):
        if rng.random() < 0.3:  # an impulse
            vel += rng.normal(scale=5.0, size=(NBODY, 3))
            spin += rng.normal(scale=5.0, size=(NBODY, 3))
        vel += h * rng.normal(size=(NBODY, 3))
        pos = pos + h * vel
        rot = [_rotation(h * spin[b]) @ rot[b] for b in range(NBODY)]
        cvel = np.concatenate([spin, vel], axis=1)
        root_twist = np.zeros((NBODY, 6))
        if rng.random() < 0.5:
            root_twist[1] = rng.normal(size=6)
        out.append(
            SimpleNamespace(
                geom_xpos=pos.copy(),
                geom_xmat=np.stack([r.reshape(9) for r in rot]),
                cvel=cvel,
                subtree_com=pos + rng.normal(scale=0.1, size=(NBODY, 3)),
                xpos=pos.copy(),
                root_twist=root_twist,
            )
        )
    return out


def _points(rng: np.random.Generator) -> np.ndarray:
    """The corners of a box on each geom, then a scatter of points on geom 0 (a group that is
    no box), as packed records; body 2 is rooted at body 1."""
    boxes = BodyBoxes(
        np.arange(NBODY),
        np.arange(NBODY),
        rng.normal(scale=0.3, size=(NBODY, 3)),
        rng.uniform(0.01, 0.5, size=(NBODY, 3)),
    )
    geom, body, offset = boxes.corners()
    scatter = rng.normal(scale=0.4, size=(5, 3))
    geom = np.concatenate([geom, np.zeros(5, dtype=np.int64)])
    body = np.concatenate([body, np.zeros(5, dtype=np.int64)])
    offset = np.concatenate([offset, scatter])
    return pack_spheres(geom, body, offset, np.array([0, 1, 1]))


def _run(motion: PointMotion, frames: list[SimpleNamespace], h: list[float], check: np.ndarray):
    """Each update's count, broken flags and the broken points' values."""
    out = []
    for f, dt in zip(frames, h, strict=True):
        n = motion.update(f, f.root_twist, dt, check)
        out.append((n, motion.broken.copy(), np.where(motion.broken, motion.values, np.nan)))
    return out


@settings(max_examples=300, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([0.5, 0.99, 1.0, 1.0 + 1e-15, 1.01, 2.0]))
def test_screened_check_flags_what_the_full_pass_flags(seed: int, factor: float) -> None:
    """Bounds at ``factor`` times the largest value the full pass measures on a body at one
    update (so some bodies sit exactly at their bound there): every update's count, flags and
    flagged values are the same with the screen as without."""
    rng = np.random.default_rng(seed)
    points = _points(rng)
    updates, h0 = 7, float(rng.choice([0.002, 0.01]))
    frames = _frames(rng, updates, h0)
    h = [h0 * float(rng.choice([1.0, 1.0, 0.5])) for _ in range(updates)]
    body = points[:, 1].astype(np.int64)
    # What the full pass measures, without bounds: the bounds are drawn from it.
    probe = PointMotion(points)
    measured = np.zeros((updates, points.shape[0], 3))
    for k, f in enumerate(frames):
        probe.update(f, f.root_twist, h[k])
        measured[k] = probe.values
    at = int(rng.integers(2, updates))
    top = np.zeros((NBODY, 3))
    np.maximum.at(top, body, measured[at])
    bounds = top[body] * factor
    speed = bounds[:, 0] if rng.random() < 0.8 else None
    check = rng.random(NBODY)[body] < 0.8
    sides = [
        PointMotion(points, bounds[:, 2], bounds[:, 1], speed, 1e-9, screen=screen)
        for screen in (False, True)
    ]
    full, screened = (_run(m, frames, h, check) for m in sides)
    for k, (a, b) in enumerate(zip(full, screened, strict=True)):
        assert a[0] == b[0], f"update {k}"
        np.testing.assert_array_equal(a[1], b[1], err_msg=f"update {k}")
        np.testing.assert_array_equal(a[2], b[2], err_msg=f"update {k}")


def test_screen_skips_quiet_groups_and_measures_the_rest() -> None:
    """The screen is not a no-op: quiet bodies are skipped, a broken one is measured."""
    rng = np.random.default_rng(3)
    points = _points(rng)
    frames = _frames(np.random.default_rng(5), 6, 0.002)
    n = points.shape[0]
    motion = PointMotion(points, np.full(n, 1e9), np.full(n, 1e9), None, 0.0, screen=True)
    for f in frames:
        motion.update(f, f.root_twist, 0.002)
    assert motion.measured_groups == 0
    low = PointMotion(points, np.zeros(n), np.zeros(n), None, 0.0, screen=True)
    for f in frames:
        low.update(f, f.root_twist, 0.002)
    assert low.measured_groups == NBODY + 1


def _same_monitors(
    m: mujoco.MjModel, d: mujoco.MjData, monitors: list[BoundMonitor], steps: int, drive
) -> None:
    for k in range(steps):
        drive(m, d)
        mujoco.mj_step(m, d)
        a, b = (mon.update(m, d) for mon in monitors)
        np.testing.assert_array_equal(a, b, err_msg=f"step {k}")
    full, screened = monitors
    assert full.violations == screened.violations
    assert full.worst == screened.worst and full.held == screened.held


def test_screened_monitor_equals_the_full_one_on_a_swarm_with_contacts() -> None:
    m, d = load_scene("swarm:60")
    p = Predictor(m, accel=2.0)
    mons = [
        BoundMonitor(m, p.bounds, p.bound_points, mocap=p.mocap, max_violations=10**9, screen=s)
        for s in (False, True)
    ]
    ctrl = make_controller(m, "random", seed=2)
    _same_monitors(m, d, mons, 400, ctrl)
    assert mons[0].nviolations > 10  # contacts broke bounds: the screen had work to pass on
    assert mons[1]._points.measured_groups < m.nbody // 2  # and most bodies were skipped


SPIN_BOX = mjcf(free("box", "0 0 0", 'type="box" size=".3 .2 .1"'), option='gravity="0 0 0"')


def test_a_spinning_box_breaks_at_its_corners_with_the_screen_too() -> None:
    """Torque-free spin: the box's centre keeps an acceleration bound its corners break
    (|omega|^2 r), so a screen that looked at the centre alone would clear it."""
    m = mujoco.MjModel.from_xml_string(SPIN_BOX)
    corner = float(np.hypot(0.3, 0.2)) * 100.0  # |omega|^2 r of the farthest corner
    for accel in (0.5 * corner, 0.99 * corner, 1.01 * corner):
        bounds = MotionBounds.declare(m, accel)
        half = np.array([[0.3, 0.2, 0.1]])
        boxes = BodyBoxes(np.array([0]), np.array([1]), np.zeros((1, 3)), half)
        mons = [
            BoundMonitor(m, bounds, boxes.corners(), max_violations=10**9, screen=s)
            for s in (False, True)
        ]
        d = mujoco.MjData(m)
        d.qvel[3:] = [0.0, 0.0, 10.0]
        _same_monitors(m, d, mons, 200, lambda m, d: None)
        if accel < corner:
            assert any(v.kind == "accel" for v in mons[0].violations)
