// The static-shape urgency: support functions, closest points and tau of a moving sphere
// against one packed shape record (proof in docs/static-shapes.md).
#include <algorithm>
#include <cmath>
#include <limits>

#include "dua/dua.h"
#include "internal.h"
#include "layout.h"

namespace dua {
namespace {

// Newton iterations of the ellipsoid's closest-point root (monotone: any count is safe).
constexpr int kEllipsoidIter = 60;

// Root t > 0 of sum (e_i y_i / (t + e_i^2))^2 = 1 for y outside the ellipsoid: F is convex and
// decreasing, so Newton from below climbs to it without overshooting.
double EllipsoidT(double e0, double e1, double e2, double y0, double y1, double y2) {
  const double emin = std::min(std::min(e0, e1), e2), emax = std::max(std::max(e0, e1), e2);
  const double ny = std::sqrt(y0 * y0 + y1 * y1 + y2 * y2);
  double t = std::max(0.0, emin * ny - emax * emax);
  for (int it = 0; it < kEllipsoidIter; ++it) {
    const double q0 = e0 * y0 / (t + e0 * e0), q1 = e1 * y1 / (t + e1 * e1),
                 q2 = e2 * y2 / (t + e2 * e2);
    const double f = q0 * q0 + q1 * q1 + q2 * q2 - 1.0;
    if (f <= 0.0) break;
    const double df =
        -2.0 * (q0 * q0 / (t + e0 * e0) + q1 * q1 / (t + e1 * e1) + q2 * q2 / (t + e2 * e2));
    const double step = -f / df;
    if (step <= 1e-16 * (t + emin * emin)) break;
    t += step;
  }
  return t;
}

// Closest point q of the shape to d (local frame) and an outward direction m at it (not
// normalised). Inside (q = d) m leaves through the nearest face: any direction gives gap <= -eps
// there, so the choice only has to exist.
void ClosestLocal(int kind, double s0, double s1, double s2, double d0, double d1, double d2,
                  double q[3], double m[3]) {
  auto set = [&](double a0, double a1, double a2, double b0, double b1, double b2) {
    q[0] = a0, q[1] = a1, q[2] = a2, m[0] = b0, m[1] = b1, m[2] = b2;
  };
  if (kind == kGeomSphere) {
    const double nd = std::sqrt(d0 * d0 + d1 * d1 + d2 * d2);
    if (nd > s0) {
      const double k = s0 / nd;
      return set(d0 * k, d1 * k, d2 * k, d0, d1, d2);
    }
    if (nd > 0.0) return set(d0, d1, d2, d0, d1, d2);
    return set(d0, d1, d2, 0.0, 0.0, 1.0);
  }
  if (kind == kGeomCapsule) {
    const double zc = std::min(std::max(d2, -s1), s1);
    const double w2 = d2 - zc;
    const double nw = std::sqrt(d0 * d0 + d1 * d1 + w2 * w2);
    if (nw > s0) {
      const double k = s0 / nw;
      return set(d0 * k, d1 * k, zc + w2 * k, d0, d1, w2);
    }
    if (nw > 0.0) return set(d0, d1, d2, d0, d1, w2);
    return set(d0, d1, d2, 1.0, 0.0, 0.0);
  }
  if (kind == kGeomCylinder) {
    const double rho = std::hypot(d0, d1);
    const double zc = std::min(std::max(d2, -s1), s1);
    double q0 = d0, q1 = d1;
    if (rho > s0) {
      const double k = s0 / rho;
      q0 = d0 * k;
      q1 = d1 * k;
    }
    if (rho > s0 || std::fabs(d2) > s1) return set(q0, q1, zc, d0 - q0, d1 - q1, d2 - zc);
    // Inside: leave through the nearer of the side wall and the cap.
    if (s0 - rho <= s1 - std::fabs(d2)) {
      if (rho > 0.0) return set(d0, d1, d2, d0, d1, 0.0);
      return set(d0, d1, d2, 1.0, 0.0, 0.0);
    }
    return set(d0, d1, d2, 0.0, 0.0, d2 >= 0.0 ? 1.0 : -1.0);
  }
  if (kind == kGeomEllipsoid) {
    const double y0 = std::fabs(d0), y1 = std::fabs(d1), y2 = std::fabs(d2);
    const double r0 = y0 / s0, r1 = y1 / s1, r2 = y2 / s2;
    if (r0 * r0 + r1 * r1 + r2 * r2 > 1.0) {
      const double t = EllipsoidT(s0, s1, s2, y0, y1, y2);
      // The normal in closed form (t d_i / (t + e_i^2)), free of d - q's cancellation.
      const double k0 = 1.0 / (t + s0 * s0), k1 = 1.0 / (t + s1 * s1), k2 = 1.0 / (t + s2 * s2);
      return set(s0 * s0 * d0 * k0, s1 * s1 * d1 * k1, s2 * s2 * d2 * k2, d0 * k0, d1 * k1,
                 d2 * k2);
    }
    const double m0 = d0 / (s0 * s0), m1 = d1 / (s1 * s1), m2 = d2 / (s2 * s2);
    if (m0 == 0.0 && m1 == 0.0 && m2 == 0.0) {
      // The centre: leave along the shortest semi-axis.
      if (s0 <= s1 && s0 <= s2) return set(d0, d1, d2, 1.0, 0.0, 0.0);
      if (s1 <= s2) return set(d0, d1, d2, 0.0, 1.0, 0.0);
      return set(d0, d1, d2, 0.0, 0.0, 1.0);
    }
    return set(d0, d1, d2, m0, m1, m2);
  }
  // Box and mesh box.
  const double q0 = std::min(std::max(d0, -s0), s0), q1 = std::min(std::max(d1, -s1), s1),
               q2 = std::min(std::max(d2, -s2), s2);
  if (q0 != d0 || q1 != d1 || q2 != d2) return set(q0, q1, q2, d0 - q0, d1 - q1, d2 - q2);
  const double p0 = s0 - std::fabs(d0), p1 = s1 - std::fabs(d1), p2 = s2 - std::fabs(d2);
  if (p0 <= p1 && p0 <= p2) return set(d0, d1, d2, d0 >= 0.0 ? 1.0 : -1.0, 0.0, 0.0);
  if (p1 <= p2) return set(d0, d1, d2, 0.0, d1 >= 0.0 ? 1.0 : -1.0, 0.0);
  return set(d0, d1, d2, 0.0, 0.0, d2 >= 0.0 ? 1.0 : -1.0);
}

// R^T x (to the shape's frame) and R x (to the world), R the record's row-major rotation.
inline void ToLocal(const double* rec, double x0, double x1, double x2, double y[3]) {
  const double* r = rec + kShapeMat;
  y[0] = r[0] * x0 + r[3] * x1 + r[6] * x2;
  y[1] = r[1] * x0 + r[4] * x1 + r[7] * x2;
  y[2] = r[2] * x0 + r[5] * x1 + r[8] * x2;
}

inline void ToWorld(const double* rec, double x0, double x1, double x2, double y[3]) {
  const double* r = rec + kShapeMat;
  y[0] = r[0] * x0 + r[1] * x1 + r[2] * x2;
  y[1] = r[3] * x0 + r[4] * x1 + r[5] * x2;
  y[2] = r[6] * x0 + r[7] * x1 + r[8] * x2;
}

// (n.c - h_S(n), n, |c| + |p| + h_local) with n the unit closest-point direction.
double Gap(double c0, double c1, double c2, const double* rec, double n[3], double* scale) {
  const int kind = static_cast<int>(rec[kShapeKind]);
  const double s0 = rec[kShapeSize], s1 = rec[kShapeSize + 1], s2 = rec[kShapeSize + 2];
  const double p0 = rec[kShapePos], p1 = rec[kShapePos + 1], p2 = rec[kShapePos + 2];
  const double d0 = c0 - p0, d1 = c1 - p1, d2 = c2 - p2;
  double l[3], q[3], m[3];
  ToLocal(rec, d0, d1, d2, l);
  ClosestLocal(kind, s0, s1, s2, l[0], l[1], l[2], q, m);
  ToWorld(rec, m[0], m[1], m[2], n);
  double nn = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  if (!(nn > 0.0)) {  // m underflowed (d - q subnormal): any direction is valid
    n[0] = 0.0, n[1] = 0.0, n[2] = 1.0, nn = 1.0;
  }
  n[0] /= nn, n[1] /= nn, n[2] /= nn;
  // The support at R^T of this very n: the half-space is exactly H(n) for the n used.
  double k[3];
  ToLocal(rec, n[0], n[1], n[2], k);
  const double h = SupportLocal(kind, s0, s1, s2, k[0], k[1], k[2]);
  *scale = std::sqrt(c0 * c0 + c1 * c1 + c2 * c2) + std::sqrt(p0 * p0 + p1 * p1 + p2 * p2) +
           std::fabs(h);
  return n[0] * d0 + n[1] * d1 + n[2] * d2 - h;
}

}  // namespace

double StaticGap(double c0, double c1, double c2, const double* rec, double n[3], double* scale) {
  return Gap(c0, c1, c2, rec, n, scale);
}

double TauStatic(double c0, double c1, double c2, double v0, double v1, double v2,
                 const double* rec, double eps, double accel, double delta, double speed) {
  if (static_cast<int>(rec[kShapeKind]) == kGeomHField) {
    return TauTerrainSphere(c0, c1, c2, v0, v1, v2, rec, eps, accel, delta);
  }
  double n[3], scale;
  const double gap = Gap(c0, c1, c2, rec, n, &scale);
  const double g = gap - eps - kGapSlack * (scale + eps);
  if (g <= 0.0) return 0.0;
  const double vn = n[0] * v0 + n[1] * v1 + n[2] * v2;
  const double nv = std::sqrt(v0 * v0 + v1 * v1 + v2 * v2);
  return WithGapSpeed(TauHalfspace(g, vn, accel, delta + kVelSlack * nv), g, nv, speed);
}

}  // namespace dua

extern "C" {

double dua_support(const double* n, const double* rec) {
  if (static_cast<int>(rec[dua::kShapeKind]) == dua::kGeomHField) {
    return dua::TerrainSupport(n, rec);
  }
  double k[3];
  dua::ToLocal(rec, n[0], n[1], n[2], k);
  const double h =
      dua::SupportLocal(static_cast<int>(rec[dua::kShapeKind]), rec[dua::kShapeSize],
                        rec[dua::kShapeSize + 1], rec[dua::kShapeSize + 2], k[0], k[1], k[2]);
  return n[0] * rec[dua::kShapePos] + n[1] * rec[dua::kShapePos + 1] +
         n[2] * rec[dua::kShapePos + 2] + h;
}

void dua_closest_point(const double* c, const double* rec, double* out) {
  if (static_cast<int>(rec[dua::kShapeKind]) == dua::kGeomHField) {
    return dua::TerrainClosest(c, rec, out);
  }
  const double p0 = rec[dua::kShapePos], p1 = rec[dua::kShapePos + 1], p2 = rec[dua::kShapePos + 2];
  double l[3], q[3], m[3];
  dua::ToLocal(rec, c[0] - p0, c[1] - p1, c[2] - p2, l);
  dua::ClosestLocal(static_cast<int>(rec[dua::kShapeKind]), rec[dua::kShapeSize],
                    rec[dua::kShapeSize + 1], rec[dua::kShapeSize + 2], l[0], l[1], l[2], q, m);
  dua::ToWorld(rec, q[0], q[1], q[2], out);
  out[0] += p0, out[1] += p1, out[2] += p2;
}

void dua_static_gap(const double* c, const double* rec, double* out) {
  if (static_cast<int>(rec[dua::kShapeKind]) == dua::kGeomHField) {
    out[0] = dua::TerrainGap(c, rec, out + 1);
    return;
  }
  double scale;
  out[0] = dua::Gap(c[0], c[1], c[2], rec, out + 1, &scale);
}

double dua_tau_static(double c0, double c1, double c2, double v0, double v1, double v2,
                      const double* rec, double eps, double accel, double delta) {
  return dua::TauStatic(c0, c1, c2, v0, v1, v2, rec, eps, accel, delta,
                        std::numeric_limits<double>::infinity());
}

}  // extern "C"
