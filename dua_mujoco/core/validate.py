"""Input validation shared by the core: arrays of the right shape, kind and range, or a clear error.

Every check names the bad value and the fix; the native core (``dua_mujoco._core``) checks again
only the indices it follows, so that no call reads out of bounds.
"""

from __future__ import annotations

import enum
import math
from typing import TypeVar

import numpy as np
import numpy.typing as npt

from dua_mujoco.exceptions import (
    InvalidBoundError,
    InvalidChoiceError,
    InvalidInputError,
    NonFiniteStateError,
    ShapeError,
)

__all__ = [
    "as_choice",
    "as_ids",
    "as_vectors",
    "check_int",
    "check_number",
    "check_period",
    "check_urgencies",
    "per_pair",
    "per_sphere",
    "real_array",
]


E = TypeVar("E", bound=enum.Enum)


def as_choice(kind: type[E], value: object, what: str) -> E:
    """``value`` as a member of the enum ``kind`` (a member or its value), or an error that names
    ``what`` and lists the values."""
    try:
        return kind(value)
    except ValueError:
        raise InvalidChoiceError(what, value, [m.value for m in kind]) from None


def real_array(name: str, value: npt.ArrayLike) -> np.ndarray:
    """``value`` as float64, refusing complex numbers (numpy would drop their imaginary part)."""
    arr = np.asarray(value)
    if arr.dtype.kind == "c":  # np.iscomplexobj's test, without its call overhead
        raise InvalidInputError(
            f"{name} holds complex numbers (dtype {arr.dtype}): pass real positions, velocities "
            "and bounds (take .real if the imaginary part is zero)."
        )
    try:
        return np.asarray(arr, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(
            f"{name} must hold numbers; got dtype {arr.dtype} ({str(value)[:60]})."
        ) from None


def as_ids(name: str, value: npt.ArrayLike, m: int | None = None) -> np.ndarray:
    """A ``(m,)`` (or ``(n,)``) integer id array as contiguous int64."""
    arr = np.asarray(value)
    if arr.ndim != 1 or (m is not None and arr.shape[0] != m):
        want = f"({m},)" if m is not None else "(n,)"
        raise ShapeError(f"{name} has shape {arr.shape}; expected {want}.")
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise InvalidInputError(f"{name} must hold integers; got dtype {arr.dtype}.")
    return np.ascontiguousarray(arr, dtype=np.int64)


def as_vectors(
    name: str, value: npt.ArrayLike, m: int | None = None, *, check_finite: bool = True
) -> np.ndarray:
    """``(m, 3)`` float64 vectors (a single ``(3,)`` vector becomes one row)."""
    if (
        not check_finite
        and type(value) is np.ndarray
        and value.dtype == np.float64
        and value.ndim == 2
        and value.shape[1] == 3
        and value.flags.c_contiguous
        and (m is None or value.shape[0] == m)
    ):
        return value  # already what the conversions below make: a fused step's common case
    arr = real_array(name, value)
    if arr.ndim == 1 and arr.shape[0] == 3:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 3 or (m is not None and arr.shape[0] != m):
        want = f"({m}, 3)" if m is not None else "(M, 3) or (3,)"
        raise ShapeError(f"{name} has shape {np.shape(value)}; expected {want}.")
    if check_finite and not np.isfinite(arr).all():
        bad = ~np.isfinite(arr).all(axis=1)
        i = int(np.flatnonzero(bad)[0])
        raise NonFiniteStateError(
            f"{name}[{i}] = {arr[i].tolist()} is not finite ({int(bad.sum())} rows): "
            "the state is NaN or inf; check that the simulation has not diverged."
        )
    return np.ascontiguousarray(arr)


def per_pair(
    name: str, value: npt.ArrayLike, m: int, *, allow_inf: bool = False, state: bool = False
) -> np.ndarray:
    """A per-pair parameter as a contiguous array of length ``m``, or 1 for a scalar.

    Bounds (the default) must be non-negative and, unless ``allow_inf``, finite; ``state``
    values (clearances, velocities) must be finite and may be negative.
    """
    arr = real_array(name, value)
    if arr.ndim == 0:
        arr = arr.reshape(1)
    elif arr.shape != (m,):
        raise ShapeError(f"{name} has shape {arr.shape}; expected a scalar or ({m},).")
    if state:
        if not np.isfinite(arr).all():
            i = int(np.flatnonzero(~np.isfinite(arr))[0])
            raise NonFiniteStateError(f"{name}[{i}] = {arr[i]} is not finite.")
        return np.ascontiguousarray(arr)
    lowest = arr.min(initial=0.0)
    if np.isnan(lowest) or lowest < 0.0 or (not allow_inf and np.isinf(arr.max(initial=0.0))):
        ok = (arr >= 0.0) & (np.isfinite(arr) | allow_inf)
        i = int(np.flatnonzero(~ok)[0])
        finite = "" if allow_inf else "finite "
        raise InvalidBoundError(
            f"{name}[{i}] = {arr[i]} is invalid: it must be a {finite}non-negative number."
        )
    return np.ascontiguousarray(arr)


def per_sphere(name: str, value: npt.ArrayLike, n: int, *, allow_inf: bool = False) -> np.ndarray:
    """A per-sphere bound, scalar or ``(n,)``, as an ``(n,)`` array (:func:`per_pair`'s checks)."""
    return np.broadcast_to(per_pair(name, value, n, allow_inf=allow_inf), (n,)).copy()


def check_int(name: str, value: object, low: int = 1, fix: str = "") -> int:
    """An int option ``>= low`` (a bool is refused: Python and the binding both take True for
    1); ``fix`` follows the bound in the message."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
        raise InvalidInputError(f"{name} = {value!r} is invalid: pass an int >= {low}{fix}.")
    return int(value)


def check_number(name: str, value: object, *, zero: bool = False, unit: str = "") -> float:
    """A finite number option ``> 0`` (``>= 0`` with ``zero``) as a float; a bool is refused
    (``float(True)`` is 1); ``unit`` follows "number" in the message (`` of seconds``)."""
    ok = isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)
    x = float(value) if ok else math.nan  # type: ignore[arg-type]
    if not (math.isfinite(x) and (x >= 0.0 if zero else x > 0.0)):
        rule = ">= 0" if zero else "> 0"
        raise InvalidInputError(
            f"{name} = {value!r} is invalid: pass a finite number{unit} {rule}."
        )
    return x


def check_period(dt: object, latency: object) -> tuple[float, int]:
    """The predictor period ``dt > 0`` (seconds) and the latency, an int ``>= 0`` (periods)."""
    fix = " (1 when a verdict takes one period to compute, 0 when it runs after each step)"
    return check_number("dt", dt, unit=" of seconds"), check_int("latency", latency, 0, fix)


def check_urgencies(name: str, tau: npt.ArrayLike, m: int | None = None) -> np.ndarray:
    """``(m,)`` non-negative urgencies (``inf`` allowed, NaN not) as contiguous float64."""
    arr = real_array(name, tau)
    if arr.ndim != 1 or (m is not None and arr.shape[0] != m):
        want = f"({m},)" if m is not None else "(M,)"
        raise ShapeError(f"{name} has shape {arr.shape}; expected {want}.")
    bad = np.isnan(arr) | (arr < 0)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InvalidInputError(
            f"{name}[{i}] = {arr[i]} is invalid: urgencies must be >= 0 (inf allowed), not NaN."
        )
    return np.ascontiguousarray(arr)
