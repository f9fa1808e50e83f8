"""The Predictor's option groups (dua_mujoco/build/options.py): validated where they are written,
modes as plain strings, the flat keywords of earlier releases refused with their new home."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import dua_mujoco
from dua_mujoco.build.options import (
    REMOVED_KEYWORDS,
    CoveringOptions,
    PairOptions,
    PilotOptions,
    ScheduleOptions,
    UrgencyOptions,
)
from dua_mujoco.core.schedules import Schedule
from dua_mujoco.core.validate import check_number
from dua_mujoco.exceptions import InvalidChoiceError, InvalidInputError
from dua_mujoco.measure.rollout import run
from dua_mujoco.models.scenes import load_scene, make_controller
from dua_mujoco.runtime.predictor import Predictor


def test_groups_are_frozen_and_exported() -> None:
    opts = ScheduleOptions(kind="dua", slots_per_bucket=4)
    assert opts.kind is Schedule.DUA
    with pytest.raises(dataclasses.FrozenInstanceError):
        opts.slots_per_bucket = 8  # type: ignore[misc]
    for cls in (CoveringOptions, ScheduleOptions, UrgencyOptions, PilotOptions, PairOptions):
        assert getattr(dua_mujoco, cls.__name__) is cls


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: ScheduleOptions(kind="fastest"), "fastest"),
        (lambda: ScheduleOptions(slots_per_bucket=3), "1, 2, 4"),
        (lambda: ScheduleOptions(alarm_backoff=0), "alarm_backoff"),
        (lambda: UrgencyOptions(exact_below=-1.0), "exact_below = -1.0"),
        (lambda: UrgencyOptions(exact="yes"), "exact = 'yes'"),  # type: ignore[arg-type]
        (lambda: PilotOptions(steps=0), "pilot steps = 0"),
        (lambda: PilotOptions(controller=3), "not callable"),  # type: ignore[arg-type]
        (lambda: PilotOptions(safety=0.5), "pilot safety = 0.5"),
        (lambda: PilotOptions(safety=math.nan), "pilot safety = nan"),
        (lambda: CoveringOptions(max_spheres_per_geom=0), "max_spheres_per_geom = 0"),
    ],
)
def test_bad_values_fail_where_they_are_written(make, match: str) -> None:
    with pytest.raises((InvalidInputError, InvalidChoiceError), match=match):
        make()


@pytest.mark.parametrize("old", sorted(REMOVED_KEYWORDS))
def test_flat_keywords_name_their_new_home(old: str) -> None:
    m, _ = load_scene("two_arms")
    with pytest.raises(InvalidInputError, match=f"{old} -> "):
        Predictor(m, accel=5.0, **{old: 1})


def test_unknown_keywords_list_the_valid_ones() -> None:
    m, _ = load_scene("two_arms")
    with pytest.raises(InvalidInputError, match="takes accel, speed"):
        Predictor(m, accel=5.0, sped=1.0)


def test_a_mode_string_is_its_group_with_defaults() -> None:
    """``schedule="dua"`` and ``ScheduleOptions(kind="dua")`` build the same predictor: the same
    alarms step by step over a rollout."""
    runs = []
    for schedule in ("dua", ScheduleOptions(kind="dua")):
        m, d = load_scene("traffic")
        p = Predictor(m, accel=4.0, schedule=schedule, pairs=PairOptions(mode="all"))
        seen: list[np.ndarray] = []

        def on_step(
            k: int, data: object, alarms: object, monitor: object, seen: list = seen
        ) -> None:
            if alarms is not None:
                seen.append(np.asarray(alarms.pairs).copy())  # type: ignore[attr-defined]

        run(
            m,
            d,
            p,
            steps=200,
            controller=make_controller(m, "random", seed=0),
            progress=False,
            on_step=on_step,
        )
        runs.append(seen)
        assert p.options.schedule == ScheduleOptions(kind="dua")
    assert len(runs[0]) == len(runs[1]) > 0
    assert all(np.array_equal(a, b) for a, b in zip(*runs, strict=True))


@pytest.mark.parametrize("value", [True, np.complex128(2 + 3j), "2", math.inf, -1.0])
def test_a_number_option_refuses_what_is_not_a_finite_real(value: object) -> None:
    with pytest.raises(InvalidInputError, match=r"rate = .* is invalid"):
        check_number("rate", value, zero=True)
    assert check_number("rate", np.float32(1.5)) == 1.5
