"""mobile_cell: where the shield loses the base's progress, and whether an evasive failsafe wins
it back (docs/shield.md, "mobile_cell: where the progress goes").

    python benchmarks/shield_evade.py --episodes 30                     # seeds 0-29
    python benchmarks/shield_evade.py --layers none shield evade0.9 p5 stop0.6 --episodes 30
    python benchmarks/shield_evade.py --layers none evade0.9 --first-seed 30 --episodes 304 \
        --jsonl b.jsonl                                             # each episode as it ends
    python benchmarks/shield_evade.py --merge a.jsonl b.jsonl       # the tables of runs' parts

Layers, every one on the same seeds, all in one run (A/B): ``none``; ``shield`` (the brake,
passed explicitly: ``benchmarks/shield.py``'s ``shield-brake``; its ``shield`` on mobile_cell
is this script's ``side0.9``); ``evade`` (the same shield with the library's native evasive
failsafe, ``dua_mujoco.shield.failsafe.Evade``, as ``dua_mujoco/experiments/shield/evade.py``
builds it; ``evade0.9``: its gain 0.9, ``evade``: ``--gain``); ``pyevade`` (the same law as a Python
policy, ``tests/reference_evade.py``, called at every rolled step: what the native one saves);
``side`` (the native one steering across the base's velocity, ``sideways=True``; ``side0.9``:
gain 0.9);
``p5`` (the brake, a control period of 5 physics steps instead of 10: the task still updates
every 10); ``stop0.6`` (the brake, ``stop_time`` 0.6 s instead of 0.45). Besides
``benchmarks/shield.py``'s table, each layer's physics steps split by what the base did: the
intended controls applied (*passing*, and the base's mean planar speed then), or the failsafe's
with the base moving or at rest (over 1 cm/s or not), touching a protected body or not; *stops*:
passing -> failsafe changes, the base's mean speed at them, and how many reached rest; the
shield's broken-hypothesis counts (a push breaks the plan: they count where the guarantee was
lost, and why).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import sys
import time
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco.experiments.report import jsonable, table
from dua_mujoco.experiments.shield.bench import peer_layer, shield_layer, summary
from dua_mujoco.experiments.shield.episodes import EpisodeResult, Layer, SceneSetup, run_episode
from dua_mujoco.experiments.shield.evade import native

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from reference_evade import EvadePolicy

SCENE = "mobile_cell"
KINDS = (
    "passing",
    "failsafe, moving, clear",
    "failsafe, moving, touched",
    "failsafe, at rest, clear",
    "failsafe, at rest, touched",
)
BREAKS = ("plan_breaks", "hold_breaks", "stop_breaks", "unverified", "bound_events")


class Watch:
    """A layer as it is, counting each step's kind (the module docstring) before the step."""

    def __init__(self, inner: Layer, setup: SceneSetup) -> None:
        self.inner = inner
        model = setup.model
        self.v = np.asarray(setup.brake.dofs[:2])
        ngeom = int(model.ngeom)
        self.watched = np.zeros((ngeom, ngeom), dtype=bool)
        self.watched[setup.pairs[:, 0], setup.pairs[:, 1]] = True
        self.watched[setup.pairs[:, 1], setup.pairs[:, 0]] = True
        self.kind = np.zeros(len(KINDS), dtype=np.int64)
        self.pass_speed = 0.0
        self.stops = 0
        self.stop_speed = 0.0
        self.to_rest = 0  # failsafe streaks in which the base came to rest
        self.rested = False
        self.was = False

    @property
    def interventions(self) -> int:
        """The inner layer's."""
        return int(self.inner.interventions)

    @property
    def guaranteed(self) -> bool:
        """The inner layer's, if it says."""
        return bool(getattr(self.inner, "guaranteed", True))

    def reset(self, data: mujoco.MjData) -> None:
        """The inner layer's."""
        self.inner.reset(data)

    def __call__(self, data: mujoco.MjData, intended: npt.ArrayLike) -> np.ndarray:
        """The inner layer's controls; the step counted by kind."""
        before = self.inner.interventions
        ctrl = self.inner(data, intended)
        now = self.inner.interventions > before
        speed = float(np.linalg.norm(data.qvel[self.v]))
        if not now:
            self.kind[0] += 1
            self.pass_speed += speed
        else:
            geoms = np.asarray(data.contact.geom)[: data.ncon]
            touched = bool(data.ncon) and bool(self.watched[geoms[:, 0], geoms[:, 1]].any())
            rest = speed <= 0.01
            self.kind[1 + 2 * rest + touched] += 1
            if not self.was:
                self.stops += 1
                self.stop_speed += speed
                self.rested = False
            if rest and not self.rested:
                self.to_rest += 1
                self.rested = True
        self.was = now
        return ctrl


def make_layer(setup: SceneSetup, name: str, gain: float) -> Layer:
    """A layer by name (the module docstring)."""
    if name == "none":
        return peer_layer(setup, name)
    if name == "shield":  # the brake, not the scene's failsafe
        return shield_layer(setup, "shield-brake")
    if name == "p5":
        return shield_layer(setup, "shield-brake", period=5)
    if name.startswith("stop"):
        return shield_layer(setup, "shield-brake", stop_time=float(name[4:]))
    if name.startswith("evade"):
        return shield_layer(setup, "shield", failsafe=native(setup, gain=float(name[5:] or gain)))
    if name.startswith("side"):
        failsafe = native(setup, gain=float(name[4:] or gain), sideways=True)
        return shield_layer(setup, "shield", failsafe=failsafe)
    if name.startswith("pyevade"):
        policy = EvadePolicy.of(setup, gain=float(name[7:] or gain))
        return shield_layer(setup, "shield", failsafe=policy)
    raise ValueError(f"unknown layer {name!r}")


_SETUP: dict[str, SceneSetup] = {}
_ARGS: dict[str, object] = {}


def work(seed: int) -> list[tuple[EpisodeResult, dict]]:
    """Every layer on one seed."""
    setup = _SETUP.get(SCENE) or _SETUP.setdefault(SCENE, SceneSetup.of(SCENE))
    out = []
    layers: list[str] = _ARGS["layers"]  # type: ignore[assignment]
    for name in layers:
        inner = make_layer(setup, name, float(_ARGS["gain"]))  # type: ignore[arg-type]
        watch = Watch(inner, setup)
        result = run_episode(setup, watch, name, seed)
        counts = dict(getattr(inner, "counts", {}))
        extra = {
            "kind": watch.kind.tolist(),
            "pass_speed": watch.pass_speed,
            "stops": watch.stops,
            "stop_speed": watch.stop_speed,
            "to_rest": watch.to_rest,
            "counts": counts,
        }
        out.append((result, extra))
    return out


def extras(rows: list[tuple[EpisodeResult, dict]], layers: list[str]) -> str:
    """The table of what the base did, by layer."""
    header = ["layer", *KINDS, "speed passing (m/s)", "stops", "speed at a stop (m/s)"]
    header += ["stops to rest", *BREAKS]
    out = []
    for name in layers:
        group = [e for r, e in rows if r.layer == name]
        kind = np.sum([e["kind"] for e in group], axis=0)
        total = max(int(kind.sum()), 1)
        stops = sum(e["stops"] for e in group)
        row = [name] + [f"{k / total:.1%}" for k in kind]
        row += [f"{sum(e['pass_speed'] for e in group) / max(int(kind[0]), 1):.3f}"]
        row += [str(stops), f"{sum(e['stop_speed'] for e in group) / max(stops, 1):.2f}"]
        row += [str(sum(e["to_rest"] for e in group))]
        row += [str(sum(e["counts"].get(b, 0) for e in group)) for b in BREAKS]
        out.append(row)
    return table(header, out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--layers", nargs="+", default=["none", "shield", "evade"])
    parser.add_argument("--episodes", type=int, default=30)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--gain", type=float, default=0.9, help="the evasive policy's gain")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--jsonl", type=Path, help="append each episode's counts here")
    parser.add_argument("--merge", nargs="+", type=Path, help="the tables of these --jsonl")
    args = parser.parse_args()
    start = time.perf_counter()
    if args.merge:
        rows = [
            (EpisodeResult(**r["result"]), r["extra"])
            for path in args.merge
            for r in map(json.loads, path.read_text().splitlines())
        ]
        args.layers = list(dict.fromkeys(r.layer for r, _ in rows))
        seeds = sorted({r.seed for r, _ in rows})
    else:
        _ARGS.update(layers=args.layers, gain=args.gain)
        seeds = list(range(args.first_seed, args.first_seed + args.episodes))
        run: Callable[[int], list] = work
        rows = []
        with multiprocessing.get_context("fork").Pool(args.jobs) as pool:
            for chunk in pool.imap_unordered(run, seeds):
                rows += chunk
                if args.jsonl:  # as they come: a long run's part is a table too
                    with args.jsonl.open("a") as out:
                        for r, e in chunk:
                            out.write(json.dumps(jsonable({"result": r.as_dict(), "extra": e})))
                            out.write("\n")
    rows.sort(key=lambda x: (x[0].layer, x[0].seed))
    print(summary([r for r, _ in rows]))
    print()
    print(extras(rows, args.layers))
    print(
        f"\n{len(rows)} episodes ({len(seeds)} a layer, seeds {seeds[0]}-{seeds[-1]}), "
        f"{time.perf_counter() - start:.0f} s on {args.jobs} processes"
    )


if __name__ == "__main__":
    main()
