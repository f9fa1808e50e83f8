// The safety shield (shield.h). Why each step keeps the guarantee: docs/theory.md, section 10.
#include "shield.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "internal.h"
#include "layout.h"

namespace dua {
namespace {

constexpr int kState = mjSTATE_INTEGRATION;

}  // namespace

std::unique_ptr<Shield> Shield::Make(const mjModel* m, std::shared_ptr<const Tables> tables,
                                     const mjModel* rolled, mjData* roll, mjData* scratch,
                                     const std::vector<int>& robot_actuators,
                                     const std::vector<int>& robot_bodies,
                                     const std::vector<int64_t>& g1, const std::vector<int64_t>& g2,
                                     Failsafe failsafe, const ShieldOptions& o, std::string* error,
                                     mjData* view) {
  const double h = m->opt.timestep;
  if (o.period < 1) {
    *error = "period must be a whole number of physics steps >= 1, not " + std::to_string(o.period);
  } else if (!(o.deviation >= 0.0) || !std::isfinite(o.deviation)) {
    *error = "deviation must be a finite distance >= 0 (m), not " + Shown(o.deviation);
  } else if (!(o.rest_speed > 0.0) || !std::isfinite(o.rest_speed)) {
    *error = "rest_speed must be a positive finite speed (m/s), not " + Shown(o.rest_speed);
  } else if (!(o.stop_distance < 0.0 || std::isfinite(o.stop_distance))) {
    *error =
        "stop_distance must be a finite distance >= 0 (m) or none, not " + Shown(o.stop_distance);
  } else if (!(o.stop_time >= h) || !std::isfinite(o.stop_time)) {
    *error = "stop_time must be a finite time of at least one timestep (" + Shown(h) + " s), not " +
             Shown(o.stop_time);
  } else if (tables->pruned) {
    *error = "the predictor's tables must hold every pair (pairs='all')";
  } else if (std::fabs(tables->schedule.dt - static_cast<double>(o.period) * h) > 1e-9 * h) {
    *error = "the predictor's period (" + Shown(tables->schedule.dt) + " s) is not the shield's (" +
             std::to_string(o.period) + " steps)";
  } else if (rolled->nq != m->nq || rolled->nv != m->nv || rolled->nu != m->nu ||
             rolled->na != m->na || rolled->ngeom != m->ngeom || rolled->nbody != m->nbody ||
             rolled->nmocap != m->nmocap) {
    *error = "the rollout model is not a copy of the model";
  } else if (g1.size() != g2.size()) {
    *error = "g1 and g2 must have the same length";
  } else if (m->opt.integrator == mjINT_RK4) {
    // RK4 collides at its intermediate stages too: a contact there, between two of the step's
    // states, changes the run before any knot the check covers (docs/theory.md, section 10).
    *error =
        "the model's integrator is RK4, whose intermediate stages make contacts between the "
        "states the shield verifies: use Euler, implicit or implicitfast "
        "(model.opt.integrator, or <option integrator=...> in the MJCF)";
  } else if (robot_actuators.empty() || robot_bodies.empty()) {
    *error = "the robot needs actuators and bodies";
  }
  if (!error->empty()) return nullptr;
  std::unique_ptr<Shield> s(new Shield());
  s->is_robot_.assign(m->nbody, 0);
  for (const int b : robot_bodies) {
    if (b < 1 || b >= m->nbody) {
      *error = "robot body id " + std::to_string(b) + " is out of range";
      return nullptr;
    }
    s->is_robot_[b] = 1;
  }
  s->protected_body_.assign(m->nbody, 0);
  for (size_t k = 0; k < g1.size(); ++k) {
    if (g1[k] < 0 || g1[k] >= m->ngeom || g2[k] < 0 || g2[k] >= m->ngeom) {
      *error = "a protected geom id is out of range";
      return nullptr;
    }
    const int b1 = m->geom_bodyid[g1[k]], b2 = m->geom_bodyid[g2[k]];
    if (!s->is_robot_[b1] || b1 == b2) {
      *error = "protected pair " + std::to_string(k) + " (geoms " + std::to_string(g1[k]) + ", " +
               std::to_string(g2[k]) + ") must have a robot geom first and another body's second";
      return nullptr;
    }
    if (!s->is_robot_[b2]) s->protected_body_[b2] = 1;
  }
  s->model_ = m, s->rolled_ = rolled, s->roll_ = roll, s->scratch_ = scratch;
  s->view_ = view;
  for (const int a : robot_actuators) {
    s->robot_ctrl_.push_back(a);
    if (m->actuator_actadr[a] < 0) continue;
    for (int i = 0; i < m->actuator_actnum[a]; ++i)
      s->robot_act_.push_back(m->actuator_actadr[a] + i);
  }
  s->tables_ = tables;
  s->failsafe_ = std::move(failsafe);
  s->o_ = o;
  s->acts_ = robot_actuators;
  s->robot_bodies_ = robot_bodies;
  s->holds_ = s->is_robot_;
  s->g1_ = g1, s->g2_ = g2;
  s->rt_ = std::make_unique<Runtime>(tables, m, 1, 0);
  s->rt_->SetReadLag(0);  // the shield steps it on the state the next mj_step starts from
  s->query_ = s->rt_->PrepareQuery(g1, g2);
  for (size_t k = 0; k < g1.size(); ++k) {
    if (s->query_.slot[k] < 0) {
      *error = "protected pair " + std::to_string(k) + " (geoms " + std::to_string(g1[k]) + ", " +
               std::to_string(g2[k]) + ") is not a pair MuJoCo's filter lets through";
      return nullptr;
    }
  }
  // The model pairs of every other geom pair: switched off, the predictor never judges them.
  const Universe& u = s->rt_->universe();
  std::vector<uint8_t> asked(u.ngp(), 0);
  for (size_t k = 0; k < g1.size(); ++k) {
    asked[u.GeomPair(std::min(g1[k], g2[k]), std::max(g1[k], g2[k]))] = 1;
  }
  for (int64_t p = 0; p < u.npair(); ++p) {
    if (!asked[u.pair_geom[p]]) s->off_.push_back(p);
  }
  s->radius_.assign(m->nbody, 0.0);
  for (int g = 0; g < m->ngeom; ++g) {
    if (m->geom_type[g] == mjGEOM_PLANE) continue;
    const double* p = m->geom_pos + 3 * g;
    const double r = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) + m->geom_rbound[g];
    s->radius_[m->geom_bodyid[g]] = std::max(s->radius_[m->geom_bodyid[g]], r);
  }
  for (int j = 0; j < m->njnt; ++j) {
    if (!s->is_robot_[m->jnt_bodyid[j]]) continue;
    const int type = m->jnt_type[j];
    const int n = type == mjJNT_FREE ? 7 : type == mjJNT_BALL ? 4 : 1;
    for (int i = 0; i < n; ++i) s->robot_q_.push_back(m->jnt_qposadr[j] + i);
    const int nv = type == mjJNT_FREE ? 6 : type == mjJNT_BALL ? 3 : 1;
    for (int i = 0; i < nv; ++i) s->robot_v_.push_back(m->jnt_dofadr[j] + i);
  }
  for (int b = 0; b < m->nbody; ++b) {
    if (s->protected_body_[b] && m->body_mocapid[m->body_rootid[b]] >= 0) s->mocap_others_ = true;
  }
  s->state_.resize(mj_stateSize(m, kState));
  s->hold_.resize(s->state_.size());
  s->held_.assign(m->nu, 0.0);
  s->ctrl_.assign(m->nu, 0.0);
  s->max_stop_ = static_cast<int64_t>(std::ceil(o.stop_time / h - 1e-9));
  return s;
}

Shield::~Shield() = default;

void Shield::Prepare(const mjData* d) {
  if (prepared_ == counts_.steps) return;
  mj_getState(model_, d, state_.data(), kState);
  mj_setState(model_, scratch_, state_.data(), kState);
  Brake::Prepare(model_, scratch_);
  prepared_ = counts_.steps;
}

void Shield::Classify() {
  rt_->Classify(model_, scratch_);
  rt_->Switch(off_, false);
  rt_->Watch(std::vector<uint8_t>(model_->ngeom, 0), {});
}

void Shield::Reset(const mjModel* m, const mjData* d) {
  counts_ = ShieldCounts();
  prepared_ = -1;
  Prepare(d);
  Classify();
  has_plan_ = false;
  plan_by_screen_ = screened_ = false;
  failsafe_mode_ = fresh_ = true;
  guaranteed_ = false;
  (void)m;
}

double Shield::Speed(const mjData* d) const {
  const mjModel* m = model_;
  double top = 0.0;
  for (const int b : robot_bodies_) {
    double v[6];
    mju_transformSpatial(v, d->cvel + 6 * b, 0, d->xpos + 3 * b,
                         d->subtree_com + 3 * m->body_rootid[b], nullptr);
    const double w = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    const double lin = std::sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5]);
    const double speed = lin + w * radius_[b];
    if (!(speed <= top)) top = std::isnan(speed) ? HUGE_VAL : speed;  // a NaN is no rest
  }
  return top;
}

bool Shield::AtRest(const mjData* d) const { return Speed(d) <= o_.rest_speed; }

bool Shield::Holds(const mjModel* m, mjData* d, bool positions) {
  // A knot at rest is the failsafe's rest only where the failsafe keeps the robot there
  // (docs/theory.md, section 10, (S5)): at its pose with the robot's velocities 0, the
  // failsafe's controls (the brake's: the box-bounded least squares of holding, a = 0, within
  // the actuators' limits) and every constraint force (MuJoCo's, the rollout model's: floors,
  // joint limits) leave an acceleration under which a point of the robot would take at least
  // stop_time to reach rest_speed from standing still. A motor too weak for gravity sags at
  // once; a robot the failsafe holds has an acceleration of rounding size.
  mj_getState(m, d, hold_.data(), kState);
  for (const int i : robot_v_) d->qvel[i] = 0.0;
  // mj_forward's stages, the failsafe's controls between the velocities and the actuation; the
  // positions' (collisions and constraint rows included) are a knot's own when mj_step1 left
  // them, as qvel does not enter them.
  if (!positions) mj_fwdPosition(m, d);
  mj_fwdVelocity(m, d);
  failsafe_(m, d, ctrl_.data());
  std::copy_n(ctrl_.data(), m->nu, d->ctrl);
  mj_forwardSkip(m, d, mjSTAGE_VEL, 1);
  for (const int i : robot_v_) d->qvel[i] = d->qacc[i];
  mj_comVel(m, d);  // a body's velocity is linear in qvel: Speed reads the points' acceleration
  const bool holds = Speed(d) * o_.stop_time <= o_.rest_speed;
  if (!holds) {
    // The rollout goes on from this knot: its state and mj_step1's values back.
    mj_setState(m, d, hold_.data(), kState);
    mj_step1(m, d);
    ++counts_.unheld;
  }
  return holds;
}

int64_t Shield::Roll(const double* intended, int64_t nint, int64_t last) {
  const mjModel* m = rolled_;
  mjData* d = roll_;
  const int64_t ngeom = m->ngeom, nq = static_cast<int64_t>(robot_q_.size());
  const auto rows = static_cast<size_t>(last + 1 + max_stop_);
  if (kpos_.size() < rows * 3 * ngeom) {
    kpos_.resize(rows * 3 * ngeom), kmat_.resize(rows * 9 * ngeom), kq_.resize(rows * nq);
  }
  if (view_ && kstate_.size() < rows * state_.size()) kstate_.resize(rows * state_.size());
  const auto keep = [&](int64_t j) {
    std::copy_n(d->geom_xpos, 3 * ngeom, kpos_.begin() + 3 * ngeom * j);
    std::copy_n(d->geom_xmat, 9 * ngeom, kmat_.begin() + 9 * ngeom * j);
    for (int64_t i = 0; i < nq; ++i) kq_[nq * j + i] = d->qpos[robot_q_[i]];
    if (view_) mj_getState(m, d, kstate_.data() + state_.size() * j, kState);
  };
  const auto joint_speed = [&] {
    double s = 0.0;
    for (const int i : robot_v_) s += std::fabs(d->qvel[i]);
    return s;
  };
  mj_setState(m, d, state_.data(), kState);
  ++counts_.rollouts;
  double speed = HUGE_VAL, joints = 0.0;  // the last knot's speed and its joint speeds' sum
  for (int64_t j = 0;; ++j) {
    bool unheld = false;  // this knot at rest, and the failsafe cannot hold it (asked once)
    // The rest knot ends the rollout, and its collisions and constraints are never used: when
    // the last knot's speed, scaled by how its joint speeds' sum changed since (this knot's
    // qvel is known), puts this one at rest, its kinematics and velocities come first (the
    // functions mj_step1 starts with, so the same values), and mj_step1 only if it is not at
    // rest after all. The guess decides what is computed, never a value.
    if (j > nint && speed * joint_speed() <= 2.0 * o_.rest_speed * joints) {
      mj_kinematics(m, d);
      mj_comPos(m, d);
      mj_comVel(m, d);
      if (AtRest(d)) {
        keep(j);
        if (Holds(m, d, false)) return j;
        unheld = true;
      }
    }
    // Knot j's state: its kinematics and velocities (mj_step1: what the step computes first).
    // A guess its failsafe could not hold has them already: Holds put the knot's state back and
    // ran mj_step1 on it, and its poses are kept.
    if (!unheld) {
      mj_step1(m, d);
      keep(j);
    }
    speed = Speed(d);
    joints = joint_speed();
    if (j >= nint && speed <= o_.rest_speed && !unheld && Holds(m, d, true)) return j;
    if (j == last) return -1;
    if (j < nint) {
      std::copy_n(intended, m->nu, d->ctrl);
    } else {
      failsafe_(m, d, ctrl_.data());
      std::copy_n(ctrl_.data(), m->nu, d->ctrl);
    }
    mj_step2(m, d);
    ++counts_.rollout_steps;
  }
}

bool Shield::BuildPlan(int64_t n, int64_t tail) {
  const mjModel* m = model_;
  const auto nbody = static_cast<int64_t>(m->nbody);
  // The robot's deviation: its own at the rolled knots, and past `tail` (the stop envelope's
  // knots, each the pose of knot tail - 1) the envelope's reach on top of twice it: the run is
  // within D of the plan when the failsafe starts, and within D of the failsafe after.
  dev_.resize(static_cast<size_t>(n * nbody));
  const double far = 2.0 * o_.deviation + o_.stop_distance;
  for (int64_t j = 0; j < n; ++j) {
    for (int64_t b = 0; b < nbody; ++b) {
      dev_[j * nbody + b] = is_robot_[b] ? (j < tail ? o_.deviation : far) : 0.0;
    }
  }
  const Tables& t = *tables_;
  // FromPoses rebuilds every field: the candidate's object is reused period after period.
  return cand_
      ->FromPoses(m, n, kpos_.data(), kmat_.data(), holds_.data(), dev_.data(), scratch_->time,
                  m->opt.timestep, t.spheres.data(), t.nsphere(), rt_->plan_geoms())
      .empty();
}

int64_t Shield::FirstContact() {
  rt_->QueryKnots(model_, scratch_, *cand_, 0, &query_, &found_);
  int64_t first = cand_->nknot();
  // -1 (the plan holds neither body) and -2 (a pair unknown) cannot happen for the pairs Make
  // accepted; either would be no verdict, taken as contact now.
  for (const int64_t k : found_) first = std::min(first, std::max(k, int64_t{0}));
  return first;
}

void Shield::Install(int64_t n, int64_t rest) {
  std::swap(plan_, cand_);
  const auto nq = robot_q_.size();
  plan_q_.assign(kq_.begin(), kq_.begin() + static_cast<std::ptrdiff_t>(n * nq));
  if (view_) {
    const auto ns = static_cast<std::ptrdiff_t>(state_.size());
    plan_state_.assign(kstate_.begin(), kstate_.begin() + n * ns);
  }
  plan_step_ = counts_.steps;
  plan_rest_ = rest;
  has_plan_ = true;
}

void Shield::Break(int64_t* counter) {
  ++*counter;
  has_plan_ = false;
  guaranteed_ = false;
  failsafe_mode_ = true;
  fresh_ = true;
}

void Shield::Check(const mjData* d) {
  if (!has_plan_) return;
  const int64_t k = counts_.steps - plan_step_;
  const auto nq = static_cast<int64_t>(robot_q_.size());
  if (k < plan_->nknot()) {
    // A run that is its plan (a rollout of the same simulation) has the same joint positions,
    // so the same poses: nothing to compute.
    const double* q = plan_q_.data() + nq * k;
    bool same = true;
    for (int64_t i = 0; i < nq && same; ++i) same = d->qpos[robot_q_[i]] == q[i];
    if (same) return;
    Prepare(d);
    broken_.clear();
    const Tables& t = *tables_;
    plan_->Check(scratch_->geom_xpos, scratch_->geom_xmat, k, t.events_rec.data(), t.nbody_events,
                 nullptr, &broken_);
    if (!broken_.empty()) Break(&counts_.plan_breaks);
  } else if (plan_rest_ >= 0) {
    Prepare(d);
    if (!AtRest(scratch_)) Break(&counts_.hold_breaks);
  } else {
    // The plan ran out before the robot came to rest: nothing covers it any longer.
    has_plan_ = false;
    fresh_ = true;
  }
}

bool Shield::Screen() const {
  const double dt = static_cast<double>(o_.period) * model_->opt.timestep;
  const double now = static_cast<double>(rt_->step()) * dt;
  return rt_->watched().expiry >= now + dt + o_.stop_time;
}

void Shield::Period(const mjModel* m, const mjData* d, const double* intended) {
  ++counts_.periods;
  Prepare(d);
  std::copy_n(intended, m->nu, held_.data());
  const bool first = counts_.steps == 0;
  bool robot_broke = false, others_broke = false;
  if (!first) {
    // The predictor's step: the violation check, the verdicts due, the mocap velocities.
    bool ok = rt_->ClockOf(scratch_->time) == Runtime::Clock::kOnePeriod;
    if (ok) ok = rt_->Step(m, scratch_) >= 0;
    if (!ok) {  // the clock jumped, or a state that is not finite: start over, no guarantee
      Classify();
      others_broke = true;
    }
    for (const int64_t b : rt_->FlaggedBodies()) {
      if (is_robot_[b]) robot_broke = true;
      if (protected_body_[b]) others_broke = true;
    }
  }
  const bool was_screened = screened_;
  screened_ = false;
  // Events: another body's bounds broke, or the robot's own after the screen relied on them.
  const bool robot_event = robot_broke && (was_screened || plan_by_screen_);
  if (others_broke) Break(&counts_.bound_events);
  if (robot_event) Break(&counts_.robot_events);
  // The first period after a reset knows no differenced mocap velocity yet (0 until the next
  // predictor step): nothing that rests on the mocap bodies' reach is checked then.
  const bool blind = first && mocap_others_;
  bool touches = false;  // a protected pair may touch at the state read (asked below)
  if (!others_broke && !robot_event && !blind) {
    if (o_.screen && Screen()) {
      screened_ = true;
      has_plan_ = plan_by_screen_ = false;
      failsafe_mode_ = fresh_ = false;
      guaranteed_ = true;
      ++counts_.screened;
      return;
    }
    // Every candidate's knot 0 is this very state, whatever the intended controls: a protected
    // pair that may touch here refuses them all (their rest knot is p >= 1 or later), so none is
    // rolled out (docs/theory.md, section 10). Asked only after a period that ran the failsafe
    // (a refusal, an event): after one that passed, this state is on a verified plan or within
    // the screen's window, and a touch here is rare; unasked, the candidate's own query answers.
    touches = failsafe_mode_ && TouchesNow();
    if (!touches) {
      const int64_t p = o_.period;
      int64_t rest, n, tail;
      if (o_.stop_distance >= 0.0) {
        // The intended controls rolled for the period and the failsafe for one more; if the
        // robot is not at rest by then, the stop envelope from there: within stop_distance of
        // that pose, at rest stop_time later (checked when a failsafe is rolled out).
        const int64_t e = 2 * p;
        rest = Roll(intended, p, e);
        if (rest < 0) {
          const int64_t ngeom = model_->ngeom, nq = static_cast<int64_t>(robot_q_.size());
          for (int64_t j = e + 1; j <= e + max_stop_; ++j) {
            std::copy_n(kpos_.begin() + 3 * ngeom * e, 3 * ngeom, kpos_.begin() + 3 * ngeom * j);
            std::copy_n(kmat_.begin() + 9 * ngeom * e, 9 * ngeom, kmat_.begin() + 9 * ngeom * j);
            std::copy_n(kq_.begin() + nq * e, nq, kq_.begin() + nq * j);
            if (view_) {
              const auto ns = static_cast<int64_t>(state_.size());
              std::copy_n(kstate_.begin() + ns * e, ns, kstate_.begin() + ns * j);
            }
          }
          rest = e + max_stop_;
          tail = e + 1;
        } else {
          tail = rest + 1;
        }
        n = rest + 1;
      } else {
        rest = Roll(intended, p, p + max_stop_);
        n = rest + 1, tail = n;
      }
      if (rest >= 0 && BuildPlan(n, tail) && FirstContact() >= rest) {
        Install(n, rest);
        envelope_ = tail < n;
        if (envelope_) {
          // The failsafe that may follow starts at knot p: its knots from tail - 1 - p on are
          // the envelope's, which starts from knot tail - 1's pose.
          const int64_t e = tail - 1, ngeom = model_->ngeom;
          env_from_ = e - p;
          env_pos_.assign(kpos_.begin() + 3 * ngeom * e, kpos_.begin() + 3 * ngeom * (e + 1));
          env_mat_.assign(kmat_.begin() + 9 * ngeom * e, kmat_.begin() + 9 * ngeom * (e + 1));
        }
        plan_by_screen_ = false;
        failsafe_mode_ = fresh_ = false;
        guaranteed_ = true;
        ++counts_.accepted;
        return;
      }
    }
  }
  ++counts_.rejected;
  failsafe_mode_ = true;
  // The verified plan's failsafe, or its hold (a plan with a stop envelope has no failsafe to
  // follow: one is rolled out below).
  if (has_plan_ && !fresh_ && !envelope_) return;
  // A failsafe from now, rolled out: verified by its own query (or at rest already), or covered
  // by the check of the period before when it stops within stop_time: the screen ruled contact
  // out until stop_time from now; a stop envelope, within stop_distance of here.
  const bool by_envelope = has_plan_ && !fresh_ && envelope_;
  const int64_t last = max_stop_ + (by_envelope ? env_from_ : 0);
  // Its knot 0 is this very state, whose kinematics and velocities Prepare computed as the
  // rollout's mj_step1 would: a robot at rest here is its own rest knot, with nothing to roll.
  int64_t rest = 0;
  if (AtRest(scratch_) && HoldsNow()) {
    KnotZero();
  } else {
    rest = Roll(nullptr, 0, last);
  }
  const int64_t n = rest >= 0 ? rest + 1 : last + 1;
  if (!BuildPlan(n, n)) {
    Break(&counts_.stop_breaks);
    return;
  }
  // A pair that may touch at the state read touches at this plan's knot 0 too, before its
  // rest knot: no query needed to say so.
  const bool verified = rest == 0 || (rest > 0 && !blind && !touches && FirstContact() >= rest);
  bool covered = rest >= 0 && !robot_broke && !others_broke && (was_screened || by_envelope);
  if (covered && by_envelope) covered = WithinEnvelope(n);
  if (rest < 0 || (by_envelope && !covered && !verified)) ++counts_.stop_breaks;
  if (verified) {
    guaranteed_ = true;
  } else if (!covered) {
    guaranteed_ = false;
    ++counts_.unverified;
  }
  Install(n, rest);
  envelope_ = false;
  plan_by_screen_ = !verified && covered && was_screened;
  fresh_ = false;
}

void Shield::KnotZero() {
  // mj_step1's kinematics of this state, which Prepare computed alike.
  const int64_t ngeom = model_->ngeom, nq = static_cast<int64_t>(robot_q_.size());
  if (kpos_.size() < static_cast<size_t>(3 * ngeom)) {
    kpos_.resize(3 * ngeom), kmat_.resize(9 * ngeom), kq_.resize(nq);
  }
  std::copy_n(scratch_->geom_xpos, 3 * ngeom, kpos_.begin());
  std::copy_n(scratch_->geom_xmat, 9 * ngeom, kmat_.begin());
  for (int64_t i = 0; i < nq; ++i) kq_[i] = scratch_->qpos[robot_q_[i]];
  if (view_) {
    if (kstate_.size() < state_.size()) kstate_.resize(state_.size());
    std::copy(state_.begin(), state_.end(), kstate_.begin());
  }
}

bool Shield::HoldsNow() {
  mj_setState(rolled_, roll_, state_.data(), kState);
  return Holds(rolled_, roll_, false);
}

bool Shield::TouchesNow() {
  KnotZero();
  return !BuildPlan(1, 1) || FirstContact() == 0;
}

bool Shield::WithinEnvelope(int64_t n) const {
  // Every corner of every robot body's box, from the envelope's start on, within stop_distance
  // + D of where the envelope put it (Lemma 8.1's measure): the run is within D of this
  // failsafe, which is within stop_distance + D of the envelope's pose, so within what the
  // envelope was checked for. (Its knots before were the candidate's own, checked.)
  const Tables& t = *tables_;
  const double limit = o_.stop_distance + o_.deviation;
  const int64_t ngeom = model_->ngeom;
  for (int64_t i = 0; i < t.nbody_events; ++i) {
    const double* box = t.events_rec.data() + i * kBNcol;
    if (!is_robot_[static_cast<int64_t>(box[kBBody])]) continue;
    const auto g = static_cast<int64_t>(box[kBFrame]);
    for (int64_t j = env_from_; j < n; ++j) {
      const double* pos = kpos_.data() + 3 * (ngeom * j + g);
      const double* mat = kmat_.data() + 9 * (ngeom * j + g);
      if (!BoxWithin(box, pos, mat, env_pos_.data() + 3 * g, env_mat_.data() + 9 * g, limit)) {
        return false;
      }
    }
  }
  return true;
}

void Shield::View(const mjData* d) {
  const mjModel* m = rolled_;
  if (has_plan_) {
    // The plan's knot for this step (its last past the rest knot: the robot held there), as the
    // rollout had it; the robot's own coordinates the run's (the same, on the plan).
    const auto ns = static_cast<int64_t>(state_.size());
    const int64_t k = std::min(counts_.steps - plan_step_, plan_->nknot() - 1);
    mj_setState(m, view_, plan_state_.data() + ns * k, kState);
    for (const int i : robot_q_) view_->qpos[i] = d->qpos[i];
    for (const int i : robot_v_) view_->qvel[i] = d->qvel[i];
    for (const int i : robot_act_) view_->act[i] = d->act[i];
    for (const int a : robot_ctrl_) view_->ctrl[a] = d->ctrl[a];
  } else {
    mj_getState(model_, d, hold_.data(), kState);
    mj_setState(m, view_, hold_.data(), kState);
  }
  // What the rollout computed at its knots before calling the failsafe.
  mj_step1(m, view_);
}

void Shield::Control(const mjModel* m, const mjData* d, const double* intended, double* ctrl) {
  if (counts_.steps > 0) Check(d);
  if (counts_.steps % o_.period == 0) Period(m, d, intended);
  std::copy_n(intended, m->nu, ctrl);
  if (failsafe_mode_) {
    if (view_) {
      View(d);
      failsafe_(rolled_, view_, ctrl_.data());
    } else {
      Prepare(d);
      failsafe_(m, scratch_, ctrl_.data());
    }
    for (const int a : acts_) ctrl[a] = ctrl_[a];
    ++counts_.interventions;
  } else {
    for (const int a : acts_) ctrl[a] = held_[a];
  }
  if (!guaranteed_) ++counts_.unguaranteed;
  ++counts_.steps;
}

}  // namespace dua
