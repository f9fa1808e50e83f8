"""``run_paper``: Tables 1 to 3 of the paper, reproduced, written as markdown, plots and JSON."""

from __future__ import annotations

import json
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

from dua_mujoco.experiments.paper.clock import (
    FIXED_DT,
    MEASURED_NS_OVERHEAD,
    MEASURED_NS_PER_EVAL,
    WorkClock,
    dua_buckets,
)
from dua_mujoco.experiments.paper.kernels import kernel_costs
from dua_mujoco.experiments.paper.markdown import markdown
from dua_mujoco.experiments.paper.plan import make_plan
from dua_mujoco.experiments.paper.plots import plots
from dua_mujoco.experiments.paper.sequences import dua_run, sa_run
from dua_mujoco.experiments.paper.tables import PaperRow, agreement_rows, paper_row
from dua_mujoco.experiments.paper.world import WorldParams
from dua_mujoco.experiments.report import jsonable
from dua_mujoco.progress import Progress

__all__ = ["run_paper"]


def run_paper(
    *,
    quick: bool = False,
    out_dir: Path | None = Path("out/paper"),
    json_path: Path | None = None,
    seeds: int = 10,
    progress: bool = True,
    tiny: bool = False,
    params: WorldParams | None = None,
    clock: WorkClock | None = None,
    fixed_dt: float = FIXED_DT,
) -> dict[str, Any]:
    """Run the reproduction; write tables, plots and JSON.

    Args:
        quick: Smaller run (N = 5..40, 100, 200; 5 seeds): well under 2 minutes.
        out_dir: Directory for ``paper-tables.md`` and the PNG plots (None: write nothing there).
        json_path: Where to write the JSON results (None: not written).
        seeds: Random sequences per (N, clock) (capped at 5 with ``quick``, 2 with ``tiny``).
        progress: Show a progress bar on stderr.
        tiny: Internal knob for tests: N in {5, 10}, 2 seeds, 25 iterations.
        params: World parameters (default ``WorldParams()``).
        clock: Work-clock model (default ``WorkClock()``).
        fixed_dt: Period of the fixed clock (s).

    Returns:
        ``{"rows": [PaperRow as dict, ...], "table3": [...], "meta": {...}, "markdown": str}``.

    Raises:
        AssertionError: A sampled collision was not alarmed (completeness violated).
    """
    plan = make_plan(quick, tiny, seeds)
    params = params or WorldParams()
    clock = clock or WorkClock()
    started = time.perf_counter()
    total = (
        sum(1 + len(plan.modes) * plan.seed_cap.get(n, plan.seeds) for n in plan.n_values)
        + len(plan.table3_lengths) * plan.table3_sequences
    )
    rows: list[PaperRow] = []
    with Progress(total, "paper", enabled=progress) as bar:
        for n in plan.n_values:
            kernel = kernel_costs(n, params, plan.kernel_reps)
            bar.update(note=f"N={n} kernels")
            m = n * (n - 1) // 2
            for mode in plan.modes:
                if mode == "realtime":
                    dt_dua, dt_sa = clock.dt(dua_buckets(m)), clock.dt(m)
                else:
                    dt_dua = dt_sa = fixed_dt
                dua_runs, sa_runs = [], []
                for s in range(plan.seed_cap.get(n, plan.seeds)):
                    dua_runs.append(
                        dua_run(params.world(n, s), dt_dua, plan.iterations[n], plan.prefixes, True)
                    )
                    sa_runs.append(
                        sa_run(params.world(n, s), dt_sa, plan.sa_iterations[n], plan.prefixes)
                    )
                    bar.update(note=f"N={n} {mode} seed {s}")
                rows.append(paper_row(n, mode, plan, dt_dua, dt_sa, dua_runs, sa_runs, kernel))
        table3 = agreement_rows(plan, params, clock, bar)
    missed = sum(r.missed_collisions for r in rows)
    if missed:
        raise AssertionError(f"{missed} sampled collisions were not alarmed beforehand.")
    meta = {
        "plan": plan.label,
        "seconds": time.perf_counter() - started,
        "world": asdict(params),
        "work_clock": {
            "seconds_per_eval": clock.seconds_per_eval,
            "overhead_evals": clock.overhead_evals,
            "measured_ns_per_eval": MEASURED_NS_PER_EVAL,
            "measured_ns_overhead": MEASURED_NS_OVERHEAD,
        },
        "fixed_dt": fixed_dt,
        "latency": 1,
        "notes": plan.notes,
    }
    text = markdown(rows, table3, meta)
    result: dict[str, Any] = {
        "rows": [jsonable(asdict(r)) for r in rows],
        "table3": [asdict(r) for r in table3],
        "meta": meta,
        "markdown": text,
    }
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / "paper-tables.md").write_text(text)
        plots(rows, table3, out_dir)
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        payload = {k: v for k, v in result.items() if k != "markdown"}
        json_path.write_text(json.dumps(payload, indent=2))
    return result
