// The pairs a runtime knows (dua_mujoco/build/universe.py's PairUniverse builds the first ones and
// reads the rest back): fixed when it holds every pair, growing per mjData with pruned pairs,
// which learn the geom pairs their candidates bring in through MuJoCo's filter, with the tables
// the step reads of them.
#ifndef DUA_MUJOCO_UNIVERSE_H_
#define DUA_MUJOCO_UNIVERSE_H_

#include <cstdint>
#include <string>
#include <vector>

#include "dua/dua.h"

namespace dua {

// What learning a pair reads, per geom, sphere and body (dua_mujoco.attach writes it).
struct DUA_API LearnTables {
  // MuJoCo's filter (FilterTables): the arrays and the struct pointing at them.
  std::vector<int64_t> body, weld, parent_weld, contype, conaffinity, exclude;
  std::vector<uint8_t> movable, lone;
  dua_filter filter{};
  bool contacts = true;  // contacts are on (no mjDSBL_CONTACT, mjDSBL_CONSTRAINT)
  // Contact distances: each geom's margin and gap, the override's margin.
  std::vector<double> margin, gap;
  bool override_margin = false;
  double o_margin = 0.0;
  // The covering: each geom's first sphere (ngeom + 1), plane and shape index (-1: none), each
  // plane's and shape's geom; each sphere's radius (the reach table's), geom and body.
  std::vector<int64_t> geom_start, geom_plane, geom_shape, plane_geom, shape_geom;
  const double* radius = nullptr;
  std::vector<int64_t> sphere_geom, sphere_body;
  // Each body's bounds (the speed bound inf where none is declared).
  std::vector<double> accel, delta, speed;
  bool has_speed = false;
  const double* exact_geoms = nullptr;  // (ngeom, 24), null when the exact level is off
  // Free spheres (FreeTables): no filter and no per-geom margins, every pair passes with the
  // contact distance o_margin (the filter's arrays and margin, gap stay empty).
  bool points = false;

  void Point();  // the filter struct at the arrays
};

struct DUA_API Universe {
  std::vector<double> pairs;             // (npair, 8) packed records
  std::vector<double> exact;             // (npair, 10) the exact level's records as built
  std::vector<int64_t> pair_geom;        // (npair,) geom pair of each
  std::vector<int64_t> geom1, geom2;     // (npair,) the first sphere's geom, then the other
  std::vector<int64_t> geom_pairs;       // (ngp, 2) rows g1 < g2
  std::vector<double> gp_contact;        // (ngp, 2) MuJoCo's margin and gap of each
  std::vector<int64_t> gp_keys, gp_ids;  // g1 << 32 | g2, increasing, and their geom pairs
  std::vector<int64_t> codes, code_ids;  // sphere-sphere pairs by min * nsphere + max, sorted
  std::vector<int64_t> always;           // pairs against a plane or a static shape, increasing
  int64_t nsphere = 0;

  int64_t npair() const { return static_cast<int64_t>(pair_geom.size()); }
  int64_t ngp() const { return static_cast<int64_t>(geom_pairs.size() / 2); }
  // Index of geom pair (g1 < g2), or -1 if it is not known.
  int64_t GeomPair(int64_t g1, int64_t g2) const;
  // Derive the lookups from pairs, pair_geom and geom_pairs (sphere records: (nsphere, 8)).
  // Returns an empty string, or what does not fit.
  std::string Index(const std::vector<double>& spheres, int64_t ngeom);
  // The known pairs among candidate sphere pairs cand[0:2n] (rows i < j) appended to ids, the
  // rows of the others to unknown (if not null).
  void Lookup(const int64_t* cand, int64_t n, std::vector<int64_t>* ids,
              std::vector<int64_t>* unknown) const;
  // Learn the geom pairs {g1[k], g2[k]} the filter lets through and the universe lacks: their
  // sphere pairs appended with their tables. Returns how many sphere pairs were added.
  int64_t Learn(const LearnTables& lt, const int64_t* g1, const int64_t* g2, int64_t n);
  // Forgets the geom pairs k with keep_gp[k] == 0 and all their sphere pairs, renumbering the
  // rest in order (an id's rank among those kept is its new id) with memory released; pair_map
  // and gp_map receive each old id's new one (-1: forgotten). Lookup and Learn then act as if
  // the forgotten pairs had never been learnt (docs/theory.md, Lemma 7.1). Returns Index's
  // verdict.
  std::string Forget(const std::vector<uint8_t>& keep_gp, const std::vector<double>& spheres,
                     int64_t ngeom, std::vector<int64_t>* pair_map, std::vector<int64_t>* gp_map);
};

}  // namespace dua

#endif  // DUA_MUJOCO_UNIVERSE_H_
