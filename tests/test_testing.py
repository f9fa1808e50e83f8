"""Tests of ``dua_mujoco.testing``: the regression assertion, baselines and the pytest plugin."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import mujoco
import numpy as np
import pytest

from dua_mujoco.measure.report import RunReport
from dua_mujoco.models.scenes import load_scene, make_controller
from dua_mujoco.runtime.alarms import Alarms
from dua_mujoco.runtime.predictor import Predictor

# The module is imported here, before pytest registers it from ``pytest_plugins``: mark it for
# assertion rewriting first, or pytest warns that it was imported before it could rewrite it
# (unless another test module of the session imported it first).
if "dua_mujoco.testing" not in sys.modules:
    pytest.register_assert_rewrite("dua_mujoco.testing")

from dua_mujoco.build.options import ScheduleOptions
from dua_mujoco.testing import (
    BASELINE_KEYS,
    assert_no_missed_collisions,
    check_baseline,
    load_baseline,
    write_baseline,
)

pytest_plugins = ["pytester", "dua_mujoco.testing"]

ROOT = Path(__file__).resolve().parent.parent

# The paper world with 20 spheres collides often; out of contact each sphere's acceleration norm
# is at most sqrt(3) * 1 m/s^2 (its motors), so 2 m/s^2 is a bound that holds out of contact.
# Sphere-sphere impulses break it; the step then evaluates the pairs of both spheres again, so
# the floor contact that follows an impulse is flagged with the default schedule too (before
# violations were events, it went unflagged and these tests ran the paper's schedule).
SCENE = "paper_world:20"
ACCEL = 2.0
CLEAN = {"accel": ACCEL}
STEPS = 1000


def _scene() -> tuple[mujoco.MjModel, mujoco.MjData]:
    return load_scene(SCENE)


@pytest.fixture(scope="module")
def clean_report() -> RunReport:
    m, d = _scene()
    return assert_no_missed_collisions(m, d, steps=STEPS, predictor=CLEAN, scene=SCENE)


# --------------------------------------------------------------------------------------------------
# The assertion.
# --------------------------------------------------------------------------------------------------


def test_clean_scene_passes_through_the_fixture(dua_predict) -> None:
    m, d = _scene()
    report = dua_predict(m, d, steps=STEPS, predictor=CLEAN)
    assert report.contact_onsets > 0
    assert report.predicted_onsets == report.contact_onsets
    assert report.missed_onsets == 0
    assert report.scene == "paper_world_20"  # the model's name when none is given


def test_defaults_build_data_controller_and_predictor() -> None:
    m, _ = _scene()
    # data=None, controller=None, predictor=None: first keyframe, random controls, "auto" bounds.
    report = assert_no_missed_collisions(m, steps=300, scene="defaults")
    assert report.physics_steps == 300 and report.scene == "defaults"


def test_never_alarming_predictor_is_caught(monkeypatch: pytest.MonkeyPatch) -> None:
    """A predictor whose alarm horizons are all -1 never alarms: every onset is a valid miss.

    The paper's schedule alarms against its horizons only (the deadline schedule's standing
    alarms follow its due steps), so zeroing them silences it.
    """
    m, d = _scene()
    broken = Predictor(m, accel=ACCEL, schedule="dua")
    reset = broken.reset

    def reset_without_horizon(data: mujoco.MjData) -> Alarms:
        alarms = reset(data)
        assert broken.scheduler is not None
        broken.scheduler.state.horizon[:] = -1.0  # tau <= -1 never holds: no alarm, ever
        return alarms

    monkeypatch.setattr(broken, "reset", reset_without_horizon)
    with pytest.raises(AssertionError) as info:
        assert_no_missed_collisions(m, d, steps=STEPS, predictor=broken, scene=SCENE)
    msg = str(info.value)
    assert "not preceded by an alarm outside the period of a bound violation" in msg
    # Geom pairs are named: sphere-sphere or sphere-wall.
    named = re.findall(
        r"'(sphere\d+)' / '(sphere\d+|floor|ceiling|wall_[xy](?:neg|pos))' at t = ", msg
    )
    assert named, msg
    assert msg.splitlines()[0].startswith(f"{SCENE}: ")


def test_broken_bounds_fail_unless_allowed_and_events_recover_the_misses() -> None:
    """Declared bounds far too small: the run fails (free motion beyond them), with the fix in
    the message; ``allow_broken_bounds=True`` accepts it.

    two_arms with A = 0 breaks the bounds at most steps. With violations as events every pair
    of a body that broke them is evaluated again at that step, so no onset is missed; without
    them the same run misses onsets long after the violations, which the helper fails as bugs
    of the guarantee.
    """
    m, d = load_scene("two_arms")
    with pytest.raises(AssertionError, match="bounds were broken in free motion") as e:
        assert_no_missed_collisions(m, d, steps=STEPS, predictor={"accel": 0.0})
    assert "allow_broken_bounds=True" in str(e.value)
    assert "accel='auto'" in str(e.value)
    assert re.search(r"body 'a_link\d': accel [\d.]+ > bound 0 ", str(e.value)), str(e.value)
    m, d = load_scene("two_arms")
    report = assert_no_missed_collisions(
        m, d, steps=STEPS, predictor={"accel": 0.0}, allow_broken_bounds=True
    )
    assert report.bound_violations > 0 and report.contact_onsets > 0
    assert report.missed_onsets == 0
    m, d = load_scene("two_arms")
    without = {"accel": 0.0, "schedule": ScheduleOptions(violation_events=False)}
    with pytest.raises(AssertionError, match="outside the period of a bound violation"):
        assert_no_missed_collisions(m, d, steps=STEPS, predictor=without, allow_broken_bounds=True)


def test_broken_bounds_fail_even_without_a_miss() -> None:
    """Violations alone fail: the guarantee did not apply, however lucky the run was.

    paper_world:12 with A = v = 0.01 breaks its bounds thousands of times in 400 steps and,
    misses nothing (violations are events); the helper passed it before it judged violations.
    """
    m, d = load_scene("paper_world:12")
    bounds = {"accel": 0.01, "speed": 0.01}
    with pytest.raises(AssertionError, match="bounds were broken") as e:
        assert_no_missed_collisions(m, d, steps=400, predictor=bounds)
    msg = str(e.value)
    assert "none missed" in msg and "allow_broken_bounds=True" in msg
    assert re.search(r"body 'sphere\d+': (accel|speed) [\d.]+ > bound 0.01 ", msg), msg
    m, d = load_scene("paper_world:12")
    report = assert_no_missed_collisions(
        m, d, steps=400, predictor=bounds, allow_broken_bounds=True
    )
    assert report.bound_violations > 1000 and report.missed_onsets == 0
    assert report.contact_onsets > 0 and report.alarms_per_step is None


def test_contact_impulses_alone_do_not_fail(clean_report: RunReport) -> None:
    """Contacts break the bounds of the bodies they hit; that alone is expected and passes."""
    assert clean_report.bound_violations > 0
    assert clean_report.bound_violations_out_of_contact == 0


def test_scene_without_collidable_pairs_fails() -> None:
    m = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><freejoint/><geom size='.1' contype='0' conaffinity='0'/>"
        "</body><geom size='.1' pos='1 0 0'/></worldbody></mujoco>"
    )
    with (
        pytest.warns(UserWarning, match="never raise an alarm"),
        pytest.raises(AssertionError, match="would check nothing"),
    ):
        assert_no_missed_collisions(m, steps=10, predictor={"accel": 1.0})


def test_unknown_predictor_option_lists_the_valid_ones() -> None:
    m, d = _scene()
    with pytest.raises(
        ValueError, match=r"unknown keyword\(s\) \['acel'\]: the Predictor takes accel"
    ):
        assert_no_missed_collisions(m, d, steps=10, predictor={"acel": 2.0})


def test_data_of_another_model_is_refused() -> None:
    m, _ = _scene()
    _, other_data = load_scene("paper_world:3")
    with pytest.raises(ValueError, match="pass the MjData of this predictor's model"):
        assert_no_missed_collisions(m, other_data, steps=10, predictor=CLEAN)


def test_helpers_work_without_pytest() -> None:
    """docs/testing.md: without pytest, call the function directly."""
    code = (
        "import sys; sys.modules['pytest'] = None\n"
        "from dua_mujoco.models.scenes import load_scene\n"
        "from dua_mujoco.testing import assert_no_missed_collisions\n"
        f"m, d = load_scene({SCENE!r})\n"
        f"r = assert_no_missed_collisions(m, d, steps=50, predictor={CLEAN!r})\n"
        "print('OK', r.physics_steps)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["OK", "50"]


def test_predictor_of_another_model_is_refused() -> None:
    m, d = _scene()
    other, _ = load_scene("paper_world:3")
    with pytest.raises(ValueError, match="another MjModel"):
        assert_no_missed_collisions(m, d, steps=10, predictor=Predictor(other, accel=ACCEL))


def test_custom_controller_is_used() -> None:
    m, d = _scene()
    calls = []
    inner = make_controller(m, "zero")

    def controller(model: mujoco.MjModel, data: mujoco.MjData) -> None:
        calls.append(data.time)
        inner(model, data)

    assert_no_missed_collisions(m, d, steps=50, controller=controller, predictor=CLEAN)
    assert len(calls) == 51  # one before the reset step, then one per step


# --------------------------------------------------------------------------------------------------
# Baselines.
# --------------------------------------------------------------------------------------------------


def _counts(report: RunReport, scale: float = 1.0) -> dict[str, float]:
    return {k: getattr(report, k) * scale for k in BASELINE_KEYS}


def test_baseline_equal_and_within_tolerance_pass(clean_report: RunReport) -> None:
    assert clean_report.alarm_episodes > 10
    check_baseline(clean_report, _counts(clean_report))
    check_baseline(clean_report, _counts(clean_report, 1 / 1.2), tolerance=0.25)


def test_baseline_exceeded_fails_and_says_how_to_update(clean_report: RunReport) -> None:
    with pytest.raises(AssertionError) as info:
        check_baseline(clean_report, _counts(clean_report, 0.5), tolerance=0.25)
    msg = str(info.value)
    assert f"alarm_episodes = {clean_report.alarm_episodes} >" in msg
    # A dict baseline is the user's own literal: the fix is the measured counts to paste.
    assert f"'alarm_episodes': {clean_report.alarm_episodes}" in msg
    assert "--dua-update-baselines" not in msg


def test_file_baseline_exceeded_says_how_to_update(clean_report: RunReport, tmp_path: Path) -> None:
    path = tmp_path / "b.json"
    path.write_text(json.dumps(_counts(clean_report, 0.5)))
    with pytest.raises(AssertionError) as info:
        check_baseline(clean_report, path, tolerance=0.25)
    msg = str(info.value)
    assert "--dua-update-baselines" in msg and "write_baseline" in msg


def test_baseline_much_better_warns(clean_report: RunReport) -> None:
    with pytest.warns(UserWarning, match="fewer alarms than the baseline"):
        check_baseline(clean_report, _counts(clean_report, 2.0))


def test_baseline_file_round_trip(clean_report: RunReport, tmp_path: Path) -> None:
    path = write_baseline(clean_report, tmp_path / "nested" / "pw20.json")
    stored = json.loads(path.read_text())
    assert stored["alarm_episodes"] == clean_report.alarm_episodes
    assert stored["false_alarm_episodes"] == clean_report.false_alarm_episodes
    assert stored["scene"] == SCENE and stored["physics_steps"] == STEPS
    check_baseline(clean_report, path)
    check_baseline(clean_report, str(path))
    assert load_baseline(path) == stored


def test_missing_or_malformed_baseline(clean_report: RunReport, tmp_path: Path) -> None:
    with pytest.raises(AssertionError, match=r"no baseline at .*--dua-update-baselines"):
        check_baseline(clean_report, tmp_path / "absent.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        check_baseline(clean_report, bad)
    with pytest.raises(ValueError, match="false_alarm_episodes"):
        check_baseline(clean_report, {"alarm_episodes": 3})
    with pytest.raises(ValueError, match="tolerance"):
        check_baseline(clean_report, _counts(clean_report), tolerance=-0.1)


def test_assert_no_missed_collisions_compares_the_baseline() -> None:
    m, d = _scene()
    with pytest.raises(AssertionError, match="more alarms than the baseline allows"):
        assert_no_missed_collisions(
            m,
            d,
            steps=STEPS,
            predictor=CLEAN,
            baseline={"alarm_episodes": 1, "false_alarm_episodes": 0},
        )


# --------------------------------------------------------------------------------------------------
# The plugin, end to end in a child pytest session.
# --------------------------------------------------------------------------------------------------

USER_TEST = textwrap.dedent(
    f"""
    from dua_mujoco.models.scenes import load_scene


    def test_my_scene(dua_predict):
        model, data = load_scene("{SCENE}")
        report = dua_predict(
            model, data, steps=300, predictor={CLEAN!r}, baseline="baselines/pw.json"
        )
        assert report.contact_onsets > 0
    """
)


def test_plugin_baseline_update_and_compare(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_user=USER_TEST)
    baseline = pytester.path / "baselines" / "pw.json"

    # No baseline yet: the test fails and says how to record it.
    result = pytester.runpytest("-p", "dua_mujoco.testing")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*no baseline at*--dua-update-baselines*"])
    assert not baseline.exists()

    # Record it (relative to the test file's folder).
    result = pytester.runpytest("-p", "dua_mujoco.testing", "--dua-update-baselines")
    result.assert_outcomes(passed=1)
    stored = json.loads(baseline.read_text())
    assert set(BASELINE_KEYS) <= stored.keys()

    # Same run: within the baseline.
    pytester.runpytest("-p", "dua_mujoco.testing").assert_outcomes(passed=1)

    # A baseline the run exceeds: fails with the update hint.
    baseline.write_text(json.dumps({"alarm_episodes": 1, "false_alarm_episodes": 0}))
    result = pytester.runpytest("-p", "dua_mujoco.testing")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*more alarms than the baseline allows*"])
    result.stdout.fnmatch_lines(["*--dua-update-baselines*"])


def test_plugin_option_is_documented(pytester: pytest.Pytester) -> None:
    result = pytester.runpytest("-p", "dua_mujoco.testing", "--help")
    result.stdout.fnmatch_lines(["*--dua-update-baselines*"])


def test_plugin_records_counts_in_user_properties(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(
        test_props=textwrap.dedent(
            f"""
            from dua_mujoco.models.scenes import load_scene


            def test_props(dua_predict, request):
                model, data = load_scene("{SCENE}")
                report = dua_predict(model, data, steps=200, predictor={CLEAN!r})
                props = dict(request.node.user_properties)
                assert props["dua_alarm_episodes"] == report.alarm_episodes
                assert props["dua_contact_onsets"] == report.contact_onsets
            """
        )
    )
    pytester.runpytest("-p", "dua_mujoco.testing").assert_outcomes(passed=1)


def test_plugin_fixture_fails_on_missed_collision(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(
        test_broken=textwrap.dedent(
            f"""
            from dua_mujoco.runtime.predictor import Predictor
            from dua_mujoco.models.scenes import load_scene


            def test_broken(dua_predict):
                model, data = load_scene("{SCENE}")
                p = Predictor(model, accel={ACCEL}, schedule="dua")
                reset = p.reset

                def never_alarm(d):
                    out = reset(d)
                    p.scheduler.state.horizon[:] = -1.0
                    return out

                p.reset = never_alarm
                dua_predict(model, data, steps={STEPS}, predictor=p)
            """
        )
    )
    result = pytester.runpytest("-p", "dua_mujoco.testing")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*'sphere*' / '*' at t = *"])


def test_module_import_does_not_load_mujoco_layers() -> None:
    """The plugin is loaded in every pytest session of a project that enables it: it must not
    import MuJoCo or the predictor until a test uses it."""
    code = (
        "import sys, dua_mujoco.testing; "
        "print([m for m in ('mujoco', 'dua_mujoco.runtime.predictor', "
        "'dua_mujoco.measure.monitor') if m in sys.modules])"
    )
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        filter(None, [str(Path(__file__).resolve().parent.parent), env.get("PYTHONPATH")])
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env
    )
    assert out.stdout.strip() == "[]", out.stdout


def test_zero_baseline_allows_no_alarm(clean_report: RunReport) -> None:
    """A zero count stays zero whatever the (relative) tolerance."""
    assert clean_report.alarm_episodes > 0
    with pytest.raises(AssertionError, match="alarm_episodes"):
        check_baseline(
            clean_report, {"alarm_episodes": 0, "false_alarm_episodes": np.inf}, tolerance=10.0
        )


# --------------------------------------------------------------------------------------------------
# Other projects in the same environment.
# --------------------------------------------------------------------------------------------------

OTHER_PROJECT_TEST = "def test_trivial():\n    assert 1 + 1 == 2\n"


def _pytest_in(folder: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """``python -m pytest`` in ``folder`` (outside the repository), as another project runs it."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST")}
    env.pop("PYTHONPATH", None)
    argv = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-W", "default", *args]
    return subprocess.run(argv, capture_output=True, text=True, env=env, cwd=folder, timeout=300)


def test_another_projects_pytest_session_shows_no_warning(tmp_path: Path) -> None:
    """An editable install of the package (scikit-build-core's path finder, imported at start-up)
    made every pytest session in the environment warn ``Module already imported so cannot be
    rewritten; _editable_skbc_dua_mujoco`` while the package declared a pytest11 entry point."""
    assert not (tmp_path / "pyproject.toml").exists() and ROOT not in tmp_path.parents
    (tmp_path / "test_other.py").write_text(OTHER_PROJECT_TEST)
    out = _pytest_in(tmp_path)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "PytestAssertRewriteWarning" not in out.stdout + out.stderr
    assert re.fullmatch(r"=+ 1 passed in [\d.]+s =+", out.stdout.strip().splitlines()[-1])


def test_a_project_that_enables_the_plugin_gets_it_without_warning(tmp_path: Path) -> None:
    (tmp_path / "conftest.py").write_text('pytest_plugins = ["dua_mujoco.testing"]\n')
    (tmp_path / "test_mine.py").write_text(
        "def test_fixture(dua_predict):\n    assert callable(dua_predict)\n"
    )
    out = _pytest_in(tmp_path)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "warning" not in out.stdout.lower(), out.stdout
    assert re.fullmatch(r"=+ 1 passed in [\d.]+s =+", out.stdout.strip().splitlines()[-1])
