"""Tests of the static-shape urgency (dua_mujoco/core/shapes.py, docs/static-shapes.md).

Independent evidence, on purpose:

* Support functions against brute force: the maximum of ``n.q`` over dense surface samples (and,
  for meshes, over the hull vertices MuJoCo compiled) never exceeds ``h_S(n)``, and reaches it up
  to the sampling resolution.
* Gaps against MuJoCo: ``mj_geomDistance`` between a tiny sphere at ``c`` and the geom (MuJoCo's
  own collision code, not ours) bounds the gap from above, and equals it for the primitives.
* Feasible trajectories: piecewise-constant accelerations ``|a| <= A`` (closed form per piece)
  and a velocity error ``|w| <= delta``, with adversarial choices (towards the closest point),
  must not come within ``eps`` of the shape before tau. The same harness, fed a kernel whose box
  is halved, finds counterexamples: it can catch a non-conservative tau.
* The static sphere is the sphere-pair problem, so there tau is decided exactly (no tolerance)
  by ``reference_tau``'s rational first root.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
import reference_tau as ref
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scalar_tau import static_gap, support, tau_static

from dua_mujoco.core.shapes import (
    SHAPE_KIND,
    SHAPE_MAT,
    SHAPE_NCOL,
    SHAPE_POS,
    SHAPE_SIZE,
    ShapeKind,
    closest_point,
    mesh_box,
    pack_shapes,
    time_to_static,
)
from dua_mujoco.core.urgency import time_to_collision
from dua_mujoco.exceptions import (
    InvalidBoundError,
    InvalidInputError,
    NonFiniteStateError,
    ShapeError,
)

PRIMITIVES = [
    ShapeKind.SPHERE,
    ShapeKind.CAPSULE,
    ShapeKind.ELLIPSOID,
    ShapeKind.CYLINDER,
    ShapeKind.BOX,
]
ALL_KINDS = [*PRIMITIVES, ShapeKind.MESH_BOX]
each_primitive = pytest.mark.parametrize("kind", PRIMITIVES, ids=lambda k: k.name)
each_kind = pytest.mark.parametrize("kind", ALL_KINDS, ids=lambda k: k.name)
# Kinds whose chosen direction makes the gap the exact distance (closed-form closest points).
EXACT_KINDS = {ShapeKind.SPHERE, ShapeKind.CAPSULE, ShapeKind.CYLINDER, ShapeKind.BOX}
_MJ_TYPE = {
    ShapeKind.SPHERE: "sphere",
    ShapeKind.CAPSULE: "capsule",
    ShapeKind.ELLIPSOID: "ellipsoid",
    ShapeKind.CYLINDER: "cylinder",
    ShapeKind.BOX: "box",
    ShapeKind.MESH_BOX: "mesh",
}
# Radius of the probe sphere standing in for the point c in mj_geomDistance (added back).
PROBE = 1e-4

SHAPES = settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
    print_blob=True,
)


# --------------------------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------------------------


def rotation(q) -> np.ndarray:
    """3x3 rotation of a (not necessarily unit) quaternion (w, x, y, z)."""
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def random_size(kind: ShapeKind, rng: np.random.Generator, scale: float = 1.0) -> np.ndarray:
    s = rng.uniform(0.05, 1.0, 3) * scale
    if kind == ShapeKind.SPHERE:
        s[1:] = 0.0
    elif kind in (ShapeKind.CAPSULE, ShapeKind.CYLINDER):
        s[2] = 0.0
    return s


def record(kind, size, pos, rot) -> np.ndarray:
    return pack_shapes([int(kind)], [size], [pos], [np.asarray(rot).ravel()])[0]


def random_shape(
    kind: ShapeKind, rng: np.random.Generator, spread: float = 1.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(size, pos, rot, record)``: a random shape of ``kind`` centred in ``[-spread, spread]^3``.

    Draws the size, then the rotation, then the centre.
    """
    size = random_size(kind, rng)
    rot = rotation(rng.normal(size=4))
    pos = rng.uniform(-spread, spread, 3)
    return size, pos, rot, record(kind, size, pos, rot)


def surface_samples(kind: ShapeKind, size, rng: np.random.Generator, n: int) -> np.ndarray:
    """Points on the surface of the shape in its own frame (dense, extreme points included)."""
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    th = rng.uniform(0, 2 * np.pi, n)
    ring = np.stack([np.cos(th), np.sin(th), np.zeros(n)], axis=1)
    a, b, c = size
    if kind == ShapeKind.SPHERE:
        return a * u
    if kind == ShapeKind.ELLIPSOID:
        return u * np.array([a, b, c])
    if kind == ShapeKind.CAPSULE:
        caps = a * u + np.sign(u[:, 2:3]) * np.array([0.0, 0.0, b])
        side = a * ring + np.outer(rng.uniform(-b, b, n), [0, 0, 1.0])
        return np.concatenate([caps, side])
    if kind == ShapeKind.CYLINDER:
        rims = [a * ring + np.array([0, 0, s * b]) for s in (-1.0, 1.0)]
        side = a * ring + np.outer(rng.uniform(-b, b, n), [0, 0, 1.0])
        disc = a * np.sqrt(rng.uniform(0, 1, n))[:, None] * ring + np.array([0, 0, b])
        return np.concatenate([*rims, side, disc])
    # box: the 8 corners and random face points
    corners = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    face = rng.uniform(-1, 1, (n, 3))
    axis = rng.integers(0, 3, n)
    face[np.arange(n), axis] = rng.choice([-1.0, 1.0], n)
    return np.concatenate([corners, face]) * np.asarray(size)


def shape_model(kind: ShapeKind, rng: np.random.Generator):
    """A MuJoCo model with the static geom 0 at a random pose and a mocap probe sphere geom 1.

    Returns (model, data, record) with the record built from MuJoCo's compiled geom exactly as
    an adapter would: geom_size (geom_aabb for meshes), geom_xpos, geom_xmat.
    """
    size = random_size(kind, rng)
    pos = rng.uniform(-1, 1, 3)
    euler = rng.uniform(-180, 180, 3)
    used = {ShapeKind.SPHERE: 1, ShapeKind.CAPSULE: 2, ShapeKind.CYLINDER: 2}.get(kind, 3)
    asset = ""
    if kind == ShapeKind.MESH_BOX:
        verts = " ".join(f"{x:.6f}" for x in (rng.normal(size=(12, 3)) * size).ravel())
        asset = f'<asset><mesh name="hull" vertex="{verts}"/></asset>'
        geom = 'type="mesh" mesh="hull"'
    else:
        geom = f'type="{_MJ_TYPE[kind]}" size="{" ".join(f"{s:.6f}" for s in size[:used])}"'
    xml = f"""
    <mujoco>
      {asset}
      <worldbody>
        <geom name="shape" {geom} pos="{pos[0]} {pos[1]} {pos[2]}"
              euler="{euler[0]} {euler[1]} {euler[2]}"/>
        <body name="probe" mocap="true"><geom type="sphere" size="{PROBE}"/></body>
      </worldbody>
    </mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    k = int(m.geom_type[0])
    assert k == int(kind), (k, kind)
    if kind == ShapeKind.MESH_BOX:
        sz, centre = mesh_box(m.geom_aabb[:1], d.geom_xpos[:1], d.geom_xmat[:1])
    else:
        sz, centre = m.geom_size[:1], d.geom_xpos[:1]
    return m, d, pack_shapes([k], sz, centre, d.geom_xmat[:1])[0]


def shape_models(kind: ShapeKind, rng: np.random.Generator, count: int):
    """``count`` random :func:`shape_model` s of ``kind``, each with its record's centre.

    Yields:
        ``(model, data, record, pos)``.
    """
    for _ in range(count):
        m, d, rec = shape_model(kind, rng)
        yield m, d, rec, rec[SHAPE_POS : SHAPE_POS + 3]


def mj_distance(m, d, c) -> float:
    """Distance from the point c to geom 0 (negative inside), by MuJoCo's collision code."""
    d.mocap_pos[0] = c
    mujoco.mj_kinematics(m, d)
    return float(mujoco.mj_geomDistance(m, d, 0, 1, 50.0, None)) + PROBE


def own_distance(rec):
    def dist(c):
        return float(np.linalg.norm(c - np.array(closest_point(c, rec))))

    return dist


def tau_one(c, v, rec, eps, accel, delta=0.0) -> float:
    out = time_to_static(
        np.asarray(c, float)[None],
        np.asarray(v, float)[None],
        rec[None],
        np.zeros(1, dtype=np.int64),
        eps,
        accel,
        vel_uncertainty=delta,
    )
    assert out.shape == (1,) and out.dtype == np.float64
    return float(out[0])


def _unit(x) -> np.ndarray:
    nx = np.linalg.norm(x)
    return np.asarray(x, float) / nx if nx > 0 else np.array([0.0, 0.0, 1.0])


def feasible_samples(c, v, A, delta, rec, t_end, prog, nsamp=64):
    """Sampled positions of one feasible trajectory on [0, t_end].

    Program: (pieces, w). Each piece is (fraction of t_end, direction, magnitude fraction, mode);
    "toward" accelerates with |a| = A at the closest point of the shape seen from the predicted
    mid-piece position (the adversarial choice), "bang" with |a| = A along the drawn direction,
    "free" with a drawn fraction of A. w = (direction, magnitude fraction, mode) is the initial
    velocity error, |w| <= delta ("toward" aims it at the closest point). Each piece is the
    closed form x + u s + a s^2 / 2.

    Returns:
        (times, points): (k,) and (k, 3), including every piece's end points.
    """
    pieces, (wd, wmag, wmode) = prog
    p = np.asarray(c, float).copy()
    wdir = _unit(np.array(closest_point(p, rec)) - p) if wmode == "toward" else _unit(wd)
    u = np.asarray(v, float) + delta * wmag * wdir
    total = sum(f for f, *_ in pieces)
    times, points, t = [], [], 0.0
    for frac, dirn, mag, mode in pieces:
        dur = t_end * frac / total
        if mode == "toward":
            mid = p + u * dur / 2
            a = A * _unit(np.array(closest_point(mid, rec)) - mid)
        else:
            a = A * (1.0 if mode == "bang" else mag) * _unit(dirn)
        s = np.linspace(0.0, dur, nsamp)
        times.append(t + s)
        points.append(p + np.outer(s, u) + 0.5 * np.outer(s * s, a))
        p = p + u * dur + 0.5 * a * dur * dur
        u = u + a * dur
        t += dur
    return np.concatenate(times), np.concatenate(points)


def earliest_violation(times, points, dist, eps, tol):
    """(time, clearance) of the first sample that comes within eps - tol of the shape, or None."""
    for t, q in zip(times, points, strict=True):
        clearance = dist(q) - eps
        if clearance < -tol:
            return float(t), clearance
    return None


def horizon(tau: float) -> float:
    # A finite tau is the window to check, up to 1000 s: beyond, the sampled positions of an
    # accelerating trajectory overflow to inf and NaN, whose clearance compares false and would
    # test nothing. Past an infinite tau, a few seconds of motion.
    return min(tau, 1e3) if math.isfinite(tau) else 5.0


# --------------------------------------------------------------------------------------------
# (a) support functions against brute force
# --------------------------------------------------------------------------------------------


@each_primitive
def test_support_against_surface_samples(kind):
    rng = np.random.default_rng(int(kind))
    for _ in range(10):
        size, pos, rot, rec = random_shape(kind, rng, spread=2.0)
        pts = pos + surface_samples(kind, size, rng, 40000) @ rot.T
        dirs = rng.normal(size=(60, 3))
        dirs /= np.linalg.norm(dirs, axis=1)[:, None]
        brute = (pts @ dirs.T).max(axis=0)
        h = np.array([support(n, rec) for n in dirs])
        scale = np.abs(pos).sum() + size.sum()
        # Never below a surface point: the half-space holds the whole shape.
        assert (brute <= h + 1e-12 * scale).all(), (kind, size, (brute - h).max())
        # And it is the support, not a loose bound: samples come within the sampling resolution.
        assert (brute >= h - 5e-3 * size.max()).all(), (kind, size, (h - brute).max())
        # Positive homogeneity: the kernels rely on it for directions that are not exactly unit.
        assert support(3.0 * dirs[0], rec) == pytest.approx(3.0 * h[0], rel=1e-14, abs=1e-14)


def test_support_of_mesh_box_holds_the_compiled_hull():
    """Every vertex MuJoCo compiled for the mesh lies in the box record's half-spaces.

    Also pins the geom_aabb convention (centre offset, half-sizes, geom frame): along the box's
    own axes the support is attained by a hull vertex.
    """
    rng = np.random.default_rng(11)
    for _ in range(8):
        m, d, rec = shape_model(ShapeKind.MESH_BOX, rng)
        R = d.geom_xmat[0].reshape(3, 3)
        verts = d.geom_xpos[0] + m.mesh_vert.astype(np.float64) @ R.T
        dirs = rng.normal(size=(200, 3))
        dirs = np.concatenate([dirs / np.linalg.norm(dirs, axis=1)[:, None], R.T, -R.T])
        brute = (verts @ dirs.T).max(axis=0)
        h = np.array([support(n, rec) for n in dirs])
        assert (brute <= h + 1e-6).all(), (brute - h).max()  # float32 vertices
        np.testing.assert_allclose(brute[-6:], h[-6:], atol=1e-6)


@each_kind
def test_chosen_direction_maximises_the_gap(kind):
    """n.c - h_S(n) over many unit n never beats the kernel's chosen n (outside the shape)."""
    rng = np.random.default_rng(100 + int(kind))
    dirs = rng.normal(size=(4000, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    for _ in range(20):
        _, pos, _, rec = random_shape(kind, rng)
        c = pos + rng.normal(size=3) * 1.5
        gap, *n = static_gap(c, rec)
        assert np.linalg.norm(n) == pytest.approx(1.0, abs=1e-15)
        assert gap == pytest.approx(float(np.dot(n, c)) - support(np.array(n), rec), abs=1e-14)
        others = dirs @ c - np.array([support(k, rec) for k in dirs])
        assert others.max() <= gap + 1e-9, (kind, c, gap, others.max())


# --------------------------------------------------------------------------------------------
# (b) gaps and closest points against MuJoCo's mj_geomDistance
# --------------------------------------------------------------------------------------------


@each_kind
def test_gap_against_mj_geom_distance(kind):
    rng = np.random.default_rng(200 + int(kind))
    n_out = 0
    for m, d, rec, pos in shape_models(kind, rng, 4):
        for _ in range(150):
            c = pos + rng.normal(size=3) * rng.uniform(0.05, 1.5)
            true = mj_distance(m, d, c)
            gap = static_gap(c, rec)[0]
            # The lower bound the proof needs; 1e-9 is MuJoCo's own convergence tolerance.
            assert gap <= true + 1e-9, (kind, c.tolist(), gap, true)
            if true <= 1e-9:
                assert gap <= 1e-12, (kind, c.tolist(), gap, true)  # inside: tau will be 0
                continue
            n_out += 1
            own = own_distance(rec)(c)
            if kind in EXACT_KINDS:
                assert gap == pytest.approx(true, abs=1e-9), (kind, c.tolist(), gap, true)
                assert own == pytest.approx(true, abs=1e-9), (kind, c.tolist(), own, true)
            elif kind == ShapeKind.ELLIPSOID:
                # MuJoCo's GJK stops at ~1e-10; the iterated root is exact to rounding.
                assert gap == pytest.approx(true, abs=1e-8), (c.tolist(), gap, true)
                assert own == pytest.approx(true, abs=1e-8), (c.tolist(), own, true)
            else:  # the mesh box: a distance to a box that holds the hull
                assert own <= true + 1e-6
    assert n_out > 300


# --------------------------------------------------------------------------------------------
# Known values and the inside case
# --------------------------------------------------------------------------------------------


def test_known_values():
    box = record(ShapeKind.BOX, [0.5, 0.5, 0.5], [0.0, 0.0, 0.0], np.eye(3))
    # Falling straight onto the top face at 1 m/s: clearance 0.4.
    assert tau_one([0, 0, 1.0], [0, 0, -1.0], box, 0.1, 0.0) == pytest.approx(0.4, rel=1e-12)
    # At rest, A = 2: 0.4 = t^2.
    assert tau_one([0, 0, 1.0], [0, 0, 0], box, 0.1, 2.0) == pytest.approx(math.sqrt(0.4), 1e-12)
    # Along the diagonal at unit speed: the corner (0.5, 0.5, 0.5) is |c - corner| = sqrt 3 away.
    c = np.array([1.5, 1.5, 1.5])
    tau = tau_one(c, -c / np.linalg.norm(c), box, 0.0, 0.0)
    assert tau == pytest.approx(math.sqrt(3.0), rel=1e-12)
    # Moving away with A = 0: never.
    assert tau_one([0, 0, 1.0], [0, 0, 1.0], box, 0.1, 0.0) == math.inf
    # A capsule along a rotated axis: the cap is the closest feature.
    rot = rotation([math.cos(math.pi / 4), math.sin(math.pi / 4), 0, 0])  # z -> -y
    cap = record(ShapeKind.CAPSULE, [0.1, 0.3, 0.0], [0.0, 0.0, 0.0], rot)
    assert tau_one([0, -1.0, 0], [0, 2.0, 0], cap, 0.0, 0.0) == pytest.approx(0.3, rel=1e-12)


@each_kind
def test_inside_or_touching_is_zero(kind):
    rng = np.random.default_rng(300 + int(kind))
    for _ in range(40):
        size, pos, rot, rec = random_shape(kind, rng)
        surf = pos + surface_samples(kind, size, rng, 20) @ rot.T
        inner = pos + rng.uniform(0, 1) * (surf - pos)  # convex: the segment to the centre
        v = rng.normal(size=3) * 10
        for p in [*inner[:5], pos]:
            assert tau_one(p, v, rec, 0.0, 1.0) == 0.0, (kind, p.tolist())
        # On the surface with eps = 0, and within eps: still 0 (never a positive gap by rounding).
        # The capsule and cylinder samples include their rims and sides.
        for p in surf[:5]:
            assert tau_one(p, v, rec, 0.0, 0.0) == 0.0, (kind, p.tolist())
            q = p + 0.01 * _unit(p - pos)
            assert tau_one(q, v, rec, 0.02, 0.0) == 0.0, (kind, q.tolist())


def test_static_sphere_decided_exactly():
    """A static sphere is the sphere-pair problem (eps + r): tau never exceeds the exact root."""
    rng = np.random.default_rng(400)
    problems = []
    for _ in range(150):
        r = rng.uniform(0.05, 1.0)
        p = rng.uniform(-1, 1, 3)
        rec = record(ShapeKind.SPHERE, [r, 0.0, 0.0], p, rotation(rng.normal(size=4)))
        c = p + _unit(rng.normal(size=3)) * rng.uniform(r, 3.0)
        v = rng.normal(size=3) * rng.choice([0.0, 1.0])
        eps, A = rng.uniform(0, 0.3), rng.choice([0.0, rng.uniform(0, 3)])
        delta = rng.choice([0.0, rng.uniform(0, 0.5)])
        tau = tau_one(c, v, rec, eps, A, delta)
        exact = ref.tau_sphere_ref(c - p, v, eps + r, A, delta)
        if not exact.is_lower_bound(tau):
            problems.append((c.tolist(), v.tolist(), r, eps, A, delta, tau, exact.value))
        # Radial motion: the half-space is as tight as the ball.
        radial = -_unit(c - p) * 0.7
        t_half = tau_one(c, radial, rec, eps, A, delta)
        t_ball = float(time_to_collision(c - p, radial, eps + r, A, vel_uncertainty=delta)[0])
        assert t_half == pytest.approx(t_ball, rel=1e-9), (c, r, eps, A, delta)
    assert not problems, problems[:5]


# --------------------------------------------------------------------------------------------
# (c) feasible trajectories
# --------------------------------------------------------------------------------------------


@st.composite
def shape_state(draw, kinds=PRIMITIVES):
    kind = draw(st.sampled_from(kinds))
    scale = 10.0 ** draw(st.floats(-1.5, 1.5))
    tscale = 10.0 ** draw(st.floats(-1, 1))
    size = np.array([draw(st.floats(0.05, 1.0)) for _ in range(3)]) * scale
    if kind == ShapeKind.SPHERE:
        size[1:] = 0.0
    elif kind in (ShapeKind.CAPSULE, ShapeKind.CYLINDER):
        size[2] = 0.0
    q = [draw(st.floats(-1, 1)) for _ in range(4)]
    if np.linalg.norm(q) < 1e-3:
        q = [1.0, 0.0, 0.0, 0.0]
    pos = np.array([draw(st.floats(-1, 1)) for _ in range(3)]) * scale
    rec = record(kind, size, pos, rotation(q))
    off = _unit([draw(st.floats(-1, 1)) for _ in range(3)])
    c = pos + off * (size.max() + size.max() * draw(st.floats(0.0, 2.0)))
    v = np.array([draw(st.floats(-2, 2)) for _ in range(3)]) * scale / tscale
    eps = draw(st.floats(0, 0.3)) * scale
    A = draw(st.sampled_from([0.0, 1.0])) * draw(st.floats(1e-3, 5)) * scale / tscale**2
    delta = draw(st.sampled_from([0.0, 1.0])) * draw(st.floats(0, 0.5)) * scale / tscale
    return rec, c, v, eps, A, delta, scale


@st.composite
def accel_program(draw):
    pieces = []
    for _ in range(draw(st.integers(1, 4))):
        frac = draw(st.floats(0.05, 1.0))
        dirn = [draw(st.floats(-1, 1)) for _ in range(3)]
        mag = draw(st.floats(0, 1))
        mode = draw(st.sampled_from(["toward", "toward", "bang", "free"]))
        pieces.append((frac, dirn, mag, mode))
    w = [draw(st.floats(-1, 1)) for _ in range(3)]
    return pieces, (
        w,
        draw(st.sampled_from([1.0, 1.0, 0.5])),
        draw(st.sampled_from(["toward", "free"])),
    )


@SHAPES
@given(shape_state(), accel_program())
def test_property_feasible_trajectories(state, prog):
    rec, c, v, eps, A, delta, scale = state
    tau = tau_one(c, v, rec, eps, A, delta)
    # The scalar kernel and the vectorised front are one computation.
    assert tau == tau_static(c[0], c[1], c[2], v[0], v[1], v[2], rec, eps, A, delta)
    if tau == 0.0:
        assert own_distance(rec)(c) <= eps * (1 + 1e-12) + 1e-12 * scale
        return
    times, points = feasible_samples(c, v, A, delta, rec, horizon(tau), prog)
    hit = earliest_violation(times, points, own_distance(rec), eps, 1e-9 * scale)
    assert hit is None, (
        f"a feasible trajectory reaches the shape before tau = {tau!r}: (t, clearance) = {hit}; "
        f"rec={rec.tolist()}, c={c.tolist()}, v={v.tolist()}, eps={eps!r}, A={A!r}, "
        f"delta={delta!r}"
    )


def _adversarial_programs(rng: np.random.Generator, k: int):
    for _ in range(k):
        pieces = [
            (rng.uniform(0.1, 1), rng.normal(size=3), rng.uniform(), str(mode))
            for mode in rng.choice(["toward", "toward", "bang"], rng.integers(1, 4))
        ]
        yield pieces, (rng.normal(size=3), 1.0, "toward")


@each_kind
def test_feasible_trajectories_against_mj_geom_distance(kind):
    """The trajectory check with MuJoCo measuring the distance (for meshes, to the real hull)."""
    rng = np.random.default_rng(500 + int(kind))
    checked = 0
    for m, d, rec, pos in shape_models(kind, rng, 3):
        reach = float(rec[SHAPE_SIZE : SHAPE_SIZE + 3].max())
        for prog in _adversarial_programs(rng, 4):
            c = pos + _unit(rng.normal(size=3)) * reach * rng.uniform(1.2, 3.0)
            v = -_unit(c - pos) * rng.uniform(0, 1) + rng.normal(size=3) * 0.3
            eps, A, delta = rng.uniform(0, 0.2), rng.uniform(0, 3), rng.uniform(0, 0.3)
            tau = tau_one(c, v, rec, eps, A, delta)
            if tau == 0.0:
                assert mj_distance(m, d, c) <= eps + 1e-9 or kind == ShapeKind.MESH_BOX
                continue
            times, points = feasible_samples(c, v, A, delta, rec, horizon(tau), prog, nsamp=48)
            hit = earliest_violation(
                times, points, lambda q, m=m, d=d: mj_distance(m, d, q), eps, 1e-9
            )
            assert hit is None, (kind, c.tolist(), v.tolist(), eps, A, delta, tau, hit)
            checked += 1
    assert checked >= 6


# --------------------------------------------------------------------------------------------
# (f) the harness catches a non-conservative kernel
# --------------------------------------------------------------------------------------------


def test_harness_catches_halved_box():
    """tau from a support function with the box half-sizes halved is late, and the harness says so.

    The same states and programs pass with the correct record, so the failures are the mutant's.
    """
    rng = np.random.default_rng(600)
    caught = passed = 0
    for _ in range(40):
        size, pos, rot, rec = random_shape(ShapeKind.BOX, rng)
        mutant = rec.copy()
        mutant[SHAPE_SIZE : SHAPE_SIZE + 3] *= 0.5
        c = pos + rot @ (_unit(rng.normal(size=3)) * size.max() * 2.5)
        v = -_unit(c - pos) * rng.uniform(0, 0.5)
        eps, A, delta = rng.uniform(0, 0.1), rng.uniform(0.5, 3), rng.uniform(0, 0.2)
        prog = ([(1.0, [0.0, 0.0, 1.0], 1.0, "toward")], ([0.0, 0.0, 1.0], 1.0, "toward"))
        dist = own_distance(rec)
        for r, is_mutant in ((rec, False), (mutant, True)):
            tau = tau_one(c, v, r, eps, A, delta)
            times, points = feasible_samples(c, v, A, delta, rec, horizon(tau), prog)
            hit = earliest_violation(times, points, dist, eps, 1e-9)
            if is_mutant:
                caught += hit is not None
            else:
                assert hit is None, (c.tolist(), v.tolist(), tau, hit)
                passed += 1
    assert passed == 40
    assert caught >= 30, caught


# --------------------------------------------------------------------------------------------
# (d) tightness: a table top held as a box versus its bounding sphere
# --------------------------------------------------------------------------------------------

TABLE_HALF = np.array([0.9, 0.45, 0.02])  # a 1.8 m x 0.9 m top, 4 cm thick
TABLE_POS = np.array([0.0, 0.0, 0.73])  # top face at 0.75 m


def test_table_top_box_is_tighter_than_bounding_sphere():
    table = record(ShapeKind.BOX, TABLE_HALF, TABLE_POS, np.eye(3))
    ball_radius = float(np.linalg.norm(TABLE_HALF))  # the smallest ball around the top: 1.007 m
    eps, A = 0.05, 2.0  # a 5 cm sphere, 2 m/s^2
    xs = np.linspace(-0.9, 0.9, 7)
    ys = np.linspace(-0.45, 0.45, 5)
    grid = np.array([[x, y, 0.75 + 0.3] for x in xs for y in ys])
    vel = np.tile([1.0, 0.5, 0.0], (len(grid), 1))  # parallel to the top
    tau_box = time_to_static(grid, vel, table[None], np.zeros(len(grid), int), eps, A)
    tau_ball = time_to_collision(grid - TABLE_POS, vel, ball_radius + eps, A)
    # 0.3 m above the top, moving parallel: 0.25 m of clearance closed by A t^2 / 2 at worst.
    np.testing.assert_allclose(tau_box, math.sqrt(2 * 0.25 / A), rtol=1e-12)
    # Every one of these centres is inside the bounding ball: it is urgent all the time.
    assert (tau_ball == 0.0).all()
    # Higher up: the ball stays at 0 until ~1.04 m above the top (its radius plus eps), and where
    # it finally gives a positive tau the box still gives twice as much.
    heights = np.array([0.5, 1.0, 1.2])
    high = np.stack([np.zeros(3), np.zeros(3), 0.75 + heights], axis=1)
    vh = np.tile([1.0, 0.0, 0.0], (3, 1))
    t_box = time_to_static(high, vh, table[None], np.zeros(3, int), eps, A)
    t_ball = time_to_collision(high - TABLE_POS, vh, ball_radius + eps, A)
    np.testing.assert_allclose(t_box, np.sqrt(2 * (heights - eps) / A), rtol=1e-12)
    np.testing.assert_array_equal(t_ball[:2], 0.0)
    assert t_box[2] / t_ball[2] > 2.0, (t_box, t_ball)


# --------------------------------------------------------------------------------------------
# (e) validation
# --------------------------------------------------------------------------------------------

I9 = np.eye(3).ravel()


def _good():
    recs = pack_shapes([6, 2], [[1, 1, 1], [0.5, 0, 0]], np.zeros((2, 3)), [I9, I9])
    c = np.array([[0.0, 0.0, 3.0], [0.0, 3.0, 0.0], [3.0, 0.0, 0.0]])
    return recs, c, np.zeros((3, 3)), np.array([0, 1, 0])


def test_pack_shapes_layout():
    rot = rotation([0.3, 0.1, -0.2, 0.9])
    recs = pack_shapes(
        np.array([ShapeKind.CYLINDER]), [[0.2, 0.3, 0.0]], [[1.0, 2.0, 3.0]], rot[None]
    )
    assert recs.shape == (1, SHAPE_NCOL) and recs.dtype == np.float64
    assert recs[0, SHAPE_KIND] == 5.0
    np.testing.assert_array_equal(recs[0, SHAPE_SIZE : SHAPE_SIZE + 3], [0.2, 0.3, 0.0])
    np.testing.assert_array_equal(recs[0, SHAPE_POS : SHAPE_POS + 3], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(recs[0, SHAPE_MAT:], rot.ravel())
    # The kind codes are MuJoCo's mjtGeom (checked here, where MuJoCo may be imported).
    for kind, name in _MJ_TYPE.items():
        assert int(kind) == int(getattr(mujoco.mjtGeom, f"mjGEOM_{name.upper()}"))


@pytest.mark.parametrize(
    ("args", "exc", "match"),
    [
        (([0], [[1, 1, 1]], [[0, 0, 0]], [I9]), InvalidInputError, r"kind\[0\] = 0.*time_to_half"),
        (([8], [[1, 1, 1]], [[0, 0, 0]], [I9]), InvalidInputError, r"kind\[0\] = 8"),
        (([6.0], [[1, 1, 1]], [[0, 0, 0]], [I9]), InvalidInputError, r"dtype float64"),
        (([6], [[1, 1]], [[0, 0, 0]], [I9]), ShapeError, r"size has shape"),
        (([6, 6], [[1, 1, 1]] * 2, [[0, 0, 0]], [I9] * 2), ShapeError, r"pos has shape"),
        (([6], [[1, -0.5, 1]], [[0, 0, 0]], [I9]), InvalidInputError, r"size\[0\].*-0\.5.*BOX"),
        (([4], [[1, 0, 1]], [[0, 0, 0]], [I9]), InvalidInputError, r"ELLIPSOID.*positive"),
        (([2], [[1, 0, 0]], [[0, np.nan, 0]], [I9]), InvalidInputError, r"pos\[0\].*not finite"),
        (([2], [[1, 0, 0]], [[0, 0, 0]], [2 * I9]), InvalidInputError, r"mat\[0\].*not a rot"),
        (([2], [[1, 0, 0]], [[0, 0, 0]], [-I9]), InvalidInputError, r"det = -1"),
    ],
)
def test_pack_shapes_rejects(args, exc, match):
    with pytest.raises(exc, match=match):
        pack_shapes(*args)


def test_time_to_static_rejects():
    recs, c, v, ids = _good()
    out = time_to_static(c, v, recs, ids, 0.1, 1.0)
    assert out.shape == (3,) and (out > 0).all()
    bad = c.copy()
    bad[1, 2] = np.nan
    with pytest.raises(NonFiniteStateError, match=r"centers\[1\]"):
        time_to_static(bad, v, recs, ids, 0.1, 1.0)
    with pytest.raises(NonFiniteStateError, match=r"velocities\[1\]"):
        time_to_static(c, np.where(bad == bad, 0.0, np.inf), recs, ids, 0.1, 1.0)
    with pytest.raises(ShapeError, match=r"velocities has shape \(2, 3\)"):
        time_to_static(c, v[:2], recs, ids, 0.1, 1.0)
    with pytest.raises(ShapeError, match=r"shapes has shape \(2, 15\)"):
        time_to_static(c, v, recs[:, :15], ids, 0.1, 1.0)
    with pytest.raises(ShapeError, match=r"shape_ids has shape \(2,\)"):
        time_to_static(c, v, recs, ids[:2], 0.1, 1.0)
    with pytest.raises(InvalidInputError, match=r"shape_ids\[2\] = 2 is out of range"):
        time_to_static(c, v, recs, np.array([0, 1, 2]), 0.1, 1.0)
    with pytest.raises(InvalidInputError, match=r"shape_ids\[0\] = -1"):
        time_to_static(c, v, recs, np.array([-1, 1, 0]), 0.1, 1.0)
    with pytest.raises(InvalidInputError, match=r"dtype float64"):
        time_to_static(c, v, recs, ids.astype(float), 0.1, 1.0)
    with pytest.raises(InvalidBoundError, match=r"accel\[1\] = -2"):
        time_to_static(c, v, recs, ids, 0.1, np.array([1.0, -2.0, 1.0]))
    with pytest.raises(InvalidBoundError, match=r"eps\[0\] = nan"):
        time_to_static(c, v, recs, ids, np.nan, 1.0)
    with pytest.raises(InvalidBoundError, match=r"vel_uncertainty\[0\] = inf"):
        time_to_static(c, v, recs, ids, 0.1, 1.0, vel_uncertainty=np.inf)
    with pytest.raises(ShapeError, match=r"accel has shape \(2,\)"):
        time_to_static(c, v, recs, ids, 0.1, np.ones(2))
    broken = recs.copy()
    broken[1, SHAPE_KIND] = 9.0
    with pytest.raises(InvalidInputError, match=r"SHAPE_KIND\]\[1\] = 9 is not"):
        time_to_static(c, v, broken, ids, 0.1, 1.0)
    broken[1, SHAPE_KIND] = 1.0  # a height field's record, without its grid
    with pytest.raises(InvalidInputError, match=r"shapes\[1\] is a terrain record"):
        time_to_static(c, v, broken, ids, 0.1, 1.0)
    broken = recs.copy()
    broken[1, SHAPE_SIZE] = 0.0  # a sphere of radius 0 divides by zero in the closest point
    with pytest.raises(InvalidInputError, match=r"SPHERE.*positive"):
        time_to_static(c, v, broken, ids, 0.1, 1.0)
    assert issubclass(NonFiniteStateError, InvalidInputError)
