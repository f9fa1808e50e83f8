"""``OverlayRenderer``: headless frames of a scene with its alarm overlay, and their limits.

Offscreen frames run headless on the CPU with ``MUJOCO_GL=egl`` (Mesa llvmpipe). Shadows are off
by default: they cost most of a software-rendered frame.
"""

from __future__ import annotations

import functools
from typing import Any

import mujoco
import numpy as np

from dua_mujoco.closing import Closing
from dua_mujoco.core.validate import check_int
from dua_mujoco.exceptions import DuaError, InvalidChoiceError, InvalidInputError
from dua_mujoco.render.overlay import AlarmOverlay, OverlayOptions
from dua_mujoco.runtime.alarms import Alarms
from dua_mujoco.runtime.predictor import Predictor

__all__ = ["MAX_FRAME_SIZE", "OverlayRenderer", "check_frame_size", "status_line"]

MAX_FRAME_SIZE = 4096
"""Largest frame side ``grow_buffer`` enlarges the offscreen buffer to (4096x4096 RGBA is 64 MB;
a larger framebuffer may exceed the GL implementation's renderbuffer limit)."""

_RND_SHADOW = int(mujoco.mjtRndFlag.mjRND_SHADOW)


def check_frame_size(model: mujoco.MjModel, width: int, height: int, *, grow_buffer: bool) -> None:
    """Refuse a frame size the offscreen framebuffer cannot hold, before anything is rendered.

    ``mujoco.Renderer`` needs ``width <= model.vis.global_.offwidth`` and ``height <=
    offheight``, and the GL implementation caps the framebuffer (beyond its limit MuJoCo fails
    with "Offscreen framebuffer is not complete").

    Args:
        model: The model to render (with ``grow_buffer`` its ``vis.global_`` is enlarged in place:
            only the offscreen buffer size changes, nothing physical).
        width: Frame width in pixels.
        height: Frame height in pixels.
        grow_buffer: Enlarge ``offwidth``/``offheight`` to fit, up to :data:`MAX_FRAME_SIZE`,
            instead of refusing a frame larger than they are.

    Raises:
        InvalidInputError: If a side is not an int >= 1, exceeds the buffer (and not
            ``grow_buffer``), or exceeds :data:`MAX_FRAME_SIZE` beyond the model's own buffer.
    """
    width, height = check_int("width", width), check_int("height", height)
    vis = model.vis.global_
    if width <= vis.offwidth and height <= vis.offheight:
        return
    w, h = max(width, vis.offwidth), max(height, vis.offheight)
    xml = f'<visual><global offwidth="{w}" offheight="{h}"/></visual>'
    if grow_buffer:
        if max(width, height) > MAX_FRAME_SIZE:
            raise InvalidInputError(
                f"a {width}x{height} frame is larger than this package renders "
                f"({MAX_FRAME_SIZE} pixels a side, the model's offscreen buffer is "
                f"{vis.offwidth}x{vis.offheight}): pass a width and height of at most "
                f"{MAX_FRAME_SIZE}, or raise the model's buffer with {xml} if your GL allows it."
            )
        vis.offwidth, vis.offheight = int(w), int(h)
        return
    raise InvalidInputError(
        f"a {width}x{height} frame does not fit the model's offscreen buffer "
        f"({vis.offwidth}x{vis.offheight}): render at most that size, add {xml} to the model, "
        "or pass grow_buffer=True."
    )


@functools.lru_cache(maxsize=8)
def _font(size: int) -> Any:
    from PIL import ImageFont

    return ImageFont.load_default(size=size)


def status_line(time: float, nalarms: int, misses: int | None = None) -> str:
    """The default text of a frame: ``"t = 1.234 s  alarms 3  missed 0"`` (``nalarms``: the
    sphere pairs standing in alarm)."""
    line = f"t = {time:.3f} s  alarms {nalarms}"
    return line if misses is None else f"{line}  missed {misses}"


def _stamp_text(frame: np.ndarray, text: str) -> np.ndarray:
    from PIL import Image, ImageDraw

    height = frame.shape[0]
    size = max(8, round(height / 18))
    pad = max(1, size // 4)
    # Darken a strip rather than draw a box: legible on any background, and never pure red.
    strip = min(height, size + 2 * pad + 2)
    frame[:strip] = (frame[:strip] * 0.35).astype(np.uint8)
    img = Image.fromarray(frame)
    ImageDraw.Draw(img).text((pad, pad), text, fill=(255, 255, 255), font=_font(size))
    return np.asarray(img)


class OverlayRenderer(Closing):
    """Offscreen frames with the alarm overlay (a resource: use ``with`` or call ``close()``).

    Args:
        predictor: The predictor whose model is rendered and whose alarms are drawn.
        width: Frame width in pixels.
        height: Frame height in pixels.
        options: What the overlay draws.
        shadows: Render shadows (about 3x slower in software rendering).
        max_geom: Capacity of the scene, model geoms and overlay geoms together.
        grow_buffer: Enlarge ``model.vis.global_.offwidth/offheight`` when the frame does not fit
            (up to :data:`MAX_FRAME_SIZE`), instead of raising.

    Raises:
        InvalidInputError: If the frame does not fit the offscreen buffer (see
            :func:`check_frame_size`) or the GL context, or a size is not a positive int.
    """

    def __init__(
        self,
        predictor: Predictor,
        *,
        width: int = 320,
        height: int = 240,
        options: OverlayOptions = OverlayOptions(),
        shadows: bool = False,
        max_geom: int = 10_000,
        grow_buffer: bool = False,
    ) -> None:
        self._renderer: mujoco.Renderer | None = None
        model = predictor.model
        check_frame_size(model, width, height, grow_buffer=grow_buffer)
        self.model = model
        self.overlay = AlarmOverlay(predictor, options=options)
        try:
            self._renderer = mujoco.Renderer(model, height=height, width=width, max_geom=max_geom)
        except mujoco.FatalError as exc:
            # A buffer the model allows but the GL implementation does not (its renderbuffer
            # limit): MuJoCo's message names neither the size nor the fix.
            raise InvalidInputError(
                f"the GL context cannot hold a {width}x{height} offscreen framebuffer "
                f"({' '.join(str(exc).split())}): render a smaller frame."
            ) from None
        self._renderer.scene.flags[_RND_SHADOW] = int(shadows)

    @property
    def width(self) -> int:
        """Frame width in pixels."""
        return int(self._require().width)

    @property
    def height(self) -> int:
        """Frame height in pixels."""
        return int(self._require().height)

    @property
    def scene(self) -> mujoco.MjvScene:
        """The scene of the last frame (model geoms, then overlay geoms)."""
        return self._require().scene

    @property
    def closed(self) -> bool:
        """True once :meth:`close` ran."""
        return self._renderer is None

    def _require(self) -> mujoco.Renderer:
        if self._renderer is None:
            raise DuaError("this OverlayRenderer is closed: create a new one to render.")
        return self._renderer

    def _camera(self, camera: int | str | mujoco.MjvCamera | None) -> int | mujoco.MjvCamera:
        if camera is None:
            return -1
        if isinstance(camera, mujoco.MjvCamera):
            return camera
        names = [self.model.camera(i).name or str(i) for i in range(self.model.ncam)]
        if isinstance(camera, str):
            cid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
            valid = cid >= 0
        else:
            cid = int(camera)
            valid = -1 <= cid < self.model.ncam
        if not valid:
            raise InvalidChoiceError(
                "camera", camera, [-1, *names], "Use -1 or None for the free camera."
            )
        return cid

    def render(
        self,
        data: mujoco.MjData,
        alarms: Alarms | None,
        *,
        camera: int | str | mujoco.MjvCamera | None = None,
        text: str | None = None,
        misses: int | None = None,
    ) -> np.ndarray:
        """Render one frame of ``data`` with the overlay.

        Args:
            data: The state to draw (kinematics as computed by the last ``mj_step``/``mj_forward``).
            alarms: The predictor's latest alarms (None: no connectors).
            camera: Camera id or name from the model, an ``MjvCamera``, or None (free camera).
            text: The status line; None for :func:`status_line` of ``data.time`` and ``alarms``.
            misses: Missed contacts so far, shown in the default status line when given.

        Returns:
            ``(height, width, 3)`` uint8 RGB frame.
        """
        r = self._require()
        r.update_scene(data, camera=self._camera(camera))
        self.overlay.add_to_scene(r.scene, data, alarms)
        frame = r.render()
        if self.overlay.options.text:
            nalarms = 0 if alarms is None else int(self.overlay.standing.size)
            frame = _stamp_text(
                frame, status_line(data.time, nalarms, misses) if text is None else text
            )
        return frame

    def close(self) -> None:
        """Free the GL context (idempotent)."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


# ----------------------------------------------------------------------------- video
