"""Scaling of the pruned pair set: the runtime's candidate grid against a KD-tree broadphase.

Needs scipy (``pip install scipy``, or ``pip install dua_mujoco[bench]``); never run as a test.

    python benchmarks/scaling.py            # N = 1e3, 1e4, 1e5 (about a minute)
    python benchmarks/scaling.py --quick    # N = 1e3, 1e4, 3 repeats

World: the paper's sphere world (``dua_mujoco.experiments.paper.WorldParams``: 0.1 m spheres,
speeds uniform in [0, 0.4] m/s, acceleration bound 0.2 m/s^2, drawn by ``SphereWorld``) at the
density of ``ref_n`` spheres in its 10 m cube, the cube's edge scaled by ``(N / ref_n)^(1/3)``.
``ref_n = 40`` is the paper's largest world (Table 2); ``ref_n = 1000`` is the largest this
repository runs in the same cube (25 times denser).

For each horizon T: reach by ``grid_reach(radius, |v|, accel, T)``; the grid is ``grid_pairs``;
the KD-tree is ``cKDTree(centers).query_pairs(2 max(reach) + margin)`` (tree build included, as
the grid is built on every call too) filtered to the exact per-pair test, and both sets are
checked equal. Times are medians over the repeats, after a warm-up call. Memory is the
``tracemalloc`` peak of one ``grid_pairs`` call per sphere: every array it uses is a numpy
allocation (the compiled kernels allocate nothing), so the figure is complete; the KD-tree's C++
nodes are invisible to ``tracemalloc``, so no figure is given for it.
"""

from __future__ import annotations

import argparse
import functools
import tracemalloc
from collections.abc import Callable

import numpy as np
from many import ROUNDING_SLACK, grid_pairs, grid_reach
from timing import median_time, table  # benchmarks/timing.py: the script folder is on sys.path

from dua_mujoco.experiments.paper.reference import PAPER_N
from dua_mujoco.experiments.paper.world import SphereWorld, WorldParams


def kdtree_pairs(centers: np.ndarray, r: np.ndarray, margin: float) -> np.ndarray:
    from scipy.spatial import cKDTree

    p = cKDTree(centers).query_pairs(2.0 * float(r.max()) + margin, output_type="ndarray")
    d = centers[p[:, 0]] - centers[p[:, 1]]
    s = r[p[:, 0]] + r[p[:, 1]] + margin
    keep = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2] <= s * s * ROUNDING_SLACK
    return np.asarray(p[keep])


def peak_bytes(fn: Callable[[], object]) -> int:
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="N = 1e3, 1e4 and 3 repeats")
    parser.add_argument("--n", type=int, nargs="+", help="sphere counts (default 1e3 1e4 1e5)")
    parser.add_argument("--horizons", type=float, nargs="+", default=[0.05, 0.2])
    parser.add_argument("--ref-n", type=int, nargs="+", default=[max(PAPER_N), 1000])
    parser.add_argument("--margin", type=float, default=0.0)
    parser.add_argument("--repeat", type=int, default=None, help="timed runs (default 7, quick 3)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    ns = args.n or ([1000, 10_000] if args.quick else [1000, 10_000, 100_000])
    repeat = args.repeat or (3 if args.quick else 7)
    wp = WorldParams()
    rows = []
    for ref_n in args.ref_n:
        for n in ns:
            box = wp.box * (n / ref_n) ** (1.0 / 3.0)
            world = SphereWorld(
                n, seed=args.seed, box=box, radius=wp.radius, accel=wp.accel, speed=wp.speed
            )
            c = world.positions
            speed = np.linalg.norm(world.velocities, axis=1)
            for T in args.horizons:
                r = grid_reach(world.radius, speed, wp.accel, T)
                grid = grid_pairs(c, r, margin=args.margin)
                kd = kdtree_pairs(c, r, args.margin)
                kd = kd[np.lexsort((kd[:, 1], kd[:, 0]))]
                if not np.array_equal(grid, kd):
                    raise SystemExit(f"pair sets differ at N = {n}, T = {T}")
                run_grid = functools.partial(grid_pairs, c, r, margin=args.margin)
                run_kd = functools.partial(kdtree_pairs, c, r, args.margin)
                t_grid = median_time(run_grid, repeat)
                t_kd = median_time(run_kd, repeat)
                mem = peak_bytes(run_grid)
                rows.append(
                    [
                        f"{ref_n}",
                        f"{n:.0e}",
                        f"{box:.1f}",
                        f"{T:g}",
                        f"{grid.shape[0]}",
                        f"{grid.shape[0] / n:.3f}",
                        f"{t_grid * 1e3:.2f}",
                        f"{t_kd * 1e3:.2f}",
                        f"{t_kd / t_grid:.1f}",
                        f"{mem / n:.0f}",
                    ]
                )
                print(" | ".join(rows[-1]), flush=True)
    header = [
        "ref_n",
        "N",
        "box (m)",
        "T (s)",
        "K",
        "K / N",
        "grid (ms)",
        "KD-tree (ms)",
        "KD / grid",
        "grid peak B / sphere",
    ]
    print()
    print(table(header, rows))


if __name__ == "__main__":
    main()
