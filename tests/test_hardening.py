"""What the native core must survive (docs/hardening.md): the C++ example on every export and
without its plugin, and the models the tables fuzzer found crashing or misbehaving, each run where
a crash cannot take the test session down (a child process) or held to what the fix promises."""

from __future__ import annotations

import base64
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
import pytest

from dua_mujoco.cli import main
from dua_mujoco.models.scenes import load_spec
from dua_mujoco.native import library_path
from dua_mujoco.plugin import _encode, attach, plugin_outputs, standing_pairs

EXAMPLE = Path(__file__).parents[1] / "dua_mujoco/csrc/examples/run_model.cc"
MUJOCO = Path(mujoco.__file__).parent

# A Python process that only loads the model and steps it, as the report did.
_CHILD = """
import sys
import mujoco
try:
    m = mujoco.MjModel.from_xml_path(sys.argv[1])
    d = mujoco.MjData(m)
except ValueError as err:
    print("refused:", " ".join(str(err).split()))
    sys.exit(0)
for _ in range(int(sys.argv[2])):
    mujoco.mj_step(m, d)
print("ran to", d.time)
"""


def _tool_env() -> dict[str, str]:
    """The environment without a sanitizer runtime preloaded (the compiler's own processes)."""
    return {k: v for k, v in os.environ.items() if k != "LD_PRELOAD"}


@pytest.fixture(scope="module")
def run_model(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """csrc/examples/run_model.cc, built against the wheel's headers and libmujoco."""
    if shutil.which("g++") is None:
        pytest.skip("needs a C++ compiler (CI installs g++)")
    (lib,) = MUJOCO.glob("libmujoco.so.*")
    exe = tmp_path_factory.mktemp("example") / "run_model"
    subprocess.run(
        ["g++", "-std=c++17", "-Wall", "-Werror", str(EXAMPLE), f"-I{MUJOCO / 'include'}",
         str(lib), f"-Wl,-rpath,{MUJOCO}", "-ldl", "-o", str(exe)],
        check=True, capture_output=True, timeout=300, env=_tool_env(),
    )  # fmt: skip
    return exe


def _run(exe: Path, library: Path | str, model: Path, steps: int) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(exe), str(library), str(model), str(steps)], capture_output=True, text=True,
        timeout=600,
    )  # fmt: skip


def _one_line(proc: subprocess.CompletedProcess) -> str:
    """The failure's line: exit status 1 (no signal), nothing on stdout, one line on stderr."""
    assert proc.returncode == 1, (proc.returncode, proc.stderr[-3000:])
    assert proc.stdout == ""
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("run_model: "), proc.stderr
    return lines[0]


@pytest.fixture(scope="module")
def exports(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("exports")
    out = {}
    for suffix in (".xml", ".mjb"):
        out[suffix] = folder / f"two_arms{suffix}"
        assert main(["export", "two_arms", str(out[suffix]), "--accel", "30"]) == 0
    return out


@pytest.mark.parametrize("suffix", [".xml", ".mjb"])
def test_the_cpp_example_runs_both_exports(
    run_model: Path, exports: dict[str, Path], suffix: str
) -> None:
    """The example loads each export (the ``.mjb`` too: it registers MuJoCo's bundled plugins
    before this one, as ``import mujoco`` does, so the plugin's slot is the one the file holds)
    and prints the sensor of every step, equal to the Python side's."""
    proc = _run(run_model, library_path(), exports[suffix], 300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    rows = np.array([[float(v) for v in line.split()] for line in proc.stdout.splitlines()])
    path = str(exports[suffix])
    m = (
        mujoco.MjModel.from_binary_path(path)
        if suffix == ".mjb"
        else mujoco.MjModel.from_xml_path(path)
    )
    d = mujoco.MjData(m)
    expected = []
    for _ in range(300):
        mujoco.mj_step(m, d)
        expected.append([d.time, *plugin_outputs(m, d)])
    np.testing.assert_array_equal(rows, np.array(expected))
    assert rows[:, 1].max() > 0


@pytest.mark.parametrize("first", ["dua_mujoco.core.spheres", "dua_mujoco._core", "mujoco"])
def test_an_mjb_reads_whichever_the_program_imports_first(
    exports: dict[str, Path], first: str
) -> None:
    """A process that imports the native core before MuJoCo (a core module, or the binding
    itself) gives the plugin the slot an ``import mujoco`` process gives it (MuJoCo's bundled
    plugins first), so each reads the other's ``.mjb``. Without the import hook it took slot 0:
    the ``.mjb`` of this session failed there (MuJoCo: "`nsensordata` is a null function
    pointer for plugin at slot 7"), and its own ``.mjb`` in every other process (slot 0; the
    flaky failure of the example above when a test worker had imported the core first)."""
    code = (
        f"import sys\nimport {first}\nimport mujoco\n"
        "m = mujoco.MjModel.from_binary_path(sys.argv[1])\nd = mujoco.MjData(m)\n"
        "mujoco.mj_step(m, d)\nprint(*m.plugin, d.sensordata.size)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code, str(exports[".mjb"])], capture_output=True, text=True,
        timeout=300,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    model = mujoco.MjModel.from_binary_path(str(exports[".mjb"]))
    assert proc.stdout.split() == [*map(str, model.plugin), str(model.nsensordata)]


@pytest.mark.parametrize("suffix", [".xml", ".mjb"])
@pytest.mark.parametrize("library", ["missing", "another plugin"])
def test_the_cpp_example_without_the_plugin_fails_in_one_line(
    run_model: Path, exports: dict[str, Path], suffix: str, library: str
) -> None:
    """Without the plugin library (a path that does not load, or a library that registers other
    plugins) the example stops with MuJoCo's message or its own, never a signal: an ``.mjb``
    read without its plugin registered made MuJoCo 4.0 segfault (it does not check the slot)."""
    path = (
        "/nonexistent/libdua_mujoco.so" if library == "missing" else MUJOCO / "plugin/libsensor.so"
    )
    line = _one_line(_run(run_model, path, exports[suffix], 10))
    if library == "missing":
        assert "Error loading plugin library" in line and "/nonexistent/" in line
    else:
        assert "did not register the plugin dua_mujoco.predictor" in line


def test_the_cpp_example_refuses_a_model_that_does_not_load_in_one_line(
    run_model: Path, exports: dict[str, Path], tmp_path: Path
) -> None:
    truncated = tmp_path / "truncated.mjb"
    truncated.write_bytes(exports[".mjb"].read_bytes()[:1000])
    assert "Truncated model file" in _one_line(_run(run_model, library_path(), truncated, 10))
    broken = tmp_path / "broken.xml"
    broken.write_text("<mujoco><worldbody>")
    assert "cannot load" in _one_line(_run(run_model, library_path(), broken, 10))
    line = _one_line(_run(run_model, library_path(), tmp_path / "missing.xml", 10))
    assert "missing.xml" in line
    # Tables the plugin refuses: its warning is the line.
    bad = tmp_path / "bad.xml"
    bad.write_text(_with_table("two_arms", {"accel": 30.0}, "config", _huge_wheel))
    line = _one_line(_run(run_model, library_path(), bad, 10))
    assert "text field 'dua:config'" in line and "max_interval" in line


# ------------------------------------------------------------------------- fuzzer findings


def _with_table(
    scene: str,
    options: dict,
    table: str,
    edit: Callable[[np.ndarray], None],
    tables: dict[str, np.ndarray] | None = None,
) -> str:
    """The scene's XML with the predictor attached and table ``table``'s entries edited (the
    tables as attached into ``tables``, if given)."""
    spec = load_spec(scene)
    arrays = attach(spec, **options).table_arrays
    if tables is not None:
        tables.update(arrays)
    xml = spec.to_xml()
    field = next(t for t in spec.texts if t.name == f"dua:{table}")
    values = np.frombuffer(base64.b64decode(field.data.split(" ", 1)[1]), dtype="<f8").copy()
    edit(values)
    assert xml.count(field.data) == 1
    return xml.replace(field.data, _encode(values))


def _child(path: Path, steps: int) -> str:
    """What the child process printed; it must exit cleanly (a signal is a crash)."""
    proc = subprocess.run(
        [sys.executable, "-c", _CHILD, str(path), str(steps)], capture_output=True, text=True,
        timeout=900,
    )  # fmt: skip
    assert proc.returncode == 0, (proc.returncode, proc.stderr[-3000:])
    return proc.stdout


def _huge_wheel(config: np.ndarray) -> None:
    from dua_mujoco.runtime.table_arrays import CONFIG

    config[CONFIG["max_interval"]] = 1e9


def test_a_wheel_too_large_for_memory_is_refused(tmp_path: Path) -> None:
    """``max_interval`` sizes the deadline wheel every ``MjData`` allocates: 1e9 (accepted up
    to 2^30 before) made each one allocate 8 GB. It is refused, the table named."""
    path = tmp_path / "wheel.xml"
    path.write_text(_with_table("two_arms", {"accel": 30.0}, "config", _huge_wheel))
    out = _child(path, 10)
    assert out.startswith("refused:") and "text field 'dua:config'" in out
    assert "max_interval = 1000000000, over 2^19" in out


def test_the_dua_schedule_survives_bodies_flagged_every_step(tmp_path: Path) -> None:
    """Bodies that break their bounds every step (clutter's falling objects against a 1 m/s^2
    bound) make their pairs due every step; under the rank ("dua") schedule a pair made due,
    then evaluated in its own slot, was queued again and again until the queue overflowed its
    buffer (a heap overflow within 10 steps, AddressSanitizer's report; silent corruption
    without it). The run now completes, as it does in the sanitizer build in CI."""
    path = tmp_path / "flagged.xml"
    assert main(["export", "clutter", str(path), "--accel", "1", "--schedule", "dua"]) == 0
    assert _child(path, 200).startswith("ran to")


def test_a_tau_that_is_not_a_number_alarms(tmp_path: Path) -> None:
    """A static shape's rotation entry of 1e308 (finite, so accepted) overflows tau to NaN: its
    pairs were neither alarmed (NaN <= horizon is false) nor rescheduled (the revisit interval
    was a NaN cast to an integer, undefined). A NaN tau now alarms: every geom pair against
    that shape stands in alarm after every step."""
    from dua_mujoco._core import LAYOUT

    mat = LAYOUT["SHAPE_MAT"]

    def overflow(shapes: np.ndarray) -> None:
        shapes[mat + 1] = 1e308  # shape 0's rotation

    path = tmp_path / "shape.xml"
    tables: dict[str, np.ndarray] = {}
    options = {"accel": 30.0, "pairs": "all"}
    path.write_text(_with_table("two_arms", options, "shapes", overflow, tables))
    assert _child(path, 50).startswith("ran to")
    m = mujoco.MjModel.from_xml_path(str(path))
    pairs = tables["pairs"].reshape(-1, LAYOUT["PAIR_NCOL"])
    on_shape = (pairs[:, LAYOUT["PAIR_KIND"]] == LAYOUT["PairKind.SHAPE"]) & (
        pairs[:, LAYOUT["PAIR_OTHER"]] == 0
    )
    geom_pairs = tables["geom_pairs"].reshape(-1, 2).astype(np.int64)
    expected = {tuple(g) for g in geom_pairs[tables["pair_geom"][on_shape].astype(np.int64)]}
    assert len(expected) > 0
    d = mujoco.MjData(m)
    for _ in range(50):
        mujoco.mj_step(m, d)
        assert expected <= {tuple(g) for g in standing_pairs(m, d)}


def test_a_selection_larger_than_the_held_pairs_fits_the_scratch(tmp_path: Path) -> None:
    """The rank schedule takes a pair made due both from its slot and from the queue, so a step
    can select more pairs than are held (up to the schedule's width: the held pairs and up to
    256 spares). The step gathered them into a scratch of one row per held pair: five falling
    spheres (ten pairs) against a 0.1 m/s^2 bound wrote past it (AddressSanitizer's heap
    overflow). It now evaluates a selection in chunks of the scratch."""
    from dua_mujoco.build.options import ScheduleOptions

    bodies = "".join(
        f'<body pos="{0.12 * i} 0 {0.3 + 0.1 * i}"><freejoint/><geom type="sphere" size=".05"/>'
        "</body>"
        for i in range(5)
    )
    spec = mujoco.MjSpec.from_string(f"<mujoco><worldbody>{bodies}</worldbody></mujoco>")
    attach(spec, accel=0.1, schedule=ScheduleOptions(kind="dua"))
    path = tmp_path / "spheres.xml"
    path.write_text(spec.to_xml())
    assert _child(path, 200).startswith("ran to")


# Two slides along x, one inside the other: 1e308 each is finite, their sum is not.
_SLIDES = """
<mujoco>
  <worldbody>
    <geom name="floor" type="box" size="2 2 .05" pos="0 0 -.05"/>
    <body name="outer" pos="0 0 .05">
      <joint type="slide" axis="1 0 0"/><geom size=".05"/>
      <body name="inner" pos=".2 0 0"><joint type="slide" axis="1 0 0"/><geom size=".05"/></body>
    </body>
    <body name="ball" pos=".5 .5 .3"><freejoint/><geom size=".05"/></body>
  </worldbody>
</mujoco>
"""


def test_a_plan_from_c_is_refused_by_its_value_and_huge_deviations_run() -> None:
    """C and C++ programs hand ``dua_plugin_set_plan`` their plan without Python's checks: the
    runtime refuses what is not finite naming the value, and a plan whose finite joint positions
    put a geom where its position is not finite (1e308 twice along x), naming the geom. Huge
    finite deviations (1e308) are accepted and steps run on them. The slides, resting on the
    floor, are planned far away, beyond their deviation: 1e308 away with a deviation of 1e308
    (the distance overflows), then 1 km away with 1 m; they break the plan and fall back to the
    motion bounds, so the plugin still stands the pairs the bounds alone stand (the slides on
    the floor), which a plan held past its deviation would clear."""
    from dua_mujoco import _core
    from dua_mujoco.exceptions import InvalidInputError

    spec = mujoco.MjSpec.from_string(_SLIDES)
    # One period's horizon: a plan of 20 knots covers it, so the slides' pairs stand only if
    # their break is seen (under a longer horizon the plan's end would stand them anyway).
    attach(spec, accel=30.0, pairs="all")
    m = spec.compile()
    d = mujoco.MjData(m)
    mujoco.mj_step(m, d)
    n = 20
    q, dev = np.tile(d.qpos, (n, 1)), np.full((n, m.nbody), 0.01)
    none = np.zeros(0)

    def set_plan(q: np.ndarray, dev: np.ndarray, start: float) -> int:
        held, pairs = none.astype(np.uint8), np.zeros((0, 2), np.int64)  # defaults; no relative
        return int(_core.plugin_set_plan(m, d, 0, q, dev, start, held, none, none, pairs, none)[0])

    def refusal(q: np.ndarray, dev: np.ndarray, start: float) -> str:
        with pytest.raises(InvalidInputError) as err:
            set_plan(q, dev, start)
        return str(err.value)

    bad_q = q.copy()
    bad_q[3, 1] = np.nan
    assert "knot 3, qpos[1]: nan" in refusal(bad_q, dev, d.time)
    bad_dev = dev.copy()
    bad_dev[2, 1] = np.inf
    assert "knot 2, body 1: inf" in refusal(q, bad_dev, d.time)
    assert "starts at a time that is not finite (nan)" in refusal(q, dev, np.nan)
    huge = q.copy()
    huge[5, :2] = 1e308
    assert "puts geom 2 where its position is not finite (knot 5)" in refusal(huge, dev, d.time)

    reference = mujoco.MjData(m)
    mujoco.mj_step(m, reference)
    for away, slack in ((1e308, 1e308), (1e3, 1.0)):
        far = np.tile(d.qpos, (n, 1))
        far[:, 0] = away
        deviation = np.full((n, m.nbody), 1e308)  # the ball's
        deviation[:, 0] = 0.0  # the world's
        deviation[:, 1:3] = slack  # the slides'
        assert set_plan(far, deviation, d.time) == 0
        for _ in range(n - 2):
            mujoco.mj_step(m, d)
            mujoco.mj_step(m, reference)
            bounds_stand = {tuple(g) for g in standing_pairs(m, reference)}
            assert bounds_stand >= {(0, 1), (0, 2)}  # the slides on the floor: not vacuous
            assert bounds_stand <= {tuple(g) for g in standing_pairs(m, d)}


def test_a_pruned_stride_past_the_horizon_is_refused() -> None:
    """A hand-edited ``config`` whose rebuild stride the reach's horizon does not cover (a pair
    left out at a rebuild could touch before the next rebuild flags it) is refused, naming the
    field, the stride and the largest the horizon covers; the stride as attached loads."""
    from dua_mujoco.runtime.table_arrays import CONFIG

    options = {"accel": 30.0, "pairs": "pruned"}
    tables: dict[str, np.ndarray] = {}
    fine = _with_table("two_arms", options, "config", lambda config: None, tables)
    stride = int(tables["config"][CONFIG["stride"]])
    mujoco.MjData(mujoco.MjModel.from_xml_string(fine))

    def past(config: np.ndarray) -> None:
        config[CONFIG["stride"]] = stride + 1

    with pytest.raises(ValueError, match="plugin") as refused:
        mujoco.MjModel.from_xml_string(_with_table("two_arms", options, "config", past))
    message = " ".join(str(refused.value).split())
    assert "text field 'dua:config'" in message, message
    assert f"stride of {stride + 1} steps past the reach's horizon" in message, message
    assert f"lower the stride to {stride} or less" in message, message


def test_a_pruned_horizon_without_the_grids_step_is_refused() -> None:
    """With ``period`` 3 the reach must cover ``dt - h`` past ``(stride + latency) dt`` (a
    contact between two predictor steps: docs/many-objects.md, "Between predictor steps"): a
    hand-edited ``config`` whose horizon lacks it is refused, naming the stride and the one the
    horizon covers; the horizon as attached loads."""
    from dua_mujoco.runtime.table_arrays import CONFIG

    options = {"accel": 30.0, "pairs": "pruned", "period": 3}
    tables: dict[str, np.ndarray] = {}
    fine = _with_table("two_arms", options, "config", lambda config: None, tables)
    stride = int(tables["config"][CONFIG["stride"]])
    h = mujoco.MjModel.from_xml_string(fine).opt.timestep
    mujoco.MjData(mujoco.MjModel.from_xml_string(fine))

    def short(config: np.ndarray) -> None:
        config[CONFIG["horizon"]] = stride * 3 * h  # (stride + latency) dt, latency 0

    with pytest.raises(ValueError, match="plugin") as refused:
        mujoco.MjModel.from_xml_string(_with_table("two_arms", options, "config", short))
    message = " ".join(str(refused.value).split())
    assert f"stride of {stride} steps past the reach's horizon" in message, message
    assert f"lower the stride to {stride - 1} or less" in message, message
