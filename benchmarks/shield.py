"""The shield's scenes under each safety layer: contacts with the robot moving, progress, cost.

    python benchmarks/shield.py                                   # 20 episodes a scene, peers
    python benchmarks/shield.py --layers none reference ttc damper --episodes 5
    python benchmarks/shield.py --episodes 340 --json docs/img/shield.json
    python benchmarks/shield.py --merge a.json b.json             # the table of runs' episodes

Layers: ``none``; ``shield`` (``dua_mujoco.Shield`` as a user would configure it on the scene:
its declared bounds and its failsafe, the brake on person_cell and arm_pair, the evasive
``Evade(sideways=True)`` at gain 0.9 on mobile_cell; ``FAILSAFES`` of
``dua_mujoco/experiments/shield/bench.py``); ``shield-brake`` (the same with the brake on every
scene); ``shield-noscreen`` (``shield`` without its screen); ``ttc`` (MoveIt Servo's
stop-distance halt, its defaults); ``ttc-scale`` (its threshold-distance velocity scaling);
``damper`` (mink's collision-avoidance limit on the intended motion, its defaults);
``reference``: the slow reference shield of ``tests/reference_shield.py`` (the intended controls
for one control period then the brake, rolled out and checked against the protected bodies'
declared bounds every period; a prototype of ``dua_mujoco.Shield``). Every layer runs the same
seeds; see ``dua_mujoco/experiments/shield/episodes.py`` for what is counted.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from dua_mujoco.experiments.report import jsonable
from dua_mujoco.experiments.shield.bench import PEERS, SHIELDS, any_layer, run_many, summary
from dua_mujoco.experiments.shield.episodes import EpisodeResult, Layer, SceneSetup
from dua_mujoco.models.cells import SHIELD_SCENES

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from reference_shield import shield_for


def make_layer(setup: SceneSetup, name: str) -> Layer:
    """The peers, and ``reference``: the slow reference shield."""
    return shield_for(setup) if name == "reference" else any_layer(setup, name)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scenes", nargs="+", default=list(SHIELD_SCENES))
    parser.add_argument("--layers", nargs="+", default=list(PEERS) + list(SHIELDS))
    parser.add_argument("--episodes", type=int, default=20, help="episodes a scene")
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--json", type=Path, help="write every episode's counts here")
    parser.add_argument(
        "--merge", nargs="+", type=Path, help="print the table of these --json files' episodes"
    )
    args = parser.parse_args()
    if args.merge:
        # Runs of other seeds (a long run in parts): one table, as run_many orders it.
        runs = [EpisodeResult(**r) for path in args.merge for r in json.loads(path.read_text())]
        print(summary(sorted(runs, key=lambda r: (r.scene, r.layer, r.seed))))
        print(f"\n{len(runs)} episodes from {len(args.merge)} runs")
        return
    seeds = range(args.first_seed, args.first_seed + args.episodes)
    start = time.perf_counter()
    results = run_many(args.scenes, args.layers, list(seeds), make=make_layer, jobs=args.jobs)
    print(summary(results))
    print(
        f"\n{len(results)} episodes ({args.episodes} a scene and layer), "
        f"{time.perf_counter() - start:.0f} s on {args.jobs} processes"
    )
    if args.json:
        args.json.write_text(json.dumps(jsonable([r.as_dict() for r in results]), indent=1))


if __name__ == "__main__":
    main()
