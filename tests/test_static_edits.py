"""The static guard: a static geom edited in the ``MjModel`` after the tables were built (its
pose, its size, its height field's data, its mesh) is refused by the plugin at init (a warning,
then MuJoCo's "plugin->init failed") and at ``mj_resetData`` (``mujoco.FatalError``), and by
``Predictor.reset``, each naming the geom and the fix; an unedited model, and an edit of
anything else, runs as before (docs/static-shapes.md, "What the guard covers")."""

from __future__ import annotations

import base64
from collections.abc import Callable

import mujoco
import numpy as np
import pytest

from dua_mujoco import Predictor, _core
from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.models.scenes import load_spec
from dua_mujoco.plugin import attach, plugin_outputs, standing_pairs

# Every kind of static shape: a box on the world body, turned (its own frame: geom_quat read),
# a height field, a mesh, a box on a body welded to the world; besides, a plane, a mocap body and
# a free ball that falls on the table.
XML = """
<mujoco>
  <asset>
    <hfield name="h" nrow="6" ncol="6" size="1 1 0.2 0.1"
            elevation="0 0 0 0 0 0 0 1 1 1 1 0 0 1 2 2 1 0 0 1 2 2 1 0 0 1 1 1 1 0 0 0 0 0 0 0"/>
    <mesh name="tet" vertex="0 0 0 0.2 0 0 0 0.2 0 0 0 0.2"/>
  </asset>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <geom name="table" type="box" pos="1 0 0.2" euler="0 0 30" size="0.3 0.3 0.2"/>
    <geom name="terrain" type="hfield" hfield="h" pos="-2 0 0"/>
    <geom name="rock" type="mesh" mesh="tet" pos="0 2 0"/>
    <body name="shelf" pos="0 -1 0.5">
      <geom name="board" type="box" pos="0 0 0.1" size="0.3 0.1 0.02"/>
    </body>
    <body name="hand" mocap="true" pos="0 0 1">
      <geom name="palm" type="sphere" size="0.05"/>
    </body>
    <body name="ball" pos="1 0 0.7"><freejoint/><geom name="ball" size="0.1"/></body>
  </worldbody>
</mujoco>
"""


def _edit_body_pos(m: mujoco.MjModel) -> str:
    m.body_pos[m.body("shelf").id, 2] += 0.3
    return "board"


def _edit_geom_pos(m: mujoco.MjModel) -> str:
    m.geom_pos[m.geom("table").id, 0] += 0.05
    return "table"


def _edit_geom_quat(m: mujoco.MjModel) -> str:
    m.geom_quat[m.geom("table").id] = [1.0, 0.0, 0.0, 0.0]
    return "table"


def _edit_geom_size(m: mujoco.MjModel) -> str:
    m.geom_size[m.geom("table").id, 2] += 0.1
    return "table"


def _edit_hfield_data(m: mujoco.MjModel) -> str:
    m.hfield_data[14] += 0.5
    return "terrain"


def _edit_mesh(m: mujoco.MjModel) -> str:
    m.mesh_vert[3] += 0.5  # the tetrahedron's x tip out of its box
    return "rock"


# Each edit, what the message names (the field that differs).
EDITS: dict[str, tuple[Callable[[mujoco.MjModel], str], str]] = {
    "body_pos": (_edit_body_pos, "position"),
    "geom_pos": (_edit_geom_pos, "position"),
    "geom_quat": (_edit_geom_quat, "rotation"),
    "geom_size": (_edit_geom_size, "geom_size"),
    "hfield_data": (_edit_hfield_data, "height field"),
    "mesh": (_edit_mesh, "mesh"),
}


def _attached(xml: str = XML) -> tuple[mujoco.MjModel, Predictor]:
    spec = mujoco.MjSpec.from_string(xml)
    p = attach(spec, accel=5.0)
    return spec.compile(), p


def test_every_kind_of_static_shape_is_recorded_where_mj_kinematics_puts_it() -> None:
    """``_core.static_records``: one row per static shape, its pose bit for bit MjData's after
    ``mj_forward``, its geom_size, a digest for the height field and the mesh only."""
    m, p = _attached()
    shapes = np.asarray(p.covering.shape_geom, dtype=np.int64)
    assert sorted(m.geom(int(g)).name for g in shapes) == ["board", "rock", "table", "terrain"]
    rec = p.table_arrays["static"]
    np.testing.assert_array_equal(rec, _core.static_records(m, shapes))
    lay = _core.LAYOUT
    assert rec.shape == (shapes.size, lay["STATIC_NCOL"])
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    g = rec[:, lay["STATIC_GEOM"]].astype(np.int64)
    np.testing.assert_array_equal(g, shapes)
    pos, mat, size = lay["STATIC_POS"], lay["STATIC_MAT"], lay["STATIC_SIZE"]
    np.testing.assert_array_equal(rec[:, pos : pos + 3], d.geom_xpos[g])
    np.testing.assert_array_equal(rec[:, mat : mat + 9], d.geom_xmat[g])
    np.testing.assert_array_equal(rec[:, size : size + 3], m.geom_size[g])
    digest = rec[:, lay["STATIC_DIGEST"] : lay["STATIC_DIGEST"] + 2]
    data = np.isin(m.geom_type[g], [mujoco.mjtGeom.mjGEOM_HFIELD, mujoco.mjtGeom.mjGEOM_MESH])
    assert (digest[data] != 0).any(axis=1).all() and (digest[~data] == 0).all()
    assert _core.static_mismatch(m, rec) == ""


@pytest.mark.parametrize("edit", sorted(EDITS))
def test_plugin_init_refuses_an_edited_static_geom(
    edit: str, capfd: pytest.CaptureFixture[str]
) -> None:
    """An MjData made after the edit: init warns naming the geom, the field and the fix, and
    fails; undone, the model is taken again."""
    m, _ = _attached()
    mujoco.MjData(m)
    saved = {f: getattr(m, f).copy() for f in ("body_pos", "geom_pos", "geom_quat", "geom_size")}
    saved |= {"hfield_data": m.hfield_data.copy(), "mesh_vert": m.mesh_vert.copy()}
    change, field = EDITS[edit]
    geom = change(m)
    capfd.readouterr()
    with pytest.raises(mujoco.FatalError, match="init failed"):
        mujoco.MjData(m)
    err = capfd.readouterr().err
    assert f"static geom {m.geom(geom).id} ('{geom}')" in err and field in err, err
    # Named as every refused table is (the tables fuzzer holds refusals to that).
    assert "text field 'dua:static' does not match the model" in err, err
    assert "attach the plugin again after editing static geoms" in err
    for f, v in saved.items():
        getattr(m, f)[:] = v
    d = mujoco.MjData(m)
    mujoco.mj_step(m, d)
    assert "dua_mujoco" not in capfd.readouterr().err


@pytest.mark.parametrize("edit", sorted(EDITS))
def test_plugin_reset_refuses_an_edited_static_geom(edit: str) -> None:
    """An MjData made before the edit, then ``mj_resetData``: a FatalError naming the geom, the
    field and the fix (its next classification would read the stale cover)."""
    m, _ = _attached()
    d = mujoco.MjData(m)
    for _ in range(10):
        mujoco.mj_step(m, d)
    mujoco.mj_resetData(m, d)  # unedited: taken
    change, field = EDITS[edit]
    geom = change(m)
    with pytest.raises(
        mujoco.FatalError,
        match=rf"^dua_mujoco.predictor: text field 'dua:static' does not match the model: "
        rf".*'{geom}'\) .*{field}.*attach the plugin again",
    ):
        mujoco.mj_resetData(m, d)


@pytest.mark.parametrize("column", ["STATIC_POS", "STATIC_MAT", "STATIC_SIZE", "STATIC_DIGEST"])
def test_a_static_table_that_does_not_match_the_model_is_refused_as_a_table(column: str) -> None:
    """Tables built from arrays whose ``static`` records differ from the model in one bit (a
    corrupted table, or one built before an edit) are refused naming the table, as the plugin
    refuses them; the records as built are taken."""
    m, p = _attached()
    arrays = dict(p.table_arrays)
    _core.Tables.build(m, arrays)
    rec = np.array(arrays["static"], copy=True)
    at = rec[-1:, _core.LAYOUT[column]].view(np.uint64)
    at ^= np.uint64(1)  # the lowest bit of one entry
    rec[-1, _core.LAYOUT[column]] = at.view(np.float64)[0]
    arrays["static"] = rec
    with pytest.raises(ValueError, match=r"^table 'static' does not match the model: static geom"):
        _core.Tables.build(m, arrays)


@pytest.mark.parametrize("edit", ["geom_size", "hfield_data", "mesh"])
def test_predictor_reset_refuses_a_resized_or_reshaped_static_geom(edit: str) -> None:
    """``Predictor.reset`` runs the native guard after its own pose check (whose moves
    tests/static_guard.py covers): a size, height field or mesh edit is refused too."""
    m = mujoco.MjModel.from_xml_string(XML)
    p = Predictor(m, accel=5.0)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    p.reset(d)
    change, field = EDITS[edit]
    geom = change(m)
    mujoco.mj_forward(m, d)
    with pytest.raises(InvalidInputError, match=rf"'{geom}'\) .*{field}.*new Predictor"):
        p.reset(d)
    Predictor(m, accel=5.0).reset(d)


@pytest.mark.parametrize("scene", ["clutter", "rough_terrain", "person_cell", "paper_world"])
def test_no_false_alarm_on_an_unedited_scene(scene: str, capfd: pytest.CaptureFixture[str]) -> None:
    """Bundled scenes with mocap bodies, planes, a height field, meshes: the plugin's MjData
    inits, steps, resets and steps again; Predictor.reset takes the data."""
    spec = load_spec(scene)
    p = attach(spec, accel=20.0)
    m = spec.compile()
    d = mujoco.MjData(m)
    for _ in range(2):
        for _ in range(30):
            mujoco.mj_step(m, d)
        mujoco.mj_resetData(m, d)
    assert "dua_mujoco" not in capfd.readouterr().err
    mujoco.mj_forward(m, d)
    p.reset(d)


def test_a_legal_edit_steps_as_before() -> None:
    """An edit the tables do not rest on (gravity; the mocap pose, in the data) passes the guard
    at reset and does not change the step: the same pairs stand as on a model built with it."""
    edited, _ = _attached()
    fresh_spec = mujoco.MjSpec.from_string(XML)
    fresh_spec.option.gravity = [0.0, 0.0, -4.0]
    attach(fresh_spec, accel=5.0)
    fresh = fresh_spec.compile()
    edited.opt.gravity[:] = [0.0, 0.0, -4.0]
    runs = []
    for m in (edited, fresh):
        d = mujoco.MjData(m)
        mujoco.mj_resetData(m, d)
        d.mocap_pos[0] = [0.5, 0.5, 1.0]
        standing = []
        for _ in range(200):
            mujoco.mj_step(m, d)
            standing.append(standing_pairs(m, d).tolist())
        runs.append((standing, plugin_outputs(m, d).evaluated))
    assert runs[0] == runs[1]
    assert any(runs[0][0])  # the ball lands: something stood


def _with_config_entry(spec: mujoco.MjSpec, index: int, value: float) -> None:
    """Writes ``value`` at ``index`` of the plugin's config table (its text field in ``spec``)."""
    (text,) = [t for t in spec.texts if t.name == "dua:config"]
    count, digits = text.data.split(" ")
    config = np.frombuffer(base64.b64decode(digits), dtype="<f8").copy()
    config[index] = value
    text.data = f"{count} {base64.b64encode(config.tobytes()).decode()}"


def test_old_tables_are_refused_naming_their_format_and_the_fix() -> None:
    """A model exported with format-5 tables (no static guard): loading it fails (MuJoCo's
    compiler makes an MjData, whose init fails), naming both formats and the fix: attach again
    or re-export."""
    spec = mujoco.MjSpec.from_string(XML)
    attach(spec, accel=5.0)
    assert _core.TABLES_VERSION == 7
    _with_config_entry(spec, _core.LAYOUT["CFG_VERSION"], 5.0)
    with pytest.raises(ValueError, match=r"tables format 5, this one reads 7\).*re-export"):
        spec.compile()
