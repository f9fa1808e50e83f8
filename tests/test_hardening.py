"""What the native core must survive (docs/hardening.md): the models the tables fuzzer found
crashing or misbehaving, each run where a crash cannot take the test session down (a child
process) or held to what the fix promises."""

from __future__ import annotations

import base64
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np

from dua_mujoco.cli import main
from dua_mujoco.mj.scenes import load_spec
from dua_mujoco.plugin import _encode, attach, standing_pairs

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
    from dua_mujoco.mj.build import CONFIG

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
