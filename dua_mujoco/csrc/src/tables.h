// The predictor's tables: everything a model's predictor reads that does not change as it runs
// (the covering spheres, the pairs and their bounds, the static shapes, the exact level's
// records, the violation check's boxes, the schedule's options, the pruned pairs' reaches and
// what learning a pair reads). Python builds them (dua_mujoco/runtime/table_arrays.py); the plugin
// reads them from the model's text fields "<prefix>:<table>", the Python predictor hands them over
// as arrays. Either way they are checked here, once per model, against the model they are for:
// every index the step follows points inside its table, or the tables are refused with an error
// that names the table.
#ifndef DUA_MUJOCO_TABLES_H_
#define DUA_MUJOCO_TABLES_H_

#include <mujoco/mujoco.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "dua/dua.h"
#include "layout.h"
#include "pruned.h"
#include "schedule.h"
#include "universe.h"

namespace dua {

// Version of the tables' format: a model's tables written by another version are refused.
// 6: the "static" table (the static guard, StaticRecords). 7: the deadline schedule's screen
// (kCfgScreen).
constexpr int64_t kTablesVersion = 7;

// Entries of the "config" table.
enum Config {
  kCfgVersion = 0,
  kCfgKind = 1,  // the schedule (ScheduleSpec)
  kCfgDt = 2,
  kCfgLatency = 3,
  kCfgSlotsPerBucket = 4,
  kCfgCap = 5,
  kCfgMaxInterval = 6,
  kCfgBackoff = 7,
  kCfgThreshold = 8,
  kCfgTimestep = 9,  // the model's timestep
  kCfgExactOn = 10,  // the exact level
  kCfgExactBelow = 11,
  kCfgQueryBelow = 12,
  kCfgNgeom = 13,  // the model the tables were made for: geoms, bodies,
  kCfgNbody = 14,
  kCfgShape = 15,         // and FNV-1a of its structure (two 32-bit halves)
  kCfgPruned = 17,        // 1: pruned pairs (the deadline schedule over the held ones)
  kCfgHorizon = 18,       // pruned: the reach's horizon T, seconds
  kCfgMargin = 19,        // pruned: the largest contact distance beyond the radii
  kCfgStride = 20,        // pruned: steps between rebuilds
  kCfgRenewMax = 21,      // pruned: most escaped spheres renewed alone
  kCfgContacts = 22,      // pruned: contacts are on (pairs can be learnt)
  kCfgFilterParent = 23,  // pruned: MuJoCo's parent filter is on
  kCfgOverride = 24,      // pruned: mjENBL_OVERRIDE (the margin is o_margin)
  kCfgOMargin = 25,       // pruned: o_margin
  kCfgHasSpeed = 26,      // pruned: speed bounds are declared
  kCfgAlarmHorizon = 27,  // the alarm horizon, seconds (at least dt, one period)
  kCfgScreen = 28,        // 1: the deadline schedule screens its far pairs (ScheduleSpec::screen)
  kCfgSize = 29,
};

struct Tables {
  ScheduleSpec schedule;
  double timestep = 0.0;
  std::vector<double> spheres, shapes, events_rec, events_params;
  // The static guard: one StaticRecords row per static shape (in the shapes' order), what the
  // shape records were built from; StaticMismatch holds a model to it.
  std::vector<double> statics;
  int64_t nbody_events = 0;
  // The exact level: its per-geom records, thresholds, and each hull vertex's climb row
  // (dua_exact's hull_at, climb and climb_at: dua.h).
  bool exact = false;
  double exact_below = 0.0, query_below = 0.0;
  std::vector<double> geoms;
  std::vector<int64_t> hull_at;
  std::vector<dua_hull_entry> climb;
  std::vector<int64_t> climb_at;
  // The pairs known from the start: every active pair, or (pruned) those held always, which
  // each run's own universe then grows from.
  Universe universe;
  // Pruned pairs: the reaches, what learning a pair reads, each geom's row in the violation
  // check.
  bool pruned = false;
  int64_t renew_max = 0;
  PrunedTables held;
  LearnTables learn;
  std::vector<int64_t> geom_row;
  // Free spheres (FreeTables): no model, the caller's centres and velocities at each step.
  bool free = false;

  int64_t nsphere() const { return static_cast<int64_t>(spheres.size()) / kSphereNcol; }
};

// Where the tables come from: get(name, out) fills out with the table's entries (row-major
// float64) and returns true, or returns false after setting *error (the table is missing or
// does not decode).
using TableSource =
    std::function<bool(const std::string& name, std::vector<double>* out, std::string* error)>;

// The tables from `source`, checked against m; null after *error says which table is wrong and
// why, naming table t as before + t + after (e.g. "text field '" + t + "'").
DUA_API std::shared_ptr<const Tables> BuildTables(const mjModel* m, const TableSource& source,
                                                  const std::string& before,
                                                  const std::string& after, std::string* error);

// The tables of free spheres (the paper's setting), from "config" (the schedule; pruned: the
// horizon, stride and renewal limit; the margin: every pair's contact distance beyond the radii;
// whether speed bounds are declared) and "reach" (nsphere rows: radius, accel, delta, speed): each
// sphere the one point of its own geom and body, no model (the runtime reads the caller's states).
// Null after *error names the table as BuildTables does.
DUA_API std::shared_ptr<const Tables> FreeTables(const TableSource& source,
                                                 const std::string& before,
                                                 const std::string& after, std::string* error);

// The tables under `prefix` in m's text fields, each its entry count, a space, then its
// little-endian float64 bytes in base64; parsed once per model content (every mjData made from
// the same model shares them), their static table held to the model at every call (an edit of
// a static geom in place refuses them, named as the text field).
DUA_API std::shared_ptr<const Tables> LoadTables(const mjModel* m, const std::string& prefix,
                                                 std::string* error);

// Decodes one text field: its entry count, a space, then the entries' little-endian float64
// bytes in base64. False after *why says what is wrong (the fuzzer, fuzz/, calls it directly).
DUA_API bool Decode(const char* text, std::vector<double>* out, std::string* why);

// FNV-1a (64 bits) of m's structure: geom_type, geom_bodyid and body_parentid as little-endian
// int32s (dua_mujoco/runtime/table_arrays.py computes the same).
DUA_API uint64_t StructureHash(const mjModel* m);

// The static guard's records (layout.h, kStatic*) of static geoms `geoms` (their bodies still:
// StillBody, or the world) of m: each geom's pose by mj_kinematics' arithmetic (KnotKinematics,
// read only), its geom_size and the digest of its height field or mesh. The shape records and
// their covering are built once, from these; tables that hold them are refused by
// StaticMismatch once a static geom was edited in the model (docs/static-shapes.md).
DUA_API std::vector<double> StaticRecords(const mjModel* m, const std::vector<int64_t>& geoms);

// The first static geom of `statics` (StaticRecords rows, of the model the tables were built
// from) that m no longer places, sizes or shapes as recorded, named with the field and its
// recorded and present values, and how many differ ("static geom 3 ('wall') moved: position was
// [...], is [...] (1 of 4 static geoms edited)"); empty when none differs. O(static geoms, plus
// their height fields' and meshes' data).
DUA_API std::string StaticMismatch(const mjModel* m, const std::vector<double>& statics);

// Why the static table is refused once StaticMismatch found `mismatch` (non-empty), with the fix;
// the refusal names the table before it, as BuildTables names tables ("table 'static' ", or
// "text field 'dua:static' ").
DUA_API std::string StaticRefusal(const std::string& mismatch);
// The same, of the static table in the model's text fields under prefix (LoadTables' tables,
// held to the model again at the plugin's reset): "text field '<prefix>:static' ...".
DUA_API std::string StaticFieldRefusal(const std::string& prefix, const std::string& mismatch);

}  // namespace dua

#endif  // DUA_MUJOCO_TABLES_H_
