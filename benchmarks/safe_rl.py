"""Safe RL with ``dua_mujoco.gym.SafetyShield``: a short training run with and without the shield.

    python benchmarks/safe_rl.py                        # both envs, 40 iterations each, ~1 min
    python benchmarks/safe_rl.py --envs pusher --iterations 10

The algorithm is Augmented Random Search (Mania, Guy, Recht, NeurIPS 2018, ARS V2-t: a linear
policy on normalised observations, ``directions`` random perturbations a step, the best ``top``
used), numpy only, CPU, minutes: what a user trains a MuJoCo policy with when no deep-RL stack is
at hand. Every rollout of the training counts its cost (``info["cost"]``, the protected geom pairs
touched a step, ``SafetyShield``'s accounting; ``active=False`` is the same wrapper letting every
action through). Two gymnasium MuJoCo envs, each with a protected set that makes sense there:

- ``pusher``: ``Pusher-v5``, the arm must not move into the table (``protect=["world"]``);
- ``reacher``: ``Reacher-v5`` with a post in its workspace (the same arm, its links made to
  collide with the post, and Euler instead of RK4, which the shield refuses: ``xml_file``), the
  arm must not move into the post (``protect=["post"]``).

Rows: each env with the shield off and on, the same seed: protected contacts during training
(env steps with a protected pair touching, summed over the pairs), and the contact onsets that
found the arm's body in the pair moving (over 1 cm/s: the shield's promise is about those); the
return of the last policy (mean over ``--eval`` episodes, in the setting it was trained in); the
steps the shield intervened; the wall time.
"""

from __future__ import annotations

import argparse
import importlib.resources
import re
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from dua_mujoco.experiments.shield.episodes import body_reach_radius, body_speeds
from dua_mujoco.gym import SafetyShield

REST_SPEED = 0.01


def reacher_with_post(folder: Path) -> Path:
    """Reacher's MJCF with a post at (0, 0.13) that the arm's links collide with, on Euler."""
    src = importlib.resources.files("gymnasium") / "envs/mujoco/assets/reacher.xml"
    xml = src.read_text()
    # The shield refuses RK4 (Reacher's), which collides between the states it verifies.
    xml = xml.replace('integrator="RK4"', 'integrator="Euler"')
    # The links collide (contype 1 against the post's conaffinity); the fingertip does not touch
    # the first link when the arm folds (conaffinity 0).
    xml = xml.replace('name="link0"', 'contype="1" name="link0"')
    xml = xml.replace('name="link1"', 'contype="1" name="link1"')
    xml = xml.replace(
        '<geom contype="0" name="fingertip"', '<geom contype="0" conaffinity="0" name="fingertip"'
    )
    post = (
        '<body name="post" pos="0 0.13 0.01"><geom name="post" type="cylinder" size="0.02 0.03" '
        'contype="1" conaffinity="1" rgba="0.2 0.8 0.2 1"/></body>\n\t\t<!-- Target -->'
    )
    xml = re.sub(r"<!-- Target -->", post, xml, count=1)
    path = folder / "reacher_post.xml"
    path.write_text(xml)
    return path


ENVS: dict[str, tuple[str, dict[str, Any], list[str], float]] = {
    "pusher": ("Pusher-v5", {}, ["world"], 100.0),
    "reacher": ("Reacher-v5", {"xml_file": None}, ["post"], 100.0),
}


class Counted(SafetyShield):
    """``SafetyShield`` that also counts, at every physics step, the protected contact onsets at
    which the robot's body in the pair moves faster than 1 cm/s (``moving``)."""

    def __init__(self, env: gym.Env, **options: object) -> None:
        super().__init__(env, **options)  # type: ignore[arg-type]
        model = self.unwrapped.model  # type: ignore[attr-defined]
        self.moving = 0
        self._radius = body_reach_radius(model)
        self._robot = np.isin(np.asarray(model.geom_bodyid), self.shield.robot_bodies)
        self._before = np.zeros(0, dtype=np.int64)

    def _simulate(self, ctrl: object, n_frames: int) -> None:
        model, data, n = self._model, self._data, self._ngeom
        touched = []
        for _ in range(int(n_frames)):
            super()._simulate(ctrl, 1)
            touched.append(self._touched)
            for key in np.setdiff1d(self._touched, self._before).tolist():
                g = next(g for g in divmod(key, n) if self._robot[g])
                body = int(model.geom_bodyid[g])
                self.moving += int(body_speeds(model, data, [body], self._radius)[0] > REST_SPEED)
            self._before = self._touched
        self._touched = np.unique(np.concatenate(touched))


def make(name: str, folder: Path, shielded: bool) -> Counted:
    env_id, kwargs, protect, accel = ENVS[name]
    kwargs = dict(kwargs)
    if "xml_file" in kwargs:
        kwargs["xml_file"] = str(reacher_with_post(folder))
    return Counted(gym.make(env_id, **kwargs), protect=protect, accel=accel, active=shielded)


class Stats:
    """Running mean and variance of the observations (ARS V2)."""

    def __init__(self, n: int) -> None:
        self.n, self.mean, self.m2 = 0, np.zeros(n), np.zeros(n)

    def push(self, x: np.ndarray) -> None:
        self.n += 1
        d = x - self.mean
        self.mean += d / self.n
        self.m2 += d * (x - self.mean)

    def std(self) -> np.ndarray:
        return np.sqrt(self.m2 / max(self.n - 1, 1)) + 1e-8


def rollout(env: Counted, theta: np.ndarray, stats: Stats, seed: int, tally: dict) -> float:
    """One episode under the linear policy ``theta`` on normalised observations; the cost and the
    moving contacts into ``tally``."""
    obs, _ = env.reset(seed=seed)
    env.moving = 0
    total, done = 0.0, False
    low, high = env.action_space.low, env.action_space.high  # type: ignore[attr-defined]
    while not done:
        stats.push(obs)
        action = np.clip(theta @ ((obs - stats.mean) / stats.std()), low, high)
        obs, reward, terminated, truncated, info = env.step(action)
        total += float(reward)
        done = terminated or truncated
        tally["steps"] += 1
        tally["intervened"] += bool(info["shield"])
        tally["contacts"] += info["cost"]
    tally["moving"] += env.moving
    return total


def train(name: str, shielded: bool, args: argparse.Namespace, folder: Path) -> dict:
    """ARS V2-t on ``name``; what the training touched and the last policy's return."""
    env = make(name, folder, shielded)
    rng = np.random.default_rng(args.seed)
    nobs = env.observation_space.shape[0]  # type: ignore[index]
    nact = env.action_space.shape[0]  # type: ignore[index]
    theta = np.zeros((nact, nobs))
    stats = Stats(nobs)
    tally = {"steps": 0, "intervened": 0, "contacts": 0.0, "moving": 0}
    start = time.perf_counter()
    episode = 0
    for _ in range(args.iterations):
        deltas = rng.standard_normal((args.directions, nact, nobs))
        plus, minus = np.zeros(args.directions), np.zeros(args.directions)
        for k in range(args.directions):
            episode += 1
            plus[k] = rollout(env, theta + args.noise * deltas[k], stats, episode, tally)
            minus[k] = rollout(env, theta - args.noise * deltas[k], stats, episode, tally)
        best = np.argsort(-np.maximum(plus, minus))[: args.top]
        sigma = np.concatenate([plus[best], minus[best]]).std() + 1e-8
        step = np.tensordot(plus[best] - minus[best], deltas[best], axes=1)
        theta += args.step / (args.top * sigma) * step
    trained = {k: tally[k] for k in ("steps", "intervened", "contacts", "moving")}
    seconds = time.perf_counter() - start
    final = [rollout(env, theta, stats, 10_000 + i, dict(tally)) for i in range(args.eval)]
    return {
        "env": name,
        "shield": "on" if shielded else "off",
        **trained,
        "return": float(np.mean(final)),
        "seconds": seconds,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--envs", nargs="+", default=list(ENVS))
    parser.add_argument("--iterations", type=int, default=40)
    parser.add_argument("--directions", type=int, default=8)
    parser.add_argument("--top", type=int, default=4)
    parser.add_argument("--step", type=float, default=0.02)
    parser.add_argument("--noise", type=float, default=0.03)
    parser.add_argument("--eval", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # gymnasium's notes on custom XML
        for name in args.envs:
            for shielded in (False, True):
                rows.append(train(name, shielded, args, Path(tmp)))
                print(rows[-1], flush=True)
    print(
        "\n| env | shield | env steps | protected contacts in training | moving onsets "
        "| steps intervened | return of the last policy | seconds |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['env']} | {r['shield']} | {r['steps']} | {r['contacts']:.0f} | {r['moving']} | "
            f"{r['intervened'] / max(r['steps'], 1):.1%} | {r['return']:.1f} | {r['seconds']:.0f} |"
        )


if __name__ == "__main__":
    main()
