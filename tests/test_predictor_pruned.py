"""The MuJoCo ``Predictor`` with pruned pairs: grid candidates within MuJoCo's exact pair filter."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from dua_mujoco import _core
from dua_mujoco.build.options import PairOptions
from dua_mujoco.core.pairset import PairSet
from dua_mujoco.core.schedules import DeadlineScheduler
from dua_mujoco.exceptions import InvalidChoiceError, InvalidInputError
from dua_mujoco.models.scenes import declared_accel_bound, load_scene, make_controller
from dua_mujoco.runtime.predictor import Predictor


def _world(n: int) -> tuple[mujoco.MjModel, mujoco.MjData, float]:
    m, d = load_scene(f"paper_world:{n}")
    bound = declared_accel_bound(m)
    assert bound is not None
    return m, d, bound


def _spheres_of(pairs, ids: np.ndarray) -> set[tuple[int, int]]:
    return set(zip(pairs.first[ids].tolist(), pairs.second[ids].tolist(), strict=True))


def test_pruned_alarms_cover_select_all_rule() -> None:
    """Every active sphere pair whose tau (over all pairs) is below ``(1 + latency) dt`` stands
    in alarm in the pruned predictor, at every step, while the bounds hold (pairs of spheres
    that ever touched anything are left out: contact breaks the acceleration bound)."""
    m, d, bound = _world(300)
    latency = 1
    pruned = Predictor(
        m, accel=bound, latency=latency, pairs=PairOptions(mode="pruned", horizon=0.02)
    )
    full = Predictor(m, accel=bound, latency=latency, pairs="all")
    assert pruned.stride == 9
    ctrl = make_controller(m, "random", seed=3)
    ctrl(m, d)
    mujoco.mj_step(m, d)
    pruned.reset(d)
    full.reset(d)
    ids = np.arange(full.nsphere_pairs)
    sp = full.sphere_pairs
    geom_sphere = np.full(m.ngeom, -1)
    cov = full.covering
    geom_sphere[np.asarray(cov.sphere_geom)] = np.arange(cov.nsphere)
    touched = np.zeros(cov.nsphere + 1, dtype=bool)  # the last entry: half-space pairs' "sphere"
    checked = 0
    for _ in range(60):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        alarms = pruned.step(d)
        full.step(d)
        nc = int(d.ncon)
        g = np.concatenate([d.contact.geom1[:nc], d.contact.geom2[:nc]])
        touched[geom_sphere[g][geom_sphere[g] >= 0]] = True
        held = pruned.held_pairs
        assert np.isin(alarms.pairs, held).all()
        sched = pruned.scheduler
        assert isinstance(sched, DeadlineScheduler)
        # The pruned predictor numbers the pairs in the order it met them: compare by spheres.
        ps = pruned.sphere_pairs
        ids_standing = held[np.flatnonzero(sched.alarm_state() & sched.active)]
        standing = _spheres_of(ps, ids_standing)
        c, v = full.sphere_states(d)
        tau = full.pair_set.tau(ids, c, v, full.halfspaces(d))
        second = np.where(sp.is_halfspace, cov.nsphere, sp.second)
        clean = ~touched[sp.first] & ~touched[second]
        urgent = np.flatnonzero((tau < (1 + latency) * full.dt - 1e-9) & clean)
        checked += urgent.size
        assert _spheres_of(sp, urgent) <= standing
        assert held.size < full.nsphere_pairs / 10
    assert checked > 0
    assert pruned.universe.counts() == (full.geom_pairs.npair, full.nsphere_pairs)
    assert pruned.nsphere_pairs < full.nsphere_pairs / 3  # met, not all


def test_switched_off_pairs_stay_off_across_rebuilds() -> None:
    m, d, bound = _world(60)
    p = Predictor(m, accel=bound, latency=0, pairs=PairOptions(mode="pruned", horizon=0.004))
    p.reset(d)
    assert p.stride == 2
    switched = p.set_active_bodies("sphere0", on=False)
    assert switched > 0
    for _ in range(6):
        mujoco.mj_step(m, d)
        p.step(d)
        sched = p.scheduler
        assert sched is not None
        body = np.asarray(p.covering.sphere_body)[p.pair_set.first[p.held_pairs]]
        b0 = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "sphere0")
        assert not sched.active[body == b0].any()


def test_pairs_option_validation_and_auto() -> None:
    m, _, bound = _world(20)
    with pytest.raises(InvalidChoiceError, match="pruned"):
        Predictor(m, accel=bound, pairs="some")
    with pytest.raises(InvalidInputError, match="schedule='deadline'"):
        Predictor(m, accel=bound, pairs="pruned", schedule="dua")
    with pytest.raises(InvalidInputError, match="horizon"):
        Predictor(m, accel=bound, pairs=PairOptions(mode="pruned", horizon=0.001))
    assert Predictor(m, accel=bound, pairs="auto").stride == 0
    big, _, bound = _world(300)
    assert Predictor(big, accel=bound, pairs="auto").stride == 32


def test_swarm_scene_keeps_the_paper_density() -> None:
    m, _ = load_scene("swarm:320")
    spheres = int((np.asarray(m.geom_type) == int(mujoco.mjtGeom.mjGEOM_SPHERE)).sum())
    assert spheres == 320
    # The cube's side is 2 for 320 = 40 * 2^3 spheres: walls at +-1.
    planes = np.asarray(m.geom_type) == int(mujoco.mjtGeom.mjGEOM_PLANE)
    assert np.allclose(np.sort(np.abs(m.geom_pos[planes]).max(axis=1)), 1.0)
    with pytest.raises(InvalidInputError, match="'swarm:20'"):
        load_scene("swarm:x")


@pytest.mark.parametrize("pairs", ["all", "pruned"])
def test_bin_pour_flags_every_onset_through_a_pile_of_impacts(pairs: str) -> None:
    """Objects poured into a bin: hundreds of onsets, impacts breaking the bounds at every step
    (events renew the pairs; a pruned set renews the pairs of a struck body that may have left
    its reach): no onset missed, all pairs or pruned."""
    from dua_mujoco import PilotOptions
    from dua_mujoco.testing import assert_no_missed_collisions

    m, d = load_scene("bin_pour:60")
    predictor = Predictor(m, pairs=pairs, pilot=PilotOptions(steps=400))
    report = assert_no_missed_collisions(m, d, steps=600, predictor=predictor, scene="bin_pour")
    assert report.contact_onsets > 300 and report.bound_violations > 1000
    if pairs == "pruned":
        # The regular rebuilds (every 32 steps), renewals far fewer than the violations.
        assert predictor.rebuilds >= 600 // 32
        assert 0 < predictor.renewals < report.bound_violations // 10


def _escaped(
    anchor: float,
    s0: float,
    accel: float,
    delta: float,
    speed: float,
    t: float,
    center: np.ndarray,
    velocity: np.ndarray,
) -> bool:
    """Whether the pruned step's escape test (``csrc/src/reach.cc``) flags one sphere anchored
    at ``(anchor, 0, 0)`` with measured speed ``s0`` then, ``t`` seconds on."""
    one = np.ones(1)
    c, v = (np.asarray(x, dtype=float).reshape(1, 3) for x in (center, velocity))
    out = _core.escapes(
        np.array([[anchor, 0.0, 0.0]]), s0 * one, accel * one, delta * one, speed * one,
        np.zeros(1, dtype=np.int64), c, v, t * one,
    )  # fmt: skip
    return out.tolist() == [0]


from hypothesis import assume, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


@settings(max_examples=300, deadline=None)
@given(
    s0=st.floats(0.0, 3.0),
    accel=st.floats(0.01, 50.0),
    delta=st.floats(0.0, 0.1),
    tau=st.floats(1e-3, 0.1),
    frac=st.floats(0.0, 1.0),
    seed=st.integers(0, 2**31 - 1),
)
def test_a_sphere_the_escape_check_passes_stays_within_its_reach(
    s0: float, accel: float, delta: float, tau: float, frac: float, seed: int
) -> None:
    """Lemma 6.4 on sampled trajectories: a state at ``tau`` that the check passes (anywhere
    inside the reach, at any speed it allows, the true velocity within ``delta`` of the
    measured one), followed by any motion within the acceleration bound, stays within the reach
    ``(s0 + delta) t + A t^2 / 2`` of the anchor for the rest of the horizon."""
    rng = np.random.default_rng(seed)

    def reach(t: float) -> float:
        return (s0 + delta) * t + 0.5 * accel * t * t

    def unit() -> np.ndarray:
        u = rng.normal(size=3)
        return u / np.linalg.norm(u)

    # States near the check's edges, on both sides: the ones it passes must stay in reach (a
    # looser check, e.g. a measured speed up to s0 + 2 delta + A t, lets some out).
    x = unit() * 1.2 * frac * reach(tau)
    measured = unit() * (s0 + accel * tau + 2.0 * delta) * rng.uniform(0.8, 1.05)
    assume(not _escaped(0.0, s0, accel, delta, np.inf, tau, x, measured))
    v = measured + unit() * delta  # the true velocity, at the edge of the uncertainty
    # Any motion within the bound: piecewise-constant accelerations, the worst one (straight
    # away from the anchor) among them.
    t, h = tau, 1e-3
    while t < 1.0:
        a = x / max(np.linalg.norm(x), 1e-12) if rng.uniform() < 0.5 else unit()
        x = x + v * h + 0.5 * accel * a * h * h
        v = v + accel * a * h
        t += h
        assert np.linalg.norm(x) <= reach(t) * (1 + 1e-9) + 1e-12


def test_the_escape_check_flags_a_sphere_out_of_its_reach_or_too_fast() -> None:
    def escaped(center: list[float], velocity: list[float], speed: float = np.inf) -> bool:
        return _escaped(0.0, 1.0, 2.0, 0.0, speed, 0.05, np.array(center), np.array(velocity))

    assert not escaped([0.05, 0, 0], [1.0, 0, 0])  # reach at 0.05 s: 0.0525 m; speed: 1.1 m/s
    assert escaped([0.06, 0, 0], [1.0, 0, 0])  # too far
    assert escaped([0.0, 0, 0], [0, 1.2, 0])  # too fast
    # A speed bound: the reach is V t at most, the speed V - delta.
    assert escaped([0.0, 0, 0], [1.06, 0, 0], speed=1.05)
    assert escaped([0.0526, 0, 0], [0, 0, 0], speed=1.05)


def _arrays(obj: object, depth: int = 2) -> list[np.ndarray]:
    """The numpy arrays an object holds in its attributes (and theirs, ``depth`` levels)."""
    found: list[np.ndarray] = []
    for value in vars(obj).values():
        values = value if isinstance(value, tuple | list) else (value,)
        for v in values:
            if isinstance(v, np.ndarray):
                found.append(v)
            elif depth > 0 and hasattr(v, "__dict__") and not isinstance(v, type):
                found += _arrays(v, depth - 1)
    return found


def test_a_pruned_run_holds_nothing_the_size_of_all_pairs() -> None:
    """Memory O(N + pairs met): after a monitored run of a swarm, no array of the predictor,
    its universe and held set, the monitor or the report is as large as the model's pairs."""
    from dua_mujoco.measure.monitor import Monitor
    from dua_mujoco.measure.rollout import run

    m, d = load_scene("swarm:1500")
    p = Predictor(m, accel=2.0)
    monitors: list[Monitor] = []
    report = run(
        m, d, p, steps=60, progress=False, series=False,
        on_step=lambda k, data, alarms, monitor: monitors.append(monitor) if k == 1 else None,
    )  # fmt: skip
    total = p.universe.counts()[1]
    assert report.pairs == total == 1500 * 1499 // 2 + 1500 * 6
    bound = 20 * (p.nsphere + p.nsphere_pairs)
    assert bound < total / 5  # the check below could fail
    holders = [p, p.universe, monitors[0], report]
    sizes = [a.size for h in holders for a in _arrays(h)]
    assert sizes and max(sizes) <= bound, max(sizes)


def test_every_pair_whose_reaches_meet_is_held_through_renewals() -> None:
    """Objects poured into a bin, whose impacts break the bounds: struck spheres are renewed
    alone, many bringing new pairs in. After every step the held set holds every active sphere
    pair whose reach balls, each from its own anchor, come within the margin (what the
    completeness proof of docs/many-objects.md rests on), and a pair not held was left out at
    the later anchor of its two spheres."""
    from reference_grid import ROUNDING_SLACK

    from dua_mujoco.build.pairfilter import FilterTables, dynamic_mask

    m, d = load_scene("bin_pour:60")
    p = Predictor(m, accel=5.0, pairs="pruned")
    p.reset(d)
    rules = FilterTables.of(m)
    geom = p.covering.sphere_geom
    n = p.nsphere
    upper = np.triu(np.ones((n, n), dtype=bool), 1)
    for _ in range(200):
        mujoco.mj_step(m, d)
        p.step(d)
        r = p._rt.reaches()
        gap = r["anchor"][:, None, :] - r["anchor"][None, :, :]
        s = r["reach"][:, None] + r["reach"][None, :] + r["margin"]
        i, j = np.nonzero(upper & (np.einsum("ijk,ijk->ij", gap, gap) <= s * s * ROUNDING_SLACK))
        # The pairs MuJoCo's filter lets through are known and held; the rest it rejects.
        sp = p.sphere_pairs
        known = {
            (int(a), int(b)): k for k, (a, b) in enumerate(zip(sp.first, sp.second, strict=True))
        }
        ids = np.array(
            [known.get((a, b), known.get((b, a), -1)) for a, b in zip(i, j, strict=True)]
        )
        assert not dynamic_mask(rules, geom[i[ids < 0]], geom[j[ids < 0]]).any()
        assert np.isin(ids[ids >= 0], p.held_pairs).all()
        out = np.setdiff1d(np.arange(p.nsphere_pairs), p.held_pairs)
        want = np.maximum(r["built"][sp.first[out]], r["built"][sp.second[out]])
        np.testing.assert_array_equal(p.pair_state().last_step_of(out), want)
    assert p.rebuilds == 200 // p.stride and p.renewals > 20


@pytest.mark.parametrize("seed", range(4))
def test_reach_pairs_equal_a_brute_force_reference(seed: int) -> None:
    """``dua_reach_pairs`` (the renewal's search): every pair of a listed sphere (listed twice,
    or both members listed, still once) whose anchored reaches meet under the grid's contract,
    and no other."""
    from reference_grid import ROUNDING_SLACK

    rng = np.random.default_rng(seed)
    n, margin = 200, 0.01
    anchor = rng.uniform(-1, 1, (n, 3))
    anchor[1] = anchor[0]  # coincident centres
    reach = rng.uniform(0.0, 0.3, n)
    ids = np.concatenate([rng.choice(n, 12, replace=False), [0, 1, 0]]).astype(np.int64)
    out = _core.reach_pairs(anchor, reach, margin, ids)
    want = set()
    for i in set(ids.tolist()):
        for j in range(n):
            dx = anchor[i] - anchor[j]
            s = (reach[i] + reach[j]) + margin
            if j != i and dx @ dx <= s * s * ROUNDING_SLACK:
                want.add((min(i, j), max(i, j)))
    got = [tuple(r) for r in out.tolist()]
    assert len(got) == len(set(got)) and set(got) == want and len(got) > 2


def test_the_tables_a_pruned_predictor_learns_are_the_all_pairs_ones() -> None:
    """The tables of the pairs a pruned predictor learns as it runs are read from its runtime
    (``PairUniverse._sync``); each row, geom pair or sphere pair, equals the all-pairs
    predictor's row of the same pair, the ``<pair>`` element's flag and margin included."""
    balls = "".join(
        f'<body pos="{0.12 * (i % 4)} {0.12 * (i // 4)} {0.3 + 0.05 * i}"><freejoint/>'
        f'<geom name="b{i}" size=".05"/></body>'
        for i in range(12)
    )
    m = mujoco.MjModel.from_xml_string(
        f'<mujoco><worldbody><geom type="plane" size="2 2 .1"/>{balls}</worldbody>'
        '<contact><pair geom1="b0" geom2="b11" margin=".02"/></contact></mujoco>'
    )
    d = mujoco.MjData(m)
    pruned = Predictor(m, accel=20.0, pairs=PairOptions(mode="pruned", horizon=0.02))
    full = Predictor(m, accel=20.0, pairs="all")
    mujoco.mj_forward(m, d)
    pruned.reset(d)
    for _ in range(300):
        mujoco.mj_step(m, d)
        pruned.step(d)
    assert pruned.universe.version > 0
    mine, theirs = pruned.geom_pairs, full.geom_pairs
    at = theirs.indices_of(mine.geom1, mine.geom2)
    assert (at >= 0).all() and mine.explicit.sum() == 1
    for name in ("explicit", "margin", "gap", "contact_distance"):
        np.testing.assert_array_equal(getattr(mine, name), getattr(theirs, name)[at], name)
    ps, pf = pruned.pair_set, full.pair_set
    assert ps is not None and pf is not None

    def rows(p: PairSet) -> list[tuple[int, int, int]]:
        return list(zip(p.first.tolist(), p.second.tolist(), p.kind.tolist(), strict=True))

    key = {k: i for i, k in enumerate(rows(pf))}
    at = np.array([key[k] for k in rows(ps)])
    for name in ("eps", "accel", "vel_uncertainty", "speed"):
        np.testing.assert_array_equal(getattr(ps, name), getattr(pf, name)[at], name)
    for name in ("geom1", "geom2", "halfspace"):
        np.testing.assert_array_equal(
            getattr(pruned.tables, name), getattr(full.tables, name)[at], name
        )
    for g in ("geom1", "geom2"):  # each sphere pair's geom pair
        np.testing.assert_array_equal(
            getattr(mine, g)[pruned.sphere_pairs.geom_pair],
            getattr(theirs, g)[full.sphere_pairs.geom_pair[at]],
        )


# Two balls on slides closing head-on at 1 m/s in zero gravity: the bounds hold (no force), and
# a pair left out at the reset's rebuild touches when the gap says.
_CLOSING = """<mujoco><option timestep="0.002" gravity="0 0 0"/><worldbody>
<body pos="{a} 0 0.5"><joint type="slide" axis="1 0 0"/><geom type="sphere" size="0.05"/></body>
<body pos="{b} 0 0.5"><joint type="slide" axis="1 0 0"/><geom type="sphere" size="0.05"/></body>
</worldbody></mujoco>"""


@pytest.mark.parametrize("period", [2, 3, 4])
def test_a_pair_left_out_touching_between_predictor_steps_is_flagged_the_horizon_ahead(
    period: int,
) -> None:
    """A pair left out at a rebuild and held from the next one, a stride later, touches at
    physics steps just past that rebuild, at every phase between two predictor steps: with
    the reach covering ``dt - h`` more than the stride (docs/many-objects.md, "Between predictor
    steps") every lead is at least the alarm horizon while the bounds hold. With the reach
    ``(stride + latency) dt`` alone the pair was left out and flagged only 1 to ``period - 1``
    steps ahead."""
    from dua_mujoco.measure.monitor import Monitor

    h = 0.002
    dt = period * h
    steps = set()
    for extra in np.arange(0.25, 2 * period, 0.5) * h:  # past the stride's time, in steps of h/2
        gap = 32 * dt + extra  # the default stride at latency 0: 32 periods
        m = mujoco.MjModel.from_xml_string(_CLOSING.format(a=-(gap + 0.1) / 2, b=(gap + 0.1) / 2))
        d = mujoco.MjData(m)
        d.qvel[:] = [0.5, -0.5]
        p = Predictor(m, accel=1e-3, period=period, pairs="pruned")
        assert p.stride == 32
        mon = Monitor(p)
        mujoco.mj_step(m, d)
        mon.start(d)
        k = 0
        while not d.ncon:
            k += 1
            mujoco.mj_step(m, d)
            mon.observe(d, p.step(d) if k % period == 0 else None)
        mon.finish()
        assert mon.onsets == mon.predicted == 1 and mon.violations == 0
        assert mon.warning.short_held == 0, (extra, k, mon.warning.leads)
        assert mon.warning.leads[0] >= p.alarm_horizon - 1e-12
        steps.add(k - 32 * period)
    assert set(range(1, period)) <= steps, steps  # every phase between the two steps
