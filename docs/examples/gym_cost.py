"""The predicted-collision cost over one episode of gymnasium MuJoCo envs (trains nothing).

    python docs/examples/gym_cost.py               # Pusher-v5 and Ant-v5: docs/img/gym-cost.png
    python docs/examples/gym_cost.py --envs Ant-v5 --steps 100 --out /tmp/ant.png

Random actions, one seed, one episode per env (a column). The top panel is ``info["cost"]``
(``cost="alarm"``: 1 while a counted geom pair stands in alarm) with the contact onsets of counted
pairs that MuJoCo reported (the exact stage): green when the pair stood in alarm at that step,
red otherwise. The bottom panel is ``info["min_tau"]``, the least time to collision the
predictor vouches for, against one env step. Resting contact the task wants is ignored: Pusher's
object on the table, Ant's ankles on the floor.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from dua_mujoco.gym import PredictCollisions

ROOT = Path(__file__).resolve().parents[2]
# Resting contact each task wants (a geom, or a pair of geoms): not counted.
IGNORE: dict[str, list[str | tuple[str, str]]] = {
    "Pusher-v5": [("table", "geom18")],  # the object (an unnamed geom) on the table
    "Ant-v5": ["left_ankle_geom", "right_ankle_geom", "third_ankle_geom", "fourth_ankle_geom"],
    "Humanoid-v5": [("floor", "left_foot"), ("floor", "right_foot")],
}


def episode(env_id: str, steps: int, seed: int) -> dict:
    """One episode of random actions: the cost, min tau and contact onsets of every step."""
    make = {"terminate_when_unhealthy": False} if env_id in ("Ant-v5", "Humanoid-v5") else {}
    ignore = IGNORE.get(env_id, [])
    env = PredictCollisions(gym.make(env_id, max_episode_steps=steps, **make), ignore=ignore)
    ignored = {frozenset(p) if isinstance(p, tuple) else p for p in ignore}
    data = env.unwrapped.data  # type: ignore[attr-defined]
    names = [str(n) for n in env.predictor.tables.geom_names]

    def contacts() -> set[tuple[str, str]]:
        pairs = zip(data.contact.geom1[: data.ncon], data.contact.geom2[: data.ncon], strict=True)
        named = {(names[min(a, b)], names[max(a, b)]) for a, b in pairs}
        return {p for p in named if frozenset(p) not in ignored and not set(p) & ignored}

    env.reset(seed=seed)
    env.action_space.seed(seed)
    cost, tau, onsets = [], [], []
    before = contacts()
    truncated = terminated = False
    while not (truncated or terminated):
        _, _, terminated, truncated, info = env.step(env.action_space.sample())
        cost.append(info["cost"])
        tau.append(info["min_tau"])
        now = contacts()
        onsets += [(len(cost), p in info["alarm_pairs"]) for p in sorted(now - before)]
        before = now
    env.close()
    return {"cost": cost, "tau": tau, "onsets": onsets, "dt": env.predictor.dt}


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--envs", nargs="+", default=["Pusher-v5", "Ant-v5"])
    parser.add_argument("--steps", type=int, default=100, help="episode length (env steps)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, default=ROOT / "docs/img/gym-cost.png")
    args = parser.parse_args()

    fig, axes = plt.subplots(
        2, len(args.envs), figsize=(4.6 * len(args.envs), 4.4), squeeze=False, sharey="row"
    )
    for col, env_id in enumerate(args.envs):
        run = episode(env_id, args.steps, args.seed)
        cost, onsets, dt = run["cost"], run["onsets"], run["dt"]
        t = dt * np.arange(1, len(cost) + 1)
        ax1, ax2 = axes[0, col], axes[1, col]
        ax1.fill_between(t, cost, step="pre", color="tab:orange", alpha=0.6, label='info["cost"]')
        for i, (k, alarmed) in enumerate(onsets):
            label = "contact onset (MuJoCo)" if i == 0 else None
            ax1.axvline(k * dt, color="tab:green" if alarmed else "tab:red", lw=0.8, label=label)
        missed = sum(not a for _, a in onsets)
        ax1.set_title(
            f"{env_id}, seed {args.seed}: mean cost {np.mean(cost):.2f}\n"
            f"{len(onsets)} contact onsets of counted pairs, {missed} without an alarm",
            fontsize=9,
        )
        ax1.set_ylim(0, 1.3)
        ax1.legend(loc="upper left", fontsize=7)
        shown = np.clip(np.asarray(run["tau"]), 1e-4, None) * 1e3
        ax2.step(t, shown, where="pre", color="tab:blue", lw=1, label='info["min_tau"]')
        ax2.axhline(
            dt * 1e3, color="0.4", ls="--", lw=0.8, label=f"one env step ({dt * 1e3:.0f} ms)"
        )
        ax2.set_yscale("log")
        ax2.set_xlabel("simulation time (s)")
        ax2.legend(loc="upper left", fontsize=7)
        print(f"{env_id}: {len(cost)} steps, mean cost {np.mean(cost):.3f}, {len(onsets)} onsets")
    axes[0, 0].set_ylabel("cost")
    axes[1, 0].set_ylabel("min tau (ms; 0 drawn at 0.1)")
    fig.tight_layout()
    fig.savefig(args.out, dpi=90)
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
