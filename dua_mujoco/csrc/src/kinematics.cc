// KnotKinematics (kinematics.h): mj_kinematics' arithmetic on the poses a plan reads.
#include "kinematics.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <type_traits>

namespace dua {

namespace {

// libmujoco's helpers on four knots in lanes. Each lane takes the IEEE operations the wheel's
// compiled helper takes, in its order (read from its machine code: mju_mulQuat adds its four
// products in pairs, (a0 b0 - a1 b1) + (a2 b2 + a3 b3) for the first, its signs as negated
// factors; mju_quat2Mat's diagonal and mju_normalize4's sum of squares are pairwise too;
// mju_mulMatVec3 and mju_rotVecQuat add left to right as written), so each lane's bits are the
// helper's. Their branches on the data become selects; the ones on model constants stay.
DUA_INLINE void MulMatVec3L(Lanes* res, const Lanes* mat, const Lanes* vec) {
  for (int i = 0; i < 3; ++i) {
    res[i] = mat[3 * i] * vec[0] + mat[3 * i + 1] * vec[1] + mat[3 * i + 2] * vec[2];
  }
}

DUA_INLINE void MulQuatL(Lanes* res, const Lanes* a, const Lanes* b) {
  const Lanes na2 = -a[2], na3 = -a[3];
  const Lanes r0 = (a[0] * b[0] - a[1] * b[1]) + (na2 * b[2] + na3 * b[3]);
  const Lanes r1 = (a[0] * b[1] + a[1] * b[0]) + (a[2] * b[3] + na3 * b[2]);
  const Lanes r2 = (a[0] * b[2] - a[1] * b[3]) + (a[2] * b[0] + a[3] * b[1]);
  const Lanes r3 = (a[0] * b[3] + a[1] * b[2]) + (na2 * b[1] + a[3] * b[0]);
  res[0] = r0, res[1] = r1, res[2] = r2, res[3] = r3;
}

DUA_INLINE LaneMask UnitQuat(const Lanes* q) {
  return (q[0] == 1.0) & (q[1] == 0.0) & (q[2] == 0.0) & (q[3] == 0.0);
}

// vec a model constant (the zero test a branch, as in mju_rotVecQuat).
DUA_INLINE void RotVecQuatL(Lanes* res, const double* vec, const Lanes* q) {
  if (vec[0] == 0 && vec[1] == 0 && vec[2] == 0) {
    res[0] = res[1] = res[2] = Splat(0.0);
    return;
  }
  const Lanes v0 = Splat(vec[0]), v1 = Splat(vec[1]), v2 = Splat(vec[2]);
  const Lanes t0 = q[0] * v0 + q[2] * v2 - q[3] * v1;
  const Lanes t1 = q[0] * v1 + q[3] * v0 - q[1] * v2;
  const Lanes t2 = q[0] * v2 + q[1] * v1 - q[2] * v0;
  const Lanes u0 = q[2] * t2 - q[3] * t1, u1 = q[3] * t0 - q[1] * t2, u2 = q[1] * t1 - q[2] * t0;
  const LaneMask unit = UnitQuat(q);
  res[0] = Select(unit, v0, v0 + (u0 + u0));
  res[1] = Select(unit, v1, v1 + (u1 + u1));
  res[2] = Select(unit, v2, v2 + (u2 + u2));
}

DUA_INLINE void Quat2MatL(Lanes* res, const Lanes* q) {
  const Lanes q00 = q[0] * q[0], q11 = q[1] * q[1], q22 = q[2] * q[2], q33 = q[3] * q[3];
  const Lanes nq0 = -q[0];
  const Lanes o1 = q[1] * q[2] + nq0 * q[3], o2 = q[1] * q[3] + q[0] * q[2];
  const Lanes o3 = q[1] * q[2] + q[0] * q[3], o5 = q[3] * q[2] + nq0 * q[1];
  const Lanes o6 = q[3] * q[1] + nq0 * q[2], o7 = q[3] * q[2] + q[0] * q[1];
  const Lanes d[9] = {(q00 - q22) + (q11 - q33), o1 + o1, o2 + o2, o3 + o3,
                      (q00 + q22) - (q11 + q33), o5 + o5, o6 + o6, o7 + o7,
                      (q00 - q22) - (q11 - q33)};
  const LaneMask unit = UnitQuat(q);
  for (int k = 0; k < 9; ++k) res[k] = Select(unit, Splat(k % 4 == 0 ? 1.0 : 0.0), d[k]);
}

DUA_INLINE void Normalize4L(Lanes* q) {
  const Lanes norm = Sqrt((q[0] * q[0] + q[1] * q[1]) + (q[2] * q[2] + q[3] * q[3]));
  const LaneMask small = norm < mjMINVAL;
  const LaneMask scale = Abs(norm + -1.0) > mjMINVAL;
  const Lanes inv = 1.0 / norm;
  for (int k = 0; k < 4; ++k) {
    q[k] = Select(small, Splat(k == 0 ? 1.0 : 0.0), Select(scale, q[k] * inv, q[k]));
  }
}

// A frame (pos, quat) given in body b's frame, to the world, as mj_local2Global computes it for
// sameframe sf: the position through the body's rotation matrix, the orientation through its
// quaternion (the product's matrix), or copied where sf says the frames coincide. For a geom at
// its body's inertial frame (mjSAMEFRAME_INERTIA*), (ipos, imat) is that frame. One knot (T a
// double: MuJoCo's exported helpers) or four in lanes; (pos, quat) model constants.
inline void MulMatVec3(double* r, const double* a, const double* v) { mju_mulMatVec3(r, a, v); }
DUA_INLINE void MulMatVec3(Lanes* r, const Lanes* a, const Lanes* v) { MulMatVec3L(r, a, v); }
inline void MulQuat(double* r, const double* a, const double* b) { mju_mulQuat(r, a, b); }
DUA_INLINE void MulQuat(Lanes* r, const Lanes* a, const Lanes* b) { MulQuatL(r, a, b); }
inline void Quat2Mat(double* r, const double* q) { mju_quat2Mat(r, q); }
DUA_INLINE void Quat2Mat(Lanes* r, const Lanes* q) { Quat2MatL(r, q); }
template <class T>
DUA_INLINE T Broadcast(double v) {
  if constexpr (std::is_same_v<T, double>) {
    return v;
  } else {
    return Splat(v);
  }
}

template <class T>
DUA_INLINE void Local2Global(const T* bpos, const T* bquat, const T* bmat, const T* ipos,
                             const T* imat, const double* pos, const double* quat, int sf, T* xpos,
                             T* xmat) {
  switch (sf) {
    case mjSAMEFRAME_NONE:
    case mjSAMEFRAME_BODYROT:
    case mjSAMEFRAME_INERTIAROT: {
      const T p[3] = {Broadcast<T>(pos[0]), Broadcast<T>(pos[1]), Broadcast<T>(pos[2])};
      MulMatVec3(xpos, bmat, p);
      for (int k = 0; k < 3; ++k) xpos[k] += bpos[k];
      break;
    }
    case mjSAMEFRAME_BODY:
      for (int k = 0; k < 3; ++k) xpos[k] = bpos[k];
      break;
    default:  // mjSAMEFRAME_INERTIA
      for (int k = 0; k < 3; ++k) xpos[k] = ipos[k];
      break;
  }
  switch (sf) {
    case mjSAMEFRAME_NONE: {
      const T q[4] = {Broadcast<T>(quat[0]), Broadcast<T>(quat[1]), Broadcast<T>(quat[2]),
                      Broadcast<T>(quat[3])};
      T tmp[4];
      MulQuat(tmp, bquat, q);
      Quat2Mat(xmat, tmp);
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

// A hinge's quaternion (cos(a/2), axis sin(a/2)) at angle a, as mju_axisAngle2Quat gives it up
// to the sine's and cosine's error: both from one reduction and two polynomials (no call; four
// lanes at a time), each within kSinCosError of the exact value where |a/2| <= kHalfAngleMax
// (docs/theory.md, section 8, "The knots' hinges"), and libmujoco's own call past it. At a = 0
// (a hinge at qpos0) it is mju_axisAngle2Quat's (1, 0, 0, 0), bit for bit. What a knot's pose
// can then lie from mj_kinematics' is bounded by KnotKinematics::tolerance and added to every
// deviation a plan built on these knots declares.
constexpr double kPio2Hi = 0x1.921fb544p0;           // pi/2's first 33 bits (k kPio2Hi exact)
constexpr double kPio2Lo = 0x1.0b4611a626331p-34;    // pi/2 - kPio2Hi, rounded
constexpr double kTwoOverPi = 0x1.45f306dc9c883p-1;  // 2/pi, rounded
constexpr double kRoundMagic = 0x1.8p52;             // x + it - it: x rounded to an integer
// 1/n!, Taylor's coefficients from the sine's r^3 and the cosine's r^4 on (rounded once).
constexpr double kSinTaylor[7] = {
    -1.0 / 6,        1.0 / 120,        -1.0 / 5040,           1.0 / 362880,
    -1.0 / 39916800, 1.0 / 6227020800, -1.0 / 1307674368000.0};
constexpr double kCosTaylor[7] = {
    1.0 / 24,        -1.0 / 720,           1.0 / 40320,           -1.0 / 3628800,
    1.0 / 479001600, -1.0 / 87178291200.0, 1.0 / 20922789888000.0};

template <class T>
DUA_INLINE void HalfAngleSinCos(T x, T* sn, T* cs) {
  // x = k pi/2 + r, |r| <= pi/4 (and a rounding): k exactly from the sum's low bits.
  const T t = x * kTwoOverPi + kRoundMagic;
  const T k = t - kRoundMagic;
  const T r = (x - k * kPio2Hi) - k * kPio2Lo;
  const T z = r * r;
  // Taylor's terms to r^15 and r^16 (Horner's, the leading terms added last): the first left
  // out is below 5e-17 on |r| <= pi/4 + 3e-14.
  T ps = Broadcast<T>(kSinTaylor[6]), pc = Broadcast<T>(kCosTaylor[6]);
  for (int i = 5; i >= 0; --i) ps = kSinTaylor[i] + z * ps, pc = kCosTaylor[i] + z * pc;
  ps = z * ps;
  pc = z * z * pc;
  const T s = r + r * ps;
  const T c = (1.0 - 0.5 * z) + pc;
  // The quadrant k mod 4 (t's last two bits, the magic's being 0): sin x is s, c, -s, -c.
  MaskOf<T> odd, sneg, cneg;
  if constexpr (std::is_same_v<T, double>) {
    int64_t q;
    std::memcpy(&q, &t, sizeof q);
    odd = (q & 1) != 0, sneg = (q & 2) != 0, cneg = ((q + 1) & 2) != 0;
  } else {
    const LaneMask q = (LaneMask)t, zero{};
    odd = (q & 1) != zero, sneg = (q & 2) != zero, cneg = ((q + 1) & 2) != zero;
  }
  const T sx = Select(odd, c, s), cx = Select(odd, s, c);
  *sn = Select(sneg, -sx, sx);
  *cs = Select(cneg, -cx, cx);
}

// qloc = the hinge quaternion of axis (a model constant) at angle a (one knot, or four in lanes).
template <class T>
DUA_INLINE void HingeQuat(T* qloc, const double* axis, T a) {
  const T x = a * 0.5;
  T sn, cs;
  HalfAngleSinCos(x, &sn, &cs);
  // mju_axisAngle2Quat's zero angle: (1, 0, 0, 0) with +0, whatever the axis' signs.
  const MaskOf<T> zero = a == 0.0;
  qloc[0] = Select(zero, Broadcast<T>(1.0), cs);
  for (int k = 0; k < 3; ++k) qloc[k + 1] = Select(zero, Broadcast<T>(0.0), sn * axis[k]);
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
  // The tolerance's model constants and ReadyHinges' inputs: the kept bodies' joints by type,
  // their mocap bodies, and every length a kept frame adds on its way from the world to a moving
  // geom's farthest point.
  double reach = 0.0;
  for (const int b : body_) {
    reach += mju_norm3(m->body_pos + 3 * b) + mju_norm3(m->body_ipos + 3 * b);
    for (int j = m->body_jntadr[b]; j < m->body_jntadr[b] + m->body_jntnum[b]; ++j) {
      reach += mju_norm3(m->jnt_pos + 3 * j);
      const int type = m->jnt_type[j];
      if (type == mjJNT_HINGE) hinge_.push_back(j);
      if (type == mjJNT_SLIDE) slide_.push_back(j);
      if (type == mjJNT_FREE) free_.push_back(j);
    }
    if (m->body_mocapid[b] >= 0) mocap_.push_back(m->body_mocapid[b]);
  }
  double far = 0.0;
  for (const int s : gmove_) {
    const int64_t g = geom_[s];
    far = std::max(far, mju_norm3(m->geom_pos + 3 * g) + m->geom_rbound[g] +
                            mju_norm3(m->geom_aabb + 6 * g) + mju_norm3(m->geom_aabb + 6 * g + 3));
  }
  if (!hinge_.empty()) {
    tolerance_ = kToleranceUnit * static_cast<double>(1 + n + hinge_.size()) *
                 (1.0 + (reach + far) + kWorldReach);
  }
  // The lanes' frames: a still body's in every lane, once (the moving ones' at each batch).
  lane_buf_.assign(kLanes * (28 * n + 1), 0.0);
  void* at = lane_buf_.data();
  size_t room = lane_buf_.size() * sizeof(double);
  // 32 bytes, not alignof(Lanes): the baseline build aligns the type to 16 only, the AVX2 clone
  // loads and stores it aligned to 32.
  lxpos_ = static_cast<Lanes*>(std::align(32, 28 * n * sizeof(Lanes), at, room));
  lxquat_ = lxpos_ + 3 * n, lxmat_ = lxquat_ + 4 * n, lxipos_ = lxmat_ + 9 * n;
  lximat_ = lxipos_ + 3 * n;
  for (size_t e = 0; e < 3 * n; ++e) lxpos_[e] = Splat(xpos_[e]), lxipos_[e] = Splat(xipos_[e]);
  for (size_t e = 0; e < 4 * n; ++e) lxquat_[e] = Splat(xquat_[e]);
  for (size_t e = 0; e < 9 * n; ++e) lxmat_[e] = Splat(xmat_[e]), lximat_[e] = Splat(ximat_[e]);
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
        const double a = qpos[qadr] - m->qpos0[qadr];
        if (!exact_ && std::fabs(a * 0.5) <= kHalfAngleMax) {
          HingeQuat(qloc, m->jnt_axis + 3 * jid, a);
        } else {
          mju_axisAngle2Quat(qloc, m->jnt_axis + 3 * jid, a);
        }
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
    // (A body's own frame is no inertial frame: the body frame stands for it, never read.)
    Local2Global(xpos, xquat, xmat_.data() + 9 * c, xpos, xmat_.data() + 9 * c,
                 m->body_ipos + 3 * i, m->body_iquat + 4 * i, m->body_sameframe[i],
                 xipos_.data() + 3 * c, ximat_.data() + 9 * c);
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

void KnotKinematics::FrameLanes(size_t c, const double* const* qpos, const double* const* mocap_pos,
                                const double* const* mocap_quat) {
  const mjModel* m = m_;
  // Frame's arithmetic in lanes, branch for branch (those on the model; the data's are selects).
  const int i = body_[c], pid = parent_[c];
  Lanes* xpos = lxpos_ + 3 * c;
  Lanes* xquat = lxquat_ + 4 * c;
  const int jntadr = m->body_jntadr[i], jntnum = m->body_jntnum[i];
  if (jntnum == 1 && m->jnt_type[jntadr] == mjJNT_FREE) {
    const int qadr = m->jnt_qposadr[jntadr];
    for (int k = 0; k < 3; ++k) xpos[k] = Gather(qpos, qadr + k);
    for (int k = 0; k < 4; ++k) xquat[k] = Gather(qpos, qadr + 3 + k);
    Normalize4L(xquat);
  } else {
    Lanes bodypos[3], bodyquat[4];
    const int mocap = m->body_mocapid[i];
    if (mocap >= 0) {
      for (int k = 0; k < 3; ++k) bodypos[k] = Gather(mocap_pos, 3 * mocap + k);
      for (int k = 0; k < 4; ++k) bodyquat[k] = Gather(mocap_quat, 4 * mocap + k);
      Normalize4L(bodyquat);
    } else {
      for (int k = 0; k < 3; ++k) bodypos[k] = Splat(m->body_pos[3 * i + k]);
      for (int k = 0; k < 4; ++k) bodyquat[k] = Splat(m->body_quat[4 * i + k]);
    }
    if (pid >= 0) {
      MulMatVec3L(xpos, lxmat_ + 9 * pid, bodypos);
      for (int k = 0; k < 3; ++k) xpos[k] += lxpos_[3 * pid + k];
      MulQuatL(xquat, lxquat_ + 4 * pid, bodyquat);
    } else {
      for (int k = 0; k < 3; ++k) xpos[k] = bodypos[k];
      for (int k = 0; k < 4; ++k) xquat[k] = bodyquat[k];
    }
    for (int j = 0; j < jntnum; ++j) {
      const int jid = jntadr + j;
      const int qadr = m->jnt_qposadr[jid];
      const int jtype = m->jnt_type[jid];
      if (jtype == mjJNT_SLIDE) {
        Lanes xaxis[3];
        RotVecQuatL(xaxis, m->jnt_axis + 3 * jid, xquat);
        const Lanes q = Gather(qpos, qadr) - m->qpos0[qadr];
        for (int k = 0; k < 3; ++k) xpos[k] += xaxis[k] * q;
        continue;
      }
      Lanes qloc[4] = {};
      if (jtype == mjJNT_BALL) {
        for (int k = 0; k < 4; ++k) qloc[k] = Gather(qpos, qadr + k);
        Normalize4L(qloc);
      } else {
        const Lanes a = Gather(qpos, qadr) - m->qpos0[qadr];
        HingeQuat(qloc, m->jnt_axis + 3 * jid, a);
        if (exact_ || Any(Abs(a * 0.5) > kHalfAngleMax)) {
          // Past the polynomials' range, or where the plan's hinges are exact: libmujoco's call
          // in those lanes, as Run takes it.
          for (int k = 0; k < kLanes; ++k) {
            if (!exact_ && std::fabs(a[k] * 0.5) <= kHalfAngleMax) continue;
            double one[4];
            mju_axisAngle2Quat(one, m->jnt_axis + 3 * jid, a[k]);
            for (int e = 0; e < 4; ++e) qloc[e][k] = one[e];
          }
        }
      }
      if (still_anchor_[jid]) {
        // Frame's anchor at the origin: 0 + xpos (the sign of a zero).
        MulQuatL(xquat, xquat, qloc);
        for (int k = 0; k < 3; ++k) xpos[k] = Splat(0.0) + xpos[k];
        continue;
      }
      Lanes xanchor[3], vec[3];
      RotVecQuatL(xanchor, m->jnt_pos + 3 * jid, xquat);
      for (int k = 0; k < 3; ++k) xanchor[k] += xpos[k];
      MulQuatL(xquat, xquat, qloc);
      RotVecQuatL(vec, m->jnt_pos + 3 * jid, xquat);
      for (int k = 0; k < 3; ++k) xpos[k] = xanchor[k] - vec[k];
    }
  }
  Normalize4L(xquat);
  Quat2MatL(lxmat_ + 9 * c, xquat);
  if (inertia_[c]) {
    // (A body's own frame is no inertial frame: the body frame stands for it, never read.)
    Local2Global(xpos, xquat, lxmat_ + 9 * c, xpos, lxmat_ + 9 * c, m->body_ipos + 3 * i,
                 m->body_iquat + 4 * i, m->body_sameframe[i], lxipos_ + 3 * c, lximat_ + 9 * c);
  }
}

DUA_LANES_CLONES void KnotKinematics::Lanes4(int nact, const double* const* qpos,
                                             const double* const* mocap_pos,
                                             const double* const* mocap_quat, double* const* pos,
                                             double* const* mat) {
  // Run's order: the moving bodies kept, parents first, then the moving geoms (a moving geom's
  // body is kept), the still ones' poses copied.
  for (const int c : move_) FrameLanes(static_cast<size_t>(c), qpos, mocap_pos, mocap_quat);
  for (const int s : gmove_) {
    const int c = gbody_[s];
    const int64_t g = geom_[s];
    Lanes p[3], r[9];
    Local2Global(lxpos_ + 3 * c, lxquat_ + 4 * c, lxmat_ + 9 * c, lxipos_ + 3 * c, lximat_ + 9 * c,
                 m_->geom_pos + 3 * g, m_->geom_quat + 4 * g, m_->geom_sameframe[g], p, r);
    if (nact == kLanes) {
      // Knot k's pose is lane k of each entry: four entries at a time turned into four knots'
      // runs of them (Transpose4), stored whole, rather than a lane read per double.
      Lanes col[kLanes];
      Transpose4(r, col);
      for (int k = 0; k < kLanes; ++k) Store(mat[k] + 9 * s, col[k]);
      Transpose4(r + 4, col);
      for (int k = 0; k < kLanes; ++k) Store(mat[k] + 9 * s + 4, col[k]);
      for (int k = 0; k < kLanes; ++k) mat[k][9 * s + 8] = r[8][k];
      const Lanes rows[kLanes] = {p[0], p[1], p[2], p[2]};
      Transpose4(rows, col);
      for (int k = 0; k < kLanes; ++k) {
        double* at = pos[k] + 3 * s;
        at[0] = col[k][0], at[1] = col[k][1], at[2] = col[k][2];
      }
      continue;
    }
    for (int k = 0; k < nact; ++k) {
      for (int e = 0; e < 3; ++e) pos[k][3 * s + e] = p[e][k];
      for (int e = 0; e < 9; ++e) mat[k][9 * s + e] = r[e][k];
    }
  }
  // (std::copy_n of 3 and 9 doubles called memcpy here, 0.3 M on baxter's replay; element by
  // element each double was reloaded, the stores possibly aliasing the source: read once.)
  for (const int s : gstill_) {
    const double* p = still_pos_.data() + 3 * s;
    const double* r = still_mat_.data() + 9 * s;
    const Lanes r0 = Load(r), r1 = Load(r + 4);
    const double r8 = r[8], p0 = p[0], p1 = p[1], p2 = p[2];
    for (int k = 0; k < nact; ++k) {
      double* to = mat[k] + 9 * s;
      Store(to, r0), Store(to + 4, r1), to[8] = r8;
      double* at = pos[k] + 3 * s;
      at[0] = p0, at[1] = p1, at[2] = p2;
    }
  }
}

DUA_LANES_CLONES void HalfAngleSinCosOf(int64_t n, const double* x, double* sn, double* cs,
                                        bool lanes) {
  int64_t i = 0;
  for (; lanes && i + kLanes <= n; i += kLanes) {
    Lanes s, c;
    HalfAngleSinCos(Load(x + i), &s, &c);
    Store(sn + i, s), Store(cs + i, c);
  }
  for (; i < n; ++i) HalfAngleSinCos(x[i], sn + i, cs + i);
}

void KnotKinematics::ReadyHinges(int64_t n, const double* qpos, int64_t nmocap_rows,
                                 const double* mocap_pos) {
  const mjModel* m = m_;
  const int64_t nq = m->nq, stride = 3 * m->nmocap;
  exact_ = false;
  if (hinge_.empty()) return;  // (nothing to take either way: tolerance 0)
  // The lengths the knots' data add (slides' travel, free and mocap bodies' places), within the
  // world the bound allows for, or every hinge by libmujoco's call. (The bound itself is the
  // model's: the same for every plan, so a replan on the same rows nests in the plan it
  // replaces.)
  double reach = 0.0;
  const auto largest = [&](int64_t rows, const double* at, int64_t step, double off) {
    double most = 0.0;
    for (int64_t k = 0; k < rows; ++k) most = std::max(most, std::fabs(at[step * k] - off));
    return most;
  };
  for (const int j : slide_) {
    const int adr = m->jnt_qposadr[j];
    reach += largest(n, qpos + adr, nq, m->qpos0[adr]);
  }
  for (const int j : free_) {
    for (int e = 0; e < 3; ++e) reach += largest(n, qpos + m->jnt_qposadr[j] + e, nq, 0.0);
  }
  for (const int id : mocap_) {
    for (int e = 0; e < 3; ++e) reach += largest(nmocap_rows, mocap_pos + 3 * id + e, stride, 0.0);
  }
  // (Exact poses are within the tolerance too: it is the model's either way.)
  exact_ = !(reach <= kWorldReach);
}

void KnotKinematics::RunKnots(int64_t n, const double* const* qpos, const double* const* mocap_pos,
                              const double* const* mocap_quat, double* const* pos,
                              double* const* mat) {
  const size_t nslot = geom_.size();
  int64_t j = 0;
  while (lanes() && n - j >= 2) {
    const int nact = static_cast<int>(std::min<int64_t>(kLanes, n - j));
    const double *q[kLanes], *mp[kLanes], *mq[kLanes];
    for (int k = 0; k < kLanes; ++k) {
      const int64_t at = j + (k < nact ? k : 0);
      q[k] = qpos[at], mp[k] = mocap_pos[at], mq[k] = mocap_quat[at];
    }
    Lanes4(nact, q, mp, mq, pos + j, mat + j);
    bool& checked = checked_[exact_ ? 1 : 0];  // (each way of taking the hinges checked)
    if (fault_ && !checked && nslot > 0) pos[j][0] = std::nextafter(pos[j][0], HUGE_VAL);
    if (!checked) {
      // The self-check: the first batch again one knot at a time, byte for byte; on a
      // difference, lanes go off and this batch is computed again below.
      checked = true;
      std::vector<double> p1(3 * nslot), r1(9 * nslot);
      for (int k = 0; k < nact && !failed_; ++k) {
        Run(q[k], mp[k], mq[k], p1.data(), r1.data());
        failed_ = std::memcmp(p1.data(), pos[j + k], 3 * nslot * sizeof(double)) != 0 ||
                  std::memcmp(r1.data(), mat[j + k], 9 * nslot * sizeof(double)) != 0;
      }
      if (failed_) break;
    }
    j += nact;
  }
  for (; j < n; ++j) Run(qpos[j], mocap_pos[j], mocap_quat[j], pos[j], mat[j]);
}

}  // namespace dua
