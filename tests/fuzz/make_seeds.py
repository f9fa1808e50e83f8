"""Seeds of the tables fuzzer (dua_mujoco/csrc/fuzz/tables_fuzzer.cc): a few small models' tables.

Writes, under OUT (default ``build/fuzz``):

- ``models/<name>.bare.xml`` and ``models/<name>.plugin.xml``: each model without and with the
  plugin (``dua_mujoco.attach``), and ``models/index.txt``, their names and edits in the fuzzer's
  order (an input's first byte picks one);
- ``seeds/<name>-<k>``: fuzz inputs holding the tables ``attach`` wrote for the model.

The models: two_arms with every pair and pruned (the exact level, static shapes, a plane); a
small scene with a mocap body and an inline mesh (the exact level's hull graph) under each
schedule, every pair and pruned; and models edited after ``attach`` (a geom moved, a geom added,
a mesh replaced), which the fuzzer runs the original's tables against. Each seed's tables are
checked to build on its model before it is written.

An input (read by tables_fuzzer.cc, little-endian)::

    b"DUAF" u8 model  u8 flags  u8 steps  u8 seed  u16 ntable
    ntable times: u8 len, name, u8 form (0: float64 entries, 1: text), u32 n, n entries or bytes

Run: ``python tests/fuzz/make_seeds.py [OUT]`` (``dua_mujoco/csrc/fuzz/run.sh`` does).
"""

from __future__ import annotations

import base64
import struct
import sys
from pathlib import Path

import mujoco
import numpy as np

from dua_mujoco import _core
from dua_mujoco.models.scenes import load_spec
from dua_mujoco.plugin import attach

# Flags of an input (tables_fuzzer.cc's kFlag*).
PLUGIN, NAN_STATE, EXTRAS = 1, 2, 4

SCENE = """
<mujoco model="mocap_mesh">
  <option timestep="0.002"/>
  <asset>
    <mesh name="gem" vertex="0.035 0 0  -0.035 0 0  0 0.03 0  0 -0.03 0  0 0 0.04  0 0 -0.025
                             0.02 0.02 0.01  -0.02 -0.02 0.01"/>
  </asset>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.05"/>
    <geom name="wall" type="box" size="0.02 0.3 0.1" pos="0.3 0 0.1"/>
    <body name="stirrer" mocap="true" pos="0.05 0.1 0.095">
      <geom name="stirrer" type="capsule" size="0.025 0.06"/>
    </body>
    <body name="gem" pos="0 0 0.1">
      <freejoint/>
      <geom name="gem" type="mesh" mesh="gem"/>
    </body>
    <body name="ball" pos="0.1 0 0.1">
      <freejoint/>
      <geom name="ball" type="sphere" size="0.03"/>
    </body>
    <body name="arm" pos="-0.1 0 0.15">
      <joint name="hinge" type="hinge" axis="0 1 0"/>
      <geom name="link" type="capsule" fromto="0 0 0 0.1 0 0" size="0.02"/>
      <body name="tip" pos="0.1 0 0">
        <joint name="tip" type="hinge" axis="0 1 0"/>
        <geom name="tip" type="box" size="0.02 0.02 0.02"/>
        <geom name="egg" type="ellipsoid" size="0.02 0.03 0.015" pos="0.03 0 0"/>
      </body>
    </body>
    <body name="can" pos="0 0.15 0.1">
      <freejoint/>
      <geom name="can" type="cylinder" size="0.02 0.03"/>
    </body>
  </worldbody>
  <actuator>
    <motor joint="hinge" gear="5"/>
    <motor joint="tip" gear="2"/>
  </actuator>
</mujoco>
"""


# Edits after attach, by name: "moved:<geom>" shifts a geom by (0.05, 0, 0.02), "added:<body>"
# adds a sphere to a body, "remeshed:<mesh>" replaces a mesh's vertices.
REMESH = [0.05, 0, 0, -0.05, 0, 0, 0, 0.04, 0, 0, -0.04, 0, 0, 0, 0.05, 0, 0, -0.03]


def _edit(spec: mujoco.MjSpec, edit: str) -> None:
    what, name = edit.split(":")
    if what == "moved":
        geom = spec.geom(name)
        geom.pos = np.asarray(geom.pos) + np.array([0.05, 0.0, 0.02])
    elif what == "added":
        spec.body(name).add_geom(
            type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.01, 0, 0], pos=[0, 0, 0.04]
        )
    else:
        spec.mesh(name).uservert = REMESH


# name, source, attach options, edit after attach ("" for none).
MODELS: list[tuple[str, str, dict, str]] = [
    ("two_arms_all", "two_arms", {"accel": 30.0, "pairs": "all"}, ""),
    ("two_arms_pruned", "two_arms", {"accel": 30.0, "pairs": "pruned"}, ""),
    ("mocap_mesh_all", SCENE, {"accel": 20.0, "pairs": "all"}, ""),
    ("mocap_mesh_pruned", SCENE, {"accel": 20.0, "pairs": "pruned", "period": 2}, ""),
    ("mocap_mesh_dua", SCENE, {"accel": 20.0, "pairs": "all", "schedule": "dua"}, ""),
    ("mocap_mesh_select_all", SCENE, {"accel": 20.0, "pairs": "all", "schedule": "select-all"},
     ""),
    ("mocap_mesh_speed", SCENE,
     {"accel": 20.0, "speed": 3.0, "pairs": "pruned", "alarm_horizon": 0.05}, ""),
    ("two_arms_moved", "two_arms", {"accel": 30.0, "pairs": "all"}, "moved:loose_can"),
    ("mocap_mesh_moved", SCENE, {"accel": 20.0, "pairs": "pruned"}, "moved:can"),
    ("mocap_mesh_added", SCENE, {"accel": 20.0, "pairs": "all"}, "added:can"),
    ("mocap_mesh_remeshed", SCENE, {"accel": 20.0, "pairs": "all"}, "remeshed:gem"),
]  # fmt: skip


def _spec(source: str) -> mujoco.MjSpec:
    # Through XML once, so that the fuzzer's models (read from XML) are these exactly.
    spec = load_spec(source) if source.isidentifier() else mujoco.MjSpec.from_string(source)
    return mujoco.MjSpec.from_string(spec.to_xml())


def _input(model: int, flags: int, steps: int, seed: int, tables: dict, text: bool) -> bytes:
    out = bytearray(b"DUAF")
    out += struct.pack("<BBBBH", model, flags, steps, seed, len(tables))
    for name, values in tables.items():
        out += struct.pack("<B", len(name)) + name.encode()
        flat = np.ascontiguousarray(values, dtype="<f8").reshape(-1)
        if text:
            # As attach writes a text field (its count, a space, the bytes in base64).
            raw = f"{flat.size} {base64.b64encode(flat.tobytes()).decode('ascii')}".encode()
            out += struct.pack("<BI", 1, len(raw)) + raw
        else:
            out += struct.pack("<BI", 0, flat.size) + flat.tobytes()
    return bytes(out)


def main(out: Path) -> None:
    (out / "models").mkdir(parents=True, exist_ok=True)
    (out / "seeds").mkdir(parents=True, exist_ok=True)
    names = []
    for index, (name, source, options, edit) in enumerate(MODELS):
        bare, attached = _spec(source), _spec(source)
        tables = attach(attached, **options).table_arrays
        if edit:
            # The edited model's plugin XML carries tables of its own (MuJoCo's compiler runs
            # the plugin's init: it must accept them); the fuzzer replaces them by the inputs'.
            _edit(bare, edit)
            attached = _spec(source)
            _edit(attached, edit)
            attach(attached, **options)
        (out / "models" / f"{name}.plugin.xml").write_text(attached.to_xml())
        (out / "models" / f"{name}.bare.xml").write_text(bare.to_xml())
        if not edit:  # the seeds hold tables the model accepts, through both paths
            _core.Tables.build(mujoco.MjModel.from_xml_string(bare.to_xml()), tables)
            plugin_model = mujoco.MjModel.from_xml_string(attached.to_xml())
            mujoco.mj_step(plugin_model, mujoco.MjData(plugin_model))
        names.append(f"{name} {edit}".strip())
        variants = [(0, 8, 0, False), (PLUGIN, 6, 1, False), (EXTRAS, 12, 2, True)]
        if not edit:
            variants.append((NAN_STATE | PLUGIN, 6, 3, False))
        for k, (flags, steps, seed, text) in enumerate(variants):
            data = _input(index, flags, steps, seed, tables, text)
            (out / "seeds" / f"{name}-{k}").write_bytes(data)
    (out / "models" / "index.txt").write_text("\n".join(names) + "\n")
    print(f"{len(names)} models, {len(list((out / 'seeds').iterdir()))} seeds in {out}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("build/fuzz"))
