// The safety shield (docs/shield.md; its proof: docs/theory.md, section 10). Between a controller
// and mj_step: each physics step it returns the controls to apply. At the start of each control
// period (every `period` physics steps) it decides, from the state the next step starts from:
//
// - the screen: when every protected pair's latest verdict of the predictor (motion bounds for
//   every body, the robot's own included) rules out contact for the period and the failsafe's
//   longest stop after it, the intended controls pass without a rollout;
// - else a rollout on the rollout model (the protected geoms collide with nothing there): the
//   intended controls held for the period, then the failsafe until every robot body is at rest
//   (at most rest_speed) at a pose where the failsafe holds it (Holds), at most stop_time after
//   the period; the candidate passes when the predictor's plan query (Runtime::QueryKnots: the
//   robot planned with its deviation, every other body on its bounds from now) puts every
//   protected pair's first possible contact at or after the rest knot. A passing candidate
//   becomes the plan the run is checked against at every step;
// - else the failsafe: the last verified plan's, as state feedback; without one (after the
//   screen, a reset, a broken hypothesis), a failsafe rolled out from now and checked the same
//   way, or covered by the screen of the period before when it stops within stop_time.
//
// Between period starts it checks the run against the plan at every step, and once past the
// plan's rest knot that the robot stays at rest. A hypothesis found broken (another body's
// bounds, the robot's bounds after a screened period, the plan, the rest, the stop time) is an
// event: the failsafe at once, and no guarantee until a check passes again.
#ifndef DUA_MUJOCO_SHIELD_H_
#define DUA_MUJOCO_SHIELD_H_

#include <mujoco/mujoco.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "brake.h"
#include "dua/dua.h"
#include "plan.h"
#include "runtime.h"
#include "tables.h"

namespace dua {

struct ShieldOptions {
  int64_t period = 1;        // physics steps per control period (the predictor's period too)
  double deviation = 0.0;    // how far every point of the robot may stray from its plans (m)
  double rest_speed = 0.01;  // a body at most this fast (every point) is at rest (m/s)
  double stop_time = 1.0;    // the failsafe's longest stop (s): rollouts give up past it
  // The failsafe's stop envelope (m; < 0: none): how far any robot point may move while it
  // stops. With one, a candidate rolls out the period and the failsafe for one period more,
  // and trusts the envelope after that when the robot is not at rest yet; the envelope is
  // checked on each failsafe rolled out from there. Without, each candidate rolls the
  // failsafe out to rest.
  double stop_distance = -1.0;
  bool screen = true;  // accept without a rollout when the motion bounds rule contact out
};

// What the shield did, and the hypotheses it found broken (each an event: no guarantee until a
// check passes again).
struct ShieldCounts {
  int64_t steps = 0;          // physics steps
  int64_t interventions = 0;  // of them, steps the failsafe's controls were applied
  int64_t unguaranteed = 0;   // of them, steps without a guarantee
  int64_t periods = 0;        // control periods
  int64_t screened = 0;       // periods the screen passed
  int64_t accepted = 0;       // periods a rolled-out candidate passed
  int64_t rejected = 0;       // periods the intended controls were refused
  int64_t rollouts = 0;       // rollouts (candidates and failsafes)
  int64_t rollout_steps = 0;  // physics steps rolled out
  int64_t bound_events = 0;   // another body's bounds broke
  int64_t robot_events = 0;   // the robot's own bounds broke after a screened period
  int64_t plan_breaks = 0;    // the robot found beyond its plan's deviation
  int64_t hold_breaks = 0;    // the robot found moving after its plan's rest knot
  int64_t unheld = 0;         // knots at rest the failsafe cannot hold (no rest knot)
  int64_t stop_breaks = 0;    // a failsafe did not stop within stop_time
  int64_t unverified = 0;     // failsafes followed that no check covered
};

// The failsafe's controls ctrl (nu) at d's state (Brake::Prepare or mj_step1 computed it);
// d->ctrl holds the controls applied last.
using Failsafe = std::function<void(const mjModel* m, mjData* d, double* ctrl)>;

// The rollout's view (a failsafe that reads more than the robot's state: where the obstacles
// are): the failsafe is called in the rollouts on the rollout's data, whose other bodies are as
// the rollout holds them (mocap bodies where the state read put them, every other body rolled
// under its held controls); the run calls it on `view`, an mjData of the rollout model holding
// the plan's knot for this step (its state as mj_step1 left it in the rollout) with the robot's
// own coordinates (qpos, qvel, act, its actuators' ctrl) the run's. A run on its plan then gives
// the failsafe the very data it had in the rollout, so it repeats the rollout whatever else the
// failsafe reads (docs/theory.md, section 10). Without a plan (after an event, until the next
// period) the view holds the run's state. Null: the failsafe reads the robot's state only (the
// brake), and the run calls it on the run's state.

class DUA_API Shield {
 public:
  // m: the model; tables: the predictor's, built for m with period options.period; rolled: a
  // copy of m whose protected geoms collide with nothing, and roll an mjData of it; scratch an
  // mjData of m (both the caller's, alive as long as the shield); robot_actuators, robot_bodies:
  // the robot; g1, g2: the protected geom pairs (robot geom first); failsafe: its controls.
  // Null with *error naming a bad value.
  static std::unique_ptr<Shield> Make(const mjModel* m, std::shared_ptr<const Tables> tables,
                                      const mjModel* rolled, mjData* roll, mjData* scratch,
                                      const std::vector<int>& robot_actuators,
                                      const std::vector<int>& robot_bodies,
                                      const std::vector<int64_t>& g1,
                                      const std::vector<int64_t>& g2, Failsafe failsafe,
                                      const ShieldOptions& options, std::string* error,
                                      mjData* view = nullptr);

  // Defined in shield.cc, where Plan's destructor (not exported) is seen.
  ~Shield();

  // Starts over at d's state: the predictor classifies, the plan is dropped, and the first
  // period runs the failsafe (guaranteed when it is verified, or the robot is held at rest).
  void Reset(const mjModel* m, const mjData* d);
  // The controls for the physics step about to start from d's state (ctrl, nu): intended (nu)
  // where verified, the robot's actuators on the failsafe otherwise. Call it right before each
  // mj_step, after moving scripted (mocap) bodies.
  void Control(const mjModel* m, const mjData* d, const double* intended, double* ctrl);

  bool guaranteed() const { return guaranteed_; }
  bool intervening() const { return failsafe_mode_; }
  const ShieldCounts& counts() const { return counts_; }
  const Runtime& runtime() const { return *rt_; }
  // The knots of the plan followed (-1: none), its rest knot (-1: none), and the knot the
  // next step starts from.
  int64_t plan_knots() const { return has_plan_ ? plan_->nknot() : -1; }
  int64_t plan_rest() const { return has_plan_ ? plan_rest_ : -1; }

 private:
  Shield() = default;
  // The largest speed bound of a robot body's points at d's state (cvel computed; a NaN is
  // HUGE_VAL), and whether every robot body is at rest there.
  double Speed(const mjData* d) const;
  bool AtRest(const mjData* d) const;
  // Whether the failsafe holds the robot at rest at d's pose (a rollout's knot at rest, on m,
  // the rollout model; positions: mj_step1 computed its position stage): false restores d's
  // state and mj_step1's values, for the rollout to go on; true leaves d's values the check's.
  bool Holds(const mjModel* m, mjData* d, bool positions);
  // The view for the run's step from d (see Failsafe): the plan's knot, the robot the run's.
  void View(const mjData* d);
  // Holds at the state read (Prepare's), on the rollout's data.
  bool HoldsNow();
  // Rolls out from the scratch's state: `nint` steps of intended, then the failsafe until rest
  // (first knot >= nint with every robot body at rest) or `last` knots; the knots' poses and
  // robot qpos into knots_. Returns the rest knot, or -1.
  int64_t Roll(const double* intended, int64_t nint, int64_t last);
  // The candidate plan of the rollout's knots 0..n-1, the robot at its deviation before knot
  // `tail`, at the stop envelope's from there (false: not finite).
  bool BuildPlan(int64_t n, int64_t tail);
  // Knot 0 (the state read: its poses and robot qpos) from the scratch's kinematics, as a
  // rollout's first knot.
  void KnotZero();
  // Whether a protected pair may touch at the state read (knot 0 of every candidate), from the
  // scratch's kinematics.
  bool TouchesNow();
  // Whether the failsafe rolled out (knots 0..n-1) stays within the stop envelope.
  bool WithinEnvelope(int64_t n) const;
  // The least of the protected pairs' first knots of possible contact under the candidate (its
  // knot count when none).
  int64_t FirstContact();
  // Whether every protected pair's latest verdict rules contact out for the period and
  // stop_time after it.
  bool Screen() const;
  // A hypothesis found broken: counted, the plan dropped, the failsafe at once, no guarantee.
  void Break(int64_t* counter);
  // Makes knots 0..n-1 the plan followed from this step on.
  void Install(int64_t n, int64_t rest);
  // The run's state against the plan (or the hold past its rest); breaks set fresh_.
  void Check(const mjData* d);
  void Prepare(const mjData* d);
  void Period(const mjModel* m, const mjData* d, const double* intended);
  void Classify();

  const mjModel* model_ = nullptr;
  const mjModel* rolled_ = nullptr;
  mjData* roll_ = nullptr;
  mjData* scratch_ = nullptr;
  mjData* view_ = nullptr;                   // the rollout's view (null: none)
  std::vector<int> robot_act_, robot_ctrl_;  // the robot's act and ctrl addresses (the view's)
  std::unique_ptr<Runtime> rt_;
  std::shared_ptr<const Tables> tables_;
  Failsafe failsafe_;
  ShieldOptions o_;
  std::vector<int> acts_, robot_bodies_, robot_q_, robot_v_;  // robot_v_: its DOFs
  std::vector<uint8_t> is_robot_, holds_, protected_body_;
  std::vector<double> radius_;  // each body's reach from its frame origin
  std::vector<int64_t> g1_, g2_, off_;
  Runtime::QueryPairs query_;
  std::vector<int64_t> found_, broken_;
  std::unique_ptr<Plan> cand_ = std::make_unique<Plan>();
  bool mocap_others_ = false;         // a protected body in a mocap tree
  std::vector<double> state_, hold_;  // mj_getState buffers: the state read, a knot's (Holds)
  // The rollout's knots: geom poses, the robot's qpos.
  std::vector<double> kpos_, kmat_, kq_, dev_;
  std::vector<double> kstate_;  // with a view: each knot's whole state (mj_getState)
  // The plan followed: from step plan_step_, its robot qpos per knot, its rest knot.
  std::unique_ptr<Plan> plan_ = std::make_unique<Plan>();
  bool has_plan_ = false;
  std::vector<double> plan_q_, plan_state_;  // plan_state_: its knots' states (a view)
  int64_t plan_step_ = 0, plan_rest_ = -1;
  bool plan_by_screen_ = false;  // verified by the screen before it, not by its own query
  bool envelope_ = false;        // the plan ends in a stop envelope (from env_pos_, env_mat_)
  int64_t env_from_ = 0;         // the knot of a failsafe from the plan's period end it starts at
  std::vector<double> env_pos_, env_mat_;
  // The period's decision.
  std::vector<double> held_, ctrl_;
  bool failsafe_mode_ = true, screened_ = false, guaranteed_ = false, fresh_ = true;
  int64_t prepared_ = -1;  // the step the scratch was last prepared at
  int64_t max_stop_ = 0;
  ShieldCounts counts_;
};

}  // namespace dua

#endif  // DUA_MUJOCO_SHIELD_H_
