// Velocities of mocap bodies, which mjData does not give: one state for the runtime (runtime.h)
// and for Python's trackers (dua_mujoco/build/mocap.py), over the kernel dua_difference_poses.
#ifndef DUA_MUJOCO_MOCAP_H_
#define DUA_MUJOCO_MOCAP_H_

#include <mujoco/mujoco.h>

#include <cstdint>
#include <vector>

#include "dua/dua.h"

namespace dua {

// The mocap bodies of a model, by mocap id: their poses at the latest record, their velocities
// (backward differences, or the user's), and the twists [angular; linear] the kinematics kernel
// adds to every point of their trees (dua_frame::root_twist, (nbody, 6), zero elsewhere).
struct DUA_API Mocap {
  explicit Mocap(const mjModel* m);  // m null: none (free spheres)

  // A new trajectory starts at d: its poses recorded, differenced velocities zero until the next
  // Difference, given ones kept.
  void Start(const mjData* d);
  // Velocities over the `elapsed` seconds since the last record (given ones kept), d's recorded.
  void Difference(const mjData* d, double elapsed);
  // A tracker's update: the first records (Start), a later one differences when time advanced
  // since the last record and keeps the velocities otherwise.
  void Update(const mjData* d);
  // Forget the poses (the next Update starts again); differenced velocities zero.
  void Forget();
  // A velocity given for mocap body i (world frame) until Clear(i); a Start keeps it.
  void Set(int64_t i, const double lin[3], const double ang[3]);
  void Clear(int64_t i) { user[i] = 0; }

  std::vector<int64_t> bodies;  // body id of each mocap id
  std::vector<double> pos, quat, linear, angular, twist;
  std::vector<uint8_t> user;  // 1: the velocity is the user's
  int64_t updates = 0;        // records since the last Start (the Start's included)
  double time = 0.0;          // d->time of the latest record

 private:
  void WriteTwist();
};

// The instant an MjData describes, as the kinematics kernel reads it (root_twist: Mocap::twist).
inline dua_frame FrameOf(const mjData* d, const double* root_twist) {
  return {d->geom_xpos, d->geom_xmat, d->cvel, d->subtree_com, root_twist, d->xpos};
}

}  // namespace dua

#endif  // DUA_MUJOCO_MOCAP_H_
