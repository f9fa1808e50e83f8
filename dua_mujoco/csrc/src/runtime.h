// The predictor at run time: one per MuJoCo mjData, or per set of free spheres. It reads a
// model's tables (tables.h), and each step it runs the violation check, the selection, tau at
// every level and the reinsertion (step.cc, schedule.cc), renews pruned pairs (pruned.cc), keeps
// the standing state and logs the alarms. The MuJoCo plugin (plugin.cc) and the Python Predictor
// (bindings.cc) both run it: one implementation, two callers, which differ only in what they do
// when the clock jumps or a state is not finite (the plugin starts over, Python raises). Free
// spheres (the paper's setting, SpherePredictor) run it too, on tables of N point bodies with no
// model (FreeTables), reading the caller's centres and velocities (SetPoints) where the others
// read an mjData: their escape test runs on every sphere before each step, since no violation
// check flags them.
#ifndef DUA_MUJOCO_RUNTIME_H_
#define DUA_MUJOCO_RUNTIME_H_

#include <mujoco/mujoco.h>

#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "dua/dua.h"
#include "internal.h"
#include "kinematics.h"
#include "mocap.h"
#include "plan.h"
#include "pruned.h"
#include "schedule.h"
#include "tables.h"
#include "universe.h"

namespace dua {

// The alarms the steps raise, appended and never overwritten while someone else holds it: a
// step's alarms are a span of it. A log without room for another step is replaced by a fresh
// one, and lives as long as someone holds it (Python's Alarms do); held by the runtime alone, it
// is rewound instead.
struct DUA_API AlarmLog {
  explicit AlarmLog(int64_t capacity)
      : pair(capacity),
        geom1(capacity),
        geom2(capacity),
        sphere1(capacity),
        sphere2(capacity),
        tau(capacity),
        fresh(capacity) {}
  int64_t capacity() const { return static_cast<int64_t>(pair.size()); }
  // The model pair, its geoms (the plane or static geom second), its spheres (-1: none), tau,
  // and whether the alarm is new (the pair did not stand in alarm before the step).
  std::vector<int64_t> pair;
  std::vector<int32_t> geom1, geom2, sphere1, sphere2;
  std::vector<double> tau;
  std::vector<uint8_t> fresh;
};

// Pruned pairs: rebuilds a learnt pair may go unheld before it is forgotten (Runtime::SetForget)
// in the plugin, unless its attribute says otherwise, and for free spheres; memory then stays
// bounded over a long run.
constexpr int64_t kForgetDefault = 8;

class DUA_API Runtime {
 public:
  // A step's result when a state the step needed was not finite and no pair can be named (a
  // rebuild or renewal of pruned pairs): the step was not taken.
  static constexpr int64_t kBadState = std::numeric_limits<int64_t>::min();

  // log_steps: steps' worth of alarms a log holds (at least log_min entries). Free spheres'
  // tables (FreeTables) have no model: m null, and every call below takes m and d null, the
  // states set by SetPoints.
  Runtime(std::shared_ptr<const Tables> tables, const mjModel* m, int64_t log_steps = 1,
          int64_t log_min = 0);
  // A copy runs on its own: its state deep-copied, the tables and the current log shared (the
  // copy appends to a log of its own).
  Runtime(const Runtime& other);
  Runtime& operator=(const Runtime&) = delete;

  // The initial classification at d's state: every held pair evaluated and scheduled (pruned:
  // the held ones chosen first). Returns -1, or a held pair whose state was not finite (every
  // pair then stands in alarm).
  int64_t Classify(const mjModel* m, const mjData* d);
  // One predictor step on d, one period after the last classification or step: returns the
  // number of alarms, logged at log_start(), or -1 - p for held pair p whose state was not
  // finite, or kBadState (either way the step was not taken).
  int64_t Step(const mjModel* m, const mjData* d);
  // What d's clock calls for since the last classification or step.
  enum class Clock { kSame, kWithinPeriod, kOnePeriod, kOther };
  Clock ClockOf(double time) const;
  // The next compute classifies again (the plugin's reset, or a state it could not step from).
  void Invalidate() { classified_ = false; }
  // Free spheres: the centres and velocities (nsphere, 3) the next classification or step reads
  // (the caller's arrays, read during that call only).
  void SetPoints(const double* centers, const double* velocities) {
    points_ = {centers, velocities};
  }

  // Switches model pairs `pairs` off or back on (a pair switched back on stands in alarm until
  // the next step evaluates it; pruned pairs not held now stay switched for when they are).
  void Switch(const std::vector<int64_t>& pairs, bool on);
  // The pairs between bodies a and b (b < 0: every pair of a), those not met yet learnt first
  // (pruned pairs); returns their model pair ids.
  std::vector<int64_t> PairsBetweenBodies(const mjModel* m, int body_a, int body_b);
  // Geom pair ids of {g1[k], g2[k]} (-1 where MuJoCo's filter rejects the pair), the pairs not
  // met yet learnt first (pruned pairs).
  std::vector<int64_t> GeomPairIds(const std::vector<int64_t>& g1, const std::vector<int64_t>& g2);

  // Switches off the pairs of every geom pair in contact in d (resting contact; pruned pairs: a
  // contact of a pair not met yet learns it); returns how many geom pairs.
  int64_t DeactivateContacts(const mjData* d);

  // A watcher (the gym wrapper) reads, after each step in O(1), how many counted geom pairs stand
  // in alarm, how many started to at that step, and the least time the counted verdicts still
  // vouch for. Geom pairs count unless a geom of theirs is in ignored_geoms (ngeom flags) or the
  // pair in ignored_pairs (keys g1 << 32 | g2, g1 < g2, sorted); pairs learnt later too.
  void Watch(const std::vector<uint8_t>& ignored_geoms, const std::vector<int64_t>& ignored_pairs);
  struct Watched {
    int64_t standing = 0;  // counted geom pairs standing in alarm
    int64_t started = 0;   // of them, those whose alarm the latest step started
    double expiry = std::numeric_limits<double>::infinity();  // min of tau + last step time
    int64_t version = 0;  // changes whenever the set of counted standing geom pairs does
  };
  const Watched& watched() const { return watched_; }
  // The counted geom pairs standing in alarm, rows (g1, g2) in increasing order.
  std::vector<int64_t> WatchedStanding() const;

  // Flight plans (plan.h; docs/theory.md, section 8). SetPlan follows `plan` (its knots at
  // start + j h, h the model's timestep, its bodies, deviations and mocap poses): every held pair
  // is evaluated again at the next step, under it. The plan must cover the state the next step
  // reads (StateTime), and the bodies it holds must have boxes in the violation check (the
  // deviation is measured at their corners). The plan it replaces stays as a *shadow*, checked
  // only, over the span its verdicts cover (until the state of the first step under the new plan
  // plus the alarm horizon and the latency): a body found beyond its old deviation there breaks
  // the old plan (counted, its pairs made due, reported by PlanBroken). departures (nbody) or
  // null receives, per body, the first state time in that span at which the new plan leaves the
  // old plan's deviation tube (|new - old| + D_new > D_old at a box corner; the first step when
  // the new plan does not hold the body; +inf: never). Returns an error message naming the bad
  // input, or "".
  std::string SetPlan(const mjModel* m, const dua_plan_input& plan, double* departures);
  // Back to the motion bounds alone (every held pair evaluated again at the next step; the plan
  // stays as a shadow, as when replaced).
  void ClearPlan();
  // How many timesteps the state a step reads lags d->time: 1 after mj_step (Python's Predictor,
  // whose state is the one MuJoCo's step started from), 0 inside mj_step (the plugin's compute,
  // before time advances). Plans place their knots by it.
  void SetReadLag(int steps) { read_lag_ = steps; }
  double StateTime(const mjModel* m, const mjData* d) const {
    return d->time - read_lag_ * m->opt.timestep;
  }
  bool has_plan() const { return plan_ != nullptr; }
  const Plan* plan() const { return plan_.get(); }
  // Bodies the plan holds and found within their deviation so far (the rest follow their bounds).
  const std::vector<uint8_t>& plan_ok() const { return plan_ok_; }
  // Bodies found beyond their deviation (of the plan, or of a shadow over its span), so far.
  int64_t plan_breaks() const { return plan_breaks_; }
  int64_t plan_queries() const { return args_.plan.queries; }
  // The tolerance the latest PlanQuery's candidate plan declared (Plan::tolerance; tests).
  double query_tolerance() const { return query_tolerance_; }
  // The exact level's mj_geomDistance calls so far (the plan's apart).
  int64_t exact_queries() const { return args_.exact.queries; }
  // The bodies of d's state beyond their deviation at its knot, of the plan and of the shadows
  // within their spans (-1 in out[0]: none covers it), checking only; the monitor's
  // every-step check.
  std::vector<int64_t> PlanBroken(const mjModel* m, const mjData* d) const;
  // The relative pairs (a, b) of d's state beyond their relative deviation (Lemma 8.2d), of the
  // plan and of the shadows within their spans, as PlanBroken's bodies: (2 n,) body ids.
  std::vector<int64_t> PlanBrokenRelative(const mjModel* m, const mjData* d) const;
  // The plan's relative pairs still within their relative deviation (Plan::relative order).
  const std::vector<uint8_t>& rel_ok() const { return rel_ok_; }
  // The check of a step's plan, between steps (period > 1: the plugin's compute at each physics
  // step, Predictor.check_plan): bodies found beyond their deviation are counted as breaks and
  // their pairs made due at the next step. Returns them.
  std::vector<int64_t> CheckPlan(const mjModel* m, const mjData* d);
  // What each held pair's latest verdict, and the one before it, rested on (dua_plan.basis).
  const std::vector<uint8_t>& basis() const { return basis_; }
  const std::vector<uint8_t>& basis_prev() const { return basis_prev_; }

  // For a candidate plan (built here, never followed) and geom pairs (g1[k], g2[k]), each pair's
  // first knot of the candidate, from the knot of d's state, at which its contact cannot be
  // excluded (the candidate's knot count when never): the plan's tau (8) where both bodies are
  // planned (the candidate holds them, or they are static), the mixed tau where one is and the
  // other follows its bounds from d's state (PlanPass's code). -1: the candidate plans neither
  // body (it says nothing of the pair); -2: not a pair this runtime knows (MuJoCo's filter
  // rejects it, or a pruned runtime has not met it: GeomPairIds learns it). Changes nothing of
  // the predictor's (the shield's question, issue 40). Returns an error naming bad input, or "".
  std::string PlanQuery(const mjModel* m, const mjData* d, const dua_plan_input& candidate,
                        const std::vector<int64_t>& g1, const std::vector<int64_t>& g2,
                        std::vector<int64_t>* knots) const;
  // PlanQuery in two parts, for a caller asking about the same geom pairs again and again (the
  // shield): the pairs' records prepared once (their sphere pairs' rows copied; the exact level
  // learns directions into the copy), then each plan's knots from knot k on d's state.
  struct QueryPairs {
    std::vector<int64_t> slot;  // each asked pair's distinct geom pair (-1: not known)
    int64_t nslot = 0;
    std::vector<double> pairs, exact;            // the slots' sphere pairs' records
    std::vector<int64_t> owner, geom_a, geom_b;  // each record's slot and geoms
    std::vector<double> state;                   // the point cache a query fills
    std::vector<int64_t> epoch, by_slot;
    std::vector<uint8_t> ok, said;
  };
  QueryPairs PrepareQuery(const std::vector<int64_t>& g1, const std::vector<int64_t>& g2) const;
  void QueryKnots(const mjModel* m, const mjData* d, const Plan& plan, int64_t k, QueryPairs* q,
                  std::vector<int64_t>* knots) const;

  // ---------------------------------------------------------------------- for tests
  // The exact level alone on held pairs ids, from sphere taus `coarse`, with the level's records
  // as built (no direction learnt) and MuJoCo asked afresh below query_below; nothing changes.
  std::vector<double> ExactOnly(const mjModel* m, const mjData* d, const std::vector<int64_t>& ids,
                                const std::vector<double>& coarse, double query_below);
  // The violation check of d's state on a copy of its state, four bodies at a time or one at a
  // time (the reference the lanes are held to): the flagged rows and the state written after.
  std::pair<std::vector<int64_t>, std::vector<double>> CheckBodiesCopy(const mjModel* m,
                                                                       const mjData* d, bool lanes);
  // Pruned pairs: whether the step looks for escaped spheres (on; off only to show what the
  // check guards).
  void SetEscapeCheck(bool on) { escape_check_ = on; }

  // ---------------------------------------------------------------------- forgetting (issue 35)
  // Pruned pairs: a learnt geom pair none of whose sphere pairs was held at the latest `after`
  // rebuilds is forgotten (its rows freed, later ids renumbered in order; Lemma 7.1 of
  // docs/theory.md: the held sets are those of a run that never forgets). after < 0: never (the
  // Python Predictor's, whose mirrors of the universe assume ids that only grow).
  void SetForget(int64_t after) { forget_after_ = after; }
  int64_t forget_after() const { return forget_after_; }
  int64_t forgotten() const { return forgotten_; }      // geom pairs forgotten so far
  int64_t compactions() const { return compactions_; }  // times the universe was compacted

  // ---------------------------------------------------------------------- what it holds
  const Tables& tables() const { return *tables_; }
  bool classified() const { return classified_; }
  int64_t step() const { return step_; }
  double last_time() const { return last_time_; }
  // The pairs known (the model's tables, or this run's own universe when pruned).
  const Universe& universe() const { return tables_->pruned ? own_ : tables_->universe; }
  // The geoms a plan's poses are kept for (Plan::Build's `geoms`).
  const std::vector<int64_t>& plan_geoms() const { return plan_geoms_; }
  int64_t universe_version() const { return universe_version_; }
  // The held pairs' model ids (sorted), and the schedule over them.
  const std::vector<int64_t>& ids() const { return ids_; }
  // The exact level's records with the directions learnt so far (empty when the level is off).
  const std::vector<double>& exact_records() const { return exact_records_; }
  // The exact level's witness points of each held pair's latest query, each in its geom's frame
  // ((held pairs, 6); NaN before the first).
  const std::vector<double>& exact_witness() const { return witness_; }
  int64_t held_version() const { return held_version_; }
  // Replaced (never resized) by a classification or a carry: a holder keeps the one it has.
  const std::shared_ptr<Schedule>& schedule() const { return schedule_; }
  const std::vector<uint8_t>& on() const { return on_; }  // each known pair's switch
  // The standing state: each held pair's, and how many geom pairs stand.
  const std::vector<uint8_t>& stands() const { return stands_; }
  // The held pairs standing in alarm, in no order (kept in O(1) a change).
  const std::vector<int64_t>& standing() const { return standing_; }
  // Held pair p's record (pair records' columns).
  const double* HeldRecord(int64_t p) const {
    return tables_->pruned ? held_pairs_.data() + kPairNcol * p
                           : tables_->universe.pairs.data() + kPairNcol * ids_[p];
  }
  const std::vector<int32_t>& geom_pair_count() const { return gp_count_; }
  int64_t nstanding() const { return nstanding_; }
  double min_tau() const { return min_tau_; }
  int64_t evaluated() const { return args_.count; }
  int64_t deferred() const { return args_.deferred; }
  int64_t flagged() const { return args_.events.nbody ? events_meta_[kMCount] : 0; }
  // The bodies (ids) the latest step's violation check flagged.
  std::vector<int64_t> FlaggedBodies() const;
  int64_t violation_events() const { return events_meta_[kMTotal]; }
  int64_t rebuilds() const { return rebuilds_; }
  int64_t renewals() const { return renewals_; }
  // Each sphere's anchor step (pruned pairs; empty otherwise).
  const std::vector<int64_t>& anchor_steps() const { return pruned_.built; }
  // Pruned pairs: each sphere's anchor, reach, and the largest contact distance beyond radii.
  const PrunedState& pruned_state() const { return pruned_; }
  const std::shared_ptr<AlarmLog>& log() const { return log_; }
  int64_t log_start() const { return log_start_; }
  // Alarms of the latest step or classification (logged from log_start()).
  int64_t log_count() const { return log_used_ - log_start_; }
  // The mocap bodies' velocities (differenced at each step, or given) and their trees' twists.
  Mocap& mocap() { return mocap_; }
  const Mocap& mocap() const { return mocap_; }
  // The step's arguments, pointed at d (and this runtime's buffers).
  dua_step_args& Bind(const mjModel* m, const mjData* d);

 private:
  // Bind's rarely taken branches, out of its lines (DUA_COLD, lanes.h): room for ncon contacts,
  // whether some basis is still a plan's, and a plan's arguments.
  DUA_COLD void GrowContacts(int ncon);
  // args_'s fields that only the tables and the held set's buffers set, written once per held
  // set rather than at every step (held_bound_).
  DUA_APART void BindHeld();
  DUA_APART bool BasisNonzero() const;
  DUA_APART void BindPlan(const mjModel* m);
  const LearnTables& learn() const { return tables_->learn; }
  int64_t npair() const { return static_cast<int64_t>(ids_.size()); }
  void Hold(const std::vector<int64_t>& held);
  void NewLog();
  bool Prune(const mjModel* m, const mjData* d, int64_t n);
  void Carry(const mjModel* m, const mjData* d, const std::vector<int64_t>& held, int64_t n);
  void Learnt();
  // Whether each pair of ids stands now recorded, and the watch's counts with it; alarms (the
  // step's alarm list, when it lists exactly the pairs of ids that stand, in ids's order: see
  // TrackStep) is read in place of the alarm rule, or null.
  void Track(const int64_t* ids, int64_t n, const int64_t* alarms = nullptr, int64_t nalarm = 0);
  // Pair p's standing becomes now (Track's, where it changed).
  void Flip(int64_t p, uint8_t now);
  void TrackAll();
  void TrackStep(int64_t nalarm);
  void Log(int64_t nalarm);
  bool Counted(int64_t gp) const;
  // The plan's part of step n at d: between-step breaks' pairs made due, the shadows checked,
  // the plan's knot, the bodies beyond their deviation flagged and their pairs made due; past
  // its end, the plan dropped (every pair due).
  void FollowPlan(const mjModel* m, const mjData* d, int64_t n);
  DUA_APART void FollowPlans(const mjModel* m, const mjData* d, int64_t n);  // its work, if any
  // The plan's and the shadows' checks of d's state: the bodies found beyond their deviation
  // appended to broken and marked (shadows past their span dropped); returns the plan's knot
  // (-1: no plan covers the state).
  // Relative pairs found beyond their relative deviation go to rel_broken as body-pair keys
  // (a * nbody + b), marked off too.
  int64_t CheckPlans(const mjModel* m, const mjData* d, std::vector<int64_t>* broken,
                     std::vector<int64_t>* rel_broken);
  // The held pairs of a relative pair broken (key a * nbody + b) made due at step n, their walks
  // forgotten (they were walked with the relative bound).
  void MakeRelativeDue(const mjModel* m, int64_t key, int64_t n);
  // A relative pair of plan's bodies without a box in the violation check: an error, or "".
  std::string RelativeBoxed(const mjModel* m, const Plan& plan) const;
  struct Shadow;
  // The bodies shadow sh checks at state time now (the plan at knot k): those still within it,
  // from the plan's departure from it on, or once the plan no longer proves them within.
  void ShadowOpen(const Shadow& sh, double now, int64_t k, double h,
                  std::vector<uint8_t>* open) const;
  // The same for its relative pairs: from the plan's departure from their relative tube on, or
  // once the plan no longer proves them within (it breaks them, or one of their bodies).
  void ShadowOpenRelative(const Shadow& sh, double now, int64_t k, double h,
                          std::vector<uint8_t>* open) const;
  // The first state time in shadow sh's span, from `next`, at which `plan` leaves its relative
  // tubes, into sh.rel_from (SetPlan).
  // Pairs nested in both `chain` (the newest shadow, checked first; null: none) and sh's record
  // of chain's plan are nested without a check (Lemma 8.6).
  void RelativeDepartures(const Plan& plan, double next, double h, const Shadow* chain,
                          Shadow* sh) const;
  // The plan (if any) becomes a shadow over the span its verdicts cover, the next step's.
  void Retire();
  // At a new plan (first knot jn0, the state time next): each held pair's cleared knots of
  // `walked`, the plan replaced, kept where both bodies (and their relative pair) stay in its
  // tubes, per nest_end and rel_end (the new plan's first knot not known to).
  void CarryCleared(const mjModel* m, const Plan* walked, const std::vector<int64_t>& nest_end,
                    const std::vector<int64_t>& rel_end, int64_t jn0, double next);
  void MakeBodyDue(const mjModel* m, int64_t body, int64_t n);
  void DropPlans();
  void MakeAllDue(int64_t n);
  void FinishWatch();         // a step's or a classification's end: started and version
  void SetExpiry(int64_t p);  // pair p's leaf of the expiry tree, and its path to the root
  void ForgetStale(std::vector<int64_t>* held);  // at a rebuild (issue 35)

  std::shared_ptr<const Tables> tables_;
  int64_t log_steps_, log_min_;
  std::shared_ptr<Schedule> schedule_;
  // The members every step's glue reads (Compute, Step, Bind, Log, TrackStep, FollowPlan) come
  // first, on as few lines as they fit: the step runs cold (MuJoCo's step evicts them between
  // two calls), so each line they spread over is a data miss a step (docs/benchmarks.md,
  // issue 42, "The step's lines").
  // The alarm log and where the latest step's alarms start in it.
  std::shared_ptr<AlarmLog> log_;
  std::shared_ptr<const Plan> plan_;  // the flight plan (none: null); see below
  int64_t log_used_ = 0, log_start_ = 0;
  double last_time_ = 0.0;
  int64_t step_ = 0;
  int64_t nstanding_ = 0;
  double min_tau_ = std::numeric_limits<double>::infinity();
  bool classified_ = false;
  bool escape_check_ = true;
  // Whether args_ points at this runtime's held-set buffers and tables (BindHeld): false until
  // Bind, again at each Hold (which reallocates them), and in a copy (whose args_ points at the
  // original's: the copy constructor leaves it false).
  bool held_bound_ = false;
  // Whether some pair's basis (or the one before) may be a plan's: false until a plan is set, and
  // again once every one is the bounds' (0), when the step need not shift them (Bind).
  bool basis_live_ = false;
  bool watching_ = false;     // the watcher's (Watch, below)
  std::vector<int64_t> ids_;  // model pair of each held pair
  std::vector<int64_t> events_meta_, contact_keys_;
  std::vector<double> contact_dist_;
  // Standing state (see stands()), and the list of the held pairs standing with each one's place
  // in it (-1: not standing).
  std::vector<uint8_t> stands_;
  std::vector<int64_t> standing_, standing_at_;
  std::vector<int32_t> gp_count_;
  // Per held pair, the knot its latest walk under the plan as it stands ended at (dua_plan's
  // `cleared`, -1: none; -2 - knot: not walked under it yet, the knots before that one cleared
  // by the replaced plan's walk, CarryCleared): forgotten at a new held set.
  std::vector<int64_t> cleared_;
  dua_step_args args_{};
  std::vector<double> point_state_, exact_records_;
  std::vector<double, LanesAligned<double>> events_prev_;  // the check's lanes read it in place
  std::vector<double> witness_;  // the exact level's witness points, (held pairs, 6)
  std::vector<int64_t> point_epoch_, events_flagged_;
  dua_points points_{};  // free spheres' states for the current call
  // Pruned pairs: the anchors, this run's universe, the held pairs' records and their index by
  // the violation check's bodies (all pairs held: the model's tables themselves).
  PrunedState pruned_;
  Universe own_;
  std::vector<double> held_pairs_;
  std::vector<int64_t> held_start_, held_members_;
  std::vector<uint8_t> on_;
  Mocap mocap_;  // the poses at the last step
  int64_t rebuilds_ = 0, renewals_ = 0;
  int64_t universe_version_ = 0, held_version_ = 0;
  // The watcher's state (Watch): the ignore lists, each geom pair's count flag, and a min-tree
  // of the held pairs' expiries (leaves at [size, 2 size)).
  std::vector<uint8_t> ignored_geoms_, gp_counted_, was_;
  std::vector<int64_t> ignored_pairs_, touched_;
  std::vector<double> expiry_tree_;
  int64_t expiry_size_ = 0;
  Watched watched_;
  // The flight plan's (plan_, above): the bodies still within their deviation, and the mjData
  // the plan's kinematics and MuJoCo's distance queries at knots use.
  struct DataDeleter {
    void operator()(mjData* d) const { mj_deleteData(d); }
  };
  std::unique_ptr<mjData, DataDeleter> plan_data_;
  mutable std::unique_ptr<mjData, DataDeleter> query_data_;  // PlanQuery's scratch
  mutable double query_tolerance_ = 0.0;  // the latest PlanQuery plan's tolerance (for tests)
  std::vector<uint8_t> plan_ok_, planned_, basis_, basis_prev_;
  // A replaced plan, checked until `until` (state time) on the bodies ok when it was replaced
  // and not found beyond it since; the state time each was found beyond it (NaN: not), and
  // the first state at which the plan that followed leaves its tube (SetPlan; -inf: unknown).
  struct Shadow {
    std::shared_ptr<const Plan> plan;
    std::vector<uint8_t> ok;
    double until;
    std::vector<double> broken_at, from;
    // Its relative pairs still within their bound, the state time each was found beyond it
    // (NaN: not), and the first state at which the plan that followed leaves its relative tube
    // (as `from`, for the relative pose of the pair's second body in its first's frame).
    std::vector<uint8_t> rel_ok;
    std::vector<double> rel_broken_at, rel_from;
    // Its plan's number (plan_serial_ when it was set), and the number of the plan it was last
    // found to hold nested (-1: none): per body and relative pair, whether that plan never
    // leaves this one's tube over the rest of its span (found by a check, or by two nestings in
    // turn, docs/theory.md, Lemma 8.6). A replan nested in the newest shadow is then nested in
    // the older ones where they nested that shadow's plan, without checking their knots.
    int64_t serial = -1, nested_in = -1;
    std::vector<uint8_t> nested, rel_nested;
    // Each of its relative pairs' index among the plan in force's (-1: none), for that plan
    // (number mapped_for) only: the step asks it of every pair of every shadow, and a search of
    // the plan's pairs each time was most of a step's checks of its shadows on g1.
    std::vector<int64_t> rel_in_plan;
    int64_t mapped_for = -1;
  };
  std::vector<Shadow> shadows_;
  std::vector<int64_t> pending_due_;  // bodies broken between steps: pairs due at the next
  std::vector<int64_t> pending_rel_;  // relative pairs (keys) broken between steps
  std::vector<uint8_t> rel_ok_;       // the plan's relative pairs within their bound so far
  std::vector<int64_t> plan_due_;     // held pairs the plan made due at this step (tracked)
  std::vector<int64_t> body_row_;     // each body's row of the violation check (-1: none)
  std::vector<uint8_t> unboxed_;      // bodies with covered geoms and no row (no plan holds them)
  std::vector<int64_t> plan_geoms_;   // the geoms a plan's poses are read for (Plan::Build)
  std::shared_ptr<PlanPool> plan_pool_ = std::make_shared<PlanPool>();  // (a copy: its own)
  // The knots' kinematics of plan_geoms_ on the model they were made for (a plan's are the same
  // for every plan of it, with the still bodies' frames computed once): each runtime its own
  // (Run writes its scratch frames), made at the first plan, not copied.
  std::unique_ptr<KnotKinematics> knots_;
  const mjModel* knots_model_ = nullptr;
  int64_t plan_breaks_ = 0;
  int64_t plan_serial_ = 0;  // plans set so far (Shadow::serial)
  int read_lag_ = 1;
  // Forgetting (issue 35): each learnt geom pair's latest rebuild held, and the counts.
  int64_t forget_after_ = -1;
  std::vector<int64_t> gp_seen_;
  int64_t forgotten_ = 0, compactions_ = 0;
};

}  // namespace dua

#endif  // DUA_MUJOCO_RUNTIME_H_
