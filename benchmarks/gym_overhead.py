"""Per-step overhead of ``dua_mujoco.gym.PredictCollisions`` on gymnasium's MuJoCo envs.

    python benchmarks/gym_overhead.py                   # prints a markdown table (about 1 min)
    python benchmarks/gym_overhead.py --rounds 3 --steps 100
    python benchmarks/gym_overhead.py --before /tmp/before \
        --before-python /tmp/before/.venv/bin/python     # A/B against another checkout

For each env a plain env and a wrapped one (default predictor options, ``cost="alarm"``) take the
same seeded random actions from the same seeded reset. Rounds alternate plain and wrapped; each
round times every ``env.step`` call of ``--steps`` steps and keeps their median. A number in the
table is the median over rounds of those per-round medians; the ratio is wrapped / plain from
those medians, the overhead their difference. A third env, wrapped by a wrapper that makes one
call into the native core a step and no predictor step (the runtime's ``watched``), gives the
floor of any wrapper that steps a predictor natively, less the step itself. In a fourth env,
wrapped the same and stepped in the same rounds but left out of the ratio (the timers' own calls
are about 0.2 us a step), ``predictor.step`` and the wrapper's bookkeeping (``_observe``:
standing alarms, ``min_tau``, names) are timed apart (``predictor.step``: the runtime's
``step_watched`` or ``step_info`` where the wrapper calls that instead; ``step_info`` writes
``info`` too, and the bookkeeping reads 0) (the medians of their calls); what the two leave of
the overhead is the rest of the wrapper's ``step`` and the caches the predictor's work takes
from MuJoCo's.

The paired ratio steps the plain and the wrapped env in turn, one step each with the same
action, the order alternating step by step (the second finds MuJoCo's code warm from the first),
and gives the median over rounds of each round's median wrapped / median plain: both sides of
the ratio see the same load, which the rounds above (400 steps of one env, then of the other)
do not on a shared machine. Two plain envs paired the same way give the method's own spread
(plain / plain, 1.000 when exact).

With ``--before``, another checkout is measured too, in its own environment: each side runs
this script in a subprocess (``--json``, ``--rounds`` rounds), the sides alternating
``--repeats`` times; a figure is the median over repeats, and the table gives each side's ratio.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from dua_mujoco.gym import PredictCollisions

ENVS = ("Ant-v5", "Humanoid-v5", "Pusher-v5")


def _make(env_id: str) -> gym.Env:
    make = {"terminate_when_unhealthy": False} if env_id in ("Ant-v5", "Humanoid-v5") else {}
    return gym.make(env_id, max_episode_steps=10**9, **make)


def _paired(plain: gym.Env, wrapped: gym.Env, steps: int, seed: int) -> tuple[float, float]:
    """Median seconds of one ``env.step`` of each env over ``steps`` steps from the same seeded
    reset, the two envs stepping in turn (the same action to both): both see the same load."""
    for env in (plain, wrapped):
        env.reset(seed=seed)
    plain.action_space.seed(seed)
    envs = (plain, wrapped)
    times = np.empty((steps, 2))
    for k in range(steps):
        action = plain.action_space.sample()
        # The second of the two steps finds MuJoCo's code warm from the first: the order
        # alternates, so each env takes each place in half of the steps.
        first = k % 2
        t0 = time.perf_counter()
        envs[first].step(action)
        t1 = time.perf_counter()
        envs[1 - first].step(action)
        times[k, first], times[k, 1 - first] = t1 - t0, time.perf_counter() - t1
    return float(np.median(times[:, 0])), float(np.median(times[:, 1]))


def _round(env: gym.Env, steps: int, seed: int) -> float:
    """Median seconds of one ``env.step`` over ``steps`` steps from a seeded reset."""
    env.reset(seed=seed)
    env.action_space.seed(seed)
    times = np.empty(steps)
    for k in range(steps):
        action = env.action_space.sample()
        t0 = time.perf_counter()
        env.step(action)
        times[k] = time.perf_counter() - t0
    return float(np.median(times))


class _TimedRuntime:
    """A runtime whose ``step_watched`` is timed as the predictor's step; the rest passes."""

    def __init__(self, runtime: Any, timed: Callable[..., Any]) -> None:
        self._runtime = runtime
        self.step_watched = timed(runtime.step_watched, "predictor")

    def __getattr__(self, name: str) -> Any:
        return getattr(self._runtime, name)


class _OneCall(gym.Wrapper):
    """The floor of any wrapper that steps a predictor natively: the wrapper layer and one call
    into the native core a step (the runtime's ``watched``, which reads three numbers), no
    predictor step."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self._runtime = PredictCollisions(env).predictor._rt

    def step(self, action: Any) -> Any:
        out = self.env.step(action)
        self.last = self._runtime.watched
        return out


def measure(env_id: str, *, rounds: int, steps: int) -> dict[str, float]:
    plain = _make(env_id)
    twin = _make(env_id)  # a second plain env, paired with the first: the null ratio
    wrapped = PredictCollisions(_make(env_id))
    one_call = _OneCall(_make(env_id))
    probe = PredictCollisions(_make(env_id))  # timed inside; its own time is not reported
    predictor = probe.predictor
    parts: dict[str, list[float]] = {"predictor": [], "observe": []}

    def timed(fn: Callable[..., Any], name: str) -> Callable[..., Any]:
        def call(*args: Any) -> Any:
            t0 = time.perf_counter()
            out = fn(*args)
            parts[name].append(time.perf_counter() - t0)
            return out

        return call

    # Instance attributes shadow the methods: the timers wrap only the probe's calls. The wrapper
    # steps the predictor through Predictor.step (before issue 42's last cut) or through its
    # runtime's step_watched (a native object takes no attributes: a proxy times it).
    predictor.step = timed(predictor.step, "predictor")  # type: ignore[method-assign]
    if hasattr(probe, "_observe"):
        probe._observe = timed(probe._observe, "observe")
    if hasattr(probe, "_step_info"):  # the step and the info in one call (issue 42, pusher42)
        probe._step_info = timed(probe._step_info, "predictor")
    elif hasattr(probe._runtime, "step_watched"):
        probe._runtime = _TimedRuntime(probe._runtime, timed)
    for env in (plain, twin, wrapped, one_call, probe):  # warm-up: caches, the step's first call
        _round(env, 20, 0)
    names = (
        "plain",
        "wrapped",
        "one_call",
        "predictor",
        "observe",
        "paired_plain",
        "paired_wrapped",
    )
    rows: dict[str, list[float]] = {k: [] for k in names}
    ratios: dict[str, list[float]] = {"paired": [], "null": []}  # paired rounds' ratios
    for r in range(rounds):
        for name in parts:
            parts[name].clear()
        rows["plain"].append(_round(plain, steps, r))
        rows["wrapped"].append(_round(wrapped, steps, r))
        rows["one_call"].append(_round(one_call, steps, r))
        _round(probe, steps, r)
        pair = _paired(plain, wrapped, steps, r)
        rows["paired_plain"].append(pair[0])
        rows["paired_wrapped"].append(pair[1])
        ratios["paired"].append(pair[1] / pair[0])
        null = _paired(plain, twin, steps, r)  # two plain envs: the method's own spread
        ratios["null"].append(null[1] / null[0])
        for name, times in parts.items():
            rows[name].append(float(np.median(times)) if times else 0.0)
    out = {f"{k}_us": float(np.median(v)) * 1e6 for k, v in rows.items()}
    out["paired_ratio"] = float(np.median(ratios["paired"]))
    out["null_ratio"] = float(np.median(ratios["null"]))
    return {**out, "pairs": predictor.nsphere_pairs, "frame_skip": predictor.period}


def ab(args: argparse.Namespace) -> None:
    """Both sides, alternating, each in its own environment; their ratios side by side."""
    from checkouts import same_mujoco  # a sibling script: the tests load this file by its path

    same_mujoco(args.before_python)
    sides = {"before": (args.before_python, args.before), "after": (sys.executable, Path.cwd())}
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    runs: dict[str, list[dict[str, dict[str, float]]]] = {s: [] for s in sides}
    for r in range(args.repeats):
        for side, (python, checkout) in sides.items():
            argv = [python, str(Path(__file__).resolve()), "--json", "--envs", *args.envs]
            argv += ["--rounds", str(args.rounds), "--steps", str(args.steps)]
            proc = subprocess.run(argv, env=env, cwd=checkout, capture_output=True, text=True)
            if proc.returncode:
                raise RuntimeError(f"{checkout} failed:\n{proc.stderr[-3000:]}")
            runs[side].append(json.loads(proc.stdout.strip().splitlines()[-1]))
        print(f"repeat {r + 1}/{args.repeats}", file=sys.stderr, flush=True)
    print(
        "| env | env.step plain before (us) | wrapped before (us) | ratio before "
        "| plain after (us) | wrapped after (us) | ratio after | predictor.step after (us) "
        "| bookkeeping after (us) | one native call, after | paired ratio before "
        "| paired ratio after | plain / plain, paired (before; after) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for env_id in args.envs:
        med = {
            s: {
                k: float(np.median([run[env_id][k] for run in runs[s]])) for k in runs[s][0][env_id]
            }
            for s in sides
        }
        b, a = med["before"], med["after"]
        nan = float("nan")
        print(
            f"| {env_id} | {b['plain_us']:.1f} | {b['wrapped_us']:.1f} "
            f"| {b['wrapped_us'] / b['plain_us']:.3f} | {a['plain_us']:.1f} "
            f"| {a['wrapped_us']:.1f} | {a['wrapped_us'] / a['plain_us']:.3f} "
            f"| {a['predictor_us']:.1f} | {a['observe_us']:.1f} "
            f"| {a['one_call_us'] / a['plain_us']:.3f} | {b.get('paired_ratio', nan):.3f} "
            f"| {a['paired_ratio']:.3f} | {b.get('null_ratio', nan):.3f}; "
            f"{a['null_ratio']:.3f} |",
            flush=True,
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--envs", nargs="+", default=list(ENVS))
    parser.add_argument("--rounds", type=int, default=9)
    parser.add_argument("--steps", type=int, default=400)
    parser.add_argument("--before", type=Path, help="another checkout, A/B against this one")
    parser.add_argument("--before-python", default=sys.executable, help="its Python (own venv)")
    parser.add_argument("--repeats", type=int, default=3, help="A/B: alternations of the sides")
    parser.add_argument("--json", action="store_true", help="one JSON line (for --before)")
    args = parser.parse_args()
    if args.before is not None:
        ab(args)
        return
    if args.json:
        results = {e: measure(e, rounds=args.rounds, steps=args.steps) for e in args.envs}
        print(json.dumps(results))
        return
    print(
        "| env | frame_skip | sphere pairs | env.step plain (us) | wrapped (us) | ratio "
        "| overhead (us) | of it predictor.step (us) | of it bookkeeping (us) "
        "| one native call / plain | paired ratio | plain / plain, paired |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for env_id in args.envs:
        m = measure(env_id, rounds=args.rounds, steps=args.steps)
        print(
            f"| {env_id} | {m['frame_skip']} | {m['pairs']} | {m['plain_us']:.1f} "
            f"| {m['wrapped_us']:.1f} | {m['wrapped_us'] / m['plain_us']:.3f} "
            f"| {m['wrapped_us'] - m['plain_us']:.1f} | {m['predictor_us']:.1f} "
            f"| {m['observe_us']:.1f} | {m['one_call_us'] / m['plain_us']:.3f} "
            f"| {m['paired_ratio']:.3f} | {m['null_ratio']:.3f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
