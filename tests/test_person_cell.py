"""The bundled person-and-arm scene (``person_cell``, docs/plans.md): a planned arm working a cell
while a person nobody plans walks in and reaches, within ISO 13855's bounds.

* It is a bundled scene: ``load_scene`` starts it at home, ``dua-mujoco run person_cell`` drives
  it with its own driver and its declared bounds; with ``--plan trajectory`` too, no onset is
  missed and none with less lead than the horizon is labelled held.
* The planned run's plan holds the arm only: every verdict on an arm-person pair rested on the
  plan for the arm and on the bounds for the person; while nothing touches the arm, its plan is
  the run (no break at deviation 0).
* The arm's declared bounds hold on seeds other than those they were measured on.
* :class:`~dua_mujoco.runtime.plans.Replanner` plans at the reset and every ``R`` steps after.
* docs/plans.md's example of the scene runs.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest

from dua_mujoco.cli import main
from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.models.people import PERSON_BOUNDS
from dua_mujoco.models.person_cell import (
    ARM,
    ARM_BOUNDS,
    CellDriver,
    declared_bounds,
    measure_arm_bounds,
)
from dua_mujoco.models.scenes import load_scene, make_controller
from dua_mujoco.run_options import add_run_options, controller_for, predictor_options
from dua_mujoco.runtime.plans import Replanner
from dua_mujoco.runtime.predictor import Predictor

TOUCH_SEED = 12
"""A visit whose person touches the arm early (first contact at step 1,954 of the rollout)."""
TOUCH_STEPS = 2300


def _options(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    parser.add_argument("scene")
    add_run_options(parser)
    return parser.parse_args(argv)


def test_the_scene_loads_at_home_and_its_driver_moves_the_person_within_its_bounds() -> None:
    m, d = load_scene("person_cell")
    assert np.allclose(d.qpos, [0.0, -0.2, 2.0, 1.2, 0.0, 0.0]) and not d.qvel.any()
    driver = CellDriver(m, TOUCH_SEED)
    h = float(m.opt.timestep)
    pos = []
    for _ in range(TOUCH_STEPS):
        driver(m, d)
        pos.append(d.mocap_pos.copy())
        mujoco.mj_step(m, d)
    speed = np.linalg.norm(np.diff(np.array(pos), axis=0), axis=2) / h
    for name, bound in PERSON_BOUNDS.items():
        mid = int(m.body_mocapid[m.body(name).id])
        assert 0.4 * bound.speed < speed[1:, mid].max() <= bound.speed * (1 + 1e-9)
    assert driver.arm.reached >= 2  # the arm works its cell


@pytest.mark.parametrize("plan", ["none", "trajectory"])
def test_the_scene_runs_under_the_cli_with_no_short_lead_held(tmp_path: Path, plan: str) -> None:
    out = tmp_path / "report.json"
    argv = ["run", "person_cell", "--steps", str(TOUCH_STEPS), "--seed", str(TOUCH_SEED)]
    argv += ["--alarm-horizon", "0.2", "--plan", plan, "--json", str(out), "--no-progress"]
    assert main(argv) == 0
    report = json.loads(out.read_text())
    assert report["contact_onsets"] > 0  # the person touches the arm
    assert report["missed_onsets"] == 0
    assert report["short_lead_bounds_held"] == 0
    assert report["warning_horizon_s"] == pytest.approx(0.2)


def test_the_cli_drives_person_cell_with_its_driver_and_declared_bounds() -> None:
    m, _ = load_scene("person_cell")
    options = _options("person_cell")
    assert isinstance(controller_for(m, options), CellDriver)
    bounds = predictor_options(m, options)["accel"]
    assert np.array_equal(bounds.accel, declared_bounds(m).accel)
    person = m.body("person").id
    assert bounds.speed[person] == 1.6 and bounds.accel[person] == 2.0  # ISO 13855 walking
    # --speed on top of the declared bounds, as on top of a pilot's.
    capped = predictor_options(m, _options("person_cell", "--speed", "1.0"))["accel"]
    assert capped.speed[person] == 1.0 and capped.accel[person] == 2.0
    # A scene without a driver of its own: random controls and a pilot, as before.
    arms, _ = load_scene("two_arms")
    assert predictor_options(arms, _options("two_arms"))["accel"] == "auto"
    with pytest.raises(InvalidInputError, match="person_cell"):
        controller_for(arms, _options("two_arms", "--ctrl", "scene"))
    with pytest.raises(InvalidInputError, match="predictor"):
        controller_for(m, _options("person_cell", "--plan", "trajectory"))


def test_the_planned_run_plans_the_arm_only() -> None:
    """Every verdict of an arm-person pair rested on the arm's plan and the person's bounds; of
    the arm's own pairs (with itself and the cell), on the plan for both sides; while nothing
    touches the arm, its plan is the run (deviation 0, no break)."""
    m, d = load_scene("person_cell")
    p = Predictor(m, accel=declared_bounds(m), alarm_horizon=0.2)
    driver = CellDriver(m, TOUCH_SEED)
    replan = Replanner(p, driver, planner=driver.plan, bodies=ARM)
    replan(m, d)
    mujoco.mj_step(m, d)
    p.reset(d)
    body = np.asarray(m.geom_bodyid)
    person = np.asarray(m.body_mocapid)[body] >= 0
    g1, g2 = p.sphere_pair_geoms
    pairs = np.arange(g1.size)
    seen = np.zeros(2, dtype=int)  # arm-person pairs, the arm's own
    for _ in range(1900):  # up to the first touch
        replan(m, d)
        mujoco.mj_step(m, d)
        p.step(d)
        basis = p.verdict_basis(pairs)[:, 0]  # the latest verdict
        on_plan = np.stack([basis & 1, basis >> 1 & 1], axis=1).astype(bool)
        sides = np.stack([person[g1], person[g2]], axis=1)
        # Planned exactly where the arm is: a side is on the plan iff it is not the person.
        assert np.array_equal(on_plan, ~sides)
        seen += [int(sides.any(axis=1).sum()), int((~sides).all(axis=1).sum())]
    assert p.plan_breaks == 0
    assert replan.plans == (1900 - 1) // replan.every + 1
    assert seen.min() > 0  # both kinds of pairs were looked at


def test_the_arm_stays_within_its_declared_bounds_on_other_seeds() -> None:
    m, _ = load_scene("person_cell")
    points = Predictor(m, accel=1.0).bound_points
    measured = measure_arm_bounds(m, 2, points=points, first_seed=50_000)
    for name, bound in ARM_BOUNDS.items():
        got = measured[name]
        assert got.speed <= bound.speed and got.accel <= bound.accel, name
        assert got.delta is not None and bound.delta is not None and got.delta <= bound.delta
        # Declared at twice what was measured: the fresh seeds come near half of it.
        assert got.accel > 0.3 * bound.accel, name


def test_a_replanner_plans_at_each_reset_and_every_r_steps_exactly() -> None:
    """On two_arms under random controls, a copy of the controller knows its own future: the
    plans are the run (no break at deviation 0); one at the reset, then every R steps, and again
    at a reset."""
    m, d = load_scene("two_arms")
    p = Predictor(m, accel=80.0, alarm_horizon=0.05)
    controller = make_controller(m, "random", seed=3)
    replan = Replanner(p, controller)
    assert replan.every == 25 and replan.knots == 25 + 25 + 1 + 1
    replan(m, d)  # before the reset: no plan
    assert replan.plans == 0
    mujoco.mj_step(m, d)
    p.reset(d)
    for _ in range(100):
        replan(m, d)
        mujoco.mj_step(m, d)
        p.step(d)
    assert replan.plans == 4 and p.plan_breaks == 0 and p.has_plan
    p.reset(d)  # drops the plan: the next call gives one
    replan(m, d)
    assert replan.plans == 5 and p.has_plan


def test_the_docs_example_runs() -> None:
    """docs/plans.md's Python example of the scene, as it is written: the person touches the arm
    (seed 12), which breaks the arm's plan."""
    text = (Path(__file__).parents[1] / "docs" / "plans.md").read_text()
    section = text.split("## A person in the cell")[1]
    code = re.search(r"```python\n(.*?)```", section, flags=re.DOTALL)
    assert code is not None
    scope: dict = {}
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code[1], "docs/plans.md", "exec"), scope)
    assert scope["predictor"].plan_breaks > 0
    assert "plan breaks" in out.getvalue()
