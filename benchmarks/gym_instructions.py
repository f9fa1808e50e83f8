"""A loop of ``env.step`` calls to count under callgrind: plain or wrapped by ``PredictCollisions``.

    valgrind --tool=callgrind --collect-atstart=no --toggle-collect=functools_reduce \\
        python benchmarks/gym_instructions.py wrapped 1000 Pusher-v5

The loop runs inside ``functools.reduce`` (a C function callgrind can toggle on), over seeded
uniform actions after 50 warm-up steps, so only the steps are counted: (wrapped - plain) / steps
is what the wrapper adds a step. MuJoCo's pybind11 bindings move the count of the same build by
up to about 1 k a step from run to run (docs/benchmarks.md, issue 42): compare the native call's
and libpython's counts (``callgrind_annotate``), or many runs.
"""

from __future__ import annotations

import argparse
import functools

import gymnasium as gym
import numpy as np

from dua_mujoco.gym import PredictCollisions


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("mode", choices=("plain", "wrapped", "empty"))
    parser.add_argument("steps", type=int)
    parser.add_argument("env", nargs="?", default="Pusher-v5")
    args = parser.parse_args()
    healthy = {"terminate_when_unhealthy": False} if args.env in ("Ant-v5", "Humanoid-v5") else {}
    env = gym.make(args.env, max_episode_steps=10**9, **healthy)
    if args.mode == "wrapped":
        env = PredictCollisions(env)
    elif args.mode == "empty":  # the gymnasium wrapper layer alone
        env = gym.Wrapper(env)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    low, high = env.action_space.low, env.action_space.high  # type: ignore[attr-defined]
    actions = [rng.uniform(low, high) for _ in range(50 + args.steps)]
    for a in actions[:50]:
        env.step(a)
    step = env.step
    functools.reduce(lambda _, a: step(a), actions[50:], None)


if __name__ == "__main__":
    main()
