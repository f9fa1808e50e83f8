// What the motion bounds limit, measured at every point they are stated for, and checked against
// them (dua_mujoco/build/kinematics.py's PointMotion: the pilot measures with it, the run
// monitor's BoundMonitor checks; the hypotheses are derived in docs/discrete-time.md). The step's
// own check (step.cc, CheckBodies) tests each body's box at once, four bodies at a time; this one
// measures every point, for the bounds and the report.
#include <cmath>
#include <limits>

#include "dua/dua.h"
#include "internal.h"

extern "C" {

int64_t dua_check_points(const double* points, int64_t n, const dua_frame* f, const double* prev,
                         double* cur, int64_t nprev, double h, const double* accel,
                         const double* disc_bound, const double* speed_bound,
                         const uint8_t* check_disc, double rtol, double* values, uint8_t* broken) {
  constexpr double kEps = std::numeric_limits<double>::epsilon();
  enum { kSpeed = 0, kDisc = 1, kAcc = 2 };
  int64_t count = 0;
  for (int64_t i = 0; i < n; ++i) {
    double* c = cur + 9 * i;
    const double* p = prev + 9 * i;
    double* val = values + 3 * i;
    uint8_t* br = broken + 3 * i;
    dua::RigidPoint(i, points, dua::kSphereNcol, *f, c);  // inline: 160,000 points a step
    br[kSpeed] = br[kDisc] = br[kAcc] = 0;
    if (nprev == 0) {
      val[kSpeed] = val[kDisc] = val[kAcc] = 0.0;
      continue;
    }
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
      continue;
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
  }
  return count;
}

}  // extern "C"
