"""Running another checkout of the package in a subprocess, for A/B benchmarks.

An editable install made by scikit-build-core puts an import finder ahead of ``sys.path``, so a
subprocess run in another checkout (``cwd``/``PYTHONPATH``) would still import this one.
:data:`PREAMBLE` removes that finder first, for a checkout other than the installed one only
(the finder maps ``dua_mujoco.models`` to ``models/``, which the source tree alone does not).
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["PREAMBLE", "scene_path"]

PREAMBLE = (
    "import sys\n"
    "sys.meta_path[:] = [f for f in sys.meta_path\n"
    "                    if type(f).__name__ != 'ScikitBuildRedirectingFinder']\n"
)


def scene_path(scene: str, root: Path) -> str:
    """A bundled XML scene as the path of its file in checkout ``root`` (another checkout finds
    the bundled files only when installed); any other scene as it is."""
    path = root / "models" / f"{scene}.xml"
    return str(path) if path.is_file() else scene
