// The plugin's pruned pairs: which of the model's pairs are held, chosen by the candidate grid
// (grid.cc) from every sphere's reach at a rebuild, and renewed for the spheres the escape check
// (reach.cc) finds outside their reach, as dua_mujoco/mj/pruning.py's HeldPairs does for the
// Python predictor (docs/many-objects.md).
#ifndef DUA_MUJOCO_PRUNED_H_
#define DUA_MUJOCO_PRUNED_H_

#include <cstdint>
#include <string>
#include <vector>

#include "dua/dua.h"

namespace dua {

// What the pruned pairs read of the model's tables, derived once and shared by every mjData.
struct PrunedTables {
  int64_t nsphere = 0;
  int64_t stride = 0;                               // steps between rebuilds
  double horizon = 0.0;                             // the reach's horizon T, seconds
  double margin = 0.0;                              // the largest contact distance beyond the radii
  std::vector<double> radius, accel, delta, speed;  // (nsphere,) each
  std::vector<int64_t> body_start, body_spheres;    // the spheres of each body
  std::vector<int64_t> codes, code_ids;  // sphere-sphere pairs: min * nsphere + max, sorted
  std::vector<int64_t> always;           // pairs against a plane or a static shape: held always

  // From the "reach" table (nsphere rows: radius, accel, delta, speed), the sphere records
  // (nsphere, 8) and the pair records (npair, 8). Returns an empty string, or what is wrong.
  std::string Build(const std::vector<double>& reach, const std::vector<double>& spheres,
                    const std::vector<double>& pairs, int64_t nbody, double horizon_s,
                    double margin_m, int64_t stride_steps);
  // The pairs among candidate sphere pairs cand[0:2n] (rows i < j), into ids (appended).
  void Lookup(const int64_t* cand, int64_t n, std::vector<int64_t>* ids) const;
};

// Each mjData's anchors and the grid's buffers.
struct PrunedState {
  std::vector<double> anchor, speed0, reach;
  std::vector<int64_t> built;
  std::vector<int64_t> escapes;  // found by the latest step, renewed at the next
  int64_t built_at = 0;          // step of the latest rebuild
  // The grid's buffers (every call sizes them).
  std::vector<int32_t> start, sid, found, tmp;
  std::vector<double> sxyz, sr, work, state;
  std::vector<int64_t> cnt_a, cnt_b, held_out, cand;
  std::vector<uint8_t> is_held;

  void Allocate(const PrunedTables& t);
  dua_reach Reach(const PrunedTables& t);
  // Every sphere anchored at its state on a's frame, step `step`; ids receives the pairs to
  // hold, sorted. False if a state is not finite (nothing changed).
  bool Select(const PrunedTables& t, const dua_step_args& a, int64_t step,
              std::vector<int64_t>* ids);
  // The escaped spheres anchored anew at step `step`; ids receives the pairs their reach brings
  // in, sorted. False if a state is not finite.
  bool Renew(const PrunedTables& t, const dua_step_args& a, int64_t step,
             std::vector<int64_t>* ids);
  // After a step: the spheres of the flagged bodies that may have left their reach.
  void FindEscapes(const PrunedTables& t, const dua_step_args& a, int64_t step);
};

}  // namespace dua

#endif  // DUA_MUJOCO_PRUNED_H_
