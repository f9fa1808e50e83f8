// The predictor at run time (runtime.h). Proofs of what each step keeps: docs/theory.md.
#include "runtime.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <numeric>
#include <string>
#include <type_traits>
#include <utility>

#include "internal.h"
#include "layout.h"

namespace dua {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::vector<int64_t> Iota(int64_t n) {
  std::vector<int64_t> v(static_cast<size_t>(n));
  std::iota(v.begin(), v.end(), int64_t{0});
  return v;
}

// How many of a replaced plan's knots a replan checks its shadow at (the bodies' nesting and the
// relative pairs'): old's from the next state's (jo0, -1 if it has none) to its last knot, while
// their time is within the shadow's span (until).
int64_t SpanKnots(const Plan& old, int64_t jo0, double next, double h, double until) {
  int64_t span = 0;
  while (jo0 >= 0 && jo0 + span < old.nknot() &&
         !(next + static_cast<double>(span) * h > until + 1e-6 * h)) {
    ++span;
  }
  return span;
}

}  // namespace

Runtime::Runtime(std::shared_ptr<const Tables> tables, const mjModel* m, int64_t log_steps,
                 int64_t log_min)
    : tables_(std::move(tables)),
      log_steps_(std::max<int64_t>(log_steps, 1)),
      log_min_(std::max<int64_t>(log_min, 0)),
      schedule_(std::make_shared<Schedule>(tables_->schedule, 0)),
      mocap_(m) {
  const Tables& t = *tables_;
  const int64_t n = t.universe.npair();
  if (t.pruned) pruned_.Allocate(t.held), own_ = t.universe;
  // Nothing outside mirrors a free runtime's pair ids: it forgets as the plugin does.
  if (t.free) forget_after_ = kForgetDefault;
  on_.assign(n, 1);
  gp_count_.assign(t.universe.ngp(), 0);
  exact_records_ = t.universe.exact;
  events_prev_.assign(EventStateLen(t.nbody_events), 0.0);
  events_meta_.assign(3, 0);
  events_flagged_.assign(std::max<int64_t>(t.nbody_events, 1), 0);
  // Free spheres (no model): the caller's states are read as they are, nothing memoised.
  const int nbody = m ? m->nbody : 0;
  if (!t.free) {
    point_state_.assign(6 * static_cast<size_t>(t.nsphere()), 0.0);
    point_epoch_.assign(t.nsphere(), -1);
  }
  // Each body's row of the violation check (whose boxes the plans measure deviations at), and
  // the bodies with covered geoms but no row (the check is off): no plan may hold those.
  body_row_.assign(nbody, -1);
  for (int64_t i = 0; i < t.nbody_events; ++i) {
    body_row_[static_cast<int64_t>(t.events_rec[kBNcol * i + kBBody])] = i;
  }
  unboxed_.assign(nbody, 0);
  for (int64_t i = 0; m && i < t.nsphere(); ++i) {
    const auto g = static_cast<int64_t>(t.spheres[kSphereNcol * i + kSphereFrame]);
    if (t.geom_row[g] < 0) unboxed_[m->geom_bodyid[g]] = 1;
  }
  // What a plan's knots are read for: the covered geoms (sphere centres, the exact level, the
  // pairs a pruned predictor learns: they are covered), the geoms of the known pairs, every
  // plane (a half-space pair's, a held body's check), and the violation check's box frames.
  // Free spheres (no model) have no plans.
  if (m) {
    std::vector<uint8_t> read(m->ngeom, 0);
    for (int64_t i = 0; i < t.nsphere(); ++i) {
      read[static_cast<int64_t>(t.spheres[kSphereNcol * i + kSphereFrame])] = 1;
    }
    for (const int64_t g : t.universe.geom_pairs) read[g] = 1;
    for (int64_t i = 0; i < t.nbody_events; ++i) {
      read[static_cast<int64_t>(t.events_rec[kBNcol * i + kBFrame])] = 1;
    }
    for (int g = 0; g < m->ngeom; ++g) {
      if (m->geom_type[g] == mjGEOM_PLANE) read[g] = 1;
      if (read[g]) plan_geoms_.push_back(g);
    }
  }
  plan_ok_.assign(nbody, 0);
  Hold(Iota(n));  // every pair known, until a pruned classification chooses
  schedule_ = std::make_shared<Schedule>(t.schedule, npair());
  NewLog();
}

Runtime::Runtime(const Runtime& o)
    : tables_(o.tables_),
      log_steps_(o.log_steps_),
      log_min_(o.log_min_),
      schedule_(std::make_shared<Schedule>(*o.schedule_)),
      plan_(o.plan_),  // immutable: shared; the mjData it is queried on is made when needed
      last_time_(o.last_time_),
      step_(o.step_),
      nstanding_(o.nstanding_),
      min_tau_(o.min_tau_),
      classified_(o.classified_),
      basis_live_(o.basis_live_),
      ids_(o.ids_),
      events_meta_(o.events_meta_),
      stands_(o.stands_),
      standing_(o.standing_),
      standing_at_(o.standing_at_),
      gp_count_(o.gp_count_),
      cleared_(o.cleared_),
      args_(o.args_),
      point_state_(o.point_state_),
      exact_records_(o.exact_records_),
      events_prev_(o.events_prev_),
      witness_(o.witness_),
      point_epoch_(o.point_epoch_),
      events_flagged_(o.events_flagged_),
      pruned_(o.pruned_),
      own_(o.own_),
      held_pairs_(o.held_pairs_),
      held_start_(o.held_start_),
      held_members_(o.held_members_),
      on_(o.on_),
      mocap_(o.mocap_),
      rebuilds_(o.rebuilds_),
      renewals_(o.renewals_),
      universe_version_(o.universe_version_),
      held_version_(o.held_version_),
      plan_ok_(o.plan_ok_),
      basis_(o.basis_),
      basis_prev_(o.basis_prev_),
      shadows_(o.shadows_),
      pending_due_(o.pending_due_),
      pending_rel_(o.pending_rel_),
      rel_ok_(o.rel_ok_),
      body_row_(o.body_row_),
      unboxed_(o.unboxed_),
      plan_geoms_(o.plan_geoms_),
      plan_breaks_(o.plan_breaks_),
      plan_serial_(o.plan_serial_),
      read_lag_(o.read_lag_),
      forget_after_(o.forget_after_),
      gp_seen_(o.gp_seen_),
      forgotten_(o.forgotten_),
      compactions_(o.compactions_) {
  NewLog();  // never append to another run's log
}

void Runtime::NewLog() {
  const int64_t room = std::max(schedule_->width(), npair());
  const int64_t capacity = std::max({log_steps_ * room, log_min_, int64_t{1}});
  log_used_ = log_start_ = 0;
  // No one else holds the log (no Alarms of an earlier step is alive): it is written again from
  // its start, not replaced. The plugin's log has room for one step, so it filled at every step
  // that alarmed: a fresh one each time was 4 % of the plugin's time on g1 at accel=200.
  if (log_ && log_.use_count() == 1 && log_->capacity() >= capacity) return;
  log_ = std::make_shared<AlarmLog>(capacity);
}

void Runtime::Hold(const std::vector<int64_t>& held) {
  const Tables& t = *tables_;
  const Universe& u = universe();
  ids_ = held;
  const auto n = static_cast<int64_t>(held.size());
  if (t.pruned) {
    held_pairs_.resize(kPairNcol * n);
    for (int64_t k = 0; k < n; ++k) {
      std::copy_n(u.pairs.begin() + kPairNcol * held[k], kPairNcol,
                  held_pairs_.begin() + kPairNcol * k);
    }
    if (t.exact) {
      // The exact level's records afresh (the direction that served last is the held pair's).
      exact_records_.resize(kXNcol * n);
      for (int64_t k = 0; k < n; ++k) {
        std::copy_n(u.exact.begin() + kXNcol * held[k], kXNcol,
                    exact_records_.begin() + kXNcol * k);
      }
    }
  }
  // Indexed by the violation check's rows: each checked body's held pairs (none unchecked).
  held_start_.assign(t.nbody_events + 1, 0);
  held_members_.assign(1, 0);
  if (t.nbody_events) {
    std::vector<int64_t> g1(n), g2(n);
    for (int64_t k = 0; k < n; ++k) g1[k] = u.geom1[held[k]], g2[k] = u.geom2[held[k]];
    held_members_.resize(std::max<int64_t>(2 * n, 1));
    held_members_.resize(std::max<int64_t>(
        dua_index_by_row(t.geom_row.data(), g1.data(), g2.data(), n, t.nbody_events,
                         held_start_.data(), held_members_.data()),
        1));
  }
  // No query made yet for the held pairs (the directions are the universe's, too).
  if (t.exact) witness_.assign(6 * static_cast<size_t>(std::max<int64_t>(n, 1)), kNaN);
  stands_.assign(n, 0);
  standing_.clear();
  standing_at_.assign(n, -1);
  basis_.assign(n, 0), basis_prev_.assign(n, 0);  // a pair new to the held set: the bounds
  cleared_.assign(n, -1);
  ++held_version_;
  held_bound_ = false;  // the buffers above may have moved: Bind points args_ at them again
}

DUA_HOT dua_step_args& Runtime::Bind(const mjModel* m, const mjData* d) {
  const Tables& t = *tables_;
  dua_step_args& a = args_;
  // What only the tables and the held set's buffers give stays between two calls (BindHeld).
  if (!held_bound_) BindHeld();
  a.schedule = *schedule_->state();
  // Free spheres: the caller's states (SetPoints), no frame.
  a.frame = d ? FrameOf(d, mocap_.twist.data()) : dua_frame{};
  a.points = t.free ? points_ : dua_points{};
  dua_exact& x = a.exact;
  x.model = m;
  x.data = d;
  // Room to index d's contacts (the exact level's skip of pairs in contact).
  if (t.exact && static_cast<int64_t>(contact_keys_.size()) < d->ncon) GrowContacts(d->ncon);
  x.contact_keys = contact_keys_.data();
  x.contact_dist = contact_dist_.data();
  x.contact_room = static_cast<int64_t>(contact_keys_.size());
  x.contact_count = -1;
  a.log_pairs = log_->pair.data();
  a.log_tau = log_->tau.data();
  a.log_new = log_->fresh.data();
  dua_plan& pl = a.plan;
  pl.impl = plan_.get();
  // Without a plan every basis is the bounds' (0) once each pair was evaluated again since the
  // last one: then the step's shift of them (every evaluated pair's, 2 % of the plugin's
  // instructions on dmc_dog) would write zeros over zeros, and is skipped (null).
  basis_live_ = plan_ != nullptr || (basis_live_ && BasisNonzero());
  pl.basis = basis_live_ ? basis_.data() : nullptr;
  pl.basis_prev = basis_live_ ? basis_prev_.data() : nullptr;
  pl.cleared = cleared_.data();
  if (plan_) BindPlan(m);
  return a;
}

void Runtime::BindHeld() {
  const Tables& t = *tables_;
  dua_step_args& a = args_;
  a.abi = DUA_ABI_VERSION;
  a.pairs = t.pruned ? held_pairs_.data() : t.universe.pairs.data();
  a.spheres = t.spheres.data();
  a.shapes = t.shapes.data();
  a.ids = ids_.data();
  dua_exact& x = a.exact;
  x.on = t.exact ? 1 : 0;
  x.geoms = t.geoms.data();
  x.records = exact_records_.data();
  x.witness = witness_.data();
  x.below = t.exact_below;
  x.query_below = t.query_below;
  x.hull_at = t.hull_at.data();
  x.climb = t.climb.data();
  x.climb_at = t.climb_at.data();
  dua_events& e = a.events;
  e.nbody = t.nbody_events;
  e.rec = t.events_rec.data();
  e.prev = events_prev_.data();
  e.meta = events_meta_.data();
  e.flagged = events_flagged_.data();
  e.start = held_start_.data();
  e.members = held_members_.data();
  e.params = t.events_params.data();
  a.point_state = point_state_.data();
  a.point_epoch = point_epoch_.data();
  a.timestep = t.timestep;
  a.period = static_cast<int64_t>(std::nearbyint(t.schedule.dt / t.timestep));
  held_bound_ = true;
}

void Runtime::GrowContacts(int ncon) { contact_keys_.resize(ncon), contact_dist_.resize(ncon); }

bool Runtime::BasisNonzero() const {
  auto zero = [](const std::vector<uint8_t>& v) {
    return std::all_of(v.begin(), v.end(), [](uint8_t b) { return b == 0; });
  };
  return !(zero(basis_) && zero(basis_prev_));
}

void Runtime::BindPlan(const mjModel* m) {
  const Tables& t = *tables_;
  dua_plan& pl = args_.plan;
  if (!plan_data_) plan_data_.reset(mj_makeData(m));
  const Universe& u = universe();
  // A batch is every pair (a classification) or a step's selection, which can outnumber the
  // held pairs (the rank schedule takes a pair made due both from its slot and from the queue).
  planned_.resize(std::max<size_t>({ids_.size(), static_cast<size_t>(schedule_->width()), 1}));
  pl.body_ok = plan_ok_.data();
  pl.rel_ok = rel_ok_.data();
  pl.geom1 = u.geom1.data();
  pl.geom2 = u.geom2.data();
  pl.geom_body = m->geom_bodyid;
  pl.geom_row = t.geom_row.data();
  pl.data = plan_data_.get();
  pl.planned = planned_.data();
}

std::string Runtime::SetPlan(const mjModel* m, const dua_plan_input& in, double* departures) {
  if (!classified_) return "comes before the first classification: reset the predictor first";
  if (!plan_data_) plan_data_.reset(mj_makeData(m));
  if (!plan_data_) return "needs an mjData that MuJoCo could not allocate";
  auto plan = std::make_shared<Plan>();
  if (!knots_ || knots_model_ != m) {
    knots_ = std::make_unique<KnotKinematics>(m, plan_geoms_);
    knots_model_ = m;
  }
  std::string error =
      plan->Build(m, plan_data_.get(), in, m->opt.timestep, tables_->spheres.data(),
                  tables_->nsphere(), plan_geoms_, plan_.get(), plan_pool_, knots_.get());
  if (!error.empty()) return error;
  for (int b = 0; b < m->nbody; ++b) {
    if (plan->holds(b) && unboxed_[b]) {
      return "holds body " + std::to_string(b) +
             ", whose deviation is measured at the violation check's box, which this predictor "
             "does not have: build it with violation_events on (the default)";
    }
  }
  error = RelativeBoxed(m, *plan);
  if (!error.empty()) return error;
  plan->SetRelativeFrames(tables_->events_rec.data(), body_row_.data());
  const double h = m->opt.timestep;
  const double next = last_time_ + tables_->schedule.dt - read_lag_ * h;
  const int64_t jn_next = plan->KnotOf(next);  // the new plan's knot of the next state
  if (jn_next < 0) {
    return "does not cover the state the next step reads (time " + std::to_string(next) +
           "): start it at or before that time, on a whole number of timesteps from it, with " +
           "knots past it";
  }
  // The plan the held pairs' walks were under (cleared_): it becomes the newest shadow, which
  // is dropped below where the new plan nests in it, so it is held here until the carry.
  const std::shared_ptr<const Plan> walked = plan_;
  Retire();
  // Each shadow's check of a body can wait for the first state in its span at which the new
  // plan leaves its tube: until then the new plan's own check proves the body within it. The
  // newest shadow first: an older one that held its plan nested, where the new plan nests in
  // it, holds the new plan nested too (Lemma 8.6), and its knots are not checked.
  const Tables& t = *tables_;
  const Shadow* newest = shadows_.empty() ? nullptr : &shadows_.back();
  std::vector<int64_t> open;    // rows of the violation check still nested, knot by knot
  std::vector<BoxReach> reach;  // each row's box's, for its checks at every knot
  if (!shadows_.empty()) {
    reach.reserve(static_cast<size_t>(t.nbody_events));
    for (int64_t i = 0; i < t.nbody_events; ++i) reach.emplace_back(&t.events_rec[kBNcol * i]);
  }
  // Per body (and relative pair of the walked plan), the new plan's first knot from which it
  // is not known to stay in the walked plan's tube (its departure, the span's end, or the
  // first knot where nothing was checked): the walks' cleared knots before it carry over.
  std::vector<int64_t> nest_end, rel_end;
  for (auto it = shadows_.rbegin(); it != shadows_.rend(); ++it) {
    Shadow& sh = *it;
    const Plan& old = *sh.plan;
    const bool carry = &sh == newest && walked != nullptr && sh.plan == walked;
    // (Its span within the newest's, as the lemma has it: spans end H + latency dt past their
    // retirement, later for a later one, unless the schedule changed between.)
    const bool link = &sh != newest && sh.nested_in == newest->serial && newest->until >= sh.until;
    const Shadow* chain = link ? newest : nullptr;
    std::fill(sh.from.begin(), sh.from.end(), kInf);
    open.clear();
    for (int64_t i = 0; i < t.nbody_events; ++i) {
      const auto b = static_cast<int64_t>(t.events_rec[kBNcol * i + kBBody]);
      const bool held = old.holds(b) && sh.ok[b];
      const bool chained = chain != nullptr && sh.nested[b] && chain->nested[b];
      // Nested without a check, or checked: nested until it departs (marked below).
      sh.nested[b] = held;
      if (held && !chained) open.push_back(i);
    }
    // Four knots at a time, every body still nested at once (a block's poses are read together),
    // each body until its first departure (BodyDeparture: the block's screen in lanes). The knots
    // checked: the shadow's from the next state's, within its span; past the new plan's last
    // knot, or where the new plan does not hold the body, the body departs.
    const int64_t jo0 = old.KnotOf(next), jn0 = jn_next;
    const int64_t span = SpanKnots(old, jo0, next, h, sh.until);
    if (carry) {
      nest_end.assign(m->nbody, jn0);
      for (const int64_t i : open) {
        nest_end[static_cast<int64_t>(t.events_rec[kBNcol * i + kBBody])] = jn0 + span;
      }
    }
    for (int64_t s = 0; s < span && !open.empty(); s += kLanes) {
      const int64_t count = std::min<int64_t>(kLanes, span - s);
      const int64_t planned = std::clamp<int64_t>(plan->nknot() - jn0 - s, 0, count);
      size_t kept = 0;
      for (const int64_t i : open) {
        const double* box = t.events_rec.data() + kBNcol * i;
        const auto b = static_cast<int64_t>(box[kBBody]);
        const int64_t d = plan->holds(b)
                              ? BodyDeparture(*plan, jn0 + s, old, jo0 + s, box, reach[i], planned)
                              : 0;
        if (d < count) {
          sh.from[b] = next + static_cast<double>(s + d) * h;
          sh.nested[b] = 0;
          if (carry) nest_end[b] = jn0 + s + d;
        } else {
          open[kept++] = i;
        }
      }
      open.resize(kept);
    }
    RelativeDepartures(*plan, next, h, chain, &sh);
    if (carry) {
      rel_end.assign(old.nrel(), jn0);
      for (int64_t r = 0; r < old.nrel(); ++r) {
        if (sh.rel_nested[r]) {
          rel_end[r] = jn0 + span;
        } else if (sh.rel_from[r] < kInf) {
          rel_end[r] = jn0 + std::llround((sh.rel_from[r] - next) / h);
        }
      }
    }
  }
  for (Shadow& sh : shadows_) sh.nested_in = plan_serial_ + 1;
  if (departures != nullptr) {
    std::fill(departures, departures + m->nbody, kInf);
    for (const Shadow& sh : shadows_) {
      for (int b = 0; b < m->nbody; ++b) departures[b] = std::min(departures[b], sh.from[b]);
    }
  }
  // A shadow the new plan never leaves over its span is nested: a body beyond it is beyond the
  // new plan (and the plans after it, while they keep to this one), whose checks find it at the
  // same state. Dropped, so that replans that keep to the plan they replace (an MPC replanning at
  // every step) keep no shadow to check or to compare with.
  shadows_.erase(std::remove_if(shadows_.begin(), shadows_.end(),
                                [](const Shadow& sh) {
                                  for (size_t b = 0; b < sh.ok.size(); ++b) {
                                    if (sh.ok[b] && sh.from[b] < kInf) return false;
                                  }
                                  for (size_t r = 0; r < sh.rel_ok.size(); ++r) {
                                    if (sh.rel_ok[r] && sh.rel_from[r] < kInf) return false;
                                  }
                                  return true;
                                }),
                 shadows_.end());
  plan_ = std::move(plan);
  ++plan_serial_;
  for (Shadow& sh : shadows_) {
    const Plan& old = *sh.plan;
    sh.rel_in_plan.resize(static_cast<size_t>(old.nrel()));
    for (int64_t r = 0; r < old.nrel(); ++r)
      sh.rel_in_plan[r] = plan_->RelOf(old.rel_a(r), old.rel_b(r));
    sh.mapped_for = plan_serial_;
  }
  for (int b = 0; b < m->nbody; ++b) plan_ok_[b] = plan_->holds(b) ? 1 : 0;
  rel_ok_.assign(plan_->nrel(), 1);
  args_.plan.rel_ok = rel_ok_.data();
  CarryCleared(m, walked.get(), nest_end, rel_end, jn_next, next);
  MakeAllDue(step_ + 1);
  return "";
}

void Runtime::CarryCleared(const mjModel* m, const Plan* walked,
                           const std::vector<int64_t>& nest_end,
                           const std::vector<int64_t>& rel_end, int64_t jn0, double next) {
  // A walk's cleared knots are a fact of its plan's geometry: no contact there while both
  // bodies keep to that plan (or the pair to its relative tube). Where the new plan keeps
  // within the old one's tubes, so do they (Lemma 8.4's triangle inequality): the new plan's
  // first walk of the pair starts where the old walk's cleared knots or the nesting end
  // (docs/theory.md, Lemma 8.2e). Encoded -2 - knot: not walked yet, clear before that knot.
  const int64_t jo0 = walked != nullptr ? walked->KnotOf(next) : -1;
  if (jo0 < 0 || nest_end.empty()) {
    std::fill(cleared_.begin(), cleared_.end(), -1);
    return;
  }
  const Universe& u = universe();
  for (size_t p = 0; p < cleared_.size(); ++p) {
    const int64_t c = cleared_[p];
    cleared_[p] = -1;
    if (c == -1) continue;
    const int64_t end_old = c >= 0 ? c : -2 - c;  // the walked plan's first knot not cleared
    int64_t end = end_old - jo0 + jn0;
    const int64_t mp = ids_[p];
    const int64_t b1 = m->geom_bodyid[u.geom1[mp]], b2 = m->geom_bodyid[u.geom2[mp]];
    for (const int64_t b : {b1, b2}) {
      if (!walked->fixed(b)) end = std::min(end, nest_end[b]);
    }
    if (end <= jn0) continue;
    const int64_t r = walked->RelOf(b1, b2);
    if (r >= 0) end = std::min(end, rel_end[r]);
    if (end > jn0) cleared_[p] = -2 - end;
  }
}

void Runtime::Retire() {
  if (!plan_) return;
  // The next step's verdicts are all under the new plan (every pair is due then); the old ones
  // are in force until that step's act (latency) and cover the alarm horizon past it.
  const ScheduleSpec& spec = tables_->schedule;
  const double horizon = spec.alarm_horizon;
  const double next = last_time_ + spec.dt - read_lag_ * tables_->timestep;
  const size_t nbody = plan_ok_.size();
  shadows_.push_back({plan_, plan_ok_, next + horizon + static_cast<double>(spec.latency) * spec.dt,
                      std::vector<double>(nbody, std::nan("")), std::vector<double>(nbody, -kInf),
                      rel_ok_, std::vector<double>(rel_ok_.size(), std::nan("")),
                      std::vector<double>(rel_ok_.size(), -kInf), plan_serial_, -1,
                      std::vector<uint8_t>(nbody, 0), std::vector<uint8_t>(rel_ok_.size(), 0),
                      std::vector<int64_t>(), -1});
}

void Runtime::ClearPlan() {
  if (!plan_) return;
  Retire();
  plan_.reset();
  args_.plan.impl = nullptr;
  MakeAllDue(step_ + 1);
}

void Runtime::DropPlans() {
  plan_.reset();
  args_.plan.impl = nullptr;
  shadows_.clear();
  pending_due_.clear();
  pending_rel_.clear();
  std::fill(plan_ok_.begin(), plan_ok_.end(), 0);
}

void Runtime::MakeAllDue(int64_t n) {
  dua_schedule* st = schedule_->state();
  for (int64_t p = 0; p < npair(); ++p) dua_make_due(st, p, n);
}

void Runtime::MakeBodyDue(const mjModel* m, int64_t b, int64_t n) {
  dua_schedule* st = schedule_->state();
  const int64_t row = body_row_[b];
  if (row >= 0) {
    for (int64_t k = held_start_[row]; k < held_start_[row + 1]; ++k) {
      dua_make_due(st, held_members_[k], n);
      plan_due_.push_back(held_members_[k]);
    }
    return;
  }
  // A body without a row (a plane geom alone): its pairs by a scan.
  const Universe& u = universe();
  for (int64_t p = 0; p < npair(); ++p) {
    const int64_t mp = ids_[p];
    if (m->geom_bodyid[u.geom1[mp]] == b || m->geom_bodyid[u.geom2[mp]] == b) {
      dua_make_due(st, p, n);
      plan_due_.push_back(p);
    }
  }
}

int64_t Runtime::CheckPlans(const mjModel* m, const mjData* d, std::vector<int64_t>* broken,
                            std::vector<int64_t>* rel_broken) {
  const double now = StateTime(m, d), h = m->opt.timestep;
  const Tables& t = *tables_;
  const int64_t k = plan_ ? plan_->KnotOf(now) : -1;
  const int64_t nbody = m->nbody;
  std::vector<int64_t> rel;
  if (k >= 0) {
    plan_->Check(d->geom_xpos, d->geom_xmat, k, t.events_rec.data(), t.nbody_events,
                 plan_ok_.data(), broken);
    for (const int64_t b : *broken) plan_ok_[b] = 0;
    // The relative pairs whose bodies are both still planned (the others' pairs follow a
    // body's bounds now, and no verdict reads their relative bound).
    plan_->CheckRelative(d->geom_xpos, d->geom_xmat, k, rel_ok_.data(), plan_ok_.data(), &rel);
    for (const int64_t r : rel) {
      rel_ok_[r] = 0;
      rel_broken->push_back(plan_->rel_a(r) * nbody + plan_->rel_b(r));
    }
  }
  shadows_.erase(std::remove_if(shadows_.begin(), shadows_.end(),
                                [&](const Shadow& sh) {
                                  const double last = sh.plan->TimeOf(sh.plan->nknot() - 1);
                                  return now > std::min(sh.until, last) + 1e-6 * h;
                                }),
                 shadows_.end());
  std::vector<uint8_t> open;
  for (Shadow& sh : shadows_) {
    const int64_t j = sh.plan->KnotOf(now);
    if (j < 0) continue;
    ShadowOpen(sh, now, k, h, &open);
    const size_t first = broken->size();
    sh.plan->Check(d->geom_xpos, d->geom_xmat, j, t.events_rec.data(), t.nbody_events, open.data(),
                   broken);
    for (size_t i = first; i < broken->size(); ++i) {
      sh.ok[(*broken)[i]] = 0;
      sh.broken_at[(*broken)[i]] = now;
    }
    // Its relative pairs, on the bodies still within it, as its bodies are checked.
    rel.clear();
    ShadowOpenRelative(sh, now, k, h, &open);
    sh.plan->CheckRelative(d->geom_xpos, d->geom_xmat, j, open.data(), sh.ok.data(), &rel);
    for (const int64_t r : rel) {
      sh.rel_ok[r] = 0;
      sh.rel_broken_at[r] = now;
      rel_broken->push_back(sh.plan->rel_a(r) * nbody + sh.plan->rel_b(r));
    }
  }
  return k;
}

void Runtime::MakeRelativeDue(const mjModel* m, int64_t key, int64_t n) {
  const int64_t a = key / m->nbody, b = key % m->nbody;
  const int64_t row = body_row_[a];
  if (row < 0) return;
  dua_schedule* st = schedule_->state();
  const Universe& u = universe();
  for (int64_t i = held_start_[row]; i < held_start_[row + 1]; ++i) {
    const int64_t p = held_members_[i], mp = ids_[p];
    const int64_t b1 = m->geom_bodyid[u.geom1[mp]], b2 = m->geom_bodyid[u.geom2[mp]];
    if (!((b1 == a && b2 == b) || (b1 == b && b2 == a))) continue;
    dua_make_due(st, p, n);
    plan_due_.push_back(p);
    cleared_[p] = -1;
  }
}

std::string Runtime::RelativeBoxed(const mjModel* m, const Plan& plan) const {
  for (int64_t r = 0; r < plan.nrel(); ++r) {
    for (const int64_t b : {plan.rel_a(r), plan.rel_b(r)}) {
      if (body_row_[b] < 0) {
        return "holds a relative deviation for body " + std::to_string(b) +
               ", which has no box in the violation check to measure it at: leave its pairs "
               "out of relative (or build the predictor with violation_events on)";
      }
    }
  }
  (void)m;
  return "";
}

void Runtime::ShadowOpen(const Shadow& sh, double now, int64_t k, double h,
                         std::vector<uint8_t>* open) const {
  open->resize(sh.ok.size());
  for (size_t b = 0; b < sh.ok.size(); ++b) {
    // Checked from the plan's departure on, or when the plan does not prove the body within.
    const bool due = now >= sh.from[b] - 1e-6 * h || k < 0 || !plan_ok_[b];
    (*open)[b] = sh.ok[b] && due;
  }
}

void Runtime::ShadowOpenRelative(const Shadow& sh, double now, int64_t k, double h,
                                 std::vector<uint8_t>* open) const {
  const Plan& old = *sh.plan;
  open->resize(sh.rel_ok.size());
  for (size_t r = 0; r < sh.rel_ok.size(); ++r) {
    const auto i = static_cast<int64_t>(r);
    const int64_t a = old.rel_a(i), b = old.rel_b(i);
    const bool mapped = sh.mapped_for == plan_serial_;
    const int64_t rn = k < 0 ? -1 : mapped ? sh.rel_in_plan[r] : plan_->RelOf(a, b);
    const bool proven = rn >= 0 && rel_ok_[rn] && plan_ok_[a] && plan_ok_[b];
    (*open)[r] = sh.rel_ok[r] && (now >= sh.rel_from[r] - 1e-6 * h || !proven);
  }
}

void Runtime::RelativeDepartures(const Plan& plan, double next, double h, const Shadow* chain,
                                 Shadow* sh) const {
  const Plan& old = *sh->plan;
  sh->rel_from.assign(old.nrel(), kInf);
  const int64_t jo0 = old.KnotOf(next), jn0 = plan.KnotOf(next);
  const int64_t span = SpanKnots(old, jo0, next, h, sh->until);
  for (int64_t r = 0; r < old.nrel(); ++r) {
    const int64_t a = old.rel_a(r), b = old.rel_b(r);
    const bool was = sh->rel_nested[r] != 0;
    sh->rel_nested[r] = 0;
    if (!sh->rel_ok[r] || !sh->ok[a] || !sh->ok[b]) continue;  // the shadow checks it no more
    if (chain != nullptr && was) {
      const int64_t rc = chain->plan->RelOf(a, b);
      if (rc >= 0 && chain->rel_nested[rc]) {  // nested in a plan nested in this one
        sh->rel_nested[r] = 1;
        continue;
      }
    }
    sh->rel_nested[r] = 1;  // until it departs
    const int64_t rn = plan.RelOf(a, b);
    // The knots in the span, old's and the new plan's: the new plan leaves the tube at its
    // first knot beyond it (RelativeDeparture), where it has no such pair, or past its knots.
    const int64_t past = rn < 0 || jn0 < 0 ? 0 : std::max<int64_t>(0, plan.nknot() - jn0);
    const int64_t s =
        past > 0 ? RelativeDeparture(plan, rn, jn0, old, r, jo0, std::min(span, past)) : 0;
    if (s < span) {
      sh->rel_from[r] = next + static_cast<double>(s) * h;
      sh->rel_nested[r] = 0;
    }
  }
}

void Runtime::FollowPlan(const mjModel* m, const mjData* d, int64_t n) {
  plan_due_.clear();
  // Without a plan, a shadow or a break between steps (every step of most runs) nothing to do.
  if (!plan_ && shadows_.empty() && pending_due_.empty() && pending_rel_.empty()) return;
  FollowPlans(m, d, n);
}

void Runtime::FollowPlans(const mjModel* m, const mjData* d, int64_t n) {
  for (const int64_t b : pending_due_) MakeBodyDue(m, b, n);
  pending_due_.clear();
  for (const int64_t key : pending_rel_) MakeRelativeDue(m, key, n);
  pending_rel_.clear();
  if (!plan_ && shadows_.empty()) return;
  std::vector<int64_t> broken, rel;
  const int64_t k = CheckPlans(m, d, &broken, &rel);
  if (k >= 0) {
    args_.plan.knot = k;
  } else if (plan_) {
    // Past the plan (or a clock the plan does not know): the bounds alone from here on. Its
    // verdicts never covered past its last knot: nothing is left to check.
    plan_.reset();
    args_.plan.impl = nullptr;
    MakeAllDue(n);
  }
  plan_breaks_ += static_cast<int64_t>(broken.size() + rel.size());
  for (const int64_t b : broken) MakeBodyDue(m, b, n);
  for (const int64_t key : rel) MakeRelativeDue(m, key, n);
}

std::vector<int64_t> Runtime::CheckPlan(const mjModel* m, const mjData* d) {
  std::vector<int64_t> broken, rel;
  if (!classified_ || (!plan_ && shadows_.empty())) return broken;
  CheckPlans(m, d, &broken, &rel);
  plan_breaks_ += static_cast<int64_t>(broken.size() + rel.size());
  pending_due_.insert(pending_due_.end(), broken.begin(), broken.end());
  pending_rel_.insert(pending_rel_.end(), rel.begin(), rel.end());
  return broken;
}

std::vector<int64_t> Runtime::PlanBroken(const mjModel* m, const mjData* d) const {
  std::vector<int64_t> out;
  const double now = StateTime(m, d);
  const double h = m->opt.timestep;
  const Tables& t = *tables_;
  bool covered = false;
  const int64_t k = plan_ ? plan_->KnotOf(now) : -1;
  if (k >= 0) {
    covered = true;
    plan_->Check(d->geom_xpos, d->geom_xmat, k, t.events_rec.data(), t.nbody_events, nullptr, &out);
  }
  const size_t planned = out.size();
  std::vector<uint8_t> open;
  for (const Shadow& sh : shadows_) {
    const int64_t j = sh.plan->KnotOf(now);
    if (j < 0 || now > sh.until + 1e-6 * h) continue;
    covered = true;
    // As the step checks it (bodies the plan beyond its deviation now no longer proves within),
    // and those found at this very state: once a break of it was seen, the verdicts in force
    // rest on later plans, not on this one.
    ShadowOpen(sh, now, k, h, &open);
    for (size_t b = 0; b < open.size(); ++b) {
      const bool here =
          std::find(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(planned),
                    static_cast<int64_t>(b)) != out.begin() + static_cast<std::ptrdiff_t>(planned);
      open[b] = open[b] || (sh.ok[b] && here) || sh.broken_at[b] == now;
    }
    const size_t first = out.size();
    sh.plan->Check(d->geom_xpos, d->geom_xmat, j, t.events_rec.data(), t.nbody_events, open.data(),
                   &out);
    // Each body once.
    for (size_t i = first; i < out.size();) {
      if (std::find(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(first), out[i]) !=
          out.begin() + static_cast<std::ptrdiff_t>(first)) {
        out.erase(out.begin() + static_cast<std::ptrdiff_t>(i));
      } else {
        ++i;
      }
    }
  }
  if (!covered) return {-1};
  return out;
}

std::vector<int64_t> Runtime::PlanBrokenRelative(const mjModel* m, const mjData* d) const {
  std::vector<int64_t> rel, out;
  if (!plan_ && shadows_.empty()) return out;  // the monitor asks at every step, plans or none
  const double now = StateTime(m, d);
  const double h = m->opt.timestep;
  const auto add = [&](const Plan& plan) {
    for (const int64_t r : rel) {
      const int64_t a = plan.rel_a(r), b = plan.rel_b(r);
      bool seen = false;
      for (size_t i = 0; i < out.size(); i += 2) seen = seen || (out[i] == a && out[i + 1] == b);
      if (!seen) out.push_back(a), out.push_back(b);
    }
    rel.clear();
  };
  const int64_t k = plan_ ? plan_->KnotOf(now) : -1;
  if (k >= 0) {
    plan_->CheckRelative(d->geom_xpos, d->geom_xmat, k, nullptr, plan_ok_.data(), &rel);
    add(*plan_);
  }
  std::vector<uint8_t> open;
  for (const Shadow& sh : shadows_) {
    const int64_t j = sh.plan->KnotOf(now);
    if (j < 0 || now > sh.until + 1e-6 * h) continue;
    // As the step checks them, and those found at this very state (PlanBroken's rule).
    ShadowOpenRelative(sh, now, k, h, &open);
    for (size_t r = 0; r < open.size(); ++r) {
      open[r] = open[r] || sh.rel_broken_at[r] == now;
    }
    sh.plan->CheckRelative(d->geom_xpos, d->geom_xmat, j, open.data(), nullptr, &rel);
    add(*sh.plan);
  }
  return out;
}

std::string Runtime::PlanQuery(const mjModel* m, const mjData* d, const dua_plan_input& candidate,
                               const std::vector<int64_t>& g1, const std::vector<int64_t>& g2,
                               std::vector<int64_t>* knots) const {
  if (!query_data_) query_data_.reset(mj_makeData(m));
  if (!query_data_) return "needs an mjData that MuJoCo could not allocate";
  const Tables& t = *tables_;
  Plan plan;
  std::string error = plan.Build(m, query_data_.get(), candidate, m->opt.timestep, t.spheres.data(),
                                 t.nsphere(), plan_geoms_, plan_.get(), nullptr);
  if (!error.empty()) return error;
  query_tolerance_ = plan.tolerance();
  for (int b = 0; b < m->nbody; ++b) {
    if (plan.holds(b) && unboxed_[b]) {
      return "holds body " + std::to_string(b) +
             ", which has no box in the violation check: build the predictor with "
             "violation_events on (the default)";
    }
  }
  error = RelativeBoxed(m, plan);
  if (!error.empty()) return error;
  plan.SetRelativeFrames(t.events_rec.data(), body_row_.data());
  const int64_t k = plan.KnotOf(StateTime(m, d));
  if (k < 0) {
    return "does not cover the state of the data (time " + std::to_string(StateTime(m, d)) +
           "): start it there, on a whole number of timesteps from it";
  }
  QueryPairs q = PrepareQuery(g1, g2);
  QueryKnots(m, d, plan, k, &q, knots);
  return "";
}

Runtime::QueryPairs Runtime::PrepareQuery(const std::vector<int64_t>& g1,
                                          const std::vector<int64_t>& g2) const {
  const Universe& u = universe();
  const auto n = static_cast<int64_t>(g1.size());
  QueryPairs q;
  // Each asked geom pair's slot (one a distinct geom pair), and the sphere pairs of each slot,
  // their records copied (the exact level writes the directions it finds into its own), in one
  // scan of the pairs known.
  std::vector<int64_t> slot_of(u.ngp(), -1);
  q.slot.assign(n, -1);
  for (int64_t k = 0; k < n; ++k) {
    const int64_t lo = std::min(g1[k], g2[k]), hi = std::max(g1[k], g2[k]);
    const int64_t gp = lo == hi ? -1 : u.GeomPair(lo, hi);
    if (gp < 0) continue;
    if (slot_of[gp] < 0) slot_of[gp] = q.nslot++;
    q.slot[k] = slot_of[gp];
  }
  for (int64_t p = 0; p < u.npair(); ++p) {
    const int64_t s = slot_of[u.pair_geom[p]];
    if (s < 0) continue;
    q.pairs.insert(q.pairs.end(), u.pairs.begin() + kPairNcol * p,
                   u.pairs.begin() + kPairNcol * (p + 1));
    if (tables_->exact) {
      q.exact.insert(q.exact.end(), u.exact.begin() + kXNcol * p,
                     u.exact.begin() + kXNcol * (p + 1));
    }
    q.owner.push_back(s), q.geom_a.push_back(u.geom1[p]), q.geom_b.push_back(u.geom2[p]);
  }
  q.state.assign(6 * static_cast<size_t>(tables_->nsphere()), 0.0);
  q.epoch.assign(tables_->nsphere(), -1);
  return q;
}

void Runtime::QueryKnots(const mjModel* m, const mjData* d, const Plan& plan, int64_t k,
                         QueryPairs* q, std::vector<int64_t>* knots) const {
  if (!query_data_) query_data_.reset(mj_makeData(m));
  const Tables& t = *tables_;
  // The step's arguments for these records on d's state (PlanPass reads the same).
  dua_step_args a = args_;
  a.pairs = q->pairs.data();
  a.spheres = t.spheres.data();
  a.shapes = t.shapes.data();
  a.frame = FrameOf(d, mocap_.twist.data());
  a.exact.on = t.exact ? 1 : 0;
  a.exact.geoms = t.geoms.data();
  a.exact.hull_at = t.hull_at.data();
  a.exact.climb = t.climb.data();
  a.exact.climb_at = t.climb_at.data();
  a.exact.records = q->exact.data();
  a.exact.witness = nullptr;  // the step's rows are of its own pairs: none read or kept
  a.exact.model = m;
  a.exact.data = d;
  a.events.rec = t.events_rec.data();
  std::fill(q->epoch.begin(), q->epoch.end(), -1);
  a.point_state = q->state.data();
  a.point_epoch = q->epoch.data();
  a.epoch = 0;
  a.plan.geom_body = m->geom_bodyid;
  a.plan.geom_row = t.geom_row.data();
  a.plan.data = query_data_.get();
  a.plan.cleared = nullptr;  // another plan, and the query's own pair records
  a.plan.rel_ok = nullptr;   // its relative bounds assumed, as its bodies' are
  q->ok.resize(m->nbody);
  for (int b = 0; b < m->nbody; ++b) q->ok[b] = plan.holds(b) ? 1 : 0;
  q->by_slot.assign(q->nslot, plan.nknot());
  q->said.assign(q->nslot, 0);
  for (size_t p = 0; p < q->owner.size(); ++p) {
    const int64_t s = q->owner[p];
    const int64_t j =
        PlanKnot(a, plan, q->ok.data(), k, static_cast<int64_t>(p), q->geom_a[p], q->geom_b[p]);
    if (j < 0) continue;
    q->said[s] = 1;
    q->by_slot[s] = std::min(q->by_slot[s], j);
  }
  knots->assign(q->slot.size(), -2);
  for (size_t i = 0; i < q->slot.size(); ++i) {
    const int64_t s = q->slot[i];
    if (s >= 0) (*knots)[i] = q->said[s] ? q->by_slot[s] : -1;
  }
}

void Runtime::Learnt() {
  const Universe& u = universe();
  if (static_cast<int64_t>(on_.size()) != u.npair()) ++universe_version_;
  on_.resize(u.npair(), 1);
  gp_count_.resize(u.ngp(), 0);
  if (watching_) {
    for (auto k = static_cast<int64_t>(gp_counted_.size()); k < u.ngp(); ++k) {
      gp_counted_.push_back(Counted(k) ? 1 : 0);
    }
  }
}

bool Runtime::Counted(int64_t gp) const {
  const Universe& u = universe();
  const int64_t g1 = u.geom_pairs[2 * gp], g2 = u.geom_pairs[2 * gp + 1];
  if (ignored_geoms_[g1] || ignored_geoms_[g2]) return false;
  return !std::binary_search(ignored_pairs_.begin(), ignored_pairs_.end(), (g1 << 32) | g2);
}

void Runtime::Watch(const std::vector<uint8_t>& ignored_geoms,
                    const std::vector<int64_t>& ignored_pairs) {
  watching_ = true;
  // Pairs on the screen go back to the wheel, due at the next step (their verdicts kept).
  Unscreen(schedule_->state(), step_ + 1);
  ignored_geoms_ = ignored_geoms;
  ignored_pairs_ = ignored_pairs;
  std::sort(ignored_pairs_.begin(), ignored_pairs_.end());
  gp_counted_.clear();
  Learnt();
  TrackAll();
  was_.assign(gp_count_.size(), 0);
  FinishWatch();
}

std::vector<int64_t> Runtime::WatchedStanding() const {
  std::vector<int64_t> out;
  const Universe& u = universe();
  for (const int64_t k : u.gp_ids) {  // in increasing (g1, g2)
    if (gp_count_[k] && gp_counted_[k]) {
      out.push_back(u.geom_pairs[2 * k]), out.push_back(u.geom_pairs[2 * k + 1]);
    }
  }
  return out;
}

DUA_HOT void Runtime::FinishWatch() {
  if (!watching_) return;
  watched_.started = 0;
  was_.resize(gp_count_.size(), 0);
  bool changed = false;
  for (const int64_t gp : touched_) {
    const uint8_t now = gp_count_[gp] > 0 && gp_counted_[gp];
    if (now == was_[gp]) continue;
    watched_.started += now;
    changed = true;
    was_[gp] = now;
  }
  touched_.clear();
  if (changed) ++watched_.version;
}

void Runtime::SetExpiry(int64_t p) {
  const Schedule& s = *schedule_;
  const bool counted = s.active[p] && gp_counted_[universe().pair_geom[ids_[p]]];
  const double expiry =
      counted ? s.last_tau[p] + static_cast<double>(s.ints[kIntLastStep * s.m() + p]) * s.spec().dt
              : kInf;
  int64_t i = expiry_size_ + p;
  expiry_tree_[i] = expiry;
  for (i /= 2; i >= 1; i /= 2) {
    expiry_tree_[i] = std::min(expiry_tree_[2 * i], expiry_tree_[2 * i + 1]);
  }
}

int64_t Runtime::Classify(const mjModel* m, const mjData* d) {
  const Tables& t = *tables_;
  if (d) mocap_.Start(d);
  std::fill(on_.begin(), on_.end(), 1);
  Bind(m, d);
  if (t.pruned) {
    std::vector<int64_t> held;
    if (!pruned_.Select(t.held, learn(), &own_, args_, 0, &held)) {
      // A state that is not finite: every pair known held, each standing in alarm (below).
      held = Iota(universe().npair());
    }
    Learnt();
    pruned_.built_at = 0;
    pruned_.escapes.clear();
    pruned_.broken = -1;
    Hold(held);
    Bind(m, d);
  }
  dua_reset_events(&args_);
  // A classification judges from the state alone: no verdict, and no plan, carries over it (a
  // reset, a jump of the clock, a state the last step could not read).
  DropPlans();
  const int64_t n = npair();
  std::vector<double> tau0(n);
  const std::vector<int64_t> all = Iota(n);
  const int64_t bad = n ? dua_evaluate(&args_, all.data(), n, tau0.data()) : -1;
  // Nothing can be predicted from a state that is not finite: every pair stands in alarm.
  if (bad >= 0) std::fill(tau0.begin(), tau0.end(), -kInf);
  const int64_t changes = schedule_->activation_changes;
  schedule_ = std::make_shared<Schedule>(t.schedule, tau0, std::vector<uint8_t>{});
  schedule_->activation_changes = changes + 1;
  if (log_->capacity() < std::max(schedule_->width(), n)) NewLog();
  Bind(m, d);
  args_.count = n;
  args_.deferred = 0;
  events_meta_[kMCount] = 0;
  classified_ = true;
  step_ = 0;
  last_time_ = d ? d->time : 0.0;
  TrackAll();
  std::fill(was_.begin(), was_.end(), 0);  // every alarm of a classification is new
  FinishWatch();
  // The classification's alarms, logged as a step's are (each new).
  const std::vector<int64_t> alarmed = schedule_->InitialAlarms();
  if (log_used_ + static_cast<int64_t>(alarmed.size()) > log_->capacity()) NewLog();
  log_start_ = log_used_;
  for (size_t k = 0; k < alarmed.size(); ++k) {
    log_->pair[log_start_ + k] = ids_[alarmed[k]];
    log_->tau[log_start_ + k] = schedule_->last_tau[alarmed[k]];
    log_->fresh[log_start_ + k] = 1;
  }
  Log(static_cast<int64_t>(alarmed.size()));
  return bad;
}

DUA_HOT Runtime::Clock Runtime::ClockOf(double time) const {
  const double dt = tables_->schedule.dt, h = tables_->timestep;
  const double elapsed = time - last_time_;
  if (std::fabs(elapsed) <= 1e-6 * h) return Clock::kSame;
  if (std::fabs(elapsed - dt) <= 1e-6 * dt) return Clock::kOnePeriod;
  const double k = elapsed / h;
  if (elapsed > 0.0 && elapsed < dt && std::fabs(k - std::nearbyint(k)) <= 1e-6 * k) {
    return Clock::kWithinPeriod;
  }
  return Clock::kOther;
}

DUA_HOT int64_t Runtime::Step(const mjModel* m, const mjData* d) {
  const Tables& t = *tables_;
  if (d) mocap_.Difference(d, d->time - last_time_);
  Bind(m, d);
  const int64_t n = step_ + 1;
  // Free spheres have no violation check to flag them: every sphere's escape test runs on this
  // step's state, and the escaped ones are renewed from it at once (Lemmas 6.4, 6.5).
  if (t.free && t.pruned && escape_check_) pruned_.FindEscapes(t.held, args_, n);
  if (t.pruned && !Prune(m, d, n)) return kBadState;
  FollowPlan(m, d, n);
  const int64_t room = schedule_->width();
  if (log_used_ + room > log_->capacity()) {
    // Rewound when nothing else holds it (no Alarms of an earlier step), else replaced.
    if (log_.use_count() == 1 && room <= log_->capacity()) {
      log_used_ = 0;
    } else {
      NewLog(), Bind(m, d);
    }
  }
  log_start_ = log_used_;
  // The shield reads each watched pair's verdict as far as it reaches (its expiry); a screened
  // pair's reaches only the alarm horizon, so a watching runtime does not screen.
  args_.screen = watching_ ? 0 : 1;
  const int64_t result = dua_step(&args_, n, log_start_);
  if (result < 0) return result;
  step_ = n;
  schedule_->step_count = n;
  last_time_ = d ? d->time : static_cast<double>(n) * t.schedule.dt;
  Log(result);
  if (t.pruned && escape_check_ && args_.events.nbody && events_meta_[kMCount]) {
    pruned_.FindEscapes(t.held, args_, step_);
  }
  TrackStep(result);
  FinishWatch();
  return result;
}

DUA_HOT void Runtime::Log(int64_t nalarm) {
  const Universe& u = universe();
  const Tables& t = *tables_;
  for (int64_t k = log_start_; k < log_start_ + nalarm; ++k) {
    const int64_t p = log_->pair[k];
    const double* rec = u.pairs.data() + kPairNcol * p;
    log_->geom1[k] = static_cast<int32_t>(u.geom1[p]);
    log_->geom2[k] = static_cast<int32_t>(u.geom2[p]);
    log_->sphere1[k] = static_cast<int32_t>(rec[kPairFirst]);
    log_->sphere2[k] = rec[kPairKind] == kKindSphere ? static_cast<int32_t>(rec[kPairSecond]) : -1;
  }
  (void)t;
  log_used_ = log_start_ + nalarm;
}

bool Runtime::Prune(const mjModel* m, const mjData* d, int64_t n) {
  const Tables& t = *tables_;
  PrunedState& ps = pruned_;
  const auto escaped = static_cast<int64_t>(ps.escapes.size());
  std::vector<int64_t> held;
  bool carry = false;
  if (n - ps.built_at >= t.held.stride || escaped > t.renew_max) {
    if (!ps.Select(t.held, learn(), &own_, args_, n, &held)) return false;
    ps.built_at = n;
    carry = true;
    ++rebuilds_;
  } else if (escaped) {
    std::vector<int64_t> found;
    if (!ps.Renew(t.held, learn(), &own_, args_, n, &found)) return false;
    std::set_union(ids_.begin(), ids_.end(), found.begin(), found.end(), std::back_inserter(held));
    carry = held.size() > ids_.size();  // some pair is new
    ++renewals_;
  }
  Learnt();
  if (ps.built_at == n) ForgetStale(&held);  // a rebuild: forget what it has not held
  ps.escapes.clear();
  if (carry) Carry(m, d, held, n);
  return true;
}

void Runtime::ForgetStale(std::vector<int64_t>* held) {
  if (forget_after_ < 0) return;
  Universe& u = own_;
  const int64_t ng = u.ngp(), ng0 = tables_->universe.ngp();
  gp_seen_.resize(ng, rebuilds_);  // learnt since the last look: met now
  for (const int64_t p : *held) gp_seen_[u.pair_geom[p]] = rebuilds_;
  for (const int64_t p : ids_) gp_seen_[u.pair_geom[p]] = rebuilds_;  // held until the carry
  // The model's own pairs (static, <pair> elements: not learnt through the filter) stay.
  std::vector<uint8_t> keep(ng, 1);
  int64_t stale = 0;
  for (int64_t k = ng0; k < ng; ++k) {
    if (rebuilds_ - gp_seen_[k] > forget_after_) keep[k] = 0, ++stale;
  }
  // Compacting costs O(pairs known): only once half the learnt geom pairs are stale, so that
  // the pairs known stay within twice those met in the last forget_after_ rebuilds.
  if (stale == 0 || 2 * stale < ng - ng0) return;
  // A switched-off pair stays known: a pair learnt anew would come back switched on.
  for (int64_t p = 0; p < u.npair(); ++p) {
    if (!on_[p]) keep[u.pair_geom[p]] = 1;
  }
  if (watching_) was_.resize(ng, 0);  // (FinishWatch sizes it after the step)
  std::vector<int64_t> pair_map, gp_map;
  const std::string bad =
      u.Forget(keep, tables_->spheres, static_cast<int64_t>(learn().geom_start.size()) - 1,
               &pair_map, &gp_map);
  (void)bad;  // the kept rows of a universe that indexed are indexed (no id is out of range)
  for (int64_t& p : ids_) p = pair_map[p];
  for (int64_t& p : *held) p = pair_map[p];
  auto compact = [](const std::vector<int64_t>& map, auto* v) {
    if (v->size() != map.size()) return;  // not in use (the watcher's, when not watching)
    std::remove_reference_t<decltype(*v)> out(static_cast<size_t>(
        std::count_if(map.begin(), map.end(), [](int64_t j) { return j >= 0; })));
    for (size_t k = 0; k < map.size(); ++k) {
      if (map[k] >= 0) out[map[k]] = (*v)[k];
    }
    v->swap(out);
  };
  compact(pair_map, &on_);
  compact(gp_map, &gp_count_);
  compact(gp_map, &gp_seen_);
  compact(gp_map, &gp_counted_);
  compact(gp_map, &was_);
  std::vector<int64_t> touched;
  for (const int64_t k : touched_) {
    if (gp_map[k] >= 0) touched.push_back(gp_map[k]);
  }
  touched_.swap(touched);
  forgotten_ += ng - u.ngp();
  ++compactions_;
  ++universe_version_;
}

void Runtime::Carry(const mjModel* m, const mjData* d, const std::vector<int64_t>& held,
                    int64_t n) {
  const std::vector<int64_t>& old = ids_;
  const auto k = static_cast<int64_t>(held.size());
  std::vector<int64_t> src(k, -1);
  for (int64_t p = 0, q = 0; p < k; ++p) {
    while (q < static_cast<int64_t>(old.size()) && old[q] < held[p]) ++q;
    if (q < static_cast<int64_t>(old.size()) && old[q] == held[p]) src[p] = q;
  }
  auto next = std::make_shared<Schedule>(tables_->schedule, k);
  next->Carry(*schedule_, src, n);
  schedule_ = std::move(next);
  // What the carried verdicts rested on goes with them; a new pair's was the bounds (its
  // exclusion rested on both bodies' reach).
  std::vector<uint8_t> basis(k, 0), basis_prev(k, 0);
  for (int64_t p = 0; p < k; ++p) {
    if (src[p] >= 0) basis[p] = basis_[src[p]], basis_prev[p] = basis_prev_[src[p]];
  }
  Hold(held);
  basis_.swap(basis), basis_prev_.swap(basis_prev);
  Bind(m, d);
  // Pairs new to the held set that were switched off stay off.
  std::vector<int64_t> off;
  for (int64_t p = 0; p < k; ++p) {
    if (src[p] < 0 && !on_[held[p]]) off.push_back(p);
  }
  if (!off.empty() &&
      dua_switch(schedule_->state(), off.data(), static_cast<int64_t>(off.size()), 0, n)) {
    ++schedule_->activation_changes;
  }
  const double min_tau = min_tau_;
  TrackAll();
  min_tau_ = min_tau;
}

DUA_HOT void Runtime::Track(const int64_t* ids, int64_t n, const int64_t* alarms, int64_t nalarm) {
  if (alarms) {
    // The alarms are a subsequence of ids, in its order: each pair is compared with the next of
    // them only (-1: none left, never a pair). Few pairs change (Flip); the loop reads the flags
    // through a pointer of its own, which Flip's stores into the members cannot move.
    const uint8_t* stands = stands_.data();
    int64_t j = 0;
    int64_t next = nalarm > 0 ? alarms[0] : -1;
    for (int64_t k = 0; k < n; ++k) {
      const int64_t p = ids[k];
      const uint8_t now = p == next ? 1 : 0;
      if (now) next = ++j < nalarm ? alarms[j] : -1;
      if (now != stands[p]) Flip(p, now);
    }
  } else {
    for (int64_t k = 0; k < n; ++k) {
      const int64_t p = ids[k];
      const uint8_t now = schedule_->Stands(p) ? 1 : 0;
      if (now != stands_[p]) Flip(p, now);
    }
  }
  if (watching_) {
    for (int64_t k = 0; k < n; ++k) SetExpiry(ids[k]);
    watched_.expiry = expiry_tree_[1];
  }
}

void Runtime::Flip(int64_t p, uint8_t now) {
  const Universe& u = universe();
  stands_[p] = now;
  if (now) {
    standing_at_[p] = static_cast<int64_t>(standing_.size());
    standing_.push_back(p);
  } else {  // swap-removed
    const int64_t last = standing_.back();
    standing_[standing_at_[p]] = last;
    standing_at_[last] = standing_at_[p];
    standing_at_[p] = -1;
    standing_.pop_back();
  }
  const int64_t gp = u.pair_geom[ids_[p]];
  int32_t& count = gp_count_[gp];
  const bool counted = watching_ && gp_counted_[gp];
  if (now) {
    if (count++ == 0) {
      ++nstanding_;
      if (counted) ++watched_.standing, touched_.push_back(gp);
    }
  } else if (--count == 0) {
    --nstanding_;
    if (counted) --watched_.standing, touched_.push_back(gp);
  }
}

void Runtime::TrackAll() {
  std::fill(stands_.begin(), stands_.end(), 0);
  standing_.clear();
  std::fill(standing_at_.begin(), standing_at_.end(), -1);
  std::fill(gp_count_.begin(), gp_count_.end(), 0);
  nstanding_ = 0;
  if (watching_) {
    watched_.standing = 0;
    for (size_t k = 0; k < gp_count_.size(); ++k) touched_.push_back(static_cast<int64_t>(k));
    expiry_size_ = 1;
    while (expiry_size_ < std::max<int64_t>(npair(), 1)) expiry_size_ *= 2;
    expiry_tree_.assign(2 * expiry_size_, kInf);
  }
  const std::vector<int64_t> all = Iota(npair());
  Track(all.data(), npair());
  const std::vector<double>& tau = schedule_->last_tau;
  min_tau_ = tau.empty() ? kInf : *std::min_element(tau.begin(), tau.end());
}

DUA_HOT void Runtime::TrackStep(int64_t nalarm) {
  const dua_schedule& s = *schedule_->state();
  const dua_events& e = args_.events;
  // The deadline wheel and select-all list each selected pair once, and their reinsert lists
  // the ones in alarm in selection order (the evaluated, then the deferred): exactly those of
  // the selection that stand now (the alarm test and Stands compute the same bound; for the
  // deadline wheel docs/theory.md, section 3, "Standing after a step"), so that list is read
  // in place of Stands on each (its horizon's bound recomputed per pair was 9 % of the
  // plugin's instructions on dmc_dog). The rank schedule may select a pair twice: Stands.
  Track(s.work + s.width, args_.count + args_.deferred,
        s.kind == kRank ? nullptr : s.work + 2 * s.width, nalarm);
  // The pairs of the bodies the violation check flagged were made due now: the deadline and
  // select-all schedules selected every one of them (evaluated, or deferred), so the line above
  // tracked them; the rank schedule queues them, and those left in the queue stand in alarm.
  for (int64_t k = 0; s.kind == kRank && e.nbody && k < events_meta_[kMCount]; ++k) {
    const int64_t i = events_flagged_[k];
    Track(held_members_.data() + held_start_[i], held_start_[i + 1] - held_start_[i]);
  }
  // The flagged bodies' pairs the deadline step settled (docs/theory.md, section 6): none
  // stands, none stood (section 3, "Settled pairs do not stand"), so Stands is not asked of
  // them (up to 9 % of the plugin's instructions: g1_mjlab at 200); only their expiry moved.
  if (s.kind == kDeadline && watching_) {
    const int64_t* settled = s.work + kWorkSlots * s.width;
    for (int64_t k = 0; k < s.params[kParamSettled]; ++k) SetExpiry(settled[k]);
  }
  // Pairs a plan break withdrew (the rank schedule may leave them waiting, standing in alarm).
  Track(plan_due_.data(), static_cast<int64_t>(plan_due_.size()));
  // In a local (a store into the member each pair could alias the taus, so it was one).
  double least = kInf;
  for (int64_t k = 0; k < args_.count; ++k) least = std::min(least, s.w_tau[k]);
  min_tau_ = least;
}

void Runtime::Switch(const std::vector<int64_t>& pairs, bool on) {
  std::vector<int64_t> held;
  for (const int64_t p : pairs) {
    on_[p] = on ? 1 : 0;
    const auto it = std::lower_bound(ids_.begin(), ids_.end(), p);
    if (it != ids_.end() && *it == p) held.push_back(it - ids_.begin());
  }
  const auto n = static_cast<int64_t>(held.size());
  if (dua_switch(schedule_->state(), held.data(), n, on ? 1 : 0, step_ + 1)) {
    ++schedule_->activation_changes;
  }
  Track(held.data(), n);
}

std::vector<int64_t> Runtime::PairsBetweenBodies(const mjModel* m, int body_a, int body_b) {
  if (tables_->pruned) {  // the pairs not met yet learnt, so that they stay switched when met
    std::vector<int64_t> g1, g2;
    for (int a = 0; a < m->ngeom; ++a) {
      if (m->geom_bodyid[a] != body_a) continue;
      for (int b = 0; b < m->ngeom; ++b) {
        if (body_b < 0 || m->geom_bodyid[b] == body_b) g1.push_back(a), g2.push_back(b);
      }
    }
    own_.Learn(learn(), g1.data(), g2.data(), static_cast<int64_t>(g1.size()));
    Learnt();
  }
  const Universe& u = universe();
  std::vector<int64_t> ids;
  for (int64_t p = 0; p < u.npair(); ++p) {
    const int64_t gp = u.pair_geom[p];
    const int ba = m->geom_bodyid[u.geom_pairs[2 * gp]];
    const int bb = m->geom_bodyid[u.geom_pairs[2 * gp + 1]];
    const bool between = body_b < 0
                             ? (ba == body_a || bb == body_a)
                             : ((ba == body_a && bb == body_b) || (ba == body_b && bb == body_a));
    if (between) ids.push_back(p);
  }
  return ids;
}

std::vector<int64_t> Runtime::GeomPairIds(const std::vector<int64_t>& g1,
                                          const std::vector<int64_t>& g2) {
  const auto n = static_cast<int64_t>(g1.size());
  auto lookup = [&](std::vector<int64_t>* out) {
    bool missing = false;
    for (int64_t k = 0; k < n; ++k) {
      const int64_t lo = std::min(g1[k], g2[k]), hi = std::max(g1[k], g2[k]);
      (*out)[k] = lo == hi ? -1 : universe().GeomPair(lo, hi);
      missing = missing || (*out)[k] < 0;
    }
    return missing;
  };
  std::vector<int64_t> out(n);
  if (lookup(&out) && tables_->pruned && own_.Learn(learn(), g1.data(), g2.data(), n) > 0) {
    Learnt();
    lookup(&out);
  }
  return out;
}

int64_t Runtime::DeactivateContacts(const mjData* d) {
  std::vector<int64_t> g1, g2;
  for (int c = 0; c < d->ncon; ++c) {
    const int a = d->contact[c].geom[0], b = d->contact[c].geom[1];
    if (a < 0 || b < 0) continue;  // a flex
    g1.push_back(a), g2.push_back(b);
  }
  const std::vector<int64_t> gp = GeomPairIds(g1, g2);
  const Universe& u = universe();
  std::vector<uint8_t> off(u.ngp(), 0);
  int64_t noff = 0;
  for (const int64_t k : gp) {
    if (k >= 0 && !off[k]) off[k] = 1, ++noff;
  }
  std::vector<int64_t> ids;
  for (int64_t p = 0; p < u.npair(); ++p) {
    if (off[u.pair_geom[p]]) ids.push_back(p);
  }
  Switch(ids, false);
  return noff;
}

std::vector<double> Runtime::ExactOnly(const mjModel* m, const mjData* d,
                                       const std::vector<int64_t>& ids,
                                       const std::vector<double>& coarse, double query_below) {
  std::vector<double> records = exact_records_, witness = witness_;
  const std::vector<double>& built = tables_->universe.exact;
  if (!tables_->pruned) {  // the records as built: no direction learnt, no query made
    records = built;
    std::fill(witness.begin(), witness.end(), kNaN);
  }
  dua_step_args a = Bind(m, d);
  a.exact.records = records.data();
  a.exact.witness = witness.data();
  a.exact.query_below = query_below;
  std::vector<double> out = coarse;
  dua_exact_pass(&a, ids.data(), static_cast<int64_t>(ids.size()), out.data());
  Bind(m, d);
  return out;
}

std::pair<std::vector<int64_t>, std::vector<double>> Runtime::CheckBodiesCopy(const mjModel* m,
                                                                              const mjData* d,
                                                                              bool lanes) {
  std::vector<double, LanesAligned<double>> prev = events_prev_;
  std::vector<int64_t> meta = events_meta_, flagged = events_flagged_;
  dua_step_args a = Bind(m, d);
  a.events.prev = prev.data(), a.events.meta = meta.data(), a.events.flagged = flagged.data();
  const int64_t count = dua_check_bodies(&a, lanes ? 1 : 0);
  flagged.resize(count);
  return {flagged, std::vector<double>(prev.begin(), prev.end())};
}

std::vector<int64_t> Runtime::FlaggedBodies() const {
  std::vector<int64_t> out;
  const Tables& t = *tables_;
  for (int64_t k = 0; k < flagged(); ++k) {
    out.push_back(static_cast<int64_t>(t.events_rec[kBNcol * events_flagged_[k] + kBBody]));
  }
  return out;
}

}  // namespace dua
