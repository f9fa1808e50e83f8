"""The exact level of the urgency (dua_mujoco/build/exact.py, docs/theory.md section 5).

Held to a slow reference written from the definitions (numpy supports, the quadratic's root),
and to trajectories: two geoms of every type pair (and a plane) move rigidly with a constant
linear acceleration and a constant angular velocity, so that every point of each geom has an
acceleration of at most ``|a| + |w|^2 r``; the exact tau must never be later than the first
instant MuJoCo's own distance says they are within contact distance. A test shows that the
rotation term is what keeps it so.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator

import mujoco
import numpy as np
import pytest
from geom_types import BLOB_ASSET, GEOM_TYPES
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dua_mujoco import _core
from dua_mujoco.build.bounds import MotionBounds
from dua_mujoco.build.exact import (
    GX_RADIUS,
    X_DIST,
    X_G1,
    X_G2,
    X_HULL1,
    X_HULL2,
    X_MODE,
    X_N,
    ExactMode,
    corner_points,
)
from dua_mujoco.build.options import CoveringOptions
from dua_mujoco.core.pairset import PAIR_ACCEL, PAIR_DELTA
from dua_mujoco.runtime.predictor import Predictor


def _model(a: str, b: str) -> mujoco.MjModel:
    """Two free bodies with geoms of types ``a`` and ``b`` (``b == "plane"``: a plane, static)."""
    second = (
        '<geom name="B" type="plane" size="3 3 .1" euler="8 -5 0"/>'
        if b == "plane"
        else f'<body name="b" pos=".8 0 1"><freejoint/><geom name="B" {GEOM_TYPES[b]}/></body>'
    )
    return mujoco.MjModel.from_xml_string(
        f"""<mujoco>
          <option gravity="0 0 0"/>
          {BLOB_ASSET}
          <worldbody>
            {second}
            <body name="a" pos="0 0 1"><freejoint/><geom name="A" {GEOM_TYPES[a]}/></body>
          </worldbody>
        </mujoco>"""
    )


def _pose(model, data, body, pos, quat, lin, ang) -> None:
    j = model.body_jntadr[body]
    qa, va = model.jnt_qposadr[j], model.jnt_dofadr[j]
    data.qpos[qa : qa + 3] = pos
    data.qpos[qa + 3 : qa + 7] = quat
    # A free joint's qvel: linear velocity of the body origin (world), angular (body frame).
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, quat)
    data.qvel[va : va + 3] = lin
    data.qvel[va + 3 : va + 6] = rot.reshape(3, 3).T @ ang


def _quat_at(q0: np.ndarray, w: np.ndarray, t: float) -> np.ndarray:
    """``exp([w] t) R0`` as a quaternion (rotation about a fixed world axis)."""
    out = np.empty(4)
    dq = np.empty(4)
    angle = np.linalg.norm(w) * t
    axis = w / np.linalg.norm(w) if angle > 0 else np.array([1.0, 0.0, 0.0])
    mujoco.mju_axisAngle2Quat(dq, axis, angle)
    mujoco.mju_mulQuat(out, dq, q0)
    return out


class Motion:
    """Rigid motions of the moving bodies: constant linear acceleration of the body origin,
    constant world angular velocity; ``state(t)`` writes them and runs the kinematics."""

    def __init__(self, model: mujoco.MjModel, draw: dict) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        self.draw = draw

    def bodies(self) -> list[int]:
        return [b for b in range(1, self.model.nbody) if self.model.body_jntnum[b]]

    def state(self, t: float) -> mujoco.MjData:
        m, d = self.model, self.data
        for b in self.bodies():
            p0, v0, a0, q0, w = (self.draw[b][k] for k in ("p", "v", "a", "q", "w"))
            pos = p0 + v0 * t + 0.5 * a0 * t * t
            _pose(m, d, b, pos, _quat_at(q0, w, t), v0 + a0 * t, w)
        mujoco.mj_forward(m, d)
        return d

    def accel_bound(self) -> dict[str, float]:
        """``|a| + |w|^2 r`` per body: every point of its geoms accelerates at most this."""
        out = {}
        for b in self.bodies():
            g = int(np.flatnonzero(self.model.geom_bodyid == b)[0])
            box = self.model.geom_aabb[g]
            corner = np.linalg.norm(np.abs(box[:3]) + box[3:])
            r = max(float(self.model.geom_rbound[g]), corner)
            w = np.linalg.norm(self.draw[b]["w"])
            out[self.model.body(b).name] = float(np.linalg.norm(self.draw[b]["a"]) + w * w * r)
        return out


def _exact_only(
    p: Predictor,
    data: mujoco.MjData,
    *,
    query: bool = True,
    coarse: float = 0.0,
    geoms: np.ndarray | None = None,
) -> np.ndarray:
    """The native exact level's tau of every pair from a sphere tau of ``coarse`` (MuJoCo asked
    afresh when ``query``), on a runtime of ``p``'s tables (with ``geoms`` for its exact-level
    geom table, when given)."""
    assert p.exact is not None
    rt = p._rt
    if geoms is not None:
        arrays = {**p.table_arrays, "exact_geoms": geoms}
        names = list(p.universe.tables.geom_names)
        rt = _core.Runtime(_core.Tables.build(p.model, arrays), p.model, names)
    p.check_data(data)
    rt.bind(data)
    ids = np.arange(p.nsphere_pairs)
    return rt.exact_only(ids, np.full(ids.size, coarse), math.inf if query else 0.0)


# --------------------------------------------------------------------------- the reference


def _support(model: mujoco.MjModel, data: mujoco.MjData, g: int, n: np.ndarray) -> float:
    """max over geom g of n.p, from the definitions (a mesh: over all its vertices)."""
    R = data.geom_xmat[g].reshape(3, 3)
    c = data.geom_xpos[g]
    m = R.T @ n
    t = int(model.geom_type[g])
    s = model.geom_size[g]
    G = mujoco.mjtGeom
    if t == int(G.mjGEOM_SPHERE):
        h = s[0] * np.linalg.norm(m)
    elif t == int(G.mjGEOM_CAPSULE):
        h = max(m[2] * s[1], -m[2] * s[1]) + s[0] * np.linalg.norm(m)
    elif t == int(G.mjGEOM_CYLINDER):
        h = abs(m[2]) * s[1] + s[0] * np.linalg.norm(m[:2])
    elif t == int(G.mjGEOM_ELLIPSOID):
        h = np.linalg.norm(s * m)
    elif t == int(G.mjGEOM_BOX):
        h = float(np.abs(m) @ s)
    elif model.mesh_graphadr[model.geom_dataid[g]] >= 0:  # mesh: every vertex (the hull's max)
        mesh = model.geom_dataid[g]
        start = model.mesh_vertadr[mesh]
        h = float((model.mesh_vert[start : start + model.mesh_vertnum[mesh]] @ m).max())
    else:  # a mesh without a hull graph: its box in the geom frame
        lo = model.geom_aabb[g, :3] - model.geom_aabb[g, 3:]
        hi = model.geom_aabb[g, :3] + model.geom_aabb[g, 3:]
        corners = np.array(
            [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
        )
        h = float((corners @ m).max())
    return float(n @ c + h)


def reference_exact_tau(p: Predictor, data: mujoco.MjData, pair: int) -> float:
    """The exact level's tau of one pair, slowly: MuJoCo's witness direction, the supports
    from their definitions, the origins' velocities from ``mj_objectVelocity`` and the first
    positive root of ``gap + (vn - delta) t - A t^2 / 2``."""
    m = p.model
    mode, g1, g2, dist = (p.exact.records[pair, k] for k in (X_MODE, X_G1, X_G2, X_DIST))
    g1, g2 = int(g1), int(g2)
    if int(mode) == ExactMode.NONE:
        return 0.0

    def origin(g: int) -> tuple[np.ndarray, np.ndarray]:
        v = np.empty(6)
        mujoco.mj_objectVelocity(m, data, mujoco.mjtObj.mjOBJ_GEOM, g, v, 0)
        return v[3:], v[:3]  # linear, angular (world)

    va, wa = origin(g1)
    spin = np.linalg.norm(wa) * p.exact.geoms[g1, GX_RADIUS]
    if int(mode) == ExactMode.PLANE:
        n = -data.geom_xmat[g2].reshape(3, 3)[:, 2]
        low_b = float(n @ data.geom_xpos[g2])
        vb = np.zeros(3)
    else:
        fromto = np.zeros(6)
        reach = np.linalg.norm(data.geom_xpos[g2] - data.geom_xpos[g1]) + dist + 1.0
        d = mujoco.mj_geomDistance(m, data, g1, g2, reach, fromto)
        if d <= dist:
            return 0.0
        n = fromto[3:] - fromto[:3]
        n /= np.linalg.norm(n)
        low_b = -_support(m, data, g2, -n)
        vb, wb = origin(g2)
        spin += np.linalg.norm(wb) * p.exact.geoms[g2, GX_RADIUS]
    gap = low_b - _support(m, data, g1, n) - dist
    if gap <= 0:
        return 0.0
    rec = p.pair_records[pair]
    w = float(n @ (vb - va)) - spin - rec[PAIR_DELTA]
    a = rec[PAIR_ACCEL]
    if a == 0:
        return math.inf if w >= 0 else gap / -w
    return (w + math.sqrt(w * w + 2 * a * gap)) / a


# --------------------------------------------------------------------------- strategies

PAIRS = [(a, b) for a in GEOM_TYPES for b in [*GEOM_TYPES, "plane"]]


def _draws(rng: np.random.Generator, model: mujoco.MjModel, speed: float) -> dict:
    out = {}
    for b in range(1, model.nbody):
        if not model.body_jntnum[b]:
            continue
        q = rng.normal(size=4)
        out[b] = {
            "p": np.array([0.0, 0.0, 1.0]) if b == model.nbody - 1 else np.array([0.8, 0.0, 1.0]),
            "v": rng.normal(size=3) * speed,
            "a": rng.normal(size=3) * 2.0,
            "q": q / np.linalg.norm(q),
            "w": rng.normal(size=3) * 3.0,
        }
        out[b]["p"] = out[b]["p"] + rng.normal(size=3) * 0.15
    return out


def _over_pairs(*, examples: int, top_speed: float) -> Callable[[Callable], Callable]:
    """A test over every type pair ``(a, b)`` in ``PAIRS``, each with ``examples`` seeds and
    speeds (m/s, up to ``top_speed``) drawn by hypothesis."""

    def wrap(test: Callable) -> Callable:
        test = given(seed=st.integers(0, 2**32 - 1), speed=st.floats(0.0, top_speed))(test)
        slow = [HealthCheck.too_slow]
        test = settings(max_examples=examples, deadline=None, suppress_health_check=slow)(test)
        return pytest.mark.parametrize(("a", "b"), PAIRS)(test)

    return wrap


def _predictor(model: mujoco.MjModel, motion: Motion, *, horizon: int = 1) -> Predictor:
    bounds = MotionBounds.declare(model, motion.accel_bound(), integrator_term=False)
    dt = float(model.opt.timestep)
    return Predictor(model, accel=bounds, pairs="all", alarm_horizon=horizon * dt)


# --------------------------------------------------------------------------- tests


def _beside_the_reference(
    model: mujoco.MjModel, rng: np.random.Generator, count: int
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """``count`` drawn states of ``model``'s two bodies, each a fresh predictor's native exact
    tau of every pair (MuJoCo asked) beside the reference's."""
    for _ in range(count):
        motion = Motion(model, _draws(rng, model, 1.0))
        p = _predictor(model, motion)
        data = motion.state(0.0)
        got = _exact_only(p, data)
        yield got, np.array([reference_exact_tau(p, data, k) for k in range(got.size)])


@pytest.mark.parametrize(("a", "b"), PAIRS)
def test_exact_tau_equals_the_reference(a: str, b: str) -> None:
    rng = np.random.default_rng(hash((a, b)) % 2**32)
    for got, want in _beside_the_reference(_model(a, b), rng, 5):
        assert np.allclose(got, want, rtol=1e-9, atol=1e-12), (got, want)


_BALL = np.random.default_rng(3).normal(size=(400, 3))
_BALL = (_BALL / np.linalg.norm(_BALL, axis=1)[:, None] * [0.15, 0.1, 0.08]).ravel()


def test_the_climb_over_a_dense_hull_reaches_the_reference_support() -> None:
    """Two meshes of some 400 hull vertices each (points on an ellipsoid): the support along
    MuJoCo's witness direction is climbed from the seed vertex, many steps of a vertex's row of
    neighbours each, so a row with a wrong neighbour or coordinate stops the climb short or
    reads another height. The tau equals the reference's, whose supports are the largest
    height over every vertex."""
    asset = f'<asset><mesh name="ball" vertex="{" ".join(f"{x:.5f}" for x in _BALL)}"/></asset>'
    model = mujoco.MjModel.from_xml_string(
        f"""<mujoco>
          <option gravity="0 0 0"/>
          {asset}
          <worldbody>
            <body name="b" pos=".8 0 1"><freejoint/><geom type="mesh" mesh="ball"/></body>
            <body name="a" pos="0 0 1"><freejoint/><geom type="mesh" mesh="ball"/></body>
          </worldbody>
        </mujoco>"""
    )
    assert model.mesh_graph[model.mesh_graphadr[0]] > 300  # the hull's vertices
    for got, want in _beside_the_reference(model, np.random.default_rng(5), 12):
        assert np.all(want > 0.0)  # apart: the supports decide
        assert np.allclose(got, want, rtol=1e-9, atol=1e-12), (got, want)


@_over_pairs(examples=25, top_speed=4.0)
def test_no_trajectory_within_the_bounds_beats_the_exact_tau(
    a: str, b: str, seed: int, speed: float
) -> None:
    """MuJoCo's own distance stays above the contact distance before tau (every type pair)."""
    model = _model(a, b)
    motion = Motion(model, _draws(np.random.default_rng(seed), model, speed))
    p = _predictor(model, motion)
    horizon = min(float(_exact_only(p, motion.state(0.0)).min()), 1.0)
    for t in np.linspace(0.0, horizon, 41)[:-1] if horizon > 0.0 else []:
        dist = mujoco.mj_geomDistance(model, motion.state(float(t)), 1, 0, 10.0, None)
        assert dist > 0.0, (t, horizon, dist)


def test_the_rotation_term_is_needed() -> None:
    """A long box spinning in place towards a sphere: without the |w| r term the bound along
    the witness direction (no translation) is late; with it, it is not."""
    model = _model("box", "sphere")
    still = {"v": np.zeros(3), "a": np.zeros(3), "q": np.array([1.0, 0.0, 0.0, 0.0])}
    draw = {
        2: {**still, "p": np.array([0.0, 0.0, 1.0]), "w": np.array([0.0, 0.0, 6.0])},
        1: {**still, "p": np.array([0.0, 0.38, 1.0]), "w": np.zeros(3)},
    }
    motion = Motion(model, draw)
    p = _predictor(model, motion)
    data = motion.state(0.0)
    tau = float(_exact_only(p, data)[0])
    # First instant the spinning box reaches the sphere (MuJoCo's distance).
    ts = np.linspace(0.0, 0.5, 5001)
    hit = next(
        t for t in ts if mujoco.mj_geomDistance(model, motion.state(t), 1, 0, 10.0, None) <= 0
    )
    assert tau <= hit
    # Dropping the term: the sphere tau and the translation-only bound both say "later".
    no_rotation = p.exact.geoms.copy()
    no_rotation[:, GX_RADIUS] = 0.0
    no_spin = float(_exact_only(p, motion.state(0.0), geoms=no_rotation)[0])
    assert no_spin > hit


def test_corner_points_bound_the_acceleration_of_every_point() -> None:
    """The acceleration of a rigid point is affine in its body coordinates: its largest norm over
    the geom's box is at a corner (checked against points sampled inside)."""
    model = _model("box", "mesh")
    rng = np.random.default_rng(0)
    g, _, off = corner_points(model, [1])
    assert g.shape == (8,) and off.shape == (8, 3)
    lin, ang, alpha = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3)

    def acc(x: np.ndarray) -> np.ndarray:
        return lin + np.cross(alpha, x) + np.cross(ang, np.cross(ang, x))

    corner = max(np.linalg.norm(acc(o)) for o in off)
    lo, hi = off.min(axis=0), off.max(axis=0)
    inside = rng.uniform(lo, hi, size=(2000, 3))
    assert max(np.linalg.norm(acc(x)) for x in inside) <= corner + 1e-12


def test_height_fields_keep_their_sphere_tau() -> None:
    model = mujoco.MjModel.from_xml_string(
        """<mujoco><asset><hfield name="h" nrow="3" ncol="3" size="1 1 .1 .1"/></asset>
          <worldbody><geom type="hfield" hfield="h"/>
          <body pos="0 0 1"><freejoint/><geom type="box" size=".1 .1 .1"/></body>
          </worldbody></mujoco>"""
    )
    p = Predictor(model, accel=1.0, covering=CoveringOptions(mode="bounding", hfield="box"))
    assert p.exact is not None
    assert (p.exact.records[:, X_MODE] == ExactMode.NONE).all()


def test_the_reset_remembers_the_direction_and_the_bounds_cover_the_corners() -> None:
    model = _model("capsule", "box")
    still = {"v": np.zeros(3), "a": np.ones(3), "q": np.array([1.0, 0.0, 0.0, 0.0])}
    draw = {
        2: {**still, "p": np.array([0.0, 0.0, 1.0]), "w": np.zeros(3)},
        1: {**still, "p": np.array([0.0, 0.5, 1.0]), "w": np.zeros(3)},
    }
    motion = Motion(model, draw)
    p = _predictor(model, motion)
    p.reset(motion.state(0.0))
    assert p.exact is not None
    # The corners of both moving geoms are bound points (the pilot and the monitor read them).
    assert {0, 1} <= set(p.bound_points[0].tolist())
    n = p._rt.exact_records[0, X_N : X_N + 3]
    assert np.isclose(np.linalg.norm(n), 1.0) and abs(n[1]) > 0.99  # along y, capsule to box


def test_a_pair_in_mujocos_contacts_keeps_its_sphere_tau_and_no_other_pair_does() -> None:
    """A pair MuJoCo holds in contact is touching along every direction: the level keeps the
    sphere tau without asking MuJoCo (GJK and EPA) for a direction. Read here from a contact
    list left over from another state, so that the skip shows: the pairs are apart now. Both
    orders are met (MuJoCo lists the plane first, the level second), and a listed contact
    farther than the pair's contact distance is no reason to skip."""
    boxes = "".join(
        f'<body name="{n}" pos="{x} 0 {z}"><freejoint/><geom name="{n}" type="box" '
        'size=".1 .1 .1"/></body>'
        for n, x, z in (("A", 0.0, 1.0), ("B", 0.15, 1.0), ("C", -0.4, 0.05))
    )
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><option gravity="0 0 0"/><worldbody><geom name="floor" type="plane" '
        f'size="3 3 .1"/>{boxes}</worldbody></mujoco>'
    )
    p = Predictor(model, accel=MotionBounds.declare(model, 1.0), pairs="all")
    assert p.exact is not None
    g1, g2 = (np.asarray(g) for g in p.sphere_pair_geoms)
    a, b, c, floor = (
        mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n) for n in ("A", "B", "C", "floor")
    )
    ab = ((g1 == a) & (g2 == b)) | ((g1 == b) & (g2 == a))
    cf = (g1 == c) & (g2 == floor)
    assert ab.any() and cf.any()
    stale = mujoco.MjData(model)
    mujoco.mj_forward(model, stale)
    listed_pairs = {frozenset(map(int, con.geom)) for con in stale.contact}
    assert listed_pairs == {frozenset((a, b)), frozenset((c, floor))}
    assert any(int(con.geom[0]) == floor for con in stale.contact)  # the plane first
    fresh = mujoco.MjData(model)
    for data in (stale, fresh):
        data.qpos[7] = 0.5  # B 35 cm further from A
        data.qpos[16] = 0.5  # C 45 cm above the floor; only the kinematics follow
        mujoco.mj_kinematics(model, data)
    coarse = p.exact.exact_below / 2
    apart = _exact_only(p, fresh, coarse=coarse)
    listed = _exact_only(p, stale, coarse=coarse)
    for pair in (ab, cf):
        assert np.all(apart[pair] > coarse) and np.all(listed[pair] == coarse)
    others = ~(ab | cf)
    assert np.array_equal(listed[others], apart[others])
    # Contacts within wider margins than the pairs': listed, but not touching by the pairs' own
    # contact distance, so they are looked at.
    wide = mujoco.MjData(model)
    wide.qpos[:] = fresh.qpos
    margin = model.geom_margin.copy()
    model.geom_margin[:] = 0.5
    try:
        mujoco.mj_forward(model, wide)
    finally:
        model.geom_margin[:] = margin
    assert any(frozenset(map(int, con.geom)) == frozenset((a, b)) for con in wide.contact)
    assert np.array_equal(_exact_only(p, wide, coarse=coarse), apart)


# --------------------------------------------------------------------------- queries not made


def _near(rng: np.random.Generator, model: mujoco.MjModel, speed: float) -> dict:
    """Draws of ``_draws`` with the two bodies' bounding spheres overlapping (every step looks at
    the pair exactly), B approaching A or leaving it at up to ``speed``."""
    out = _draws(rng, model, speed)
    bodies = sorted(out)
    if len(bodies) == 2:
        a, b = bodies[1], bodies[0]  # "a" is the last body
        radius = sum(
            float(model.geom_rbound[np.flatnonzero(model.geom_bodyid == k)[0]]) for k in bodies
        )
        u = rng.normal(size=3)
        out[b]["p"] = out[a]["p"] + u / np.linalg.norm(u) * radius * rng.uniform(0.5, 1.0)
    return out


@_over_pairs(examples=15, top_speed=3.0)
def test_a_query_not_made_could_not_have_cleared_the_alarm(
    a: str, b: str, seed: int, speed: float
) -> None:
    """The level asks MuJoCo for a new direction only where one could clear the pair's alarm
    (docs/theory.md, section 5, "Queries that cannot clear"): at every step, a pair the step
    leaves in alarm has no direction that clears it, MuJoCo's witness direction at that state
    included (the reference), and MuJoCo's direction never clears a pair the step alarms."""
    _alarms_no_direction_clears(a, b, seed, speed)


@given(seed=st.integers(0, 2**32 - 1), speed=st.floats(0.0, 1.5))
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_between_two_hulls_a_query_not_made_could_not_have_cleared_the_alarm(
    seed: int, speed: float
) -> None:
    """The same between two meshes, more often: there the test that no direction clears also
    reads the hull vertices the supports reached, and the direction between them is tried before
    asking (docs/theory.md, section 5, "Two pairs of points")."""
    _alarms_no_direction_clears("mesh", "mesh", seed, speed, horizon=8)


def _hull_vertex(model: mujoco.MjModel, g: int, local: int) -> np.ndarray:
    """Vertex ``local`` (the hull graph's own numbering, as the level keeps it) of geom g's
    hull, in the geom's frame."""
    mesh = int(model.geom_dataid[g])
    adr = int(model.mesh_graphadr[mesh])
    vert = int(model.mesh_vertadr[mesh]) + int(
        model.mesh_graph[adr + 2 + model.mesh_graph[adr] + local]
    )
    return np.asarray(model.mesh_vert[vert], dtype=np.float64)


def _least_on_segment(w1: np.ndarray, w2: np.ndarray) -> float:
    """min |l w1 + (1 - l) w2| over l in [0, 1], from the definition: a convex quadratic in l is
    least at an end or at its stationary point, if that lies between them."""
    dw = w1 - w2
    candidates = [float(np.linalg.norm(w1)), float(np.linalg.norm(w2))]
    if dw @ dw > 0:
        stationary = -(w2 @ dw) / (dw @ dw)
        if 0 < stationary < 1:
            candidates.append(float(np.linalg.norm(w2 + stationary * dw)))
    return min(candidates)


def _two_pairs_bound(
    p: Predictor, data: mujoco.MjData, witness: np.ndarray, horizon: float
) -> tuple[float, float, bool]:
    """Pair 0's bound on every direction's separation at ``horizon`` from its two pairs of points
    (the witness points ``witness``, (6,) in their geoms' frames, and the hull vertices its
    record names), what the pair can close over the horizon, and whether the second pair was
    read: the two sides of the test that no direction clears, slowly."""
    model, rec = p.model, p._rt.exact_records[0]
    g1, g2 = int(rec[X_G1]), int(rec[X_G2])

    def carried(g: int, local: np.ndarray) -> np.ndarray:
        return data.geom_xmat[g].reshape(3, 3) @ local + data.geom_xpos[g]

    def velocity(g: int) -> tuple[np.ndarray, np.ndarray]:
        v = np.empty(6)
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_GEOM, g, v, 0)
        return v[3:], v[:3]  # linear, angular (world)

    (va, wa), (vb, wb) = velocity(g1), velocity(g2)
    r = (vb - va) * horizon
    w1 = carried(g2, witness[3:]) - carried(g1, witness[:3]) + r
    most, second = float(np.linalg.norm(w1)), rec[X_HULL1] >= 0 and rec[X_HULL2] >= 0
    if second:
        a2 = carried(g1, _hull_vertex(model, g1, int(rec[X_HULL1])))
        b2 = carried(g2, _hull_vertex(model, g2, int(rec[X_HULL2])))
        most = _least_on_segment(w1, b2 - a2 + r)
    assert p.exact is not None
    radius = p.exact.geoms[[g1, g2], GX_RADIUS]
    spin = np.linalg.norm(wa) * radius[0] + np.linalg.norm(wb) * radius[1]
    pair = p.pair_records[0]
    least = rec[X_DIST] + (spin + pair[PAIR_DELTA]) * horizon + 0.5 * pair[PAIR_ACCEL] * horizon**2
    return most, float(least), bool(second)


def test_between_two_hulls_a_look_settles_only_where_the_two_pairs_of_points_allow() -> None:
    """The test that no direction clears (docs/theory.md, section 5, "Two pairs of points"),
    held to a slow reference at every step it settles a pair (leaves it in alarm, MuJoCo not
    asked and no direction kept): with the witness points of the latest query ``a``, ``b`` and the
    hull vertices the kept direction's supports reached ``a'``, ``b'``, all carried to the state,
    ``w1 = b - a + r H`` and ``w2 = b' - a' + r H`` (``r`` the origins' relative velocity, ``H``
    the horizon), the least length over the segment between them must be below what the pair
    can close over the horizon, ``m + (|w_A| r_A + |w_B| r_B + delta) H + A H^2 / 2``. A level
    that read the second pair without the motion over the horizon, or took the point of the
    line beyond the segment, settles pairs the reference does not: more alarms stand than the
    bound allows (never a miss), which a test of MuJoCo's direction at the state catches only
    by chance. Meshes near each other, moving and turning, over a horizon of eight periods; a
    fixed set of draws, so that the states that show it are met on every run."""
    settled = 0
    for seed in range(150):
        rng = np.random.default_rng(seed)
        model = _model("mesh", "mesh")
        motion = Motion(model, _near(rng, model, float(rng.uniform(0.0, 1.5))))
        p = _predictor(model, motion, horizon=8)
        assert p.exact is not None
        data = motion.state(0.0)
        p.reset(data)
        horizon = min(p.exact.query_below, p.alarm_horizon)
        for k in range(1, 21):
            rt = p._rt
            witness, queries = rt.exact_witness[0].copy(), rt.exact_queries
            kept = rt.exact_records[0, X_N : X_N + 3].copy()
            data = motion.state(k * p.dt)
            data.time = k * p.dt
            p.step(data)
            if not p.evaluations_per_step or data.ncon or np.isnan(witness[0]):
                continue  # not looked at, in MuJoCo's contacts (not looked at), or no query yet
            tau = float(p.pair_state().last_tau_of(np.arange(1))[0])
            if tau >= p.exact.query_below or rt.exact_queries != queries:
                continue  # cleared, or asked
            if not np.array_equal(rt.exact_records[0, X_N : X_N + 3], kept):
                continue  # the carried or the segment's direction kept
            most, least, second = _two_pairs_bound(p, data, witness, horizon)
            settled += second
            assert most < least * (1 + 1e-9), (seed, k, most, least)
    assert settled >= 20, settled  # states settled with both pairs of points (49 when written)


def _alarms_no_direction_clears(
    a: str, b: str, seed: int, speed: float, *, horizon: int = 1
) -> None:
    """Steps a predictor of geoms of types ``a`` and ``b`` near each other 20 times (an alarm
    horizon of ``horizon`` periods); at each step, no pair left in alarm is cleared by the
    reference (MuJoCo's witness direction)."""
    model = _model(a, b)
    motion = Motion(model, _near(np.random.default_rng(seed), model, speed))
    p = _predictor(model, motion, horizon=horizon)
    assert p.exact is not None
    data = motion.state(0.0)
    p.reset(data)
    horizon = p.exact.query_below
    for k in range(1, 21):
        data = motion.state(k * p.dt)
        data.time = k * p.dt
        p.step(data)
        if not p.evaluations_per_step:
            continue
        tau = p.pair_state().last_tau_of(np.arange(p.nsphere_pairs))
        for pair in np.flatnonzero(tau <= horizon):
            want = reference_exact_tau(p, data, int(pair))
            assert want <= horizon * (1 + 1e-6), (k, pair, float(tau[pair]), want, horizon)


def _reset_then_step(
    model: mujoco.MjModel, draw: dict
) -> tuple[Predictor, mujoco.MjData, np.ndarray]:
    """A predictor of ``draw``'s motion reset at t = 0 (one query: no direction yet) and stepped
    once (the pair evaluated), the state of that step, and the direction the reset kept (3,)."""
    motion = Motion(model, draw)
    p = _predictor(model, motion)
    assert p.exact is not None
    p.reset(motion.state(0.0))
    assert p._rt.exact_queries == 1
    kept = p._rt.exact_records[0, X_N : X_N + 3].copy()
    data = motion.state(p.dt)
    data.time = p.dt
    p.step(data)
    assert p.evaluations_per_step == 1
    return p, data, kept


def test_a_pair_no_direction_can_clear_keeps_its_direction() -> None:
    """Two parallel capsules 0.5 mm apart, spinning about their axes (which the level bounds by
    |w| r, 1 m/s together) while one slides past the other at 0.3 m/s: within the alarm horizon
    along every direction. The reset asks MuJoCo (no direction yet); at the next step the pair
    is in alarm along the direction it has and no direction could clear it: MuJoCo is not asked,
    and the pair stands in alarm, as MuJoCo's own direction at that state leaves it."""
    model = _model("capsule", "capsule")
    quat = np.array([1.0, 0.0, 0.0, 0.0])
    spin = np.array([0.0, 0.0, 2.0])
    draw = {
        2: {
            "p": np.array([0.0, 0.0, 1.0]),
            "v": np.zeros(3),
            "a": np.zeros(3),
            "q": quat,
            "w": spin,
        },
        1: {
            "p": np.array([0.0, 0.1005, 1.0]),
            "v": np.array([0.3, 0.0, 0.0]),
            "a": np.zeros(3),
            "q": quat,
            "w": spin,
        },
    }
    p, data, _ = _reset_then_step(model, draw)
    assert p._rt.exact_queries == 1  # not asked again
    assert p.pair_state().alarm_state()[0]
    assert reference_exact_tau(p, data, 0) <= p.exact.query_below


def test_the_carried_witness_direction_clears_without_a_query() -> None:
    """Two flat boxes 12 mm apart face to face, turning together as one rigid body about the
    vertical at 8 rad/s: the pair's geometry does not change, its faces turn 16 mrad a step.
    The reset asks MuJoCo; at the next step the kept direction (fixed in the world) sees the
    faces tilted, 4 mm nearer each along it, and would leave the pair in alarm; the direction
    between the witness points, carried with the boxes, is the faces' normal again and clears
    it, without a query, and it is the direction kept."""
    model = _model("box", "box")
    quat = np.array([1.0, 0.0, 0.0, 0.0])
    w = np.array([0.0, 0.0, 8.0])
    centre, offset = np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.212, 0.0])
    still = {"v": np.zeros(3), "a": np.zeros(3), "q": quat, "w": w}
    draw = {
        2: {**still, "p": centre},
        # B's origin on the circle about A's, to second order: velocity w x d, acceleration -w^2 d.
        1: {**still, "p": centre + offset, "v": np.cross(w, offset), "a": -(w @ w) * offset},
    }
    p, _, kept = _reset_then_step(model, draw)
    assert abs(kept[1]) > 0.999
    assert p._rt.exact_queries == 1  # not asked again
    assert not p.pair_state().alarm_state()[0]
    turned = p._rt.exact_records[0, X_N : X_N + 3]
    angle = float(np.arccos(min(1.0, abs(turned @ kept))))
    assert abs(angle - 8.0 * p.dt) < 1e-3  # the faces' turn, not the world's fixed direction


def test_a_pair_leaving_fast_is_asked_and_cleared() -> None:
    """Two flat boxes face to face, each turning in place about the vertical at 8 rad/s (the
    level bounds that by |w| r, 8.7 mm over the horizon of one step), B leaving at 2 m/s: 7 mm
    apart after one step. The kept direction (fixed in the world) sees the tilted faces overlap,
    and the witness points' distance now is within what the turning could close in the horizon;
    only B's leaving over the horizon (the r H of the test, 4 mm) leaves a direction that clears.
    MuJoCo is asked, and its direction (the faces' normal) clears the alarm, as the reference's
    does: a test that dropped the pair's motion over the horizon would not ask, and leave the
    pair in alarm."""
    model = _model("box", "box")
    quat = np.array([1.0, 0.0, 0.0, 0.0])
    w = np.array([0.0, 0.0, 8.0])
    still = {"v": np.zeros(3), "a": np.zeros(3), "q": quat, "w": w}
    leave = np.array([0.0, 2.0, 0.0])
    draw = {
        2: {**still, "p": np.array([0.0, 0.0, 1.0])},
        # Faces at y = +-0.1 of each centre: 3 mm apart at the reset, 7 mm after one step.
        1: {**still, "p": np.array([0.0, 0.203, 1.0]), "v": leave},
    }
    p, data, _ = _reset_then_step(model, draw)
    assert p._rt.exact_queries == 2  # asked
    assert not p.pair_state().alarm_state()[0]
    assert reference_exact_tau(p, data, 0) > p.exact.query_below


@pytest.mark.parametrize(("a", "b"), [(a, b) for a in GEOM_TYPES for b in GEOM_TYPES if a <= b])
def test_mujocos_witness_points_lie_in_their_geoms(a: str, b: str) -> None:
    """The knots' screen (docs/theory.md section 8) takes MuJoCo's witness points as points of
    the geoms: each one, probed by a 1e-9 m sphere, is within 1e-9 m of its geom."""
    model = mujoco.MjModel.from_xml_string(
        f"""<mujoco>{BLOB_ASSET}<worldbody>
          <body mocap="true"><geom {GEOM_TYPES[a]}/></body>
          <body mocap="true"><geom {GEOM_TYPES[b]}/></body>
          <body mocap="true" pos="9 9 9"><geom type="sphere" size="1e-9"/></body>
        </worldbody></mujoco>"""
    )
    data = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    probed = 0
    for _ in range(60):
        data.mocap_pos[:2] = [np.zeros(3), rng.normal(size=3) * 0.4]
        quats = rng.normal(size=(2, 4))
        data.mocap_quat[:2] = quats / np.linalg.norm(quats, axis=1, keepdims=True)
        data.mocap_pos[2] = 9.0
        mujoco.mj_kinematics(model, data)
        fromto = np.zeros(6)
        if not 0.0 < mujoco.mj_geomDistance(model, data, 0, 1, 1.0, fromto) < 1.0:
            continue
        for geom, point in ((0, fromto[:3].copy()), (1, fromto[3:].copy())):
            data.mocap_pos[2] = point
            mujoco.mj_kinematics(model, data)
            assert mujoco.mj_geomDistance(model, data, 2, geom, 1.0, None) <= 1e-12, (geom, point)
            probed += 1
    assert probed >= 40
