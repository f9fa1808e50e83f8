// The poses a plan's knots read (docs/theory.md, section 8): the frames of the geoms its verdicts
// read, computed from a row of joint positions and mocap poses by the arithmetic of MuJoCo's own
// mj_kinematics, call for call (mju_normalize4, mju_mulMatVec3, mju_mulQuat, mju_rotVecQuat,
// mju_axisAngle2Quat's quaternion, mju_quat2Mat, in mj_kinematics1's and mj_local2Global's
// order), on the bodies that carry those geoms and their ancestors only, and without what no
// pose reads: the joints' Cartesian anchors and axes (a hinge's or ball's axis; a slide's anchor;
// the anchor of a joint at its body's origin, where mj_kinematics adds and takes off an exact
// zero), the inertial frames no kept geom sits at, the world body's frames, and every other geom,
// site, camera and light. A hinge's sine and cosine are the one departure: polynomials (within
// kSinCosError, where libmujoco calls sin and cos: half of a robot's knots' kinematics), so each
// pose lies within tolerance() of mj_kinematics' (a plan adds it to every deviation), and is
// mj_kinematics' bit for bit with the hinges exact (SetExactHinges; tests/test_knot_kinematics.py
// holds both on every bundled scene and every joint type). RunKnots computes four knots at once
// in AVX2 lanes (the same IEEE operations, in the order libmujoco's compiled helpers take them:
// no contraction, no reordering), and checks the lanes' bytes against this one-knot path on its
// first batch: where they differ it computes every knot one at a time (docs/theory.md, section
// 8).
#ifndef DUA_MUJOCO_KINEMATICS_H_
#define DUA_MUJOCO_KINEMATICS_H_

#include <mujoco/mujoco.h>

#include <cstdint>
#include <vector>

#include "dua/dua.h"
#include "lanes.h"

namespace dua {

// Whether body b is welded to the world outside mocap trees: no joint and no mocap pose on its
// path to the world, so that mj_kinematics places it from model constants alone (the same pose
// at every knot of a plan, and no plan holds it).
inline bool StillBody(const mjModel* m, int64_t b) {
  return m->body_weldid[b] == 0 && m->body_mocapid[m->body_rootid[b]] < 0;
}

// sin(x[i]) and cos(x[i]) to sn and cs by the knots' hinges' polynomials (|x| at most
// kHalfAngleMax: within kSinCosError of the exact values, docs/theory.md, section 8), four at a
// time in lanes or one at a time (the same bits); for tests.
constexpr double kHalfAngleMax = 64.0;
constexpr double kSinCosError = 0x1p-50;
DUA_API void HalfAngleSinCosOf(int64_t n, const double* x, double* sn, double* cs, bool lanes);

class DUA_API KnotKinematics {
 public:
  // The geoms read (geoms[c] the model's geom of slot c), of model m, which must outlive this.
  // Not for a model with flexes or sleeping enabled (mj_kinematics reads more there): callers
  // run mj_kinematics on those.
  KnotKinematics(const mjModel* m, const std::vector<int64_t>& geoms);
  KnotKinematics(const KnotKinematics&) = delete;  // (its lanes point into its own buffer)
  KnotKinematics& operator=(const KnotKinematics&) = delete;
  // One knot: qpos (nq), mocap_pos (nmocap x 3) and mocap_quat (nmocap x 4) as mj_kinematics
  // reads them from mjData; slot c's position to pos + 3 c, its rotation matrix to mat + 9 c.
  void Run(const double* qpos, const double* mocap_pos, const double* mocap_quat, double* pos,
           double* mat);
  // Slot s's pose when its body is still (StillBody, or the world): computed once, here, so
  // readable without a Run (the static guard, tables.h, reads it so).
  const double* still_pos(size_t s) const { return still_pos_.data() + 3 * s; }
  const double* still_mat(size_t s) const { return still_mat_.data() + 9 * s; }
  // n knots: knot k reads qpos[k], mocap_pos[k] and mocap_quat[k] and writes pos[k] and mat[k]
  // as Run does, bit for bit; four at a time in lanes (the last two or three together, a last
  // lone one by Run) while lanes are on and the self-check passed. The first batch in lanes is
  // also computed by Run: where a byte differs, lanes go off for good and Run's poses stand.
  void RunKnots(int64_t n, const double* const* qpos, const double* const* mocap_pos,
                const double* const* mocap_quat, double* const* pos, double* const* mat);
  // Readies the next knots' hinges for n knots of rows qpos (n, nq) and mocap_pos (nmocap_rows,
  // nmocap, 3): by the polynomials, or, where the rows' slides, free bodies and mocap bodies
  // reach past kWorldReach metres, by libmujoco's call. The tolerance is the same either way.
  void ReadyHinges(int64_t n, const double* qpos, int64_t nmocap_rows, const double* mocap_pos);
  // How far (metres) any point of a kept geom's box may lie from where mj_kinematics puts it,
  // and how far a kept frame's rotation may move a vector of the world: 0 where no kept body
  // has a hinge (the poses are mj_kinematics' bit for bit); else the model's bound of
  // docs/theory.md, section 8 ("The knots' hinges"), the same for every plan, the hinges taken
  // either way.
  double tolerance() const { return tolerance_; }
  // The bound's unit (relative rounding per kept body or hinge and metre), and the reach of the
  // world (metres) it allows for beyond the model's own lengths.
  static constexpr double kToleranceUnit = 0x1p-42;
  static constexpr double kWorldReach = 1000.0;
  // Every hinge by libmujoco's call (true) or by the polynomials (false); ReadyHinges sets it.
  void SetExactHinges(bool on) { exact_ = on; }
  // Test hooks: lanes off (every knot by Run) or on; a flipped bit in the lanes' first pose
  // (the fault the self-check must catch). lanes(): whether RunKnots computes in lanes.
  void SetLanes(bool on) { lanes_ = on; }
  void SetLaneFault(bool on) { fault_ = on; }
  bool lanes() const { return lanes_ && !failed_; }
  // The bodies computed (model ids, parents first) and their frames at the last Run, in that
  // order: (n, 3), (n, 4), (n, 9); for tests.
  const std::vector<int>& bodies() const { return body_; }
  const std::vector<double>& xpos() const { return xpos_; }
  const std::vector<double>& xquat() const { return xquat_; }
  const std::vector<double>& xmat() const { return xmat_; }

 private:
  // Kept body c's frame (its parent's computed) and, if a kept geom sits at it, its inertial
  // frame; slot s's geom pose from its body's frames into (pos, mat).
  void Frame(size_t c, const double* qpos, const double* mocap_pos, const double* mocap_quat);
  void GeomFrame(size_t s, double* pos, double* mat) const;
  // nact (2 to 4) knots in lanes; lanes past nact read knot 0's row and write nothing.
  void Lanes4(int nact, const double* const* qpos, const double* const* mocap_pos,
              const double* const* mocap_quat, double* const* pos, double* const* mat);
  void FrameLanes(size_t c, const double* const* qpos, const double* const* mocap_pos,
                  const double* const* mocap_quat);

  const mjModel* m_;
  std::vector<int> body_;    // model id of each kept body
  std::vector<int> parent_;  // index of its parent among the kept bodies, -1 for the world
  std::vector<uint8_t> still_anchor_;  // per joint of m: jnt_pos is +0 exactly
  std::vector<uint8_t> inertia_;       // per kept body: a kept geom reads its inertial frame
  std::vector<int> gbody_;             // per slot: its body's index among the kept
  std::vector<int64_t> geom_;          // per slot: the model's geom
  std::vector<double> xpos_, xquat_, xmat_, xipos_, ximat_;
  std::vector<int> move_, gmove_, gstill_;     // the kept bodies not still; the slots moving, still
  std::vector<double> still_pos_, still_mat_;  // per slot: a still geom's pose, computed once
  // The kept bodies' frames in lanes (lane k: knot k of a batch), as xpos_ ... ximat_, a still
  // body's in every lane: in lane_buf_, from its first 32-byte boundary (what AVX2's aligned
  // loads and stores need; a baseline build aligns Lanes to 16 only).
  std::vector<double> lane_buf_;
  Lanes *lxpos_ = nullptr, *lxquat_ = nullptr, *lxmat_ = nullptr, *lxipos_ = nullptr,
        *lximat_ = nullptr;
  bool lanes_ = true, checked_[2] = {false, false}, failed_ = false, fault_ = false, exact_ = false;
  // ReadyHinges': the kept bodies' joints by type and mocap ids; the tolerance (a constant).
  std::vector<int> hinge_, slide_, free_, mocap_;
  double tolerance_ = 0.0;
};

}  // namespace dua

#endif  // DUA_MUJOCO_KINEMATICS_H_
