"""The plans' roundings held to exact rational arithmetic (docs/theory.md, section 8).

Each term the plans' verdicts rest on is an upper bound computed in floating point: its factor
past the rounding is what makes it one. A rounding-sized shortfall hides from every verdict of a
rollout (the gaps' own allowances are larger), so these tests call the terms themselves through
test-only bindings and compare them with their exact values, on the inputs where the rounding
decides: the deviation check's first screen (``BoxWithin``, Lemma 8.1) on a body that moves
without turning, and a free body's reach (the mixed tau's ``Reach``, Lemma 8.3). Without its
factor, about half of the draws where the rounding decides fail. (The stray of Lemma 8.3 is held
the same way in ``test_plan_partial.py::test_the_stray_is_rounded_up``.)
"""

from __future__ import annotations

import itertools
import math
from fractions import Fraction as Q

import mujoco
import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from dua_mujoco import _core
from dua_mujoco._core import LAYOUT

CENTER, HALF, NCOL = LAYOUT["B_CENTER"], LAYOUT["B_HALF"], LAYOUT["B_SPEED"] + 1
SPHERE_OFFSET, SPHERE_NCOL = LAYOUT["SPHERE_OFFSET"], LAYOUT["SPHERE_NCOL"]
SIGNS = (-1.0, 1.0)


def _zero_or(top: float) -> st.SearchStrategy[float]:
    """0, or a value from 1e-6 to ``top`` (far from the products' underflow, which no relative
    allowance covers)."""
    return st.one_of(st.just(0.0), st.floats(1e-6, top))


def _offset() -> st.SearchStrategy[float]:
    """A coordinate's difference between two poses: 0, or 1e-9 to 1 m either way (the squared
    differences far from underflow: below about 1e-162 m, Lemma 8.1 says, the first screen's
    bound rounds to 0, a deviation below any declared one but 0)."""
    size = st.floats(1e-9, 1.0)
    return st.one_of(st.just(0.0), size, size.map(lambda x: -x))


def _rotation(quat: list[float]) -> np.ndarray:
    """The rotation matrix of a quaternion (normalised), as MuJoCo makes it: (9,)."""
    q = np.asarray(quat, dtype=np.float64)
    out = np.zeros(9)
    mujoco.mju_quat2Mat(out, q / np.linalg.norm(q))
    return out


# A quaternion's components (and a box's centre, halved) drawn as the offsets are, 0 or from 1e-9
# either way: a component of 1e-223 turned by no angle comes back from the round trip through the
# matrix with entries 1e-238 off, whose squares underflow (below about 1e-162, Lemma 8.1 says,
# the first screen's bound rounds to 0: BoxWithin passed a limit of 0 below a BoxDeviation of
# 1e-253); a box 1e-250 across has an exact deviation whose square is below every double (_below
# then steps up from 0 an ulp at a time).
_QUAT = st.lists(_offset(), min_size=4, max_size=4).filter(lambda q: sum(x * x for x in q) > 1e-3)


def _corner_deviation(box: np.ndarray, pa, ra, pb, rb) -> Q:
    """The largest squared displacement ``|(pa - pb) + (ra - rb) q|^2`` over the box's eight
    corners ``q`` (centre + sign * half, as BodyBoxes.corners computes them), exactly."""
    worst = Q(0)
    for sx in SIGNS:
        for sy in SIGNS:
            for sz in SIGNS:
                q = [box[CENTER + j] + s * box[HALF + j] for j, s in enumerate((sx, sy, sz))]
                v = [
                    Q(pa[i])
                    - Q(pb[i])
                    + sum((Q(ra[3 * i + j]) - Q(rb[3 * i + j])) * Q(q[j]) for j in range(3))
                    for i in range(3)
                ]
                worst = max(worst, sum(x * x for x in v))
    return worst


def _below(square: Q) -> float:
    """The largest double whose square is below ``square`` (> 0)."""
    x = math.sqrt(float(square))
    while Q(x) ** 2 >= square:
        x = math.nextafter(x, 0.0)
    while Q(math.nextafter(x, math.inf)) ** 2 < square:
        x = math.nextafter(x, math.inf)
    return x


@given(
    pa=st.lists(st.floats(-10.0, 10.0), min_size=3, max_size=3),
    offset=st.lists(_offset(), min_size=3, max_size=3),
    centre=st.lists(_offset().map(lambda x: x / 2), min_size=3, max_size=3),
    half=st.lists(_zero_or(0.5), min_size=3, max_size=3),
    qa=_QUAT,
    qb=st.one_of(st.none(), _QUAT),
)
@settings(max_examples=300, deadline=None)
def test_the_deviation_checks_first_screen_passes_no_box_beyond_its_limit(
    pa: list[float],
    offset: list[float],
    centre: list[float],
    half: list[float],
    qa: list[float],
    qb: list[float] | None,
) -> None:
    """``BoxWithin`` (Lemma 8.1) passes a box only where every corner, in exact arithmetic, is
    within the limit: at the largest double below the corners' exact deviation it fails. Its
    first screen, ``|pa - pb| + |ra - rb|_F |q_max|``, has the triangle inequality's room when
    the body turns, none when it only moves (``qb`` None: the same rotation), where its
    roundings (the differences, squares, sum and root) put it a few ulps below the exact
    ``|pa - pb|`` about half the time: the factor ``1 + 2e-9`` covers them (and the corners'
    own allowance, which the screen must not undercut). It passes again a rounding above the
    exact deviation (at most 2^-40 of it and of the terms' magnitudes)."""
    box = np.zeros(NCOL)
    box[CENTER : CENTER + 3], box[HALF : HALF + 3] = centre, half
    pa_ = np.asarray(pa)
    pb_ = pa_ + np.asarray(offset)
    ra = _rotation(qa)
    rb = ra.copy() if qb is None else _rotation(qb)
    square = _corner_deviation(box, pa_, ra, pb_, rb)
    assume(square > 0)
    assert not _core.box_within(box, pa_, ra, pb_, rb, _below(square))
    qmax = np.abs(box[CENTER : CENTER + 3]) + box[HALF : HALF + 3]
    scale = float(np.sum(np.abs(pa_ - pb_)) + np.sum(np.abs(ra - rb).reshape(3, 3) * qmax))
    above = math.sqrt(float(square)) * (1 + 2.0**-40) + 2.0**-40 * scale
    assert _core.box_within(box, pa_, ra, pb_, rb, above)


def _box_deviation(box: np.ndarray, pa, ra, pb, rb) -> float:
    """``BoxDeviation`` (plan.h): the largest of the eight corners' ``PoseDeviation`` (each
    rounded up past its own rounding), through ``plan_deviation`` on the corners as points,
    computed as BodyBoxes.corners and ``BoxDeviation`` compute them (centre + sign * half)."""
    points = np.zeros((8, SPHERE_NCOL))
    for k, signs in enumerate(itertools.product(SIGNS, repeat=3)):
        points[k, SPHERE_OFFSET : SPHERE_OFFSET + 3] = [
            box[CENTER + j] + s * box[HALF + j] for j, s in enumerate(signs)
        ]
    pose = [np.asarray(x, dtype=np.float64).reshape(1, 1, -1) for x in (pa, ra, pb, rb)]
    return float(_core.plan_deviation(points, *pose, np.zeros(0, np.int64)).max())


def _turned(ra: np.ndarray, axis: list[float], angle: float) -> np.ndarray:
    """``ra`` turned by ``angle`` (rad) about ``axis`` in its own frame: (9,)."""
    quat, turn, out = np.zeros(4), np.zeros(4), np.zeros(9)
    mujoco.mju_mat2Quat(quat, ra)
    mujoco.mju_axisAngle2Quat(turn, np.asarray(axis) / np.linalg.norm(axis), angle)
    mujoco.mju_mulQuat(quat, quat, turn)
    mujoco.mju_quat2Mat(out, quat)
    return out


def _screens(box: np.ndarray, pa, ra, pb, rb) -> list[float]:
    """The first screen's bounds with and without ``1 + 2e-9`` (by the columns of ``ra - rb``,
    and by its Frobenius norm, the screen before it), computed in floating point."""
    e = np.asarray(pa) - np.asarray(pb)
    f = (np.asarray(ra) - np.asarray(rb)).reshape(3, 3)
    qmax = np.abs(box[CENTER : CENTER + 3]) + box[HALF : HALF + 3]
    norm = math.sqrt(float(e @ e))
    columns = norm + sum(math.sqrt(float(f[:, j] @ f[:, j])) * qmax[j] for j in range(3))
    frobenius = norm + math.sqrt(float(np.sum(f * f))) * math.sqrt(float(qmax @ qmax))
    return [b * k for b in (columns, frobenius) for k in (1.0, 1.0 + 2e-9)]


_HALF = st.one_of(st.just(0.0), st.floats(1e-3, 0.5))


@given(
    pa=st.lists(st.floats(-10.0, 10.0), min_size=3, max_size=3),
    offset=st.lists(_offset(), min_size=3, max_size=3),
    centre=st.lists(st.one_of(st.just(0.0), st.floats(-0.5, 0.5)), min_size=3, max_size=3),
    half=st.lists(_HALF, min_size=3, max_size=3),
    qa=_QUAT,
    axis=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).filter(
        lambda a: sum(x * x for x in a) > 1e-3
    ),
    angle=st.one_of(st.just(0.0), st.floats(1e-9, 0.1), st.floats(0.1, math.pi)),
)
@settings(max_examples=400, deadline=None)
def test_the_deviation_checks_verdict_is_the_largest_corners(
    pa: list[float],
    offset: list[float],
    centre: list[float],
    half: list[float],
    qa: list[float],
    axis: list[float],
    angle: float,
) -> None:
    """``BoxWithin`` (Lemma 8.1) decides as ``BoxDeviation <= limit`` does (plan.h), whichever
    of its screens decides: at ``BoxDeviation`` itself, a double below it, and at each screen's
    bound (a column's norm of ``ra - rb`` at a time, the Frobenius norm, each with and without
    its factor) and a double below each. A screen that passed below the largest corner (its
    factor dropped, a row's norm for a column's, a column's reach for another's) passes a
    double below ``BoxDeviation`` on some draw: a box along one axis turned about another, or
    moved without turning. The replan's nesting checks (``Runtime::SetPlan``) rest on this: their
    verdicts, and so the departures and the alarms, are the corners' whichever screen is used."""
    box = np.zeros(NCOL)
    box[CENTER : CENTER + 3], box[HALF : HALF + 3] = centre, half
    pa_ = np.asarray(pa)
    pb_ = pa_ + np.asarray(offset)
    ra = _rotation(qa)
    rb = _turned(ra, axis, angle)
    deviation = _box_deviation(box, pa_, ra, pb_, rb)
    limits = [deviation, *_screens(box, pa_, ra, pb_, rb)]
    for limit in [*limits, *(math.nextafter(x, -math.inf) for x in limits)]:
        assert _core.box_within(box, pa_, ra, pb_, rb, limit) == (deviation <= limit), (
            limit,
            deviation,
        )


@given(
    t=_zero_or(2.0),
    s=_zero_or(10.0),
    accel=_zero_or(100.0),
    disc=_zero_or(10.0),
    speed=st.one_of(st.just(math.inf), _zero_or(20.0)),
)
@settings(max_examples=300, deadline=None)
def test_the_free_bodys_reach_is_rounded_up(
    t: float, s: float, accel: float, disc: float, speed: float
) -> None:
    """The mixed tau's reach of a free body (Lemma 8.3: ``(s + D) t + A t^2 / 2``, or ``V t``
    when that is less) is never below its exact value, held here in rational arithmetic: each
    term's factor (``1 + 8 eps`` on the quadratic's two products and three sums, ``1 + 2 eps``
    on the speed's one product) covers its roundings, which without it come out a little short
    about half the time. It is at most a few ulps above. ``speed`` inf: no speed bound."""
    got = Q(_core.mixed_reach(t, s, accel, disc, speed))
    quad = (Q(s) + Q(disc)) * Q(t) + Q(accel) * Q(t) * Q(t) / 2
    exact = quad if math.isinf(speed) else min(quad, Q(speed) * Q(t))
    assert got >= exact, (float(got - exact), float(exact))
    assert got <= exact * (1 + Q(2) ** -48) + Q(2) ** -1074, (float(got - exact), float(exact))
