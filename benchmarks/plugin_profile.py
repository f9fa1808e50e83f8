"""Where the plugin's time goes inside ``mj_step``, per scene: instruction counts (callgrind).

    python benchmarks/plugin_profile.py                          # every scene, both bounds
    python benchmarks/plugin_profile.py --scenes robot/g1 robot/yam --bounds 200
    python benchmarks/plugin_profile.py --json /tmp/profile.json # the rows, for later tables
    python benchmarks/plugin_profile.py --tool callgrind --keep /tmp/cg  # callgrind_annotate them
    python benchmarks/plugin_profile.py --tool cache --scenes robot/ur5e --bounds 200  # L1 misses

Per scene and bounds (``auto``: a pilot of random controls held 50 steps, seed 99, as
``benchmarks/plugin.py`` measures; or a declared ``accel`` in m/s^2, e.g. ``200``), the model
alone and the model with the plugin attached (``dua_mujoco.attach``, the default options) are
written as ``.mjb`` files; then one ``valgrind --tool=callgrind`` process steps every model,
driven by ``make_controller``'s random controls (seed 0): ``--warmup`` steps (the
classification and the schedule's settling), then ``--steps`` steps counted. Callgrind collects
only inside ``mj_step`` (``--toggle-collect``), so Python's own work between steps is not
counted, and its counts do not depend on the machine's load.

The table splits the plugin's instructions a step by where they go, from each function's
inclusive count. The release build inlines most of the step into ``dua_step`` (the gather, the
check, the exact pass), so the profile is of a build of its own: the native core compiled with
``-DDUA_PROFILE=ON`` (each section's function out of line, ``DUA_SECTION`` in ``lanes.h``, and
debug information) into ``build/profile`` (made, or brought up to date, by this script: about a
minute the first time) and loaded by the profiled process before the installed one. The
plugin's tables are built by the installed package, which reads them the same way.

* ``check``: the violation check of every body (``CheckBodies``);
* ``select``/``reinsert``: the schedule (the deadline wheel; select takes the flagged bodies'
  pairs, ``SelectMadeDue``);
* ``gather``: each due pair's state read from MjData (``TauRows`` less the kernels it calls);
* ``sphere tau``: the tau kernels ``TauRows`` calls (spheres four at a time, planes, static
  shapes);
* ``geomDistance``: MuJoCo's ``mj_geomDistance`` calls of the exact level;
* ``axes``: the exact level's supports along a direction (``AxisTau``);
* ``exact rest``: the rest of the exact level (the contact index, the geoms' velocities);
* ``fixed``: what the step does whatever is due (``Bind``, ``TrackStep``, ``Log``, mocap, the
  plugin's glue, and ``dua_step``'s own loops);
* ``mujoco``: what MuJoCo's step does more with the plugin than without, outside the plugin
  (the sensor stage: ``mj_step`` with the plugin, less without, less the plugin's compute).

Ratios are of instructions, not time: confirm a large item with a wall-clock A/B
(``benchmarks/plugin.py``).

``--tool cache``: callgrind with its cache simulation at this machine's caches, read from
``/sys/devices/system/cpu/cpu0/cache`` (the first level's data and instruction caches, and the
second level as callgrind's last), on the installed (release) build, not split by section: per
step, the plugin library's own instructions, first-level misses (instruction reads, data reads,
data writes) and second-level misses (reads of either kind, writes), and what MuJoCo's own code
does more with the plugin than without (its step's work and misses after the plugin's).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import mujoco
import numpy as np

HERE = Path(__file__).resolve().parent

# Runs under the profiler: steps each model; callgrind dumps before each call of the marker
# (--dump-before), perf counts only between "enable" and "disable" on its control fifo.
CHILD = r"""
import json, sys
import mujoco
from dua_mujoco.models.scenes import make_controller

warmup, steps, control, paths = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3], sys.argv[4:]
marker = mujoco.mj_version

fifos = []

def say(word):
    if control == "-":
        marker()
        return
    if not fifos:  # perf holds both open: ours stay open too
        ctl, ack = control.split(",")
        fifos.extend([open(ctl, "w"), open(ack)])
    fifos[0].write(word + "\n")
    fifos[0].flush()
    fifos[1].readline()

phases = []
for path in paths:
    m = mujoco.MjModel.from_binary_path(path)
    d = mujoco.MjData(m)
    drive = make_controller(m, "random", seed=0)
    sensor = next((i for i in range(m.nsensor) if m.sensor(i).name == "dua"), None)
    evaluated, flagged = [], []
    for k in range(warmup):
        drive(m, d); mujoco.mj_step(m, d)
    say("enable"); phases.append((path, "warmup"))
    for k in range(steps):
        drive(m, d); mujoco.mj_step(m, d)
        if sensor is not None:
            adr = m.sensor_adr[sensor]
            evaluated.append(float(d.sensordata[adr + 2]))
            flagged.append(float(d.sensordata[adr + 4]))
    say("disable"); phases.append((path, "counted"))
    print(json.dumps(dict(path=path, evaluated=sum(evaluated) / max(len(evaluated), 1),
                          flagged=sum(flagged) / max(len(flagged), 1))), flush=True)
print(json.dumps(dict(phases=phases)), flush=True)
"""

# The sections of the plugin's step, each by the functions whose time is its own: a sample (or
# an instruction) goes to the first section one of whose functions is on its stack. Names are
# substrings of the demangled symbols (perf omits argument lists, callgrind writes them).
SECTIONS = (
    ("geomDistance", ("mj_geomDistance",)),
    ("axes", ("AxisTau",)),
    ("exact rest", ("ExactPass",)),
    (
        "sphere tau",
        ("TauSpeedFour", "TauStatic", "TauHalfspace", "WithGapSpeed", "TauTerrainSphere"),
    ),
    ("gather", ("TauRows",)),
    ("check", ("dua_violation_pass", "CheckBodies")),
    ("select", ("dua_select", "SelectMadeDue")),
    ("reinsert", ("dua_reinsert",)),
    ("fixed", ("lambda(mjModel_ const*, mjData_*, int, int)",)),
)
COMPUTE = SECTIONS[-1][1][0]
STRIPPED = (
    "the plugin's sections have no names in the profile: is {library} a DUA_PROFILE=ON build "
    "(remove build/profile to make it again)?"
)
PROFILE_BUILD = HERE.parent / "build" / "profile"
CHILD_ENV: dict[str, str] = {}


def profile_library() -> Path:
    """The native core built for the profile (DUA_PROFILE=ON) in build/profile: made, or brought
    up to date with the sources, here."""
    src = HERE.parent / "dua_mujoco" / "csrc"
    if not (PROFILE_BUILD / "CMakeCache.txt").exists():
        subprocess.run(
            [
                "cmake",
                "-S",
                str(src),
                "-B",
                str(PROFILE_BUILD),
                "-DDUA_PROFILE=ON",
                f"-DPython_EXECUTABLE={sys.executable}",
            ],
            check=True,
            stdout=subprocess.DEVNULL,
        )
    subprocess.run(
        ["cmake", "--build", str(PROFILE_BUILD), "--target", "dua_mujoco", "-j", "2"],
        check=True,
        stdout=subprocess.DEVNULL,
    )
    return PROFILE_BUILD / "libdua_mujoco.so"


HEADS = [name for name, _ in SECTIONS] + ["mujoco"]


def _name(names: dict[str, str], field: str) -> str:
    """A name of a callgrind dump, "(id) name" the first time and "(id)" after."""
    m = re.match(r"\((\d+)\)(?: (.*))?", field)
    if not m:
        return field
    if m.group(2) is not None:
        names[m.group(1)] = m.group(2)
    return names.get(m.group(1), field)


def parse_callgrind(
    path: Path,
) -> tuple[dict[str, int], dict[str, int], dict[tuple[str, str], int]]:
    """Inclusive instruction counts and call counts of every function of one callgrind dump, and
    the inclusive cost of each caller's calls to each callee.

    Inclusive: the function's own cost plus the cost of its calls to others (a call of a
    function to itself is not added again: its cost is within the outer call's)."""
    names: dict[str, str] = {}
    self_cost: dict[str, int] = defaultdict(int)
    call_cost: dict[str, int] = defaultdict(int)
    calls: dict[str, int] = defaultdict(int)
    edges: dict[tuple[str, str], int] = defaultdict(int)
    fn = cfn = ""
    pending = 0  # the next cost line is a call's (its count), or 0: the function's own
    with open(path) as f:
        for line in f:
            if line.startswith("fn="):
                fn = _name(names, line[3:].rstrip("\n"))
            elif line.startswith("cfn="):
                cfn = _name(names, line[4:].rstrip("\n"))
            elif line.startswith("calls="):
                pending = int(line[6:].split()[0])
            elif line[:1].isdigit() or line[:1] in "+-*":
                parts = line.split()
                cost = int(parts[1]) if len(parts) > 1 else 0
                if pending:
                    calls[cfn] += pending
                    if cfn != fn:
                        call_cost[fn] += cost
                        edges[(fn, cfn)] += cost
                    pending = 0
                else:
                    self_cost[fn] += cost
    inclusive = {
        k: self_cost.get(k, 0) + call_cost.get(k, 0) for k in set(self_cost) | set(call_cost)
    }
    return inclusive, dict(calls), dict(edges)


def _match(fname: str, keys: tuple[str, ...]) -> bool:
    return any(k in fname for k in keys) and ".cold" not in fname


def _sum(table: dict[str, int], keys: tuple[str, ...]) -> int:
    return sum(v for k, v in table.items() if _match(k, keys))


def callgrind_sections(dump: Path, plain: Path, steps: int) -> dict[str, float]:
    """Instructions a step by section, from inclusive counts: a section's functions' inclusive
    count less what the sections before it (called from them) took."""
    incl, calls, edges = parse_callgrind(dump)
    mj_step = incl.get("mj_step", 0)
    mj_plain = parse_callgrind(plain)[0].get("mj_step", 0)
    out = {"geomDistance": _sum(incl, SECTIONS[0][1])}
    out["axes"] = _sum(incl, SECTIONS[1][1])
    out["exact rest"] = _sum(incl, SECTIONS[2][1]) - out["geomDistance"] - out["axes"]
    kernels = sum(v for (a, b), v in edges.items() if "TauRows" in a and _match(b, SECTIONS[3][1]))
    out["sphere tau"] = kernels
    out["gather"] = _sum(incl, SECTIONS[4][1]) - kernels
    # dua_step checks the bodies and selects (the flagged bodies' pairs with step n's) itself:
    # a build before that made the flagged pairs due inside dua_violation_pass (each count
    # inclusive of the other name's, when both are there: one of them, not their sum).
    out["check"] = _sum(incl, ("dua_violation_pass",)) or _sum(incl, ("CheckBodies",))
    out["select"] = _sum(incl, ("SelectMadeDue",)) or _sum(incl, ("dua_select",))
    out["reinsert"] = _sum(incl, ("dua_reinsert",))
    compute = _sum(incl, (COMPUTE,))
    if not compute or not _sum(incl, SECTIONS[5][1] + SECTIONS[4][1]):
        raise RuntimeError(STRIPPED.format(library=PROFILE_BUILD / "libdua_mujoco.so"))
    out["fixed"] = compute - sum(out.values())
    out["mujoco"] = mj_step - mj_plain - compute
    out = {k: v / steps for k, v in out.items()}
    out["mj_step_plain"] = mj_plain / steps
    out["geomDistance calls"] = _sum(calls, ("mj_geomDistance",)) / steps
    return out


def perf_sections(data: Path, plain: Path, steps: int) -> dict[str, float]:
    """CPU seconds a step by section, from perf's samples: each sample's period goes to the
    first section with a function on its stack (inside mj_step), the rest of mj_step to
    ``mujoco`` less the model alone's mj_step."""

    def samples(path: Path) -> list[tuple[int, list[str]]]:
        text = subprocess.run(
            ["perf", "script", "-i", str(path), "-F", "period,ip,sym", "--no-inline"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        out = []
        for block in text.split("\n\n"):
            lines = block.strip("\n").split("\n")
            if not lines or not lines[0].strip().isdigit():
                continue
            frames = [ln.strip().split(" ", 1)[-1] for ln in lines[1:]]
            out.append((int(lines[0].strip()), frames))
        return out

    def in_step(frames: list[str]) -> bool:
        return "mj_step" in frames

    mj_plain = sum(p for p, f in samples(plain) if in_step(f))
    out = dict.fromkeys(HEADS, 0.0)
    mj_step = 0
    for period, frames in samples(data):
        if not in_step(frames):
            continue
        mj_step += period
        for name, keys in SECTIONS:
            if any(_match(f, keys) for f in frames):
                out[name] += period
                break
    compute = sum(out.values())
    if not out["fixed"]:
        raise RuntimeError(STRIPPED.format(library=PROFILE_BUILD / "libdua_mujoco.so"))
    out["mujoco"] = mj_step - mj_plain - compute
    out = {k: v * 1e-9 / steps for k, v in out.items()}
    out["mj_step_plain"] = mj_plain * 1e-9 / steps
    return out


def _spec(scene: str) -> mujoco.MjSpec:
    if scene.startswith("robot/"):
        sys.path.insert(0, str(HERE))
        from robots import robot_spec

        return robot_spec(scene.split("/", 1)[1])
    from dua_mujoco.models.scenes import load_spec

    if "/" in scene:
        sys.path.insert(0, str(HERE))
        from pareto import _external

        return load_spec(_external(scene))
    return load_spec(scene)


def prepare(scene: str, bounds: str, folder: Path) -> tuple[Path, Path, dict]:
    """The scene's model alone and with the plugin (``bounds``), as ``.mjb`` files."""
    from dua_mujoco import CoveringOptions, PilotOptions, Predictor
    from dua_mujoco.models.scenes import make_controller
    from dua_mujoco.plugin import attach

    spec = _spec(scene)
    plain = spec.compile()
    covering = CoveringOptions(hfield="box")
    if bounds == "auto":
        pilot = PilotOptions(
            steps=1000, seed=99, controller=make_controller(plain, "random", seed=99)
        )
        accel = Predictor(plain, accel="auto", covering=covering, pilot=pilot).bounds
    else:
        accel = float(bounds)
    twin = attach(spec, accel=accel, covering=covering)
    with_plugin = spec.compile()
    stem = re.sub(r"[^A-Za-z0-9]+", "_", f"{scene}_{bounds}")
    paths = (folder / f"{stem}.plain.mjb", folder / f"{stem}.plugin.mjb")
    mujoco.mj_saveModel(plain, str(paths[0]), None)
    mujoco.mj_saveModel(with_plugin, str(paths[1]), None)
    # How long a step of the model alone takes here (for perf's budget of samples).
    d = mujoco.MjData(plain)
    drive = make_controller(plain, "random", seed=0)
    t0 = time.perf_counter()
    for _ in range(200):
        drive(plain, d)
        mujoco.mj_step(plain, d)
    info = dict(
        scene=scene,
        bounds=bounds,
        pairs=int(twin.nsphere_pairs),
        bodies=int(plain.nbody),
        step_s=(time.perf_counter() - t0) / 200,
    )
    return paths[0], paths[1], info


def _run_child(prefix: list[str], warmup: int, steps: int, control: str, paths: list[str]) -> dict:
    """The child under ``prefix`` (the profiler's command); its stats by model path, and the
    phases in order."""
    cmd = [*prefix, sys.executable, "-c", CHILD, str(warmup), str(steps), control, *paths]
    proc = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, **CHILD_ENV})
    if proc.returncode:
        raise RuntimeError(f"{' '.join(cmd[:4])} ... failed:\n{proc.stderr[-3000:]}")
    lines = [json.loads(x) for x in proc.stdout.splitlines() if x.startswith("{")]
    return {"phases": lines[-1]["phases"], **{row["path"]: row for row in lines[:-1]}}


def _inside_mj_step(out_file: Path, *options: str) -> list[str]:
    """callgrind collecting inside mj_step only, one dump per model (before ``mj_version``)."""
    return [
        "valgrind",
        "--tool=callgrind",
        *options,
        "--collect-atstart=no",
        "--toggle-collect=mj_step",
        "--dump-before=mj_version",
        f"--callgrind-out-file={out_file}",
    ]


def profile_callgrind(jobs: list, warmup: int, steps: int, folder: Path) -> list[dict]:
    """One callgrind process over every model, collecting inside mj_step only."""
    paths = [str(p) for job in jobs for p in job[:2]]
    out = _run_child(_inside_mj_step(folder / "cg.out"), warmup, steps, "-", paths)
    # One dump before each marker call, in the phases' order (and the last at exit).
    dumps = sorted(folder.glob("cg.out.*"), key=lambda p: int(p.suffix[1:]))[: len(out["phases"])]
    counted = {
        path: dump
        for (path, phase), dump in zip(out["phases"], dumps, strict=True)
        if phase == "counted"
    }
    rows = []
    for plain, plugin, info in jobs:
        row = dict(info, evaluated=out[str(plugin)]["evaluated"])
        row.update(callgrind_sections(counted[str(plugin)], counted[str(plain)], steps))
        rows.append(row)
    return rows


def profile_perf(jobs: list, warmup: int, seconds: float, folder: Path, rounds: int) -> list[dict]:
    """perf's CPU-clock samples (10 kHz, DWARF call stacks) of each model, in a process of its
    own, over as many steps as take ``seconds`` of the model alone (at least 1,000); the model
    alone and with the plugin alternate, ``rounds`` times."""
    ctl, ack = folder / "ctl", folder / "ack"
    for fifo in (ctl, ack):
        if not fifo.exists():
            os.mkfifo(fifo)
    rows = []
    for plain, plugin, info in jobs:
        steps = max(1000, int(seconds / info["step_s"]))
        parts = []
        for r in range(rounds):
            data = {}
            for path in (plain, plugin):
                data[path] = folder / f"{path.stem}.{r}.perf"
                prefix = [
                    "perf",
                    "record",
                    "-q",
                    "-e",
                    "cpu-clock",
                    "-F",
                    "10000",
                    "-m",
                    "4096",
                    "--call-graph",
                    "dwarf,8192",
                    "-D",
                    "-1",
                    "--control",
                    f"fifo:{ctl},{ack}",
                    "-o",
                    str(data[path]),
                    "--",
                ]
                out = _run_child(prefix, warmup, steps, f"{ctl},{ack}", [str(path)])
            parts.append(perf_sections(data[plugin], data[plain], steps))
        row = dict(info, evaluated=out[str(plugin)]["evaluated"], steps=steps)
        row.update({k: float(np.median([p[k] for p in parts])) for k in parts[0]})
        rows.append(row)
    return rows


CACHE_EVENTS = ("Ir", "I1mr", "D1mr", "D1mw", "ILmr", "DLmr", "DLmw")
CACHE_DIR = Path("/sys/devices/system/cpu/cpu0/cache")


def cache_sim(folder: Path = CACHE_DIR) -> list[str]:
    """callgrind's options simulating this machine's caches: the first level's data and
    instruction caches as D1 and I1, the second level as its last level (LL), each as
    ``size,ways,line`` read from ``folder`` (sysfs)."""
    found: dict[tuple[int, str], str] = {}
    for index in sorted(folder.glob("index*")):
        level, kind = int((index / "level").read_text()), (index / "type").read_text().strip()
        size = (index / "size").read_text().strip()
        unit = {"K": 1 << 10, "M": 1 << 20}.get(size[-1:], 1)
        size_b = int(size.rstrip("KM")) * unit
        ways = (index / "ways_of_associativity").read_text().strip()
        line = (index / "coherency_line_size").read_text().strip()
        found[(level, kind)] = f"{size_b},{ways},{line}"
    wanted = {"D1": (1, "Data"), "I1": (1, "Instruction"), "LL": (2, "Unified")}
    missing = [f"level {lv} {kind}" for lv, kind in wanted.values() if (lv, kind) not in found]
    if missing:
        raise RuntimeError(
            f"{folder} describes no {', '.join(missing)} cache: --tool cache needs the caches' "
            "sizes from sysfs (use --tool callgrind or perf on this machine)"
        )
    return ["--cache-sim=yes", *(f"--{k}={found[v]}" for k, v in wanted.items())]


def cost_by_object(path: Path) -> dict[str, dict[str, int]]:
    """Each shared object's own cost (its functions' self cost) by event, from one callgrind
    dump (a call's line, its inclusive cost, is skipped)."""
    names: dict[str, str] = {}
    out: dict[str, dict[str, int]] = defaultdict(lambda: defaultdict(int))
    events: list[str] = []
    ob, call = "", False
    with open(path) as f:
        for line in f:
            if line.startswith("events:"):
                events = line.split()[1:]
            elif line.startswith(("ob=", "cob=")):
                named = _name(names, line.split("=", 1)[1].rstrip("\n"))
                ob = named if line.startswith("ob=") else ob
            elif line.startswith("calls="):
                call = True
            elif line[:1].isdigit() or line[:1] in "+-*":
                if not call:
                    for event, value in zip(events, line.split()[1:], strict=False):
                        out[ob][event] += int(value)
                call = False
    return out


def profile_cache(jobs: list, warmup: int, steps: int, folder: Path) -> list[dict]:
    """callgrind with the caches simulated (:func:`cache_sim`), one process over every model: a
    step's instructions and misses (first level, and second as the last) of the plugin library,
    and of MuJoCo's with the plugin less without."""
    paths = [str(p) for job in jobs for p in job[:2]]
    sim = cache_sim()
    print("cache model: " + " ".join(sim[1:]), flush=True)
    out = _run_child(_inside_mj_step(folder / "cache.out", *sim), warmup, steps, "-", paths)
    dumps = sorted(folder.glob("cache.out.*"), key=lambda p: int(p.suffix[1:]))
    counted = {
        path: cost_by_object(dump)
        for (path, phase), dump in zip(out["phases"], dumps[: len(out["phases"])], strict=True)
        if phase == "counted"
    }

    def of(path: Path, word: str) -> dict[str, float]:
        obs = [v for k, v in counted[str(path)].items() if word in k.rsplit("/", 1)[-1]]
        return {e: sum(v.get(e, 0) for v in obs) / steps for e in CACHE_EVENTS}

    rows = []
    for plain, plugin, info in jobs:
        row = dict(info, evaluated=out[str(plugin)]["evaluated"])
        row["plain"] = of(plain, "libmujoco")
        row["plugin"] = of(plugin, "libdua_mujoco")
        row["mujoco"] = {k: v - row["plain"][k] for k, v in of(plugin, "libmujoco").items()}
        rows.append(row)
    return rows


def cache_table(rows: list[dict]) -> str:
    """A step's instructions and misses (:data:`CACHE_EVENTS`): MuJoCo's alone, the plugin's own,
    and what MuJoCo's code does more with the plugin."""
    heads = [f"{who} {e}" for who in ("mj_step", "plugin", "mujoco +") for e in CACHE_EVENTS]
    out = ["| scene | bounds | " + " | ".join(heads) + " |", "|---" * (len(heads) + 2) + "|"]
    for row in rows:
        cells = [f"{row[k][e]:,.0f}" for k in ("plain", "plugin", "mujoco") for e in CACHE_EVENTS]
        out.append(f"| {row['scene']} | {row['bounds']} | " + " | ".join(cells) + " |")
    return "\n".join(out)


# The table's columns: the sections, select and reinsert together.
COLUMNS = {
    **{h: (h,) for h in HEADS if h not in ("select", "reinsert")},
    "schedule": ("select", "reinsert"),
}


def table(rows: list[dict], unit: str) -> str:
    """Each section's share of what the plugin adds to mj_step."""
    heads = [h for h in COLUMNS if h != "schedule"]
    heads.insert(heads.index("fixed"), "schedule")
    out = [
        f"| scene | bounds | pairs | evals/step | mj_step {unit} | plugin adds | "
        + " | ".join(heads)
        + " |",
        "|---" * (len(heads) + 6) + "|",
    ]
    scale = 1e-3 if unit == "kIr" else 1e6
    for row in rows:
        added = sum(row[h] for h in HEADS)
        share = {h: sum(row[k] for k in COLUMNS[h]) for h in heads}
        shares = [f"{100 * share[h] / added:.0f} %" if added > 0 else "-" for h in heads]
        out.append(
            f"| {row['scene']} | {row['bounds']} | {row['pairs']} | {row['evaluated']:.1f} | "
            f"{row['mj_step_plain'] * scale:.1f} | {added / row['mj_step_plain']:+.2f}x | "
            + " | ".join(shares)
            + " |"
        )
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", nargs="*", default=None)
    ap.add_argument("--bounds", nargs="*", default=["200", "auto"])
    ap.add_argument("--tool", choices=("perf", "callgrind", "cache"), default="perf")
    ap.add_argument("--warmup", type=int, default=200)
    ap.add_argument("--steps", type=int, default=300, help="callgrind: steps counted")
    ap.add_argument("--seconds", type=float, default=2.0, help="perf: steps counted, in seconds")
    ap.add_argument("--rounds", type=int, default=3, help="perf: rounds (medians)")
    ap.add_argument("--json", type=Path, default=None, help="also write the rows here")
    ap.add_argument(
        "--keep", type=Path, default=None, help="write the models and profiles here, kept"
    )
    args = ap.parse_args(argv)
    sys.path.insert(0, str(HERE))
    from plugin import _scenes

    scenes = _scenes(args.scenes)
    # The profiled processes load the profiling build (_run_child); this one, the installed one.
    # The binding finds libdua_mujoco.so through its RUNPATH, which LD_LIBRARY_PATH precedes: the
    # child's `import mujoco` loads MuJoCo's bundled plugins, then the entry point the profiling
    # build, so every plugin gets the slot it had when the models were saved.
    if args.tool != "cache":  # the cache's profile is of the installed build
        path = [str(profile_library().parent), os.environ.get("LD_LIBRARY_PATH", "")]
        CHILD_ENV["LD_LIBRARY_PATH"] = os.pathsep.join(p for p in path if p)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) if args.keep is None else args.keep
        folder.mkdir(parents=True, exist_ok=True)
        jobs = []
        for scene in scenes:
            for bounds in args.bounds:
                jobs.append(prepare(scene, bounds, folder))
                print(f"prepared {scene} {bounds}", file=sys.stderr, flush=True)
        if args.tool == "cache":
            rows = profile_cache(jobs, args.warmup, args.steps, folder)
        elif args.tool == "callgrind":
            rows = profile_callgrind(jobs, args.warmup, args.steps, folder)
        else:
            rows = profile_perf(jobs, args.warmup, args.seconds, folder, args.rounds)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    if args.tool == "cache":
        print(cache_table(rows))
        return 0
    print(table(rows, "kIr" if args.tool == "callgrind" else "us"))
    for bounds in args.bounds:
        adds = [
            sum(r[h] for h in HEADS) / r["mj_step_plain"]
            for r in rows
            if r["bounds"] == bounds and r["scene"].startswith("robot/")
        ]
        if adds:
            print(
                f"\nbounds {bounds}: the plugin adds a median {np.median(adds):+.2f}x mj_step over "
                f"{len(adds)} robots, at most {max(adds):+.2f}x"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
