// KnotKinematics (kinematics.h): mj_kinematics' arithmetic on the poses a plan reads.
#include "kinematics.h"

#include <algorithm>
#include <cmath>

namespace dua {

namespace {

// A frame (pos, quat) given in body b's frame, to the world, as mj_local2Global computes it for
// sameframe sf: the position through the body's rotation matrix, the orientation through its
// quaternion (the product's matrix), or copied where sf says the frames coincide. For a geom at
// its body's inertial frame (mjSAMEFRAME_INERTIA*), (ipos, imat) is that frame.
void Local2Global(const double* bpos, const double* bquat, const double* bmat, const double* ipos,
                  const double* imat, const double* pos, const double* quat, int sf, double* xpos,
                  double* xmat) {
  switch (sf) {
    case mjSAMEFRAME_NONE:
    case mjSAMEFRAME_BODYROT:
    case mjSAMEFRAME_INERTIAROT:
      mju_mulMatVec3(xpos, bmat, pos);
      for (int k = 0; k < 3; ++k) xpos[k] += bpos[k];
      break;
    case mjSAMEFRAME_BODY:
      for (int k = 0; k < 3; ++k) xpos[k] = bpos[k];
      break;
    default:  // mjSAMEFRAME_INERTIA
      for (int k = 0; k < 3; ++k) xpos[k] = ipos[k];
      break;
  }
  switch (sf) {
    case mjSAMEFRAME_NONE: {
      double tmp[4];
      mju_mulQuat(tmp, bquat, quat);
      mju_quat2Mat(xmat, tmp);
      break;
    }
    case mjSAMEFRAME_BODY:
    case mjSAMEFRAME_BODYROT:
      for (int k = 0; k < 9; ++k) xmat[k] = bmat[k];  // (copy_n called memcpy here)
      break;
    default:  // mjSAMEFRAME_INERTIA, mjSAMEFRAME_INERTIAROT
      for (int k = 0; k < 9; ++k) xmat[k] = imat[k];
      break;
  }
}

}  // namespace

KnotKinematics::KnotKinematics(const mjModel* m, const std::vector<int64_t>& geoms) : m_(m) {
  const int nbody = m->nbody;
  std::vector<uint8_t> keep(nbody, 0);
  for (const int64_t g : geoms) keep[m->geom_bodyid[g]] = 1;
  for (int b = nbody - 1; b > 0; --b) keep[m->body_parentid[b]] |= keep[b];
  std::vector<int> id(nbody, -1);  // a kept body's index
  for (int b = 1; b < nbody; ++b) {
    if (!keep[b]) continue;
    id[b] = static_cast<int>(body_.size());
    body_.push_back(b);
    parent_.push_back(id[m->body_parentid[b]]);  // -1: the world
  }
  still_anchor_.assign(m->njnt, 0);
  for (int j = 0; j < m->njnt; ++j) {
    const double* p = m->jnt_pos + 3 * j;
    // +0 exactly (not -0): where mj_kinematics' anchor and its removal add and take off +0.
    still_anchor_[j] = !std::signbit(p[0]) && !std::signbit(p[1]) && !std::signbit(p[2]) &&
                       p[0] == 0.0 && p[1] == 0.0 && p[2] == 0.0;
  }
  const size_t n = body_.size();
  inertia_.assign(n, 0);
  for (const int64_t g : geoms) {
    const int b = m->geom_bodyid[g];
    const int sf = m->geom_sameframe[g];
    gbody_.push_back(b ? id[b] : -1);
    geom_.push_back(g);
    if (b && (sf == mjSAMEFRAME_INERTIA || sf == mjSAMEFRAME_INERTIAROT)) inertia_[id[b]] = 1;
  }
  xpos_.assign(3 * n, 0.0), xquat_.assign(4 * n, 0.0), xmat_.assign(9 * n, 0.0);
  xipos_.assign(3 * n, 0.0), ximat_.assign(9 * n, 0.0);
  // Bodies welded to the world (outside mocap trees: no joint and no mocap pose on their path to
  // it) read nor qpos nor a mocap pose: their frames, their inertial frames and their geoms'
  // poses are the same at every knot, computed here once by the same calls (per plan they were
  // a third of tiago's knots).
  for (size_t c = 0; c < n; ++c) {
    if (StillBody(m, body_[c])) {
      Frame(c, nullptr, nullptr, nullptr);
    } else {
      move_.push_back(static_cast<int>(c));
    }
  }
  still_pos_.assign(3 * geom_.size(), 0.0), still_mat_.assign(9 * geom_.size(), 0.0);
  for (size_t s = 0; s < geom_.size(); ++s) {
    const int c = gbody_[s];
    if (c >= 0 && !StillBody(m, body_[c])) {
      gmove_.push_back(static_cast<int>(s));
    } else {
      gstill_.push_back(static_cast<int>(s));
      GeomFrame(s, still_pos_.data() + 3 * s, still_mat_.data() + 9 * s);
    }
  }
}

void KnotKinematics::Frame(size_t c, const double* qpos, const double* mocap_pos,
                           const double* mocap_quat) {
  const mjModel* m = m_;
  // mj_kinematics1's body loop, on its arithmetic, for kept body c (its parent done already).
  const int i = body_[c], pid = parent_[c];
  double* xpos = xpos_.data() + 3 * c;
  double* xquat = xquat_.data() + 4 * c;
  const int jntadr = m->body_jntadr[i], jntnum = m->body_jntnum[i];
  if (jntnum == 1 && m->jnt_type[jntadr] == mjJNT_FREE) {
    const int qadr = m->jnt_qposadr[jntadr];
    std::copy_n(qpos + qadr, 3, xpos);
    std::copy_n(qpos + qadr + 3, 4, xquat);
    mju_normalize4(xquat);
  } else {
    const double *bodypos, *bodyquat;
    double quat[4];
    const int mocap = m->body_mocapid[i];
    if (mocap >= 0) {
      bodypos = mocap_pos + 3 * mocap;
      std::copy_n(mocap_quat + 4 * mocap, 4, quat);
      mju_normalize4(quat);
      bodyquat = quat;
    } else {
      bodypos = m->body_pos + 3 * i;
      bodyquat = m->body_quat + 4 * i;
    }
    if (pid >= 0) {
      mju_mulMatVec3(xpos, xmat_.data() + 9 * pid, bodypos);
      for (int k = 0; k < 3; ++k) xpos[k] += xpos_[3 * pid + k];
      mju_mulQuat(xquat, xquat_.data() + 4 * pid, bodyquat);
    } else {
      std::copy_n(bodypos, 3, xpos);
      std::copy_n(bodyquat, 4, xquat);
    }
    for (int j = 0; j < jntnum; ++j) {
      const int jid = jntadr + j;
      const int qadr = m->jnt_qposadr[jid];
      const int jtype = m->jnt_type[jid];
      if (jtype == mjJNT_SLIDE) {
        // The axis moves the body; the anchor is read by nothing here.
        double xaxis[3];
        mju_rotVecQuat(xaxis, m->jnt_axis + 3 * jid, xquat);
        const double q = qpos[qadr] - m->qpos0[qadr];
        for (int k = 0; k < 3; ++k) xpos[k] += xaxis[k] * q;
        continue;
      }
      // Ball or hinge (the compiler makes no other jointed body but a free one, above).
      double qloc[4];
      if (jtype == mjJNT_BALL) {
        std::copy_n(qpos + qadr, 4, qloc);
        mju_normalize4(qloc);
      } else {
        mju_axisAngle2Quat(qloc, m->jnt_axis + 3 * jid, qpos[qadr] - m->qpos0[qadr]);
      }
      if (still_anchor_[jid]) {
        // The anchor is xpos + 0 and the rotation's offset +0: xpos becomes 0 + xpos (which
        // differs from xpos only in the sign of a zero).
        mju_mulQuat(xquat, xquat, qloc);
        for (int k = 0; k < 3; ++k) xpos[k] = 0.0 + xpos[k];
        continue;
      }
      double xanchor[3], vec[3];
      mju_rotVecQuat(xanchor, m->jnt_pos + 3 * jid, xquat);
      for (int k = 0; k < 3; ++k) xanchor[k] += xpos[k];
      mju_mulQuat(xquat, xquat, qloc);
      mju_rotVecQuat(vec, m->jnt_pos + 3 * jid, xquat);
      for (int k = 0; k < 3; ++k) xpos[k] = xanchor[k] - vec[k];
    }
  }
  mju_normalize4(xquat);
  mju_quat2Mat(xmat_.data() + 9 * c, xquat);
  // mj_kinematics2's inertial frame, where a kept geom sits at it.
  if (inertia_[c]) {
    Local2Global(xpos, xquat, xmat_.data() + 9 * c, nullptr, nullptr, m->body_ipos + 3 * i,
                 m->body_iquat + 4 * i, m->body_sameframe[i], xipos_.data() + 3 * c,
                 ximat_.data() + 9 * c);
  }
}

void KnotKinematics::GeomFrame(size_t s, double* pos, double* mat) const {
  static const double kZero[3] = {0.0, 0.0, 0.0}, kUnit[4] = {1.0, 0.0, 0.0, 0.0},
                      kEye[9] = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
  const int64_t g = geom_[s];
  const int c = gbody_[s];
  // The world body's frames, as mj_kinematics1 sets them: the origin, unrotated.
  const double* bpos = c >= 0 ? xpos_.data() + 3 * c : kZero;
  const double* bquat = c >= 0 ? xquat_.data() + 4 * c : kUnit;
  const double* bmat = c >= 0 ? xmat_.data() + 9 * c : kEye;
  const double* ipos = c >= 0 ? xipos_.data() + 3 * c : kZero;
  const double* imat = c >= 0 ? ximat_.data() + 9 * c : kEye;
  Local2Global(bpos, bquat, bmat, ipos, imat, m_->geom_pos + 3 * g, m_->geom_quat + 4 * g,
               m_->geom_sameframe[g], pos, mat);
}

void KnotKinematics::Run(const double* qpos, const double* mocap_pos, const double* mocap_quat,
                         double* pos, double* mat) {
  // The moving bodies kept, parents first (a body's inertial frame with it: mj_kinematics2
  // computes it from the same body frame), then the moving geoms; the still ones' poses copied.
  for (const int c : move_) Frame(static_cast<size_t>(c), qpos, mocap_pos, mocap_quat);
  for (const int s : gmove_) GeomFrame(static_cast<size_t>(s), pos + 3 * s, mat + 9 * s);
  for (const int s : gstill_) {
    const double* p = still_pos_.data() + 3 * s;
    const double* r = still_mat_.data() + 9 * s;
    for (int e = 0; e < 3; ++e) pos[3 * s + e] = p[e];
    for (int e = 0; e < 9; ++e) mat[9 * s + e] = r[e];
  }
}

}  // namespace dua
