// Building and checking the predictor's tables (tables.h). Every table a step reads by index is
// checked here against the model, so that no input, however malformed, makes the step read or
// write out of bounds: a fuzzed model must fail at load with an error naming the table.
#include "tables.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <mutex>
#include <numeric>
#include <utility>
#include <vector>

#include "dua/dua.h"
#include "internal.h"
#include "kinematics.h"

namespace dua {
namespace {

// Integers travel as float64: beyond 2^53 they are not exact.
constexpr double kMaxInt = 9007199254740992.0;

// A table's entries as integers in [lo, hi); false if one is not (NaN, a fraction, out of range).
bool AsInts(const std::vector<double>& v, double lo, double hi, std::vector<int64_t>* out) {
  out->resize(v.size());
  for (size_t i = 0; i < v.size(); ++i) {
    const double x = v[i];
    if (!(x >= lo && x < hi) || x != std::floor(x)) return false;
    (*out)[i] = static_cast<int64_t>(x);
  }
  return true;
}

bool IsIndex(double x, int64_t n) {
  return x >= 0.0 && x < static_cast<double>(n) && x == std::floor(x);
}
bool Finite(double x) { return std::isfinite(x); }
bool Bound(double x) { return std::isfinite(x) && x >= 0.0; }  // a finite bound >= 0
bool SpeedBound(double x) { return x >= 0.0; }                 // >= 0, inf: none (NaN fails)

// Reads tables by name from `source`, their errors saying where they come from.
class Reader {
 public:
  // Errors name table t as before + t + after.
  Reader(const TableSource& source, std::string before, std::string after, std::string* error)
      : source_(source), before_(std::move(before)), after_(std::move(after)), error_(error) {}

  // Table `name` with rows x ncol entries (rows < 0: any multiple of ncol).
  bool Get(const std::string& name, int64_t rows, int64_t ncol, std::vector<double>* out) {
    std::string why;
    if (!source_(name, out, &why)) return Fail(name, why);
    const auto n = static_cast<int64_t>(out->size());
    if (rows >= 0 && n != rows * ncol) {
      return Fail(name, "holds " + std::to_string(n) + " entries, not " +
                            std::to_string(rows * ncol) + " (" + std::to_string(rows) +
                            " rows of " + std::to_string(ncol) + ")");
    }
    if (rows < 0 && n % ncol != 0) {
      return Fail(name,
                  "holds " + std::to_string(n) + " entries, not rows of " + std::to_string(ncol));
    }
    return true;
  }

  // Refuse table `name` for `why`.
  bool Fail(const std::string& name, const std::string& why) {
    *error_ = before_ + name + after_ + " " + why;
    return false;
  }

 private:
  const TableSource& source_;
  std::string before_, after_;
  std::string* error_;
};

// Row r of a table with ncol columns fails `ok`: the table is refused naming the row.
template <class Ok>
bool Rows(Reader* r, const std::string& name, const std::vector<double>& t, int64_t ncol,
          const char* what, Ok ok) {
  const int64_t rows = static_cast<int64_t>(t.size()) / ncol;
  for (int64_t i = 0; i < rows; ++i) {
    if (!ok(t.data() + ncol * i)) {
      return r->Fail(name, "row " + std::to_string(i) + ": " + what);
    }
  }
  return true;
}

// A sphere record (pack_spheres; the exact level's geom records start with one): frame geom,
// its body, that body's root, a finite offset.
bool SphereRecordOk(const mjModel* m, const double* rec) {
  if (!IsIndex(rec[kSphereFrame], m->ngeom)) return false;
  const auto g = static_cast<int>(rec[kSphereFrame]);
  const int b = m->geom_bodyid[g];
  return rec[kSphereBody] == b && rec[kSphereRoot] == m->body_rootid[b] &&
         Finite(rec[kSphereOffset]) && Finite(rec[kSphereOffset + 1]) &&
         Finite(rec[kSphereOffset + 2]);
}

// The config's version, size and schedule options (every predictor's, on a model or not).
bool ReadSchedule(Reader* r, std::vector<double>* c, Tables* t) {
  if (!r->Get("config", -1, 1, c)) return false;
  if (c->empty() || (*c)[kCfgVersion] != static_cast<double>(kTablesVersion)) {
    return r->Fail("config",
                   "was written by another version of dua_mujoco (tables format " +
                       (c->empty() ? std::string("none") : Shown((*c)[kCfgVersion])) +
                       ", this one reads " + std::to_string(kTablesVersion) +
                       "): attach the predictor again with this version (dua_mujoco.attach on "
                       "the spec, or re-export the model: dua-mujoco export)");
  }
  if (static_cast<int64_t>(c->size()) != kCfgSize) {
    return r->Fail("config", "holds " + std::to_string(c->size()) + " entries, not " +
                                 std::to_string(kCfgSize));
  }
  const std::vector<double>& v = *c;
  auto integer = [&](int i, double lo, double hi, int64_t* out) {
    if (!(v[i] >= lo && v[i] <= hi) || v[i] != std::floor(v[i])) return false;
    *out = static_cast<int64_t>(v[i]);
    return true;
  };
  ScheduleSpec& s = t->schedule;
  s.dt = v[kCfgDt];
  s.threshold = v[kCfgThreshold];
  s.alarm_horizon = v[kCfgAlarmHorizon];
  if (!integer(kCfgKind, 0, 2, &s.kind) || !integer(kCfgLatency, 0, 1 << 30, &s.latency) ||
      !integer(kCfgSlotsPerBucket, 1, 1 << 30, &s.slots_per_bucket) ||
      !integer(kCfgCap, 0, kMaxInt, &s.cap) ||
      !integer(kCfgMaxInterval, 1, 1 << 30, &s.max_interval) ||
      !integer(kCfgBackoff, 1, kMaxInt, &s.backoff) || !integer(kCfgScreen, 0, 1, &s.screen)) {
    return r->Fail("config", "holds a schedule option that is not a valid integer");
  }
  const std::string bad = s.Check();
  if (!bad.empty()) return r->Fail("config", "holds an invalid schedule option: " + bad);
  // Every MjData allocates the deadline wheel, a power of two > max_interval slots of 8 bytes:
  // 8 MB at most (attach writes 1024).
  if (s.max_interval > (1 << 19)) {
    return r->Fail("config", "holds max_interval = " + std::to_string(s.max_interval) +
                                 ", over 2^19 steps (its wheel would take 8 bytes a step in "
                                 "every MjData)");
  }
  t->pruned = v[kCfgPruned] != 0.0;
  return true;
}

bool ReadConfig(const mjModel* m, Reader* r, std::vector<double>* c, Tables* t) {
  if (!ReadSchedule(r, c, t)) return false;
  const std::vector<double>& v = *c;
  const uint64_t shape = StructureHash(m);
  if (v[kCfgNgeom] != m->ngeom || v[kCfgNbody] != m->nbody ||
      v[kCfgShape] != static_cast<double>(shape & 0xffffffffu) ||
      v[kCfgShape + 1] != static_cast<double>(shape >> 32)) {
    return r->Fail("config", "was made for another model (" + std::to_string(v[kCfgNgeom]) +
                                 " geoms and " + std::to_string(v[kCfgNbody]) +
                                 " bodies, or another structure; this one has " +
                                 std::to_string(m->ngeom) + " and " + std::to_string(m->nbody) +
                                 "): the spec changed after dua_mujoco.attach; attach last, after "
                                 "every edit");
  }
  t->timestep = v[kCfgTimestep];
  if (!(t->timestep > 0.0) || !Finite(t->timestep) || t->timestep != m->opt.timestep) {
    return r->Fail("config", "holds a timestep (" + std::to_string(t->timestep) +
                                 ") other than the model's (" + std::to_string(m->opt.timestep) +
                                 "): the timestep changed after dua_mujoco.attach");
  }
  // The period is a whole number of physics steps (the plugin's clock counts them).
  const double steps = t->schedule.dt / t->timestep;
  if (!(steps >= 1.0 - 1e-9) || std::fabs(steps - std::nearbyint(steps)) > 1e-6 * steps) {
    return r->Fail("config", "holds a period that is not a whole number of timesteps");
  }
  t->exact = v[kCfgExactOn] != 0.0;
  t->exact_below = v[kCfgExactBelow];
  t->query_below = v[kCfgQueryBelow];
  if (!(t->exact_below >= 0.0) || !(t->query_below >= 0.0) || std::isnan(t->exact_below) ||
      std::isnan(t->query_below)) {
    return r->Fail("config", "holds the exact level's thresholds not >= 0");
  }
  return true;
}

// The spheres, shapes and pairs (and their index: the universe).
bool ReadPairs(const mjModel* m, Reader* r, Tables* t) {
  if (!r->Get("spheres", -1, kSphereNcol, &t->spheres)) return false;
  if (!Rows(r, "spheres", t->spheres, kSphereNcol,
            "its geom, body and root are not the model's, or its offset is not finite",
            [m](const double* rec) { return SphereRecordOk(m, rec); })) {
    return false;
  }
  const int64_t nsphere = t->nsphere();
  if (!r->Get("shapes", -1, kShapeNcol, &t->shapes)) return false;
  // Terrain records point into their blocks, after every record: every block must fit
  // (terrain.cc); the records are the rows before the first block.
  const int64_t shape_rows = static_cast<int64_t>(t->shapes.size()) / kShapeNcol;
  const int64_t bad_terrain = dua_check_shapes(t->shapes.data(), shape_rows);
  if (bad_terrain >= 0) {
    return r->Fail("shapes", "row " + std::to_string(bad_terrain) +
                                 ": a terrain record whose block does not fit the table");
  }
  const int64_t nshape = ShapeRecordCount(t->shapes.data(), shape_rows);
  const std::vector<double> records(t->shapes.begin(), t->shapes.begin() + nshape * kShapeNcol);
  if (!Rows(r, "shapes", records, kShapeNcol, "not a shape of a known kind with finite entries",
            [](const double* rec) {
              const double k = rec[kShapeKind];
              if (k == kGeomHField) return true;  // checked with its block above
              bool ok = k >= kGeomSphere && k <= kGeomMeshBox && k == std::floor(k);
              for (int c = 1; c < kShapeNcol; ++c) ok = ok && Finite(rec[c]);
              for (int c = 0; c < 3; ++c) ok = ok && rec[kShapeSize + c] >= 0.0;
              return ok;
            })) {
    return false;
  }
  Universe& u = t->universe;
  std::vector<double> pair_geom, geom_pairs;
  if (!r->Get("pairs", -1, kPairNcol, &u.pairs) || !r->Get("geom_pairs", -1, 2, &geom_pairs)) {
    return false;
  }
  const auto npair = static_cast<int64_t>(u.pairs.size()) / kPairNcol;
  const auto ngp = static_cast<int64_t>(geom_pairs.size()) / 2;
  if (!r->Get("pair_geom", npair, 1, &pair_geom)) return false;
  const int64_t ngeom = m->ngeom;
  if (!Rows(r, "pairs", u.pairs, kPairNcol,
            "its members, kind or bounds are out of range (members: a sphere, and a sphere, a "
            "plane geom or a shape; bounds finite and >= 0)",
            [&](const double* rec) {
              const double kind = rec[kPairKind];
              bool ok = IsIndex(rec[kPairFirst], nsphere);
              if (kind == kKindSphere) {
                ok =
                    ok && IsIndex(rec[kPairSecond], nsphere) && rec[kPairSecond] != rec[kPairFirst];
              } else if (kind == kKindHalfspace) {
                ok = ok && IsIndex(rec[kPairOther], ngeom);
              } else if (kind == kKindShape) {
                ok = ok && IsIndex(rec[kPairOther], nshape) && IsIndex(rec[kPairSecond], nshape);
              } else {
                ok = false;
              }
              return ok && Bound(rec[kPairEps]) && Bound(rec[kPairAccel]) &&
                     Bound(rec[kPairDelta]) && SpeedBound(rec[kPairSpeed]);
            })) {
    return false;
  }
  if (!AsInts(pair_geom, 0, static_cast<double>(ngp), &u.pair_geom)) {
    return r->Fail("pair_geom", "holds an entry that is not a geom pair's row");
  }
  if (!AsInts(geom_pairs, 0, static_cast<double>(ngeom), &u.geom_pairs)) {
    return r->Fail("geom_pairs", "holds an entry that is not a geom of the model");
  }
  if (!r->Get("geom_pair_contact", ngp, 2, &u.gp_contact)) return false;
  for (const double x : u.gp_contact) {
    if (!Finite(x)) return r->Fail("geom_pair_contact", "holds a margin or gap not finite");
  }
  const std::string bad = u.Index(t->spheres, ngeom);
  if (!bad.empty()) return r->Fail("pairs", "do not fit together: " + bad);
  // A half-space pair's plane is a plane geom; a shape pair's shape the one of its geom pair.
  for (int64_t p = 0; p < npair; ++p) {
    const double* rec = u.pairs.data() + kPairNcol * p;
    if (rec[kPairKind] == kKindHalfspace &&
        (m->geom_type[static_cast<int64_t>(rec[kPairOther])] != mjGEOM_PLANE ||
         u.geom2[p] != static_cast<int64_t>(rec[kPairOther]))) {
      return r->Fail("pairs", "row " + std::to_string(p) +
                                  ": a half-space pair whose plane is not "
                                  "the plane geom of its geom pair");
    }
  }
  return true;
}

// The static guard's records: one per shape record, in their order, each of a geom that does
// not move (its body the world or still), so that StaticMismatch's KnotKinematics reads no
// state.
bool ReadStatic(const mjModel* m, Reader* r, Tables* t) {
  const int64_t rows = static_cast<int64_t>(t->shapes.size()) / kShapeNcol;
  if (!r->Get("static", ShapeRecordCount(t->shapes.data(), rows), kStaticNcol, &t->statics)) {
    return false;
  }
  if (!Rows(r, "static", t->statics, kStaticNcol, "its geom is not a static geom of the model",
            [m](const double* rec) {
              if (!IsIndex(rec[kStaticGeom], m->ngeom)) return false;
              const int b = m->geom_bodyid[static_cast<int>(rec[kStaticGeom])];
              return b == 0 || StillBody(m, b);
            })) {
    return false;
  }
  // Records that no longer describe the model's static geoms (an edit since the build, or a
  // corrupted table) would leave the shape records stale: the table is refused, as a table.
  const std::string edited = StaticMismatch(m, t->statics);
  return edited.empty() || r->Fail("static", StaticRefusal(edited));
}

bool ReadEvents(const mjModel* m, Reader* r, Tables* t) {
  if (!r->Get("events_rec", -1, kBNcol, &t->events_rec) ||
      !r->Get("events_params", 1, 2, &t->events_params)) {
    return false;
  }
  t->nbody_events = static_cast<int64_t>(t->events_rec.size()) / kBNcol;
  if (!Rows(r, "events_rec", t->events_rec, kBNcol,
            "its geom, body and root are not the model's, or its box or bounds are not finite",
            [m](const double* rec) {
              if (!IsIndex(rec[kBFrame], m->ngeom)) return false;
              const int b = m->geom_bodyid[static_cast<int>(rec[kBFrame])];
              bool ok = rec[kBBody] == b && rec[kBRoot] == m->body_rootid[b];
              for (int c = 0; c < 3; ++c) {
                ok = ok && Finite(rec[kBCenter + c]) && Bound(rec[kBHalf + c]);
              }
              return ok && Bound(rec[kBAccel]) && Bound(rec[kBDisc]) && SpeedBound(rec[kBSpeed]);
            })) {
    return false;
  }
  const double h = t->events_params[0], rtol = t->events_params[1];
  if (!(h > 0.0) || !Finite(h) || !Bound(rtol)) {
    return r->Fail("events_params", "is not (period > 0, tolerance >= 0)");
  }
  // Each geom's row in the check (its body's, -1: not checked); a body checked twice would have
  // its pairs indexed under one row only.
  std::vector<int64_t> body_row(m->nbody, -1);
  for (int64_t i = 0; i < t->nbody_events; ++i) {
    int64_t& row = body_row[static_cast<int64_t>(t->events_rec[kBNcol * i + kBBody])];
    if (row >= 0) return r->Fail("events_rec", "row " + std::to_string(i) + ": a body twice");
    row = i;
  }
  t->geom_row.resize(m->ngeom);
  for (int g = 0; g < m->ngeom; ++g) t->geom_row[g] = body_row[m->geom_bodyid[g]];
  return true;
}

bool ReadExact(const mjModel* m, Reader* r, Tables* t) {
  Universe& u = t->universe;
  if (!r->Get("exact_geoms", m->ngeom, kGxNcol, &t->geoms) ||
      !r->Get("exact_records", u.npair(), kXNcol, &u.exact)) {
    return false;
  }
  // The model's hull graphs, read here only (an address not negative is one of its meshes'
  // mesh_graphadr, checked below): the climb reads its own rows (climb).
  const int32_t* graph = m->mesh_graph;
  // Hull vertices of geom g's mesh when the level climbs its hull graph, else 0.
  auto numvert = [&](int64_t g) -> int64_t {
    const double adr = t->geoms[kGxNcol * g + kGxGraph];
    return adr >= 0.0 ? graph[static_cast<int64_t>(adr)] : 0;
  };
  int64_t g = 0;
  if (!Rows(r, "exact_geoms", t->geoms, kGxNcol,
            "not the record of this geom (origin, kind, size, radius, and a mesh's vertices and "
            "hull graph as the model has them)",
            [&](const double* rec) {
              const int64_t id = g++;
              if (!SphereRecordOk(m, rec) || rec[kSphereFrame] != id) return false;
              const double kind = rec[kGxKind];
              // A geom the level does not read, and a height field (read through its terrain's
              // grid, never its own record): no hull (the hulls' pass below indexes the graph
              // by any address that is not negative).
              const bool no_hull = rec[kGxGraph] == -1.0 && rec[kGxVert] == -1.0;
              if (kind == -1.0) return no_hull;
              if (kind == kGeomHField) return no_hull && m->geom_type[id] == mjGEOM_HFIELD;
              bool ok = kind >= kGeomSphere && kind <= kGeomMeshBox && kind == std::floor(kind);
              for (int c = 0; c < 3; ++c) {
                ok = ok && Bound(rec[kGxSize + c]) && Finite(rec[kGxCentre + c]);
              }
              ok = ok && Bound(rec[kGxRadius]);
              if (!ok || rec[kGxGraph] == -1.0) return ok && rec[kGxVert] == -1.0;
              // A mesh's hull: the model's own vertex and graph addresses, seeds among its
              // hull's vertices.
              const int mesh = m->geom_dataid[id];
              if (m->geom_type[id] != mjGEOM_MESH || mesh < 0 || m->mesh_graphadr[mesh] < 0 ||
                  rec[kGxGraph] != m->mesh_graphadr[mesh] ||
                  rec[kGxVert] != m->mesh_vertadr[mesh]) {
                return false;
              }
              const int64_t nv = graph[m->mesh_graphadr[mesh]];
              for (int c = 0; c < 6; ++c) ok = ok && IsIndex(rec[kGxSeed + c], nv);
              return ok;
            })) {
    return false;
  }
  // Each hull's climb rows once (geoms of one mesh share them), in its graph's local order.
  t->hull_at.assign(m->ngeom, -1);
  t->climb.clear();
  t->climb_at.clear();
  std::vector<int64_t> at_graph(static_cast<size_t>(m->nmeshgraph), -1);
  for (int64_t id = 0; id < m->ngeom; ++id) {
    const double adr = t->geoms[kGxNcol * id + kGxGraph];
    if (adr < 0.0) continue;
    int64_t& at = at_graph[static_cast<int64_t>(adr)];
    if (at < 0) {
      at = static_cast<int64_t>(t->climb_at.size());
      const int64_t nv = graph[static_cast<int64_t>(adr)];
      const int32_t* global = graph + static_cast<int64_t>(adr) + 2 + nv;
      const float* verts =
          m->mesh_vert + 3 * static_cast<int64_t>(t->geoms[kGxNcol * id + kGxVert]);
      const int32_t* edges = global - nv;
      const int32_t* local = global + nv;
      auto entry = [&](int64_t k, int64_t value) {
        const float* v = verts + 3 * global[k];
        return dua_hull_entry{v[0], v[1], v[2], static_cast<int32_t>(value)};
      };
      for (int64_t k = 0; k < nv; ++k) {
        t->climb_at.push_back(static_cast<int64_t>(t->climb.size()));
        const int32_t* first = local + edges[k];
        const int32_t* e = first;
        while (*e >= 0) ++e;
        t->climb.push_back(entry(k, e - first));
        for (e = first; *e >= 0; ++e) t->climb.push_back(entry(*e, *e));
      }
    }
    t->hull_at[id] = at;
  }
  if (t->climb.empty()) t->climb.assign(1, dua_hull_entry{0.0f, 0.0f, 0.0f, 0});
  if (t->climb_at.empty()) t->climb_at.assign(1, 0);
  for (int64_t p = 0; p < u.npair(); ++p) {
    const double* rec = u.exact.data() + kXNcol * p;
    const double mode = rec[kXMode];
    bool ok = mode >= kModeNone && mode <= kModeTerrain && mode == std::floor(mode) &&
              rec[kXG1] == u.geom1[p] && rec[kXG2] == u.geom2[p] && Bound(rec[kXDist]);
    for (int c = 0; c < 3; ++c) ok = ok && Finite(rec[kXN + c]);
    if (ok && mode != kModeNone) {
      // The geoms it reads are ones the level has records of.
      const double k2 = t->geoms[kGxNcol * u.geom2[p] + kGxKind];
      ok = t->geoms[kGxNcol * u.geom1[p] + kGxKind] >= kGeomSphere &&
           (mode == kModePlane || (mode == kModeTerrain ? k2 == kGeomHField : k2 >= kGeomSphere));
      // A terrain's pair reads the terrain record of its shape pair (terrain.cc).
      if (ok && mode == kModeTerrain) {
        const double* pair = u.pairs.data() + kPairNcol * p;
        ok = pair[kPairKind] == kKindShape &&
             t->shapes[kShapeNcol * static_cast<int64_t>(pair[kPairOther]) + kShapeKind] ==
                 kGeomHField;
      }
      ok = ok && (mode != kModePlane || m->geom_type[u.geom2[p]] == mjGEOM_PLANE);
    }
    ok = ok && (rec[kXHull1] == -1.0 || IsIndex(rec[kXHull1], numvert(u.geom1[p])));
    ok = ok && (rec[kXHull2] == -1.0 || IsIndex(rec[kXHull2], numvert(u.geom2[p])));
    if (!ok) {
      return r->Fail("exact_records", "row " + std::to_string(p) +
                                          ": not the exact level's record of its pair (mode, "
                                          "geoms, contact distance, direction, hull vertices)");
    }
  }
  return true;
}

// Reads table `name` as (rows, ncol) into columns: out[c][r].
bool Columns(Reader* r, const std::string& name, int64_t rows, int ncol,
             std::vector<std::vector<double>>* out) {
  std::vector<double> v;
  if (!r->Get(name, rows, ncol, &v)) return false;
  out->assign(ncol, std::vector<double>(rows));
  for (int64_t i = 0; i < rows; ++i) {
    for (int c = 0; c < ncol; ++c) (*out)[c][i] = v[ncol * i + c];
  }
  return true;
}

// What learning a pair reads (universe.h).
bool ReadLearn(const mjModel* m, Reader* r, const std::vector<double>& config, Tables* t) {
  LearnTables& l = t->learn;
  std::vector<std::vector<double>> f, c, lone, body;
  std::vector<double> exclude, start, planes, shapes;
  const int64_t nsphere = t->nsphere(), ngeom = m->ngeom, nbody = m->nbody;
  if (!Columns(r, "filter", ngeom, 7, &f) || !Columns(r, "contact", ngeom, 2, &c) ||
      !Columns(r, "geom_lone", ngeom, 2, &lone) || !Columns(r, "body_bounds", nbody, 3, &body) ||
      !r->Get("exclude", -1, 1, &exclude) || !r->Get("geom_start", ngeom + 1, 1, &start) ||
      !r->Get("plane_geom", -1, 1, &planes) || !r->Get("shape_geom", -1, 1, &shapes)) {
    return false;
  }
  const auto nplane = static_cast<double>(planes.size());
  const auto nshape = static_cast<double>(shapes.size());
  std::vector<int64_t> movable, lone_flag;
  if (!AsInts(f[0], 0, nbody, &l.body) || !AsInts(f[1], 0, nbody, &l.weld) ||
      !AsInts(f[2], 0, nbody, &l.parent_weld) || !AsInts(f[3], 0, 2, &movable) ||
      !AsInts(f[4], 0, 4294967296.0, &l.contype) ||
      !AsInts(f[5], 0, 4294967296.0, &l.conaffinity) || !AsInts(f[6], 0, 2, &lone_flag)) {
    return r->Fail("filter",
                   "holds an entry out of range (bodies, weld groups, flags 0/1, "
                   "contype and conaffinity as unsigned 32-bit)");
  }
  for (int64_t g = 0; g < ngeom; ++g) {
    if (l.body[g] != m->geom_bodyid[g]) {
      return r->Fail("filter", "row " + std::to_string(g) + ": not the body of that geom");
    }
  }
  l.movable.assign(movable.begin(), movable.end());
  l.lone.assign(lone_flag.begin(), lone_flag.end());
  if (!AsInts(exclude, 0, kMaxInt, &l.exclude) ||
      !std::is_sorted(l.exclude.begin(), l.exclude.end())) {
    return r->Fail("exclude", "is not a sorted list of body-pair signatures");
  }
  if (!AsInts(start, 0, static_cast<double>(nsphere) + 1, &l.geom_start) ||
      !std::is_sorted(l.geom_start.begin(), l.geom_start.end()) || l.geom_start.back() != nsphere) {
    return r->Fail("geom_start",
                   "is not each geom's first sphere (increasing, ending at the "
                   "number of spheres)");
  }
  if (!AsInts(lone[0], -1, nplane, &l.geom_plane) || !AsInts(lone[1], -1, nshape, &l.geom_shape) ||
      !AsInts(planes, 0, ngeom, &l.plane_geom) || !AsInts(shapes, 0, ngeom, &l.shape_geom)) {
    return r->Fail("geom_lone", "or plane_geom or shape_geom holds an index out of range");
  }
  for (int64_t g = 0; g < ngeom; ++g) {
    const bool plane = l.geom_plane[g] >= 0, shape = l.geom_shape[g] >= 0;
    const bool spheres = l.geom_start[g + 1] > l.geom_start[g];
    if ((plane && (shape || spheres || l.plane_geom[l.geom_plane[g]] != g)) ||
        (shape && (spheres || l.shape_geom[l.geom_shape[g]] != g))) {
      return r->Fail("geom_lone", "row " + std::to_string(g) +
                                      ": a geom covered twice, or not the geom of its plane or "
                                      "shape");
    }
  }
  for (int64_t i = 0; i < nsphere; ++i) {
    const auto g = static_cast<int64_t>(t->spheres[kSphereNcol * i + kSphereFrame]);
    if (i < l.geom_start[g] || i >= l.geom_start[g + 1]) {
      return r->Fail("geom_start",
                     "does not hold sphere " + std::to_string(i) + " in its geom's range");
    }
  }
  l.margin = c[0], l.gap = c[1];
  for (int64_t g = 0; g < ngeom; ++g) {
    if (!Finite(l.margin[g]) || !Finite(l.gap[g])) {
      return r->Fail("contact", "row " + std::to_string(g) + ": margin and gap not finite");
    }
  }
  l.accel = body[0], l.delta = body[1], l.speed = body[2];
  for (int64_t b = 0; b < nbody; ++b) {
    if (!Bound(l.accel[b]) || !Bound(l.delta[b]) || !SpeedBound(l.speed[b])) {
      return r->Fail("body_bounds", "row " + std::to_string(b) + ": bounds not >= 0");
    }
  }
  l.filter.filterparent = config[kCfgFilterParent] != 0.0;
  l.contacts = config[kCfgContacts] != 0.0;
  l.override_margin = config[kCfgOverride] != 0.0;
  l.o_margin = config[kCfgOMargin];
  l.has_speed = config[kCfgHasSpeed] != 0.0;
  if (!Finite(l.o_margin)) return r->Fail("config", "holds a margin override that is not finite");
  l.radius = t->held.radius.data();  // the Tables are never copied or moved once built
  l.sphere_geom.resize(nsphere), l.sphere_body.resize(nsphere);
  for (int64_t i = 0; i < nsphere; ++i) {
    l.sphere_geom[i] = static_cast<int64_t>(t->spheres[kSphereNcol * i + kSphereFrame]);
    l.sphere_body[i] = static_cast<int64_t>(t->spheres[kSphereNcol * i + kSphereBody]);
  }
  l.exact_geoms = t->exact ? t->geoms.data() : nullptr;
  l.Point();
  return true;
}

// The pruned pairs' tables.
// The reach table (nsphere rows: radius, accel, delta, speed) and the pruned pairs' options
// (all pairs held: the reach's rows alone, which free spheres learn their pairs with).
bool ReadReach(Reader* r, const std::vector<double>& reach, const std::vector<double>& config,
               int64_t nbody, Tables* t) {
  double horizon = t->schedule.dt, stride = 1;  // all pairs held: neither is read
  if (t->pruned) {
    horizon = config[kCfgHorizon], stride = config[kCfgStride];
    const double renew = config[kCfgRenewMax];
    if (!(stride >= 1 && stride < 1e9) || stride != std::floor(stride)) {
      return r->Fail("config", "holds a stride that is not an int in [1, 1e9)");
    }
    if (!(renew >= 0 && renew < 1e9) || renew != std::floor(renew)) {
      return r->Fail("config", "holds a renewal limit that is not an int in [0, 1e9)");
    }
    t->renew_max = static_cast<int64_t>(renew);
    // A pair left out at a rebuild has no contact within the horizon; the next rebuild, a stride
    // later, holds it, and its alarm acts after the latency and must lead the alarm horizon:
    // (stride + latency) dt + (alarm_horizon - dt) + (dt - timestep) <= horizon, the last term
    // (0 at period 1) for a contact between two predictor steps (docs/many-objects.md and
    // docs/theory.md, section 8; a billionth of a step is the rounding of the writer's product,
    // a stride is whole steps).
    const ScheduleSpec& s = t->schedule;
    const double lead =
        static_cast<double>(s.latency) * s.dt + (s.alarm_horizon - s.dt) + (s.dt - t->timestep);
    if (stride * s.dt + lead > horizon + 1e-9 * s.dt) {
      const double most = std::floor((horizon - lead) / s.dt + 1e-9);
      const std::string fix = most >= 1.0 ? "lower the stride to " + Shown(most) + " or less"
                                          : std::string("lengthen the horizon");
      return r->Fail("config",
                     "holds a stride of " + Shown(stride) + " steps past the reach's horizon (" +
                         Shown(horizon) +
                         " s): a pair left out at a rebuild could touch before the " +
                         "next rebuild's alarm leads by the alarm horizon; " + fix +
                         ", so that (stride + latency) dt + alarm_horizon - timestep <= " +
                         "horizon, or build the tables again (attach, or a new predictor)");
    }
    // Pruned pairs are carried into the deadline schedule only.
    if (t->schedule.kind != kDeadline) {
      return r->Fail("config", "holds pruned pairs with a schedule other than the deadline one");
    }
  }
  const std::string bad = t->held.Build(reach, t->spheres, nbody, horizon, config[kCfgMargin],
                                        static_cast<int64_t>(stride));
  if (!bad.empty()) return r->Fail("reach", "does not fit: " + bad);
  return true;
}

bool ReadPruned(const mjModel* m, Reader* r, const std::vector<double>& config, Tables* t) {
  std::vector<double> reach;
  return r->Get("reach", t->nsphere(), 4, &reach) && ReadReach(r, reach, config, m->nbody, t) &&
         ReadLearn(m, r, config, t);
}

// Free spheres' covering and learning tables: sphere i the one point of geom i on body i (its own
// root), every pair passing with the config's margin as its contact distance (LearnTables'
// points: no filter, no per-geom margins).
void FreeLayout(int64_t n, const std::vector<double>& config, Tables* t) {
  t->spheres.assign(kSphereNcol * n, 0.0);
  for (int64_t i = 0; i < n; ++i) {
    double* rec = t->spheres.data() + kSphereNcol * i;
    rec[kSphereFrame] = rec[kSphereBody] = rec[kSphereRoot] = static_cast<double>(i);
  }
  LearnTables& l = t->learn;
  l.points = true;
  l.geom_start.resize(n + 1);
  std::iota(l.geom_start.begin(), l.geom_start.end(), int64_t{0});
  l.sphere_geom = l.sphere_body =
      std::vector<int64_t>(l.geom_start.begin(), l.geom_start.end() - 1);
  l.geom_plane.assign(n, -1), l.geom_shape.assign(n, -1);
  l.o_margin = config[kCfgMargin];
  l.contacts = true;
  l.has_speed = config[kCfgHasSpeed] != 0.0;
  l.Point();
}

}  // namespace

bool Decode(const char* text, std::vector<double>* out, std::string* why) {
  char* end = nullptr;
  const long long count = std::strtoll(text, &end, 10);
  if (end == text || count < 0 || *end != ' ' || count > (1LL << 40)) {
    *why = "does not start with its entry count and a space";
    return false;
  }
  const char* digits = end + 1;
  const size_t nbytes = static_cast<size_t>(count) * sizeof(double);
  const size_t ndigits = (nbytes + 2) / 3 * 4;
  if (std::strlen(digits) != ndigits) {
    *why = "does not hold its " + std::to_string(count) + " entries";
    return false;
  }
  static const std::array<int8_t, 256> kDigit = [] {
    std::array<int8_t, 256> t{};
    t.fill(-1);
    const char* alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    for (int i = 0; i < 64; ++i)
      t[static_cast<unsigned char>(alphabet[i])] = static_cast<int8_t>(i);
    t['='] = 0;
    return t;
  }();
  std::vector<unsigned char> bytes(ndigits / 4 * 3);
  const auto* in = reinterpret_cast<const unsigned char*>(digits);
  for (size_t i = 0, o = 0; i < ndigits; i += 4, o += 3) {
    const int a = kDigit[in[i]], b = kDigit[in[i + 1]], c = kDigit[in[i + 2]],
              e = kDigit[in[i + 3]];
    if ((a | b | c | e) < 0) {
      *why = "holds a character that is not base64";
      return false;
    }
    const unsigned triple = (static_cast<unsigned>(a) << 18) | (static_cast<unsigned>(b) << 12) |
                            (static_cast<unsigned>(c) << 6) | static_cast<unsigned>(e);
    bytes[o] = static_cast<unsigned char>(triple >> 16);
    bytes[o + 1] = static_cast<unsigned char>(triple >> 8);
    bytes[o + 2] = static_cast<unsigned char>(triple);
  }
  out->resize(static_cast<size_t>(count));
  if (nbytes) std::memcpy(out->data(), bytes.data(), nbytes);  // little-endian, as written
  return true;
}

namespace {

// A digest of everything BuildTables reads from a model: the text fields under prefix and the
// model arrays the checks and copies read (ReadConfig, ReadPairs, ReadExact, ReadPruned). Two
// models with one digest give the same tables, so LoadTables may hand out tables it parsed for
// another model at the same address. A check that reads another model field adds it here.
class Digest {
 public:
  void Bytes(const void* p, size_t n) {
    const auto* c = static_cast<const unsigned char*>(p);
    size_t k = 0;
    if (n >= 64) {
      // Four words at a time in four lanes, folded in after: a height field's megabyte at each
      // reset (the static guard) runs at four times the throughput. Each step is one-to-one in
      // its word, so one word changed changes its lane and the digest.
      uint64_t lane[4] = {h_, h_ ^ 1, h_ ^ 2, h_ ^ 3};
      for (; k + 32 <= n; k += 32) {
        for (int j = 0; j < 4; ++j) lane[j] = Mix(lane[j], Word(c + k + 8 * j));
      }
      for (const uint64_t l : lane) h_ = Mix(h_, l);
    }
    for (; k + 8 <= n; k += 8) h_ = Mix(h_, Word(c + k));  // it tells contents apart, not FNV
    for (; k < n; ++k) h_ = (h_ ^ c[k]) * 0x100000001b3ULL;
  }
  template <typename T>
  void Array(const T* values, int64_t n) {
    Bytes(&n, sizeof n);
    if (n > 0) Bytes(values, static_cast<size_t>(n) * sizeof(T));
  }
  uint64_t value() const { return h_; }

 private:
  static uint64_t Word(const unsigned char* c) {
    uint64_t w;
    std::memcpy(&w, c, 8);
    return w;
  }
  static uint64_t Mix(uint64_t h, uint64_t w) {
    h = (h ^ w) * 0x100000001b3ULL;
    return h ^ (h >> 29);
  }

  uint64_t h_ = 0xcbf29ce484222325ULL;
};

uint64_t TablesDigest(const mjModel* m, const std::string& prefix) {
  Digest d;
  const std::string head = prefix + ":";
  for (int i = 0; i < m->ntext; ++i) {
    const char* name = m->names + m->name_textadr[i];
    if (std::strncmp(name, head.c_str(), head.size()) != 0) continue;
    d.Array(name, static_cast<int64_t>(std::strlen(name)));
    d.Array(m->text_data + m->text_adr[i], m->text_size[i]);
  }
  d.Bytes(&m->opt.timestep, sizeof m->opt.timestep);
  d.Array(m->geom_type, m->ngeom);
  d.Array(m->geom_bodyid, m->ngeom);
  d.Array(m->geom_dataid, m->ngeom);
  d.Array(m->body_parentid, m->nbody);
  d.Array(m->body_rootid, m->nbody);
  d.Array(m->mesh_vertadr, m->nmesh);
  d.Array(m->mesh_graphadr, m->nmesh);
  // The vertices themselves are read from the model at each step (Runtime::Bind), not copied.
  d.Bytes(&m->nmeshvert, sizeof m->nmeshvert);
  d.Array(m->mesh_graph, m->nmeshgraph);
  return d.value();
}

// The digest of what static geom g's record was built from beyond its pose and size: a height
// field's size, grid and heights; a mesh's geom_aabb (its box) and vertices; 0 for the others.
uint64_t StaticDigest(const mjModel* m, int64_t g) {
  const int type = m->geom_type[g], id = m->geom_dataid[g];
  if (id < 0 || (type != mjGEOM_HFIELD && type != mjGEOM_MESH)) return 0;
  Digest d;
  if (type == mjGEOM_HFIELD) {
    const int64_t grid[2] = {m->hfield_nrow[id], m->hfield_ncol[id]};
    d.Array(m->hfield_size + 4 * id, 4);
    d.Array(grid, 2);
    d.Array(m->hfield_data + m->hfield_adr[id], grid[0] * grid[1]);
  } else {
    d.Array(m->geom_aabb + 6 * g, 6);
    d.Array(m->mesh_vert + 3 * int64_t{m->mesh_vertadr[id]}, 3 * int64_t{m->mesh_vertnum[id]});
  }
  return d.value();
}

// n values as "[a, b, c]", each in the fewest digits that read back to it (as Python's repr:
// an edit in the last bits shows, 0.3 stays 0.3).
std::string Values(const double* v, int n) {
  std::string out = "[";
  for (int k = 0; k < n; ++k) {
    char text[32];
    for (int digits = 6; digits <= 17; ++digits) {
      std::snprintf(text, sizeof text, "%.*g", digits, v[k]);
      if (std::strtod(text, nullptr) == v[k]) break;
    }
    out += (k ? ", " : "") + std::string(text);
  }
  return out + "]";
}

// A digest's two 32-bit halves as 16 hex digits; halves that are not such integers (a corrupted
// table's) as their values.
std::string Hex(const double* halves) {
  for (int k = 0; k < 2; ++k) {
    if (!(halves[k] >= 0.0 && halves[k] < 4294967296.0 && halves[k] == std::floor(halves[k]))) {
      return Values(halves, 2);
    }
  }
  char text[32];
  std::snprintf(text, sizeof text, "%08llx%08llx", static_cast<unsigned long long>(halves[1]),
                static_cast<unsigned long long>(halves[0]));
  return text;
}

}  // namespace

std::vector<double> StaticRecords(const mjModel* m, const std::vector<int64_t>& geoms) {
  const KnotKinematics k(m, geoms);
  std::vector<double> out(kStaticNcol * geoms.size(), 0.0);
  for (size_t s = 0; s < geoms.size(); ++s) {
    const int64_t g = geoms[s];
    double* rec = out.data() + kStaticNcol * s;
    rec[kStaticGeom] = static_cast<double>(g);
    std::copy_n(k.still_pos(s), 3, rec + kStaticPos);
    std::copy_n(k.still_mat(s), 9, rec + kStaticMat);
    std::copy_n(m->geom_size + 3 * g, 3, rec + kStaticSize);
    const uint64_t digest = StaticDigest(m, g);
    rec[kStaticDigest] = static_cast<double>(digest & 0xffffffffu);
    rec[kStaticDigest + 1] = static_cast<double>(digest >> 32);
  }
  return out;
}

std::string StaticRefusal(const std::string& mismatch) {
  return "does not match the model: " + mismatch +
         ". The tables cover the static geoms as they were when they were built, and would miss "
         "their contacts: attach the plugin again after editing static geoms (edit the spec, "
         "then dua_mujoco.attach(spec) and spec.compile(), or re-export the model), and make the "
         "MjData from that model";
}

std::string StaticFieldRefusal(const std::string& prefix, const std::string& mismatch) {
  return "text field '" + prefix + ":static' " + StaticRefusal(mismatch);
}

std::string StaticMismatch(const mjModel* m, const std::vector<double>& statics) {
  const size_t n = statics.size() / kStaticNcol;
  if (n == 0) return std::string();
  std::vector<int64_t> geoms(n);
  for (size_t s = 0; s < n; ++s) {
    geoms[s] = static_cast<int64_t>(statics[kStaticNcol * s + kStaticGeom]);
  }
  const std::vector<double> now = StaticRecords(m, geoms);
  // Each static geom's first column that differs (NaN differs from itself: a geom put at NaN is
  // refused too).
  size_t first = n, edited = 0;
  int column = 0;
  for (size_t s = 0; s < n; ++s) {
    for (int c = kStaticPos; c < kStaticNcol; ++c) {
      const size_t i = kStaticNcol * s + static_cast<size_t>(c);
      if (now[i] == statics[i]) continue;
      if (first == n) first = s, column = c;
      ++edited;
      break;
    }
  }
  if (first == n) return std::string();
  const int64_t g = geoms[first];
  const char* name = mj_id2name(m, mjOBJ_GEOM, static_cast<int>(g));
  const double* was = statics.data() + kStaticNcol * first;
  const double* is = now.data() + kStaticNcol * first;
  std::string what;
  if (column < kStaticMat) {
    what = "moved: its position (geom_xpos) was " + Values(was + kStaticPos, 3) + ", is " +
           Values(is + kStaticPos, 3);
  } else if (column < kStaticSize) {
    what = "turned: its rotation (geom_xmat) was " + Values(was + kStaticMat, 9) + ", is " +
           Values(is + kStaticMat, 9);
  } else if (column < kStaticDigest) {
    what = "changed size: its geom_size was " + Values(was + kStaticSize, 3) + ", is " +
           Values(is + kStaticSize, 3);
  } else {
    what = std::string("changed shape: its ") +
           (m->geom_type[g] == mjGEOM_HFIELD ? "height field (hfield_data, hfield_size)"
                                             : "mesh (mesh_vert, geom_aabb)") +
           " had digest " + Hex(was + kStaticDigest) + ", has " + Hex(is + kStaticDigest);
  }
  const std::string shown = name && *name ? name : "geom" + std::to_string(g);
  return "static geom " + std::to_string(g) + " ('" + shown + "') " + what + " (" +
         std::to_string(edited) + " of " + std::to_string(n) +
         " static geoms edited since the tables were built)";
}

uint64_t StructureHash(const mjModel* m) {
  uint64_t h = 0xcbf29ce484222325ULL;
  auto feed = [&h](const int* values, int n) {
    for (int i = 0; i < n; ++i) {
      const auto v = static_cast<uint32_t>(values[i]);
      for (int b = 0; b < 4; ++b) {
        h ^= (v >> (8 * b)) & 0xffu;
        h *= 0x100000001b3ULL;
      }
    }
  };
  feed(m->geom_type, m->ngeom);
  feed(m->geom_bodyid, m->ngeom);
  feed(m->body_parentid, m->nbody);
  return h;
}

std::shared_ptr<const Tables> BuildTables(const mjModel* m, const TableSource& source,
                                          const std::string& before, const std::string& after,
                                          std::string* error) {
  auto t = std::make_shared<Tables>();
  Reader r(source, before, after, error);
  std::vector<double> config;
  if (!ReadConfig(m, &r, &config, t.get()) || !ReadPairs(m, &r, t.get()) ||
      !ReadStatic(m, &r, t.get()) || !ReadEvents(m, &r, t.get()) ||
      (t->exact && !ReadExact(m, &r, t.get())) ||
      (t->pruned && !ReadPruned(m, &r, config, t.get()))) {
    return nullptr;
  }
  return t;
}

std::shared_ptr<const Tables> FreeTables(const TableSource& source, const std::string& before,
                                         const std::string& after, std::string* error) {
  auto t = std::make_shared<Tables>();
  Reader r(source, before, after, error);
  std::vector<double> config, reach;
  if (!ReadSchedule(&r, &config, t.get()) || !r.Get("reach", -1, 4, &reach)) return nullptr;
  const auto n = static_cast<int64_t>(reach.size() / 4);
  if (n < 1 || n >= (int64_t{1} << 31)) {
    r.Fail("reach", "holds " + std::to_string(n) + " spheres, not 1 to 2^31 - 1");
    return nullptr;
  }
  t->free = true;
  t->timestep = t->schedule.dt;
  FreeLayout(n, config, t.get());
  if (!ReadReach(&r, reach, config, n, t.get())) return nullptr;
  LearnTables& l = t->learn;
  l.radius = t->held.radius.data();  // the Tables are never copied or moved once built
  l.accel = t->held.accel, l.delta = t->held.delta, l.speed = t->held.speed;
  Universe& u = t->universe;
  u.Index(t->spheres, n);  // no pair known yet
  if (!t->pruned) {
    // Every pair held: learnt now, in increasing (i, j) (Learn orders them by geom pair).
    std::vector<int64_t> g1, g2;
    for (int64_t i = 0; i < n; ++i) {
      for (int64_t j = i + 1; j < n; ++j) g1.push_back(i), g2.push_back(j);
    }
    u.Learn(l, g1.data(), g2.data(), static_cast<int64_t>(g1.size()));
  }
  return t;
}

std::shared_ptr<const Tables> LoadTables(const mjModel* m, const std::string& prefix,
                                         std::string* error) {
  // Parsed once per model content: every mjData of a model shares its tables, and the last few
  // table sets stay alive after their last mjData goes (a loop that makes and drops an mjData
  // parses once). The digest tells apart a model freed and another made at its address.
  constexpr size_t kKept = 8;
  struct Entry {
    const mjModel* model;
    std::string prefix;
    uint64_t digest;
    std::shared_ptr<const Tables> tables;
  };
  static std::mutex mutex;
  static std::vector<Entry> recent;  // most recent last
  const uint64_t digest = TablesDigest(m, prefix);
  std::shared_ptr<const Tables> kept;
  {
    std::lock_guard<std::mutex> lock(mutex);
    for (auto it = recent.begin(); it != recent.end(); ++it) {
      if (it->model == m && it->prefix == prefix && it->digest == digest) {
        std::rotate(it, it + 1, recent.end());
        kept = recent.back().tables;
        break;
      }
    }
  }
  if (kept) {
    // The digest reads no static pose or shape: the static geoms edited in place since the parse
    // are refused as ReadStatic refuses them in a fresh one.
    const std::string edited = StaticMismatch(m, kept->statics);
    if (edited.empty()) return kept;
    *error = StaticFieldRefusal(prefix, edited);
    return nullptr;
  }
  const TableSource source = [m, &prefix](const std::string& name, std::vector<double>* out,
                                          std::string* why) {
    const std::string full = prefix + ":" + name;
    const int id = mj_name2id(m, mjOBJ_TEXT, full.c_str());
    if (id < 0) {
      *why = "is missing (plugin attribute 'prefix' = '" + prefix +
             "'): build the model with dua_mujoco.attach(spec), which writes the tables";
      return false;
    }
    return Decode(m->text_data + m->text_adr[id], out, why);
  };
  std::shared_ptr<const Tables> t =
      BuildTables(m, source, "text field '" + prefix + ":", "'", error);
  if (!t) return nullptr;
  std::lock_guard<std::mutex> lock(mutex);
  recent.erase(
      std::remove_if(recent.begin(), recent.end(),
                     [m, &prefix](const Entry& e) { return e.model == m && e.prefix == prefix; }),
      recent.end());
  if (recent.size() == kKept) recent.erase(recent.begin());
  recent.push_back({m, prefix, digest, t});
  return t;
}

}  // namespace dua
