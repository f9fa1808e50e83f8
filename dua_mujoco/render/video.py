"""Videos: frames streamed to the encoder as they come, written atomically, read back."""

from __future__ import annotations

import os
from collections.abc import Generator, Iterable
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from dua_mujoco.closing import Closing
from dua_mujoco.exceptions import DuaError, InvalidChoiceError, InvalidInputError
from dua_mujoco.outputs import publish, temporary_beside, writes_in_place

__all__ = [
    "VIDEO_SUFFIXES",
    "VideoWriter",
    "check_mp4_size",
    "read_video",
    "use_bundled_ffmpeg",
    "video_path",
    "write_video",
]

VIDEO_SUFFIXES = (".mp4", ".gif")


def video_path(path: str | os.PathLike[str]) -> Path:
    """``path`` as a ``Path``, checked to name a format :class:`VideoWriter` writes: its suffix
    (``.mp4`` or ``.gif``, any case) picks the format.

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
    """Refuse a frame size (pixels) an ``.mp4`` cannot hold (H.264 in yuv420p needs even sides).

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


class VideoWriter(Closing):
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
        if not writes_in_place(self.path):
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._tmp = target = temporary_beside(self.path, self.path.suffix)
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
                publish(self._tmp, self.path)
            else:
                self._discard()

    def _discard(self) -> None:
        if self._tmp is not None:
            self._tmp.unlink(missing_ok=True)
            self._tmp = None


def write_video(
    frames: Iterable[np.ndarray], path: str | os.PathLike[str], *, fps: float = 30.0
) -> int:
    """Write RGB frames to an ``.mp4`` (H.264 via imageio-ffmpeg's ffmpeg) or a ``.gif``.

    Frames are consumed and encoded one at a time (:class:`VideoWriter`), so a generator keeps
    memory flat for both formats. ``frames``: ``(H, W, 3)`` uint8, all the same size; ``path``
    and ``fps`` as :class:`VideoWriter`'s.

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
