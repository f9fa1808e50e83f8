"""A virtual X display for tests of windows: Xvfb, its screen as pixels, keys typed into it.

Xvfb (Debian's ``xvfb``) keeps its screen in a file under ``-fbdir`` in XWD format, so a
screenshot is a read of that file: no screenshot tool. Keys are typed with ``xdotool`` (XTEST).
Both are optional system packages: a test that needs them (the ``display`` and ``xvfb`` fixtures
of ``conftest.py``) is skipped, with the apt line, where they are not installed, and fails instead
under ``DUA_REQUIRE_XVFB=1``, which ``.ci/run`` (it installs them) sets.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

__all__ = [
    "APT_LINE",
    "REQUIRE_XVFB",
    "Display",
    "ctrl_c_able",
    "reddish",
    "require_xvfb",
    "virtual_display",
]

APT_LINE = "apt-get install xvfb xdotool"
"""What installs the tools (Debian, Ubuntu)."""

REQUIRE_XVFB = "DUA_REQUIRE_XVFB"
"""Set to 1 (CI), a missing tool fails the tests that need it instead of skipping them."""

_TOOLS = ("Xvfb", "xdotool")


def ctrl_c_able(argv: list[str]) -> list[str]:
    """``argv`` run with Ctrl-C (SIGINT) at its default, for the tests that send it one. A
    background job of a shell without job control (``pytest ... &`` in a script) starts with
    SIGINT ignored, and an ignored signal stays ignored across ``exec``: the command would leave
    it ignored (it takes over only a default Ctrl-C) and run on. Set to the default here, it
    stays the default across the ``exec`` into ``argv``."""
    reset = "import os, signal, sys; signal.signal(signal.SIGINT, signal.SIG_DFL); "
    return [sys.executable, "-c", reset + "os.execv(sys.argv[1], sys.argv[1:])", *argv]


class Display:
    """A running Xvfb: its ``name`` (``":N"``) and its screen."""

    def __init__(self, name: str, framebuffer: Path) -> None:
        self.name = name
        self.framebuffer = framebuffer

    def env(self) -> dict[str, str]:
        """The environment of a process that opens its windows here."""
        return {**os.environ, "DISPLAY": self.name}

    def screenshot(self) -> np.ndarray:
        """``(height, width, 3)`` uint8 RGB of the whole screen now."""
        return read_xwd(self.framebuffer.read_bytes())

    def key(self, *keys: str) -> None:
        """Type keys (X keysym names: ``space``, ``Return``, ``Right``) into the focused window."""
        subprocess.run(["xdotool", "key", *keys], env=self.env(), check=True, timeout=30)

    def wait_for(
        self, condition: Callable[[np.ndarray], bool], *, timeout: float = 120.0
    ) -> np.ndarray:
        """The first screenshot for which ``condition`` holds (polled; fails after ``timeout``
        seconds, a bound against a hang, not a measurement)."""
        deadline = time.monotonic() + timeout
        while True:
            shot = self.screenshot()
            if condition(shot):
                return shot
            if time.monotonic() > deadline:
                raise AssertionError(f"no screenshot met the condition in {timeout:.0f} s")
            time.sleep(0.2)


def read_xwd(raw: bytes) -> np.ndarray:
    """RGB pixels of an XWD image (TrueColor, 32 bits per pixel, as Xvfb's ``-fbdir`` keeps)."""
    header = np.frombuffer(raw[:100], dtype=">u4")
    header_size, width, height = int(header[0]), int(header[4]), int(header[5])
    byte_order, bits_per_pixel, bytes_per_line = int(header[7]), int(header[11]), int(header[12])
    ncolors = int(header[19])
    assert bits_per_pixel == 32, f"{bits_per_pixel} bits per pixel: start Xvfb with depth 24"
    start = header_size + 12 * ncolors  # the header, then ncolors 12-byte colormap entries
    rows = np.frombuffer(raw[start : start + bytes_per_line * height], dtype=np.uint8)
    pixels = rows.reshape(height, bytes_per_line)[:, : 4 * width].reshape(height, width, 4)
    # LSBFirst (0): each pixel is B, G, R, unused; MSBFirst: unused, R, G, B.
    return np.ascontiguousarray(pixels[..., [2, 1, 0]] if byte_order == 0 else pixels[..., 1:])


def require_xvfb(which: Callable[[str], str | None] = shutil.which) -> None:
    """Skip the calling test, naming the apt line, if Xvfb or xdotool is not on the ``PATH``;
    fail it instead if ``DUA_REQUIRE_XVFB=1`` (CI, where a skip would hide the tests).

    Args:
        which: Finds a program on the ``PATH`` (``shutil.which``; tests pass their own).
    """
    missing = [tool for tool in _TOOLS if which(tool) is None]
    if not missing:
        return
    reason = (
        f"{' and '.join(missing)} not installed (a virtual screen for the live viewer's tests): "
        f"{APT_LINE}"
    )
    if os.environ.get(REQUIRE_XVFB) == "1":
        pytest.fail(f"{reason} ({REQUIRE_XVFB}=1: these tests must run)", pytrace=False)
    pytest.skip(reason)


@contextmanager
def virtual_display(folder: Path, size: tuple[int, int] = (1024, 768)) -> Iterator[Display]:
    """Start an Xvfb on a free display number, its screen kept in ``folder``; stop it after.

    Skips the test (fails it under ``DUA_REQUIRE_XVFB=1``) without Xvfb and xdotool."""
    require_xvfb()
    read, write = os.pipe()
    screen = f"{size[0]}x{size[1]}x24"
    xvfb = subprocess.Popen(
        ["Xvfb", "-displayfd", str(write), "-screen", "0", screen, "-fbdir", str(folder)],
        pass_fds=(write,),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    os.close(write)
    try:
        with os.fdopen(read) as pipe:
            number = pipe.readline().strip()  # Xvfb writes it once it accepts clients
        assert number, "Xvfb did not start"
        yield Display(f":{number}", folder / "Xvfb_screen0")
    finally:
        xvfb.terminate()
        xvfb.wait(timeout=30)


def reddish(shot: np.ndarray, *, dim: bool = False) -> int:
    """Pixels of the tints' hue (brick red, orange): red well above green and blue; ``dim``
    counts the dark ones instead (translucent covering spheres over the black background)."""
    f = shot.astype(int)
    r, g, b = f[..., 0], f[..., 1], f[..., 2]
    bright = (r > 90) if not dim else (r > 20) & (r <= 90)
    return int(np.count_nonzero(bright & (r > 1.6 * g) & (r > 1.6 * b)))
