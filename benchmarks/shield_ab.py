"""A/B: the shield's decisions bit for bit, and its cost, from this checkout and another one.

    git worktree add --detach /tmp/before main     # then build it in a venv of its own
    python benchmarks/shield_ab.py --before-python /tmp/before/.venv/bin/python --episodes 60
    python benchmarks/shield_ab.py --before-python /tmp/before/.venv/bin/python --episodes 20 \\
        --hash

Each side runs the ``shield`` layer of ``benchmarks/shield.py`` (``--layer``: another of its
shields) on the same seeds, in its own subprocess (its own Python: the other checkout's native
library), the two sides interleaved by chunks of ``--chunk`` episodes (which goes first
alternates). Per scene: how many episodes' counts (interventions, contacts, progress) are the
same on both sides, the cost (the layer's time over ``mj_step``'s) median over episodes on each,
and the median of after / before per episode. ``--hash`` also digests every control the shield
returned (the hashing is inside the timed call: read the costs of a run without it). ``--brake``
gives both sides the brake as the failsafe (``failsafe=None``, which every checkout reads as the
brake): mobile_cell's ``shield`` has the evasive failsafe since shield40b, the brake before
(1b67fc7 and older, which do not know ``shield-brake``), so against those its A/B needs
``--brake``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from pathlib import Path

from checkouts import same_mujoco

# Runs inside each side's subprocess.
PROBE = r"""
import hashlib, json, sys
import numpy as np
from dua_mujoco.experiments.shield.bench import run_many, shield_layer

scene, seeds, digest = sys.argv[1], [int(s) for s in sys.argv[2].split(",")], sys.argv[3] == "1"
which, brake = sys.argv[4], sys.argv[5] == "1"


class Hashed:
    def __init__(self, inner):
        self.inner, self.h = inner, hashlib.sha256()

    def __call__(self, data, intended):
        ctrl = self.inner(data, intended)
        self.h.update(np.asarray(ctrl, dtype=np.float64).tobytes())
        return ctrl

    def __getattr__(self, name):
        return getattr(self.inner, name)


made = []


def make(setup, name):
    layer = shield_layer(setup, name, failsafe=None) if brake else shield_layer(setup, name)
    if digest:
        layer = Hashed(layer)
        made.append(layer)
    return layer


out = []
for i, r in enumerate(run_many([scene], [which], seeds, make=make, jobs=1, progress=False)):
    d = r.as_dict()
    if digest:
        d["ctrl_sha"], d["counts"] = made[i].h.hexdigest(), made[i].inner.counts
    out.append(d)
print(json.dumps(out))
"""

TIMING = {"layer_seconds", "step_seconds"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--before-python", required=True, help="the other checkout's python")
    parser.add_argument("--scenes", nargs="+", default=["person_cell", "arm_pair", "mobile_cell"])
    parser.add_argument("--episodes", type=int, default=20, help="episodes a scene (seeds 0..)")
    parser.add_argument("--chunk", type=int, default=5)
    parser.add_argument("--hash", action="store_true", help="digest every control returned")
    parser.add_argument("--layer", default="shield", help="the shield layer both sides run")
    parser.add_argument("--brake", action="store_true", help="the brake as every side's failsafe")
    args = parser.parse_args()
    same_mujoco(args.before_python)
    sides = {"before": args.before_python, "after": sys.executable}
    for scene in args.scenes:
        res: dict[str, list[dict]] = {"before": [], "after": []}
        for c0 in range(0, args.episodes, args.chunk):
            seeds = ",".join(map(str, range(c0, min(args.episodes, c0 + args.chunk))))
            order = ["before", "after"] if (c0 // args.chunk) % 2 == 0 else ["after", "before"]
            for side in order:
                run = subprocess.run(
                    [sides[side], "-c", PROBE, scene, seeds, "1" if args.hash else "0", args.layer,
                     "1" if args.brake else "0"],
                    capture_output=True, text=True, check=True, cwd=Path("/tmp"),
                )  # fmt: skip
                res[side] += json.loads(run.stdout)
        b, a = res["before"], res["after"]
        pairs = zip(b, a, strict=True)
        same = sum(all(x[k] == y[k] for k in x if k not in TIMING) for x, y in pairs)
        cb = [x["layer_seconds"] / x["step_seconds"] for x in b]
        ca = [x["layer_seconds"] / x["step_seconds"] for x in a]
        ratio = statistics.median(y / x for x, y in zip(cb, ca, strict=True))
        print(
            f"{scene}: {len(b)} episodes, identical {same}/{len(b)}; cost median before "
            f"{statistics.median(cb):.3f}x after {statistics.median(ca):.3f}x; after/before "
            f"median per episode {ratio:.3f}"
        )


if __name__ == "__main__":
    main()
