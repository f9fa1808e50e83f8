// Flight plans (docs/theory.md, section 8): the motion the caller expects over the coming physics
// steps, as joint positions at each of them (an MPC's or a planner's trajectory, or a rollout of
// known controls), and a bound on how far every point of each body may stray from where the plan
// puts it. While a plan covers a step and a body has stayed within its deviation, a pair's tau is
// the time to the first knot at which the plan's geometry, less both bodies' deviations, may
// touch: no acceleration bound enters, so the verdict stays tight over any horizon the plan
// covers. A body found farther than its deviation, and every pair past the plan's end, falls
// back to the motion bounds.
#ifndef DUA_MUJOCO_PLAN_H_
#define DUA_MUJOCO_PLAN_H_

#include <mujoco/mujoco.h>

#include <cstdint>
#include <string>
#include <vector>

#include "dua/dua.h"

namespace dua {

class Plan {
 public:
  // The plan of qpos (n, nq), row j the state at time start + j h, every geom's pose computed
  // by mj_kinematics on scratch (an mjData of m whose mocap poses are the run's), and dev (n,
  // nbody): a bound on the distance of every point of each body's geoms from its planned
  // position at each knot. Returns an error message naming the bad input, or "".
  std::string Build(const mjModel* m, mjData* scratch, const double* qpos, int64_t n,
                    const double* dev, double start, double h);

  // The knot at `time` (-1: not one of the plan's, within a millionth of a step).
  int64_t KnotOf(double time) const;
  // Appends to broken the bodies with a geom farther from its planned pose at knot k than the
  // body's deviation (a bound on every point's distance: |dp| + |dR|_F r, r the geom's bounding
  // radius about its origin; a plane off its planned pose is unbounded).
  void Check(const mjModel* m, const mjData* d, int64_t k, std::vector<int64_t>* broken) const;

  int64_t nknot() const { return nknot_; }
  double start() const { return start_; }
  double h() const { return h_; }
  const double* pos(int64_t k) const { return pos_.data() + 3 * ngeom_ * k; }
  const double* mat(int64_t k) const { return mat_.data() + 9 * ngeom_ * k; }
  // How far any point of geom g may have moved along the plan from knot 0 to knot k (a prefix
  // sum of each step's bound; +inf once a plane geom moves).
  double sweep(int64_t k, int64_t g) const { return sweep_[ngeom_ * k + g]; }
  double dev(int64_t k, int64_t b) const { return dev_[nbody_ * k + b]; }

 private:
  int64_t nknot_ = 0, ngeom_ = 0, nbody_ = 0;
  double start_ = 0.0, h_ = 0.0;
  std::vector<double> pos_, mat_, sweep_, dev_;
};

// tau of held pairs ids[0:count] under a.plan where it covers them (both bodies within their
// deviation): out[k] replaced and a.plan.planned[k] set; elsewhere planned[k] = 0 and out[k]
// kept. MuJoCo's distance queries at knots are counted in a.plan.queries.
void PlanPass(dua_step_args& a, const int64_t* ids, int64_t count, double* out);

}  // namespace dua

#endif  // DUA_MUJOCO_PLAN_H_
