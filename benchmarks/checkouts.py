"""Running another checkout of the package in a subprocess, for A/B benchmarks.

An editable install made by scikit-build-core puts an import finder ahead of ``sys.path``, so a
subprocess run in another checkout (``cwd``/``PYTHONPATH``) would still import this one.
:data:`PREAMBLE` removes that finder first, for a checkout other than the installed one only
(the finder maps ``dua_mujoco.models`` to ``models/``, which the source tree alone does not).
"""

from __future__ import annotations

__all__ = ["PREAMBLE"]

PREAMBLE = (
    "import sys\n"
    "sys.meta_path[:] = [f for f in sys.meta_path\n"
    "                    if type(f).__name__ != 'ScikitBuildRedirectingFinder']\n"
)
