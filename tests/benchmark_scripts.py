"""The benchmarks' scripts for the tests that hold their pure parts: each loaded once by its
path, so that the benchmarks folder stays off sys.path."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def script(stem: str) -> ModuleType:
    """``benchmarks/<stem>.py``, as the module ``benchmarks_<stem>`` (loaded at the first call)."""
    name = f"benchmarks_{stem}"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, BENCHMARKS / f"{stem}.py")
        assert spec is not None and spec.loader is not None
        sys.modules[name] = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(sys.modules[name])
    return sys.modules[name]
