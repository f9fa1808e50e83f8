"""The reproduction's plots: cost per iteration, false alarms, agreement, beside the paper's."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from dua_mujoco.experiments.paper.reference import (
    PAPER_N,
    PAPER_TABLE1,
    PAPER_TABLE2_DUA,
    PAPER_TABLE2_SA,
    PAPER_TABLE3,
)
from dua_mujoco.experiments.paper.tables import AgreementRow, PaperRow
from dua_mujoco.experiments.report import pyplot, save_figure

__all__ = ["plots"]


def plots(rows: Sequence[PaperRow], table3: Sequence[AgreementRow], out_dir: Path) -> None:
    """Write ``paper-cost.png``, ``paper-false-alarms.png`` and ``paper-agreement.png``.

    Nothing is written without matplotlib (the ``plots`` extra).

    Args:
        rows: Tables 1 and 2's rows (both clocks).
        table3: Table 3's rows.
        out_dir: An existing folder.
    """
    plt = pyplot()
    if plt is None:
        return
    rt = [r for r in rows if r.mode == "realtime"]
    fx = [r for r in rows if r.mode == "fixed"]
    ns = np.asarray([r.N for r in rt], dtype=np.float64)

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    ax1.loglog(ns, [r.dua_evals_per_iter for r in rt], "o-", label="DUA evaluations/it")
    ax1.loglog(ns, [r.sa_evals_per_iter for r in rt], "s-", label="SA(τ) evaluations/it")
    grid = np.geomspace(ns.min(), ns.max(), 50)
    ax1.loglog(grid, np.log2(grid * (grid - 1) / 2 + 1), "k:", label="log2(M+1) = O(log N)")
    ax1.loglog(grid, grid * (grid - 1) / 2, "k--", lw=0.8, label="M = N(N-1)/2")
    ax1.set_xlabel("spheres N")
    ax1.set_ylabel("evaluations per iteration")
    ax1.set_title("Cost per iteration (hardware-independent)")
    ax1.legend(fontsize=8)
    if all(r.dua_kernel_ns_per_iter is not None for r in rt):
        ax2.loglog(ns, [r.dua_kernel_ns_per_iter for r in rt], "o-", label="DUA kernel (ns)")
        ax2.loglog(ns, [r.sa_kernel_ns_per_iter for r in rt], "s-", label="SA(τ) kernel (ns)")
    ax2.loglog(ns, [r.dua_us_per_iter * 1e3 for r in rt], "o--", label="DUA step_points (ns)")
    ax2.loglog(ns, [r.sa_us_per_iter * 1e3 for r in rt], "s--", label="SA(τ) API (ns)")
    pn = np.asarray(PAPER_N, dtype=np.float64)
    # Paper ticks are 1/60 s; plotted in ns / 1e6 so the curves share the axis (shape only).
    ax2.loglog(pn, np.asarray(PAPER_TABLE1["DUA"]) * 100, "^:", label="paper DUA (ticks x 100)")
    ax2.loglog(pn, np.asarray(PAPER_TABLE1["SA"]) * 100, "v:", label="paper SA (ticks x 100)")
    ax2.set_xlabel("spheres N")
    ax2.set_ylabel("time per iteration")
    ax2.set_title("Time per iteration")
    ax2.legend(fontsize=7)
    save_figure(plt, fig, out_dir / "paper-cost.png")

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, rs, title in ((axes[0], rt, "work clock (realtime)"), (axes[1], fx, "fixed clock")):
        x = [r.N for r in rs]
        # Per iteration, so runs of different lengths (SA at N = 1000) are comparable; +0.01 keeps
        # zero counts on the log axis.
        ax.loglog(x, [r.dua_false_alarms_per_iter + 0.01 for r in rs], "o-", label="DUA")
        ax.loglog(x, [r.sa_false_alarms_per_iter + 0.01 for r in rs], "s-", label="SA(τ)")
        if rs is rt:
            last = 75
            ax.loglog(
                PAPER_N,
                np.asarray(PAPER_TABLE2_DUA[last]) / last + 0.01,
                "^:",
                label="paper DUA (all)",
            )
            ax.loglog(
                PAPER_N,
                np.asarray([a for a, _ in PAPER_TABLE2_SA[last]]) / last + 0.01,
                "v:",
                label="paper SA(τ)",
            )
        ax.set_xlabel("spheres N")
        ax.set_ylabel("false alarms per iteration (+0.01)")
        ax.set_title(title)
        ax.legend(fontsize=8)
    save_figure(plt, fig, out_dir / "paper-false-alarms.png")

    fig, ax = plt.subplots(figsize=(8, 4))
    labels = [str(a.iterations) for a in table3]
    xs = np.arange(len(table3))
    paper_n = PAPER_TABLE3["iterations"]["n"]

    def paper(key: str) -> list[float]:
        return [
            PAPER_TABLE3[key]["mean"][paper_n.index(a.iterations)]
            if a.iterations in paper_n
            else np.nan
            for a in table3
        ]

    w = 0.2
    ax.bar(xs - 1.5 * w, [a.dua_sat_mean for a in table3], w, label="DUA vs SA(τ), ours")
    ax.bar(xs - 0.5 * w, paper("dua_sat"), w, label="DUA vs SA(τ), paper")
    ax.bar(xs + 0.5 * w, [a.sad_sat_mean for a in table3], w, label="SA(d) vs SA(τ), ours")
    ax.bar(xs + 1.5 * w, paper("sad_sat"), w, label="SA(d) vs SA(τ), paper")
    ax.set_xticks(xs, labels)
    ax.set_xlabel("iterations per run (N = 10)")
    ax.set_ylabel("agreement on the most urgent pair (%)")
    ax.set_ylim(0, 100)
    ax.legend(fontsize=8)
    save_figure(plt, fig, out_dir / "paper-agreement.png")
