"""The package as a whole: what it exports, what it ships, and what importing it costs."""

from __future__ import annotations

import ast
import importlib
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

import dua_mujoco

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "dua_mujoco"


def _modules() -> list[Path]:
    """The package's modules, the demo scenes of the top-level ``models/`` among them (through
    the link ``dua_mujoco/models``, which ``rglob`` does not follow)."""
    paths = [*PACKAGE.rglob("*.py"), *(PACKAGE / "models").glob("*.py")]
    return sorted(p for p in paths if "__pycache__" not in p.parts)


def _python(code: str) -> str:
    """What ``python -c code`` prints in a fresh interpreter (its stderr shown if it fails)."""
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT
    )
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_public_api_resolves() -> None:
    """Every name in ``__all__`` imports, the lazy ones included."""
    for name in dua_mujoco.__all__:
        assert getattr(dua_mujoco, name) is not None, name
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        _ = dua_mujoco.nope  # type: ignore[attr-defined]


def test_the_wheel_ships_the_package_the_scenes_and_the_native_core(tmp_path: Path) -> None:
    """The editable install reads the source tree, so a file the wheel leaves out works here and
    is missing for a user: build the wheel (no isolation: this environment's build backend and
    mujoco) and look inside."""
    out = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "--no-build-isolation",
         "-w", str(tmp_path), "-q"],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-3000:]
    (wheel,) = tmp_path.glob("dua_mujoco-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    packages = {
        p.parent.relative_to(ROOT).as_posix() + "/__init__.py"
        for p in PACKAGE.rglob("__init__.py")
        if "__pycache__" not in p.parts
    }
    modules = {p.relative_to(ROOT).as_posix() for p in _modules()}
    modules = {m for m in modules if not m.startswith("dua_mujoco/csrc/")}
    scenes = {f"dua_mujoco/models/{p.name}" for p in (PACKAGE / "models").glob("*.xml")}
    assert packages <= names, sorted(packages - names)
    assert "dua_mujoco/models/scenes.py" in modules and modules <= names, sorted(modules - names)
    assert scenes and scenes <= names, sorted(scenes - names)
    assert {"dua_mujoco/py.typed", "dua_mujoco/libdua_mujoco.so", "dua_mujoco/_core.pyi"} <= names
    assert [n for n in names if n.startswith("dua_mujoco/_core.") and n.endswith(".so")]
    assert not [n for n in names if "/csrc/" in n]  # sources stay in the sdist
    entry_points = next(n for n in names if n.endswith("entry_points.txt"))
    text = zipfile.ZipFile(wheel).read(entry_points).decode()
    assert "[mujoco.plugins]" in text and "dua_mujoco.native:load_plugin" in text
    # The command starts in a light module (Ctrl-C during its imports is one line), and no
    # pytest11 entry point makes pytest warn in other projects (tests/test_pytest_plugin.py).
    assert "dua-mujoco = dua_mujoco.__main__:main" in text
    assert "[pytest11]" not in text
    # Installed from the wheel alone (this environment's editable finder removed), the demo
    # scenes import from dua_mujoco.models and find their XMLs.
    site = tmp_path / "site"
    out = subprocess.run(
        [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(site),
         str(wheel)],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-3000:]
    code = (
        "import sys\n"
        "sys.meta_path[:] = [f for f in sys.meta_path\n"
        "                    if type(f).__name__ != 'ScikitBuildRedirectingFinder']\n"
        "from dua_mujoco.models.scenes import load_scene\n"
        "import dua_mujoco\n"
        "print(dua_mujoco.__file__, load_scene('two_arms')[0].ngeom > 0)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
        cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(site)},
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.split() == [str(site / "dua_mujoco" / "__init__.py"), "True"]


def test_the_bindings_type_stub_is_current(tmp_path: Path) -> None:
    """``dua_mujoco/_core.pyi`` (what mypy and editors read) is what nanobind's stub generator
    writes for the compiled module: regenerate it after changing a binding with
    ``python -m nanobind.stubgen -m dua_mujoco._core -o dua_mujoco/_core.pyi``."""
    out = tmp_path / "_core.pyi"
    run = subprocess.run(
        [sys.executable, "-m", "nanobind.stubgen", "-q", "-m", "dua_mujoco._core", "-o", str(out)],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert out.read_text() == (PACKAGE / "_core.pyi").read_text()


def test_no_private_names_across_modules() -> None:
    """A module imports no underscore name from another module of the package (the compiled
    binding ``_core`` aside: the package's own, private to it as a whole)."""
    offenders = []
    for path in _modules():
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("dua_mujoco"):
                offenders += [
                    f"{path.relative_to(ROOT)}: {node.module}.{a.name}"
                    for a in node.names
                    if a.name.startswith("_") and a.name not in ("__version__", "_core")
                ]
    assert offenders == []


def test_modules_stay_small() -> None:
    sizes = {str(p.relative_to(ROOT)): len(p.read_text().splitlines()) for p in _modules()}
    # "About 500 lines": a module past 600 holds two things.
    assert {k: v for k, v in sizes.items() if v > 600} == {}


def test_the_pytest_plugin_imports_neither_the_core_nor_mujoco() -> None:
    """A project that enables the plugin loads it in every pytest session: it must cost nothing
    there (MuJoCo alone takes about a fifth of a second)."""
    code = (
        "import sys, pytest\n"
        "import dua_mujoco, dua_mujoco.testing\n"
        "heavy = sorted(m for m in ('dua_mujoco._core', 'mujoco') if m in sys.modules)\n"
        "print(heavy)\n"
    )
    assert _python(code) == "[]"


def test_submodules_import() -> None:
    for path in _modules():
        rel = path.relative_to(ROOT).with_suffix("")
        parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
        if parts[-1] == "__main__":
            continue
        importlib.import_module(".".join(parts))


def test_native_code_is_reached_through_the_binding_only() -> None:
    """No numba, llvmlite or ctypes in the package, its tests or the benchmark scripts: every
    kernel is the native core's, called through the compiled binding ``_core`` (one
    implementation, one bridge)."""
    banned = {"numba", "llvmlite", "ctypes"}
    paths = [
        *_modules(),
        *sorted((ROOT / "tests").rglob("*.py")),
        *sorted((ROOT / "benchmarks").glob("*.py")),
    ]
    offenders = []
    for path in paths:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""]
            else:
                continue
            offenders += [
                f"{path.relative_to(ROOT)}: {n}" for n in names if n.split(".")[0] in banned
            ]
    assert offenders == []


def test_a_run_loads_no_jit_and_numba_is_no_dependency() -> None:
    """A sphere predictor's and a MuJoCo predictor's reset and step, tau and the schedules load
    neither numba nor llvmlite (nor does anything they import), and the distribution does not
    require them."""
    code = (
        "import sys, importlib.metadata\n"
        "import mujoco, numpy as np\n"
        "from dua_mujoco import Predictor, SpherePredictor, time_to_collision\n"
        "from dua_mujoco.core.schedules import DUAScheduler\n"
        "from dua_mujoco.models.scenes import load_scene\n"
        "p = SpherePredictor(np.full(3, 0.1), 1.0, dt=0.01)\n"
        "c = np.arange(9.0).reshape(3, 3)\n"
        "p.reset(c, np.zeros((3, 3)))\n"
        "p.step(c, np.zeros((3, 3)))\n"
        "DUAScheduler(time_to_collision(c, c, 0.1, 1.0), dt=0.01)\n"
        "m, d = load_scene('two_arms')\n"
        "q = Predictor(m, accel=30.0)\n"
        "mujoco.mj_step(m, d); q.reset(d); mujoco.mj_step(m, d); q.step(d)\n"
        "req = importlib.metadata.requires('dua_mujoco') or []\n"
        "jit = [r for r in req if r.split(';')[0].strip().startswith(('numba', 'llvmlite'))]\n"
        "print(sorted(m for m in ('numba', 'llvmlite') if m in sys.modules), jit)\n"
    )
    assert _python(code) == "[] []"


# The package's layers, lowest first: a module imports only from its own layer or below.
# "base" is what every layer may use (errors, the compiled binding, the native loader, the
# progress bar and output helpers); "front" is everything else (the CLI, rendering, the plugin,
# gym, export, the sweep, the test helpers, experiments, the package's own lazy exports).
LAYERS = ("base", "core", "build", "runtime", "measure", "models", "front")
BASE = ("_core", "closing", "exceptions", "native", "outputs", "progress")


def _layer(module: str) -> str:
    head = [*module.split("."), ""][1]
    if head in BASE:
        return "base"
    if head == "shield":  # the safety shield sits at the runtime's level, over the predictor
        return "runtime"
    return head if head in LAYERS else "front"


def _import_graph() -> dict[str, set[str]]:
    """Every module of the package and the modules it imports (at the top, inside functions
    and under ``TYPE_CHECKING`` alike). ``from P import X`` is an edge to ``P.X`` when that is a
    module, to the module ``dua_mujoco``'s lazy export ``X`` comes from, else to ``P``; a module
    importing its own parent package (``import dua_mujoco.core.schedules`` in
    ``core/schedules/base.py``, to register the subclasses) adds no edge: Python has begun
    loading every parent package before the module."""
    names = {}
    for path in _modules():
        rel = path.relative_to(ROOT).with_suffix("")
        parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
        names[".".join(parts)] = path
    known = set(names) | {"dua_mujoco._core"}
    lazy = {**dua_mujoco._LAZY, **{n: "dua_mujoco.exceptions" for n in dir(dua_mujoco.exceptions)}}

    def target(module: str, name: str) -> str:
        if f"{module}.{name}" in known:
            return f"{module}.{name}"
        return lazy.get(name, module) if module == "dua_mujoco" else module

    graph: dict[str, set[str]] = {"dua_mujoco._core": set()}
    for module, path in names.items():
        package = module if path.name == "__init__.py" else module.rpartition(".")[0]
        found = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                found |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join(up + ([base] if base else []))
                found |= {target(base, a.name) for a in node.names}
        graph[module] = {
            m for m in found if m in known and m != module and not module.startswith(m + ".")
        }
    return graph


def test_the_layers_import_down_only() -> None:
    """core knows nothing of MuJoCo's layers; build (model and options to tables) imports
    neither runtime nor measure; runtime (the objects over the native runtime) does not import
    measure, which wraps a Predictor; the demo scenes (models) and the front sit on top."""
    rank = {layer: i for i, layer in enumerate(LAYERS)}
    upward = sorted(
        f"{a} ({_layer(a)}) -> {b} ({_layer(b)})"
        for a, deps in _import_graph().items()
        for b in deps
        if rank[_layer(b)] > rank[_layer(a)]
    )
    assert upward == []


def test_no_import_cycles() -> None:
    graph = _import_graph()
    cycles, state = [], dict.fromkeys(graph, 0)  # 0 unseen, 1 on the path, 2 done

    def visit(module: str, path: list[str]) -> None:
        state[module] = 1
        for dep in sorted(graph[module]):
            if state[dep] == 1:
                cycles.append(" -> ".join([*path[path.index(dep) :], dep]))
            elif state[dep] == 0:
                visit(dep, [*path, dep])
        state[module] = 2

    for module in sorted(graph):
        if state[module] == 0:
            visit(module, [module])
    assert cycles == []
