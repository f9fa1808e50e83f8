"""MuJoCo's collision filter (dua_mujoco.build.filter) against a literal reference and MuJoCo."""

from __future__ import annotations

import importlib.resources
import pathlib

import mujoco
import numpy as np
import pytest

from dua_mujoco.build.covering import cover_model
from dua_mujoco.build.filter import (
    GeomPairs,
    active_geom_pairs,
    pairs_between_bodies,
    sphere_pair_mask,
    sphere_pairs,
)
from dua_mujoco.build.geom_types import GEOM_HFIELD, GEOM_PLANE
from dua_mujoco.exceptions import InvalidChoiceError, UnsupportedGeomError

# Parent-child, welded children, static bodies, mocap weld groups, explicit pairs (static-static,
# mocap-mocap, parent-child), excludes, contype/conaffinity, a height field and planes.
FILTER_XML = """
<mujoco>
  <asset><hfield name="hf" nrow="2" ncol="2" size="1 1 .1 .1"/></asset>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 .1"/>
    <geom name="wbox" type="box" size=".2 .2 .2" pos="0 0 .1"/>
    <geom name="terrain" type="hfield" hfield="hf"/>
    <body name="static1" pos="0 0 .1"><geom name="s1" type="sphere" size=".3"/>
      <geom name="s1plane" type="plane" size="1 1 .1"/>
      <body name="dynchild"><joint type="hinge"/><geom name="dc" type="sphere" size=".3"/></body>
    </body>
    <body name="static2" pos="0 0 .1"><geom name="s2" type="sphere" size=".3"/></body>
    <body name="mocap" mocap="true" pos="0 0 .1"><geom name="mc" type="sphere" size=".3"/>
      <body name="mocapchild"><geom name="mcc" type="sphere" size=".3"/></body>
      <body name="mocapdyn"><joint type="slide"/><geom name="mcd" type="sphere" size=".3"/></body>
    </body>
    <body name="mocap2" mocap="true" pos="0 0 .1"><geom name="mc2" type="sphere" size=".3"/></body>
    <body name="free" pos="0 0 .1"><freejoint/>
      <geom name="f" type="sphere" size=".3"/>
      <geom name="f_b" type="box" size=".1 .1 .1" contype="2" conaffinity="2"/>
      <body name="fchild"><joint type="hinge"/><geom name="fc" type="capsule" size=".1 .3"/>
        <body name="fgrand"><geom name="fg" type="sphere" size=".3" contype="2" conaffinity="1"/>
          <body name="fgreat"><joint type="hinge"/><geom name="fgg" type="sphere" size=".2"/></body>
        </body>
      </body>
    </body>
    <body name="free2" pos="0 0 .1"><freejoint/>
      <geom name="g" type="ellipsoid" size=".1 .2 .3" contype="4" conaffinity="0"/>
      <geom name="g_b" type="cylinder" size=".1 .2"/>
    </body>
  </worldbody>
  <contact>
    <pair geom1="s2" geom2="s1"/>
    <pair geom1="mc" geom2="mc2" margin=".1" gap=".2"/>
    <pair geom1="fc" geom2="f" margin=".05" gap=".01"/>
    <pair geom1="floor" geom2="g" margin=".02"/>
    <exclude body1="free" body2="free2"/>
    <exclude body1="fgrand" body2="free2"/>
  </contact>
</mujoco>"""


def _can_collide_reference(model: mujoco.MjModel, g1: int, g2: int) -> bool:
    """Slow, literal transcription of MuJoCo's filter for one geom pair .

    Follows ``mj_collision``/``mj_broadphase``/``filterBodyPair``/``filterCollisionPair`` in
    ``engine_collision_driver.c`` statement by statement, with the MuJoCo 4.0 rule that pairs where
    neither weld group has dofs are skipped. Geometry (bounding volumes) is ignored.
    """
    g1, g2 = int(g1), int(g2)
    if g1 == g2:
        return False
    opt_dis = int(model.opt.disableflags)
    if opt_dis & int(mujoco.mjtDisableBit.mjDSBL_CONTACT):
        return False
    if opt_dis & int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT):
        return False
    t1, t2 = int(model.geom_type[g1]), int(model.geom_type[g2])
    if t1 in (GEOM_PLANE, GEOM_HFIELD) and t2 in (GEOM_PLANE, GEOM_HFIELD):
        return False  # mjCOLLISIONFUNC[t1][t2] == NULL

    # predefined pairs are always tested
    for k in range(int(model.npair)):
        if {int(model.pair_geom1[k]), int(model.pair_geom2[k])} == {g1, g2}:
            return True

    b1, b2 = int(model.geom_bodyid[g1]), int(model.geom_bodyid[g2])
    if b1 == b2:
        return False  # broadphase never pairs a body with itself
    w1, w2 = int(model.body_weldid[b1]), int(model.body_weldid[b2])
    pw1 = int(model.body_weldid[int(model.body_parentid[w1])])
    pw2 = int(model.body_weldid[int(model.body_parentid[w2])])
    if w1 == w2:
        return False
    if int(model.body_dofnum[w1]) == 0 and int(model.body_dofnum[w2]) == 0:
        return False
    filterparent = not (opt_dis & int(mujoco.mjtDisableBit.mjDSBL_FILTERPARENT))
    if filterparent and w1 != 0 and w2 != 0 and (w1 == pw2 or w2 == pw1):
        return False
    signature = (min(b1, b2) << 16) + max(b1, b2)
    for k in range(int(model.nexclude)):
        if int(model.exclude_signature[k]) == signature:
            return False
    c1, a1 = int(model.geom_contype[g1]), int(model.geom_conaffinity[g1])
    c2, a2 = int(model.geom_contype[g2]), int(model.geom_conaffinity[g2])
    return bool((c1 & a2) or (c2 & a1))


def _with_flags(xml: str, flags: str) -> str:
    return xml.replace("<mujoco>", f"<mujoco><option><flag {flags}/></option>", 1)


FILTER_MODELS = {
    "default": FILTER_XML,
    "no_filterparent": _with_flags(FILTER_XML, 'filterparent="disable"'),
    "no_contact": _with_flags(FILTER_XML, 'contact="disable"'),
    "override": FILTER_XML.replace(
        "<mujoco>", '<mujoco><option o_margin=".07"><flag override="enable"/></option>', 1
    ),
    "margins": FILTER_XML.replace('size=".3"/>', 'size=".3" margin=".01" gap=".03"/>'),
}


def _pairset(gp: GeomPairs) -> set[tuple[int, int]]:
    return set(zip(gp.geom1.tolist(), gp.geom2.tolist(), strict=True))


def _reference_set(m: mujoco.MjModel) -> set[tuple[int, int]]:
    return {
        (a, b)
        for a in range(m.ngeom)
        for b in range(a + 1, m.ngeom)
        if _can_collide_reference(m, a, b)
    }


def _mujoco_oracle_set(m: mujoco.MjModel) -> set[tuple[int, int]]:
    """Pairs MuJoCo itself reports once every margin is huge: geometry then prunes nothing."""
    saved = (m.geom_margin.copy(), m.pair_margin.copy(), m.opt.o_margin)
    try:
        m.geom_margin[:] = 100.0
        m.pair_margin[:] = 200.0
        m.opt.o_margin = 200.0
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        return {
            (min(int(c.geom1), int(c.geom2)), max(int(c.geom1), int(c.geom2)))
            for c in d.contact[: d.ncon]
        }
    finally:
        m.geom_margin[:], m.pair_margin[:] = saved[0], saved[1]
        m.opt.o_margin = saved[2]


@pytest.mark.parametrize("name", list(FILTER_MODELS))
def test_filter_matches_reference_and_mujoco(name: str) -> None:
    m = mujoco.MjModel.from_xml_string(FILTER_MODELS[name])
    gp = active_geom_pairs(m)
    assert _pairset(gp) == _reference_set(m)
    assert _pairset(gp) == _mujoco_oracle_set(m)
    assert np.all(gp.geom1 < gp.geom2)
    assert gp.geom1.dtype == np.int32 and gp.margin.dtype == np.float64
    if name == "no_contact":
        assert gp.npair == 0


def _gid(m: mujoco.MjModel, name: str) -> int:
    return int(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name))


def test_filter_rules_spelled_out() -> None:
    m = mujoco.MjModel.from_xml_string(FILTER_XML)
    gp = active_geom_pairs(m)

    def active(a: str, b: str) -> bool:
        return gp.index_of(_gid(m, a), _gid(m, b)) >= 0

    assert not active("wbox", "s1")  # static-static
    assert active("s1", "s2")  # ... unless an explicit pair says so
    assert active("s1", "dc")  # no parent filter against a static parent
    # parent-child, but an explicit <pair> overrides every body filter (index_of: either order)
    assert active("fc", "f") and gp.explicit[gp.index_of(_gid(m, "f"), _gid(m, "fc"))]
    assert not active("fc", "fg")  # welded child: same weld group
    assert not active("fc", "fgg")  # parent-child through the weld group
    assert not active("mc", "mcd")  # mocap bodies filter their children (MuJoCo 4.0)
    assert not active("mc", "mcc")  # same weld group
    assert not active("mc", "wbox")  # neither can move (MuJoCo 4.0)
    assert not active("mcc", "mc2")
    assert active("mc", "mc2")  # explicit
    assert active("mcd", "mc2") and active("mc", "f")
    assert not active("f", "g_b")  # <exclude>
    assert not active("f_b", "dc")  # contype 2 vs conaffinity 1
    assert active("fg", "dc")  # fg.contype & dc.conaffinity = 0, but dc.contype & fg.conaffinity
    assert not active("floor", "terrain")  # no plane-hfield collider
    assert not active("floor", "s1plane")  # no plane-plane collider
    assert active("floor", "g")
    i = gp.index_of(_gid(m, "mc"), _gid(m, "mc2"))
    assert gp.explicit[i] and gp.margin[i] == pytest.approx(0.1)
    assert gp.contact_distance[i] == pytest.approx(0.3)
    assert gp.index_of(0, 0) == -1


def test_margin_and_gap_semantics() -> None:
    """Dynamic pairs sum geom margins and gaps; contacts appear at dist <= margin + gap."""
    xml = """<mujoco><worldbody>
      <body pos="0 0 1"><freejoint/><geom name="a" size=".5" margin=".1" gap=".05"/></body>
      <body pos="{x} 0 1"><freejoint/><geom name="b" size=".5" margin=".1" gap=".05"/></body>
      <body pos="0 3 1"><freejoint/><geom name="c" size=".5" margin=".1"/></body>
      <body pos="{y} 3 1"><freejoint/><geom name="e" size=".5"/></body>
    </worldbody><contact><pair geom1="c" geom2="e" margin="0" gap=".4"/></contact></mujoco>"""
    for sep, expect in [(0.19, 0), (0.21, 1), (0.29, 1), (0.31, None)]:
        m = mujoco.MjModel.from_xml_string(xml.format(x=1 + sep, y=1 + sep + 0.1))
        gp = active_geom_pairs(m)
        i = gp.index_of(0, 1)
        assert gp.margin[i] == pytest.approx(0.2) and gp.gap[i] == pytest.approx(0.1)
        assert gp.contact_distance[i] == pytest.approx(0.3)
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        con = [c for c in d.contact[: d.ncon] if {c.geom1, c.geom2} == {0, 1}]
        if expect is None:
            assert not con
        else:
            assert len(con) == 1 and con[0].exclude == expect
            assert con[0].includemargin == pytest.approx(gp.margin[i])
        j = gp.index_of(2, 3)
        assert gp.explicit[j] and gp.contact_distance[j] == pytest.approx(0.4)
        pair_con = [c for c in d.contact[: d.ncon] if {c.geom1, c.geom2} == {2, 3}]
        assert len(pair_con) == (1 if sep + 0.1 <= 0.4 else 0)


def _asset_paths() -> list[pathlib.Path]:
    paths: list[pathlib.Path] = []
    for package, sub in (("gymnasium", "envs/mujoco/assets"), ("dm_control", "suite")):
        try:
            root = pathlib.Path(str(importlib.resources.files(package) / sub))
        except ModuleNotFoundError:
            continue
        paths += sorted(root.glob("*.xml"))
    return paths


ASSETS = _asset_paths()
# Rollout length per asset; the dog is large (300 geoms), keep it short to stay within budget.
STEPS = {"dog.xml": 60}


def _load(path: pathlib.Path) -> mujoco.MjModel:
    try:
        return mujoco.MjModel.from_xml_path(str(path))
    except Exception as exc:  # MuJoCo cannot load it: not ours to test
        print(f"skipping {path.parent.name}/{path.name}: {exc}")
        pytest.skip(f"MuJoCo cannot load {path.name}: {exc}")


@pytest.mark.skipif(not ASSETS, reason="neither gymnasium nor dm_control is installed")
@pytest.mark.parametrize("path", ASSETS, ids=[f"{p.parent.name}/{p.name}" for p in ASSETS])
def test_asset_rollout_contacts_are_active_pairs(path: pathlib.Path) -> None:
    m = _load(path)
    gp = active_geom_pairs(m)
    # (c) the active set is exactly the reference filter
    assert _pairset(gp) == _reference_set(m)
    # every active pair of a real scene expands to sphere pairs (height fields as boxes)
    sp = sphere_pairs(cover_model(m, mode="multi", hfield="box"), gp)
    assert set(np.unique(sp.geom_pair).tolist()) == set(range(gp.npair))
    # (b) every contact MuJoCo reports along a random rollout is an active pair at its distance
    d = mujoco.MjData(m)
    rng = np.random.default_rng(0)
    lo, hi = m.actuator_ctrlrange.T if m.nu else (np.zeros(0), np.zeros(0))
    limited = np.asarray(m.actuator_ctrllimited, dtype=bool) if m.nu else np.zeros(0, bool)
    lo = np.where(limited, lo, -1.0)
    hi = np.where(limited, hi, 1.0)
    speculative = bool(int(m.opt.enableflags) & int(mujoco.mjtEnableBit.mjENBL_SPECULATIVE))
    ncontacts = 0
    for step in range(STEPS.get(path.name, 300)):
        if step % 10 == 0 and m.nu:
            d.ctrl[:] = rng.uniform(lo, hi)
        mujoco.mj_step(m, d)
        con = d.contact[: d.ncon]
        if d.ncon == 0:
            continue
        g1 = np.asarray(con.geom1)
        g2 = np.asarray(con.geom2)
        geom_contact = (g1 >= 0) & (g2 >= 0)
        idx = gp.indices_of(g1[geom_contact], g2[geom_contact])
        bad = np.flatnonzero(idx < 0)
        assert bad.size == 0, f"contact between geoms {g1[bad[0]]}, {g2[bad[0]]} not active"
        if not speculative:
            dist = np.asarray(con.dist)[geom_contact]
            assert np.all(dist <= gp.contact_distance[idx] + 1e-9)
        np.testing.assert_allclose(np.asarray(con.includemargin)[geom_contact], gp.margin[idx])
        ncontacts += int(geom_contact.sum())
    print(f"{path.name}: {gp.npair} active pairs, {ncontacts} contacts checked")


def test_large_model_is_vectorised() -> None:
    bodies = "".join(
        f'<body pos="{i % 40} {i // 40} 1"><freejoint/>'
        f'<geom size=".1"/><geom type="box" size=".1 .1 .1" pos=".2 0 0"/></body>'
        for i in range(1000)
    )
    m = mujoco.MjModel.from_xml_string(f"<mujoco><worldbody>{bodies}</worldbody></mujoco>")
    gp = active_geom_pairs(m)
    assert gp.npair == 2000 * 1999 // 2 - 1000
    rng = np.random.default_rng(0)
    for a, b in rng.integers(0, m.ngeom, size=(50, 2)):
        assert (gp.index_of(a, b) >= 0) == _can_collide_reference(m, a, b)


SPHERE_PAIR_XML = """
<mujoco><worldbody>
  <geom name="floor" type="plane" size="5 5 .1" margin=".01"/>
  <geom name="wall" type="plane" size="5 5 .1" pos="3 0 0" euler="0 90 0"/>
  <body name="arm" pos="0 0 1"><freejoint/>
    <geom name="upper" type="capsule" size=".05 .3" margin=".02" gap=".01"/>
    <body name="fore" pos="0 0 .6"><joint type="hinge"/>
      <geom name="lower" type="box" size=".05 .05 .3"/>
    </body>
  </body>
  <body name="ball" pos="1 0 1"><freejoint/><geom name="ball" size=".1" margin=".03"/></body>
</worldbody></mujoco>"""


@pytest.mark.parametrize("mode", ["bounding", "multi"])
def test_sphere_pairs_expand_geom_pairs(mode: str) -> None:
    m = mujoco.MjModel.from_xml_string(SPHERE_PAIR_XML)
    cov = cover_model(m, mode=mode, max_spheres_per_geom=4)
    gp = active_geom_pairs(m)
    sp = sphere_pairs(cov, gp)
    assert len(sp) == sp.first.shape[0]
    for p in range(gp.npair):
        g1, g2 = int(gp.geom1[p]), int(gp.geom2[p])
        rows = np.flatnonzero(sp.geom_pair == p)
        if cov.geom_plane[g1] >= 0 and cov.geom_plane[g2] >= 0:
            assert rows.size == 0
            continue
        if cov.geom_plane[g1] >= 0 or cov.geom_plane[g2] >= 0:
            plane, other = (g1, g2) if cov.geom_plane[g1] >= 0 else (g2, g1)
            assert np.all(sp.is_halfspace[rows])
            assert set(sp.first[rows]) == set(cov.spheres_of(other))
            assert np.all(sp.second[rows] == cov.geom_plane[plane])
            want = cov.sphere_radius[sp.first[rows]] + gp.contact_distance[p]
        else:
            assert not np.any(sp.is_halfspace[rows])
            got = set(zip(sp.first[rows].tolist(), sp.second[rows].tolist(), strict=True))
            assert got == {(a, b) for a in cov.spheres_of(g1) for b in cov.spheres_of(g2)}
            want = (
                cov.sphere_radius[sp.first[rows]]
                + cov.sphere_radius[sp.second[rows]]
                + gp.contact_distance[p]
            )
        np.testing.assert_allclose(sp.eps[rows], want)
    sel = pairs_between_bodies(m, gp, "ball", "arm")
    assert {(int(gp.geom1[i]), int(gp.geom2[i])) for i in sel} == {
        (_gid(m, "upper"), _gid(m, "ball"))
    }
    mask = sphere_pair_mask(sp, sel)
    assert np.array_equal(mask, np.isin(sp.geom_pair, sel))
    assert np.array_equal(sphere_pair_mask(sp, iter(sel.tolist())), mask)
    everything = pairs_between_bodies(m, gp, 0)
    assert everything.size == np.count_nonzero(m.geom_bodyid[gp.geom1] == 0)
    with pytest.raises(InvalidChoiceError, match="ball"):
        pairs_between_bodies(m, gp, "nosuchbody")


def test_moving_plane_is_rejected() -> None:
    # The compiler only allows planes on bodies without dofs; a mocap body can still move.
    m = mujoco.MjModel.from_xml_string(
        """<mujoco><worldbody>
        <body name="tray" mocap="true"><geom name="tray" type="plane" size="1 1 .1"/></body>
        <body><freejoint/><geom size=".1"/></body>
        </worldbody></mujoco>"""
    )
    with pytest.raises(UnsupportedGeomError, match="plane geom 0"):
        sphere_pairs(cover_model(m), active_geom_pairs(m))


def _lazy_parity(m: mujoco.MjModel) -> None:
    """A pruned predictor's filter on candidates gives MuJoCo's pairs: the explicit pairs and
    the candidates' filtered geom pairs, offered every geom pair, are ``active_geom_pairs``
    (with the same distances), and the universe's count of the model's pairs is its size."""
    from dua_mujoco.build.covering import cover_model
    from dua_mujoco.build.filter import candidate_geom_pairs, explicit_geom_pairs
    from dua_mujoco.build.pairfilter import FilterTables
    from dua_mujoco.build.universe import PairUniverse

    full = active_geom_pairs(m)
    explicit = explicit_geom_pairs(m)
    g1, g2 = np.triu_indices(m.ngeom, 1)
    known = explicit.indices_of(g1, g2) >= 0
    lazy = explicit.concat(candidate_geom_pairs(m, FilterTables.of(m), g1[~known], g2[~known]))
    assert _pairset(lazy) == _pairset(full)
    idx = lazy.indices_of(full.geom1, full.geom2)
    np.testing.assert_array_equal(lazy.contact_distance[idx], full.contact_distance)
    np.testing.assert_array_equal(lazy.explicit[idx], full.explicit)
    covering = cover_model(m, hfield="box")
    universe = PairUniverse(m, covering, lazy=True, exact=None)
    eager = PairUniverse(m, covering, lazy=False, exact=None)
    assert universe.counts() == eager.counts() == (full.npair, eager.npair)


@pytest.mark.parametrize("name", list(FILTER_MODELS))
def test_the_filter_on_candidates_gives_mujocos_pairs(name: str) -> None:
    _lazy_parity(mujoco.MjModel.from_xml_string(FILTER_MODELS[name]))


@pytest.mark.parametrize("classes", [2, 1 << 30])
def test_the_count_by_classes_is_the_pair_loops(classes: int) -> None:
    """``count_dynamic_pairs`` (by geom classes, less the listed related pairs; with many
    classes the pair loop) equals the pairs ``all_dynamic_pairs`` lists and their weights, on
    random tables with shared welds, parent joints and duplicate, same-body exclusions."""
    from dua_mujoco.build.pairfilter import FilterTables, all_dynamic_pairs, count_dynamic_pairs

    rng = np.random.default_rng(classes)
    for _ in range(200):
        n, nbody = int(rng.integers(0, 120)), int(rng.integers(1, 40))
        body_weld = np.minimum(rng.integers(0, nbody, nbody), np.arange(nbody))
        body = rng.integers(0, nbody, n)
        weld = body_weld[body]
        b1, b2 = rng.integers(0, nbody, (2, int(rng.integers(0, nbody))))
        tables = FilterTables(
            body=body,
            weld=weld,
            parent_weld=body_weld[rng.integers(0, nbody, nbody)][weld],
            movable=rng.random(nbody)[weld] < 0.8,
            contype=rng.integers(0, classes, n),
            conaffinity=rng.integers(0, classes, n),
            lone=rng.random(n) < 0.2,
            exclude=np.sort((np.minimum(b1, b2) << 16) + np.maximum(b1, b2)),
            filterparent=bool(rng.random() < 0.7),
        )
        weight = rng.integers(1, 5, n)
        g1, g2 = all_dynamic_pairs(tables)
        assert count_dynamic_pairs(tables, weight) == (g1.size, int(weight[g1] @ weight[g2]))


@pytest.mark.parametrize("scene", ["two_arms", "traffic", "clutter", "bin_pour:40", "swarm:300"])
def test_the_filter_on_candidates_gives_mujocos_pairs_on_scenes(scene: str) -> None:
    from dua_mujoco.models.scenes import load_scene

    _lazy_parity(load_scene(scene)[0])


@pytest.mark.skipif(not ASSETS, reason="neither gymnasium nor dm_control is installed")
@pytest.mark.parametrize("path", ASSETS, ids=[f"{p.parent.name}/{p.name}" for p in ASSETS])
def test_the_filter_on_candidates_gives_mujocos_pairs_on_assets(path: pathlib.Path) -> None:
    _lazy_parity(_load(path))


@pytest.mark.parametrize(
    "scene", ["two_arms", "clutter", "bin_pour:20", "traffic", "rough_terrain"]
)
def test_pair_tables_equal_a_loop_over_geom_pairs(scene: str) -> None:
    """The native expansion, bounds and exact records (one implementation, which the plugin's
    pruned pairs use too) equal a plain loop over the geom pairs: sphere pairs in order (each
    geom pair's, the sphere-covered geom's spheres first), eps, summed bounds, exact modes."""
    from dua_mujoco.build.bounds import MotionBounds
    from dua_mujoco.build.exact import GX_KIND, ExactMode, build_exact
    from dua_mujoco.build.pairbounds import bounded_pairs
    from dua_mujoco.core.pairset import PairKind
    from dua_mujoco.core.shapes import ShapeKind
    from dua_mujoco.models.scenes import load_scene

    m, _ = load_scene(scene)
    cov = cover_model(m, mode="multi", max_spheres_per_geom=3)
    gp = active_geom_pairs(m)
    sp = sphere_pairs(cov, gp)
    rows = []
    for k in range(gp.npair):
        g1, g2 = int(gp.geom1[k]), int(gp.geom2[k])
        lone1 = cov.geom_plane[g1] >= 0 or cov.geom_shape[g1] >= 0
        ga, gb = (g2, g1) if lone1 else (g1, g2)
        if cov.geom_plane[gb] >= 0 and cov.geom_plane[ga] >= 0:
            continue
        d = float(gp.contact_distance[k])
        for i in cov.spheres_of(ga).tolist():
            if cov.geom_plane[gb] >= 0:
                rows.append((i, int(cov.geom_plane[gb]), 1, k, cov.sphere_radius[i] + 0.0 + d))
            elif cov.geom_shape[gb] >= 0:
                rows.append((i, int(cov.geom_shape[gb]), 2, k, cov.sphere_radius[i] + 0.0 + d))
            else:
                for j in cov.spheres_of(gb).tolist():
                    rows.append((i, j, 0, k, cov.sphere_radius[i] + cov.sphere_radius[j] + d))
    want = np.array(rows, dtype=object).reshape(-1, 5)
    np.testing.assert_array_equal(sp.first, want[:, 0].astype(int))
    np.testing.assert_array_equal(sp.second, want[:, 1].astype(int))
    np.testing.assert_array_equal(sp.kind, want[:, 2].astype(int))
    np.testing.assert_array_equal(sp.geom_pair, want[:, 3].astype(int))
    np.testing.assert_array_equal(sp.eps, want[:, 4].astype(float))  # the same sums, exactly
    # (The quadruped on terrain collides with its ground alone: shape pairs only.)
    assert (sp.kind == int(PairKind.SPHERE)).any() or scene == "rough_terrain"

    rng = np.random.default_rng(0)
    accel, delta = rng.uniform(0, 50, m.nbody), rng.uniform(0, 0.1, m.nbody)
    accel[0] = delta[0] = 0.0
    bounds = MotionBounds(accel=accel, vel_uncertainty=delta, speed=rng.uniform(1, 9, m.nbody))
    ps = bounded_pairs(m, cov, sp, bounds)
    b1 = cov.sphere_body[sp.first]
    b2 = np.where(sp.kind == 0, cov.sphere_body[np.where(sp.kind == 0, sp.second, 0)], 0)
    np.testing.assert_array_equal(ps.accel, accel[b1] + accel[b2])
    np.testing.assert_array_equal(ps.vel_uncertainty, delta[b1] + delta[b2])
    assert bounds.speed is not None
    v = bounds.speed
    np.testing.assert_array_equal(ps.speed, np.where(sp.kind == 0, v[b1] + v[b2], v[b1]))

    planes = np.append(np.asarray(cov.plane_geom), -1)  # a last entry for the other kinds
    shapes = np.append(np.asarray(cov.shape_geom), -1)
    geom2 = np.where(
        sp.kind == 1,
        planes[np.where(sp.kind == 1, sp.second, -1)],
        np.where(
            sp.kind == 2,
            shapes[np.where(sp.kind == 2, sp.second, -1)],
            cov.sphere_geom[np.where(sp.kind == 0, sp.second, 0)],
        ),
    )
    geom1 = cov.sphere_geom[sp.first]
    level = build_exact(m, geom1, geom2, sp.kind, sp.eps, 1.0)
    for p in range(sp.npair):
        kind, g1, g2 = int(sp.kind[p]), int(geom1[p]), int(geom2[p])
        # Geoms with a support of their own (kinds from SPHERE on); a height field held as
        # terrain (a shape pair) is read through its grid.
        k1, k2 = level.geoms[g1, GX_KIND], level.geoms[g2, GX_KIND]
        terrain = kind == 2 and k2 == int(ShapeKind.HFIELD)
        usable = k1 >= int(ShapeKind.SPHERE) and (
            kind == 1 or terrain or k2 >= int(ShapeKind.SPHERE)
        )
        mode = [ExactMode.GEOMS, ExactMode.PLANE, ExactMode.SHAPE][kind] if usable else 0
        mode = ExactMode.TERRAIN if usable and terrain else mode
        want_row = [mode, g1, g2, sp.eps[p], 0, 0, 0, -1, -1, 0]
        np.testing.assert_array_equal(level.records[p], want_row)
    if scene == "rough_terrain":
        assert (level.records[:, 0] == int(ExactMode.TERRAIN)).all()
