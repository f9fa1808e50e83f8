"""The tests that need a virtual screen: skipped with the apt line without Xvfb, failed in CI.

A fresh machine passes the README's test command without Xvfb and xdotool (optional system
packages); ``.ci/run`` installs them and sets ``DUA_REQUIRE_XVFB=1``, so that a skip there, which
would hide the live viewer's tests, fails instead.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from screens import APT_LINE, REQUIRE_XVFB, require_xvfb

REPO = Path(__file__).resolve().parent.parent

# The tests that open windows (the `display` and `xvfb` fixtures mark them `xvfb`).
WINDOW_TESTS = ["tests/test_view.py", "tests/test_plugin.py"]


def _found(*tools: str):
    return lambda tool: f"/usr/bin/{tool}" if tool in tools else None


def test_both_tools_found_is_a_go(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(REQUIRE_XVFB, "1")
    require_xvfb(which=_found("Xvfb", "xdotool"))


@pytest.mark.parametrize(
    ("tools", "missing"),
    [((), "Xvfb and xdotool"), (("Xvfb",), "xdotool"), (("xdotool",), "Xvfb")],
    ids=["none", "no-xdotool", "no-xvfb"],
)
def test_a_missing_tool_skips_with_the_apt_line(
    monkeypatch: pytest.MonkeyPatch, tools: tuple[str, ...], missing: str
) -> None:
    monkeypatch.delenv(REQUIRE_XVFB, raising=False)
    with pytest.raises(pytest.skip.Exception) as info:
        require_xvfb(which=_found(*tools))
    assert str(info.value) == (
        f"{missing} not installed (a virtual screen for the live viewer's tests): {APT_LINE}"
    )


def test_a_missing_tool_fails_where_the_tests_must_run(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(REQUIRE_XVFB, "1")
    with pytest.raises(pytest.fail.Exception, match=f"{APT_LINE} \\({REQUIRE_XVFB}=1"):
        require_xvfb(which=_found("xdotool"))


def _window_tests(env_extra: dict[str, str]) -> subprocess.CompletedProcess[str]:
    """The window tests in a child pytest whose ``PATH`` holds this Python's folder only (no
    Xvfb, no xdotool), as on a machine without them."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST", REQUIRE_XVFB))}
    env.update(PATH=str(Path(sys.executable).parent), MUJOCO_GL="egl", **env_extra)
    argv = [sys.executable, "-m", "pytest", "-m", "xvfb", "-p", "no:cacheprovider", "-rs"]
    return subprocess.run(
        [*argv, *WINDOW_TESTS], capture_output=True, text=True, env=env, cwd=REPO, timeout=600
    )


def test_without_xvfb_the_window_tests_are_skipped_naming_the_apt_line() -> None:
    out = _window_tests({})
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    summary = out.stdout.strip().splitlines()[-1]
    skipped = re.search(r"(\d+) skipped", summary)
    assert skipped and int(skipped[1]) >= 3 and "passed" not in summary, summary
    reasons = [x for x in out.stdout.splitlines() if x.startswith("SKIPPED")]
    assert reasons and all(
        x.endswith(f"not installed (a virtual screen for the live viewer's tests): {APT_LINE}")
        for x in reasons
    ), reasons


def test_without_xvfb_the_window_tests_fail_under_require_xvfb() -> None:
    out = _window_tests({REQUIRE_XVFB: "1"})
    assert out.returncode == 1, out.stdout[-3000:]
    summary = out.stdout.strip().splitlines()[-1]
    errors = re.search(r"(\d+) errors?", summary)
    assert errors and int(errors[1]) >= 3 and "skipped" not in summary, summary
    assert f"{APT_LINE} ({REQUIRE_XVFB}=1: these tests must run)" in out.stdout
