// What the motion bounds limit, measured at every point they are stated for, and checked against
// them (dua_mujoco/build/kinematics.py's PointMotion: the pilot measures with it, the run
// monitor's BoundMonitor checks; the hypotheses are derived in docs/discrete-time.md). The step's
// own check (step.cc, CheckBodies) tests each body's box at once, four bodies at a time; this one
// measures every point, for the bounds and the report. The monitor's screened pass
// (dua_check_groups) measures only the points of groups that a screen in O(1) a group cannot
// clear, with the same flags (docs/theory.md, "The monitor's screen").
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "dua/dua.h"
#include "internal.h"

namespace dua {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();
enum { kSpeed = 0, kDisc = 1, kAcc = 2 };

// Measure one point whose row c (centre, velocity read) is written, against its previous row p,
// and flag what broke; its bounds and flags are at index i. Returns how many checks broke.
int64_t Measure(int64_t i, double* c, const double* p, int64_t nprev, double h, const double* accel,
                const double* disc_bound, const double* speed_bound, const uint8_t* check_disc,
                double rtol, double* val, uint8_t* br) {
  br[kSpeed] = br[kDisc] = br[kAcc] = 0;
  if (nprev == 0) {
    val[kSpeed] = val[kDisc] = val[kAcc] = 0.0;
    return 0;
  }
  int64_t count = 0;
  double scale = 0.0, scale_prev = 0.0;
  for (int k = 0; k < 3; ++k) {
    c[6 + k] = (c[k] - p[k]) / h;
    scale = std::fmax(scale, std::fabs(c[k]));
    scale_prev = std::fmax(scale_prev, std::fabs(p[k]));
  }
  // The round-off of a second difference of positions of size |c| is ~4 eps |c| / h^2.
  const double tol_a = 8.0 * kEps * (scale + scale_prev) / (h * h);
  val[kSpeed] = std::sqrt(c[6] * c[6] + c[7] * c[7] + c[8] * c[8]);
  if (speed_bound && val[kSpeed] > speed_bound[i] * (1.0 + rtol) + 0.5 * tol_a * h) {
    br[kSpeed] = 1;
    ++count;
  }
  double disc = 0.0, wprev = 0.0;
  for (int k = 0; k < 3; ++k) {
    const double e = c[6 + k] - p[3 + k];
    disc += e * e;
    wprev += p[3 + k] * p[3 + k];
  }
  disc = std::sqrt(disc);
  val[kDisc] = disc;
  const double tol_d = tol_a * h + 8.0 * kEps * std::sqrt(wprev);
  if (check_disc[i] && disc > disc_bound[i] * (1.0 + rtol) + tol_d) {
    br[kDisc] = 1;
    ++count;
  }
  if (nprev == 1) {
    val[kAcc] = 0.0;
    return count;
  }
  double acc = 0.0;
  for (int k = 0; k < 3; ++k) {
    const double e = c[6 + k] - p[6 + k];
    acc += e * e;
  }
  acc = std::sqrt(acc) / h;
  val[kAcc] = acc;
  if (acc > accel[i] * (1.0 + rtol) + tol_a) {
    br[kAcc] = 1;
    ++count;
  }
  return count;
}

// Copy the frame rows a group's points read into row (kFrameRowLen).
void GatherFrame(const double* group, const dua_frame& f, double* row) {
  const int64_t g = static_cast<int64_t>(group[kGroupFrame]);
  const int64_t b = static_cast<int64_t>(group[kGroupBody]);
  const int64_t r = static_cast<int64_t>(group[kGroupRoot]);
  std::memcpy(row + kFrameR, f.mat + 9 * g, 9 * sizeof(double));
  std::memcpy(row + kFrameP, f.pos + 3 * g, 3 * sizeof(double));
  std::memcpy(row + kFrameTw, f.twist + 6 * b, 6 * sizeof(double));
  std::memcpy(row + kFrameRef, f.twist_ref + 3 * r, 3 * sizeof(double));
  std::memcpy(row + kFrameRt, f.root_twist + 6 * r, 6 * sizeof(double));
  std::memcpy(row + kFrameRo, f.root_origin + 3 * r, 3 * sizeof(double));
}

// RigidPoint of point rec on a gathered frame row: the same operations, so the same bits.
inline void PointOnRow(const double* rec, const double* row, double* out) {
  RigidPointOn(rec, row + kFrameP, row + kFrameR, row + kFrameTw, row + kFrameRef, row + kFrameRt,
               row + kFrameRo, out);
}

inline double Norm3(double x, double y, double z) { return std::sqrt(x * x + y * y + z * z); }

// Whether the screen clears a group (its record: a ball oc, rho holding its points, and their
// bounds): every point o = oc + d, |d| <= rho, of a rigid group whose frame rows at the last
// three updates are now, last, first (h and h_prev apart) has its chord speed, discrepancy and
// acceleration within the bounds by more than the rounding of the per-point pass
// (docs/theory.md, "The monitor's screen"). NaN anywhere fails the comparisons, so the group is
// measured.
bool Clears(const double* now, const double* last, const double* first, const double* group,
            double h, double h_prev, double rtol) {
  // 2^-40: thousands of times the rounding of either pass (a few units of 2^-53 of the values'
  // magnitudes), a millionth of a micro-unit of the bounds the scenes declare.
  constexpr double kSlack = 0x1p-40;
  const double oc[3] = {group[kGroupCentre], group[kGroupCentre + 1], group[kGroupCentre + 2]};
  const double rho = group[kGroupRadius];
  const double reach = Norm3(oc[0], oc[1], oc[2]) + rho;
  double c[3][3];      // the centre oc at now, last, first
  double scale = 0.0;  // bounds every coordinate of every point at the three instants
  const double* rows[3] = {now, last, first};
  for (int t = 0; t < 3; ++t) {
    const double* R = rows[t] + kFrameR;
    const double* P = rows[t] + kFrameP;
    double entries = 0.0;  // at least |R|'s Frobenius norm, without a root
    for (int j = 0; j < 9; ++j) entries += std::fabs(R[j]);
    scale = std::max(scale, std::fabs(P[0]) + std::fabs(P[1]) + std::fabs(P[2]) + entries * reach);
    for (int k = 0; k < 3; ++k) {
      c[t][k] = P[k] + R[3 * k] * oc[0] + R[3 * k + 1] * oc[1] + R[3 * k + 2] * oc[2];
    }
  }
  const double inv_h = 1.0 / h, inv_hp = 1.0 / h_prev;
  double u[3], up[3];
  for (int k = 0; k < 3; ++k) {
    u[k] = (c[0][k] - c[1][k]) * inv_h;
    up[k] = (c[1][k] - c[2][k]) * inv_hp;
  }
  // G = (R_now - R_last) / h moves a point's chord by G d; Gp the same one update before; B =
  // G - [W]x R_last the discrepancy's, W the angular velocity read at last.
  const double* Rn = now + kFrameR;
  const double* Rl = last + kFrameR;
  const double* Rf = first + kFrameR;
  const double* tw = last + kFrameTw;
  const double* rt = last + kFrameRt;
  const double W[3] = {tw[0] + rt[0], tw[1] + rt[1], tw[2] + rt[2]};
  double g2 = 0.0, a2 = 0.0, b2 = 0.0;
  for (int j = 0; j < 9; ++j) {
    const double g = (Rn[j] - Rl[j]) * inv_h;
    const double gp = (Rl[j] - Rf[j]) * inv_hp;
    g2 += g * g;
    a2 += (g - gp) * (g - gp);
  }
  for (int col = 0; col < 3; ++col) {
    const double r0 = Rl[col], r1 = Rl[3 + col], r2 = Rl[6 + col];
    const double wr[3] = {W[1] * r2 - W[2] * r1, W[2] * r0 - W[0] * r2, W[0] * r1 - W[1] * r0};
    for (int k = 0; k < 3; ++k) {
      const double b = (Rn[3 * k + col] - Rl[3 * k + col]) * inv_h - wr[k];
      b2 += b * b;
    }
  }
  // The velocity read at last at oc, as RigidPoint reads it (the mocap term is zero when rt is).
  const double* ref = last + kFrameRef;
  const double* ro = last + kFrameRo;
  const double dx = c[1][0] - ref[0], dy = c[1][1] - ref[1], dz = c[1][2] - ref[2];
  const double ex = c[1][0] - ro[0], ey = c[1][1] - ro[1], ez = c[1][2] - ro[2];
  const double w0 = tw[3] + tw[1] * dz - tw[2] * dy + rt[3] + rt[1] * ez - rt[2] * ey;
  const double w1 = tw[4] + tw[2] * dx - tw[0] * dz + rt[4] + rt[2] * ex - rt[0] * ez;
  const double w2 = tw[5] + tw[0] * dy - tw[1] * dx + rt[5] + rt[0] * ey - rt[1] * ex;
  const double vscale = Norm3(tw[3], tw[4], tw[5]) + Norm3(rt[3], rt[4], rt[5]) +
                        (Norm3(tw[0], tw[1], tw[2]) + Norm3(rt[0], rt[1], rt[2])) *
                            (scale + Norm3(ref[0], ref[1], ref[2]) + Norm3(ro[0], ro[1], ro[2]));
  const double speed = Norm3(u[0], u[1], u[2]) + std::sqrt(g2) * rho;
  const double acc =
      (Norm3(u[0] - up[0], u[1] - up[1], u[2] - up[2]) + std::sqrt(a2) * rho) * inv_h;
  const double disc = Norm3(u[0] - w0, u[1] - w1, u[2] - w2) + std::sqrt(b2) * rho;
  const double slack_s = kSlack * 2.0 * scale * inv_h;
  const double slack_a = kSlack * 4.0 * scale * inv_h * std::max(inv_h, inv_hp);
  return speed * (1.0 + kSlack) + slack_s <= group[kGroupSpeed] * (1.0 + rtol) &&
         acc * (1.0 + kSlack) + slack_a <= group[kGroupAccel] * (1.0 + rtol) &&
         disc * (1.0 + kSlack) + slack_s + kSlack * vscale <= group[kGroupDisc] * (1.0 + rtol);
}

}  // namespace
}  // namespace dua

extern "C" {

int64_t dua_check_points(const double* points, int64_t n, const dua_frame* f, const double* prev,
                         double* cur, int64_t nprev, double h, const double* accel,
                         const double* disc_bound, const double* speed_bound,
                         const uint8_t* check_disc, double rtol, double* values, uint8_t* broken) {
  int64_t count = 0;
  for (int64_t i = 0; i < n; ++i) {
    double* c = cur + 9 * i;
    dua::RigidPoint(i, points, dua::kSphereNcol, *f, c);  // inline: 160,000 points a step
    count += dua::Measure(i, c, prev + 9 * i, nprev, h, accel, disc_bound, speed_bound, check_disc,
                          rtol, values + 3 * i, broken + 3 * i);
  }
  return count;
}

int64_t dua_check_groups(const double* points, const dua_frame* f, const int64_t* group_start,
                         const double* groups, int64_t ngroup, double* frames, int64_t* computed,
                         int64_t update, double* prev, double* cur, int64_t nprev, double h,
                         double h_prev, const double* accel, const double* disc_bound,
                         const double* speed_bound, const uint8_t* check_disc, double rtol,
                         double* values, uint8_t* broken) {
  constexpr int64_t kRow = dua::kFrameRowLen;
  int64_t count = 0;
  for (int64_t g = 0; g < ngroup; ++g) {
    const int64_t lo = group_start[g], hi = group_start[g + 1];
    // The group's record, not its first point's: one row a group, read in order.
    const double* group = groups + dua::kGroupNcol * g;
    // Two slots: the last update's rows, and the one before, which this update's replace (kept
    // here while they serve).
    double* now = frames + kRow * (2 * g + update % 2);
    const double* last = frames + kRow * (2 * g + (update + 1) % 2);
    double first[kRow];
    std::memcpy(first, now, sizeof(first));
    dua::GatherFrame(group, *f, now);
    if (nprev >= 2) {
      if (dua::Clears(now, last, first, group, h, h_prev, rtol)) {
        std::memset(broken + 3 * lo, 0, static_cast<size_t>(3 * (hi - lo)));
        continue;
      }
      if (computed[g] != update - 1) {
        // Its rows of the last update were skipped: rebuilt from the kept frames, as that
        // update would have written them.
        for (int64_t i = lo; i < hi; ++i) {
          const double* rec = points + dua::kSphereNcol * i;
          double* p = prev + 9 * i;
          double before[6];
          dua::PointOnRow(rec, first, before);
          dua::PointOnRow(rec, last, p);
          for (int k = 0; k < 3; ++k) p[6 + k] = (p[k] - before[k]) / h_prev;
        }
      }
    }
    for (int64_t i = lo; i < hi; ++i) {
      double* c = cur + 9 * i;
      dua::PointOnRow(points + dua::kSphereNcol * i, now, c);
      count += dua::Measure(i, c, prev + 9 * i, nprev, h, accel, disc_bound, speed_bound,
                            check_disc, rtol, values + 3 * i, broken + 3 * i);
    }
    computed[g] = update;
  }
  return count;
}

}  // extern "C"
