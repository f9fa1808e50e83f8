// The MuJoCo sensor plugin "dua_mujoco.predictor": the predictor's step inside mj_step.
//
// The tables (covering spheres, held pairs, shapes, bounds, the exact level's records, the
// violation check's boxes, the schedule's parameters) travel in the compiled model as custom
// numeric fields "<prefix>:<table>", written by dua_mujoco.attach (dua_mujoco/plugin.py, which
// documents each). What changes as the simulation runs (the schedule, the exact level's last
// directions, the violation check's last states) lives in plugin_data, one Instance per mjData:
// init allocates it, copy duplicates it, reset clears it, destroy frees it.
//
// Timing. compute runs at the velocity stage of each mj_forward (and so of each mj_step), on the
// kinematics of the state the step starts from: the instant the Python predictor reads after
// that mj_step (docs/discrete-time.md). The first compute after init or mj_resetData classifies
// every pair (the Python predictor's reset); later ones step the schedule when the clock has
// advanced by one predictor period, do nothing when it has not moved (an mj_forward between
// steps), and classify again when it moved any other way (time set back, a jump).
#include <mujoco/mjplugin.h>
#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "dua/dua.h"

namespace dua {
namespace {

constexpr char kPluginName[] = "dua_mujoco.predictor";
constexpr const char* kAttributes[] = {"prefix", "overlay"};
constexpr int kNAttribute = sizeof(kAttributes) / sizeof(kAttributes[0]);
constexpr double kInf = std::numeric_limits<double>::infinity();

// Sensor outputs.
enum Output {
  kStanding = 0,   // geom pairs standing in alarm
  kMinTau = 1,     // least latest tau over the active pairs (seconds, inf if none)
  kEvaluated = 2,  // tau evaluations this step
  kDeferred = 3,   // pairs due this step but left for a later one (a capped schedule)
  kFlagged = 4,    // bodies whose motion broke its bounds this step
  kNOutput = 5,
};

// Entries of "<prefix>:config".
enum Config {
  kCfgAbi = 0,
  kCfgKind,
  kCfgDt,
  kCfgLatency,
  kCfgPeriod,
  kCfgRows,
  kCfgNslots,
  kCfgNqueue,
  kCfgExactOn,
  kCfgExactBelow,
  kCfgQueryBelow,
  kCfgNparams = 11,  // the schedule's 9 params follow
  kCfgParams = 12,
  kCfgSize = kCfgParams + 9,
};

// A table in the model: "<prefix>:<name>", read only.
struct Table {
  const mjtNum* data = nullptr;
  int size = 0;
};

Table FindTable(const mjModel* m, const std::string& prefix, const char* name) {
  const std::string full = prefix + ":" + name;
  const int id = mj_name2id(m, mjOBJ_NUMERIC, full.c_str());
  if (id < 0) return {};
  return {m->numeric_data + m->numeric_adr[id], m->numeric_size[id]};
}

std::vector<int64_t> AsInts(const Table& t) {
  std::vector<int64_t> out(t.size);
  for (int i = 0; i < t.size; ++i) out[i] = static_cast<int64_t>(t.data[i]);
  return out;
}

struct Instance {
  // Model tables (owned by the model, shared by every mjData of it).
  const mjtNum* pairs = nullptr;
  const mjtNum* spheres = nullptr;
  const mjtNum* shapes = nullptr;
  const mjtNum* geoms = nullptr;
  const mjtNum* verts = nullptr;
  const mjtNum* events_rec = nullptr;
  const mjtNum* events_params = nullptr;
  std::vector<int64_t> pair_geom;   // (npair,) geom pair of each sphere pair
  std::vector<int64_t> geom_pairs;  // (ngp, 2)
  std::vector<int64_t> events_start, events_members;
  std::vector<int32_t> graph;
  int64_t npair = 0, ngp = 0, nbody_events = 0;
  int sensor_adr = -1;
  bool overlay = true;
  double period_time = 0.0;  // dt: one predictor period
  const mjtNum* config = nullptr;

  // Per-mjData state.
  std::vector<double> last_tau, horizon, w_tau, scratch, exact_records, events_prev, root_twist;
  std::vector<uint8_t> active;
  std::vector<int64_t> ints, slots, queue, params, work, ids, events_meta, events_flagged;
  std::vector<int64_t> log_pairs;
  std::vector<double> log_tau;
  std::vector<uint8_t> log_new;
  std::vector<uint8_t> standing;  // (ngp,) geom pairs standing in alarm
  bool classified = false;
  double last_time = 0.0;
  int64_t step = 0;
  dua_step_args args{};

  // Point the step's arguments at this instance's buffers (after any copy).
  void Bind(const mjModel* m, const mjData* d) {
    dua_step_args& a = args;
    a.abi = DUA_ABI_VERSION;
    dua_schedule& s = a.schedule;
    s.kind = static_cast<int64_t>(config[kCfgKind]);
    s.dt = config[kCfgDt];
    s.latency = static_cast<int64_t>(config[kCfgLatency]);
    s.m = npair;
    s.last_tau = last_tau.data();
    s.active = active.data();
    s.ints = ints.data();
    s.slots = slots.data();
    s.nslots = static_cast<int64_t>(slots.size());
    s.horizon = horizon.data();
    s.queue = queue.data();
    s.nqueue = static_cast<int64_t>(queue.size());
    s.params = params.data();
    s.work = work.data();
    s.width = static_cast<int64_t>(w_tau.size());
    s.w_tau = w_tau.data();
    a.pairs = pairs;
    a.spheres = spheres;
    a.shapes = shapes;
    a.ids = ids.data();
    a.frame = {d->geom_xpos, d->geom_xmat, d->cvel, d->subtree_com, root_twist.data(), d->xpos};
    dua_exact& x = a.exact;
    x.on = geoms != nullptr && static_cast<int64_t>(config[kCfgExactOn]) != 0;
    x.geoms = geoms;
    x.records = exact_records.data();
    x.below = config[kCfgExactBelow];
    x.query_below = config[kCfgQueryBelow];
    x.verts = verts;
    x.graph = graph.data();
    x.model = m;
    x.data = d;
    dua_events& e = a.events;
    e.nbody = nbody_events;
    e.rec = events_rec;
    e.prev = events_prev.data();
    e.meta = events_meta.data();
    e.flagged = events_flagged.data();
    e.start = events_start.data();
    e.members = events_members.data();
    e.params = events_params;
    a.scratch = scratch.data();
    a.scratch_rows = static_cast<int64_t>(scratch.size() / 12);
    a.log_pairs = log_pairs.data();
    a.log_tau = log_tau.data();
    a.log_new = log_new.data();
  }
};

bool Fail(const std::string& message) {
  mju_warning("%s", message.c_str());
  return false;
}

// Read the model's tables into `in`; false (after a warning naming what is wrong) on failure.
bool Load(const mjModel* m, int instance, Instance* in) {
  const char* prefix_attr = mj_getPluginConfig(m, instance, "prefix");
  const std::string prefix = (prefix_attr && *prefix_attr) ? prefix_attr : "dua";
  const char* overlay = mj_getPluginConfig(m, instance, "overlay");
  if (overlay && *overlay) {
    const std::string v = overlay;
    if (v == "true" || v == "1") {
      in->overlay = true;
    } else if (v == "false" || v == "0") {
      in->overlay = false;
    } else {
      return Fail("dua_mujoco.predictor: attribute 'overlay' = '" + v +
                  "' does not parse: use true or false.");
    }
  }
  const Table config = FindTable(m, prefix, "config");
  if (!config.data) {
    return Fail("dua_mujoco.predictor: the model has no numeric field '" + prefix +
                ":config' (attribute 'prefix' = '" + prefix +
                "'): build the model with dua_mujoco.attach(spec), which writes the tables.");
  }
  if (config.size != kCfgSize || static_cast<int64_t>(config.data[kCfgAbi]) != DUA_ABI_VERSION) {
    return Fail("dua_mujoco.predictor: '" + prefix +
                ":config' was written by another version of dua_mujoco: attach again with "
                "this one.");
  }
  in->config = config.data;
  const Table pairs = FindTable(m, prefix, "pairs");
  const Table spheres = FindTable(m, prefix, "spheres");
  const Table shapes = FindTable(m, prefix, "shapes");
  const Table pair_geom = FindTable(m, prefix, "pair_geom");
  const Table geom_pairs = FindTable(m, prefix, "geom_pairs");
  const Table horizon = FindTable(m, prefix, "horizon");
  const Table events_rec = FindTable(m, prefix, "events_rec");
  const Table events_params = FindTable(m, prefix, "events_params");
  const Table events_start = FindTable(m, prefix, "events_start");
  const Table events_members = FindTable(m, prefix, "events_members");
  const char* missing = !pairs.data              ? "pairs"
                        : !spheres.data          ? "spheres"
                        : !shapes.data           ? "shapes"
                        : !pair_geom.data        ? "pair_geom"
                        : !geom_pairs.data       ? "geom_pairs"
                        : !horizon.data          ? "horizon"
                        : !events_params.data    ? "events_params"
                        : !events_start.data     ? "events_start"
                        : nullptr;
  if (missing) {
    return Fail("dua_mujoco.predictor: the model has no numeric field '" + prefix + ":" + missing +
                "': attach the predictor again with dua_mujoco.attach(spec).");
  }
  in->pairs = pairs.data;
  in->spheres = spheres.data;
  in->shapes = shapes.data;
  in->npair = pairs.size / 8;
  in->pair_geom = AsInts(pair_geom);
  in->geom_pairs = AsInts(geom_pairs);
  in->ngp = geom_pairs.size / 2;
  in->horizon.assign(horizon.data, horizon.data + horizon.size);
  in->events_rec = events_rec.data;
  in->nbody_events = events_rec.data ? events_rec.size / 12 : 0;
  in->events_params = events_params.data;
  in->events_start = AsInts(events_start);
  in->events_members = events_members.data ? AsInts(events_members) : std::vector<int64_t>{};
  in->period_time = in->config[kCfgDt];
  if (static_cast<int64_t>(in->config[kCfgExactOn])) {
    const Table geoms = FindTable(m, prefix, "exact_geoms");
    const Table records = FindTable(m, prefix, "exact_records");
    const Table verts = FindTable(m, prefix, "exact_verts");
    if (!geoms.data || !records.data || !verts.data) {
      return Fail("dua_mujoco.predictor: the exact level is on but the model lacks '" + prefix +
                  ":exact_geoms', ':exact_records' or ':exact_verts': attach again.");
    }
    in->geoms = geoms.data;
    in->verts = verts.data;
    in->exact_records.assign(records.data, records.data + records.size);
    in->graph.assign(m->mesh_graph, m->mesh_graph + m->nmeshgraph);
    if (in->graph.empty()) in->graph.assign(1, -1);
  }
  in->sensor_adr = -1;
  for (int i = 0; i < m->nsensor; ++i) {
    if (m->sensor_type[i] == mjSENS_PLUGIN && m->sensor_plugin[i] == instance) {
      in->sensor_adr = m->sensor_adr[i];
      break;
    }
  }
  const int64_t npair = in->npair;
  const int64_t width = std::max<int64_t>(npair, 1);
  in->last_tau.assign(npair, kInf);
  in->active.assign(npair, 1);
  in->ints.assign(static_cast<size_t>(in->config[kCfgRows]) * npair, 0);
  in->slots.assign(static_cast<size_t>(in->config[kCfgNslots]), -1);
  in->queue.assign(static_cast<size_t>(in->config[kCfgNqueue]) + 1, 0);
  in->params.assign(9, 0);
  in->work.assign(4 * width, 0);
  in->w_tau.assign(width, 0.0);
  in->scratch.assign(12 * width, 0.0);
  in->ids.resize(npair);
  for (int64_t p = 0; p < npair; ++p) in->ids[p] = p;
  in->events_prev.assign(in->nbody_events * 31, 0.0);
  in->events_meta.assign(3, 0);
  in->events_flagged.assign(std::max<int64_t>(in->nbody_events, 1), 0);
  in->root_twist.assign(6 * m->nbody, 0.0);
  in->log_pairs.assign(width, 0);
  in->log_tau.assign(width, 0.0);
  in->log_new.assign(width, 0);
  in->standing.assign(in->ngp, 0);
  return true;
}

// The initial classification at this instant: every pair evaluated and scheduled.
void Classify(const mjModel* m, mjData* d, Instance* in) {
  in->Bind(m, d);
  dua_step_args& a = in->args;
  dua_schedule& s = a.schedule;
  const int64_t npair = in->npair;
  std::fill(in->active.begin(), in->active.end(), 1);
  std::fill(in->slots.begin(), in->slots.end(), -1);
  std::fill(in->queue.begin(), in->queue.end(), 0);
  for (int i = 0; i < 9; ++i) in->params[i] = static_cast<int64_t>(in->config[kCfgParams + i]);
  const int64_t kind = s.kind;
  std::fill(in->ints.begin(), in->ints.end(), kind == 1 ? -1 : 0);
  if (kind == 1) std::fill(in->ints.begin() + npair, in->ints.begin() + 2 * npair, 0);
  dua_reset_events(&a);
  const int64_t bad = dua_evaluate(&a, in->ids.data(), npair, in->last_tau.data());
  if (bad >= 0) {
    // A state that is not finite: nothing can be predicted from it; stand every pair in alarm.
    std::fill(in->last_tau.begin(), in->last_tau.end(), -kInf);
  }
  if (kind == 1) dua_deadline_classify(&s);
  in->classified = true;
  in->step = 0;
  in->last_time = d->time;
}

// Standing geom pairs and the sensor outputs, from the schedule's state (the alarm rule on
// each pair's latest tau: docs/theory.md, section 3).
void Publish(const mjModel* m, mjData* d, Instance* in) {
  dua_step_args& a = in->args;
  const dua_schedule& s = a.schedule;
  std::fill(in->standing.begin(), in->standing.end(), 0);
  double min_tau = kInf;
  const int64_t* where = s.ints;
  const int64_t* last_step = s.ints + s.m;
  for (int64_t p = 0; p < in->npair; ++p) {
    if (!s.active[p]) continue;
    const double tau = s.last_tau[p];
    double horizon = s.horizon[0];
    if (s.kind == 1) {
      horizon = where[p] >= 0 ? static_cast<double>(where[p] - last_step[p] + s.latency) * s.dt
                              : -kInf;
    }
    if (tau < horizon) in->standing[in->pair_geom[p]] = 1;
    min_tau = std::min(min_tau, tau);
  }
  int64_t nstanding = 0;
  for (uint8_t v : in->standing) nstanding += v;
  if (in->sensor_adr >= 0) {
    mjtNum* out = d->sensordata + in->sensor_adr;
    out[kStanding] = static_cast<mjtNum>(nstanding);
    out[kMinTau] = min_tau;
    out[kEvaluated] = static_cast<mjtNum>(a.count);
    out[kDeferred] = static_cast<mjtNum>(a.deferred);
    out[kFlagged] = static_cast<mjtNum>(a.events.meta[1]);
  }
  (void)m;
}

void Compute(const mjModel* m, mjData* d, int instance) {
  auto* in = reinterpret_cast<Instance*>(d->plugin_data[instance]);
  if (!in) return;
  const double dt = in->period_time;
  if (!in->classified) {
    in->args.count = 0;
    in->args.deferred = 0;
    Classify(m, d, in);
    Publish(m, d, in);
    return;
  }
  const double elapsed = d->time - in->last_time;
  if (std::fabs(elapsed) <= 1e-6 * dt) return;  // an mj_forward at the same instant
  const double per_physics = m->opt.timestep;
  if (elapsed > 0.0 && elapsed < dt - 1e-6 * dt) {
    // Within a predictor period (period > 1): the next step comes when the period is over,
    // if the clock advanced by whole physics steps.
    const double k = elapsed / per_physics;
    if (std::fabs(k - std::nearbyint(k)) <= 1e-6 * std::max(k, 1.0)) return;
  }
  if (std::fabs(elapsed - dt) > 1e-6 * dt) {
    in->args.count = 0;
    in->args.deferred = 0;
    Classify(m, d, in);
    Publish(m, d, in);
    return;
  }
  in->Bind(m, d);
  in->step += 1;
  dua_step(&in->args, in->step, 0);
  if (in->args.bad >= 0) {
    // Not finite: the step was undone; classify again at the next finite state.
    in->classified = false;
    return;
  }
  in->last_time = d->time;
  Publish(m, d, in);
}

void Visualize(mjData* d, mjvScene* scn, int instance) {
  auto* in = reinterpret_cast<Instance*>(d->plugin_data[instance]);
  if (!in || !in->overlay || !in->classified) return;
  const float red[4] = {0.95f, 0.15f, 0.1f, 0.9f};
  for (int64_t k = 0; k < in->ngp; ++k) {
    if (!in->standing[k]) continue;
    if (scn->ngeom >= scn->maxgeom) return;  // mjv_updateScene warns of a full scene
    const int64_t g1 = in->geom_pairs[2 * k], g2 = in->geom_pairs[2 * k + 1];
    const mjtNum* a = d->geom_xpos + 3 * g1;
    const mjtNum* b = d->geom_xpos + 3 * g2;
    mjvGeom* geom = scn->geoms + scn->ngeom;
    mjv_initGeom(geom, mjGEOM_NONE, nullptr, nullptr, nullptr, red);
    mjv_connector(geom, mjGEOM_LINE, 3.0, a, b);
    geom->category = mjCAT_DECOR;
    geom->objtype = mjOBJ_UNKNOWN;
    geom->objid = -1;
    scn->ngeom++;
  }
}

void Register() {
  mjpPlugin plugin;
  mjp_defaultPlugin(&plugin);
  plugin.name = kPluginName;
  plugin.capabilityflags |= mjPLUGIN_SENSOR;
  plugin.nattribute = kNAttribute;
  plugin.attributes = kAttributes;
  // The state lives in plugin_data (copy below); nothing in plugin_state.
  plugin.nstate = +[](const mjModel*, int) { return 0; };
  plugin.nsensordata = +[](const mjModel*, int, int) { return static_cast<int>(kNOutput); };
  // cvel and subtree_com are ready at the velocity stage.
  plugin.needstage = mjSTAGE_VEL;
  plugin.init = +[](const mjModel* m, mjData* d, int instance) {
    auto* in = new Instance;
    if (!Load(m, instance, in)) {
      delete in;
      return -1;
    }
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
    *to = *from;  // every buffer deep-copied; Bind re-points the step at dest's
    to->Bind(m, dest);
  };
  plugin.reset = +[](const mjModel*, mjtNum*, void* plugin_data, int) {
    auto* in = reinterpret_cast<Instance*>(plugin_data);
    if (in) in->classified = false;
  };
  plugin.compute = +[](const mjModel* m, mjData* d, int instance, int) {
    Compute(m, d, instance);
  };
  plugin.visualize = +[](const mjModel*, mjData* d, const mjvOption*, mjvScene* scn,
                         int instance) { Visualize(d, scn, instance); };
  mjp_registerPlugin(&plugin);
}

}  // namespace
}  // namespace dua

mjPLUGIN_LIB_INIT(dua_mujoco) { dua::Register(); }

extern "C" {

// Geom pairs standing in alarm in plugin instance `instance` of d: up to `capacity` (g1, g2)
// rows into out; returns how many there are (-1: no instance).
DUA_API int64_t dua_plugin_standing(const mjData* d, int instance, int64_t* out,
                                    int64_t capacity) {
  if (instance < 0 || instance >= d->nplugin) return -1;
  const auto* in = reinterpret_cast<const dua::Instance*>(d->plugin_data[instance]);
  if (!in) return -1;
  if (!in->classified) return 0;
  int64_t n = 0;
  for (int64_t k = 0; k < in->ngp; ++k) {
    if (!in->standing[k]) continue;
    if (n < capacity) {
      out[2 * n] = in->geom_pairs[2 * k];
      out[2 * n + 1] = in->geom_pairs[2 * k + 1];
    }
    ++n;
  }
  return n;
}

}  // extern "C"
