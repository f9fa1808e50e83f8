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

#include "pruned.h"

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
  kCfgParams = 11,  // the schedule's 9 params
  kCfgNgeom = 20,   // the model the tables were made for: geoms, bodies,
  kCfgNbody = 21,
  kCfgShape = 22,  // and FNV-1a of its geom_type, geom_bodyid and body_parentid (two 32-bit halves)
  kCfgWidth = 24,  // the schedule's work width (the most pairs a step selects)
  kCfgPruned = 25,    // 1: pruned pairs (the deadline schedule over the held ones)
  kCfgHorizon = 26,   // pruned: the reach's horizon T, seconds
  kCfgMargin = 27,    // pruned: the largest contact distance beyond the radii
  kCfgStride = 28,    // pruned: steps between rebuilds
  kCfgRenewMax = 29,  // pruned: most escaped spheres renewed alone
  kCfgSize = 30,
};

// The model's tables, parsed once per mjData and shared by its copies.
struct Tables {
  std::vector<double> config, pairs, spheres, shapes, horizon, events_rec, events_params;
  std::vector<double> geoms, exact_records, verts;
  std::vector<int64_t> pair_geom, geom_pairs, events_start, events_members;
  std::vector<int32_t> graph;
  std::vector<int64_t> gp_keys;  // (ngp,) g1 << 32 | g2 of each geom pair, increasing
  int64_t npair = 0, ngp = 0, nbody_events = 0;
  bool exact = false;
  // Pruned pairs: the pairs' geoms (the first sphere's first, as PairTables has them) for the
  // violation check's index of the held pairs, and each body's row in it.
  bool pruned = false;
  PrunedTables held;
  std::vector<int64_t> geom1, geom2, geom_row;
  double Config(int i) const { return config[i]; }
  // Index of geom pair (g1 < g2), or -1 if it is none of the tables'.
  int64_t GeomPair(int64_t g1, int64_t g2) const {
    const int64_t key = (g1 << 32) | g2;
    const auto it = std::lower_bound(gp_keys.begin(), gp_keys.end(), key);
    return it != gp_keys.end() && *it == key ? it - gp_keys.begin() : -1;
  }
};

// The tables under `prefix`, checked against the model; null after a warning naming what is
// missing, malformed, of another version or made for another model.
std::shared_ptr<const Tables> LoadTables(const mjModel* m, const std::string& prefix);

}  // namespace dua

#endif  // DUA_MUJOCO_PLUGIN_TABLES_H_
