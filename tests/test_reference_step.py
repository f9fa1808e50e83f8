"""The step held to an independent slow reference (tests/reference_step.py): at many states of
rollouts of the bundled scenes and of robot models, every pair's tau after a classification
never exceeds the time at which an explicit motion the declared bounds allow brings its two
geoms into contact (MuJoCo's own distance on the moved poses), and every pair such a motion
touches within the alarm horizon stands in alarm. The reference shares no code with the runtime,
so a tau kernel, the exact level, the pair tables or the alarm rule that is wrong in the
dangerous direction fails here (the mutants of benchmarks/mutants.py show it)."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import gymnasium
import mujoco
import numpy as np
import pytest
import reference_step as ref
from benchmark_scripts import script

from dua_mujoco._core import LAYOUT
from dua_mujoco.models.scenes import load_scene, make_controller
from dua_mujoco.runtime.predictor import Predictor

ANT = str(Path(gymnasium.__file__).parent / "envs/mujoco/assets/ant.xml")
HUMANOID = str(Path(gymnasium.__file__).parent / "envs/mujoco/assets/humanoid.xml")


@dataclass
class Tally:
    """What the reference found over a run's states."""

    pairs: int = 0
    left_out: int = 0  # a height field or SDF, a mocap tree, a spin beyond the bound
    at_horizon: int = 0  # a motion touches within the alarm horizon (each stood in alarm)
    tight: int = 0  # a motion touches by 1.5 tau (a tau half again as late fails)
    uncovered: int = 0
    screened: int = 0  # stepped: geom pairs whose verdict is the screen's (docs/theory.md, 3)
    late: list[str] = field(default_factory=list)
    unflagged: list[str] = field(default_factory=list)


def _model(name: str) -> tuple[mujoco.MjModel, mujoco.MjData]:
    if name.startswith("robot/"):
        m = script("robots").load_robot(name.split("/", 1)[1])
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        return m, d
    return load_scene(name)


def hold_to_reference(
    name: str, accel: float, *, speed: float | None = None, states: int = 6, every: int = 40,
    max_pairs: int = 600, seed: int = 0, stepped: bool = False, **options: object,
) -> Tally:  # fmt: skip
    """Roll ``name`` out under random controls and, every ``every`` steps, classify and hold
    each geom pair (``max_pairs`` of them at most a state, the most urgent first; a geom pair's
    tau is the least of its sphere pairs') to the reference. ``options``: more of the
    ``Predictor``'s (the exact level is on, every pair held). ``stepped``: the predictor steps
    along instead, and each state holds the verdicts made at it (the evaluated pairs' and the
    screen's, section 3) to the reference; whether the pairs within the horizon stand rests on
    older verdicts too, so only the lateness is checked."""
    m, d = _model(name)
    p = Predictor(m, accel=accel, speed=speed, pairs="all", **options)  # type: ignore[arg-type]
    bounds = ref.declared(m, accel, speed)
    ctrl = make_controller(m, "random", seed=seed)
    scratch = mujoco.MjData(m)
    geom1, geom2 = (np.asarray(g) for g in p.sphere_pair_geoms)
    keys, inverse = np.unique(np.sort(np.stack([geom1, geom2], 1), 1), axis=0, return_inverse=True)
    unsupported = np.isin(np.asarray(m.geom_type), sorted(ref.UNSUPPORTED))
    in_mocap_tree = np.asarray(m.body_mocapid)[np.asarray(m.body_rootid)] >= 0
    mocap_geom = in_mocap_tree[np.asarray(m.geom_bodyid)]
    tally = Tally()
    ids = np.arange(geom1.size)
    screened = np.zeros(len(keys), dtype=bool)
    judged = np.ones(len(keys), dtype=bool)  # stepped: geom pairs with a verdict of this state
    if stepped:
        p.reset(d)
    for k in range(1, states * every + 1):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        if stepped:
            p.step(d)
        if k % every:
            continue
        if not stepped:
            p.reset(d)  # every pair evaluated from this state alone
        state = p.pair_state()
        last_tau = state.last_tau_of(ids)
        if stepped:
            fresh = state.last_step_of(ids) == state.step_count
            at = np.full(ids.size, -1)
            at[np.asarray(p.held_pairs)] = state.scheduler.ints[LAYOUT["WHERE"]]
            # The screen's own verdicts (the double above the horizon), not the evaluations of
            # the pairs that joined it at this state.
            cleared = np.nextafter(state.scheduler.horizon[0], np.inf)
            by_test = fresh & (at == LAYOUT["SCREENED"]) & (last_tau == cleared)
            last_tau = np.where(fresh, last_tau, np.inf)
            screened[:] = judged[:] = False
            np.logical_or.at(screened, inverse, by_test)
            np.logical_or.at(judged, inverse, fresh)
        tau = np.full(len(keys), np.inf)
        np.minimum.at(tau, inverse, last_tau)
        stands = np.zeros(len(keys), dtype=bool)
        np.logical_or.at(stands, inverse, state.alarm_state())
        mujoco.mj_copyData(scratch, m, d)
        reference = ref.PairReference(ref.PairProbe(m, scratch), horizon=p.alarm_horizon)
        for i in np.argsort(tau, kind="stable")[:max_pairs].tolist():
            if not judged[i]:
                continue
            a, b = (int(g) for g in keys[i])
            if unsupported[[a, b]].any() or mocap_geom[[a, b]].any():
                tally.left_out += 1
                continue
            sa, sb = ref.geom_state(m, d, a, bounds), ref.geom_state(m, d, b, bounds)
            if not (sa.feasible and sb.feasible):
                tally.left_out += 1
                continue
            verdict = reference.check(sa, sb, ref.contact_distance(m, a, b), float(tau[i]))
            tally.pairs += 1
            tally.screened += bool(screened[i])
            tally.tight += verdict.tight
            tally.uncovered += not verdict.covered
            where = f"step {k}, {m.geom(a).name or a} / {m.geom(b).name or b}"
            if verdict.before is not None:
                tally.late.append(f"{where}: tau {tau[i]:.9g} s, contact at {verdict.before:.9g} s")
            if verdict.at_horizon:
                tally.at_horizon += 1
                if not stands[i] and not stepped:
                    tally.unflagged.append(f"{where}: tau {tau[i]:.9g} s, not in alarm")
    assert not tally.late, f"{len(tally.late)} taus later than a feasible contact: {tally.late[:5]}"
    assert not tally.unflagged, f"{len(tally.unflagged)} pairs not flagged: {tally.unflagged[:5]}"
    return tally


# (scene, acceleration bound, speed bound): robots as the suite runs them (the
# gymnasium and dm_control models are test dependencies); DUA_REFERENCE_ROBOTS=1 adds every
# robot of benchmarks/robots.py whose package is installed (docs/testing.md).
CASES: list[tuple[str, float, float | None, dict]] = [
    ("two_arms", 30.0, None, {}),
    ("two_arms", 30.0, None, {"covering": "multi"}),  # a geom pair's least sphere pair
    ("traffic", 4.0, None, {}),  # fast cars passing under a low bound: tau's later roots
    ("clutter", 30.0, None, {}),
    ("paper_world", 30.0, 1.0, {}),  # with a speed bound
    ("bin_pour:30", 5.0, None, {}),
    (ANT, 30.0, None, {}),
    (HUMANOID, 30.0, None, {}),
    ("robot/dmc_quadruped", 30.0, None, {}),
    ("robot/dmc_dog", 30.0, None, {}),
]
ROBOTS: list[str] = []
if os.environ.get("DUA_REFERENCE_ROBOTS"):
    # Bounds that random controls of a robot come nearer (docs/theory.md, section 9's 10^2 -
    # 10^4 m/s^2): fewer bodies spin beyond them (pairs left out).
    ROBOTS = [f"robot/{r}" for r in script("robots").available() if not r.startswith("dmc_")]
    CASES += [(r, 300.0, None, {}) for r in ROBOTS]


# The screen's verdicts (docs/theory.md, section 3, "The screen"), made at the states held.
STEPPED: list[tuple[str, float, float | None, dict]] = [
    ("two_arms", 200.0, None, {}),
    ("clutter", 200.0, None, {}),
    ("robot/dmc_dog", 200.0, None, {}),
]


def _case_id(case: tuple) -> str:
    scene, _, _, options = case
    name = Path(scene).stem.split(":")[0].removeprefix("robot/")
    return "-".join([name, *(str(v) for v in options.values())])


@pytest.mark.parametrize(("scene", "accel", "speed", "options"), CASES, ids=map(_case_id, CASES))
def test_tau_is_never_later_than_a_feasible_contact_and_those_within_the_horizon_stand(
    scene: str, accel: float, speed: float | None, options: dict
) -> None:
    tally = hold_to_reference(scene, accel, speed=speed, **options)
    if scene in ROBOTS:  # an arm may touch nothing in a few states
        assert tally.pairs >= 50
        return
    # Not vacuous: most pairs are held to the reference, some are touched within the horizon
    # (each stood in alarm), some by motions that touch at most 1.5 tau after the state.
    assert tally.pairs >= 50 and tally.left_out <= tally.pairs
    assert tally.at_horizon > 0 and tally.tight > 0
    assert tally.uncovered <= tally.pairs // 100


@pytest.mark.parametrize(
    ("scene", "accel", "speed", "options"), STEPPED, ids=map(_case_id, STEPPED)
)
def test_screened_verdicts_are_never_later_than_a_feasible_contact(
    scene: str, accel: float, speed: float | None, options: dict
) -> None:
    tally = hold_to_reference(scene, accel, speed=speed, stepped=True, **options)
    assert tally.pairs >= 50 and tally.screened >= 10


def main() -> None:
    """Print the tallies of every case as a markdown table (docs/testing.md)."""
    print(
        "| model | bound (m/s^2) | pairs held | left out | touched within the horizon | tight | s |"
    )
    print("|---|---|---|---|---|---|---|")
    for case in CASES:
        scene, accel, speed, options = case
        start = time.monotonic()
        t = hold_to_reference(
            scene, accel, speed=speed, **options
        )  # asserts: no late, no unflagged
        bound = f"{accel:g}" + ("" if speed is None else f", V = {speed:g} m/s")
        print(
            f"| {_case_id(case)} | {bound} | {t.pairs} | {t.left_out} | {t.at_horizon} | "
            f"{t.tight} | {time.monotonic() - start:.1f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
