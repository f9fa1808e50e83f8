"""The reproduction's tables, markdown, beside the paper's numbers."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from dua_mujoco.experiments.paper.reference import (
    PAPER_N,
    PAPER_TABLE1,
    PAPER_TABLE2_DT,
    PAPER_TABLE2_DUA,
    PAPER_TABLE2_SA,
    PAPER_TABLE3,
    PAPER_TABLE3_OVERALL,
)
from dua_mujoco.experiments.paper.tables import AgreementRow, PaperRow
from dua_mujoco.experiments.report import fmt, table

__all__ = ["markdown"]


def markdown(rows: Sequence[PaperRow], table3: Sequence[AgreementRow], meta: dict[str, Any]) -> str:
    """The reproduction's tables beside the paper's, as markdown.

    Args:
        rows: Tables 1 and 2's rows (both clocks).
        table3: Table 3's rows.
        meta: ``run_paper``'s ``meta`` (plan, run time, world, work clock, fixed dt, notes).
    """
    rt = {r.N: r for r in rows if r.mode == "realtime"}
    fx = {r.N: r for r in rows if r.mode == "fixed"}
    out = [f"# Paper reproduction ({meta['plan']} run, {meta['seconds']:.0f} s)", ""]
    wc = meta["work_clock"]
    out += [
        f"World: {meta['world']}. Latency 1 (paper eq. 26). Work clock: dt = "
        f"{wc['seconds_per_eval']} s x (E + {wc['overhead_evals']:.2f}) (E evaluations per "
        f"iteration; our measured {wc['measured_ns_per_eval']} ns/evaluation + "
        f"{wc['measured_ns_overhead']} ns/iteration on the paper's 0.0556 s/evaluation scale). "
        f"Fixed clock: dt = {meta['fixed_dt']} s.",
        "",
    ]
    if meta["notes"]:
        out += [f"Note: {' '.join(meta['notes'])}", ""]

    out += ["## Table 1: cost per iteration", ""]
    body = []
    for n, r in rt.items():
        paper = (
            (
                fmt(PAPER_TABLE1["DUA"][PAPER_N.index(n)], 2),
                fmt(PAPER_TABLE1["SA"][PAPER_N.index(n)], 2),
            )
            if n in PAPER_N
            else ("-", "-")
        )
        body.append(
            [
                str(n),
                str(r.pairs),
                fmt(r.dua_evals_per_iter, 2),
                fmt(r.sa_evals_per_iter, 0),
                fmt(r.dua_kernel_ns_per_iter, 0),
                fmt(r.sa_kernel_ns_per_iter, 0),
                fmt(r.dua_us_per_iter, 1),
                fmt(r.dua_select_update_us_per_iter, 1),
                fmt(r.sa_us_per_iter, 1),
                *paper,
            ]
        )
    out += [
        table(
            [
                "N",
                "pairs M",
                "DUA evals/it",
                "SA evals/it",
                "DUA kernel ns/it",
                "SA kernel ns/it",
                "DUA step_points us/it",
                "DUA select/update us/it",
                "SA us/it",
                "paper DUA ticks",
                "paper SA ticks",
            ],
            body,
            right_align=True,
        ),
        "",
        "Evaluations: mean per iteration. Kernel: one native call an iteration, serial. us/it: "
        "median wall time through the public API (includes input validation and, for SA from "
        "65,536 pairs on, the tau batch on two threads). Paper: 'CPU cycles' = 1/60 s ticks on a "
        "SPARC 470.",
        "",
    ]

    out += ["## Table 2: false alarms per run (repetitive alarms counted once)", ""]
    for mode, by_n in (("realtime (work clock)", rt), ("fixed clock", fx)):
        out += [f"### {mode}", ""]
        body = []
        for n, r in by_n.items():
            i = PAPER_N.index(n) if n in PAPER_N and mode.startswith("realtime") else None
            last = max(PAPER_TABLE2_DUA) if r.dua_iterations >= 75 else 25
            paper_dua = "-" if i is None else str(PAPER_TABLE2_DUA[last][i])
            paper_sa = "-" if i is None else "{} ({})".format(*PAPER_TABLE2_SA[last][i])
            paper_dt = (
                "-" if i is None else f"{PAPER_TABLE2_DT['DUA'][i]} / {PAPER_TABLE2_DT['SA'][i]}"
            )
            body.append(
                [
                    str(n),
                    f"{fmt(r.dt_dua, 2)} / {fmt(r.dt_sa, 2)}",
                    paper_dt,
                    f"{r.dua_iterations} / {r.sa_iterations}",
                    f"{fmt(r.dua_false_alarms)} ({fmt(r.dua_alarms_all)})",
                    f"{fmt(r.sa_false_alarms)} ({fmt(r.sa_alarms_all)})",
                    f"{fmt(r.dua_false_alarms_per_iter, 2)} / {fmt(r.sa_false_alarms_per_iter, 2)}",
                    f"{fmt(r.dua_collisions, 2)} / {fmt(r.sa_collisions, 2)}",
                    paper_dua,
                    paper_sa,
                ]
            )
        out += [
            table(
                [
                    "N",
                    "dt DUA / SA (s)",
                    "paper dt DUA / SA",
                    "iterations DUA / SA",
                    "DUA false (all)",
                    "SA false (all)",
                    "false per iteration DUA / SA",
                    "collisions DUA / SA",
                    "paper DUA (all)",
                    "paper SA false (all)",
                ],
                body,
                right_align=True,
            ),
            "",
        ]
    # The paper's per-iteration-count rows, for N <= 40.
    small = [n for n in PAPER_N if n in rt and len(rt[n].dua_false_alarms_at) > 1]
    if small:
        out += ["### realtime, by iteration count (ours: false; paper: DUA all / SA false)", ""]
        body = []
        for k in sorted(rt[small[0]].dua_false_alarms_at):
            cells = [str(k)]
            for n in small:
                r = rt[n]
                i = PAPER_N.index(n)
                paper_cell = (
                    f" [{PAPER_TABLE2_DUA[k][i]} / {PAPER_TABLE2_SA[k][i][0]}]"
                    if k in PAPER_TABLE2_DUA
                    else ""
                )
                cells.append(
                    f"{fmt(r.dua_false_alarms_at.get(k), 0)} / "
                    f"{fmt(r.sa_false_alarms_at.get(k), 0)}{paper_cell}"
                )
            body.append(cells)
        out += [
            table(
                ["iterations", *(f"N={n} DUA / SA [paper]" for n in small)], body, right_align=True
            ),
            "",
        ]
    out += [
        "A false alarm is an alarm episode (an alarm whose pair did not alarm at its previous "
        "evaluation during the run) of a pair never in contact at any sample of the run. '(all)': "
        "every alarm, unfiltered (the paper's DUA numbers are unfiltered). Collisions: contact "
        f"onsets at the samples, per run; every sampled contact was alarmed beforehand "
        f"(missed: {sum(r.missed_collisions for r in rows)}).",
        "",
    ]

    out += ["## Table 3: most-urgent-pair agreement (%)", ""]
    body = []
    paper_n = PAPER_TABLE3["iterations"]["n"]
    for a in table3:
        j = paper_n.index(a.iterations) if a.iterations in paper_n else None
        pd = (
            "-"
            if j is None
            else f"{PAPER_TABLE3['dua_sat']['mean'][j]} ± {PAPER_TABLE3['dua_sat']['std'][j]}"
        )
        ps = (
            "-"
            if j is None
            else f"{PAPER_TABLE3['sad_sat']['mean'][j]} ± {PAPER_TABLE3['sad_sat']['std'][j]}"
        )
        body.append(
            [
                str(a.iterations),
                f"{a.dua_sat_mean:.1f} ± {a.dua_sat_std:.1f}",
                pd,
                f"{a.sad_sat_mean:.1f} ± {a.sad_sat_std:.1f}",
                ps,
            ]
        )
    if table3:
        da = np.mean([a.dua_sat_mean for a in table3])
        sd = np.mean([a.sad_sat_mean for a in table3])
        po = PAPER_TABLE3_OVERALL
        body.append(
            [
                "overall",
                f"{da:.1f}",
                f"{po['dua_sat'][0]} ± {po['dua_sat'][1]}",
                f"{sd:.1f}",
                f"{po['sad_sat'][0]} ± {po['sad_sat'][1]}",
            ]
        )
    out += [
        table(
            ["iterations", "DUA vs SA(τ)", "paper", "SA(d) vs SA(τ)", "paper"],
            body,
            right_align=True,
        ),
        "",
        f"N = 10, DUA on its work clock, {table3[0].sequences if table3 else 0} sequences per "
        "length; mean ± standard deviation over sequences. Ties in tau count as agreement.",
        "",
        "### Agreement at every N (same runs as Table 2)",
        "",
        table(
            ["N", "clock", "DUA vs SA(τ)", "SA(d) vs SA(τ)"],
            [
                [str(r.N), r.mode, fmt(r.agree_dua_sat), fmt(r.agree_sad_sat)]
                for r in sorted(rows, key=lambda r: (r.mode, r.N))
            ],
            right_align=True,
        ),
        "",
    ]
    return "\n".join(out)
