"""``LiveViewer``: MuJoCo's interactive viewer with the alarm overlay drawn live, and ``view``: a
monitored rollout shown in it (``dua-mujoco view``).

The overlay is :class:`~dua_mujoco.render.overlay.AlarmOverlay`'s, in the colours of the videos:
connectors and covering spheres in the viewer's ``user_scn``, the tint through the model's
``geom_rgba`` (restored by ``close``). Keys (``key_callback``; none of them is bound by MuJoCo's
viewer in passive mode): Space pauses and resumes, Right steps one predictor period while paused,
Enter shows or hides the covering spheres.

The viewer needs a display: on a machine without one, run it under Xvfb (``xvfb-run -a
dua-mujoco view``), or render a video instead (``dua-mujoco run --video``).
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Callable
from typing import Any, TextIO

import mujoco
import numpy as np

from dua_mujoco.closing import Closing
from dua_mujoco.core.validate import check_number
from dua_mujoco.exceptions import DuaError, InvalidInputError
from dua_mujoco.measure.monitor import Monitor
from dua_mujoco.measure.report import RunInterrupted, RunReport
from dua_mujoco.measure.rollout import run
from dua_mujoco.render.frames import status_line
from dua_mujoco.render.overlay import AlarmOverlay, OverlayOptions
from dua_mujoco.runtime.alarms import Alarms
from dua_mujoco.runtime.predictor import Predictor

__all__ = ["KEY_PAUSE", "KEY_SPHERES", "KEY_STEP", "LiveViewer", "ViewerKeys", "view"]

# GLFW's key codes, which the viewer's key_callback receives.
KEY_PAUSE = 32  # Space
KEY_STEP = 262  # Right arrow
KEY_SPHERES = 257  # Enter

KEYS_HELP = "Space: pause  Right: step  Enter: spheres"
TEXT_INTERVAL = 0.5
"""Seconds of wall time between refreshes of the status text while the rollout runs."""
CLOSE_TIMEOUT = 30.0
"""Seconds ``close`` waits for the viewer's thread to destroy its window."""


class ViewerKeys:
    """What the keys asked for: written on the viewer's thread, read on the stepping thread.

    Attributes:
        paused: Space toggles it.
        spheres: Enter toggles it (show the covering spheres).
        steps: Right-arrow presses not yet served (each: one predictor period while paused).
    """

    def __init__(self, *, paused: bool = False, spheres: bool = False) -> None:
        self.paused = paused
        self.spheres = spheres
        self.steps = 0

    def press(self, key: int) -> None:
        """Handle a key (the viewer's ``key_callback``); other keys are the viewer's own."""
        if key == KEY_PAUSE:
            self.paused = not self.paused
        elif key == KEY_SPHERES:
            self.spheres = not self.spheres
        elif key == KEY_STEP and self.paused:
            self.steps += 1


class LiveViewer(Closing):
    """MuJoCo's passive viewer on ``data`` with a predictor's alarm overlay (a resource: use
    ``with`` or call ``close()``, which also restores the model's colours).

    Args:
        predictor: The predictor whose alarms are drawn (its model is shown).
        data: The ``MjData`` that is stepped and shown.
        options: What the overlay draws (``show_spheres`` is the Enter key's starting state).
        show_ui: Show the viewer's side panels.

    Raises:
        InvalidInputError: No display (``DISPLAY`` unset) or the viewer could not open.
    """

    def __init__(
        self,
        predictor: Predictor,
        data: mujoco.MjData,
        *,
        options: OverlayOptions = OverlayOptions(),
        show_ui: bool = True,
    ) -> None:
        import mujoco.viewer

        self.model = predictor.model
        self.overlay = AlarmOverlay(predictor, options=options)
        self.keys = ViewerKeys(spheres=options.show_spheres)
        self._base_rgba = np.array(self.model.geom_rgba)
        self._note: str | None = None
        self._texted = -np.inf
        self._handle: Any = None
        before = set(threading.enumerate())
        try:
            self._handle = mujoco.viewer.launch_passive(
                self.model,
                data,
                key_callback=self.keys.press,
                show_left_ui=show_ui,
                show_right_ui=show_ui,
            )
        except (mujoco.FatalError, RuntimeError) as exc:
            raise InvalidInputError(
                f"MuJoCo's viewer could not open ({' '.join(str(exc).split())}): it needs a "
                "display (on a machine without one, run under Xvfb: xvfb-run -a ...), and on "
                "macOS the mjpython launcher; or render a video instead (run --video)."
            ) from None
        # The viewer's render thread (a daemon): close() joins it, or GLFW's atexit terminate
        # would run on the main thread while that thread still draws (a segfault at exit).
        self._threads = [t for t in threading.enumerate() if t not in before]
        with self._handle.lock():
            # The videos' default view (Renderer's free camera), not MjvCamera's fixed default.
            mujoco.mjv_defaultFreeCamera(self.model, self._handle.cam)

    @property
    def handle(self) -> Any:
        """The ``mujoco.viewer`` handle (``cam``, ``opt``, ``user_scn``, ...)."""
        if self._handle is None:
            raise DuaError("this LiveViewer is closed: create a new one to view.")
        return self._handle

    @property
    def running(self) -> bool:
        """False once the window was closed (or :meth:`close` ran)."""
        return self._handle is not None and bool(self._handle.is_running())

    def draw(self, data: mujoco.MjData, alarms: Alarms | None, *, note: str = "") -> None:
        """Draw the overlay of the predictor's current state and hand the frame to the viewer.

        Args:
            data: The ``MjData`` the predictor read.
            alarms: Its latest alarms (None before the reset: no connectors).
            note: Text after the status line (time, alarms).
        """
        handle = self.handle
        overlay = self.overlay
        if overlay.options.show_spheres != self.keys.spheres:
            overlay.options = dataclasses.replace(overlay.options, show_spheres=self.keys.spheres)
        with handle.lock():
            overlay.add_to_user_scn(handle, data, alarms)
            overlay.tint_rgba(self.model.geom_rgba, self._base_rgba)
        now = time.perf_counter()
        if overlay.options.text and (note != self._note or now - self._texted >= TEXT_INTERVAL):
            # set_texts waits for the viewer's next frame (40 ms in software GL, measured):
            # refreshed every TEXT_INTERVAL, or when the note (paused) changes. Outside the
            # lock, which it takes too (the viewer's mutex is not reentrant).
            nalarms = 0 if alarms is None else int(overlay.standing.size)
            text = f"{status_line(data.time, nalarms)}{note}"
            grid = int(mujoco.mjtGridPos.mjGRID_BOTTOMLEFT)
            handle.set_texts((None, grid, text, KEYS_HELP))
            self._note, self._texted = note, now
        handle.sync()

    def close(self) -> None:
        """Close the window and restore the model's colours (idempotent)."""
        self.model.geom_rgba[:] = self._base_rgba
        if self._handle is not None:
            self._handle.close()
            self._handle = None
            for thread in self._threads:
                thread.join(timeout=CLOSE_TIMEOUT)


class _WindowClosed(KeyboardInterrupt):
    """The window was closed: the rollout stops, as after a Ctrl-C, but it is no interrupt."""


def view(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    predictor: Predictor,
    *,
    steps: int | None = None,
    controller: Callable[[mujoco.MjModel, mujoco.MjData], None] | None = None,
    rate: float = 1.0,
    fps: float = 60.0,
    options: OverlayOptions = OverlayOptions(),
    show_ui: bool = True,
    scene: str = "",
    realtime: bool = False,
    geom_distance: bool = False,
    log: TextIO | None = None,
) -> RunReport:
    """Run a monitored rollout (:func:`~dua_mujoco.measure.rollout.run`) shown live in the viewer.

    The rollout is ``run``'s (``data``, ``predictor``, ``controller``, ``scene``, ``realtime``
    and ``geom_distance`` as there): the same exact stage and the same report. Frames are drawn
    at predictor steps, at most ``fps`` a second of wall time.

    Args:
        steps: Physics steps; None runs until the window is closed.
        rate: Simulated seconds per second of wall time (1: real time); 0 runs as fast as the
            machine allows.
        fps: Most frames drawn per second of wall time.
        options: What the overlay draws.
        show_ui: Show the viewer's side panels.
        log: Where to say that the run paused, resumed or stepped (None: nowhere).

    Returns:
        The run's report, ``interrupted=True`` if the window was closed before ``steps``.

    Raises:
        RunInterrupted: On a Ctrl-C, with the report of the steps done.
        InvalidInputError: A bad ``rate``, ``fps`` or ``steps``, or no display.
    """
    rate = check_number("rate", rate, zero=True, unit=" of simulated seconds a wall second")
    fps = check_number("fps", fps, unit=" of frames a second")
    total = 2**62 if steps is None else steps  # run checks it
    with LiveViewer(predictor, data, options=options, show_ui=show_ui) as viewer:
        pace = _Pacer(viewer, data, rate=rate, fps=fps, log=log)
        try:
            return run(
                model,
                data,
                predictor,
                steps=total,
                controller=controller,
                scene=scene,
                realtime=realtime,
                geom_distance=geom_distance,
                progress=False,
                on_step=pace.on_step,
                series=False,
            )
        except RunInterrupted as exc:
            if isinstance(exc.__cause__, _WindowClosed):
                return exc.report
            raise


class _Pacer:
    """``run``'s ``on_step`` for :func:`view`: draws, paces to ``rate``, pauses and steps."""

    def __init__(
        self,
        viewer: LiveViewer,
        data: mujoco.MjData,
        *,
        rate: float,
        fps: float,
        log: TextIO | None,
    ) -> None:
        self.viewer = viewer
        self.rate = rate
        self.frame = 1.0 / fps
        self.log = log
        self.alarms: Alarms | None = None
        self.advance = 0  # physics steps left of a Right-arrow step
        self.holding = False  # paused (stepping one period at a time included)
        self._restart(float(data.time))
        self._drawn = -np.inf

    def _restart(self, time_now: float) -> None:
        """Pace from now on (after a pause, wall time does not catch up)."""
        self._wall0 = time.perf_counter()
        self._time0 = time_now

    def _say(self, what: str, data: mujoco.MjData) -> None:
        if self.log is not None:
            print(f"dua-mujoco view: {what} at t = {data.time:.3f} s", file=self.log, flush=True)

    def on_step(self, k: int, data: mujoco.MjData, alarms: Alarms | None, monitor: Monitor) -> None:
        viewer = self.viewer
        if alarms is not None:
            self.alarms = alarms
        note = f"  missed {len(monitor.misses)}"
        if self.advance > 0:  # a Right-arrow step: one predictor period, then hold again
            self.advance -= 1
            if self.advance > 0:
                return
        if viewer.keys.paused:
            self._hold(data, note, monitor)
            return
        now = time.perf_counter()
        if alarms is not None and now - self._drawn >= self.frame:
            if not viewer.running:
                raise _WindowClosed
            viewer.draw(data, self.alarms, note=note)
            self._drawn = now
        if self.rate > 0:
            # Sleep in slices of a frame: a closed window is noticed within one.
            ahead = self._wall0 + (data.time - self._time0) / self.rate - now
            while ahead > 1e-3:
                time.sleep(min(ahead, self.frame))
                if not viewer.running:
                    raise _WindowClosed
                ahead = self._wall0 + (data.time - self._time0) / self.rate - time.perf_counter()

    def _hold(self, data: mujoco.MjData, note: str, monitor: Monitor) -> None:
        """Paused: keep drawing (camera moves, sphere toggles) until resumed or stepped."""
        viewer, keys = self.viewer, self.viewer.keys
        if not self.holding:
            self.holding = True
            self._say("paused", data)
        while keys.paused:
            if not viewer.running:
                raise _WindowClosed
            if keys.steps > 0:
                keys.steps -= 1
                self.advance = monitor.predictor.period
                self._say("stepping one period", data)
                return
            viewer.draw(data, self.alarms, note=f"{note}  (paused)")
            time.sleep(self.frame)
        self.holding = False
        self._say("resumed", data)
        self._restart(float(data.time))
