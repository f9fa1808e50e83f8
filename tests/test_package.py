"""The package as a whole: what it exports, what it ships, and what importing it costs."""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

import dua_mujoco

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "dua_mujoco"


def _modules() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts)


def test_public_api_resolves() -> None:
    """Every name in ``__all__`` imports, the lazy ones included."""
    for name in dua_mujoco.__all__:
        assert getattr(dua_mujoco, name) is not None, name
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        _ = dua_mujoco.nope  # type: ignore[attr-defined]


def test_every_sub_package_ships() -> None:
    """A sub-package missing from pyproject's list works in the editable install and is missing
    from the wheel."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    listed = set(config["tool"]["setuptools"]["packages"])
    found = {
        ".".join(p.parent.relative_to(ROOT).parts)
        for p in PACKAGE.rglob("__init__.py")
        if "__pycache__" not in p.parts
    }
    assert found <= listed, f"add {sorted(found - listed)} to [tool.setuptools] packages"


def test_no_private_names_across_modules() -> None:
    """A module imports no underscore name from another module of the package."""
    offenders = []
    for path in _modules():
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("dua_mujoco"):
                offenders += [
                    f"{path.relative_to(ROOT)}: {node.module}.{a.name}"
                    for a in node.names
                    if a.name.startswith("_") and a.name != "__version__"
                ]
    assert offenders == []


def test_modules_stay_small() -> None:
    sizes = {str(p.relative_to(ROOT)): len(p.read_text().splitlines()) for p in _modules()}
    # "About 500 lines": a module past 600 holds two things.
    assert {k: v for k, v in sizes.items() if v > 600} == {}


def test_the_pytest_plugin_imports_neither_numba_nor_mujoco() -> None:
    """Everyone who installs the package loads the plugin in every pytest session: it must cost
    nothing there (numba and llvmlite alone take about half a second)."""
    code = (
        "import sys, pytest\n"
        "import dua_mujoco, dua_mujoco.testing\n"
        "heavy = sorted(m for m in ('numba', 'llvmlite', 'mujoco') if m in sys.modules)\n"
        "print(heavy)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_submodules_import() -> None:
    for path in _modules():
        rel = path.relative_to(ROOT).with_suffix("")
        parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
        if parts[-1] == "__main__":
            continue
        importlib.import_module(".".join(parts))
