"""Evaluations a step of the deadline wheel against a screen of every pair every step (a model).

On the robots where the plugin costs most, the wheel's evaluations are sphere pairs a few
centimetres apart under large bounds, revisited every one to four steps, at about 57 ns each
all told (dmc_dog at auto bounds: 2,300-2,400 a step). Most of them could be cleared for one
step by far less than the kernel: a pair cannot alarm within the horizon ``H`` where

    |x| - eps > (|v| + delta) H + A H^2 / 2,

since ``|x + v t| >= |x| - |v| t`` puts the kernel's first root (docs/theory.md, section 1)
above ``H`` there (``tests/test_screen_model_script.py`` holds it to the kernel). The design
this script counts keeps every pair that passes that screen off the wheel, screened every step;
a pair that fails it is evaluated as today and goes to the wheel under today's rules (rule (3),
the backoff (3b)); a wheel pair whose evaluation leaves it out of alarm and passing the screen
goes back to it. Every pair at every step is covered by that step's screen or by a wheel
verdict.

This is the model that led to the schedule's screen, not the screen as built
(``ScheduleOptions(screen=True)``, docs/theory.md, section 3, "The screen"): that one bounds the
relative speed by the sum of the two spheres' speeds (a root a sphere, not a pair), takes only
pairs whose wait on the wheel is at most 16 steps, and runs the exact level as every step does.

The model runs both on the same motion at the sphere level: the exact level is not simulated
(a pair below the horizon is counted as a look and its verdict is the sphere tau), nor are the
bound violations' made-due pairs, and latency is 0 with a one-period horizon. Per robot it
prints, means a step after 200 steps: the wheel's evaluations, looks and standing pairs, and the
screen's screens, evaluations, looks and standing pairs. Bounds as plugin.py's (the pilot's
random controls, seed 99, for ``auto``), the run under ``make_controller``'s random controls
(seed 0)::

    python benchmarks/screen_model.py                       # dmc_dog yam go1 franka_kitchen
    python benchmarks/screen_model.py --accel 200 --robots dmc_dog --steps 600
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Callable
from functools import partial
from pathlib import Path

import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from robots import robot_spec
from tau_variants import accel_option, predictor_for, sphere_pairs

from dua_mujoco.core.urgency import time_to_collision
from dua_mujoco.exceptions import BoundViolationWarning
from dua_mujoco.models.scenes import make_controller

ROBOTS = ("dmc_dog", "yam", "go1", "franka_kitchen")
RUN_SEED = 0  # plugin.py's run
MAX_INTERVAL, BACKOFF = 1024, 8  # the deadline schedule's defaults
WARMUP = 200


def screen_passes(
    x: np.ndarray, v: np.ndarray, eps: np.ndarray, accel: np.ndarray, delta: np.ndarray, h: float
) -> np.ndarray:
    """``(M,)`` whether each pair (offsets ``x`` and velocities ``v``, ``(M, 3)``) cannot come
    within ``eps`` in ``h`` seconds under ``accel`` and ``delta`` ``(M,)``: ``|x| - eps`` above
    ``(|v| + delta) h + accel h^2 / 2``, with margins against the kernel's inflation and the
    rounding."""
    reach = (np.linalg.norm(v, axis=1) + delta) * h + 0.5 * accel * h * h
    # The kernel solves a problem inflated by 4e-15 of |x|, eps, |v| and delta (docs/theory.md,
    # section 1): the margins cover that and the rounding here, on the gap and on the reach.
    gap = np.linalg.norm(x, axis=1) * (1.0 - 1e-12) - eps * (1.0 + 1e-12)
    return gap > reach * (1.0 + 1e-9)


def intervals(tau: np.ndarray, dt: float, max_interval: int) -> np.ndarray:
    """``(M,)`` rule (3) at latency 0 and a one-period horizon: the largest ``s`` in ``[1,
    max_interval]`` with ``s dt < tau``, or 1 (``_core.deadline_interval``, vectorized)."""
    s = np.ceil(np.minimum(tau, (max_interval + 1) * dt) / dt) - 1.0
    # ceil(tau / dt) - 1 is the largest s with s dt < tau in exact arithmetic; the rounded
    # quotient is settled on the test itself, as the native rule does.
    s = np.where(s * dt >= tau, s - 1.0, s)
    s = np.where((s + 1.0) * dt < tau, s + 1.0, s)
    return np.clip(s, 1, max_interval).astype(np.int64)


class Wheel:
    """The deadline wheel's waits on ``m`` pairs: due steps, whether the last verdict alarmed,
    and its step."""

    def __init__(self, m: int) -> None:
        self.due = np.zeros(m, dtype=np.int64)
        self.alarmed = np.zeros(m, dtype=bool)
        self.last = np.zeros(m, dtype=np.int64)

    def renew(self, ids: np.ndarray, tau: np.ndarray, step: int, h: float, dt: float) -> None:
        """Verdicts ``tau`` of pairs ``ids`` at ``step``: rule (3), and (3b) for a pair that
        alarms again."""
        alarm = tau <= h
        wait = np.where(alarm, 1, intervals(tau, dt, MAX_INTERVAL))
        again = alarm & self.alarmed[ids]
        wait = np.where(again, np.minimum(2 * (step - self.last[ids]), BACKOFF), wait)
        self.due[ids], self.alarmed[ids], self.last[ids] = step + wait, alarm, step


class Hybrid:
    """The screen and the wheel on ``m`` pairs: every pair starts on the screen; one that fails
    it is evaluated and goes to the wheel; a wheel pair whose evaluation leaves it out of alarm
    and passing the screen goes back."""

    def __init__(self, m: int) -> None:
        self.wheel = Wheel(m)
        self.screened = np.ones(m, dtype=bool)

    def step(
        self,
        step: int,
        tau: Callable[[np.ndarray], np.ndarray],
        screen: Callable[[np.ndarray], np.ndarray],
        h: float,
        dt: float,
    ) -> tuple[int, np.ndarray, np.ndarray]:
        """One step: ``screen(ids)`` says which pairs pass, ``tau(ids)`` evaluates them. Returns
        the screens made (the held pairs', then the evaluated wheel pairs'), the pairs evaluated
        and their tau."""
        held = np.flatnonzero(self.screened)
        failed = held[~screen(held)]
        due = np.flatnonzero(~self.screened & (self.wheel.due <= step))
        evaluated = np.concatenate([failed, due])
        t = tau(evaluated)
        self.wheel.renew(evaluated, t, step, h, dt)
        self.screened[failed] = False
        back = np.zeros(len(due), dtype=bool)
        if len(due):
            back = ~self.wheel.alarmed[due] & screen(due)
        self.screened[due[back]] = True
        return len(held) + len(due), evaluated, t


def measure(name: str, accel: str, steps: int) -> dict[str, float]:
    """Means a step, after ``WARMUP``, of the wheel's and the screen's counts on ``name``."""
    m = robot_spec(name).compile()
    p = predictor_for(m, accel)
    i, j, eps, bound, delta, speed = sphere_pairs(p)
    dt, h, count = float(m.opt.timestep), float(p.alarm_horizon), len(i)

    def tau(x: np.ndarray, v: np.ndarray, k: np.ndarray) -> np.ndarray:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", BoundViolationWarning)
            return time_to_collision(
                x[k], v[k], eps[k], bound[k], speed=speed[k], vel_uncertainty=delta[k]
            )

    def screen(x: np.ndarray, v: np.ndarray, k: np.ndarray) -> np.ndarray:
        return screen_passes(x[k], v[k], eps[k], bound[k], delta[k], h)

    alone, hybrid = Wheel(count), Hybrid(count)
    rows: dict[str, list[float]] = {
        k: [] for k in ("evals", "looks", "standing", "screens", "h_evals", "h_looks", "h_standing")
    }
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    drive = make_controller(m, "random", seed=RUN_SEED)
    for step in range(1, steps + 1):
        drive(m, d)
        mujoco.mj_step(m, d)
        c, u = p.sphere_states(d)
        x, v = c[j] - c[i], u[j] - u[i]
        due = np.flatnonzero(alone.due <= step)
        t = tau(x, v, due)
        alone.renew(due, t, step, h, dt)
        screens, evaluated, th = hybrid.step(step, partial(tau, x, v), partial(screen, x, v), h, dt)
        if step > WARMUP:
            for key, value in (
                ("evals", len(due)), ("looks", np.count_nonzero(t < h)),
                ("standing", np.count_nonzero(alone.alarmed)), ("screens", screens),
                ("h_evals", len(evaluated)), ("h_looks", np.count_nonzero(th < h)),
                ("h_standing", np.count_nonzero(hybrid.wheel.alarmed)),
            ):  # fmt: skip
                rows[key].append(float(value))
    return {"pairs": float(count)} | {k: float(np.mean(v)) for k, v in rows.items()}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", nargs="*", default=list(ROBOTS))
    ap.add_argument("--accel", type=accel_option, default="auto", help="'auto' or a declared m/s^2")
    ap.add_argument("--steps", type=int, default=1200)
    args = ap.parse_args(argv)
    if args.steps <= WARMUP:
        ap.error(f"--steps {args.steps}: pass more than the {WARMUP} steps of warm-up")
    print(
        "| robot | bounds | sphere pairs | wheel: evaluations | looks | standing "
        "| screen: screens | evaluations | looks | standing | evaluations, wheel / screen |"
    )
    print("|---" * 11 + "|")
    for k, name in enumerate(args.robots):
        print(f"{name} ({k + 1}/{len(args.robots)})", file=sys.stderr, flush=True)
        r = measure(name, args.accel, args.steps)
        print(
            f"| {name} | {args.accel} | {r['pairs']:.0f} | {r['evals']:.0f} | {r['looks']:.1f} "
            f"| {r['standing']:.1f} | {r['screens']:.0f} | {r['h_evals']:.0f} "
            f"| {r['h_looks']:.1f} | {r['h_standing']:.1f} | {r['evals'] / r['h_evals']:.1f} |",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
