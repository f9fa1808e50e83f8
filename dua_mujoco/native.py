"""The native core: where ``libdua_mujoco.so`` is, and loading it for MuJoCo.

One shared library holds the predictor's runtime and kernels (``dua_mujoco/csrc``) and the MuJoCo
sensor plugin ``dua_mujoco.predictor``, which its load-time constructor registers with MuJoCo.
``pip install`` builds it with CMake (scikit-build-core) against the mujoco wheel's headers and
``libmujoco``, beside ``dua_mujoco._core``, the Python module that calls it (nanobind).
``import mujoco`` runs :func:`load_plugin` through the ``mujoco.plugins`` entry point; C and C++
programs load the library themselves (:func:`library_path`, docs/plugin.md).
"""

from __future__ import annotations

import importlib
import os
import sys
import threading
from pathlib import Path

from dua_mujoco.exceptions import NativeLibraryError

__all__ = ["LIBRARY", "MUJOCO_FIRST", "MujocoFirst", "library_path", "load_plugin"]

LIBRARY = "libdua_mujoco.so"


def library_path() -> Path:
    """Where ``libdua_mujoco.so`` is: ``$DUA_MUJOCO_LIBRARY`` if set (another build of it, a
    ThreadSanitizer one: docs/hardening.md), beside this package (a wheel, or an in-place
    build), or where an editable install put the compiled files (its record of installed
    files)."""
    override = os.environ.get("DUA_MUJOCO_LIBRARY")
    if override:
        if not Path(override).is_file():
            raise NativeLibraryError(
                f"DUA_MUJOCO_LIBRARY = {override!r} names no file: point it at a built "
                f"{LIBRARY}, or unset it to load the installed one."
            )
        return Path(override).resolve()
    here = Path(__file__).resolve().parent / LIBRARY
    if here.is_file():
        return here
    import importlib.metadata  # here only: ``import dua_mujoco`` imports this module

    try:
        files = importlib.metadata.files("dua_mujoco") or []
    except importlib.metadata.PackageNotFoundError:
        files = []
    candidates = [Path(str(f.locate())) for f in files if f.name == LIBRARY]
    # Another copy of the metadata can shadow the installed one (a stale egg-info in the
    # working directory): the package folders on sys.path are looked at too.
    candidates += [Path(entry or ".") / "dua_mujoco" / LIBRARY for entry in sys.path]
    for path in candidates:
        if path.is_file():
            return path.resolve()
    raise NativeLibraryError(
        f"{LIBRARY} not found beside {here.parent} nor among the installed files of "
        "dua_mujoco: the native core is built at install time; reinstall with "
        "`pip install -e .` (it needs a C++ compiler and CMake)."
    )


class MujocoFirst(threading.local):
    """The import hook ``import dua_mujoco`` installs: the binding loads the native core, whose
    constructor registers the plugin, after ``import mujoco``, so that MuJoCo's bundled plugins
    take the first slots whichever a program imports first (an ``.mjb`` records the slot:
    docs/plugin.md); the entry point meanwhile leaves the core to that import."""

    importing = False

    def find_spec(self, name: str, path: object = None, target: object = None) -> None:
        if name == "dua_mujoco._core" and "mujoco" not in sys.modules:
            self.importing = True
            try:
                importlib.import_module("mujoco")
            finally:
                self.importing = False


MUJOCO_FIRST = MujocoFirst()


def load_plugin() -> None:
    """The ``mujoco.plugins`` entry point: load the native core, whose load-time constructor
    registers the sensor plugin ``dua_mujoco.predictor`` with MuJoCo.

    Importing the binding ``dua_mujoco._core`` loads ``libdua_mujoco.so`` (its dependency,
    found beside it), which finds ``libmujoco`` in the mujoco package (its run path): the one
    way the library is loaded, so that the plugin and the binding share one copy of its state.

    Raises:
        NativeLibraryError: The native core is missing or does not load.
    """
    if MUJOCO_FIRST.importing:
        return  # the binding's import asked for MuJoCo, and loads the core next
    try:
        importlib.import_module("dua_mujoco._core")
    except ImportError as err:
        raise NativeLibraryError(
            f"the native core of dua_mujoco failed to load ({err}): it is built at install "
            "time against the installed mujoco; reinstall with `pip install -e .` (it needs a "
            "C++ compiler and CMake), and again after upgrading mujoco."
        ) from err
