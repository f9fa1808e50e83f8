// Pruned pairs, for every caller of the runtime (the plugin, Predictor, SpherePredictor): which of
// the pairs are held, chosen by the candidate grid (grid.cc) from every sphere's reach at a
// rebuild, and renewed for the spheres the escape check (reach.cc) finds outside their reach
// (docs/many-objects.md; docs/theory.md, Lemmas 6.4 and 6.5).
#ifndef DUA_MUJOCO_PRUNED_H_
#define DUA_MUJOCO_PRUNED_H_

#include <cstdint>
#include <string>
#include <vector>

#include "dua/dua.h"
#include "universe.h"

namespace dua {

// What the pruned pairs read of the model's tables, derived once and shared by every mjData.
struct DUA_API PrunedTables {
  int64_t nsphere = 0;
  int64_t stride = 0;                               // steps between rebuilds
  double horizon = 0.0;                             // the reach's horizon T, seconds
  double margin = 0.0;                              // the largest contact distance beyond the radii
  std::vector<double> radius, accel, delta, speed;  // (nsphere,) each
  std::vector<int64_t> body_start, body_spheres;    // the spheres of each body

  // From the "reach" table (nsphere rows: radius, accel, delta, speed) and the sphere records
  // (nsphere, 8). Returns an empty string, or what is wrong.
  std::string Build(const std::vector<double>& reach, const std::vector<double>& spheres,
                    int64_t nbody, double horizon_s, double margin_m, int64_t stride_steps);
};

// Each mjData's anchors and the grid's buffers.
struct DUA_API PrunedState {
  std::vector<double> anchor, speed0, reach;
  std::vector<int64_t> built;
  std::vector<int64_t> escapes;  // found by the latest step, renewed at the next
  int64_t built_at = 0;          // step of the latest rebuild
  int64_t broken = -1;           // free spheres: an escaped one whose state proves a violation
  // The grid's buffers (every call sizes them).
  std::vector<int32_t> start, sid, found, tmp;
  std::vector<double> sxyz, sr, work;
  std::vector<int64_t> cnt_a, cnt_b, held_out, cand;
  std::vector<uint8_t> is_held;

  void Allocate(const PrunedTables& t);
  dua_reach Reach(const PrunedTables& t);
  // Every sphere anchored at its state on a's frame, step `step`; ids receives the pairs to
  // hold, sorted, the universe learning the candidates it lacks. False if a state is not
  // finite or a centre is beyond 1e150 (nothing changed).
  bool Select(const PrunedTables& t, const LearnTables& learn, Universe* u, const dua_step_args& a,
              int64_t step, std::vector<int64_t>* ids);
  // The escaped spheres anchored anew at step `step`; ids receives the pairs their reach brings
  // in, sorted (learnt as by Select). False if a state is not finite.
  bool Renew(const PrunedTables& t, const LearnTables& learn, Universe* u, const dua_step_args& a,
             int64_t step, std::vector<int64_t>* ids);
  // After a step: the spheres of the flagged bodies that may have left their reach (free
  // spheres: before a step, every sphere; and `broken`).
  void FindEscapes(const PrunedTables& t, const dua_step_args& a, int64_t step);

 private:
  // The known pairs among candidates cand (k rows), learning the others first.
  void Known(const LearnTables& learn, Universe* u, int64_t k, std::vector<int64_t>* ids);
};

}  // namespace dua

#endif  // DUA_MUJOCO_PRUNED_H_
