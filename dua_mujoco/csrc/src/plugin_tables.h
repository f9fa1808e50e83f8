// The plugin's tables: what dua_mujoco.attach writes into the model as text fields
// "<prefix>:<table>" (dua_mujoco/plugin.py documents each), parsed once per model instance and
// shared by every mjData made from it.
#ifndef DUA_MUJOCO_PLUGIN_TABLES_H_
#define DUA_MUJOCO_PLUGIN_TABLES_H_

#include <mujoco/mujoco.h>

#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "layout.h"
#include "pruned.h"
#include "universe.h"

namespace dua {

// Entries of "<prefix>:config".
enum Config {
  kCfgAbi = 0,
  kCfgKind = 1,
  kCfgDt = 2,
  kCfgLatency = 3,
  kCfgTimestep = 4,
  kCfgRows = 5,
  kCfgNslots = 6,
  kCfgNqueue = 7,
  kCfgExactOn = 8,
  kCfgExactBelow = 9,
  kCfgQueryBelow = 10,
  kCfgParams = 11,  // the schedule's kNParams params
  kCfgNgeom = 20,   // the model the tables were made for: geoms, bodies,
  kCfgNbody = 21,
  kCfgShape = 22,  // and FNV-1a of its geom_type, geom_bodyid and body_parentid (two 32-bit halves)
  kCfgWidth = 24,  // the schedule's work width (the most pairs a step selects)
  kCfgPruned = 25,        // 1: pruned pairs (the deadline schedule over the held ones)
  kCfgHorizon = 26,       // pruned: the reach's horizon T, seconds
  kCfgMargin = 27,        // pruned: the largest contact distance beyond the radii
  kCfgStride = 28,        // pruned: steps between rebuilds
  kCfgRenewMax = 29,      // pruned: most escaped spheres renewed alone
  kCfgContacts = 30,      // pruned: contacts are on (pairs can be learnt)
  kCfgFilterParent = 31,  // pruned: MuJoCo's parent filter is on
  kCfgOverride = 32,      // pruned: mjENBL_OVERRIDE (the margin is o_margin)
  kCfgOMargin = 33,       // pruned: o_margin
  kCfgHasSpeed = 34,      // pruned: speed bounds are declared
  kCfgSize = 35,
};

// The model's tables, parsed once per mjData and shared by its copies.
struct Tables {
  std::vector<double> config, spheres, shapes, horizon, events_rec, events_params;
  std::vector<double> geoms, verts;
  std::vector<int64_t> events_start, events_members;
  std::vector<int32_t> graph;
  int64_t nbody_events = 0;
  bool exact = false;
  // The pairs known from the start: every active pair, or (pruned) those held always, which
  // each mjData's own universe then grows from.
  Universe universe;
  // Pruned pairs: the reaches, what learning a pair reads, each geom's row in the violation
  // check.
  bool pruned = false;
  PrunedTables held;
  LearnTables learn;
  std::vector<int64_t> geom_row;
  double Config(int i) const { return config[i]; }
  int64_t nsphere() const { return static_cast<int64_t>(spheres.size()) / kSphereNcol; }
};

// The tables under `prefix`, checked against the model; null after a warning naming what is
// missing, malformed, of another version or made for another model.
std::shared_ptr<const Tables> LoadTables(const mjModel* m, const std::string& prefix);

}  // namespace dua

#endif  // DUA_MUJOCO_PLUGIN_TABLES_H_
