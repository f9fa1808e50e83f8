"""The notebooks run end to end at small sizes.

Each notebook is executed in-process with ``nbclient`` (no ``jupyter nbconvert`` subprocess; the
kernel is the usual ipykernel child). Parameters are injected by replacing the source of the cell
tagged ``parameters``. The kernel's working directory is the repository root, so the notebooks
import ``dua_mujoco`` whether or not the package is installed.

Needs ``nbclient``, ``nbformat`` and ``ipykernel`` (the ``test`` extra), plus ``matplotlib``
(the ``plots`` extra).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import nbformat
import pytest
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOKS = ROOT / "notebooks"
pytestmark = pytest.mark.slow  # ~10-30 s in all: kernel start-up, numba compile, rendering

CELL_TIMEOUT = 300  # seconds per cell: generous for a cold numba cache on a slow CI machine


def _execute(name: str, params: dict[str, Any]) -> tuple[nbformat.NotebookNode, float]:
    """Execute ``notebooks/<name>`` with ``params`` replacing its ``parameters`` cell."""
    nb = nbformat.read(NOTEBOOKS / name, as_version=4)
    tagged = [c for c in nb.cells if "parameters" in c.get("metadata", {}).get("tags", [])]
    assert len(tagged) == 1, f"{name} must have exactly one cell tagged 'parameters'"
    cell = tagged[0]
    missing = set(params) - {line.split("=")[0].strip() for line in cell.source.splitlines()}
    assert not missing, f"{name}: the parameters cell does not define {sorted(missing)}"
    cell.source = "\n".join(f"{k} = {v!r}" for k, v in params.items())
    client = NotebookClient(
        nb,
        timeout=CELL_TIMEOUT,
        kernel_name="python3",
        allow_errors=False,
        resources={"metadata": {"path": str(ROOT)}},
    )
    start = time.perf_counter()
    client.execute()  # raises CellExecutionError on the first failing cell
    return nb, time.perf_counter() - start


def _outputs(nb: nbformat.NotebookNode) -> list[dict[str, Any]]:
    return [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]


def _assert_no_errors(nb: nbformat.NotebookNode) -> None:
    errors = [o for o in _outputs(nb) if o.get("output_type") == "error"]
    assert not errors, [f"{e['ename']}: {e['evalue']}" for e in errors]


def test_quickstart() -> None:
    # One test, one execution: a shared fixture would run once per pytest-xdist worker.
    nb, _ = _execute(
        "quickstart.ipynb",
        {
            "STEPS": 200,
            "WIDTH": 96,
            "HEIGHT": 72,
            "FRAMES": 10,
            "SEED": 0,
            "GYM_STEPS": 20,
        },
    )
    _assert_no_errors(nb)
    data = [o.get("data", {}) for o in _outputs(nb)]
    figures = [d for d in data if "image/png" in d]
    videos = [d for d in data if "<video" in d.get("text/html", "")]
    tables = [d for d in data if "<table>" in d.get("text/html", "")]
    assert len(figures) >= 3, "expected the tau/alarms plot, the stills and the gym cost"
    assert len(videos) == 1, "expected one inline video (mediapy.show_video)"
    assert "data:video/mp4;base64," in videos[0]["text/html"]
    assert tables and "contact onsets" in tables[0]["text/html"]
    printed = "".join(o.get("text", "") for o in _outputs(nb) if o.get("name") == "stdout")
    assert "20 env steps of Pusher-v5: mean cost" in printed


def test_paper_reproduction_runs() -> None:
    nb, _ = _execute("paper_reproduction.ipynb", {"QUICK": True, "SEEDS": 2, "TINY": True})
    _assert_no_errors(nb)
    data = [o.get("data", {}) for o in _outputs(nb)]
    markdown = [d["text/markdown"] for d in data if "text/markdown" in d]
    assert markdown and "Table 1" in markdown[0] and "Table 3" in markdown[0]
    assert sum("image/png" in d for d in data) == 3, "expected the three PNG plots"
