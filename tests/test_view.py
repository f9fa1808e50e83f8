"""``dua-mujoco view``: MuJoCo's viewer with the live alarm overlay, headless under Xvfb.

The command runs in a subprocess on a virtual display (the ``display`` fixture, tests/screens.py:
skipped without Xvfb); screenshots are read from Xvfb's screen, keys typed with xdotool.
"""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco
import numpy as np
import pytest
from mjcf import motors
from screens import Display, ctrl_c_able, reddish

from dua_mujoco.cli import main
from dua_mujoco.render import TINTS, AlarmOverlay, OverlayOptions
from dua_mujoco.render.live import KEY_PAUSE, KEY_SPHERES, KEY_STEP, ViewerKeys
from dua_mujoco.runtime.predictor import Predictor

# Two grey boxes 2 cm apart on springy slides, pushed about by random motors. With an
# acceleration bound of 5e4 m/s^2 the gap closes within a period: both stand in alarm at every
# step, tinted "imminent" (brick red), so any red-orange pixel on screen is the overlay's.
BOXES = f"""
<mujoco>
  <option timestep="0.002" gravity="0 0 0"/>
  <worldbody>
    <light pos="0 -0.5 1" dir="0 0.5 -1"/>
    <body name="a" pos="-0.06 0 0">
      <joint name="a" type="slide" axis="1 0 0" stiffness="200" damping="2"/>
      <geom name="a" type="box" size="0.05 0.05 0.05" rgba="0.6 0.6 0.6 1"/>
    </body>
    <body name="b" pos="0.06 0 0">
      <joint name="b" type="slide" axis="0 0 1" stiffness="200" damping="2"/>
      <geom name="b" type="box" size="0.05 0.05 0.05" rgba="0.6 0.6 0.6 1"/>
    </body>
  </worldbody>
  {motors("a", "b", gear="20", ctrlrange="-1 1")}
</mujoco>
"""


class _Lines:
    """A subprocess's stderr, read line by line on a thread (nothing blocks on a full pipe)."""

    def __init__(self, stream) -> None:
        self.lines: queue.Queue[str] = queue.Queue()
        self.seen: list[str] = []
        self.everything: list[str] = []
        self._reader = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self._reader.start()

    def _read(self, stream) -> None:
        for line in stream:
            self.everything.append(line)
            self.lines.put(line)

    def text(self, timeout: float = 120.0) -> str:
        """All of the stream, once it has closed (the process ended)."""
        self._reader.join(timeout)
        return "".join(self.everything)

    def wait_for(self, text: str, timeout: float = 120.0) -> str:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                line = self.lines.get(timeout=0.5)
            except queue.Empty:
                continue
            self.seen.append(line)
            if text in line:
                return line
        raise AssertionError(f"no line with {text!r} on stderr; saw {self.seen}")


def _view(display: Display, scene: Path, *extra: str) -> subprocess.Popen:
    argv = [sys.executable, "-m", "dua_mujoco", "view", str(scene), "--accel", "5e4"]
    argv += ["--pilot-steps", "100", "--hide-ui", *extra]
    env = display.env()
    env.pop("MUJOCO_GL", None)  # the viewer opens a GLFW window, whatever the offscreen choice
    return subprocess.Popen(
        ctrl_c_able(argv), env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def _settled(display: Display, timeout: float = 120.0) -> np.ndarray:
    """A screen that a second later is still the same (the paused viewer's: the frames drawn
    before the pause, and the paused note's, may land late on a loaded machine); fails after
    ``timeout`` if it keeps changing (a viewer that runs on)."""
    deadline, last = time.monotonic() + timeout, display.screenshot()
    while time.monotonic() < deadline:
        time.sleep(1.0)
        shot = display.screenshot()
        if np.array_equal(shot, last):
            return shot
        last = shot
    raise AssertionError(f"the screen still changed every second after {timeout:.0f} s")


@pytest.fixture
def boxes(tmp_path: Path) -> Path:
    path = tmp_path / "boxes.xml"
    path.write_text(BOXES)
    return path


def test_viewer_shows_the_tint_live_and_its_keys_pause_step_and_toggle_spheres(
    display: Display, boxes: Path
) -> None:
    proc = _view(display, boxes)
    err = _Lines(proc.stderr)
    try:
        # Live: the boxes are tinted (nothing in the scene is red-orange of its own).
        tinted = display.wait_for(lambda shot: reddish(shot) > 2000)
        halo = reddish(tinted, dim=True)  # the boxes' edges
        # Enter: the covering spheres, translucent and tinted, larger than the boxes: a dim
        # red halo around each (measured: 2e3 such pixels before, 2.3e4 after).
        display.key("Return")
        display.wait_for(lambda shot: reddish(shot, dim=True) > max(4 * halo, 8000))
        # Space: paused; the frame no longer changes.
        display.key("space")
        err.wait_for("paused at t =")
        frozen = _settled(display)
        # Right: one predictor period, then paused again, the state moved.
        display.key("Right")
        err.wait_for("stepping one period")
        display.wait_for(lambda shot: not np.array_equal(shot, frozen))
        display.key("space")
        err.wait_for("resumed at t =")
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=120)
        except subprocess.TimeoutExpired:  # deaf to Ctrl-C: killed, and the test fails below
            proc.kill()
            proc.wait()
        out = proc.stdout.read()
        rest = err.text()
    assert proc.returncode == 130, rest
    assert "interrupted: the table covers the steps shown" in rest
    assert "contact onsets" in out and "interrupted" in out  # the run's table
    assert "Traceback" not in rest


def test_viewer_runs_the_steps_asked_and_prints_the_table(display: Display, boxes: Path) -> None:
    proc = _view(display, boxes, "--steps", "40", "--rate", "0")
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    assert "physics steps (predictor period)      40 (1)" in out


def test_view_without_a_display_is_one_line_exit_2(monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    assert main(["view", "two_arms"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "xvfb-run" in err[0] and "DISPLAY is not set" in err[0]


def test_view_rejects_a_negative_rate(capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["view", "--rate", "-1"])
    assert exc.value.code == 2
    assert "--rate '-1' is invalid" in capsys.readouterr().err


def test_keys_pause_step_only_while_paused_and_toggle_spheres() -> None:
    keys = ViewerKeys()
    keys.press(KEY_STEP)  # running: Right does nothing
    assert (keys.paused, keys.steps, keys.spheres) == (False, 0, False)
    keys.press(KEY_PAUSE)
    keys.press(KEY_STEP)
    keys.press(KEY_STEP)
    keys.press(KEY_SPHERES)
    assert (keys.paused, keys.steps, keys.spheres) == (True, 2, True)
    keys.press(ord("A"))  # the viewer's own keys are left to it
    keys.press(KEY_PAUSE)
    keys.press(KEY_SPHERES)
    assert (keys.paused, keys.spheres) == (False, False)


def test_tint_rgba_writes_the_videos_tint_into_geom_rgba(boxes: Path) -> None:
    """The live viewer's tint: the alarmed geoms get TINTS, the rest their own colour, alpha
    kept; with tinting off, the model's colours only."""
    model = mujoco.MjModel.from_xml_path(str(boxes))
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data)
    predictor = Predictor(model, accel=5e4)
    alarms = predictor.reset(data)
    overlay = AlarmOverlay(predictor)
    scene = mujoco.MjvScene(model, maxgeom=100)
    overlay.add_to_scene(scene, data, alarms)  # reads the standing pairs
    base = np.array(model.geom_rgba)
    base[:, 3] = 0.7
    rgba = np.zeros_like(base)
    overlay.tint_rgba(rgba, base)
    levels = overlay.geom_levels()
    assert levels.tolist() == [0, 0]  # both imminent
    np.testing.assert_array_equal(rgba[:, :3], TINTS[[0, 0]])
    np.testing.assert_array_equal(rgba[:, 3], base[:, 3])
    overlay.options = OverlayOptions(tint_geoms=False)
    overlay.tint_rgba(rgba, base)
    np.testing.assert_array_equal(rgba, base)
