// The shield's default failsafe (docs/shield.md): a brake to rest within the actuators' limits,
// for any model whose robot actuators are affine in this step's control. Each physics step it
// asks the robot's DOFs for the accelerations a = (target - qvel) / T (target 0: a brake; T one
// timestep by default, the fastest stop the limits allow), gravity and every bias force held:
//
//     tau = K a + qfrc_bias - qfrc_passive,
//
// K the DOFs' inertia as the integrator sees it (M, plus h times the damping it treats
// implicitly), clipped to the joints' actuatorfrcrange; the actuator forces f are the
// box-bounded least squares solution of moment^T f = tau in the metric K^-1 (the acceleration
// error's kinetic energy: MuJoCo's mju_boxQP on f^T H f / 2 + g^T f, H = moment K^-1 moment^T,
// g = -moment K^-1 tau), each f within what its control range and force range allow, and each
// control follows from the actuator's affine law f = gain ctrl + bias. Contact forces are not
// foreseen: the shield rolls the brake out with MuJoCo, which has them.
//
// tests/reference_brake.py is the slow numpy reference the brake is held to.
#ifndef DUA_MUJOCO_BRAKE_H_
#define DUA_MUJOCO_BRAKE_H_

#include <mujoco/mujoco.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "dua/dua.h"

namespace dua {

class DUA_API Brake {
 public:
  // The brake of actuators `actuators` (ids) of m, time constant `time_constant` seconds (<= 0:
  // one timestep). Null with *error naming every actuator it cannot take (dyntype none,
  // gaintype fixed or affine, biastype none or affine, no plugin: motor, position and velocity
  // without timeconst, general of those types), or the bad argument.
  static std::unique_ptr<Brake> Make(const mjModel* m, const std::vector<int>& actuators,
                                     double time_constant, std::string* error);

  // What Compute reads at d's state (d->qpos, qvel, ctrl, act, mocap): the kinematics, the
  // inertia, the transmission, the velocities, the passive and bias forces. mj_step1 leaves the
  // same values, computed by the same functions (so a rollout and a run brake alike).
  static void Prepare(const mjModel* m, mjData* d);

  // ctrl (nu): d->ctrl with the robot's actuators set to drive its DOFs toward the joint
  // velocities target (dofs().size(), in that order; null: 0, a brake), read at d's state as
  // Prepare or mj_step1 left it.
  void Compute(const mjModel* m, const mjData* d, const double* target, double* ctrl);

  // The robot: its actuators, the DOFs of the kinematic trees they move (the brake's), the
  // bodies of those trees.
  const std::vector<int>& actuators() const { return acts_; }
  const std::vector<int>& dofs() const { return dofs_; }
  const std::vector<int>& bodies() const { return bodies_; }
  double time_constant() const { return tc_; }

 private:
  Brake() = default;
  std::vector<int> acts_, dofs_, bodies_, dof_index_;
  double tc_ = 0.0;
  int implicit_ = 0;  // 0 none, 1 the DOFs' damping (Euler), 2 actuators' too (implicit*)
  std::vector<double> tau_lo_, tau_hi_;
  // Workspace.
  std::vector<double> full_m_, all_moment_, k_, kinv_b_, h_, g_, force_, lo_, hi_, r_;
  std::vector<double> gain_, bias_, clo_, chi_, tau_;
  std::vector<double> qp_h_, g_free_, lo_free_, hi_free_, x_free_;  // the free forces' box QP
  std::vector<int> free_;
  std::vector<uint8_t> moves_;  // actuators with a nonzero moment arm on a braked DOF, this step
};

}  // namespace dua

#endif  // DUA_MUJOCO_BRAKE_H_
