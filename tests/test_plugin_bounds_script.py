"""benchmarks/plugin_bounds.py on an inline arm: every model steps the whole run, and a row holds
each bound's figures (no timing asserted)."""

from __future__ import annotations

import math

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
    steps: list[int] = []
    step = mujoco.mj_step

    def counted(m: mujoco.MjModel, d: mujoco.MjData) -> None:
        steps.append(id(d))
        step(m, d)

    monkeypatch.setattr(bounds, "robot_spec", lambda name: mujoco.MjSpec.from_string(ARM))
    monkeypatch.setattr(bounds.mujoco, "mj_step", counted)
    row = bounds._robot("arm", 150.0, steps=50, block=20, skip=10)
    assert set(row) == {"alone_us", "auto_adds", "auto_evals", "150_adds", "150_evals"}
    assert row["alone_us"] > 0 and all(math.isfinite(v) for v in row.values())
    assert row["auto_evals"] >= 0 and row["150_evals"] >= 0
    # The three models (alone, auto, 150) each step the whole run on their own MjData, besides
    # the pilot's steps on its own.
    run = steps[-150:]
    assert sorted(run.count(d) for d in set(run)) == [50, 50, 50]


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--robots", "no_such_robot"], "not installed"),
        (["--skip", "3000"], "need 0 <= skip < steps"),
        (["--block", "0"], "need 0 <= skip < steps and block >= 1"),
    ],
)
def test_bad_options_are_refused_with_the_fix(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as error:
        script("plugin_bounds").main(argv)
    assert error.value.code == 2
    assert message in capsys.readouterr().err
