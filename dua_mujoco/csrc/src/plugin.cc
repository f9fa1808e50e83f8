// The MuJoCo sensor plugin "dua_mujoco.predictor": the predictor's step inside mj_step.
//
// The tables travel in the model as custom text fields "<prefix>:<table>", written by
// dua_mujoco.attach; tables.cc reads and checks them, once per model (every mjData of it
// shares them). The predictor itself is a Runtime (runtime.h), one per mjData, in plugin_data:
// init makes it, copy duplicates it, reset starts it over, destroy frees it. This file is the
// glue: registration, the attributes, when to classify or step, the sensor outputs, the overlay.
//
// Timing. compute runs at the velocity stage of each mj_forward (and so of each mj_step), on the
// kinematics of the state the step starts from: the instant the Python predictor reads after
// that mj_step (docs/discrete-time.md). The first compute after init or mj_resetData classifies
// every pair; later ones step when the clock has advanced by one predictor period, do nothing
// when it has not moved (an mj_forward between steps), only check a flight plan when it has
// moved by whole physics steps within the period, and classify again when it moved any other way
// (time set back, a jump) or when the last step met a state that is not finite.
#include <mujoco/mjplugin.h>
#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "dua/dua.h"
#include "runtime.h"
#include "tables.h"

namespace dua {
namespace {

constexpr char kPluginName[] = "dua_mujoco.predictor";
constexpr const char* kAttributes[] = {"prefix", "overlay", "forget"};
constexpr int kNAttribute = sizeof(kAttributes) / sizeof(kAttributes[0]);

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
  Instance(std::shared_ptr<const Tables> t, const mjModel* m) : rt(std::move(t), m) {
    rt.SetReadLag(0);  // the compute reads the state of d->time (mj_step has not advanced it)
  }
  Runtime rt;
  std::string prefix;  // of the tables' text fields (the plugin attribute)
  int sensor_adr = -1;
  bool overlay = true;
  bool skip_subtree_vel = false;  // see SubtreeVelUnused
};

Instance* InstanceOf(const mjData* d, int instance) {
  return reinterpret_cast<Instance*>(d->plugin_data[instance]);
}

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

// Reads the instance's attributes and tables; null after a warning naming what is wrong.
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
          "dua_mujoco.predictor: plugin attribute 'overlay' = '%s' does not parse: use true or "
          "false.",
          v.c_str());
      return nullptr;
    }
  }
  int64_t forget = kForgetDefault;
  const char* forget_attr = mj_getPluginConfig(m, instance, "forget");
  if (forget_attr && *forget_attr) {
    const std::string v = forget_attr;
    char* end = nullptr;
    const long long k = std::strtoll(v.c_str(), &end, 10);
    if (v == "never") {
      forget = -1;
    } else if (*end || k < 0) {
      mju_warning(
          "dua_mujoco.predictor: plugin attribute 'forget' = '%s' does not parse: use a whole "
          "number of rebuilds >= 0, or never.",
          v.c_str());
      return nullptr;
    } else {
      forget = k;
    }
  }
  std::string error;
  std::shared_ptr<const Tables> tables = LoadTables(m, prefix, &error);
  if (!tables) {
    mju_warning("dua_mujoco.predictor: %s.", error.c_str());
    return nullptr;
  }
  auto* in = new Instance(std::move(tables), m);
  in->prefix = prefix;
  in->overlay = overlay;
  in->rt.SetForget(forget);
  in->skip_subtree_vel = SubtreeVelUnused(m);
  for (int i = 0; i < m->nsensor; ++i) {
    if (m->sensor_type[i] == mjSENS_PLUGIN && m->sensor_plugin[i] == instance) {
      in->sensor_adr = m->sensor_adr[i];
      break;
    }
  }
  return in;
}

// The sensor outputs (O(1)).
DUA_HOT void Publish(mjData* d, const Instance* in) {
  if (in->sensor_adr < 0) return;
  const Runtime& rt = in->rt;
  mjtNum* out = d->sensordata + in->sensor_adr;
  out[kStanding] = static_cast<mjtNum>(rt.nstanding());
  out[kMinTau] = rt.min_tau();
  out[kEvaluated] = static_cast<mjtNum>(rt.evaluated());
  out[kDeferred] = static_cast<mjtNum>(rt.deferred());
  out[kFlagged] = static_cast<mjtNum>(rt.flagged());
}

DUA_HOT void Compute(const mjModel* m, mjData* d, int instance) {
  Instance* in = InstanceOf(d, instance);
  if (!in) return;
  Runtime& rt = in->rt;
  if (rt.classified()) {
    switch (rt.ClockOf(d->time)) {
      case Runtime::Clock::kSame:  // an mj_forward at the same instant: the outputs stand
        break;
      case Runtime::Clock::kWithinPeriod:
        // Within the period the next step comes at its end; a flight plan is checked at every
        // physics step, so that a body off its plan between two steps has its pairs made due
        // at the next (docs/theory.md, section 8).
        rt.CheckPlan(m, d);
        break;
      case Runtime::Clock::kOnePeriod:
        // Not finite: the step was undone; classify again at the next state.
        if (rt.Step(m, d) < 0) rt.Invalidate();
        break;
      case Runtime::Clock::kOther:  // the clock moved otherwise: start over from this state
        rt.Classify(m, d);
        break;
    }
  } else {
    rt.Classify(m, d);
  }
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
  const Instance* in = InstanceOf(d, instance);
  if (!in || !in->overlay || !in->rt.classified()) return;
  const Universe& u = in->rt.universe();
  const std::vector<int32_t>& standing = in->rt.geom_pair_count();
  const float line[4] = {0.95f, 0.15f, 0.1f, 0.9f};
  const float ball[4] = {0.95f, 0.15f, 0.1f, 0.3f};
  auto moving = [m](int64_t g) { return m->body_weldid[m->geom_bodyid[g]] != 0; };
  std::vector<uint8_t> hot(m->ngeom, 0);
  mjvGeom* geom = nullptr;
  for (int64_t k = 0; k < u.ngp(); ++k) {
    if (!standing[k]) continue;
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
  // Another copy of this library (a second install of the package) registered it already:
  // registering twice is a fatal error in MuJoCo, and one copy serves.
  if (mjp_getPlugin(kPluginName, nullptr)) return;
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
    delete InstanceOf(d, instance);
    d->plugin_data[instance] = 0;
  };
  plugin.copy = +[](mjData* dest, const mjModel* m, const mjData* src, int instance) {
    const Instance* from = InstanceOf(src, instance);
    Instance* to = InstanceOf(dest, instance);
    if (!from || from == to) return;
    delete to;  // the state deep-copied, the tables shared
    to = new Instance(*from);
    dest->plugin_data[instance] = reinterpret_cast<uintptr_t>(to);
    to->rt.Bind(m, dest);
  };
  plugin.reset = +[](const mjModel* m, mjtNum*, void* plugin_data, int) {
    auto* in = reinterpret_cast<Instance*>(plugin_data);
    if (!in) return;
    // A static geom edited in the model since init: the next classification would read stale
    // shape records (O(static geoms) and their height fields' and meshes' data; no step pays it).
    const std::string edited = StaticMismatch(m, in->rt.tables().statics);
    if (!edited.empty()) {
      mju_error("dua_mujoco.predictor: %s.", StaticFieldRefusal(in->prefix, edited).c_str());
    }
    in->rt.Invalidate();
  };
  plugin.compute = +[](const mjModel* m, mjData* d, int instance, int capability) {
    const Instance* in = InstanceOf(d, instance);
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
  return InstanceOf(d, instance);
}

}  // namespace
}  // namespace dua

mjPLUGIN_LIB_INIT(dua_mujoco) { dua::Register(); }

extern "C" {

DUA_API int64_t dua_plugin_standing(const mjModel* m, const mjData* d, int instance, int64_t* out,
                                    int64_t capacity) {
  const dua::Instance* in = dua::Find(m, d, instance);
  if (!in) return -1;
  const dua::Runtime& rt = in->rt;
  if (!rt.classified()) return 0;
  const dua::Universe& u = rt.universe();
  int64_t n = 0;
  for (const int64_t k : u.gp_ids) {  // in increasing (g1, g2)
    if (!rt.geom_pair_count()[k]) continue;
    if (n < capacity) {
      out[2 * n] = u.geom_pairs[2 * k];
      out[2 * n + 1] = u.geom_pairs[2 * k + 1];
    }
    ++n;
  }
  return n;
}

DUA_API int64_t dua_plugin_memory(const mjModel* m, const mjData* d, int instance, int64_t* out,
                                  int64_t capacity) {
  const dua::Instance* in = dua::Find(m, d, instance);
  if (!in) return -1;
  const dua::Runtime& rt = in->rt;
  const dua::Universe& u = rt.universe();
  const int64_t count[5] = {u.npair(), u.ngp(), static_cast<int64_t>(rt.ids().size()),
                            rt.forgotten(), rt.compactions()};
  int64_t n = 0;
  for (const int64_t c : count) {
    if (n < capacity) out[n] = c;
    ++n;
  }
  // Then the known geom pairs, rows (g1, g2) in increasing order.
  for (const int64_t k : u.gp_ids) {
    if (n + 1 < capacity) out[n] = u.geom_pairs[2 * k], out[n + 1] = u.geom_pairs[2 * k + 1];
    n += 2;
  }
  return n;
}

DUA_API int64_t dua_plugin_set_active(const mjModel* m, mjData* d, int instance, int body_a,
                                      int body_b, int on) {
  dua::Instance* in = dua::Find(m, d, instance);
  if (!in) return -1;
  if (!in->rt.classified()) return -2;
  if (body_a < 0 || body_a >= m->nbody || body_b >= m->nbody) return -3;
  const std::vector<int64_t> ids = in->rt.PairsBetweenBodies(m, body_a, body_b);
  in->rt.Switch(ids, on != 0);
  dua::Publish(d, in);
  return static_cast<int64_t>(ids.size());
}

DUA_API int64_t dua_plugin_set_plan(const mjModel* m, mjData* d, int instance,
                                    const dua_plan_input* plan, double* departures, char* error,
                                    int64_t error_size) {
  dua::Instance* in = dua::Find(m, d, instance);
  if (!in) return -1;
  if (!in->rt.classified()) return -2;
  const std::string why = plan == nullptr ? std::string("is null: pass a dua_plan_input")
                                          : in->rt.SetPlan(m, *plan, departures);
  if (why.empty()) return 0;
  if (error != nullptr && error_size > 0) {
    const std::string message = "the plan " + why;
    const size_t len = std::min(message.size(), static_cast<size_t>(error_size - 1));
    std::copy_n(message.data(), len, error);
    error[len] = '\0';
  }
  return -3;
}

DUA_API int64_t dua_plugin_clear_plan(const mjModel* m, mjData* d, int instance) {
  dua::Instance* in = dua::Find(m, d, instance);
  if (!in) return -1;
  in->rt.ClearPlan();
  return 0;
}

DUA_API int64_t dua_plugin_deactivate_contacts(const mjModel* m, mjData* d, int instance) {
  dua::Instance* in = dua::Find(m, d, instance);
  if (!in) return -1;
  if (!in->rt.classified()) return -2;
  const int64_t n = in->rt.DeactivateContacts(d);
  dua::Publish(d, in);
  return n;
}

}  // extern "C"
