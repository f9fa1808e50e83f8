"""benchmarks/plugin_bounds.py on an inline arm: the models take turns in rotated blocks on one
trajectory, a row holds each bound's figures over the steps after the skip (no timing
asserted), and bad options are refused with the fix."""

from __future__ import annotations

import math
from types import SimpleNamespace

import mujoco
import pytest
from benchmark_scripts import script

ARM = """
<mujoco>
  <worldbody>
    <geom type="plane" size="1 1 0.1"/>
    <body pos="0 0 0.3">
      <joint name="j1" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.03"/>
      <body pos="0.2 0 0">
        <joint name="j2" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.03"/>
      </body>
    </body>
    <body pos="0.25 0 0.1"><geom type="box" size="0.05 0.05 0.05"/></body>
  </worldbody>
  <actuator>
    <motor joint="j1" gear="5" ctrlrange="-1 1"/>
    <motor joint="j2" gear="5" ctrlrange="-1 1"/>
  </actuator>
</mujoco>
"""


def test_a_robots_row_has_both_bounds(monkeypatch: pytest.MonkeyPatch) -> None:
    bounds = script("plugin_bounds")
    calls: list[tuple[int, tuple[float, ...]]] = []
    step = mujoco.mj_step

    def counted(m: mujoco.MjModel, d: mujoco.MjData) -> None:
        step(m, d)
        calls.append((id(d), tuple(d.qpos)))

    def outputs(m: mujoco.MjModel, d: mujoco.MjData) -> SimpleNamespace:
        # The evaluations "read" after a step: the steps that MjData has taken.
        return SimpleNamespace(evaluated=sum(1 for i, _ in calls if i == id(d)))

    monkeypatch.setattr(bounds, "robot_spec", lambda name: mujoco.MjSpec.from_string(ARM))
    monkeypatch.setattr(bounds.mujoco, "mj_step", counted)
    monkeypatch.setattr(bounds, "plugin_outputs", outputs)
    row = bounds._robot("arm", 150.0, steps=50, block=20, skip=10)
    assert set(row) == {"alone_us", "auto_adds", "auto_evals", "150_adds", "150_evals"}
    assert row["alone_us"] > 0 and all(math.isfinite(v) for v in row.values())
    # The evaluations are averaged over the steps after the skip alone: steps 11 to 50.
    assert row["auto_evals"] == row["150_evals"] == 30.5
    # The run's last 150 calls (the pilot's own come before): blocks of 20, 20, 10 steps, the
    # order rotated by one model each block.
    run = calls[-150:]
    a, b, c = run[0][0], run[20][0], run[40][0]
    expected = [a] * 20 + [b] * 20 + [c] * 20 + [b] * 20 + [c] * 20 + [a] * 20
    expected += [c] * 10 + [a] * 10 + [b] * 10
    assert [i for i, _ in run] == expected and len({a, b, c}) == 3
    # Every model follows the same trajectory, step by step.
    paths = {d: [q for i, q in run if i == d] for d in (a, b, c)}
    assert paths[a] == paths[b] == paths[c] and len(paths[a]) == 50


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--robots", "no_such_robot"], "unknown robots no_such_robot; known: panda"),
        (["--skip", "3000"], "pass a skip from 0 to steps - 1"),
        (["--block", "0"], "--block 0: pass at least 1"),
        (["--accel", "nan"], "--accel nan: pass a finite bound >= 0"),
    ],
)
def test_bad_options_are_refused_with_the_fix(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as error:
        script("plugin_bounds").main(argv)
    assert error.value.code == 2
    assert message in capsys.readouterr().err
