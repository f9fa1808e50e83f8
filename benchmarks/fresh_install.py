"""A/B: what a new user meets, this checkout against another one: the first run, install, import.

    python benchmarks/fresh_install.py /tmp/before [--rounds 3] [--workdir /tmp/fresh]

Each side's checkout is built into a wheel (``pip wheel --no-deps``, an isolated build) and
installed with its dependencies into a fresh venv of its own, as ``pip install`` does for a user
(bytecode compiled at install). Then, rounds alternating the sides:

- ``first run``: ``dua-mujoco run two_arms --steps 200`` with the package's caches emptied
  (numba's ``.nbi``/``.nbc`` files where there are any, the state right after ``pip install``);
- ``cold``: the same with every ``__pycache__`` in the venv removed too (nothing compiled);
- ``warm``: the same command again, each cache as the runs before left it.

Every figure is a median over rounds (the first round's first run is the fresh install's
own). Then, each venv once: the installed size of each distribution the package pulls in
(``importlib.metadata``'s file lists), and ``import dua_mujoco`` (lazy: the errors only) and
``from dua_mujoco import Predictor``: the median wall time of ``--imports`` fresh interpreters
(alternating sides, interpreter start included) and ``python -X importtime``'s sum over the
statement's own top-level imports (those after the start-up's ``site``).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parents[1]

RUN = ["run", "two_arms", "--steps", "200"]

IMPORTS = ("import dua_mujoco", "from dua_mujoco import Predictor")

# Inside a side's venv: each installed distribution's size in bytes, from its RECORD.
SIZES = r"""
import json, importlib.metadata as md
out = {}
for dist in md.distributions():
    total = 0
    for f in dist.files or ():
        p = f.locate()
        try:
            total += p.stat().st_size
        except OSError:
            pass
    out[dist.metadata["Name"]] = total
print(json.dumps(out))
"""


def sh(argv: list[str], cwd: str | None = None) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    proc = subprocess.run(argv, env=env, cwd=cwd, capture_output=True, text=True)
    if proc.returncode:
        raise RuntimeError(f"{' '.join(argv)} failed:\n{proc.stderr[-3000:]}")
    return proc


def install(checkout: Path, venv: Path) -> None:
    """A wheel of ``checkout`` installed with its dependencies into a new ``venv``."""
    if venv.exists():
        shutil.rmtree(venv)
    wheels = venv.with_name(venv.name + "-wheel")
    shutil.rmtree(wheels, ignore_errors=True)
    sh([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(wheels), str(checkout)])
    sh([sys.executable, "-m", "venv", str(venv)])
    wheel = next(wheels.glob("*.whl"))
    sh([str(venv / "bin" / "pip"), "install", "-q", str(wheel)], cwd="/")


def site_packages(venv: Path) -> Path:
    return next((venv / "lib").glob("python3*/site-packages"))


def clear(venv: Path, *, bytecode: bool) -> None:
    """Empty numba's caches in ``venv`` (and every ``__pycache__`` when ``bytecode``)."""
    for cache in site_packages(venv).rglob("__pycache__"):
        if bytecode:
            shutil.rmtree(cache)
        else:
            for f in cache.iterdir():
                if f.suffix in (".nbi", ".nbc"):
                    f.unlink()


def timed_run(venv: Path) -> float:
    t0 = time.perf_counter()
    sh([str(venv / "bin" / "dua-mujoco"), *RUN], cwd="/tmp")
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("before", type=Path, help="the other checkout")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--imports", type=int, default=15)
    ap.add_argument("--workdir", type=Path, default=Path("/tmp/fresh"))
    ap.add_argument("--reuse", action="store_true", help="keep venvs a previous run installed")
    ap.add_argument("--install-only", action="store_true", help="build and install, no timing")
    args = ap.parse_args(argv)
    os.environ.setdefault("MUJOCO_GL", "egl")
    sides = {"before": args.before.resolve(), "after": HERE}
    venvs = {s: args.workdir / s for s in sides}
    for side, checkout in sides.items():
        if not (args.reuse and (venvs[side] / "bin" / "dua-mujoco").exists()):
            print(f"building and installing {side} ({checkout})", file=sys.stderr, flush=True)
            install(checkout, venvs[side])
    if args.install_only:
        return 0
    times: dict[str, dict[str, list[float]]] = {s: {} for s in sides}
    for r in range(args.rounds):
        for side, venv in venvs.items():
            t = times[side]
            if r:  # the first round's first run is the install's own
                clear(venv, bytecode=False)
            t.setdefault("first run", []).append(timed_run(venv))
            t.setdefault("warm", []).append(timed_run(venv))
            clear(venv, bytecode=True)
            t.setdefault("cold", []).append(timed_run(venv))
            t.setdefault("warm", []).append(timed_run(venv))
        print(f"round {r + 1}/{args.rounds}", file=sys.stderr, flush=True)
    imports: dict[tuple[str, str], list[float]] = {(s, c): [] for s in sides for c in IMPORTS}
    for _ in range(args.imports):
        for code in IMPORTS:
            for side, venv in venvs.items():
                t0 = time.perf_counter()
                sh([str(venv / "bin" / "python"), "-c", code], cwd="/tmp")
                imports[side, code].append(time.perf_counter() - t0)
    importtime: dict[tuple[str, str], float] = {}
    sizes: dict[str, dict[str, int]] = {}
    for side, venv in venvs.items():
        py = str(venv / "bin" / "python")
        for code in IMPORTS:
            err = sh([py, "-X", "importtime", "-c", code], cwd="/tmp").stderr
            # Top-level imports (one space after the bar) sum to the statement's own time.
            rows = [x.split("|") for x in err.splitlines()[1:] if x.startswith("import time:")]
            rows = rows[1 + max(k for k, r in enumerate(rows) if r[2].strip() == "site") :]
            importtime[side, code] = sum(float(r[1]) for r in rows if not r[2].startswith("  "))
        sizes[side] = json.loads(sh([py, "-c", SIZES], cwd="/tmp").stdout)
    med = {s: {k: float(np.median(v)) for k, v in times[s].items()} for s in sides}
    print(f"`dua-mujoco {' '.join(RUN)}`, s (median of {args.rounds} rounds; warm: of 2 each)\n")
    print("| run | before | after |")
    print("|---|---|---|")
    for key in ("first run", "cold", "warm"):
        print(f"| {key} | {med['before'][key]:.2f} | {med['after'][key]:.2f} |")
    for key in ("first run", "cold"):
        print(
            f"| {key} - warm | {med['before'][key] - med['before']['warm']:.2f} "
            f"| {med['after'][key] - med['after']['warm']:.2f} |"
        )
    print("\n| python -c ... (ms) | wall before | after | -X importtime before | after |")
    print("|---|---|---|---|---|")
    for code in IMPORTS:
        wall = {s: np.median(imports[s, code]) * 1e3 for s in sides}
        print(
            f"| `{code}` | {wall['before']:.0f} | {wall['after']:.0f} "
            f"| {importtime['before', code] / 1e3:.0f} | {importtime['after', code] / 1e3:.0f} |"
        )
    skip = {"pip", "setuptools"}
    names = sorted(set(sizes["before"]) | set(sizes["after"]) - skip, key=str.lower)
    print("\n| installed (MB) | before | after |")
    print("|---|---|---|")
    for name in names:
        if name in skip:
            continue
        b, a = (sizes[s].get(name) for s in sides)
        if max(b or 0, a or 0) >= 5e6 or name in ("numba", "llvmlite", "dua_mujoco"):
            print(
                f"| {name} | {'-' if b is None else f'{b / 1e6:.1f}'} "
                f"| {'-' if a is None else f'{a / 1e6:.1f}'} |"
            )
    totals = {s: sum(v for k, v in sizes[s].items() if k not in skip) / 1e6 for s in sides}
    print(
        f"| all ({len(sizes['before'])} / {len(sizes['after'])} distributions) "
        f"| {totals['before']:.1f} | {totals['after']:.1f} |"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
