// The MuJoCo sensor plugin "dua_mujoco.predictor": the predictor's step inside mj_step.
//
// The tables (covering spheres, pairs, shapes, bounds, the exact level's records, the violation
// check's boxes, the schedule's parameters) travel in the model as custom text fields
// "<prefix>:<table>", written by dua_mujoco.attach (plugin_tables.cc reads them). init decodes
// them; every copy of the mjData shares them. What changes as the simulation runs (the schedule,
// the exact level's last directions, the violation check's last states) lives in plugin_data, one
// Instance per mjData: init allocates it, copy duplicates it, reset clears it, destroy frees it.
//
// Timing. compute runs at the velocity stage of each mj_forward (and so of each mj_step), on the
// kinematics of the state the step starts from: the instant the Python predictor reads after
// that mj_step (docs/discrete-time.md). The first compute after init or mj_resetData classifies
// every pair (the Python predictor's reset); later ones step the schedule when the clock has
// advanced by one predictor period, do nothing when it has not moved (an mj_forward between
// steps) or has moved by whole physics steps within the period, and classify again when it
// moved any other way (time set back, a jump).
//
// Pruned pairs (attach(spec, pairs="pruned")): the schedule runs over the held pairs only,
// chosen and renewed as the Python predictor chooses them (pruned.cc); `ids` maps a held
// position to the model's pair.
#include <mujoco/mjplugin.h>
#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "dua/dua.h"
#include "internal.h"
#include "plugin_tables.h"
#include "pruned.h"

namespace dua {
namespace {

constexpr char kPluginName[] = "dua_mujoco.predictor";
constexpr const char* kAttributes[] = {"prefix", "overlay"};
constexpr int kNAttribute = sizeof(kAttributes) / sizeof(kAttributes[0]);
constexpr double kInf = std::numeric_limits<double>::infinity();

// Sensor outputs.
enum Output {
  kStanding = 0,   // geom pairs standing in alarm
  kMinTau = 1,     // least tau of the latest step's evaluations (seconds, inf if none)
  kEvaluated = 2,  // tau evaluations this step
  kDeferred = 3,   // pairs due this step but left for a later one (a capped schedule)
  kFlagged = 4,    // bodies whose motion broke its bounds this step
  kNOutput = 5,
};

struct Instance {
  std::shared_ptr<const Tables> tables;
  int sensor_adr = -1;
  bool overlay = true;
  bool skip_subtree_vel = false;  // see SubtreeVelUnused

  // Per-mjData state.
  std::vector<double> last_tau, w_tau, scratch, point_state, exact_records, events_prev, root_twist;
  std::vector<uint8_t> active;
  std::vector<int64_t> ints, slots, queue, params, work, ids, events_meta, events_flagged;
  std::vector<int64_t> log_pairs, point_epoch;
  std::vector<double> log_tau;
  std::vector<uint8_t> log_new;
  // Which pairs stand in alarm, kept up to date from the pairs each step renews (no other
  // pair's standing changes): the sphere pairs, their count per geom pair, the geom pairs.
  std::vector<uint8_t> stands;
  std::vector<int32_t> gp_count;
  int64_t nstanding = 0;
  double min_tau = kInf;
  // Mocap bodies (by mocap id) and their poses at the last step, differenced into the twists
  // of the trees they root (root_twist), as dua_mujoco.mj.mocap does.
  std::vector<int64_t> mocap_bodies;
  std::vector<double> mocap_pos, mocap_quat, mocap_linear, mocap_angular;
  std::vector<uint8_t> mocap_user;
  bool classified = false;
  double last_time = 0.0;
  int64_t step = 0;
  dua_step_args args{};
  // Pruned pairs: the anchors, each model pair's switch, and the held pairs' records and index
  // by body (all pairs held: the model's tables themselves).
  PrunedState pruned;
  Universe own;  // pruned pairs: the pairs known in this mjData (learnt ones too)
  std::vector<uint8_t> on;
  std::vector<double> held_pairs;
  std::vector<int64_t> held_start, held_members;

  int64_t npair() const { return static_cast<int64_t>(ids.size()); }
  // The pairs known: the model's tables, or this mjData's own universe (pruned pairs).
  const Universe& U() const { return tables->pruned ? own : tables->universe; }
  // After learning: room for the new pairs' switches (on) and geom pairs' standing counts.
  void Grow() {
    on.resize(U().npair(), 1);
    gp_count.resize(U().ngp(), 0);
  }

  void Allocate(const mjModel* m) {
    const Tables& t = *tables;
    if (t.pruned) pruned.Allocate(t.held), own = t.universe;
    const int64_t n = t.universe.npair();
    on.assign(n, 1);
    ids.resize(n);
    for (int64_t p = 0; p < n; ++p) ids[p] = p;
    Size(n);
    exact_records = t.universe.exact;
    events_prev.assign(dua::EventStateLen(t.nbody_events), 0.0);
    events_meta.assign(3, 0);
    events_flagged.assign(std::max<int64_t>(t.nbody_events, 1), 0);
    root_twist.assign(6 * m->nbody, 0.0);
    point_state.assign(6 * t.nsphere(), 0.0);
    point_epoch.assign(t.nsphere(), -1);
    gp_count.assign(t.universe.ngp(), 0);
    mocap_bodies.assign(m->nmocap, -1);
    for (int b = 0; b < m->nbody; ++b) {
      if (m->body_mocapid[b] >= 0) mocap_bodies[m->body_mocapid[b]] = b;
    }
    mocap_pos.assign(3 * m->nmocap, 0.0);
    mocap_quat.assign(4 * m->nmocap, 0.0);
    mocap_linear.assign(3 * m->nmocap, 0.0);
    mocap_angular.assign(3 * m->nmocap, 0.0);
    mocap_user.assign(m->nmocap, 0);
  }

  // The schedule's buffers for `npair` pairs (held ones, when pruned: the work width is theirs).
  void Size(int64_t n) {
    const Tables& t = *tables;
    const int64_t width =
        std::max<int64_t>(t.pruned ? n : static_cast<int64_t>(t.Config(kCfgWidth)), 1);
    last_tau.assign(n, kInf);
    active.assign(n, 1);
    ints.assign(static_cast<size_t>(t.Config(kCfgRows)) * n, 0);
    slots.assign(static_cast<size_t>(t.Config(kCfgNslots)), -1);
    queue.assign(static_cast<size_t>(t.Config(kCfgNqueue)) + 1, 0);
    params.assign(9, 0);
    work.assign(4 * width, 0);
    w_tau.assign(width, 0.0);
    scratch.assign(12 * std::max(width, n), 0.0);  // the classification's too
    log_pairs.assign(width, 0);
    log_tau.assign(width, 0.0);
    log_new.assign(width, 0);
    stands.assign(n, 0);
  }

  // Hold the sorted model pairs `held`: their records gathered (the exact level's afresh, as
  // Predictor._hold does), and indexed by the bodies the violation check reads.
  void Hold(const std::vector<int64_t>& held) {
    const Tables& t = *tables;
    ids = held;
    const auto n = static_cast<int64_t>(held.size());
    held_pairs.resize(kPairNcol * n);
    for (int64_t k = 0; k < n; ++k) {
      std::copy_n(U().pairs.begin() + kPairNcol * held[k], kPairNcol,
                  held_pairs.begin() + kPairNcol * k);
    }
    if (t.exact) {
      exact_records.resize(kXNcol * n);
      for (int64_t k = 0; k < n; ++k) {
        std::copy_n(U().exact.begin() + kXNcol * held[k], kXNcol,
                    exact_records.begin() + kXNcol * k);
      }
    }
    // Indexed by the violation check's rows, as EventTable.hold indexes them.
    std::vector<int64_t> g1(n), g2(n);
    for (int64_t k = 0; k < n; ++k) g1[k] = U().geom1[held[k]], g2[k] = U().geom2[held[k]];
    held_start.resize(t.nbody_events + 1);
    held_members.resize(2 * n);
    held_members.resize(dua_index_by_row(t.geom_row.data(), g1.data(), g2.data(), n, t.nbody_events,
                                         held_start.data(), held_members.data()));
  }

  // A new trajectory: record the mocap poses; their twists are zero until the next step.
  void StartMocap(const mjData* d) {
    for (size_t i = 0; i < mocap_bodies.size(); ++i) {
      const int64_t b = mocap_bodies[i];
      std::copy(d->xpos + 3 * b, d->xpos + 3 * b + 3, mocap_pos.begin() + 3 * i);
      std::copy(d->xquat + 4 * b, d->xquat + 4 * b + 4, mocap_quat.begin() + 4 * i);
    }
    std::fill(mocap_linear.begin(), mocap_linear.end(), 0.0);
    std::fill(mocap_angular.begin(), mocap_angular.end(), 0.0);
    std::fill(root_twist.begin(), root_twist.end(), 0.0);
  }

  // The mocap bodies' twists over the `elapsed` seconds since the last step.
  void DifferenceMocap(const mjModel* m, const mjData* d, double elapsed) {
    if (mocap_bodies.empty()) return;
    dua_difference_poses(d->xpos, d->xquat, mocap_bodies.data(),
                         static_cast<int64_t>(mocap_bodies.size()), mocap_pos.data(),
                         mocap_quat.data(), elapsed, mocap_user.data(), mocap_linear.data(),
                         mocap_angular.data(), root_twist.data(), m->nbody);
  }

  // Point the step's arguments at this instance's buffers and d's (after any copy).
  void Bind(const mjModel* m, const mjData* d) {
    const Tables& t = *tables;
    dua_step_args& a = args;
    a.abi = DUA_ABI_VERSION;
    dua_schedule& s = a.schedule;
    s.kind = static_cast<int64_t>(t.Config(kCfgKind));
    s.dt = t.Config(kCfgDt);
    s.latency = static_cast<int64_t>(t.Config(kCfgLatency));
    s.m = npair();
    s.last_tau = last_tau.data();
    s.active = active.data();
    s.ints = ints.data();
    s.slots = slots.data();
    s.nslots = static_cast<int64_t>(slots.size());
    s.horizon = const_cast<double*>(t.horizon.data());  // the step only reads it
    s.queue = queue.data();
    s.nqueue = static_cast<int64_t>(queue.size());
    s.params = params.data();
    s.work = work.data();
    s.width = static_cast<int64_t>(w_tau.size());
    s.w_tau = w_tau.data();
    a.pairs = t.pruned ? held_pairs.data() : t.universe.pairs.data();
    a.spheres = t.spheres.data();
    a.shapes = t.shapes.data();
    a.ids = ids.data();
    a.frame = {d->geom_xpos, d->geom_xmat, d->cvel, d->subtree_com, root_twist.data(), d->xpos};
    dua_exact& x = a.exact;
    x.on = t.exact ? 1 : 0;
    x.geoms = t.geoms.data();
    x.records = exact_records.data();
    x.below = t.Config(kCfgExactBelow);
    x.query_below = t.Config(kCfgQueryBelow);
    x.verts = t.verts.data();
    x.graph = t.graph.data();
    x.model = m;
    x.data = d;
    dua_events& e = a.events;
    e.nbody = t.nbody_events;
    e.rec = t.events_rec.data();
    e.prev = events_prev.data();
    e.meta = events_meta.data();
    e.flagged = events_flagged.data();
    e.start = t.pruned ? held_start.data() : t.events_start.data();
    e.members = t.pruned ? held_members.data() : t.events_members.data();
    e.params = t.events_params.data();
    a.scratch = scratch.data();
    a.scratch_rows = static_cast<int64_t>(scratch.size() / 12);
    a.point_state = point_state.data();
    a.point_epoch = point_epoch.data();
    a.log_pairs = log_pairs.data();
    a.log_tau = log_tau.data();
    a.log_new = log_new.data();
  }
};

// MuJoCo runs mj_subtreeVel before every velocity-stage sensor plugin, whether the plugin needs
// it or not (its TODO b/247107630): a pass over every body with mj_objectVelocity, much of what
// this plugin adds to a small robot's mj_step (panda: 0.12x of mj_step with it, 0.07x without).
// Nothing here reads subtree_linvel or subtree_angmom, so the plugin's passive call (in
// mj_fwdVelocity, after mj_comVel, before the sensors) marks them computed, when no one else in
// the model could read them: no subtree or user sensor, no other plugin. They then stay as a
// model without this plugin leaves them (computed on demand only, mj_subtreeVel), and the flag
// is cleared again once the sensors have run.
bool SubtreeVelUnused(const mjModel* m) {
  for (int i = 0; i < m->nsensor; ++i) {
    const int type = m->sensor_type[i];
    if (type == mjSENS_SUBTREELINVEL || type == mjSENS_SUBTREEANGMOM || type == mjSENS_USER) {
      return false;
    }
  }
  for (int i = 0; i < m->nplugin; ++i) {
    const mjpPlugin* plugin = mjp_getPluginAtSlot(m->plugin[i]);
    if (!plugin || std::string(plugin->name) != kPluginName) return false;
  }
  return true;
}

// Reads the instance's attributes and tables; null (after a warning naming what is wrong).
Instance* Create(const mjModel* m, int instance) {
  const char* prefix_attr = mj_getPluginConfig(m, instance, "prefix");
  const std::string prefix = (prefix_attr && *prefix_attr) ? prefix_attr : "dua";
  bool overlay = true;
  const char* overlay_attr = mj_getPluginConfig(m, instance, "overlay");
  if (overlay_attr && *overlay_attr) {
    const std::string v = overlay_attr;
    if (v == "false" || v == "0") {
      overlay = false;
    } else if (v != "true" && v != "1") {
      mju_warning(
          "dua_mujoco.predictor: plugin attribute 'overlay' = '%s' does not parse: use "
          "true or false.",
          v.c_str());
      return nullptr;
    }
  }
  std::shared_ptr<const Tables> tables = LoadTables(m, prefix);
  if (!tables) return nullptr;
  auto* in = new Instance;
  in->tables = std::move(tables);
  in->overlay = overlay;
  in->skip_subtree_vel = SubtreeVelUnused(m);
  for (int i = 0; i < m->nsensor; ++i) {
    if (m->sensor_type[i] == mjSENS_PLUGIN && m->sensor_plugin[i] == instance) {
      in->sensor_adr = m->sensor_adr[i];
      break;
    }
  }
  in->Allocate(m);
  return in;
}

// The initial classification at this instant: every held pair evaluated and scheduled, as the
// schedules' constructors in dua_mujoco.core.schedules do it (pruned pairs: the held ones
// chosen first, as Predictor.reset chooses them).
void Classify(const mjModel* m, mjData* d, Instance* in) {
  const Tables& t = *in->tables;
  in->StartMocap(d);
  in->Bind(m, d);
  std::fill(in->on.begin(), in->on.end(), 1);
  if (t.pruned) {
    std::vector<int64_t> held;
    if (!in->pruned.Select(t.held, t.learn, &in->own, in->args, 0, &held)) {
      // A state that is not finite: every pair known held, each standing in alarm (below).
      held.resize(in->U().npair());
      for (int64_t p = 0; p < in->U().npair(); ++p) held[p] = p;
    }
    in->Grow();
    in->pruned.built_at = 0;
    in->pruned.escapes.clear();
    in->Hold(held);
    in->Size(in->npair());
    in->Bind(m, d);
  }
  dua_step_args& a = in->args;
  dua_schedule& s = a.schedule;
  const int64_t n = in->npair();
  std::fill(in->active.begin(), in->active.end(), 1);
  std::fill(in->slots.begin(), in->slots.end(), -1);
  std::fill(in->queue.begin(), in->queue.end(), 0);
  for (int i = 0; i < kNParams; ++i) in->params[i] = static_cast<int64_t>(t.Config(kCfgParams + i));
  std::fill(in->ints.begin(), in->ints.end(), s.kind == kDeadline ? -1 : 0);
  if (s.kind == kDeadline) {  // LAST_STEP: 0
    std::fill(in->ints.begin() + n, in->ints.begin() + 2 * n, 0);
  }
  dua_reset_events(&a);
  std::vector<int64_t> all(n);
  for (int64_t p = 0; p < n; ++p) all[p] = p;
  if (dua_evaluate(&a, all.data(), n, in->last_tau.data()) >= 0) {
    // A state that is not finite: nothing can be predicted from it; every pair stands in alarm.
    std::fill(in->last_tau.begin(), in->last_tau.end(), -kInf);
  }
  if (s.kind == kDeadline) dua_deadline_classify(&s);
  if (s.kind == kRank) dua_rank_classify(&s);
  a.count = n;
  a.deferred = 0;
  in->classified = true;
  in->step = 0;
  in->last_time = d->time;
}

// Whether pair p stands in alarm: the alarm rule on its latest tau (the schedulers'
// alarm_state, docs/theory.md, section 3).
bool Stands(const dua_schedule& s, int64_t p) {
  if (!s.active[p]) return false;  // switched off: never reported
  double horizon = s.horizon[0];
  if (s.kind == kRank) horizon = s.horizon[BucketOf(s.ints[p])];  // its slot's bucket
  if (s.kind == kDeadline) {
    const int64_t where = s.ints[p], last_step = s.ints[s.m + p];
    horizon = where >= 0 ? static_cast<double>(where - last_step + s.latency) * s.dt : -kInf;
  }
  return s.last_tau[p] < horizon;
}

// Renew the standing of pairs ids[0:n].
void Track(Instance* in, const int64_t* ids, int64_t n) {
  const dua_schedule& s = in->args.schedule;
  for (int64_t k = 0; k < n; ++k) {
    const int64_t p = ids[k];
    const uint8_t now = Stands(s, p) ? 1 : 0;
    if (now == in->stands[p]) continue;
    in->stands[p] = now;
    int32_t& count = in->gp_count[in->U().pair_geom[in->ids[p]]];
    if (now) {
      if (count++ == 0) ++in->nstanding;
    } else if (--count == 0) {
      --in->nstanding;
    }
  }
}

// After a classification: every pair's standing.
void TrackAll(Instance* in) {
  std::fill(in->stands.begin(), in->stands.end(), 0);
  std::fill(in->gp_count.begin(), in->gp_count.end(), 0);
  in->nstanding = 0;
  std::vector<int64_t> all(in->npair());
  for (size_t p = 0; p < all.size(); ++p) all[p] = static_cast<int64_t>(p);
  Track(in, all.data(), in->npair());
  const std::vector<double>& tau = in->last_tau;
  in->min_tau = tau.empty() ? kInf : *std::min_element(tau.begin(), tau.end());
}

// After a step: the pairs it renewed (evaluated, and due but deferred) and those whose verdict
// the violation check withdrew (the rank schedule may leave them waiting, standing in alarm).
void TrackStep(Instance* in) {
  const dua_schedule& s = in->args.schedule;
  const dua_events& e = in->args.events;
  const int64_t* w_ids = s.work + s.width;
  Track(in, w_ids, in->args.count + in->args.deferred);
  for (int64_t k = 0; e.nbody && k < e.meta[1]; ++k) {
    const int64_t i = e.flagged[k];
    Track(in, e.members + e.start[i], e.start[i + 1] - e.start[i]);
  }
  in->min_tau = kInf;
  for (int64_t k = 0; k < in->args.count; ++k) in->min_tau = std::min(in->min_tau, s.w_tau[k]);
}

// The sensor outputs (O(1)).
void Publish(mjData* d, const Instance* in) {
  if (in->sensor_adr < 0) return;
  const dua_step_args& a = in->args;
  mjtNum* out = d->sensordata + in->sensor_adr;
  out[kStanding] = static_cast<mjtNum>(in->nstanding);
  out[kMinTau] = in->min_tau;
  out[kEvaluated] = static_cast<mjtNum>(a.count);
  out[kDeferred] = static_cast<mjtNum>(a.deferred);
  out[kFlagged] = static_cast<mjtNum>(a.events.nbody ? a.events.meta[1] : 0);
}

// Hold the sorted model pairs `held` from step n (Predictor._carry): kept pairs carry their
// verdicts (dua_deadline_carry), new ones stand in alarm, due at n; new ones switched off stay
// off; every held pair's standing renewed.
void Carry(const mjModel* m, mjData* d, Instance* in, const std::vector<int64_t>& held, int64_t n) {
  const std::vector<int64_t>& old = in->ids;
  const auto k = static_cast<int64_t>(held.size());
  std::vector<int64_t> src(k, -1);
  for (int64_t p = 0, q = 0; p < k; ++p) {
    while (q < static_cast<int64_t>(old.size()) && old[q] < held[p]) ++q;
    if (q < static_cast<int64_t>(old.size()) && old[q] == held[p]) src[p] = q;
  }
  // The old schedule's buffers stay alive (moved, not copied) while the carry reads them.
  const dua_schedule from = in->args.schedule;
  std::vector<double> last_tau = std::move(in->last_tau), w_tau = std::move(in->w_tau);
  std::vector<uint8_t> active = std::move(in->active);
  std::vector<int64_t> ints = std::move(in->ints), slots = std::move(in->slots),
                       queue = std::move(in->queue), params = std::move(in->params),
                       work = std::move(in->work);
  in->Hold(held);
  in->Size(k);
  std::fill(in->ints.begin(), in->ints.end(), -1);
  in->params = params;
  in->params[kParamCount] = in->params[kParamDeferred] = 0;
  in->Bind(m, d);
  dua_deadline_carry(&from, &in->args.schedule, src.data(), k, n);
  std::vector<int64_t> off;
  for (int64_t p = 0; p < k; ++p) {
    if (src[p] < 0 && !in->on[held[p]]) off.push_back(p);
  }
  if (!off.empty()) {
    dua_switch(&in->args.schedule, off.data(), static_cast<int64_t>(off.size()), 0, n);
  }
  const double min_tau = in->min_tau;
  TrackAll(in);
  in->min_tau = min_tau;
}

// Before step n, pruned pairs: a rebuild every stride steps (or when too many spheres escaped),
// else the renewal of the spheres the last step found escaped (Predictor.step). False if a
// state is not finite.
bool Prune(const mjModel* m, mjData* d, Instance* in, int64_t n) {
  const Tables& t = *in->tables;
  PrunedState& ps = in->pruned;
  const auto escaped = static_cast<int64_t>(ps.escapes.size());
  std::vector<int64_t> held;
  bool carry = false;
  if (n - ps.built_at >= t.held.stride || escaped > static_cast<int64_t>(t.Config(kCfgRenewMax))) {
    if (!ps.Select(t.held, t.learn, &in->own, in->args, n, &held)) return false;
    ps.built_at = n;
    carry = true;
  } else if (escaped) {
    std::vector<int64_t> found;
    if (!ps.Renew(t.held, t.learn, &in->own, in->args, n, &found)) return false;
    std::set_union(in->ids.begin(), in->ids.end(), found.begin(), found.end(),
                   std::back_inserter(held));
    carry = held.size() > in->ids.size();  // some pair is new
  }
  in->Grow();
  ps.escapes.clear();
  if (carry) Carry(m, d, in, held, n);
  return true;
}

void Compute(const mjModel* m, mjData* d, int instance) {
  auto* in = reinterpret_cast<Instance*>(d->plugin_data[instance]);
  if (!in) return;
  const Tables& t = *in->tables;
  if (!in->classified) {
    Classify(m, d, in);
    TrackAll(in);
    Publish(d, in);
    return;
  }
  const double dt = t.Config(kCfgDt), h = t.Config(kCfgTimestep);
  const double elapsed = d->time - in->last_time;
  if (std::fabs(elapsed) <= 1e-6 * h) {
    Publish(d, in);  // an mj_forward at the same instant: the outputs stand
    return;
  }
  const bool one_period = std::fabs(elapsed - dt) <= 1e-6 * dt;
  if (!one_period) {
    const double k = elapsed / h;
    if (elapsed > 0.0 && elapsed < dt && std::fabs(k - std::nearbyint(k)) <= 1e-6 * k) {
      Publish(d, in);  // within the period: the next step comes at its end
      return;
    }
    Classify(m, d, in);  // the clock moved otherwise: start over from this state
    TrackAll(in);
    Publish(d, in);
    return;
  }
  in->DifferenceMocap(m, d, elapsed);
  in->Bind(m, d);
  if ((t.pruned && !Prune(m, d, in, in->step + 1)) || dua_step(&in->args, in->step + 1, 0) < 0) {
    // Not finite: the step was undone; classify again at the next state.
    in->classified = false;
    return;
  }
  in->step += 1;
  in->last_time = d->time;
  const dua_events& e = in->args.events;
  if (t.pruned && e.nbody && e.meta[kMCount]) in->pruned.FindEscapes(t.held, in->args, in->step);
  TrackStep(in);
  Publish(d, in);
}

// Adds a decor geom to scn (false when it is full: mjv_updateScene warns of that).
bool AddDecor(mjvScene* scn, mjvGeom** geom) {
  if (scn->ngeom >= scn->maxgeom) return false;
  *geom = scn->geoms + scn->ngeom++;
  return true;
}

// Marks a geom as the overlay's: decor, of no model object (picking ignores it).
void Decor(mjvGeom* geom) {
  geom->category = mjCAT_DECOR;
  geom->objtype = mjOBJ_UNKNOWN;
  geom->objid = -1;
}

// The standing pairs: a translucent red ball (the geom's bounding sphere) on every moving geom of
// a standing pair, and a red line between the centres of two moving geoms standing together
// (a moving geom against a static one, a table or a wall, shows by its ball alone). visualize
// runs before mjv_updateScene adds the model's geoms, so it can add geoms but not tint them.
void Visualize(const mjModel* m, mjData* d, mjvScene* scn, int instance) {
  auto* in = reinterpret_cast<Instance*>(d->plugin_data[instance]);
  if (!in || !in->overlay || !in->classified) return;
  const Universe& u = in->U();
  const float line[4] = {0.95f, 0.15f, 0.1f, 0.9f};
  const float ball[4] = {0.95f, 0.15f, 0.1f, 0.3f};
  auto moving = [m](int64_t g) { return m->body_weldid[m->geom_bodyid[g]] != 0; };
  std::vector<uint8_t> hot(m->ngeom, 0);
  mjvGeom* geom = nullptr;
  for (int64_t k = 0; k < u.ngp(); ++k) {
    if (!in->gp_count[k]) continue;
    const int64_t g1 = u.geom_pairs[2 * k], g2 = u.geom_pairs[2 * k + 1];
    hot[g1] = hot[g2] = 1;
    if (moving(g1) && moving(g2)) {
      if (!AddDecor(scn, &geom)) return;
      mjv_initGeom(geom, mjGEOM_NONE, nullptr, nullptr, nullptr, line);
      mjv_connector(geom, mjGEOM_LINE, 3.0, d->geom_xpos + 3 * g1, d->geom_xpos + 3 * g2);
      Decor(geom);
    }
  }
  for (int g = 0; g < m->ngeom; ++g) {
    if (!hot[g] || !moving(g) || !(m->geom_rbound[g] > 0)) continue;
    if (!AddDecor(scn, &geom)) return;
    const mjtNum size[3] = {m->geom_rbound[g], 0, 0};
    mjv_initGeom(geom, mjGEOM_SPHERE, size, d->geom_xpos + 3 * g, nullptr, ball);
    Decor(geom);
  }
}

void Register() {
  mjpPlugin plugin;
  mjp_defaultPlugin(&plugin);
  plugin.name = kPluginName;
  // Passive: only to spare the mj_subtreeVel nothing reads (SubtreeVelUnused); no forces.
  plugin.capabilityflags |= mjPLUGIN_SENSOR | mjPLUGIN_PASSIVE;
  plugin.nattribute = kNAttribute;
  plugin.attributes = kAttributes;
  // The state lives in plugin_data (copied by `copy`); nothing in plugin_state.
  plugin.nstate = +[](const mjModel*, int) { return 0; };
  plugin.nsensordata = +[](const mjModel*, int, int) { return static_cast<int>(kNOutput); };
  // cvel and subtree_com are ready at the velocity stage.
  plugin.needstage = mjSTAGE_VEL;
  plugin.init = +[](const mjModel* m, mjData* d, int instance) {
    Instance* in = Create(m, instance);
    if (!in) return -1;
    d->plugin_data[instance] = reinterpret_cast<uintptr_t>(in);
    return 0;
  };
  plugin.destroy = +[](mjData* d, int instance) {
    delete reinterpret_cast<Instance*>(d->plugin_data[instance]);
    d->plugin_data[instance] = 0;
  };
  plugin.copy = +[](mjData* dest, const mjModel* m, const mjData* src, int instance) {
    const auto* from = reinterpret_cast<const Instance*>(src->plugin_data[instance]);
    auto* to = reinterpret_cast<Instance*>(dest->plugin_data[instance]);
    if (!from || from == to) return;
    if (!to) {
      to = new Instance;
      dest->plugin_data[instance] = reinterpret_cast<uintptr_t>(to);
    }
    *to = *from;  // the state deep-copied, the tables shared
    to->Bind(m, dest);
  };
  plugin.reset = +[](const mjModel*, mjtNum*, void* plugin_data, int) {
    auto* in = reinterpret_cast<Instance*>(plugin_data);
    if (in) in->classified = false;
  };
  plugin.compute = +[](const mjModel* m, mjData* d, int instance, int capability) {
    const auto* in = reinterpret_cast<const Instance*>(d->plugin_data[instance]);
    const bool skip = in && in->skip_subtree_vel;
    if (capability == mjPLUGIN_PASSIVE) {
      if (skip) d->flg_subtreevel = 1;
      return;
    }
    // Past the last instance's check the flag goes back to what MuJoCo computed: code that
    // reads it after the step ("computed yet?") must not take the stale values for fresh ones.
    if (skip && instance == m->nplugin - 1) d->flg_subtreevel = 0;
    Compute(m, d, instance);
  };
  plugin.visualize = +[](const mjModel* m, mjData* d, const mjvOption*, mjvScene* scn,
                         int instance) { Visualize(m, d, scn, instance); };
  mjp_registerPlugin(&plugin);
}

// Instance `instance` of d if it is one of this plugin's, else null.
Instance* Find(const mjModel* m, const mjData* d, int instance) {
  if (instance < 0 || instance >= m->nplugin || instance >= d->nplugin) return nullptr;
  const mjpPlugin* plugin = mjp_getPluginAtSlot(m->plugin[instance]);
  if (!plugin || std::string(plugin->name) != kPluginName) return nullptr;
  return reinterpret_cast<Instance*>(d->plugin_data[instance]);
}

// Switches the model's sphere pairs `pairs` on or off (Predictor._switch): the held ones in the
// schedule, all of them for when a rebuild holds them (pruned pairs); renews the outputs.
void Switch(const mjModel* m, mjData* d, Instance* in, const std::vector<int64_t>& pairs, bool on) {
  in->Bind(m, d);
  std::vector<int64_t> held;
  for (const int64_t p : pairs) {
    in->on[p] = on ? 1 : 0;
    const auto it = std::lower_bound(in->ids.begin(), in->ids.end(), p);
    if (it != in->ids.end() && *it == p) held.push_back(it - in->ids.begin());
  }
  const auto n = static_cast<int64_t>(held.size());
  dua_switch(&in->args.schedule, held.data(), n, on ? 1 : 0, in->step + 1);
  Track(in, held.data(), n);
  Publish(d, in);
}

}  // namespace
}  // namespace dua

mjPLUGIN_LIB_INIT(dua_mujoco) { dua::Register(); }

extern "C" {

// Geom pairs standing in alarm in plugin instance `instance` of d: up to `capacity` rows
// (g1, g2) into out; returns how many there are (-1: no such instance of this plugin).
DUA_API int64_t dua_plugin_standing(const mjModel* m, const mjData* d, int instance, int64_t* out,
                                    int64_t capacity) {
  const dua::Instance* in = dua::Find(m, d, instance);
  if (!in) return -1;
  if (!in->classified) return 0;
  const dua::Universe& u = in->U();
  int64_t n = 0;
  for (const int64_t k : u.gp_ids) {  // in increasing (g1, g2)
    if (!in->gp_count[k]) continue;
    if (n < capacity) {
      out[2 * n] = u.geom_pairs[2 * k];
      out[2 * n + 1] = u.geom_pairs[2 * k + 1];
    }
    ++n;
  }
  return n;
}

// Switches the pairs between bodies body_a and body_b (body_b < 0: every pair of body_a) off
// (on = 0: intended contact, a grasp) or back on, in plugin instance `instance` of d, as
// Predictor.set_active_bodies does (pruned pairs: those not met yet learnt first, so that they
// stay off when met); a pair switched back on stands in alarm until the next step evaluates
// it. Returns the number of sphere pairs between the bodies, -1 if the instance is not this
// plugin's, -2 before the first compute (nothing to switch yet).
DUA_API int64_t dua_plugin_set_active(const mjModel* m, mjData* d, int instance, int body_a,
                                      int body_b, int on) {
  dua::Instance* in = dua::Find(m, d, instance);
  if (!in) return -1;
  if (!in->classified) return -2;
  if (in->tables->pruned) {  // PairUniverse.between
    std::vector<int64_t> g1, g2;
    for (int a = 0; a < m->ngeom; ++a) {
      if (m->geom_bodyid[a] != body_a) continue;
      for (int b = 0; b < m->ngeom; ++b) {
        if (body_b < 0 || m->geom_bodyid[b] == body_b) g1.push_back(a), g2.push_back(b);
      }
    }
    in->own.Learn(in->tables->learn, g1.data(), g2.data(), static_cast<int64_t>(g1.size()));
    in->Grow();
  }
  const dua::Universe& u = in->U();
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
  dua::Switch(m, d, in, ids, on != 0);
  return static_cast<int64_t>(ids.size());
}

// Switches off the pairs of every geom pair in contact in d (resting contact), as
// Predictor.deactivate_contacts does (pruned pairs: a contact of a pair not met yet learns it);
// they stay off until switched back on (dua_plugin_set_active). Returns the number of geom pairs
// switched off, -1 if the instance is not this plugin's, -2 before its first compute.
DUA_API int64_t dua_plugin_deactivate_contacts(const mjModel* m, mjData* d, int instance) {
  dua::Instance* in = dua::Find(m, d, instance);
  if (!in) return -1;
  if (!in->classified) return -2;
  std::vector<int64_t> g1, g2;
  for (int c = 0; c < d->ncon; ++c) {
    const int a = d->contact[c].geom[0], b = d->contact[c].geom[1];
    if (a < 0 || b < 0) continue;  // a flex
    g1.push_back(std::min(a, b)), g2.push_back(std::max(a, b));
  }
  if (in->tables->pruned) {
    in->own.Learn(in->tables->learn, g1.data(), g2.data(), static_cast<int64_t>(g1.size()));
    in->Grow();
  }
  const dua::Universe& u = in->U();
  std::vector<uint8_t> off(u.ngp(), 0);
  int64_t noff = 0;
  for (size_t c = 0; c < g1.size(); ++c) {
    const int64_t gp = u.GeomPair(g1[c], g2[c]);
    if (gp >= 0 && !off[gp]) {
      off[gp] = 1;
      ++noff;
    }
  }
  std::vector<int64_t> ids;
  for (int64_t p = 0; p < u.npair(); ++p) {
    if (off[u.pair_geom[p]]) ids.push_back(p);
  }
  dua::Switch(m, d, in, ids, false);
  return noff;
}

}  // extern "C"
