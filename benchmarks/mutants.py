"""The mutation check (issue 43): small changes to the lines the promise rests on, each of which
the tests listed with it must catch.

    python benchmarks/mutants.py                   # every mutant (docs/testing.md: the time)
    python benchmarks/mutants.py tau-accel-halved  # only these
    python benchmarks/mutants.py --list            # the list, with the tests of each

Each mutant replaces one piece of text of one file (native or Python) by another. The check
copies the working tree (tracked and new files) to a scratch folder, builds its native core
there with CMake (its own build folder: the developer's install is never touched), runs the
mutant's tests once on the unmutated copy (they must pass), then, for each mutant: applies it,
rebuilds, runs its tests, reverts it. A mutant is *killed* when its tests fail (or time out),
*survived* when they pass, *stale* when its text no longer occurs exactly once in its file (the
code moved on: aim it again), *broken* when it does not build. The exit status is 1 unless every
mutant is killed.

The scratch copy's package is imported instead of the installed one: a ``sitecustomize`` on
``PYTHONPATH`` takes the editable install's import hook out of ``sys.meta_path`` in every
process (pytest's workers too), so ``dua_mujoco`` resolves to the copy, which holds its own
``libdua_mujoco.so`` and ``_core``.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Mutant:
    """One small change and the tests that must catch it.

    Attributes:
        name: What it breaks, in a few words.
        path: The file, relative to the checkout.
        old: Text that occurs exactly once in it.
        new: What replaces it.
        tests: pytest node ids (files, or ``file::test``) that must fail with it.
        why: The promise it breaks.
    """

    name: str
    path: str
    old: str
    new: str
    tests: tuple[str, ...]
    why: str

    @property
    def native(self) -> bool:
        """Whether it needs a rebuild."""
        return self.path.startswith("dua_mujoco/csrc/")


_URGENCY = "dua_mujoco/csrc/src/urgency.cc"
_STEP = "dua_mujoco/csrc/src/step.cc"
_RUNTIME = "dua_mujoco/csrc/src/runtime.cc"
_SCHEDULE = "dua_mujoco/csrc/src/schedule.cc"
_SCHEDULE_H = "dua_mujoco/csrc/src/schedule.h"
_PLAN = "dua_mujoco/csrc/src/plan.cc"
_FLIGHTPLAN = "dua_mujoco/runtime/flightplan.py"
_KINEMATICS = "dua_mujoco/csrc/src/kinematics.cc"
_KINEMATICS_H = "dua_mujoco/csrc/src/kinematics.h"
_KNOTS = "tests/test_knot_kinematics.py"
_PLUGIN = "dua_mujoco/csrc/src/plugin.cc"
_TABLES = "dua_mujoco/csrc/src/tables.cc"
_STATIC_EDITS = "tests/test_static_edits.py"
_INTERNAL = "dua_mujoco/csrc/src/internal.h"
_LANES = "dua_mujoco/csrc/src/lanes.h"
_TERRAIN = "dua_mujoco/csrc/src/terrain.cc"
_SHIELD = "dua_mujoco/csrc/src/shield.cc"
_SHIELD_EPISODES = "tests/test_shield.py::test_every_protected_contact_finds_the_robot_at_rest"
_HOLD_EDGE = "tests/test_shield.py::test_a_held_robot_breaks_its_hold_one_ulp_past_rest_speed"
_SMALL_BOUNDS = (
    "tests/test_events.py::test_the_checks_lanes_judge_bounds_below_their_squares_underflow"
)
_GRID_STEPS = (
    "tests/test_warning_time.py::test_the_grid_counts_no_step_past_the_first_state_it_can_touch_at"
)
_TWO_HULLS = (
    "tests/test_exact.py::"
    "test_between_two_hulls_a_look_settles_only_where_the_two_pairs_of_points_allow"
)
_MADE_DUE = (
    "tests/test_scheduler.py::test_made_due_pairs_are_selected_as_make_due_then_select_selects_them"
)
_SETTLE_BOUND = "tests/test_urgency.py::test_settle_bound_is_never_after_the_first_root"
_LANE_PAIRS = (
    "tests/test_predictor.py::test_fused_steps_sphere_lanes_are_the_row_kernels_bit_for_bit"
)
_SETTLED = (
    "tests/test_events.py::test_settled_pairs_get_a_verdict_of_that_step_below_the_sphere_kernels"
)
_SETTLED_STANDING = "tests/test_alarms.py::test_settled_pairs_neither_stood_nor_stand"
_REF = (
    "tests/test_reference_step.py::"
    "test_tau_is_never_later_than_a_feasible_contact_and_those_within_the_horizon_stand"
)
_REF_TRAFFIC, _REF_PAPER = f"{_REF}[traffic]", f"{_REF}[paper_world]"
_REF_CLUTTER, _REF_ARMS = f"{_REF}[clutter]", f"{_REF}[two_arms]"
_RELATIVE = "tests/test_plan_relative.py"
_SCREEN = "tests/test_wheel_screen.py::"
_SCREEN_BOUNDARY = (
    _SCREEN + "test_the_screen_at_its_boundary_clears_only_what_the_model_keeps_apart"
)
_SCREEN_RANDOM = _SCREEN + "test_the_screen_never_clears_a_pair_that_can_touch_within_h"
_SCREEN_REFERENCE = (
    "tests/test_reference_step.py::test_screened_verdicts_are_never_later_than_a_feasible_contact"
)
_SCREEN_INVARIANT = _SCREEN + "test_every_active_pair_is_on_the_wheel_or_the_screen"
_SCREEN_WATCH = _SCREEN + "test_no_pair_is_screened_while_the_runtime_watches_or_off_the_grid"
_SCREEN_PLAN = _SCREEN + "test_no_pair_the_plan_revisits_soon_is_screened"
_SCREEN_REFUSALS = _SCREEN + "test_the_screen_leaves_what_it_cannot_judge_to_the_kernel"
_ROUNDING = "tests/test_plan_rounding.py"
_PYRAMID = "tests/test_terrain.py::test_search_equals_every_cell_through_the_pyramid_for_a_sphere"
_CHECKS = "dua_mujoco/csrc/src/checks.cc"
_SCREEN = "tests/test_monitor_screen.py"

MUTANTS: tuple[Mutant, ...] = (
    # ---------------------------------------------------------------- tau kernels (section 1)
    Mutant(
        "tau-accel-halved",
        _URGENCY,
        "p.h = 0.5 * bound * (1.0 + kKappa);",
        "p.h = 0.25 * bound * (1.0 + kKappa);",
        ("tests/test_urgency.py::test_random_against_reference", _REF_PAPER),
        "the sphere kernel's reachable ball grows half as fast: tau too late",
    ),
    Mutant(
        "tau-interior-root-skipped",
        _URGENCY,
        "    if (Predicate(x, v, e, d, h, ta) <= 0.0) return Refine(x, v, e, d, h, 0.0, ta);\n",
        "",
        ("tests/test_urgency.py::test_exact_dyadic_tangency", _REF_TRAFFIC),
        "a first root before g's interior minimum is skipped for a later one",
    ),
    Mutant(
        "g1root-capped-at-200",
        _URGENCY,
        "constexpr int kG1MaxIter = 2200;",
        "constexpr int kG1MaxIter = 200;",
        ("tests/test_urgency.py::test_tiny_accelerations_never_late",),
        "g's interior minimum is located by a search that stops before its bracket closes, past "
        "the minimum under tiny bounds: the first root is skipped",
    ),
    Mutant(
        "accel-floor-dropped",
        _URGENCY,
        "Select(And(0.0 < accel, accel < kAccelFloor), T{} + kAccelFloor, accel);",
        "Select(And(0.0 < accel, accel < 0.0), T{} + kAccelFloor, accel);",
        (
            "tests/test_urgency.py::test_one_problem_at_tiny_scales_never_late",
            "tests/test_urgency.py::test_a_slow_pair_under_a_tiny_bound_never_late",
        ),
        "a bound whose h^2 v^2 underflows is solved as it is: g's interior minimum is missed "
        "and the bracket holds three roots",
    ),
    Mutant(
        "settle-accel-floor-dropped",
        _INTERNAL,
        "const double bound = 0.0 < accel && accel < kAccelFloor ? kAccelFloor : accel;",
        "const double bound = 0.0 < accel && accel < 0.0 ? kAccelFloor : accel;",
        ("tests/test_urgency.py::test_settle_bound_stays_below_the_kernel_under_tiny_bounds",),
        "the settling bound keeps a bound the kernel raises: a pair settled for longer than an "
        "evaluation would give it",
    ),
    Mutant(
        "unread-predicate-says-never",
        _URGENCY,
        "      // 1.3e154): no time past start is certified.\n      return start;",
        "      // 1.3e154): no time past start is certified.\n      return kInf;",
        ("tests/test_urgency.py::test_norms_past_the_squares_range_give_zero",),
        "a first root the predicate could not read (x + v t past 1.3e154 m) is reported never",
    ),
    Mutant(
        "tau-certified-bracket-top",
        _URGENCY,
        "HalleyGuess(x, v, e, d, h, lo, hi, true), &tl)) return tl;",
        "HalleyGuess(x, v, e, d, h, lo, hi, true), &tl)) return tl * (1.0 + kRtol);",
        ("tests/test_urgency.py::test_random_against_reference",),
        "the scalar refinement returns the top of its certified bracket, past the root by up "
        "to 1e-13",
    ),
    Mutant(
        "halfspace-accel-halved",
        _URGENCY,
        "const double a = accel * (1.0 + kKappa);",
        "const double a = 0.5 * accel * (1.0 + kKappa);",
        ("tests/test_urgency.py::test_halfspace_random_against_reference", _REF_ARMS),
        "planes, static shapes and the exact level see half the acceleration",
    ),
    Mutant(
        "speed-term-doubled",
        _URGENCY,
        "    tau = std::max(tau, ts);",
        "    tau = std::max(tau, 2.0 * ts);",
        ("tests/test_urgency.py::test_speed_between_max_formula_and_lens", _REF_PAPER),
        "the speed bound's term claims twice the time",
    ),
    Mutant(
        "lane-pairs-fallback-dropped",
        _STEP,
        "if (left != 0) TauSpeedFourPairsLeft(",
        "if (left < 0) TauSpeedFourPairsLeft(",
        (_LANE_PAIRS,),
        "the step's sphere pairs off the lanes' common path (A = 0, an interior minimum, an "
        "uncertified guess) keep whatever tau the wheel's work row held: no scalar fallback",
    ),
    Mutant(
        "lane-pairs-written-in-lane-order",
        _URGENCY,
        "for (int k = 0; k < kLanes; ++k) out[at[k]] = tau[k];",
        "for (int k = 0; k < kLanes; ++k) out[at[0] + k] = tau[k];",
        ("tests/test_predictor.py::test_fused_steps_sphere_lanes_write_each_pairs_own_place",),
        "the step's four sphere pairs' taus written to the four places from the first one's, not "
        "the pairs' own: where a half-space pair sits inside the group, it and the pairs after "
        "take another's tau",
    ),
    Mutant(
        "lane-pairs-padding-written-over-the-first",
        _STEP,
        "pr[k] = pr[np - 1], pat[k] = pat[np - 1];",
        "pr[k] = pr[np - 1], pat[k] = pat[0];",
        (_LANE_PAIRS,),
        "a ragged group's padding lanes (the last pair repeated) write their tau to the group's "
        "first pair's place, not the last one's: the first pair takes the last one's tau",
    ),
    Mutant(
        "lane-pairs-bounds-transposed-wrong",
        _URGENCY,
        "const Lanes eps = c[0], accel = c[1], delta = c[2], speed = c[3];",
        "const Lanes eps = c[0], accel = c[2], delta = c[2], speed = c[3];",
        (_LANE_PAIRS,),
        "the four pair records' bounds transposed wrong: the step's sphere lanes read the "
        "velocity uncertainty as the acceleration bound",
    ),
    # ---------------------------------------------------------------- the step: state, exact level
    Mutant(
        "point-velocity-cross-sign",
        "dua_mujoco/csrc/src/internal.h",
        "out[3] = tw[3] + tw[1] * dz - tw[2] * dy;",
        "out[3] = tw[3] - tw[1] * dz + tw[2] * dy;",
        ("tests/test_kinematics.py", _REF_ARMS),
        "a rotating body's point velocity read with the wrong sign (x)",
    ),
    Mutant(
        "exact-rotation-term-dropped",
        _STEP,
        "const double vn = n0 * r0 + n1 * r1 + n2 * r2 - spin;",
        "const double vn = n0 * r0 + n1 * r1 + n2 * r2;",
        ("tests/test_exact.py::test_the_rotation_term_is_needed", _REF_ARMS),
        "the exact level forgets that rotation moves a geom's points (5.3)",
    ),
    Mutant(
        "exact-contact-skip-widened",
        _STEP,
        "    if (same && c.dist <= dist) return true;",
        "    if (same) return true;",
        (
            "tests/test_exact.py::test_a_pair_in_mujocos_contacts_keeps_its_sphere_tau_and_no_other_pair_does",
        ),
        "a pair MuJoCo lists beyond its contact distance is not looked at (a looser skip is "
        "safe, but the test pins the rule)",
    ),
    Mutant(
        "two-point-bound-second-pair-still",
        _STEP,
        "w2[j] = b[j] - a[j] + r[j];",
        "w2[j] = b[j] - a[j];",
        (_TWO_HULLS,),
        "the hull vertices' pair is read without the pair's motion over the horizon (more "
        "alarms stand, none is missed)",
    ),
    Mutant(
        "two-point-bound-weight-unclamped",
        _STEP,
        "const double lambda = dd > 0.0 ? std::min(1.0, std::max(0.0, along / dd)) : 1.0;",
        "const double lambda = dd > 0.0 ? along / dd : 1.0;",
        (_TWO_HULLS,),
        "the nearest point of the line through the two pairs' differences, beyond the segment "
        "(more alarms stand, none is missed)",
    ),
    Mutant(
        "pair-accel-one-body",
        "dua_mujoco/csrc/src/pairs.cc",
        "out_accel[p] = accel[b1] + accel[b2];",
        "out_accel[p] = std::max(accel[b1], accel[b2]);",
        (_REF_PAPER,),
        "a pair's acceleration bound is one body's, not the sum of both",
    ),
    Mutant(
        "delta-dropped",
        "dua_mujoco/build/bounds.py",
        "            delta += discrete_velocity_uncertainty(model, A, velocity_accel=C)",
        "            delta += 0.0 * discrete_velocity_uncertainty(model, A, velocity_accel=C)",
        ("tests/test_bounds.py::test_declare_scalar_static_bodies_zero", _REF_PAPER),
        "declared bounds without the discrete-time velocity uncertainty",
    ),
    Mutant(
        "covering-radius-shrunk",
        "dua_mujoco/build/covering.py",
        "    one = (np.zeros((1, 3)), np.array([rbound]))",
        "    one = (np.zeros((1, 3)), np.array([0.95 * rbound]))",
        ("tests/test_covering.py",),
        "a bounding sphere a little smaller than its geom",
    ),
    # ---------------------------------------------------------------- schedules (sections 2, 3)
    Mutant(
        "dua-revisit-halved",
        _SCHEDULE,
        "const int64_t first = (n * q) % size;",
        "const int64_t first = (n * q / 2) % size;",
        ("tests/test_scheduler.py::test_matches_reference_and_revisits_exactly",),
        "the rank schedule revisits each slot half as often as its alarm rule assumes",
    ),
    Mutant(
        "deadline-interval-one-late",
        _SCHEDULE,
        "return static_cast<double>(s + latency) * dt + extra < tau; };",
        "return static_cast<double>(s + latency - 1) * dt + extra < tau; };",
        (
            "tests/test_scheduler.py::test_deadline_interval_is_the_latest_safe_step",
            "tests/test_completeness.py::test_deadline_flags_every_onset",
        ),
        "a pair waits one step longer than its verdict covers (3)",
    ),
    Mutant(
        "reinsert-lanes-cover-not-strict",
        _SCHEDULE,
        "const LaneMask covered = (s + lat) * dt + extra < tau;",
        "const LaneMask covered = (s + lat) * dt + extra <= tau;",
        ("tests/test_scheduler.py::test_reinsert_waits_are_the_deadline_interval",),
        "the reinsertion's lanes keep a wait its verdict covers only up to tau itself (3)",
    ),
    Mutant(
        "reinsert-lanes-fallback-dropped",
        _SCHEDULE,
        "    if (left != 0) {\n      for (int j = 0; j < m; ++j) {",
        "    if (left != 0 && false) {\n      for (int j = 0; j < m; ++j) {",
        ("tests/test_scheduler.py::test_reinsert_waits_are_the_deadline_interval",),
        "the reinsertion's lanes keep their guess where the scalar loops would step from it (3)",
    ),
    Mutant(
        "reinsert-lanes-rounded-up",
        _SCHEDULE,
        "ints = ints - magic_bits + up;",
        "ints = ints - magic_bits;",
        ("tests/test_scheduler.py::test_reinsert_waits_are_the_deadline_interval",),
        "the reinsertion's lanes link a pair one step past the wait they tested (3)",
    ),
    Mutant(
        "tau-nan-passed-off-the-grid",
        _STEP,
        "      out[k] = std::isnan(t) ? 0.0 : t;",
        "      out[k] = t;",
        ("tests/test_hardening.py::test_a_tau_that_is_not_a_number_alarms",),
        "off the predictor's grid a tau that is not a number is passed on: it neither alarms nor "
        "gets a wait of its own (docs/hardening.md)",
    ),
    Mutant(
        "alarm-test-strict",
        _SCHEDULE,
        "inline bool Alarms(double tau, double horizon) { return tau <= horizon; }",
        "inline bool Alarms(double tau, double horizon) { return tau < 0.5 * horizon; }",
        ("tests/test_scheduler.py::test_alarm_rule",),
        "the alarm rule against half the horizon",
    ),
    Mutant(
        "stands-one-period-short",
        _SCHEDULE_H,
        "      return static_cast<double>(where - last + spec_.latency) * spec_.dt + Extra();",
        "      return static_cast<double>(where - last + spec_.latency - 1) * spec_.dt + Extra();",
        (_REF_CLUTTER,),
        "the standing state covers one period less than the wait",
    ),
    Mutant(
        "deferral-stands-short",
        _SCHEDULE,
        "static_cast<double>(where[p] - last_step[p] + latency) * dt + st->extra)) {",
        "static_cast<double>(where[p] - last_step[p] + latency - 1) * dt + st->extra)) {",
        ("tests/test_scheduler.py::test_deadline_matches_reference",),
        "a deferred pair is reported standing one step too few",
    ),
    # ---------------------------------------------------------------- violations (section 6)
    Mutant(
        "violation-accel-doubled",
        _STEP,
        "const T b_accel = prev[kSAccel] * (1.0 + rtol) + tol_a;",
        "const T b_accel = 2.0 * prev[kSAccel] * (1.0 + rtol) + tol_a;",
        ("tests/test_events.py::test_step_flags_the_bodies_the_bound_monitor_flags",),
        "the step's check lets accelerations up to twice the bound pass",
    ),
    Mutant(
        "check-first-test-without-accel",
        _STEP,
        "if (nprev >= 2) open = Or(open, Not(passes(n_accel, b_accel)));",
        "(void)b_accel;",
        ("tests/test_events.py::test_a_body_that_breaks_its_acceleration_bound_alone_is_flagged",),
        "the check's common path (every screen's first test passes) forgets the acceleration's: "
        "a body that breaks only its acceleration bound is flagged only when another screen opens",
    ),
    Mutant(
        "check-first-test-unscaled",
        _STEP,
        "return And(4.0 * n <= bound * bound, Not(bound < 1e-139));",
        "return And(n <= bound * bound, Not(bound < 1e-139));",
        ("tests/test_events.py::test_step_flags_the_bodies_the_bound_monitor_flags",),
        "the check's common path passes a body on its vectors' squared norms without the factor "
        "4 that bounds the largest corner (|a| + |x| + |y| + |z|)^2 <= 4 (na + nx + ny + nz)",
    ),
    Mutant(
        "check-lanes-transposed-wrong",
        _LANES,
        "c[1] = __builtin_shufflevector(hi01, hi23, 0, 1, 4, 5);",
        "c[1] = __builtin_shufflevector(lo01, lo23, 2, 3, 6, 7);",
        ("tests/test_events.py::test_the_checks_lanes_equal_one_body_at_a_time",),
        "the lanes' 4 x 4 transpose (lanes.h: the four-body check's runs of four, the sphere "
        "lanes' bounds, the relative nesting's blocks) puts a block's third column in its second",
    ),
    Mutant(
        "check-small-bounds-first-lane-only",
        _STEP,
        "for (int k = 0; k < LaneCount<T>(); ++k) {",
        "for (int k = 0; k < 1; ++k) {",
        (_SMALL_BOUNDS,),
        "the four-body check rescans only its first lane for a bound below 1e-139: another "
        "body's chord whose squares underflow passes a bound it breaks",
    ),
    Mutant(
        "check-small-bounds-threshold-lowered",
        _STEP,
        "const MaskOf<T> small = bound < 1e-139;",
        "const MaskOf<T> small = bound < 1e-300;",
        (_SMALL_BOUNDS,),
        "the check rescans only bounds below 1e-300: a chord of 1e-162 (its squares 0) passes a "
        "bound of 1e-173",
    ),
    Mutant(
        "settle-under-a-plan",
        _STEP,
        "const bool settles = flagged > 0 && bounds_only;",
        "const bool settles = flagged > 0;",
        ("tests/test_flightplan.py::test_no_pair_is_settled_while_a_plan_is_set",),
        "a flagged body's pairs settled by the motion bounds' norms while a plan is set",
    ),
    Mutant(
        "violation-not-made-due",
        _STEP,
        "dua::SelectMadeDue(st, ev.flagged, flagged, ev.start, ev.members, n,",
        "dua::SelectMadeDue(st, ev.flagged, 0 * flagged, ev.start, ev.members, n,",
        (
            "tests/test_events.py::test_a_collision_right_after_an_impulse_is_flagged_only_with_events",
        ),
        "a flagged body's pairs keep the verdicts the impulse broke until they fall due",
    ),
    Mutant(
        "made-due-selected-twice",
        _SCHEDULE,
        "if (at == kTaken || at == dua::kScreened || (at < 0 && !active[p])) continue;",
        "if (at == dua::kScreened || (at < 0 && !active[p])) continue;",
        (_MADE_DUE,),
        "a pair of two flagged bodies is evaluated twice and linked twice into the wheel",
    ),
    Mutant(
        "made-due-order-reversed",
        _SCHEDULE,
        "for (int64_t j = start[g + 1] - 1; j >= start[g]; --j) {",
        "for (int64_t j = start[g]; j < start[g + 1]; ++j) {",
        (_MADE_DUE,),
        "the flagged pairs reach the kernel in another order than make_due's (the four-lane "
        "groups, and so the alarms, are not main's bit for bit)",
    ),
    Mutant(
        "settle-without-speed",
        _INTERNAL,
        "const double gap = nx - e, b = nv + d;",
        "const double gap = nx - e, b = d;",
        (_SETTLE_BOUND, _SETTLED),
        "a flagged body's pair is settled by a bound that ignores how fast it approaches "
        "(Lemma 6.8 without |v| t)",
    ),
    Mutant(
        "settle-without-accel",
        _INTERNAL,
        "const double q = b * b + 4.0 * h * gap;",
        "const double q = b * b + 0.0 * h * gap;",
        (_SETTLE_BOUND, _SETTLED),
        "a flagged body's pair is settled by a bound that ignores the acceleration bound "
        "(Lemma 6.8 without A t^2 / 2)",
    ),
    Mutant(
        "settle-cover-without-accel",
        _INTERNAL,
        "if (gap - t2 * (b + h * t2) > 0.0) return cover * (1.0 + kSettleKappa);",
        "if (gap - t2 * b > 0.0) return cover * (1.0 + kSettleKappa);",
        (_SETTLE_BOUND, _SETTLED),
        "a flagged body's pair keeps its due step on a cover test that ignores the acceleration "
        "bound (Lemma 6.8' without A t^2 / 2)",
    ),
    Mutant(
        "settle-underflowed-norms",
        _INTERNAL,
        "if (!(nx >= 1e-100) || (nv < 1e-100 && (v0 != 0.0 || v1 != 0.0 || v2 != 0.0))) {",
        "if (!(nx >= 0.0)) {",
        (_SETTLE_BOUND,),
        "the settling bound computed from norms whose squares underflow (|x| 41 % long, a |v| "
        "of 1e-170 read as 0)",
    ),
    Mutant(
        "settle-kept-after-a-failed-step",
        _SCHEDULE,
        "for (int64_t k = 0; k < st->params[kSettled]; ++k) {",
        "for (int64_t k = 0; k < 0; ++k) {",
        (
            "tests/test_events.py::"
            "test_a_step_retried_after_it_failed_judges_the_pairs_it_had_settled_again",
        ),
        "a failed step's settled verdicts kept: its retry leaves those pairs alone",
    ),
    Mutant(
        "exact-hull-address-unread",
        "dua_mujoco/csrc/src/tables.cc",
        "if (kind == -1.0) return no_hull;",
        "if (kind == -1.0) return true;",
        (
            "tests/test_tables.py::"
            "test_a_hull_address_on_a_geom_without_a_hull_is_refused[clutter--1.0]",
        ),
        "a geom the exact level does not read passes with a hull address, which the hulls' "
        "pass then uses as an index (the tables fuzzer's finding)",
    ),
    Mutant(
        "climb-row-last-neighbour-dropped",
        "dua_mujoco/csrc/src/tables.cc",
        "t->climb.push_back(entry(k, e - first));",
        "t->climb.push_back(entry(k, e - first - 1));",
        ("tests/test_exact.py::test_the_climb_over_a_dense_hull_reaches_the_reference_support",),
        "each hull vertex's climb row counts one neighbour fewer: a climb can stop below the top "
        "(a support too low, a gap too large)",
    ),
    Mutant(
        "climb-row-neighbours-at-the-vertex",
        "dua_mujoco/csrc/src/tables.cc",
        "for (e = first; *e >= 0; ++e) t->climb.push_back(entry(*e, *e));",
        "for (e = first; *e >= 0; ++e) t->climb.push_back(entry(k, *e));",
        ("tests/test_exact.py::test_the_climb_over_a_dense_hull_reaches_the_reference_support",),
        "a climb row's neighbours carry the vertex's own coordinates: no neighbour is ever "
        "higher, and the climb stays at its start",
    ),
    Mutant(
        "climb-row-not-followed",
        _STEP,
        "    v = x.climb + row[imax];",
        "    (void)row;",
        ("tests/test_exact.py::test_the_climb_over_a_dense_hull_reaches_the_reference_support",),
        "after a move the climb scans the row it left, not the vertex it reached: it stops one "
        "move from its start (a support too low, a gap too large)",
    ),
    Mutant(
        "hull-top-point-mirrored",
        _STEP,
        "const double local[3] = {v.x, v.y, v.z};",
        "const double local[3] = {v.x, v.y, -v.z};",
        (_TWO_HULLS,),
        "the hull vertex a climb reached is read mirrored, a point outside the geom: the "
        "two-point bound can clear an alarm that a query would not",
    ),
    Mutant(
        "escape-speed-loose",
        "dua_mujoco/csrc/src/reach.cc",
        "const double top = std::min(s0 + a * t, vmax - d);",
        "const double top = std::min(s0 + 2.0 * d + a * t, vmax - d);",
        ("tests/test_spheres.py::test_escape_test_keeps_passing_spheres_inside_their_reach",),
        "the escape test of the earlier release (Lemma 6.4's speed test loosened by 2 delta)",
    ),
    Mutant(
        "pruned-stride-without-the-lead",
        "dua_mujoco/csrc/src/tables.cc",
        "if (stride * s.dt + lead > horizon + 1e-9 * s.dt) {",
        "if (stride * s.dt > horizon + 1e-9 * s.dt) {",
        ("tests/test_spheres.py::test_a_horizon_shortened_by_one_step_is_refused[1]",),
        "tables whose stride the reach's horizon covers without the latency and alarm horizon pass",
    ),
    # ---------------------------------------------------------------- the filter
    Mutant(
        "filter-bitmask-both-ways",
        "dua_mujoco/csrc/src/filter.cc",
        "(f.contype[g1] & f.conaffinity[g2]) == 0 && (f.contype[g2] & f.conaffinity[g1]) == 0",
        "(f.contype[g1] & f.conaffinity[g2]) == 0 || (f.contype[g2] & f.conaffinity[g1]) == 0",
        ("tests/test_pairs.py::test_filter_rules_spelled_out",),
        "a pair MuJoCo collides one way round only is filtered out",
    ),
    # ---------------------------------------------------------------- flight plans (section 8)
    Mutant(
        "plan-check-never-breaks",
        _PLAN,
        "BoxWithin(box, pos + 3 * g, mat + 9 * g, this->pos(k, g), this->mat(k, g), dev(k, b))",
        "BoxWithin(box, pos + 3 * g, mat + 9 * g, this->pos(k, g), this->mat(k, g), kInf)",
        (
            "tests/test_hardening.py::test_a_plan_from_c_is_refused_by_its_value_and_huge_deviations_run",
        ),
        "a body beyond its deviation keeps following the plan",
    ),
    Mutant(
        "plan-check-twice-the-deviation",
        _PLAN,
        "BoxWithin(box, pos + 3 * g, mat + 9 * g, this->pos(k, g), this->mat(k, g), dev(k, b))",
        "BoxWithin(box, pos + 3 * g, mat + 9 * g, this->pos(k, g), this->mat(k, g), "
        "2.0 * dev(k, b))",
        ("tests/test_flightplan.py::test_a_body_strayed_past_its_deviation_breaks_its_plan",),
        "a body strays up to twice its deviation before its plan breaks",
    ),
    Mutant(
        "plan-check-rotation-dropped",
        _PLAN,
        "bound += Sqrt(column) * qmax[j];",
        "bound += 0.0 * Sqrt(column) * qmax[j];",
        ("tests/test_flightplan.py::test_a_turn_alone_past_the_deviation_breaks_its_plan",),
        "a body that turns away from its planned pose without moving its origin keeps the plan",
    ),
    Mutant(
        "plan-tau-one-knot-late",
        _PLAN,
        "    if (!(gap > allow)) return j;",
        "    if (!(gap > allow)) return j + 1;",
        (
            "tests/test_flightplan.py::test_the_plans_tau_is_never_above_the_reference_and_is_mostly_equal",
        ),
        "a plan's tau one knot after the first knot that may touch",
    ),
    Mutant(
        "plan-walk-search-trusts-the-last-knot",
        _PLAN,
        "    if (skip(n - 1)) return n;",
        "    return n;",
        (
            "tests/test_flightplan.py::test_the_plans_tau_is_never_above_the_reference_and_is_mostly_equal",
            f"{_RELATIVE}::test_a_walks_search_stops_at_the_first_knot_a_rising_deviation_reaches",
        ),
        "a walk's search takes every knot left for cleared once the first after its base is, "
        "without asking the last",
    ),
    Mutant(
        "plan-walk-search-asks-the-knot-before-the-last",
        _PLAN,
        "    if (skip(n - 1)) return n;",
        "    if (skip(n - 2)) return n;",
        (f"{_RELATIVE}::test_a_walks_search_stops_at_the_first_knot_a_rising_deviation_reaches",),
        "a walk's search takes the plan's last knot for cleared when the one before it is (a "
        "contact first possible at the last knot passed over)",
    ),
    Mutant(
        "plan-deviation-dropped",
        _PLAN,
        "const double sum = (plan.dev(j, b1) + plan.dev(j, b2)) * (1.0 + 4.0 * kEpsilon);",
        "const double sum = 0.0 * (plan.dev(j, b1) + plan.dev(j, b2));",
        (
            "tests/test_flightplan.py::test_the_plans_tau_is_never_above_the_reference_and_is_mostly_equal",
        ),
        "a plan's verdicts without the deviations",
    ),
    Mutant(
        "plan-relative-not-checked",
        _PLAN,
        "    if (!RelativePoseWithin(rel_box_[r], rel_reach_[r], actual, rel_pose(k, r), "
        "rel_dev(k, r))) {",
        "    if (false && !RelativePoseWithin(rel_box_[r], rel_reach_[r], actual, rel_pose(k, r),\n"
        "                                     rel_dev(k, r))) {",
        (
            f"{_RELATIVE}::test_a_fold_beyond_the_relative_deviation_is_a_plan_break",
            f"{_RELATIVE}::test_the_monitor_labels_an_onset_after_a_relative_break_as_not_held",
        ),
        "a pair beyond its relative deviation goes unseen: its verdicts keep the relative bound",
    ),
    Mutant(
        "plan-relative-in-the-world-frame",
        _PLAN,
        "  const double d[3] = {pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]};",
        "  std::copy_n(pb, 3, pos), std::copy_n(rb, 9, mat);\n  return;\n"
        "  const double d[3] = {pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]};",
        (
            f"{_RELATIVE}::test_the_actual_distance_is_never_below_the_planned_one_less_the_relative_deviation",
            f"{_RELATIVE}::test_a_plan_off_in_the_swing_keeps_the_relative_pose_and_frees_the_pair",
        ),
        "the relative deviation measured as b's own, in the world frame",
    ),
    Mutant(
        "plan-relative-alone-not-the-min",
        _PLAN,
        "return r >= 0 ? std::min(sum, plan.rel_dev(j, r) * (1.0 + 4.0 * kEpsilon)) : sum;",
        "return r >= 0 ? plan.rel_dev(j, r) * (1.0 + 4.0 * kEpsilon) : sum;",
        (f"{_RELATIVE}::test_a_relative_deviation_above_the_sum_changes_no_verdict",),
        "a pair's gap less its relative deviation alone, however far above the sum",
    ),
    Mutant(
        "monitor-relative-basis-dropped",
        "dua_mujoco/measure/warning_time.py",
        "        relative = ((basis >> 2) & 1).astype(np.uint8)",
        "        relative = ((basis >> 2) & 0).astype(np.uint8)",
        (f"{_RELATIVE}::test_the_monitor_labels_an_onset_after_a_relative_break_as_not_held",),
        "an onset after a relative break its verdicts rested on counts as held",
    ),
    Mutant(
        "plan-walk-end-carried-past-it",
        _PLAN,
        "  if (cleared != nullptr && *cleared >= k) return *cleared;",
        "  if (cleared != nullptr && *cleared >= k) return *cleared + 1;",
        (
            "tests/test_flightplan.py::test_a_pairs_later_verdicts_under_one_plan_are_never_above_the_reference",
        ),
        "a pair evaluated again under one plan takes one knot past where its last walk ended",
    ),
    Mutant(
        "held-bound-kept-over-a-new-held-set",
        "dua_mujoco/csrc/src/runtime.cc",
        "  held_bound_ = false;  // the buffers above may have moved: Bind points args_ at "
        "them again\n",
        "",
        ("tests/test_predictor_pruned.py",),
        "after a new held set the step reads the old set's freed buffers (Bind's cached pointers)",
    ),
    Mutant(
        "held-bound-copied",
        "dua_mujoco/csrc/src/runtime.cc",
        "      basis_live_(o.basis_live_),\n",
        "      held_bound_(o.held_bound_),\n      basis_live_(o.basis_live_),\n",
        (
            "tests/test_plugin.py::test_copies_and_resets_keep_their_own_state",
            "tests/test_plugin.py::test_a_copy_steps_on_its_own_buffers_once_the_original_is_gone",
        ),
        "a copied runtime's step reads and writes the original's buffers (Bind's cached pointers)",
    ),
    Mutant(
        "plan-walks-kept-over-a-new-plan",
        "dua_mujoco/csrc/src/runtime.cc",
        "    cleared_[p] = -1;\n    if (c == -1) continue;",
        "    if (c == -1) continue;",
        (
            "tests/test_flightplan.py::test_a_pairs_later_verdicts_under_one_plan_are_never_above_the_reference",
        ),
        "a new plan's pairs take the knots the old plan's walks ended at",
    ),
    Mutant(
        "plan-shadow-span-one-knot-short",
        "dua_mujoco/csrc/src/runtime.cc",
        "!(next + static_cast<double>(span) * h > until + 1e-6 * h)",
        "!(next + static_cast<double>(span + 1) * h > until + 1e-6 * h)",
        (
            "tests/test_plan_holes.py::test_a_replan_is_checked_to_the_last_knot_of_the_replaced_plans_span",
        ),
        "a replan is checked against the plan it replaces one knot short of the span its "
        "verdicts cover (the bodies' nesting and the relative pairs'): a departure at the last "
        "knot goes unseen",
    ),
    Mutant(
        "plan-nesting-passed-on-without-the-older-nesting",
        "dua_mujoco/csrc/src/runtime.cc",
        "chain != nullptr && sh.nested[b] && chain->nested[b];",
        "chain != nullptr && chain->nested[b];",
        (
            "tests/test_plan_holes.py::test_a_replan_nested_in_the_newest_shadow_keeps_the_older_shadows_departures",
        ),
        "a replan nested in the newest shadow is taken as nested in an older one it departs",
    ),
    Mutant(
        "plan-carry-past-the-departure",
        "dua_mujoco/csrc/src/runtime.cc",
        "if (carry) nest_end[b] = jn0 + s + d;",
        "if (carry) nest_end[b] = jn0 + span;",
        (
            "tests/test_plan_holes.py::test_a_replan_keeps_the_old_walks_cleared_knots_only_where_it_nests",
        ),
        "a replan's first walks start past the knot it leaves the old plan's tube at",
    ),
    Mutant(
        "plan-carry-for-bodies-never-checked",
        "dua_mujoco/csrc/src/runtime.cc",
        "      nest_end.assign(m->nbody, jn0);",
        "      nest_end.assign(m->nbody, jn0 + span);",
        ("tests/test_plan_holes.py::test_a_body_that_broke_the_replaced_plan_carries_no_walk",),
        "a body the nesting did not check (broken, or not held) taken as nested over the span",
    ),
    Mutant(
        "plan-carry-a-knot-past-the-departure",
        "dua_mujoco/csrc/src/runtime.cc",
        "if (carry) nest_end[b] = jn0 + s + d;",
        "if (carry) nest_end[b] = jn0 + s + d + 1;",
        (
            "tests/test_plan_holes.py::test_a_replan_keeps_the_old_walks_cleared_knots_only_where_it_nests",
        ),
        "a replan's first walks start one knot past its departure from the old plan's tube",
    ),
    Mutant(
        "plan-carry-past-the-span",
        "dua_mujoco/csrc/src/runtime.cc",
        "nest_end[static_cast<int64_t>(t.events_rec[kBNcol * i + kBBody])] = jn0 + span;",
        "nest_end[static_cast<int64_t>(t.events_rec[kBNcol * i + kBBody])] = jn0 + old.nknot();",
        (
            "tests/test_plan_holes.py::test_a_replan_keeps_the_old_walks_cleared_knots_only_where_it_nests",
        ),
        "the old walks' cleared knots carried past the span the nesting checked",
    ),
    Mutant(
        "plan-carry-past-the-relative-departure",
        "dua_mujoco/csrc/src/runtime.cc",
        "if (r >= 0) end = std::min(end, rel_end[r]);",
        "if (r < -1) end = std::min(end, rel_end[r]);",
        (
            "tests/test_plan_relative.py::test_a_replan_keeps_the_old_walks_cleared_knots_only_within_the_relative_tube",
        ),
        "a walk cleared on a relative deviation carried over a replan that leaves its tube",
    ),
    Mutant(
        "plan-carry-a-knot-past-the-relative-departure",
        "dua_mujoco/csrc/src/runtime.cc",
        "rel_end[r] = jn0 + std::llround((sh.rel_from[r] - next) / h);",
        "rel_end[r] = jn0 + std::llround((sh.rel_from[r] - next) / h) + 1;",
        (
            "tests/test_plan_relative.py::test_a_replan_keeps_the_old_walks_cleared_knots_only_within_the_relative_tube",
        ),
        "a walk cleared on a relative deviation carried one knot past the relative departure",
    ),
    Mutant(
        "plan-check-negative-deviations-passed",
        _PLAN,
        "    below += x - abs;",
        "    below += x - x;",
        (
            "tests/test_flightplan.py::test_set_plan_refuses_a_value_out_of_range_wherever_it_stands",
        ),
        "the scan of a plan's deviations lets a negative one through (the pairs' lanes)",
    ),
    Mutant(
        "plan-check-skips-the-odd-entry",
        _PLAN,
        "  for (; i < count; ++i) all = all && (!nonneg || v[i] >= 0.0) && std::isfinite(v[i]);",
        "",
        (
            "tests/test_flightplan.py::test_set_plan_refuses_a_value_out_of_range_wherever_it_stands",
        ),
        "the scan of a plan's numbers two at a time never reads the last of an odd count",
    ),
    Mutant(
        "plan-carry-start-taken-as-the-end",
        _PLAN,
        "const int64_t j = BothWalk(a, plan, d, from, p, g1, g2, b1, b2, r);",
        "const int64_t j = from > k ? from : BothWalk(a, plan, d, from, p, g1, g2, b1, b2, r);",
        (
            "tests/test_plan_holes.py::test_a_replan_keeps_the_old_walks_cleared_knots_only_where_it_nests",
        ),
        "the knot a carried walk starts at taken as the first that may touch",
    ),
    Mutant(
        "plan-nesting-passed-on-without-the-newest-nesting",
        "dua_mujoco/csrc/src/runtime.cc",
        "chain != nullptr && sh.nested[b] && chain->nested[b];",
        "chain != nullptr && sh.nested[b];",
        (
            "tests/test_plan_holes.py::test_a_replan_nested_in_the_newest_shadow_keeps_the_older_shadows_departures",
        ),
        "a replan that leaves the newest shadow is taken as nested in the older ones",
    ),
    Mutant(
        "plan-relative-nesting-passed-on-without-the-older-nesting",
        "dua_mujoco/csrc/src/runtime.cc",
        "    if (chain != nullptr && was) {\n",
        "    if (chain != nullptr && (was || true)) {\n",
        (
            "tests/test_plan_relative.py::test_a_replan_nested_in_the_newest_shadow_keeps_the_older_shadows_relative_departures",
        ),
        "a relative pair is taken as nested in an older shadow whose relative tube it departs",
    ),
    Mutant(
        "plan-relative-nesting-passed-on-without-the-newest-nesting",
        "dua_mujoco/csrc/src/runtime.cc",
        "if (rc >= 0 && chain->rel_nested[rc]) {",
        "if (rc >= 0) {",
        (
            "tests/test_plan_relative.py::test_a_replan_nested_in_the_newest_shadow_keeps_the_older_shadows_relative_departures",
        ),
        "a relative pair that leaves the newest shadow's tube is taken as nested in the older ones",
    ),
    Mutant(
        "plan-screen-squared-length",
        _PLAN,
        "std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]) * (1.0 + 1e-12) + kGapSlack * scale;",
        "(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]) * (1.0 + 1e-12) + kGapSlack * scale;",
        ("tests/test_flightplan.py::test_no_walk_stops_at_a_knot_mujocos_distance_clears",),
        "the knots' exact level skips a query whose direction would clear the knot",
    ),
    Mutant(
        "plan-box-screen-below-its-bound",
        _PLAN,
        "return bound * (1.0 + 2e-9);",
        "return bound * 0.5;",
        (
            "tests/test_plan_relative.py::"
            "test_the_actual_distance_is_never_below_the_planned_one_less_the_relative_deviation",
        ),
        "the deviation check's first screen passes a box whose corners stray beyond the limit",
    ),
    Mutant(
        "plan-relative-nesting-lanes-block-passed",
        _PLAN,
        "    return !Any(Not(And(room >= Splat(0.0), bound <= room)));\n",
        "    return !Any(Not(And(room >= Splat(0.0), bound <= room))) || s >= 0;\n",
        (
            "tests/test_plan_relative.py::test_a_relative_departure_is_found_at_its_knot_in_every_lane",
            "tests/test_plan_relative.py::"
            "test_a_replaced_plans_relative_pair_is_checked_from_the_new_plans_departure",
        ),
        "the relative nesting's four-knot blocks pass unchecked: a replan that leaves the replaced "
        "plan's relative tube is taken as nested, and its shadow checks the pair no more",
    ),
    Mutant(
        "plan-relative-nesting-lanes-last-entry-dropped",
        _PLAN,
        "Transpose4(rd, d + c);",
        "Transpose4(rd, d + c);\n      if (c == 8) d[11] = Splat(0.0);",
        (
            f"{_RELATIVE}::test_a_relative_departure_turning_about_x_is_found_at_its_knot_in_every_lane",
        ),
        "the relative nesting's lanes screen without the relative rotations' last entry: a body "
        "turned about x or y in the other's frame by a large angle is taken as within the "
        "replaced plan's relative tube beyond it, and the pair's departure is found late or never",
    ),
    Mutant(
        "plan-relative-nesting-lanes-last-entry-for-the-eighth",
        _PLAN,
        "Transpose4(rd, d + c);",
        "Transpose4(rd, d + c);\n      if (c == 8) d[11] = d[10];",
        (
            f"{_RELATIVE}::test_a_relative_departure_turning_about_x_is_found_at_its_knot_in_every_lane",
        ),
        "the relative nesting's lanes read the relative rotations' eighth entry for their last: "
        "a body turned about x in the other's frame is taken as within the relative tube beyond it",
    ),
    Mutant(
        "plan-relative-nesting-lanes-first-lane-only",
        _PLAN,
        "    return !Any(Not(And(room >= Splat(0.0), bound <= room)));\n",
        "    return And(room >= Splat(0.0), bound <= room)[0] != 0;\n",
        (
            "tests/test_plan_relative.py::test_a_relative_departure_is_found_at_its_knot_in_every_lane",
        ),
        "a block of the relative nesting whose first knot passes passes whole: a departure at its "
        "other knots is found a block later, and the shadow checks the pair knots late",
    ),
    Mutant(
        "plan-nesting-lanes-departure-at-the-blocks-end",
        _PLAN,
        "      if (!within(s + k)) return s + k;\n    }\n  }\n  for (; s < count; ++s) {\n"
        "    if (!within(s)) return s;\n  }\n  return count;\n}\n\n}  // namespace",
        "      if (!within(s + k)) return s + kLanes - 1;\n    }\n  }\n"
        "  for (; s < count; ++s) {\n    if (!within(s)) return s;\n  }\n  return count;\n}"
        "\n\n}  // namespace",
        (
            "tests/test_plan_relative.py::test_a_relative_departure_is_found_at_its_knot_in_every_lane",
            "tests/test_plan_relative.py::test_a_bodys_departure_is_found_at_its_knot_in_every_lane",
        ),
        "a departure in a block of the nesting's lanes (the relative pairs' and the bodies') is "
        "reported at the block's last knot",
    ),
    Mutant(
        "plan-box-screen-rounded-to-nearest",
        _PLAN,
        "return bound * (1.0 + 2e-9);",
        "return bound;",
        (f"{_ROUNDING}::test_the_deviation_checks_first_screen_passes_no_box_beyond_its_limit",),
        "the deviation check's first screen without its rounding room: a body that moves without "
        "turning passes a few ulps beyond its limit about half the time",
    ),
    Mutant(
        "plan-box-screen-rows-for-columns",
        _PLAN,
        "for (int i = 0; i < 3; ++i) column += f(3 * i + j) * f(3 * i + j);",
        "for (int i = 0; i < 3; ++i) column += f(3 * j + i) * f(3 * j + i);",
        (f"{_ROUNDING}::test_the_deviation_checks_verdict_is_the_largest_corners",),
        "the deviation check's first screen by the rows' norms of R - R', not the columns': a "
        "box along one axis turned about another passes with its corners beyond the limit",
    ),
    Mutant(
        "plan-box-screen-one-columns-reach",
        _PLAN,
        "bound += Sqrt(column) * qmax[j];",
        "bound += Sqrt(column) * qmax[0];",
        (f"{_ROUNDING}::test_the_deviation_checks_verdict_is_the_largest_corners",),
        "the deviation check's first screen weighs every column by the box's reach along x: a box "
        "longer along y or z passes with its corners beyond the limit",
    ),
    Mutant(
        "plan-box-screen-centre-for-reach",
        _PLAN,
        "for (int j = 0; j < 3; ++j) qmax[j] = std::fabs(box[kBCenter + j]) + box[kBHalf + j];",
        "for (int j = 0; j < 3; ++j) qmax[j] = std::fabs(box[kBCenter + j]);",
        (f"{_ROUNDING}::test_the_deviation_checks_verdict_is_the_largest_corners",),
        "the deviation check's first screen reaches only the box's centre, not its corners: a "
        "turned box passes with its corners beyond the limit",
    ),
    Mutant(
        "plan-nesting-lanes-reach-of-x",
        _PLAN,
        "for (int j = 0; j < 3; ++j) qmax[j] = Splat(reach.qmax[j]);",
        "for (int j = 0; j < 3; ++j) qmax[j] = Splat(reach.qmax[0]);",
        (
            "tests/test_plan_relative.py::test_a_relative_departure_is_found_at_its_knot_in_every_lane",
            "tests/test_plan_relative.py::"
            "test_a_replaced_plans_relative_pair_is_checked_from_the_new_plans_departure",
            "tests/test_plan_relative.py::test_a_bodys_departure_is_found_at_its_knot_in_every_lane",
        ),
        "the nesting's lanes (the bodies' and the relative pairs') screen every column by the "
        "box's reach along x, not the scalar's: a replan that leaves the replaced plan's tube "
        "along y or z is nested",
    ),
    Mutant(
        "plan-body-nesting-lanes-position-dropped",
        _PLAN,
        "rp[k] = Load(pa) - Load(pb);",
        "rp[k] = (Load(pa) - Load(pb)) * 0.0;",
        ("tests/test_plan_relative.py::test_a_bodys_departure_is_found_at_its_knot_in_every_lane",),
        "the bodies' nesting's lanes screen without the frames' positions: a replan that moves a "
        "body's frame out of the replaced plan's tube is nested",
    ),
    Mutant(
        "plan-body-nesting-lanes-last-entry-dropped",
        _PLAN,
        "f8[k] = ra[8] - rb[8];",
        "f8[k] = 0.0;",
        (
            f"{_RELATIVE}::test_a_bodys_departure_turning_about_x_is_found_at_its_knot_in_every_lane",
        ),
        "the bodies' nesting's lanes screen without the rotations' last entry (loaded knot by "
        "knot): a body turned about x or y by a large angle is taken as within the replaced "
        "plan's tube beyond it, and its departure is found late or never",
    ),
    Mutant(
        "plan-body-nesting-lanes-last-entry-for-the-eighth",
        _PLAN,
        "f8[k] = ra[8] - rb[8];",
        "f8[k] = ra[7] - rb[7];",
        (
            f"{_RELATIVE}::test_a_bodys_departure_turning_about_x_is_found_at_its_knot_in_every_lane",
        ),
        "the bodies' nesting's lanes read the rotations' eighth entry for their last: a body "
        "turned about x by a large angle is taken as within the replaced plan's tube beyond it",
    ),
    Mutant(
        "plan-body-nesting-lanes-first-lane-only",
        _PLAN,
        "    return !Any(Not(NormBound(e, f, qmax) <= limit));\n",
        "    return (NormBound(e, f, qmax) <= limit)[0] != 0;\n",
        ("tests/test_plan_relative.py::test_a_bodys_departure_is_found_at_its_knot_in_every_lane",),
        "a block of the bodies' nesting whose first knot passes passes whole: a departure at its "
        "other knots is found a block later, and the shadow checks the body knots late",
    ),
    Mutant(
        "plan-shadow-map-stale",
        "dua_mujoco/csrc/src/runtime.cc",
        "sh.rel_in_plan[r] = plan_->RelOf(old.rel_a(r), old.rel_b(r));",
        "sh.rel_in_plan[r] = sh.rel_in_plan[r];",
        (
            "tests/test_plan_relative.py::"
            "test_a_replaced_plans_relative_pair_is_read_at_its_own_place_in_the_new_plan",
        ),
        "a shadow reads its relative pairs' flags where the plan before the one in force had them",
    ),
    Mutant(
        "plan-kinematics-ancestors-dropped",
        _KINEMATICS,
        "  for (int b = nbody - 1; b > 0; --b) keep[m->body_parentid[b]] |= keep[b];\n",
        "",
        ("tests/test_plans.py::test_a_rolled_plan_is_followed_without_a_break", _KNOTS),
        "a plan's kinematics without the bodies between the geoms it reads (a mount): poses off",
    ),
    Mutant(
        "plan-covered-state-unchecked",
        "dua_mujoco/csrc/src/step.cc",
        "        if (!(tame_i && tame_j)) {",
        "        if (!(tame_i && tame_j) && !(skip != nullptr && skip[k])) {",
        ("tests/test_plans.py::test_a_planned_pairs_state_is_checked_though_the_plan_judges_it",),
        "a planned pair's state no longer checked: a diverged simulation judged by its plan",
    ),
    Mutant(
        "plan-kinematics-inertial-frames-dropped",
        _KINEMATICS,
        "sf == mjSAMEFRAME_INERTIAROT)) inertia_[id[b]] = 1;",
        "sf == mjSAMEFRAME_INERTIAROT)) inertia_[id[b]] = 0;",
        ("tests/test_plans.py::test_a_rolled_plan_is_followed_without_a_break", _KNOTS),
        "a geom at its body's inertial frame put at the body frame by the plan's kinematics",
    ),
    Mutant(
        "plan-kinematics-every-anchor-at-the-origin",
        _KINEMATICS,
        "      if (still_anchor_[jid]) {\n        // The anchor is xpos + 0",
        "      if (true) {\n        // The anchor is xpos + 0",
        (_KNOTS,),
        "a plan's hinge or ball joint turned about its body's origin, not its anchor: poses off "
        "mj_kinematics' wherever a joint sits off its body's origin",
    ),
    Mutant(
        "knot-lanes-every-anchor-at-the-origin",
        _KINEMATICS,
        "      if (still_anchor_[jid]) {\n        // Frame's anchor at the origin",
        "      if (true) {\n        // Frame's anchor at the origin",
        (_KNOTS,),
        "the knots' lanes turn a hinge or ball joint about its body's origin: the self-check "
        "turns lanes off on every model with an anchor off the origin",
    ),
    Mutant(
        "knot-lanes-a-zeros-sign-kept",
        _KINEMATICS,
        "        for (int k = 0; k < 3; ++k) xpos[k] = Splat(0.0) + xpos[k];\n",
        "",
        (_KNOTS,),
        "the knots' lanes keep -0 where mj_kinematics adds an anchor at the origin: the lanes' "
        "bytes differ from MuJoCo's (the self-check turns them off)",
    ),
    Mutant(
        "knot-lanes-quaternion-product-summed-in-order",
        _KINEMATICS,
        "(a[0] * b[0] - a[1] * b[1]) + (na2 * b[2] + na3 * b[3])",
        "a[0] * b[0] - a[1] * b[1] + na2 * b[2] + na3 * b[3]",
        (_KNOTS,),
        "the lanes' mju_mulQuat adds left to right as its source reads, not in the pairs the "
        "wheel's compiled helper adds: the last bit differs, the self-check turns lanes off",
    ),
    Mutant(
        "knot-lanes-rotation-diagonal-summed-in-order",
        _KINEMATICS,
        "(q00 - q22) + (q11 - q33), o1 + o1",
        "q00 + q11 - q22 - q33, o1 + o1",
        (_KNOTS,),
        "the lanes' mju_quat2Mat sums its diagonal as its source reads, not pairwise as the "
        "wheel's helper does: the last bit differs, the self-check turns lanes off",
    ),
    Mutant(
        "knot-lanes-zero-quaternion-unnormalised",
        _KINEMATICS,
        "const LaneMask small = norm < mjMINVAL;",
        "const LaneMask small = norm < 0.0;",
        (_KNOTS,),
        "the lanes' mju_normalize4 scales a zero quaternion (NaN) instead of making it the unit",
    ),
    Mutant(
        "knot-lanes-lone-last-knot-dropped",
        _KINEMATICS,
        "  for (; j < n; ++j) Run(qpos[j], mocap_pos[j], mocap_quat[j], pos[j], mat[j]);\n",
        "",
        (_KNOTS,),
        "the knots left after the last batch of lanes (a lone one, or all after the self-check "
        "failed) are never computed: their poses are stale",
    ),
    Mutant(
        "knot-lanes-self-check-skipped",
        _KINEMATICS,
        "    if (!checked) {",
        "    if (false) {",
        (_KNOTS,),
        "lanes are trusted without their first batch compared with the one-knot path: a lane "
        "off by a bit would change a plan's poses (and a verdict)",
    ),
    Mutant(
        "plan-knots-never-computed",
        _PLAN,
        "    while (done < kat.size() && kat[done] <= j) {",
        "    while (false && done < kat.size() && kat[done] <= j) {",
        (
            "tests/test_knot_kinematics.py::test_a_run_that_is_the_plan_never_breaks_it_at_deviation_0",
            "tests/test_plans.py::test_a_rolled_plan_is_followed_without_a_break",
        ),
        "set_plan gathers the knots to compute but never computes them (RunKnots not called)",
    ),
    Mutant(
        "plan-kinematics-a-zeros-sign-kept",
        _KINEMATICS,
        "        for (int k = 0; k < 3; ++k) xpos[k] = 0.0 + xpos[k];",
        "",
        (_KNOTS,),
        "a plan's body position where mj_kinematics adds an anchor at the origin: the sign of a "
        "zero differs from MuJoCo's (no longer its poses bit for bit)",
    ),
    Mutant(
        "plan-tolerance-not-added",
        _PLAN,
        "    for (double& d : dev_) d += tolerance;",
        "    for (double& d : dev_) d += 0.0 * tolerance;",
        (
            "tests/test_knot_kinematics.py::test_a_run_that_is_the_plan_never_breaks_it_at_deviation_0",
        ),
        "a plan's deviations not widened by its knots' tolerance: a run that is the plan, at "
        "deviation 0, is found beyond it (its poses are MuJoCo's, the knots' within T of them)",
    ),
    Mutant(
        "plan-query-tolerance-its-own",
        _PLAN,
        ", prev != nullptr ? prev->tolerance() : 0.0);",
        ", 0.0);",
        (
            "tests/test_knot_kinematics.py::"
            "test_a_query_that_copies_the_plans_knots_declares_the_plans_tolerance",
        ),
        "a candidate plan with knots of its own by mj_kinematics (sleep on) declares its own "
        "tolerance, 0, while it copies the followed plan's knots that the polynomials computed",
    ),
    Mutant(
        "plan-relative-tolerance-not-added",
        _PLAN,
        "        const double wide = in.relative_deviation[nr * j + col] + 3.0 * tolerance;",
        "        const double wide = in.relative_deviation[nr * j + col] + 0.0 * tolerance;",
        (f"{_RELATIVE}::test_a_run_that_is_the_plan_keeps_a_relative_deviation_of_0",),
        "a plan's relative deviations not widened by three times its knots' tolerance: a run "
        "that is the plan breaks a relative deviation of 0",
    ),
    Mutant(
        "plan-relative-rises-unwidened",
        _PLAN,
        "        const double now = std::min(da + db, wide);",
        "        const double now = std::min(da + db - 2.0 * tolerance, wide - 3.0 * tolerance);",
        (f"{_RELATIVE}::test_a_relative_pairs_rises_are_those_of_its_widened_deviations",),
        "a relative pair's rises taken from its deviations as given, not as the walk reads them "
        "(each body's D + T, the pair's D_ab + 3T): a widened sequence that falls is searched",
    ),
    Mutant(
        "knot-hinge-sine-reduced-by-pi-over-2s-first-bits-alone",
        _KINEMATICS,
        "  const T r = (x - k * kPio2Hi) - k * kPio2Lo;",
        "  const T r = x - k * kPio2Hi;",
        (f"{_KNOTS}::test_the_hinges_sine_and_cosine_stay_within_their_bound",),
        "the hinges' argument reduced by pi/2's first 33 bits only: sines and cosines off by up "
        "to 41 x 6e-11 past the first quadrant",
    ),
    Mutant(
        "knot-hinge-cosine-quadrant-sign-dropped",
        _KINEMATICS,
        "  *cs = Select(cneg, -cx, cx);",
        "  *cs = cx;",
        (_KNOTS,),
        "the hinges' cosine without its quadrant's sign: hinges past a quarter turn turned the "
        "wrong way",
    ),
    Mutant(
        "plan-kinematics-still-on-a-moving-body",
        _KINEMATICS_H,
        "return m->body_weldid[b] == 0 && m->body_mocapid[m->body_rootid[b]] < 0;",
        "return m->body_jntnum[b] == 0 && m->body_mocapid[m->body_rootid[b]] < 0;",
        (_KNOTS,),
        "a plan's kinematics take a body without joints welded to a moving one for a still one "
        "(its frame computed once): poses off wherever its parent moves",
    ),
    Mutant(
        "plan-knots-computed-after-their-sweep",
        _PLAN,
        "    while (done < kat.size() && kat[done] <= j) {",
        "    while (done < kat.size() && kat[done] < j) {",
        (
            "tests/test_knot_kinematics.py::test_a_run_that_is_the_plan_never_breaks_it_at_deviation_0",
            "tests/test_flightplan.py::test_the_plans_tau_is_never_above_the_reference_and_is_mostly_equal",
        ),
        "set_plan's sweeps read a knot's poses before the kinematics computes them (the knots "
        "computed a batch at a time as the sweeps reach them, one knot late)",
    ),
    Mutant(
        "plan-deviation-rises-never-cleared",
        _PLAN,
        "  for (int64_t b = 0; b < nbody; ++b) rises_[b] = falls[b] == 0.0;",
        "  for (int64_t b = 0; b < nbody; ++b) rises_[b] = 1;",
        (f"{_RELATIVE}::test_a_deviation_that_falls_is_not_searched_past",),
        "a body's deviation taken for rising over the knots where it falls: the walk's search "
        "skips knots the carried gap does not clear",
    ),
    Mutant(
        "knot-lanes-stores-the-next-knots-rotation",
        "dua_mujoco/csrc/src/kinematics.cc",
        "      for (int k = 0; k < kLanes; ++k) Store(mat[k] + 9 * s, col[k]);",
        "      for (int k = 0; k < kLanes; ++k) Store(mat[k] + 9 * s, col[(k + 1) % kLanes]);",
        (_KNOTS,),
        "a moving geom's rotation stored at another knot's (the lanes turned into knots)",
    ),
    Mutant(
        "knot-still-geom-rotation-halves-swapped",
        "dua_mujoco/csrc/src/kinematics.cc",
        "      Store(to, r0), Store(to + 4, r1), to[8] = r8;",
        "      Store(to, r1), Store(to + 4, r0), to[8] = r8;",
        (_KNOTS,),
        "a still geom's rotation copied to each knot with its halves swapped",
    ),
    Mutant(
        "plan-relative-rises-never-cleared",
        _PLAN,
        "        if (j > 0 && now < last[c]) rel_rises_[c] = 0;",
        "        if (false && j > 0 && now < last[c]) rel_rises_[c] = 0;",
        (f"{_RELATIVE}::test_a_deviation_that_falls_is_not_searched_past",),
        "a relative pair's min(D_a + D_b, D_ab) taken for rising over the knots where it falls: "
        "the walk's search skips knots the carried gap does not clear",
    ),
    Mutant(
        "plan-sweep-step-taken-once-for-moving-geoms",
        _PLAN,
        "for (int64_t c = 0; c < nslot_; ++c) still[c] = fixed[m->geom_bodyid[geoms[c]]];",
        "for (int64_t c = 0; c < nslot_; ++c) still[c] = 1;",
        (
            "tests/test_flightplan.py::test_the_plans_tau_is_never_above_the_reference_and_is_mostly_equal",
        ),
        "a moving geom's sweep takes its first step's displacement at every knot, as a still "
        "geom's does: the carried gaps skip knots the geoms come closer at",
    ),
    Mutant(
        "plan-grid-shave-dropped",
        _INTERNAL,
        "return static_cast<double>(grid) * h * (1.0 - kGridShave);",
        "return static_cast<double>(grid) * h;",
        (
            "tests/test_plans.py::test_an_exact_plans_alarm_stands_the_whole_horizon_wherever_the_touch_falls",
        ),
        "a plan's tau on the step grid, where the deadline test's roundings let a pair wait a "
        "step too long",
    ),
    Mutant(
        "plan-tau-rounded-up-to-the-period-grid",
        _INTERNAL,
        "const int64_t grid = p > 1 ? s / p * p : s;",
        "const int64_t grid = p > 1 ? (s + p - 1) / p * p : s;",
        (
            "tests/test_flightplan.py::test_a_plan_that_is_the_simulation_flags_every_onset_the_horizon_ahead",
        ),
        "with period > 1, a plan's tau rounded up to the predictor's grid covers a wait past the "
        "horizon's lead",
    ),
    Mutant(
        "bounds-tau-off-the-period-grid",
        _STEP,
        "  if (a.period <= 1) {\n    // Every tau written back",
        "  if (true) {\n    // Every tau written back",
        (
            "tests/test_warning_time.py::"
            "test_a_landing_between_predictor_steps_is_flagged_the_horizon_ahead",
        ),
        "with period > 1, a tau of the motion bounds off the predictor's grid lets a landing "
        "between two predictor steps be flagged up to (period - 1) steps short of the horizon",
    ),
    Mutant(
        "bounds-tau-a-step-past-the-first-state-in-contact",
        _INTERNAL,
        "const double s = std::min(std::ceil(tau / h), kFar);",
        "const double s = std::min(std::ceil(tau / h) + 1.0, kFar);",
        (
            "tests/test_warning_time.py::"
            "test_a_landing_between_predictor_steps_is_flagged_the_horizon_ahead",
            "tests/test_warning_time.py::"
            "test_the_plugin_flags_a_landing_between_its_steps_the_horizon_ahead",
            _GRID_STEPS,
        ),
        "with period > 1, a tau counted one physics step past the first state it can be in "
        "contact at covers a landing at the end of a period one period too long",
    ),
    Mutant(
        "grid-steps-by-a-reciprocal",
        _INTERNAL,
        "const double s = std::min(std::ceil(tau / h), kFar);",
        "const double s = std::min(std::ceil(tau * (1.0 / h)), kFar);",
        (_GRID_STEPS,),
        "a quotient rounded twice can cross a whole step upwards: the ceiling a step past the "
        "first state in contact",
    ),
    Mutant(
        "grid-steps-floored",
        _INTERNAL,
        "const double s = std::min(std::ceil(tau / h), kFar);",
        "const double s = std::min(std::floor(tau / h), kFar);",
        (_GRID_STEPS,),
        "not a break of the promise but of Lemma 8.5's ceiling: grid43's floor, alarming up to a "
        "physics step sooner than needed (the test asserts the ceiling where the quotient allows)",
    ),
    Mutant(
        "reach-without-the-grids-step",
        "dua_mujoco/build/pruning.py",
        "grid=dt - universe.model.opt.timestep)",
        "grid=0.0)",
        (
            "tests/test_predictor_pruned.py::"
            "test_a_pair_left_out_touching_between_predictor_steps_is_flagged_the_horizon_ahead",
        ),
        "with period > 1, a pruned reach that ends at the stride's predictor step lets a pair "
        "left out touch between two predictor steps, flagged short of the horizon",
    ),
    Mutant(
        "reach-check-without-the-grids-step",
        "dua_mujoco/csrc/src/tables.cc",
        "(s.alarm_horizon - s.dt) + (s.dt - t->timestep);",
        "(s.alarm_horizon - s.dt);",
        ("tests/test_hardening.py::test_a_pruned_horizon_without_the_grids_step_is_refused",),
        "the runtime loads pruned tables whose reach lacks the grid's step at period > 1",
    ),
    Mutant(
        "mixed-carried-place-behind",
        _PLAN,
        "for (int e = 0; e < 3; ++e) cb[e] = sb_state[e] + t * sb_state[3 + e];",
        "for (int e = 0; e < 3; ++e) cb[e] = sb_state[e] - t * sb_state[3 + e];",
        (
            "tests/test_plan_partial.py::"
            "test_no_motion_within_the_persons_bounds_touches_the_planned_arm_before_tau",
        ),
        "the mixed tau's reach about where the free body heads, carried the wrong way",
    ),
    Mutant(
        "mixed-stray-without-the-accel",
        _PLAN,
        "return ((spin + disc) * t + 0.5 * accel * t * t) * (1.0 + 8.0 * kEpsilon) +",
        "return ((spin + disc) * t + 0.0 * accel * t * t) * (1.0 + 8.0 * kEpsilon) +",
        (
            "tests/test_plan_partial.py::"
            "test_no_motion_within_the_persons_bounds_touches_the_planned_arm_before_tau",
        ),
        "the free body strays from where its velocity carries it by its velocity's error alone",
    ),
    Mutant(
        "mixed-without-the-carried-place",
        _PLAN,
        "return ((spin + disc) * t + 0.5 * accel * t * t) * (1.0 + 8.0 * kEpsilon) +",
        "return kInf + ((spin + disc) * t + 0.5 * accel * t * t) * (1.0 + 8.0 * kEpsilon) +",
        ("tests/test_plan_partial.py::test_a_person_walking_past_is_judged_where_it_walks",),
        "the mixed tau judges a body walking past by where it stands alone (no carried place)",
    ),
    Mutant(
        "mixed-stray-rounded-to-nearest",
        _PLAN,
        "return ((spin + disc) * t + 0.5 * accel * t * t) * (1.0 + 8.0 * kEpsilon) +",
        "return ((spin + disc) * t + 0.5 * accel * t * t) +",
        ("tests/test_plan_partial.py::test_the_stray_is_rounded_up",),
        "the free body's stray rounded to nearest, a few ulps below its exact value half the "
        "time (hidden today by the gaps' own 1e-14 allowance)",
    ),
    Mutant(
        "mixed-stray-without-its-rounding-room",
        _PLAN,
        "4.0 * kEpsilon * (size[0] + t * size[1]);",
        "0.0 * kEpsilon * (size[0] + t * size[1]);",
        ("tests/test_plan_partial.py::test_the_carried_place_keeps_room_for_its_own_rounding",),
        "far from the origin, the carried place y + t w rounds past the planned geom's reach",
    ),
    Mutant(
        "mixed-reach-rounded-to-nearest",
        _PLAN,
        "const double quad = ((s + disc) * t + 0.5 * accel * t * t) * (1.0 + 8.0 * kEpsilon);",
        "const double quad = ((s + disc) * t + 0.5 * accel * t * t);",
        (f"{_ROUNDING}::test_the_free_bodys_reach_is_rounded_up",),
        "the free body's reach rounded to nearest, a few ulps below its exact value half the time",
    ),
    Mutant(
        "mixed-reach-speed-rounded-to-nearest",
        _PLAN,
        "return std::min(quad, speed * t * (1.0 + 2.0 * kEpsilon));",
        "return std::min(quad, speed * t);",
        (f"{_ROUNDING}::test_the_free_bodys_reach_is_rounded_up",),
        "the free body's reach by its speed bound, V t, rounded to nearest: below it half the time",
    ),
    # ---------------------------------------------------------------- terrain (section 9)
    Mutant(
        "terrain-base-twice-as-deep",
        _TERRAIN,
        "TauHalfspace(-t.base - o.eps - o.hi[2] - o.slack,",
        "TauHalfspace(-2.0 * t.base - o.eps - o.hi[2] - o.slack,",
        ("tests/test_terrain.py::test_edges_sides_and_base",),
        "an object under the terrain is held to a base twice as deep",
    ),
    Mutant(
        "terrain-pyramid-half-the-children",
        _TERRAIN,
        "for (int64_t i = 2 * it.i; i < std::min(2 * it.i + 2, t.ny[l]); ++i) {",
        "for (int64_t i = 2 * it.i; i < std::min(2 * it.i + 1, t.ny[l]); ++i) {",
        (_PYRAMID,),
        "the branch and bound visits only the first row of a node's children",
    ),
    Mutant(
        "terrain-floor-too-high",
        _TERRAIN,
        "floor = std::min(g0, g0 + drift - grow) - 1e-12",
        "floor = std::max(g0, g0 + drift - grow) - 1e-12",
        ("tests/test_terrain.py::test_search_equals_every_cell_for_a_sphere", _PYRAMID),
        "cells that can be reached by coming down are skipped",
    ),
    Mutant(
        "terrain-reach-without-spin",
        _TERRAIN,
        "o.w = std::hypot(o.u[0], o.u[1]) + spin;",
        "o.w = std::hypot(o.u[0], o.u[1]);",
        (
            "tests/test_terrain.py::test_a_fine_grid_reached_sideways_is_searched_not_settled_by_the_base",
        ),
        "a spinning geom's horizontal reach without its rotation",
    ),
    # ---------------------------------------------------------------- the monitor's labels
    Mutant(
        "monitor-every-onset-predicted",
        "dua_mujoco/measure/monitor.py",
        "            if self._standing[g] > 0:",
        "            if self._standing[g] >= 0:",
        ("tests/test_testing.py::test_never_alarming_predictor_is_caught",),
        "an onset no alarm stood for counts as predicted",
    ),
    Mutant(
        "monitor-miss-excused-by-any-violation",
        "dua_mujoco/measure/monitor.py",
        "            broke = self.warning.hypotheses.broke(g, live, self._pred_steps.at(last))",
        "            broke = self.warning.hypotheses.broke(g, live, 0 * last)",
        (
            "tests/test_warning_time.py::test_a_miss_long_after_a_violation_is_one_with_the_bounds_held",
        ),
        "a miss counts as after a violation whenever its bodies broke their bounds once, "
        "however long before its pair's last evaluation",
    ),
    Mutant(
        "monitor-miss-in-any-violation-period",
        "dua_mujoco/measure/monitor.py",
        "            in_period = bool(self.bound_checks) and broke > seen",
        "            in_period = bool(self.bound_checks) and broke >= 0",
        (
            "tests/test_events.py::test_a_collision_right_after_an_impulse_is_flagged_only_with_events",
        ),
        "every miss after any violation falls in the guarantee's one exception",
    ),
    Mutant(
        "lead-short-blamed-on-any-violation",
        "dua_mujoco/measure/warning_time.py",
        "self.hypotheses.started(started, raised, raised_gp, self._last_eval[raised])",
        "self.hypotheses.started(started, raised, raised_gp, 0 * self._last_eval[raised])",
        ("tests/test_warning_time.py::test_short_leads_are_told_apart_by_the_bounds",),
        "a short lead counts as after a violation whenever its bodies broke their bounds once",
    ),
    Mutant(
        "lead-short-raisers-joined",
        "dua_mujoco/measure/warning_time.py",
        "        return int(steps[steps > after].max(initial=-1))",
        "        return int(steps[(steps > after.min()) & (after < _NEVER)].max(initial=-1))",
        (
            "tests/test_warning_time.py::test_a_break_before_a_verdict_excuses_no_other_verdicts_short_lead",
        ),
        "an onset's verdicts are judged on the union of their hypotheses since the earliest of "
        "their evaluations: a break before one verdict excuses another's short lead or miss",
    ),
    Mutant(
        "monitor-deferral-opens-a-window",
        "dua_mujoco/measure/monitor.py",
        "        made = evaluated[: evaluated.size - deferred]",
        "        made = evaluated",
        ("tests/test_monitor.py::test_a_deferral_opens_no_window_for_the_onsets_labels",),
        "a deferral moves a pair's window past violations its verdict in force rested on",
    ),
    # ---------------------------------------------------- the gym wrapper's info (issue 42)
    Mutant(
        "gym-info-standing-named-once",
        "dua_mujoco/csrc/src/bindings.cc",
        "if (watched.version != w.version) {",
        "if (w.version < 0) {",
        ("tests/test_gym.py::test_alarms_and_min_tau_follow_the_predictor_at_every_step",),
        "info['alarm_pairs'] keeps the first set named, not the pairs standing now",
    ),
    Mutant(
        "gym-info-cost-new-as-alarm",
        "dua_mujoco/csrc/src/bindings.cc",
        "cost = static_cast<double>(started);",
        "cost = nb::len(w.pairs) ? 1.0 : 0.0;",
        ("tests/test_gym.py::test_cost_new_counts_pairs_whose_alarm_started",),
        "cost='new' counts the standing pairs, not those whose alarm started",
    ),
    Mutant(
        "gym-info-mapping-cost-dropped",
        "dua_mujoco/csrc/src/bindings.cc",
        'before = out.attr("get")(w.total, before);',
        "before = nb::float_(0.0);",
        ("tests/test_gym.py::test_cost_adds_to_a_cost_the_env_reports",),
        "an info that is a mapping but not a dict loses the env's own cost",
    ),
    # ---------------------------------------------------------------- the shield (section 10)
    Mutant(
        "shield-screen-without-the-stop",
        _SHIELD,
        "return rt_->watched().expiry >= now + dt + o_.stop_time;",
        "return rt_->watched().expiry >= now + dt;",
        (f"{_SHIELD_EPISODES}[mobile_cell-brake]",),
        "the screen passes a period whose failsafe's stop it does not cover",
    ),
    Mutant(
        "shield-rest-without-the-turn",
        _SHIELD,
        "const double speed = lin + w * radius_[b];",
        "const double speed = lin + 0.0 * w * radius_[b];",
        ("tests/test_shield.py::test_a_robot_spinning_in_place_is_not_at_rest",),
        "a robot body turning about its origin counts as at rest",
    ),
    Mutant(
        "shield-rest-knot-guessed-not-kept",
        _SHIELD,
        "        keep(j);\n        if (Holds(m, d, false)) return j;",
        "        if (Holds(m, d, false)) return j;",
        (f"{_SHIELD_EPISODES}[arm_pair]",),
        "a rest knot found before mj_step1 ends the rollout without its poses",
    ),
    Mutant(
        "shield-nan-speed-at-rest",
        _SHIELD,
        "    if (!(speed <= top)) top = std::isnan(speed) ? HUGE_VAL : speed;  // a NaN is no rest",
        "    if (speed > top) top = speed;",
        ("tests/test_shield.py::test_a_velocity_that_is_not_a_number_is_no_rest",),
        "a robot body whose speed is not a number counts as at rest (its hold never breaks)",
    ),
    Mutant(
        "shield-rest-speed-excluded",
        _SHIELD,
        "bool Shield::AtRest(const mjData* d) const { return Speed(d) <= o_.rest_speed; }",
        "bool Shield::AtRest(const mjData* d) const { return Speed(d) < o_.rest_speed; }",
        (f"{_HOLD_EDGE}[slide-at]",),
        "a robot exactly at rest_speed is not at rest (the bound excluded: a held robot breaks "
        "its hold at the speed it declared rest)",
    ),
    Mutant(
        "shield-hold-break-past-rest-speed",
        _SHIELD,
        "    if (!AtRest(scratch_)) Break(&counts_.hold_breaks);",
        "    if (!(Speed(scratch_) <= o_.rest_speed * (1.0 + 1e-12))) Break(&counts_.hold_breaks);",
        (f"{_HOLD_EDGE}[slide-past]",),
        "the hold check lets a held robot a rounding faster than rest_speed count as at rest",
    ),
    Mutant(
        "shield-hold-without-the-turn",
        _SHIELD,
        "const double speed = lin + w * radius_[b];",
        "const double speed = lin + 0.0 * w * radius_[b];",
        (f"{_HOLD_EDGE}[spin-past]",),
        "a held robot spinning in place past rest_speed keeps its hold (the hold check reads "
        "the origin's speed alone)",
    ),
    Mutant(
        "shield-rest-knot-not-held",
        _SHIELD,
        "  const bool holds = Speed(d) * o_.stop_time <= o_.rest_speed;",
        "  const bool holds = true;",
        ("tests/test_shield.py::test_a_robot_its_failsafe_cannot_hold_is_never_guaranteed",),
        "a knot at rest is a rest knot though the failsafe cannot hold the robot there",
    ),
    Mutant(
        "shield-hold-tolerance-doubled",
        _SHIELD,
        "  const bool holds = Speed(d) * o_.stop_time <= o_.rest_speed;",
        "  const bool holds = Speed(d) * o_.stop_time <= 2.0 * o_.rest_speed;",
        (
            "tests/test_shield.py::"
            "test_a_failsafe_holds_a_knot_only_while_its_pull_stays_under_rest_speed_over_stop_time",
        ),
        "a knot is held though the failsafe's pull takes the robot past rest_speed within "
        "stop_time (up to twice as fast)",
    ),
    Mutant(
        "shield-unheld-knot-not-restored",
        _SHIELD,
        "    mj_setState(m, d, hold_.data(), kState);\n    mj_step1(m, d);\n",
        "",
        ("tests/test_shield.py::test_a_rollout_goes_on_past_a_knot_its_failsafe_cannot_hold",),
        "a rollout goes on from a knot it could not hold with the check's velocities, not its own",
    ),
    Mutant(
        "shield-protected-robot-body-out-of-the-rollout",
        "dua_mujoco/shield/shield.py",
        "        rolled.body_contype[bodies] = 0\n        rolled.body_conaffinity[bodies] = 0",
        "        rolled.body_contype[np.flatnonzero(prot)] = 0\n"
        "        rolled.body_conaffinity[np.flatnonzero(prot)] = 0",
        ("tests/test_shield.py::test_protected_robot_bodies_keep_their_contacts_in_the_rollout",),
        "a protected robot body collides with nothing in the rollouts (it falls through floors)",
    ),
    Mutant(
        "shield-accept-contact-before-rest",
        _SHIELD,
        "if (rest >= 0 && BuildPlan(n, tail) && FirstContact() >= rest) {",
        "if (rest >= 0 && BuildPlan(n, tail) && FirstContact() >= std::min(rest, o_.period)) {",
        (f"{_SHIELD_EPISODES}[person_cell]",),
        "a candidate passes when contact is ruled out for the period only, not until rest",
    ),
    Mutant(
        "shield-plan-without-the-deviation",
        _SHIELD,
        "dev_[j * nbody + b] = is_robot_[b] ? (j < tail ? o_.deviation : far) : 0.0;",
        "dev_[j * nbody + b] = is_robot_[b] ? (j < tail ? 0.0 : far) : 0.0;",
        (
            "tests/test_shield.py::"
            "test_a_candidate_whose_deviation_reaches_the_protected_body_is_refused[0.16-False]",
        ),
        "a candidate is queried with the robot exactly on its rollout",
    ),
    Mutant(
        "shield-envelope-once-the-deviation",
        _SHIELD,
        "const double far = 2.0 * o_.deviation + o_.stop_distance;",
        "const double far = o_.deviation + o_.stop_distance;",
        (
            "tests/test_shield.py::test_the_stop_envelope_counts_twice_the_deviation[0.05-0.06-False]",
        ),
        "the stop envelope reaches the deviation once, not twice",
    ),
    Mutant(
        "shield-envelope-limit-doubled",
        _SHIELD,
        "const double limit = o_.stop_distance + o_.deviation;",
        "const double limit = 2.0 * (o_.stop_distance + o_.deviation);",
        (
            "tests/test_shield.py::"
            "test_a_failsafe_leaving_its_stop_envelope_is_a_stop_break[0.0-0.04-False]",
        ),
        "a failsafe that leaves its stop envelope before rest counts as covered by it",
    ),
    Mutant(
        "shield-candidate-rolled-while-touching",
        _SHIELD,
        "    if (!touches) {",
        "    if (true) {",
        (
            "tests/test_shield.py::"
            "test_a_robot_touching_a_protected_body_is_refused_without_a_rollout[0.2-0.0-1.0]",
        ),
        "a candidate is rolled out though a protected pair may touch at its knot 0",
    ),
    Mutant(
        "shield-view-is-the-run",
        _SHIELD,
        "  if (has_plan_) {\n    // The plan's knot for this step",
        "  if (false) {\n    // The plan's knot for this step",
        (
            "tests/test_shield_evade.py::"
            "test_a_failsafe_reading_the_obstacles_in_its_data_repeats_its_rollouts",
        ),
        "the run calls a failsafe that reads the obstacles on the live state, not the rollout's "
        "view: it leaves the plans it was verified on",
    ),
    Mutant(
        "monitor-screen-acceleration-at-the-centre",
        _CHECKS,
        "(Norm3(u[0] - up[0], u[1] - up[1], u[2] - up[2]) + std::sqrt(a2) * rho) * inv_h",
        "Norm3(u[0] - up[0], u[1] - up[1], u[2] - up[2]) * inv_h",
        (_SCREEN,),
        "the monitor's screen bounds a group's acceleration by its centre's: a spinning body's "
        "corners break the bound unseen",
    ),
    Mutant(
        "monitor-screen-speed-at-the-centre",
        _CHECKS,
        "const double speed = Norm3(u[0], u[1], u[2]) + std::sqrt(g2) * rho;",
        "const double speed = Norm3(u[0], u[1], u[2]);",
        (_SCREEN,),
        "the monitor's screen bounds a group's chord speed by its centre's",
    ),
    Mutant(
        "monitor-screen-stale-rows",
        _CHECKS,
        "if (computed[g] != update - 1) {",
        "if (false) {",
        (_SCREEN,),
        "a group the screen skipped is measured against rows of an older update",
    ),
    Mutant(
        "plan-basis-dropped-when-cleared",
        "dua_mujoco/csrc/src/runtime.cc",
        "plan_ != nullptr || (basis_live_ && BasisNonzero());",
        "plan_ != nullptr || (false && BasisNonzero());",
        ("tests/test_flightplan.py::test_verdicts_after_a_plan_is_cleared_rest_on_the_bounds",),
        "once the plan is cleared the step stops renewing the verdicts' bases (the plan's stay)",
    ),
    Mutant(
        "standing-step-drops-the-last-alarm",
        "dua_mujoco/csrc/src/runtime.cc",
        "      if (now) next = ++j < nalarm ? alarms[j] : -1;",
        "      if (now) next = ++j + 1 < nalarm ? alarms[j] : -1;",
        ("tests/test_alarms.py::test_the_steps_standing_state_is_the_alarm_rule",),
        "the step's standing state, read from its alarm list, misses a pair in alarm",
    ),
    Mutant(
        "switched-off-left-in-the-wheel",
        _SCHEDULE,
        "      Unlink(v, p);\n    }\n  }\n  return changed;",
        "    }\n  }\n  return changed;",
        (_MADE_DUE,),
        "a deadline pair switched off stays linked: the wheel selects it when due, and made due "
        'it is taken without its switch read (docs/theory.md, section 3, "Linked pairs are '
        'switched on")',
    ),
    Mutant(
        "settle-a-standing-pair",
        _SCHEDULE,
        "if (settle != nullptr && at >= 0 &&\n"
        "          !Alarms(last_tau[p], static_cast<double>(at - last_step[p] + latency) * dt + "
        "extra)) {",
        "if (settle != nullptr && at >= 0) {",
        (_SETTLED_STANDING,),
        "a flagged body's pair standing in alarm is settled: the step, which tracks no settled "
        "pair, keeps it standing after its alarm ended (docs/theory.md, section 3)",
    ),
    Mutant(
        "settle-below-the-cover",
        _SCHEDULE,
        "if (cover > 0.0 && tau > cover) {",
        "if (cover > 0.0 && tau > horizon) {",
        (_SETTLED_STANDING,),
        "a settled pair keeps its due step on a verdict that does not cover the wait: it stands "
        "in alarm unreported (the step tracks no settled pair)",
    ),
    Mutant(
        "settle-off-the-period-grid",
        _INTERNAL,
        "return grid ? GridFloor(t, a.timestep, a.period) : t;",
        "return t;",
        (
            "tests/test_events.py::test_settled_pairs_wait_on_the_predictor_grid_at_period_above_one",
        ),
        "with period > 1, a settled pair's wait off the predictor's grid",
    ),
    Mutant(
        "plan-arrays-kept-in-any-layout",
        _FLIGHTPLAN,
        "if type(value) is np.ndarray and value.dtype is _F64 and value.flags.c_contiguous:",
        "if type(value) is np.ndarray and value.dtype is _F64:",
        (
            "tests/test_flightplan.py::test_set_plan_reads_the_callers_arrays_without_copies_or_writes",
        ),
        "a plan's qpos passed on in the caller's layout, not the C order the runtime reads",
    ),
    Mutant(
        "plan-arrays-kept-in-any-dtype",
        _FLIGHTPLAN,
        "    if type(value) is np.ndarray and value.dtype is _F64:\n        return value",
        "    if type(value) is np.ndarray:\n        return value",
        (
            "tests/test_flightplan.py::test_set_plan_reads_the_callers_arrays_without_copies_or_writes",
        ),
        "a deviation passed on in the caller's dtype, not float64",
    ),
    Mutant(
        "plan-relative-deviation-a-row-per-knot",
        _FLIGHTPLAN,
        "column = per_row and dev.ndim == 1",
        "column = dev.ndim == 1",
        (
            "tests/test_flightplan.py::test_set_plan_reads_the_callers_arrays_without_copies_or_writes",
        ),
        "one relative deviation a pair read as one a knot",
    ),
    Mutant(
        "plan-deviation-a-column-per-body",
        _FLIGHTPLAN,
        "column = per_row and dev.ndim == 1",
        "column = False",
        (
            "tests/test_flightplan.py::test_set_plan_reads_the_callers_arrays_without_copies_or_writes",
        ),
        "one deviation a knot read as one a body",
    ),
    Mutant(
        "plan-deviation-rows-knots-unchecked",
        "dua_mujoco/runtime/profiles.py",
        "if type(knots) is not int or knots < 1:",
        "if type(knots) is not int:",
        ("tests/test_plans.py::test_plan_deviation_reads_the_profile_past_the_origin",),
        "plan_deviation takes a plain int below 1 for a plan's knots",
    ),
    Mutant(
        "basis-kept-after-the-plan",
        "dua_mujoco/csrc/src/runtime.cc",
        "  return !(zero(basis_) && zero(basis_prev_));",
        "  return !(zero(basis_) && zero(basis_prev_) && false);",
        ("tests/test_flightplan.py::test_settling_resumes_once_a_plan_runs_out",),
        "settling off for good after any plan (cost, not the promise)",
    ),
    # ------------------------------------------------------- the static guard (static-shapes.md)
    Mutant(
        "static-guard-skipped-at-reset",
        _PLUGIN,
        "    if (!edited.empty()) {\n      mju_error(",
        "    if (edited.empty() && !edited.empty()) {\n      mju_error(",
        (f"{_STATIC_EDITS}::test_plugin_reset_refuses_an_edited_static_geom",),
        "mj_resetData after a static geom was edited classifies against the stale cover",
    ),
    Mutant(
        "static-guard-skipped-at-init",
        _TABLES,
        "    const std::string edited = StaticMismatch(m, kept->statics);",
        "    const std::string edited;",
        (f"{_STATIC_EDITS}::test_plugin_init_refuses_an_edited_static_geom",),
        "an MjData made after a static geom was edited runs on the stale cover",
    ),
    Mutant(
        "static-table-unchecked-at-build",
        _TABLES,
        '  return edited.empty() || r->Fail("static", StaticRefusal(edited));',
        "  return true;",
        (
            f"{_STATIC_EDITS}::test_a_static_table_that_does_not_match_the_model_is_refused_as_a_table",
        ),
        "tables whose static records do not match the model (corrupted, or built before an "
        "edit) are taken as sound",
    ),
    Mutant(
        "static-pose-unrecorded",
        _TABLES,
        "    std::copy_n(k.still_pos(s), 3, rec + kStaticPos);\n",
        "",
        (_STATIC_EDITS,),
        "a static geom moved under the tables is not seen (both records hold zeros)",
    ),
    Mutant(
        "static-size-unchecked",
        _TABLES,
        "    std::copy_n(m->geom_size + 3 * g, 3, rec + kStaticSize);\n",
        "",
        (_STATIC_EDITS,),
        "a static geom resized under the tables is not seen",
    ),
    Mutant(
        "static-hfield-data-unread",
        _TABLES,
        "    d.Array(m->hfield_data + m->hfield_adr[id], grid[0] * grid[1]);\n",
        "",
        (_STATIC_EDITS,),
        "a height field's heights edited under its terrain records are not seen",
    ),
    Mutant(
        "static-mesh-vertices-unread",
        _TABLES,
        "3 * int64_t{m->mesh_vertnum[id]});",
        "0);",
        (_STATIC_EDITS,),
        "a static mesh's vertices moved out of its box are not seen",
    ),
    Mutant(
        "static-digest-uncompared",
        _TABLES,
        "for (int c = kStaticPos; c < kStaticNcol; ++c) {",
        "for (int c = kStaticPos; c < kStaticDigest; ++c) {",
        (_STATIC_EDITS,),
        "a height field's or a mesh's digest is recorded but never compared",
    ),
    Mutant(
        "static-guard-skipped-at-predictor-reset",
        "dua_mujoco/build/tables.py",
        "    edited = _core.static_mismatch(model, records)",
        '    edited = ""',
        (
            f"{_STATIC_EDITS}::test_predictor_reset_refuses_a_resized_or_reshaped_static_geom",
            "tests/test_static_pairs.py",
        ),
        "Predictor.reset takes a model whose static geoms were moved, resized or reshaped",
    ),
    Mutant(
        "screen-margin-reversed",
        _INTERNAL,
        "constexpr double kScreenMargin = 1.0 + 1e-9;",
        "constexpr double kScreenMargin = 1.0 - 1e-9;",
        (_SCREEN_BOUNDARY,),
        "the screen clears a pair up to 1e-9 inside its reach: one that can touch within the "
        "horizon stands in no alarm",
    ),
    Mutant(
        "screen-one-sphere-speed",
        _INTERNAL,
        "  const double speeds = si[3] + sj[3];\n",
        "  const double speeds = sj[3];\n",
        (_SCREEN_BOUNDARY, _SCREEN_RANDOM, _SCREEN_REFERENCE),
        "the screen's reach leaves out the first sphere's speed: a pair closing on it is cleared",
    ),
    Mutant(
        "screen-pass-past-1e300",
        _INTERNAL,
        "return d2 < 1e300 && d2 > reach * reach * kScreenMargin;",
        "return d2 > reach * reach * kScreenMargin;",
        (_SCREEN_REFUSALS,),
        "the screen clears a pair whose squared offset is past 1e300 (two tame rows 2e151 apart), "
        "where it could have overflowed, whatever its spheres' speeds",
    ),
    Mutant(
        "screen-base-unchecked",
        _INTERNAL,
        "return ScreenHorizon(h) && base >= kScreenLeastBase && ScreenedPairClears",
        "return ScreenHorizon(h) && ScreenedPairClears",
        (_SCREEN_REFUSALS,),
        "the screen takes a pair whose reach's bounds part is below 1e-100, where a cleared "
        "squared offset need not be normal (Lemma 3.9's rounding)",
    ),
    Mutant(
        "screen-failures-dropped",
        _SCHEDULE,
        "of step n - 1\n      w_ids[count++] = p;",
        "of step n - 1\n      w_ids[count] = p;",
        (_SCREEN_INVARIANT,),
        "a pair the screen does not clear is neither evaluated nor linked: never looked at again",
    ),
    Mutant(
        "screened-pair-carried-nowhere",
        _SCHEDULE,
        "if (due >= 0 || due == dua::kScreened) {",
        "if (due >= 0) {",
        (_SCREEN_INVARIANT,),
        "a rebuild of the held pairs drops the screened ones from both the wheel and the screen",
    ),
    Mutant(
        "screened-pair-switched-off-kept",
        _SCHEDULE,
        "    if (where[p] == dua::kScreened) where[p] = -1;\n",
        "",
        (_SCREEN_INVARIANT,),
        "a pair switched off stays on the screen and is evaluated when the test fails",
    ),
    Mutant(
        "screen-stale-entries-tested",
        _SCHEDULE,
        "    if (where[p] != kScreened) continue;  // left the screen since the last test\n",
        "",
        (_SCREEN_INVARIANT,),
        "a pair that left the screen between steps (made due, switched off) is still tested: "
        "selected a second time, or a switched-off pair evaluated and linked",
    ),
    Mutant(
        "screen-while-watching",
        _RUNTIME,
        "args_.screen = watching_ ? 0 : 1;",
        "args_.screen = 1;",
        (_SCREEN_WATCH,),
        "a watching runtime screens: the shield reads a screened pair's verdict as reaching the "
        "horizon only, and acts on a pair that cannot touch",
    ),
    Mutant(
        "screen-under-a-plan",
        _STEP,
        "a->screen != 0 && bounds_only && a->period <= 1;",
        "a->screen != 0 && a->period <= 1;",
        (_SCREEN_PLAN,),
        "the screen clears pairs by the bounds while a plan is set, whose verdicts rest on it",
    ),
    Mutant(
        "screen-off-the-grid",
        _STEP,
        "a->screen != 0 && bounds_only && a->period <= 1;",
        "a->screen != 0 && bounds_only;",
        (_SCREEN_WATCH,),
        "the screen's verdict, not on the predictor's grid, is kept with period > 1",
    ),
    Mutant(
        "screen-verdict-at-the-horizon",
        _SCHEDULE,
        "const double cleared = std::nextafter(h, std::numeric_limits<double>::infinity());",
        "const double cleared = h;",
        (_SCREEN_INVARIANT,),
        "a cleared pair's verdict is the horizon itself, which the alarm rule reads as standing",
    ),
)


# ------------------------------------------------------------------------------------------------
# The scratch copy
# ------------------------------------------------------------------------------------------------

_HOOK = '''"""Imports dua_mujoco from the mutation check's copy, not the editable install."""
import sys

sys.meta_path[:] = [f for f in sys.meta_path if "ScikitBuild" not in type(f).__name__]
'''


class Scratch:
    """A copy of the working tree with its own build of the native core."""

    def __init__(self, root: Path, jobs: int) -> None:
        self.root = root
        self.tree = root / "tree"
        self.build = root / "build"
        self.hook = root / "hook"
        self.jobs = jobs

    def copy(self) -> None:
        """The working tree's tracked and new files (not ignored ones: no build, no venv)."""
        listed = subprocess.run(
            ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
            cwd=HERE, check=True, capture_output=True,
        ).stdout.decode().split("\0")  # fmt: skip
        if self.tree.exists():
            shutil.rmtree(self.tree)
        for rel in filter(None, listed):
            src, dst = HERE / rel, self.tree / rel
            dst.parent.mkdir(parents=True, exist_ok=True)
            if src.is_symlink():  # dua_mujoco/models -> ../models
                dst.symlink_to(os.readlink(src))
            elif src.is_file():
                # A fresh mtime: a reused --scratch build dir may hold objects newer than the
                # working tree's sources (built from the last run's mutant), which make would
                # otherwise take as up to date.
                shutil.copy(src, dst)
        self.hook.mkdir(parents=True, exist_ok=True)
        (self.hook / "sitecustomize.py").write_text(_HOOK)

    def compile(self) -> None:
        """Configure once, then build (incremental) and put the libraries in the copy."""
        if not (self.build / "CMakeCache.txt").exists():
            subprocess.run(
                ["cmake", "-S", str(self.tree / "dua_mujoco/csrc"), "-B", str(self.build),
                 f"-DPython_EXECUTABLE={sys.executable}", "-DCMAKE_BUILD_TYPE=Release"],
                check=True, capture_output=True,
            )  # fmt: skip
        subprocess.run(
            ["cmake", "--build", str(self.build), "-j", str(self.jobs)],
            check=True, capture_output=True,
        )  # fmt: skip
        for lib in [self.build / "libdua_mujoco.so", *self.build.glob("_core.*.so")]:
            shutil.copy2(lib, self.tree / "dua_mujoco" / lib.name)

    def pytest(self, tests: tuple[str, ...], timeout: float) -> tuple[bool, str]:
        """Whether ``tests`` pass in the copy (False on a timeout), and pytest's last line."""
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join([str(self.hook), str(self.tree)])
        # The copy's _core finds libmujoco by a run path that holds only beside an installed
        # package ($ORIGIN/../mujoco): name mujoco's folder to the loader instead.
        spec = importlib.util.find_spec("mujoco")
        assert spec is not None and spec.submodule_search_locations
        mujoco_dir = spec.submodule_search_locations[0]
        env["LD_LIBRARY_PATH"] = os.pathsep.join(
            filter(None, [mujoco_dir, env.get("LD_LIBRARY_PATH")])
        )
        env.setdefault("MUJOCO_GL", "egl")
        argv = [sys.executable, "-m", "pytest", "-x", "-q", "-n", str(self.jobs),
                "-p", "no:cacheprovider", *tests]  # fmt: skip
        try:
            run = subprocess.run(
                argv, cwd=self.tree, env=env, capture_output=True, text=True, timeout=timeout
            )
        except subprocess.TimeoutExpired:
            return False, f"timed out after {timeout:.0f} s"
        lines = [ln for ln in run.stdout.splitlines() if ln.strip()]
        return run.returncode == 0, lines[-1] if lines else run.stderr[-200:]


def _apply(tree: Path, mutant: Mutant) -> str | None:
    """Apply ``mutant`` in ``tree``; returns the original text, or None if it is stale."""
    path = tree / mutant.path
    text = path.read_text()
    if text.count(mutant.old) != 1:
        return None
    path.write_text(text.replace(mutant.old, mutant.new))
    return text


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="*", help="mutants to run (default: all)")
    parser.add_argument("--list", action="store_true", help="print the list and exit")
    parser.add_argument("--scratch", type=Path, help="scratch folder (default: a temporary one)")
    parser.add_argument("--jobs", type=int, default=2, help="build jobs and pytest workers")
    parser.add_argument("--timeout", type=float, default=900.0, help="seconds per test run")
    args = parser.parse_args(argv)
    known = {m.name: m for m in MUTANTS}
    unknown = [n for n in args.names if n not in known]
    if unknown:
        parser.error(f"unknown mutants {unknown}; known: {', '.join(known)}")
    chosen = [known[n] for n in args.names] if args.names else list(MUTANTS)
    if args.list:
        for m in chosen:
            print(f"{m.name}: {m.path} -- {m.why}\n    tests: {' '.join(m.tests)}")
        return 0
    root = args.scratch or Path(tempfile.mkdtemp(prefix="dua-mutants-"))
    scratch = Scratch(root, args.jobs)
    start = time.monotonic()
    scratch.copy()
    scratch.compile()
    print(f"scratch copy and build: {root} ({time.monotonic() - start:.0f} s)", flush=True)
    tests = tuple(dict.fromkeys(t for m in chosen for t in m.tests))
    ok, last = scratch.pytest(tests, args.timeout)
    if not ok:
        print(f"the tests fail without any mutant ({last}): nothing to learn", file=sys.stderr)
        return 2
    print(f"unmutated: {last}", flush=True)
    rows, bad = [], 0
    for m in chosen:
        t0 = time.monotonic()
        original = _apply(scratch.tree, m)
        if original is None:
            result, detail = "stale", "its text does not occur exactly once"
        else:
            try:
                if m.native:
                    scratch.compile()
                passed, detail = scratch.pytest(m.tests, args.timeout)
                result = "survived" if passed else "killed"
            except subprocess.CalledProcessError:
                result, detail = "broken", "does not build: aim it again"
            finally:
                (scratch.tree / m.path).write_text(original)
        bad += result != "killed"
        rows.append((m.name, result, time.monotonic() - t0, detail))
        print(f"{m.name}: {result} ({rows[-1][2]:.0f} s; {detail})", flush=True)
    if any(m.native for m in chosen):
        scratch.compile()  # leave the copy built as it is
    print("\n| mutant | file | what it breaks | killed by | result | s |")
    print("|---|---|---|---|---|---|")
    for m, (_, result, secs, _) in zip(chosen, rows, strict=True):
        killers = ", ".join(f"`{t.removeprefix('tests/')}`" for t in m.tests)
        where = m.path.rsplit("/", 1)[-1]
        print(f"| {m.name} | {where} | {m.why} | {killers} | {result} | {secs:.0f} |")
    print(f"\n{len(rows) - bad} of {len(rows)} killed in {time.monotonic() - start:.0f} s")
    if args.scratch is None:
        shutil.rmtree(root, ignore_errors=True)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
