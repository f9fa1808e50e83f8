"""Reproduction of the paper's experiments (Hayward et al. 1995, section 8).

The world is the paper's: ghost spheres in a cube under random, exactly bounded, piecewise-constant
accelerations (``world``). Three measurements, each beside the paper's (``reference``):

* **Table 1, cost per iteration against N**: evaluations of tau per iteration (the
  hardware-independent analogue of the paper's CPU time), wall-clock microseconds through the
  public API (DUA's fused ``step_points``, DUA's ``select``/``update``, SA(tau)'s
  ``select``/``update``) and native-kernel nanoseconds (``kernels``: one native call an
  iteration, the closest analogue of the paper's instruction counts).
* **Table 2, false alarms** (repetitive alarms counted once) in two clocks (``clock``): the *work
  clock* ("realtime"), where an iteration lasts as long as it computes, and a *fixed* clock, one
  period for both algorithms. Real collisions are counted too, and every one must have been
  alarmed (asserted).
* **Table 3, most-urgent-pair agreement** at N = 10: DUA's bucket-0 occupant against SA(tau)'s
  argmin tau, and SA(d)'s argmin distance against SA(tau)'s.

``run_paper`` (``reproduce``) runs them (``sequences``, condensed by ``tables``) and writes
``markdown`` and ``plots``; docs/paper-reproduction.md discusses the results.
"""

from __future__ import annotations

from dua_mujoco.experiments.paper.cli import add_arguments, main
from dua_mujoco.experiments.paper.clock import (
    FIXED_DT,
    MEASURED_NS_OVERHEAD,
    MEASURED_NS_PER_EVAL,
    PAPER_SECONDS_PER_EVAL,
    WorkClock,
)
from dua_mujoco.experiments.paper.kernels import calibrate_work_clock
from dua_mujoco.experiments.paper.reproduce import run_paper
from dua_mujoco.experiments.paper.tables import AgreementRow, PaperRow
from dua_mujoco.experiments.paper.world import WorldParams

__all__ = [
    "FIXED_DT",
    "MEASURED_NS_OVERHEAD",
    "MEASURED_NS_PER_EVAL",
    "PAPER_SECONDS_PER_EVAL",
    "AgreementRow",
    "PaperRow",
    "WorkClock",
    "WorldParams",
    "add_arguments",
    "calibrate_work_clock",
    "main",
    "run_paper",
]
