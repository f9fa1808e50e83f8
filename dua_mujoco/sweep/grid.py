"""Option sets of a sweep: ``run``'s options varied by a small TOML file (docs/integrations.md).

A grid file holds a ``[grid]`` table, whose lists multiply into every combination, and/or named
``[[set]]`` tables (each combined with every grid point); keys are ``run``'s option names
(dashes or underscores), values as on the command line or TOML booleans for switches. Values
are checked by the command line's own parsers, so a bad value fails before any run starts.
"""

from __future__ import annotations

import argparse
import copy
import itertools
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dua_mujoco.exceptions import InvalidChoiceError, InvalidInputError

__all__ = ["OptionSet", "load_grid", "option_sets"]

NOT_IN_A_SET = frozenset({"seed"})
"""Options a set may not vary: the seeds are the sweep's own axis (``--seed``, ``--seeds``)."""


@dataclass(frozen=True)
class OptionSet:
    """One combination of options: a ``name`` for the table and the parsed ``run`` options."""

    name: str
    options: argparse.Namespace


def load_grid(path: Path, base: argparse.Namespace) -> list[OptionSet]:
    """The option sets of a TOML grid file over ``base`` (the command line's run options).

    Raises:
        InvalidInputError: The file does not parse, holds no set, or a value is invalid.
        InvalidChoiceError: An unknown table or option name (the valid ones are listed).
    """
    try:
        doc = tomllib.loads(Path(path).read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise InvalidInputError(f"--grid {str(path)!r} cannot be read: {exc}.") from None
    return option_sets(doc, base, source=str(path))


def option_sets(
    doc: Mapping[str, Any], base: argparse.Namespace, *, source: str = "grid"
) -> list[OptionSet]:
    """The option sets a parsed grid document describes (see the module docstring)."""
    for table in doc:
        if table not in ("grid", "set"):
            raise InvalidChoiceError(
                "table", table, ["grid", "set"], f"({source}: [grid] lists, [[set]] named sets)"
            )
    grid = doc.get("grid", {})
    named = doc.get("set", [])
    if not isinstance(grid, dict) or not isinstance(named, list):
        raise InvalidInputError(f"{source}: [grid] is a table and [[set]] an array of tables.")
    axes = []
    for key, values in grid.items():
        if not isinstance(values, list) or not values:
            raise InvalidInputError(
                f"{source}: [grid] {key} = {values!r} is invalid: give a non-empty list."
            )
        axes.append([(key, v) for v in values])
    points = [dict(p) for p in itertools.product(*axes)]  # one empty point without a grid
    sets = []
    for k, entry in enumerate(named or [{}]):
        if not isinstance(entry, dict):
            raise InvalidInputError(f"{source}: [[set]] number {k + 1} is not a table.")
        entry = dict(entry)
        name = str(entry.pop("name", "" if not named else f"set {k + 1}"))
        for point in points:
            overlap = sorted(set(point) & set(entry))
            if overlap:
                raise InvalidInputError(
                    f"{source}: {overlap} set both in [grid] and in [[set]] {name!r}: keep one."
                )
            parts = [name] if name else []
            parts += [f"{key}={_show(v)}" for key, v in point.items()]
            sets.append(
                OptionSet(
                    ", ".join(parts) or "default", apply(base, {**entry, **point}, source=source)
                )
            )
    names = [s.name for s in sets]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InvalidInputError(f"{source}: option set names {twice} repeat: name each [[set]].")
    return sets


def apply(
    base: argparse.Namespace, values: Mapping[str, Any], *, source: str = "grid"
) -> argparse.Namespace:
    """``base`` with ``values`` (option name -> TOML value) set, each checked as on the command
    line. Raises InvalidChoiceError naming an unknown option and listing the valid ones."""
    from dua_mujoco.run_options import run_option_actions

    actions = {k: a for k, a in run_option_actions().items() if k not in NOT_IN_A_SET}
    options = copy.copy(base)
    for key, value in values.items():
        dest = key.replace("-", "_")
        action = actions.get(dest)
        if action is None:
            raise InvalidChoiceError(
                "option in a sweep set", key, sorted(actions), f"(in {source})"
            )
        setattr(options, dest, _parse(action, f"{source}: {key}", value))
    return options


def _parse(action: argparse.Action, key: str, value: Any) -> Any:
    if action.nargs == 0:  # a switch: --realtime (store_true), --no-exact (store_false)
        if not isinstance(value, bool):
            raise InvalidInputError(f"{key} = {value!r} is invalid: it is a switch, true or false.")
        return value
    if isinstance(value, bool | list | dict):
        raise InvalidInputError(f"{key} = {value!r} is invalid: give a number or a string.")
    text = str(value)
    try:
        parsed = action.type(text) if callable(action.type) else text
    except (argparse.ArgumentTypeError, ValueError) as exc:
        raise InvalidInputError(f"{key} = {value!r} is invalid: {exc}.") from None
    if action.choices is not None and parsed not in action.choices:
        raise InvalidChoiceError(f"{key} value", value, action.choices)
    return parsed


def _show(value: Any) -> str:
    return str(value).lower() if isinstance(value, bool) else str(value)
