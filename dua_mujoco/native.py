"""The native core: where ``libdua_mujoco.so`` is, and loading it for MuJoCo.

One shared library holds the predictor's runtime and kernels (``dua_mujoco/csrc``) and the MuJoCo
sensor plugin ``dua_mujoco.predictor``, which its load-time constructor registers with MuJoCo.
``pip install`` builds it with CMake (scikit-build-core) against the mujoco wheel's headers and
``libmujoco``, beside ``dua_mujoco._core``, the Python module that calls it (nanobind). This
module is the one place that loads the library without that module: ``import mujoco`` runs
:func:`load_plugin` through the ``mujoco.plugins`` entry point, and it imports nothing heavy.
"""

from __future__ import annotations

import ctypes
import functools
import importlib.metadata
import importlib.util
import os
import sys
from pathlib import Path

from dua_mujoco.exceptions import NativeLibraryError

__all__ = ["LIBRARY", "library", "library_path", "load_plugin"]

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


def _mujoco_dir() -> Path:
    spec = importlib.util.find_spec("mujoco")
    if spec is None or spec.origin is None:  # pragma: no cover - mujoco is a dependency
        raise NativeLibraryError("the mujoco package is not installed: pip install mujoco")
    return Path(spec.origin).parent


@functools.cache
def library() -> ctypes.CDLL:
    """The loaded native core (loaded once a process; MuJoCo's plugin registered by then).

    ``libmujoco`` is loaded first, under the soname the native core was linked against.

    Raises:
        NativeLibraryError: The library is missing or does not load.
    """
    mujoco_dir = _mujoco_dir()
    mujoco_libs = sorted(mujoco_dir.glob("libmujoco.so*"))
    if mujoco_libs:
        ctypes.CDLL(str(mujoco_libs[-1]), mode=os.RTLD_NOW | os.RTLD_GLOBAL)
    path = library_path()
    try:
        lib = ctypes.CDLL(str(path), mode=os.RTLD_NOW | os.RTLD_GLOBAL)
    except OSError as err:
        raise NativeLibraryError(
            f"{path} failed to load ({err}): rebuild it against this mujoco "
            f"({mujoco_dir}) with `pip install -e .`."
        ) from err
    return lib


def load_plugin() -> None:
    """The ``mujoco.plugins`` entry point: load the native core, which registers the sensor
    plugin ``dua_mujoco.predictor`` with MuJoCo."""
    library()


def declare(signatures):  # type: ignore[no-untyped-def]  # TEMPORARY until core/ is ported
    lib = library()
    for name, (restype, argtypes) in signatures.items():
        fn = getattr(lib, name)
        fn.restype = restype
        fn.argtypes = list(argtypes)
    return lib
