"""``render_rollout``: a rollout with prediction, rendered with its overlay into a video."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import mujoco
import numpy as np

from dua_mujoco.core.validate import check_int
from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.progress import Progress
from dua_mujoco.render.frames import OverlayRenderer
from dua_mujoco.render.overlay import OverlayOptions
from dua_mujoco.render.video import check_mp4_size, video_path, write_video
from dua_mujoco.runtime.alarms import Alarms
from dua_mujoco.runtime.predictor import Predictor

__all__ = ["render_rollout"]


def render_rollout(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    predictor: Predictor,
    *,
    steps: int,
    path: str | Path,
    controller: Callable[[mujoco.MjModel, mujoco.MjData], None] | None = None,
    every: int = 5,
    width: int = 320,
    height: int = 240,
    fps: float = 30.0,
    camera: int | str | mujoco.MjvCamera | None = None,
    options: OverlayOptions = OverlayOptions(),
    shadows: bool = False,
    progress: bool = True,
) -> int:
    """Run ``steps`` physics steps with the predictor and write a video of every k-th one.

    The protocol is the predictor's: ``controller``, ``mj_step``; ``predictor.reset`` after the
    first physics step, ``predictor.step`` every ``predictor.period`` steps after that. Frames are
    rendered after physics steps ``every, 2 every, ...`` and streamed to the writer. The offscreen
    buffer is enlarged if the frame does not fit (only ``model.vis`` changes).

    Args:
        data: Its data, at the start state (advanced in place).
        predictor: A predictor of ``model`` (reset here).
        steps: Physics steps to run (>= 1).
        path: Output ``.mp4`` or ``.gif``.
        controller: ``controller(model, data)`` called before every ``mj_step`` (None: no control).
        every: Render every k-th physics step.
        width: Frame width in pixels (even for ``.mp4``).
        height: Frame height in pixels (even for ``.mp4``).
        fps: Frames per second of the video.
        camera: Camera id or name, an ``MjvCamera``, or None for the free camera.
        options: What the overlay draws.
        shadows: Render shadows (slow in software).
        progress: Draw a progress bar on stderr.

    Returns:
        The number of frames written (``steps // every``).

    Raises:
        InvalidInputError: If ``steps`` or ``every`` is < 1, or an ``.mp4`` size is odd.
        InvalidChoiceError: If the suffix of ``path`` or the camera is unknown.
    """
    out = video_path(path)
    steps, every = check_int("steps", steps), check_int("every", every)
    if steps < every:
        raise InvalidInputError(
            f"steps = {steps} < every = {every}: no frame would be rendered; lower every."
        )
    if out.suffix.lower() == ".mp4":
        check_mp4_size(width, height)
    period = predictor.period

    def frames() -> Iterator[np.ndarray]:
        with (
            OverlayRenderer(
                predictor,
                width=width,
                height=height,
                options=options,
                shadows=shadows,
                grow_buffer=True,
            ) as renderer,
            Progress(steps, f"video {out.name}", enabled=progress) as bar,
        ):
            cam = renderer._camera(camera)  # fail before the first physics step
            alarms: Alarms | None = None
            for s in range(1, steps + 1):
                if controller is not None:
                    controller(model, data)
                mujoco.mj_step(model, data)
                if s == 1:
                    alarms = predictor.reset(data)
                elif (s - 1) % period == 0:
                    alarms = predictor.step(data)
                bar.update()
                if s % every == 0:
                    yield renderer.render(data, alarms, camera=cam)

    return write_video(frames(), out, fps=fps)
