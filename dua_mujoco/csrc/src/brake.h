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

// An evasive failsafe for a robot with two planar slide DOFs (a mobile base; docs/shield.md, "An
// evasive failsafe"): each step, with s = max(|vx|, |vy|) its planar velocity's larger axis
// speed, the brake driving the planar velocity toward gain * s * u (u away from the obstacles and
// the room's walls, each pushing by the inverse square of its clearance, its larger component
// 1) and every other braked DOF toward 0, as fast as the actuators allow; `sideways`: u across the
// planar velocity instead, to the side away from them. The axis with the larger speed still
// brakes at its limit (gain < 1), the other moves the base away meanwhile; at most `still` on
// both axes it is the brake. It reads the obstacles' positions (d->xpos) at its data's
// state: the shield calls it on the rollout's data and, in the run, on the rollout's view
// (shield.h), so the run repeats the rollout.
class DUA_API Evade {
 public:
  // brake: the robot's brake (moved in); x, y: the planar slide DOFs (among the brake's DOFs);
  // obstacles: body ids, radius: their radii (m, the clearance counts from them); room: xlo,
  // xhi, ylo, yhi the walls' inner faces (an empty room: none); gain in [0, 1); still > 0;
  // sideways: steer across the velocity. Null with *error naming a bad value.
  static std::unique_ptr<Evade> Make(const mjModel* m, std::unique_ptr<Brake> brake, int x, int y,
                                     const std::vector<int>& obstacles,
                                     const std::vector<double>& radius,
                                     const std::vector<double>& room, double gain, double still,
                                     bool sideways, std::string* error);

  // ctrl (nu) at d's state (Brake::Prepare or mj_step1 computed it, the obstacles' xpos too).
  void Compute(const mjModel* m, const mjData* d, double* ctrl);
  // The direction away from the obstacles and walls from (x, y), d's obstacle positions.
  void Away(const mjData* d, double x, double y, double* ux, double* uy) const;

  Brake& brake() { return *brake_; }
  const Brake& brake() const { return *brake_; }

 private:
  Evade() = default;
  std::unique_ptr<Brake> brake_;
  int x_ = 0, y_ = 0, xq_ = 0, yq_ = 0, xi_ = 0, yi_ = 0;  // DOFs, qpos addresses, brake slots
  std::vector<int> obstacles_;
  std::vector<double> radius_, room_, target_;
  double gain_ = 0.0, still_ = 0.0;
  bool sideways_ = false;
};

}  // namespace dua

#endif  // DUA_MUJOCO_BRAKE_H_
