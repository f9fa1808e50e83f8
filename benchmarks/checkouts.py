"""Running a checkout of the package in a subprocess, for A/B benchmarks (:func:`probe`).

A checkout with a venv of its own (``<checkout>/.venv``, made as CONTRIBUTING.md says) runs in
it: its compiled modules live in that venv (scikit-build-core's editable install keeps them out
of the source tree), and so do its dependencies (numba, before issue 33). Otherwise the checkout
runs in this interpreter from its source tree. An editable install made by scikit-build-core
puts an import finder ahead of ``sys.path``, so such a subprocess would still import this
checkout: :data:`PREAMBLE` removes that finder first (before issue 41 it mapped
``dua_mujoco.models`` to ``models/``, which the source tree alone did not; the link
``dua_mujoco/models`` now does).
"""

from __future__ import annotations

import functools
import os
import subprocess
import sys
from pathlib import Path

__all__ = ["HERE", "PREAMBLE", "probe", "run", "same_mujoco", "scene_path"]

HERE = Path(__file__).resolve().parents[1]
"""This checkout: the one the editable install's finder resolves to."""

PREAMBLE = (
    "import sys\n"
    "sys.meta_path[:] = [f for f in sys.meta_path\n"
    "                    if type(f).__name__ != 'ScikitBuildRedirectingFinder']\n"
)


def _own_env() -> dict[str, str]:
    """This environment for another venv's Python: without this checkout's path or venv."""
    return {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}


@functools.cache
def same_mujoco(python: str) -> None:
    """Refuse an A/B whose other side, run by ``python``, imports another MuJoCo than this one:
    two releases step a scene to different states (4.0.1 fixed 4.0.0's sparse factorization),
    so its bounds, alarms and costs would differ whatever the change.

    Raises:
        SystemExit: The versions differ (both named, and the fix).
    """
    import mujoco

    code = "import mujoco; print(mujoco.__version__)"
    proc = subprocess.run([python, "-c", code], env=_own_env(), capture_output=True, text=True)
    other = proc.stdout.strip() if proc.returncode == 0 else f"none ({proc.stderr.strip()[-200:]})"
    if other != mujoco.__version__:
        raise SystemExit(
            f"the other side's Python ({python}) has mujoco {other}, this one "
            f"{mujoco.__version__}: install the same in both (pip install "
            f"mujoco=={mujoco.__version__}, then "
            "pip install -e . --no-build-isolation --no-deps to rebuild the native core)"
        )


def scene_path(scene: str, root: Path) -> str:
    """A bundled XML scene as the path of its file in checkout ``root`` (another checkout finds
    the bundled files only when installed); any other scene as it is."""
    path = root / "models" / f"{scene}.xml"
    return str(path) if path.is_file() else scene


def probe(code: str, checkout: Path, *args: str, **env: str) -> tuple[list[str], dict[str, str]]:
    """``python -c code args`` run on ``checkout``: its argv and environment (``env`` added).
    Another checkout with a ``.venv`` runs in that venv's Python; otherwise in this one, with
    ``PYTHONPATH`` the checkout and the :data:`PREAMBLE` first for any checkout but this one.
    Run it with ``cwd=checkout`` ("python -c" puts the working directory first on the path)."""
    other = checkout.resolve() != HERE
    own = checkout / ".venv" / "bin" / "python"
    if other and own.exists():
        same_mujoco(str(own))
        return [str(own), "-c", code, *args], {**_own_env(), **env}
    argv = [sys.executable, "-c", (PREAMBLE if other else "") + code, *args]
    return argv, {**os.environ, "PYTHONPATH": str(checkout), **env}


def run(code: str, checkout: Path, *args: str, **env: str) -> str:
    """Run :func:`probe`'s ``python -c code args`` on ``checkout`` to the end; its stdout.

    Raises:
        RuntimeError: The subprocess failed (its stderr's tail said why).
    """
    argv, environ = probe(code, checkout, *args, **env)
    proc = subprocess.run(argv, env=environ, cwd=checkout, capture_output=True, text=True)
    if proc.returncode:
        raise RuntimeError(f"{checkout} failed:\n{proc.stderr[-3000:]}")
    return proc.stdout
