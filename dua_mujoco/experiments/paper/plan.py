"""Sizes of a reproduction: full (the paper's and larger N), quick, or tiny (tests)."""

from __future__ import annotations

from dataclasses import dataclass, field

from dua_mujoco.experiments.paper.reference import PAPER_N, PAPER_TABLE3

__all__ = ["Plan", "make_plan"]


@dataclass(frozen=True)
class Plan:
    """Sizes of one reproduction (full, quick or tiny).

    Attributes:
        n_values: Sphere counts of Tables 1 and 2.
        seeds: Random sequences per (N, clock).
        iterations: DUA iterations per run, by N.
        sa_iterations: SA(tau) iterations per run, by N.
        prefixes: Run lengths after which false alarms are also counted (the paper's rows).
        table3_lengths: Run lengths of Table 3.
        table3_sequences: Sequences per Table 3 run length.
        kernel_reps: DUA iterations per compiled-kernel measurement.
        modes: Clocks: ``"realtime"`` (work clock) and ``"fixed"``.
        label: ``"full"``, ``"quick"`` or ``"tiny"``.
        seed_cap: Fewer sequences at some N.
        notes: What the tables' reader must know about this plan.
    """

    n_values: tuple[int, ...]
    seeds: int
    iterations: dict[int, int]
    sa_iterations: dict[int, int]
    prefixes: tuple[int, ...]
    table3_lengths: tuple[int, ...]
    table3_sequences: int
    kernel_reps: int
    modes: tuple[str, ...] = ("realtime", "fixed")
    label: str = "full"
    seed_cap: dict[int, int] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def make_plan(quick: bool, tiny: bool, seeds: int) -> Plan:
    """The plan of a full run, or of a ``quick`` or ``tiny`` one; ``seeds`` is capped by both."""
    if tiny:
        ns: tuple[int, ...] = (5, 10)
        return Plan(
            n_values=ns,
            seeds=min(seeds, 2),
            iterations=dict.fromkeys(ns, 25),
            sa_iterations=dict.fromkeys(ns, 25),
            prefixes=(25,),
            table3_lengths=(25,),
            table3_sequences=2,
            kernel_reps=50,
            label="tiny",
        )
    if quick:
        ns = (*PAPER_N, 100, 200)
        its = {n: 75 if n <= 40 else 25 for n in ns}
        return Plan(
            n_values=ns,
            seeds=min(seeds, 5),
            iterations=its,
            sa_iterations=dict(its),
            prefixes=(25, 50, 75),
            table3_lengths=(25, 50, 100, 250),
            table3_sequences=5,
            kernel_reps=500,
            label="quick",
        )
    ns = (*PAPER_N, 100, 200, 400, 1000)
    its = {n: 75 if n <= 40 else 25 for n in ns}
    sa_its = dict(its)
    # SA's work-clock period is ~1.2 h of world time at N = 400 and ~7.7 h at N = 1000 (M = 79800
    # and 499500 evaluations per iteration): simulating that world time exactly dominates the
    # run, so SA gets 10 and 2 iterations there, and N = 1000 gets 5 sequences instead of 10.
    sa_its[400] = 10
    sa_its[1000] = 2
    return Plan(
        n_values=ns,
        seeds=seeds,
        iterations=its,
        sa_iterations=sa_its,
        prefixes=(25, 35, 50, 65, 75),
        table3_lengths=PAPER_TABLE3["iterations"]["n"],  # type: ignore[arg-type]
        table3_sequences=10,
        kernel_reps=2000,
        seed_cap={1000: min(seeds, 5)},
        notes=[
            "SA(tau) runs 10 iterations at N = 400 and 2 at N = 1000; N = 1000 uses "
            f"{min(seeds, 5)} sequences (its SA period is hours of world time to simulate)."
        ],
    )
