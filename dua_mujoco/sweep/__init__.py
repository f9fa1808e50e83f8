"""Sweeps: every scene x seed x option set run as ``dua-mujoco run`` runs it, one row a run.

``dua-mujoco sweep`` is the command line (:mod:`dua_mujoco.sweep.cli`); :func:`sweep` the same
from Python. Runs go to local worker processes by default or to Ray
(:mod:`dua_mujoco.sweep.executors`); option sets come from a TOML grid
(:mod:`dua_mujoco.sweep.grid`); a run's row is :func:`~dua_mujoco.sweep.runner.run_task`'s.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from typing import Any

from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.sweep.executors import Runner, SweepInterrupted, run_local, run_ray
from dua_mujoco.sweep.grid import OptionSet, load_grid, option_sets
from dua_mujoco.sweep.runner import COLUMNS, DETERMINISTIC, Task, run_task

__all__ = [
    "COLUMNS",
    "DETERMINISTIC",
    "OptionSet",
    "SweepInterrupted",
    "Task",
    "load_grid",
    "option_sets",
    "run_task",
    "sweep",
    "tasks_of",
]


def tasks_of(scenes: Sequence[str], seeds: Sequence[int], sets: Sequence[OptionSet]) -> list[Task]:
    """Every scene x seed x option set, scene-major (the table's order)."""
    return [
        Task(scene, seed, s.name, s.options) for scene in scenes for s in sets for seed in seeds
    ]


def sweep(
    tasks: Sequence[Task],
    *,
    workers: int | None = None,
    ray: bool | str = False,
    runner: Runner = run_task,
    on_row: Callable[[int, dict[str, Any]], None] | None = None,
) -> list[dict[str, Any]]:
    """Run ``tasks`` and return their rows in task order.

    Args:
        tasks: The runs (:func:`tasks_of`).
        workers: Local processes, or the CPUs of a local Ray instance (default: the machine's
            CPUs, at most one a task).
        ray: False for local processes; True for a local Ray instance; an address
            (``"ray://host:10001"``, ``"auto"``) for an existing cluster.
        runner: What runs a task (a module-level function; default :func:`run_task`).
        on_row: Called with ``(index, row)`` as each run finishes (progress).

    Returns:
        One row a task (:data:`COLUMNS`); a run that failed or crashed has its ``error``.

    Raises:
        SweepInterrupted: On Ctrl-C, with the rows done.
        InvalidInputError: ``workers`` < 1, or ``ray`` asked for and Ray not installed.
    """
    if workers is None:
        workers = min(os.cpu_count() or 1, max(len(tasks), 1))
    if not (isinstance(workers, int) and workers >= 1):
        raise InvalidInputError(f"workers = {workers!r} is invalid: pass an int >= 1.")
    report = on_row or (lambda index, row: None)
    if ray is False:
        rows = run_local(tasks, runner, workers=workers, on_row=report)
    else:
        address = None if ray is True else str(ray)
        rows = run_ray(tasks, runner, address=address, num_cpus=workers, on_row=report)
    return [rows[i] for i in range(len(tasks))]
