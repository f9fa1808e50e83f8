"""Test-session setup shared by every test module."""

import os
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager
from pathlib import Path

import pytest
from screens import Display, require_xvfb, virtual_display

# MuJoCo picks its OpenGL backend when it is first imported, which may be in any test module:
# make the offscreen renderer headless (EGL, Mesa llvmpipe on the CPU) before any of them loads.
os.environ.setdefault("MUJOCO_GL", "egl")


# --------------------------------------------------------------------------------------------------
# A virtual screen (Xvfb) for the tests of windows: tests/screens.py.
# --------------------------------------------------------------------------------------------------


@pytest.fixture
def xvfb() -> Callable[[Path], AbstractContextManager[Display]]:
    """``virtual_display``: starts an Xvfb on a free display, its screen in the folder given,
    and stops it. Skips the test (with the apt line) where Xvfb or xdotool is missing, fails it
    under ``DUA_REQUIRE_XVFB=1``."""
    require_xvfb()
    return virtual_display


@pytest.fixture
def display(
    xvfb: Callable[[Path], AbstractContextManager[Display]],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> Iterator[Display]:
    """A running Xvfb for this test, ``DISPLAY`` set to it (windows of this process and its
    children open there), stopped after."""
    folder = tmp_path / "screen"
    folder.mkdir()
    with xvfb(folder) as screen:
        monkeypatch.setenv("DISPLAY", screen.name)
        yield screen


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    # `-m xvfb` selects the tests that need the virtual screen (tests/test_screens.py runs them
    # without it); the fixtures mark them, so that no test can forget the marker.
    for item in items:
        if "xvfb" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.xvfb)
