"""Alarm overlays on MuJoCo scenes, headless frames and videos.

Colours (docs/rendering.md):

- pure red lines ``(1, 0, 0, 1)``: one per alarmed sphere pair, between the two sphere centres (to
  the plane for a half-space pair). Pure red is reserved for them so that a pixel test finds them.
- geom tint, from the urgency ratio ``tau / horizon`` of a geom's most urgent active sphere pair
  (``horizon`` is the revisit horizon of the pair's DUA bucket): brick red ``(0.9, 0.3, 0.2)``
  when alarmed (ratio < 1), orange within 2 horizons, yellow within 4, the model's own colour
  otherwise. Plane geoms (floors) are never tinted: they would flood the frame.
- translucent covering spheres (``show_spheres``): blue, or the tint of their geom.

Offscreen frames run headless on the CPU with ``MUJOCO_GL=egl`` (Mesa llvmpipe). Shadows are off
by default: they cost most of a software-rendered frame.

Live viewer (``mujoco.viewer.launch_passive``): the viewer draws ``viewer.user_scn`` on top of its
own scene, so connectors and spheres work there, but the model's geoms are not reachable and
cannot be tinted::

    import mujoco, mujoco.viewer
    from dua_mujoco.predictor import Predictor
    from dua_mujoco.render import AlarmOverlay, OverlayOptions
    from dua_mujoco.scenes import load_scene, make_controller

    m, d = load_scene("two_arms")
    p, ctrl = Predictor(m, accel=80.0), make_controller(m, "random")
    overlay = AlarmOverlay(p, options=OverlayOptions(show_spheres=True))
    mujoco.mj_step(m, d)
    alarms = p.reset(d)
    with mujoco.viewer.launch_passive(m, d) as viewer:
        while viewer.is_running():
            ctrl(m, d)
            mujoco.mj_step(m, d)
            alarms = p.step(d)
            with viewer.lock():
                overlay.add_to_user_scn(viewer, d, alarms)
            viewer.sync()
"""

from __future__ import annotations

import dataclasses
import functools
import os
import stat
import tempfile
import warnings
from collections.abc import Callable, Generator, Iterable, Iterator
from pathlib import Path
from types import TracebackType
from typing import Any, BinaryIO

import mujoco
import numpy as np

from dua_mujoco.exceptions import DuaError, InvalidChoiceError, InvalidInputError
from dua_mujoco.predictor import Alarms, Predictor
from dua_mujoco.progress import Progress
from dua_mujoco.state import sphere_centers

__all__ = [
    "ALARM_RGBA",
    "MAX_FRAME_SIZE",
    "AlarmOverlay",
    "OverlayOptions",
    "OverlayRenderer",
    "SceneFullWarning",
    "VideoWriter",
    "check_frame_size",
    "check_mp4_size",
    "read_video",
    "render_rollout",
    "status_line",
    "use_bundled_ffmpeg",
    "video_path",
    "write_video",
]

ALARM_RGBA = (1.0, 0.0, 0.0, 1.0)
"""Colour of alarm connectors, reserved: nothing else the overlay draws is pure red."""

URGENCY_LEVELS = (1.0, 2.0, 4.0)
"""Upper bounds of ``tau / horizon`` for the tints alarmed, urgent, soon (then neutral)."""

TINTS = np.array([[0.9, 0.3, 0.2], [1.0, 0.55, 0.1], [0.95, 0.85, 0.25]], dtype=np.float32)
"""``(3, 3)`` RGB of the levels alarmed, urgent, soon."""

SPHERE_RGB = (0.3, 0.7, 1.0)
"""Colour of covering spheres whose geom is not urgent."""

VIDEO_SUFFIXES = (".mp4", ".gif")

MAX_FRAME_SIZE = 4096
"""Largest frame side ``grow_buffer`` enlarges the offscreen buffer to (4096x4096 RGBA is 64 MB;
a larger framebuffer may exceed the GL implementation's renderbuffer limit)."""

_OBJ_GEOM = int(mujoco.mjtObj.mjOBJ_GEOM)
_OBJ_UNKNOWN = int(mujoco.mjtObj.mjOBJ_UNKNOWN)
_CAT_DECOR = int(mujoco.mjtCatBit.mjCAT_DECOR)
_GEOM_LINE = int(mujoco.mjtGeom.mjGEOM_LINE)
_GEOM_SPHERE = int(mujoco.mjtGeom.mjGEOM_SPHERE)
_GEOM_PLANE = int(mujoco.mjtGeom.mjGEOM_PLANE)
_RND_SHADOW = int(mujoco.mjtRndFlag.mjRND_SHADOW)
_EYE = np.eye(3).ravel()
_ZERO3 = np.zeros(3)


class SceneFullWarning(UserWarning):
    """The ``MjvScene`` had no room left (``maxgeom``): some overlay geoms were not drawn."""


@dataclasses.dataclass(frozen=True)
class OverlayOptions:
    """What :class:`AlarmOverlay` draws.

    Attributes:
        show_spheres: Draw the covering spheres (one scene geom per sphere).
        sphere_alpha: Opacity of the covering spheres, in ``(0, 1]``.
        tint_geoms: Recolour model geoms by urgency (offscreen only; see module docstring).
        connectors: Draw a pure red line for each alarmed sphere pair.
        text: Stamp a status line (time, alarms, misses) on rendered frames.
        connector_width: Width of connector lines in pixels (``mjGEOM_LINE`` widths are pixels).
    """

    show_spheres: bool = False
    sphere_alpha: float = 0.25
    tint_geoms: bool = True
    connectors: bool = True
    text: bool = True
    connector_width: float = 3.0

    def __post_init__(self) -> None:
        if not 0.0 < self.sphere_alpha <= 1.0:
            raise InvalidInputError(
                f"sphere_alpha = {self.sphere_alpha!r} is invalid: it must be in (0, 1]."
            )
        if not self.connector_width > 0.0:
            raise InvalidInputError(
                f"connector_width = {self.connector_width!r} is invalid: it must be > 0 pixels."
            )


class AlarmOverlay:
    """Adds a predictor's alarms to an ``MjvScene`` (offscreen renderer or live viewer).

    Args:
        predictor: The predictor whose alarms and scheduler state are drawn.
        options: What to draw.

    Attributes:
        dropped: Overlay geoms dropped so far because the scene was full.
    """

    def __init__(self, predictor: Predictor, *, options: OverlayOptions = OverlayOptions()) -> None:
        self.predictor = predictor
        self.options = options
        self.dropped = 0
        self._warned = False
        model = predictor.model
        cov = predictor.covering
        pairs = predictor.pairs
        sgeom = np.asarray(cov.sphere_geom, dtype=np.int64)
        planes = np.asarray(cov.plane_geom, dtype=np.int64)
        first = np.asarray(pairs.first, dtype=np.int64)
        second = np.asarray(pairs.second, dtype=np.int64)
        half = np.asarray(pairs.halfspace, dtype=bool)
        self._second = second
        self._half = half
        # Same geoms as Predictor's private pair tables, rebuilt from public fields.
        self._pair_geom1 = sgeom[first]
        self._pair_geom2 = np.where(
            half,
            planes[np.where(half, second, 0)] if planes.size else -1,
            sgeom[np.where(half, 0, second)],
        )
        self._all_pairs = np.arange(first.shape[0], dtype=np.int64)
        self._tintable = np.asarray(model.geom_type) != _GEOM_PLANE

    # ------------------------------------------------------------------- urgency

    def geom_urgency(self) -> np.ndarray:
        """Urgency ratio of every geom.

        Returns:
            ``(ngeom,)`` float64: the minimum over the geom's active sphere pairs of
            ``last_tau / horizon[bucket]`` (``< 1`` means alarmed); ``inf`` for geoms without
            active pairs, and for all geoms before ``predictor.reset``.
        """
        out = np.full(self.predictor.model.ngeom, np.inf)
        sched = self.predictor.scheduler
        if sched is None or self._all_pairs.size == 0:
            return out
        horizon = sched.horizon[sched.bucket(self._all_pairs)]
        ratio = np.where(sched.active, sched.last_tau / horizon, np.inf)
        np.minimum.at(out, self._pair_geom1, ratio)
        valid = self._pair_geom2 >= 0
        np.minimum.at(out, self._pair_geom2[valid], ratio[valid])
        return out

    def geom_levels(self) -> np.ndarray:
        """``(ngeom,)`` int urgency level per geom: 0 alarmed, 1 urgent, 2 soon, 3 neutral."""
        return np.searchsorted(np.asarray(URGENCY_LEVELS), self.geom_urgency(), side="right")

    # ------------------------------------------------------------------- scene

    def add_to_scene(
        self, scene: mujoco.MjvScene, data: mujoco.MjData, alarms: Alarms | None
    ) -> int:
        """Tint the scene's model geoms and append connectors and spheres.

        Call it after ``mjv_updateScene`` (``Renderer.update_scene``) and before rendering. Geoms
        are appended at ``scene.ngeom`` until ``scene.maxgeom``; connectors go first, as they
        matter most when room is short.

        Args:
            scene: The scene to modify in place.
            data: The ``MjData`` the predictor read (sphere centres come from ``geom_xpos``).
            alarms: The alarms to draw (None: none, e.g. before ``reset``).

        Returns:
            The number of overlay geoms dropped because the scene was full (also added to
            :attr:`dropped`; the first drop warns with :class:`SceneFullWarning`).
        """
        opts = self.options
        levels = self.geom_levels()
        if opts.tint_geoms:
            self._tint(scene, levels)
        dropped = 0
        if opts.connectors and alarms is not None and len(alarms):
            start, end = self._connector_ends(data, alarms)
            dropped += self._add_connectors(scene, start, end)
        if opts.show_spheres and self.predictor.nsphere:
            dropped += self._add_spheres(scene, data, levels)
        if dropped:
            self.dropped += dropped
            if not self._warned:
                self._warned = True
                warnings.warn(
                    f"the MjvScene is full (maxgeom = {scene.maxgeom}): {dropped} overlay geom(s) "
                    "were not drawn. Pass a larger max_geom to OverlayRenderer (or "
                    "mujoco.MjvScene(model, maxgeom=...)), or hide the covering spheres.",
                    SceneFullWarning,
                    stacklevel=2,
                )
        return dropped

    def add_to_user_scn(self, viewer: Any, data: mujoco.MjData, alarms: Alarms | None) -> int:
        """Replace the overlay in a passive viewer's ``user_scn`` (call before ``viewer.sync()``).

        The user scene holds only the overlay, so tinting does nothing there.

        Args:
            viewer: The handle of ``mujoco.viewer.launch_passive``.
            data: The ``MjData`` the predictor read.
            alarms: The alarms to draw.

        Returns:
            The number of overlay geoms dropped (see :meth:`add_to_scene`).
        """
        scn = getattr(viewer, "user_scn", None)
        if scn is None:
            raise InvalidInputError(
                f"{type(viewer).__name__} has no user_scn: pass the handle returned by "
                "mujoco.viewer.launch_passive(model, data)."
            )
        scn.ngeom = 0
        return self.add_to_scene(scn, data, alarms)

    def _tint(self, scene: mujoco.MjvScene, levels: np.ndarray) -> None:
        tint = (levels < len(URGENCY_LEVELS)) & self._tintable
        if not tint.any():
            return
        geoms = scene.geoms
        # The bindings expose scene geoms as structs, not arrays: one pass over the scene's
        # geoms (about ngeom, microseconds) is the only way to find a model geom's scene slot.
        for i in range(scene.ngeom):
            g = geoms[i]
            if g.objtype == _OBJ_GEOM and tint[g.objid]:
                g.rgba[:3] = TINTS[levels[g.objid]]

    def _connector_ends(self, data: mujoco.MjData, alarms: Alarms) -> tuple[np.ndarray, np.ndarray]:
        cov = self.predictor.covering
        pairs = np.asarray(alarms.pairs, dtype=np.int64)
        half = self._half[pairs]
        second = self._second[pairs]
        start = sphere_centers(
            data.geom_xpos, data.geom_xmat, cov.sphere_geom, cov.sphere_offset, alarms.sphere1
        )
        end = sphere_centers(
            data.geom_xpos,
            data.geom_xmat,
            cov.sphere_geom,
            cov.sphere_offset,
            np.where(half, 0, second),
        )
        if half.any():
            normals, offsets = self.predictor.halfspaces(data)
            n = normals[second[half]]
            height = np.einsum("ij,ij->i", n, start[half]) - offsets[second[half]]
            end[half] = start[half] - height[:, None] * n
        return start, end

    def _add_connectors(self, scene: mujoco.MjvScene, start: np.ndarray, end: np.ndarray) -> int:
        rgba = np.asarray(ALARM_RGBA, dtype=np.float32)
        width = float(self.options.connector_width)
        for j in range(start.shape[0]):
            g = self._new_geom(scene, _GEOM_LINE, _ZERO3, _ZERO3, rgba)
            if g is None:
                return start.shape[0] - j
            mujoco.mjv_connector(g, _GEOM_LINE, width, start[j], end[j])
        return 0

    def _add_spheres(self, scene: mujoco.MjvScene, data: mujoco.MjData, levels: np.ndarray) -> int:
        cov = self.predictor.covering
        centres = sphere_centers(data.geom_xpos, data.geom_xmat, cov.sphere_geom, cov.sphere_offset)
        nsphere = centres.shape[0]
        room = max(scene.maxgeom - scene.ngeom, 0)
        lvl = levels[np.asarray(cov.sphere_geom)]
        rgba = np.empty((nsphere, 4), dtype=np.float32)
        rgba[:, :3] = np.where(
            (lvl < len(URGENCY_LEVELS))[:, None],
            TINTS[np.minimum(lvl, len(URGENCY_LEVELS) - 1)],
            SPHERE_RGB,
        )
        rgba[:, 3] = self.options.sphere_alpha
        size = np.zeros((nsphere, 3))
        size[:, 0] = cov.sphere_radius
        # One mjv_initGeom per drawn sphere is inherent to the MjvScene API.
        for i in range(min(nsphere, room)):
            self._new_geom(scene, _GEOM_SPHERE, size[i], centres[i], rgba[i])
        return nsphere - min(nsphere, room)

    @staticmethod
    def _new_geom(
        scene: mujoco.MjvScene, kind: int, size: np.ndarray, pos: np.ndarray, rgba: np.ndarray
    ) -> mujoco.MjvGeom | None:
        if scene.ngeom >= scene.maxgeom:
            return None
        g = scene.geoms[scene.ngeom]
        mujoco.mjv_initGeom(g, kind, size, pos, _EYE, rgba)
        # mjv_initGeom leaves these fields as they were; stale values would make an overlay geom
        # pass for a model geom (tinting, segmentation) or cast shadows.
        g.objtype = _OBJ_UNKNOWN
        g.objid = -1
        g.category = _CAT_DECOR
        g.segid = -1
        g.castshadow = False
        scene.ngeom += 1
        return g


# ----------------------------------------------------------------------------- offscreen


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
    for name, value in (("width", width), ("height", height)):
        if not isinstance(value, int | np.integer) or value < 1:
            raise InvalidInputError(f"{name} = {value!r} is invalid: it must be an int >= 1.")
    vis = model.vis.global_
    if width <= vis.offwidth and height <= vis.offheight:
        return
    if grow_buffer:
        if max(width, height) > MAX_FRAME_SIZE:
            raise InvalidInputError(
                f"a {width}x{height} frame is larger than this package renders "
                f"({MAX_FRAME_SIZE} pixels a side, the model's offscreen buffer is "
                f"{vis.offwidth}x{vis.offheight}): pass a width and height of at most "
                f"{MAX_FRAME_SIZE}, or raise the model's buffer with <visual><global "
                f'offwidth="{max(width, vis.offwidth)}" offheight="{max(height, vis.offheight)}"'
                "/></visual> if your GL allows it."
            )
        vis.offwidth = max(int(vis.offwidth), int(width))
        vis.offheight = max(int(vis.offheight), int(height))
        return
    raise InvalidInputError(
        f"a {width}x{height} frame does not fit the model's offscreen buffer "
        f"({vis.offwidth}x{vis.offheight}): render at most that size, add "
        f'<visual><global offwidth="{max(width, vis.offwidth)}" '
        f'offheight="{max(height, vis.offheight)}"/></visual> to the model, or pass '
        "grow_buffer=True."
    )


@functools.lru_cache(maxsize=8)
def _font(size: int) -> Any:
    from PIL import ImageFont

    return ImageFont.load_default(size=size)


def status_line(time: float, nalarms: int, misses: int | None = None) -> str:
    """The default text of a frame: ``"t = 1.234 s  alarms 3  missed 0"``."""
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


class OverlayRenderer:
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
            nalarms = 0 if alarms is None else len(alarms)
            frame = _stamp_text(
                frame, status_line(data.time, nalarms, misses) if text is None else text
            )
        return frame

    def close(self) -> None:
        """Free the GL context (idempotent)."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __enter__(self) -> OverlayRenderer:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


# ----------------------------------------------------------------------------- video


def video_path(path: str | os.PathLike[str]) -> Path:
    """Check that a video path names a format :class:`VideoWriter` writes.

    Args:
        path: The output file; its suffix (``.mp4`` or ``.gif``, any case) picks the format.

    Returns:
        ``path`` as a ``Path``.

    Raises:
        InvalidChoiceError: If the suffix is not ``.mp4`` or ``.gif``.
    """
    p = Path(path)
    if p.suffix.lower() not in VIDEO_SUFFIXES:
        raise InvalidChoiceError(
            "video format", p.suffix or p.name, VIDEO_SUFFIXES, "Name the file e.g. 'out.mp4'."
        )
    return p


def check_mp4_size(width: int, height: int) -> None:
    """Refuse a frame size an ``.mp4`` cannot hold (H.264 in yuv420p needs even sides).

    Args:
        width: Frame width in pixels.
        height: Frame height in pixels.

    Raises:
        InvalidInputError: If ``width`` or ``height`` is odd (the message gives the nearest even
            size).
    """
    if width % 2 or height % 2:
        raise InvalidInputError(
            f"an .mp4 (H.264, yuv420p) needs even frame sizes; got {width}x{height}: use e.g. "
            f"{width + width % 2}x{height + height % 2}, or write a .gif."
        )


def use_bundled_ffmpeg() -> Any:
    """Point mediapy at imageio-ffmpeg's ffmpeg and return the ``mediapy`` module.

    There may be no ffmpeg on PATH, and a newer system ffmpeg writes files mediapy cannot read
    back, so this package reads and writes with the bundled one.
    """
    import imageio_ffmpeg
    import mediapy

    mediapy.set_ffmpeg(imageio_ffmpeg.get_ffmpeg_exe())
    return mediapy


def _configure_mediapy() -> None:
    """Give mediapy the bundled ffmpeg unless the user already chose one.

    Without it ``mediapy.read_video`` fails on a machine without ffmpeg on PATH, so the
    package's own videos could not be read back with plain mediapy. mediapy has no public
    getter: its config keeps the default ``'ffmpeg'`` until ``mediapy.set_ffmpeg`` is called.
    """
    try:
        import mediapy
    except ImportError:  # pragma: no cover - a dependency; nothing to configure without it
        return
    config = getattr(mediapy, "_config", None)
    if getattr(config, "ffmpeg_name_or_path", "ffmpeg") == "ffmpeg":
        use_bundled_ffmpeg()


_configure_mediapy()


def read_video(path: str | os.PathLike[str]) -> np.ndarray:
    """Read a video written by ``write_video`` back as ``(frames, H, W, 3)`` uint8."""
    return np.asarray(use_bundled_ffmpeg().read_video(str(path)))


def _writes_in_place(path: Path) -> bool:
    """True for a path that is written through, never replaced: a symlink, device or FIFO."""
    try:
        mode = os.lstat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):
        return False
    return not stat.S_ISREG(mode)


class VideoWriter:
    """Streams RGB frames into an ``.mp4`` or a ``.gif`` as they come (use ``with``).

    Each frame goes to the encoder when it is added, so memory stays flat however long the
    video: an ``.mp4`` is piped to imageio-ffmpeg's bundled ffmpeg (H.264, yuv420p), a ``.gif``
    is encoded frame by frame with Pillow (a 256-colour palette per frame, and only the rectangle
    that changed since the previous frame). The video goes to a temporary file beside ``path``
    that replaces ``path`` when the writer closes, also when it closes on an exception: a Ctrl-C
    leaves a playable video of the frames added so far, and never half a file. A symlink, device
    or FIFO at ``path`` is written in place, not replaced.

    Args:
        path: Output file; the suffix picks the format. Parent folders are created.
        fps: Frames per second (GIF delays are whole centiseconds: at most 100, browsers slow
            anything above 50).

    Attributes:
        path: The output file.
        count: Frames written so far.

    Raises:
        InvalidChoiceError: If the suffix is not ``.mp4`` or ``.gif``.
        InvalidInputError: If ``fps <= 0``.
    """

    def __init__(self, path: str | os.PathLike[str], *, fps: float = 30.0) -> None:
        self.path = video_path(path)
        if not fps > 0:
            raise InvalidInputError(f"fps = {fps!r} is invalid: it must be > 0.")
        self.fps = float(fps)
        self.count = 0
        self._gif = self.path.suffix.lower() == ".gif"
        self._shape: tuple[int, ...] | None = None
        self._tmp: Path | None = None
        self._file: BinaryIO | None = None
        self._ffmpeg: Generator[None, Any, None] | None = None
        self._prev: np.ndarray | None = None
        self._closed = False

    def add(self, frame: np.ndarray) -> None:
        """Encode one ``(H, W, 3)`` uint8 RGB frame (the first fixes the size).

        Raises:
            InvalidInputError: If the frame is not ``(H, W, 3)``, differs in shape from the first,
                or an ``.mp4`` frame has an odd side.
            DuaError: If the writer is closed.
        """
        if self._closed:
            raise DuaError(f"the VideoWriter of {str(self.path)!r} is closed: open a new one.")
        f = np.asarray(frame)
        if self._shape is None:
            if f.ndim != 3 or f.shape[2] != 3:
                raise InvalidInputError(
                    f"frames must be (H, W, 3) RGB arrays; got shape {f.shape}."
                )
            if not self._gif:
                check_mp4_size(f.shape[1], f.shape[0])
            self._open(f.shape)
        elif f.shape != self._shape:
            raise InvalidInputError(
                f"frame {self.count} has shape {f.shape}; frame 0 has {self._shape}."
            )
        f = np.ascontiguousarray(f, dtype=np.uint8)
        if self._gif:
            self._add_gif(f)
        else:
            assert self._ffmpeg is not None
            self._ffmpeg.send(f)
        self.count += 1

    def _open(self, shape: tuple[int, ...]) -> None:
        self._shape = shape
        target = self.path
        if not _writes_in_place(self.path):
            self.path.parent.mkdir(parents=True, exist_ok=True)
            fd, name = tempfile.mkstemp(
                dir=self.path.parent, prefix=f".{self.path.stem}.", suffix=self.path.suffix
            )
            os.close(fd)
            # mkstemp makes the file private (0600): give it the mode a plain open would.
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(name, 0o666 & ~umask)
            self._tmp = target = Path(name)
        if self._gif:
            self._file = open(target, "wb")  # noqa: SIM115 - closed by close()
            return
        import imageio_ffmpeg

        # Not mediapy.VideoWriter: imageio-ffmpeg starts ffmpeg in its own process group, so a
        # Ctrl-C in the terminal reaches only Python, and closing the pipe still finishes the file.
        self._ffmpeg = imageio_ffmpeg.write_frames(
            str(target),
            (shape[1], shape[0]),
            fps=self.fps,
            codec="libx264",
            pix_fmt_out="yuv420p",
            quality=None,
            macro_block_size=1,
            ffmpeg_log_level="error",
            output_params=["-qp", "20" if shape[0] * shape[1] <= 640 * 480 else "28", "-f", "mp4"],
        )
        self._ffmpeg.send(None)

    def _add_gif(self, f: np.ndarray) -> None:
        from PIL import GifImagePlugin, Image

        assert self._file is not None
        prev = self._prev
        x0, y0, x1, y1 = 0, 0, f.shape[1], f.shape[0]
        if prev is not None:
            changed = np.any(f != prev, axis=2)
            rows = np.flatnonzero(changed.any(axis=1))
            cols = np.flatnonzero(changed.any(axis=0))
            # An unchanged frame still needs an image block to carry its delay: one pixel.
            x0, y0, x1, y1 = (
                (int(cols[0]), int(rows[0]), int(cols[-1]) + 1, int(rows[-1]) + 1)
                if rows.size
                else (0, 0, 1, 1)
            )
        # Fast octree without dithering: the fastest palette, and pure red stays pure red.
        img = Image.fromarray(f[y0:y1, x0:x1]).quantize(
            colors=256, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE
        )
        if prev is None:
            header, _ = GifImagePlugin.getheader(img, None, {"loop": 0})
            self._file.writelines(header)
        self._file.writelines(
            GifImagePlugin.getdata(
                img,
                offset=(x0, y0),
                duration=max(10, round(1000.0 / self.fps)),
                disposal=1,  # keep the previous frame under the changed rectangle
                include_color_table=True,
            )
        )
        self._file.flush()  # each frame on disk as it comes, as the .mp4 pipe does
        self._prev = f.copy()

    def close(self) -> None:
        """Finish the file and move it into place (idempotent).

        With no frame added nothing is written and ``path`` is left as it was.
        """
        if self._closed:
            return
        self._closed = True
        try:
            if self._file is not None:
                if self.count:
                    self._file.write(b";")  # the GIF trailer
                self._file.close()
            if self._ffmpeg is not None:
                self._ffmpeg.close()
        except BaseException:
            self._discard()
            raise
        if self._tmp is not None:
            if self.count:
                os.replace(self._tmp, self.path)
            else:
                self._discard()

    def _discard(self) -> None:
        if self._tmp is not None:
            self._tmp.unlink(missing_ok=True)
            self._tmp = None

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def write_video(
    frames: Iterable[np.ndarray], path: str | os.PathLike[str], *, fps: float = 30.0
) -> int:
    """Write RGB frames to an ``.mp4`` (H.264 via imageio-ffmpeg's ffmpeg) or a ``.gif``.

    Frames are consumed and encoded one at a time (:class:`VideoWriter`), so a generator keeps
    memory flat for both formats.

    Args:
        frames: ``(H, W, 3)`` uint8 frames, all the same size.
        path: Output file; the suffix picks the format. Parent folders are created.
        fps: Frames per second (GIF delays are whole centiseconds: at most 100, browsers slow
            anything above 50).

    Returns:
        The number of frames written.

    Raises:
        InvalidChoiceError: If the suffix is not ``.mp4`` or ``.gif``.
        InvalidInputError: If there are no frames, ``fps <= 0``, frames differ in shape, or an
            ``.mp4`` frame size is odd.
    """
    with VideoWriter(path, fps=fps) as writer:
        for f in frames:
            writer.add(f)
        if not writer.count:
            raise InvalidInputError(f"no frames to write to {str(writer.path)!r}.")
        return writer.count


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
        model: The model.
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
    for name, value in (("steps", steps), ("every", every)):
        if not isinstance(value, int | np.integer) or value < 1:
            raise InvalidInputError(f"{name} = {value!r} is invalid: it must be an int >= 1.")
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
