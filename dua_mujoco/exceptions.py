"""The one exception hierarchy of dua_mujoco.

Every error names the offending value and says how to fix it; errors about a choice list the valid
choices (as mink's ``InvalidFrame`` lists the frame names).
"""

from __future__ import annotations

from collections.abc import Iterable


class DuaError(Exception):
    """Base class of every error raised by dua_mujoco."""


class InvalidInputError(DuaError, ValueError):
    """An argument has the wrong shape, dtype or value (NaN, inf, negative bound, dt <= 0)."""


class ShapeError(InvalidInputError):
    """An array does not have the shape the function documents."""


class NonFiniteStateError(InvalidInputError):
    """A position or velocity is NaN or infinite: the simulation has diverged or was not stepped."""


class InvalidBoundError(InvalidInputError):
    """A declared motion bound is negative, NaN, or refers to something that does not exist."""


class SchedulerError(DuaError):
    """The scheduler was driven out of protocol (e.g. ``update`` with ids not selected)."""


class UnsupportedGeomError(DuaError, ValueError):
    """A geom cannot be covered by spheres (e.g. a height field without the box fallback)."""


class NativeLibraryError(DuaError, ImportError):
    """The native core (libdua_mujoco.so) is missing, of another version, or failed to load."""


class InvalidChoiceError(InvalidInputError):
    """A name (scene, body, geom, mode) is not among the valid choices."""

    def __init__(self, what: str, value: object, choices: Iterable[object], hint: str = "") -> None:
        listed = ", ".join(repr(c) for c in choices)
        msg = f"Unknown {what} {value!r}. Valid choices: {listed}."
        if hint:
            msg += f" {hint}"
        super().__init__(msg)
        self.value = value
        self.choices = tuple(choices)


class BoundViolationWarning(UserWarning):
    """The state contradicts a declared bound (e.g. |v| > V): the guarantee does not hold there."""


class DeadlineOverrunWarning(UserWarning):
    """A predictor step took longer than its period: the predictor cannot keep up."""


class NoActivePairsWarning(UserWarning):
    """The model has no geom pair MuJoCo could put in contact: the predictor has nothing to do."""


class PilotWarning(UserWarning):
    """The pilot rollout could not measure part of the motion (a mocap body it never moved):
    the bounds it gives there are zero, and the run will break them."""
