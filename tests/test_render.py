"""Overlay, offscreen frames and videos (headless: MUJOCO_GL=egl through Mesa llvmpipe)."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import itertools
import subprocess
import sys
import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest
from mjcf import free, mjcf

from dua_mujoco.exceptions import DuaError, InvalidChoiceError, InvalidInputError
from dua_mujoco.render import (
    ALARM_RGBA,
    AlarmOverlay,
    OverlayOptions,
    OverlayRenderer,
    SceneFullWarning,
    VideoWriter,
    check_frame_size,
    read_video,
    render_rollout,
    write_video,
)
from dua_mujoco.runtime.predictor import Predictor

W, H = 320, 240

# Two free spheres on the x axis, seen by a camera on -y looking along +y (camera z = -y).
TWO_SPHERES = f"""
<mujoco>
  <option gravity="0 0 0" timestep="0.002"/>
  <visual><global offwidth="{W}" offheight="{H}"/></visual>
  <worldbody>
    <light pos="0 -1 1" dir="0 1 -1"/>
    <camera name="front" pos="0 -1.5 0" xyaxes="1 0 0 0 0 1" fovy="45"/>
    <body name="a" pos="-0.2 0 0">
      <freejoint/>
      <geom name="a" type="sphere" size="0.05" rgba="0.8 0.8 0.8 1"/>
    </body>
    <body name="b" pos="0.2 0 0">
      <freejoint/>
      <geom name="b" type="sphere" size="0.05" rgba="0.8 0.8 0.8 1"/>
    </body>
  </worldbody>
</mujoco>
"""

# A sphere above a floor: its only pair is a sphere/half-space pair.
BALL_ON_PLANE = mjcf(
    '<geom name="floor" type="plane" size="1 1 0.1"/>',
    free("ball", "0.1 0.2 0.3", 'name="ball" type="sphere" size="0.05"'),
    option='gravity="0 0 0"',
)


def _start(xml: str, accel: float, *, x: float | None = None, speed: float = 0.0):
    """Model, data after one step, predictor and its initial alarms."""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    if x is not None:
        data.qpos[0], data.qpos[7] = -x, x
    if speed:
        data.qvel[0], data.qvel[6] = speed, -speed  # towards each other
    mujoco.mj_step(model, data)
    predictor = Predictor(model, accel=accel)
    return model, data, predictor, predictor.reset(data)


def _project(model: mujoco.MjModel, data: mujoco.MjData, cam: int, point: np.ndarray):
    """Pixel (column, row) of a world point in a fixed camera (OpenGL: camera looks along -z)."""
    R = data.cam_xmat[cam].reshape(3, 3)
    pc = R.T @ (point - data.cam_xpos[cam])
    f = 0.5 * H / np.tan(np.deg2rad(model.cam_fovy[cam]) / 2)
    return W / 2 + f * pc[0] / -pc[2], H / 2 - f * pc[1] / -pc[2]


def _pure_red(frame: np.ndarray, tol: int = 10) -> np.ndarray:
    f = frame.astype(int)
    return (f[..., 0] >= 255 - tol) & (f[..., 1] <= tol) & (f[..., 2] <= tol)


def test_alarmed_pair_draws_a_red_connector_at_its_midpoint() -> None:
    # accel 1e6 m/s^2 closes the 0.3 m gap in < 1 ms: alarmed within one 2 ms period.
    model, data, predictor, alarms = _start(TWO_SPHERES, 1e6, speed=0.5)
    assert len(alarms) == 1
    centres, _ = predictor.sphere_states(data)
    mid = centres[[alarms.sphere1[0], alarms.sphere2[0]]].mean(axis=0)
    u, v = _project(model, data, 0, mid)
    with OverlayRenderer(predictor, width=W, height=H) as renderer:
        frame = renderer.render(data, alarms, camera="front")
        assert frame.shape == (H, W, 3) and frame.dtype == np.uint8
        red = _pure_red(frame)
        rows, cols = np.nonzero(red)
        near = (np.abs(cols - u) <= 8) & (np.abs(rows - v) <= 8)
        assert near.sum() >= 3, f"no pure red near ({u:.0f}, {v:.0f}); red at {len(rows)} px"
        # The alarmed spheres are tinted, but never pure red: the red came from the connector.
        plain = OverlayRenderer(
            predictor, width=W, height=H, options=OverlayOptions(connectors=False, text=False)
        )
        with plain:
            assert not _pure_red(plain.render(data, alarms, camera="front")).any()
        assert AlarmOverlay(predictor).geom_levels().tolist() == [0, 0]


def test_nothing_alarmed_draws_no_pure_red() -> None:
    _, data, predictor, alarms = _start(TWO_SPHERES, 1.0, x=0.35)
    assert len(alarms) == 0
    with OverlayRenderer(
        predictor, width=W, height=H, options=OverlayOptions(show_spheres=True)
    ) as renderer:
        frame = renderer.render(data, alarms, camera="front")
    assert not _pure_red(frame).any()
    assert AlarmOverlay(predictor).geom_levels().tolist() == [3, 3]


def test_overlay_draws_every_pair_standing_in_alarm_and_pruned_sets() -> None:
    """Tint, connectors and count follow the pairs standing in alarm (by the model's pair ids),
    also on steps where the backoff does not evaluate them, and on a pruned predictor, whose
    scheduler holds only some pairs."""
    from dua_mujoco.models.scenes import load_scene

    model, data = load_scene("swarm:300")
    predictor = Predictor(model, accel=30.0)
    # Made before the reset, as a video's renderer is: the pruned predictor learns its pairs
    # after it, and the overlay must draw the ids it learns.
    overlay = AlarmOverlay(predictor)
    known = predictor.nsphere_pairs
    mujoco.mj_step(model, data)
    predictor.reset(data)
    assert predictor.held_pairs.size < predictor.universe.counts()[1]  # pruned
    learnt = False
    quiet_steps = 0
    for _ in range(60):
        mujoco.mj_step(model, data)
        alarms = predictor.step(data)
        standing = overlay.standing_pairs()
        state = predictor.pair_state()
        np.testing.assert_array_equal(standing, np.flatnonzero(state.alarm_state() & state.active))
        assert set(alarms.pairs.tolist()) <= set(standing.tolist())
        quiet_steps += bool(standing.size > len(alarms))
        scene = _scene(model, data, model.ngeom + standing.size + 1)
        before = scene.ngeom
        assert overlay.add_to_scene(scene, data, alarms) == 0
        assert scene.ngeom - before == standing.size  # one connector per standing pair
        learnt |= bool(standing.size and standing.max() >= known)
    assert quiet_steps > 0  # pairs stood in alarm without being evaluated (backoff)
    assert learnt  # pairs met after the overlay was made stood in alarm, and were drawn


def _scene(model: mujoco.MjModel, data: mujoco.MjData, maxgeom: int) -> mujoco.MjvScene:
    scene = mujoco.MjvScene(model, maxgeom=maxgeom)
    cam = mujoco.MjvCamera()
    mujoco.mjv_defaultFreeCamera(model, cam)
    mujoco.mjv_updateScene(
        model, data, mujoco.MjvOption(), None, cam, int(mujoco.mjtCatBit.mjCAT_ALL), scene
    )
    return scene


def test_halfspace_connector_ends_on_the_plane() -> None:
    model, data, predictor, alarms = _start(BALL_ON_PLANE, 1e6)
    assert len(alarms) == 1 and alarms.sphere2[0] == -1
    scene = _scene(model, data, 100)
    n0 = scene.ngeom
    assert AlarmOverlay(predictor).add_to_scene(scene, data, alarms) == 0
    assert scene.ngeom == n0 + 1
    line = scene.geoms[n0]
    assert line.type == int(mujoco.mjtGeom.mjGEOM_LINE)
    np.testing.assert_allclose(line.rgba, ALARM_RGBA)
    end = line.pos + line.mat[:, 2] * line.size[2]
    np.testing.assert_allclose(line.pos, data.geom_xpos[1], atol=1e-6)
    np.testing.assert_allclose(end, [0.1, 0.2, 0.0], atol=1e-6)


def test_full_scene_drops_geoms_and_warns_once() -> None:
    model, data, predictor, alarms = _start(TWO_SPHERES, 1e6)
    overlay = AlarmOverlay(predictor, options=OverlayOptions(show_spheres=True))
    scene = _scene(model, data, model.ngeom + 1)  # room for the connector only
    with pytest.warns(SceneFullWarning, match="maxgeom"):
        assert overlay.add_to_scene(scene, data, alarms) == 2
    assert scene.ngeom == scene.maxgeom
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert overlay.add_to_user_scn(_Viewer(_scene(model, data, 1)), data, alarms) == 2
    assert overlay.dropped == 4
    # A renderer whose scene cannot even hold the model does not crash either.
    with (
        pytest.warns(SceneFullWarning),
        OverlayRenderer(predictor, width=64, height=48, max_geom=1) as renderer,
    ):
        assert renderer.render(data, alarms).shape == (48, 64, 3)


class _Viewer:
    def __init__(self, scene: mujoco.MjvScene) -> None:
        self.user_scn = scene


def test_offscreen_buffer_too_small() -> None:
    _, _, predictor, _ = _start(TWO_SPHERES, 1.0)
    with pytest.raises(InvalidInputError, match=r"offwidth=\"640\".*grow_buffer"):
        OverlayRenderer(predictor, width=640, height=H)
    with OverlayRenderer(predictor, width=640, height=H, grow_buffer=True) as renderer:
        assert renderer.width == 640 and predictor.model.vis.global_.offwidth == 640


def test_renderer_closes() -> None:
    _, data, predictor, alarms = _start(TWO_SPHERES, 1.0)
    with OverlayRenderer(predictor, width=64, height=48) as renderer:
        renderer.render(data, alarms)
        with pytest.raises(InvalidChoiceError, match="front"):
            renderer.render(data, alarms, camera="nope")
    assert renderer.closed
    renderer.close()  # idempotent
    with pytest.raises(DuaError, match="closed"):
        renderer.render(data, alarms)


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_render_rollout_writes_a_readable_video(tmp_path: Path, suffix: str) -> None:
    model, data, predictor, _ = _start(TWO_SPHERES, 1e6, speed=0.5)
    path = tmp_path / "sub" / f"run{suffix}"
    n = render_rollout(
        model,
        data,
        predictor,
        steps=20,
        every=2,
        width=64,
        height=48,
        fps=10,
        path=path,
        camera="front",
        options=OverlayOptions(show_spheres=True),
        progress=False,
    )
    assert n == 10
    video = read_video(path)
    assert video.shape == (10, 48, 64, 3)


def test_write_video_rejects_bad_input(tmp_path: Path) -> None:
    frames = [np.zeros((48, 64, 3), np.uint8)] * 2
    with pytest.raises(InvalidChoiceError, match=r"\.mp4"):
        write_video(frames, tmp_path / "x.avi", fps=10)
    with pytest.raises(InvalidInputError, match="even"):
        write_video([np.zeros((47, 64, 3), np.uint8)], tmp_path / "x.mp4", fps=10)
    with pytest.raises(InvalidInputError, match="no frames"):
        write_video([], tmp_path / "x.gif", fps=10)
    with pytest.raises(InvalidInputError, match="frame 1"):
        write_video([frames[0], np.zeros((48, 66, 3), np.uint8)], tmp_path / "x.gif", fps=10)


def _frames(n: int, h: int = 48, w: int = 64) -> list[np.ndarray]:
    """Distinct frames: a bright square moving over a dark gradient."""
    base = np.zeros((h, w, 3), np.uint8)
    base[..., 2] = np.linspace(0, 120, w, dtype=np.uint8)
    out = []
    for i in range(n):
        f = base.copy()
        x = (4 * i) % (w - 8)
        f[10:18, x : x + 8] = (240, 240, 40)
        out.append(f)
    return out


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_video_writer_streams_and_an_interrupt_leaves_a_playable_video(
    tmp_path: Path, suffix: str
) -> None:
    """Frames reach the file as they are added; an exception mid-video keeps what was written."""
    path = tmp_path / f"v{suffix}"
    path.write_bytes(b"an older video")
    frames = _frames(12)
    sizes = []
    with pytest.raises(KeyboardInterrupt), VideoWriter(path, fps=10) as writer:
        for i, f in enumerate(frames):
            if i == 7:
                raise KeyboardInterrupt
            writer.add(f)
            tmp = [p for p in tmp_path.iterdir() if p.name != path.name]
            sizes.append(sum(p.stat().st_size for p in tmp))
    assert writer.count == 7
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no temporary left
    umask = os.umask(0)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask  # not the temporary file's 0600
    video = read_video(path)
    assert video.shape == (7, 48, 64, 3)
    assert np.abs(video.astype(int) - np.asarray(frames[:7], dtype=int)).mean() < 8
    if suffix == ".gif":  # encoded frame by frame: the file grows with every frame
        assert all(b > a for a, b in itertools.pairwise(sizes)), sizes


def test_gif_frames_are_exact_where_colours_fit_the_palette(tmp_path: Path) -> None:
    """Changed rectangles over kept pixels rebuild every frame; pure red stays pure red."""
    frames = _frames(6)
    for f in frames:
        f[30:32, 5:40] = (255, 0, 0)
    write_video(frames, tmp_path / "x.gif", fps=10)
    video = read_video(tmp_path / "x.gif")
    assert video.shape == (6, 48, 64, 3)
    for got, want in zip(video, frames, strict=True):
        assert _pure_red(got)[30:32, 5:40].all()
        assert np.abs(got.astype(int) - want.astype(int)).max() <= 16


def test_video_writer_writes_through_a_symlink(tmp_path: Path) -> None:
    target = tmp_path / "real.gif"
    target.write_bytes(b"")
    link = tmp_path / "link.gif"
    link.symlink_to(target)
    assert write_video(_frames(3), link, fps=10) == 3
    assert link.is_symlink() and read_video(target).shape[0] == 3


def test_plain_mediapy_reads_the_videos_back(tmp_path: Path) -> None:
    """Importing the render module gives mediapy the bundled ffmpeg unless one was set."""
    path = tmp_path / "x.mp4"
    write_video(_frames(4), path, fps=10)
    code = (
        "import sys, mediapy, dua_mujoco.render\n"
        "print(mediapy.read_video(sys.argv[1]).shape)\n"
        "mediapy.set_ffmpeg('/my/ffmpeg')\n"
        "import importlib; importlib.reload(dua_mujoco.render)\n"
        "print(mediapy._config.ffmpeg_name_or_path)\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "PATH"} | {"PATH": "/nonexistent"}
    env["PYTHONPATH"] = str(Path(__file__).resolve().parent.parent)
    out = subprocess.run(
        [sys.executable, "-c", code, str(path)], capture_output=True, text=True, env=env
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split("\n")[:2] == ["(4, 48, 64, 3)", "/my/ffmpeg"]


def test_frame_size_beyond_the_maximum_is_refused_up_front() -> None:
    model, _, predictor, _ = _start(TWO_SPHERES, 1.0)
    with pytest.raises(InvalidInputError, match=r"100000x240 .* at most 4096.*offwidth"):
        check_frame_size(model, 100_000, H, grow_buffer=True)
    assert model.vis.global_.offwidth == W  # nothing grown on refusal
    with pytest.raises(InvalidInputError, match=r"at most 4096"):
        OverlayRenderer(predictor, width=100_000, height=H, grow_buffer=True)
    # A buffer the model allows but the GL context cannot hold: one clear error, no FatalError.
    model.vis.global_.offwidth = 40_000
    with pytest.raises(InvalidInputError, match=r"GL context cannot hold a 40000x240"):
        OverlayRenderer(predictor, width=40_000, height=H)
