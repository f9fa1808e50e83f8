// Urgency: conservative lower bounds on the time to collision. The proof that none of these
// returns more than the exact first root is in docs/theory.md, section 1; the comments here only
// say which step of it a line carries out.
#include <algorithm>
#include <cmath>
#include <limits>

#include "dua/dua.h"
#include "internal.h"

namespace dua {
namespace {

// Relative inflation of the problem: it dominates the predicate's rounding (~4.5 u), ~8x.
constexpr double kKappa = 4e-15;
// Relative bracket width at which refinement stops (the result is the bracket's lower end).
constexpr double kRtol = 2e-13;
constexpr int kMaxIter = 200;
constexpr double kInf = std::numeric_limits<double>::infinity();

// |x + v t| - (e + d t + h t^2): positive while the reachable ball misses B(0, e).
inline double Predicate(const double x[3], const double v[3], double e, double d, double h,
                        double t) {
  const double y0 = x[0] + v[0] * t, y1 = x[1] + v[1] * t, y2 = x[2] + v[2] * t;
  return std::sqrt(y0 * y0 + y1 * y1 + y2 * y2) - (e + t * (d + h * t));
}

// The predicate (same expression, so the same sign), f' and f''; a = |v|^2.
inline void PredicateAndSlopes(const double x[3], const double v[3], double a, double e, double d,
                               double h, double t, double* f, double* df, double* d2) {
  const double y0 = x[0] + v[0] * t, y1 = x[1] + v[1] * t, y2 = x[2] + v[2] * t;
  const double ny = std::sqrt(y0 * y0 + y1 * y1 + y2 * y2);
  *f = ny - (e + t * (d + h * t));
  double p = 0.0;
  if (ny > 0.0) {
    p = (y0 * v[0] + y1 * v[1] + y2 * v[2]) / ny;
    *d2 = (a - p * p) / ny - 2.0 * h;
  } else {
    *d2 = -2.0 * h;
  }
  *df = p - (d + 2.0 * h * t);
}

// Lower end of a tight bracket of the single root in [lo, hi]. Requires predicate(lo) > 0,
// predicate(hi) <= 0 and one root there. Safeguarded Halley; every iterate tightens the bracket.
double RefineSafe(const double x[3], const double v[3], double e, double d, double h, double lo,
                  double hi) {
  const double a = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
  double t = hi, f, df, d2;
  PredicateAndSlopes(x, v, a, e, d, h, t, &f, &df, &d2);
  bool probe = false;  // the previous iterate was a probe past a converged point
  for (int it = 0; it < kMaxIter; ++it) {
    const double tol = kRtol * hi;
    if (hi - lo <= tol) break;
    const double den = 2.0 * df * df - f * d2;
    double tn = (df < 0.0 && den > 0.0) ? t - 2.0 * f * df / den : -1.0;
    const bool side = f > 0.0;
    if (std::fabs(tn - t) <= tol) {
      if (probe) {
        // A probe did not close the bracket: creeping towards a minimum, not a root.
        tn = 0.5 * (lo + hi);
        probe = false;
      } else {
        tn = side ? t + tol : t - tol;
        probe = true;
      }
    } else {
      probe = false;
    }
    if (!(lo < tn && tn < hi)) tn = 0.5 * (lo + hi);
    PredicateAndSlopes(x, v, a, e, d, h, tn, &f, &df, &d2);
    if (f > 0.0) {
      lo = tn;
    } else {
      hi = tn;
    }
    if (probe && (f > 0.0) != side) probe = false;
    t = tn;
  }
  return lo;
}

// Halley on the expanded quartic steers; the bracket it proposes is certified with the vector
// predicate, else the safe iteration runs: correctness rests on the predicate alone.
double Refine(const double x[3], const double v[3], double e, double d, double h, double lo,
              double hi) {
  const double a = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
  const double b = x[0] * v[0] + x[1] * v[1] + x[2] * v[2];
  const double c = x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
  const double c4 = -h * h, c3 = -2.0 * h * d, c2 = a - d * d - 2.0 * e * h;
  const double c1 = 2.0 * (b - e * d), c0 = c - e * e;
  // g, g' and g'' by Estrin's scheme: shorter dependency chains than Horner's (the loop is
  // latency-bound; 5 % of the kernel, measured). They only steer: the predicate certifies.
  const double k4 = 4.0 * c4, k3 = 3.0 * c3, k2 = 2.0 * c2, k12 = 12.0 * c4, k6 = 6.0 * c3;
  double blo = lo, bhi = hi, t = hi;
  for (int it = 0; it < 16; ++it) {
    const double t2 = t * t;
    const double g = (c4 * t2 + (c3 * t + c2)) * t2 + (c1 * t + c0);
    const double g1 = (k4 * t + k3) * t2 + (k2 * t + c1);
    const double g2 = k12 * t2 + (k6 * t + k2);
    if (g > 0.0) {
      blo = std::max(blo, t);
    } else {
      bhi = std::min(bhi, t);
    }
    const double den = 2.0 * g1 * g1 - g * g2;
    bool halley = g1 < 0.0 && den > 0.0;
    double tn = halley ? t - 2.0 * g * g1 / den : -1.0;
    if (!(blo <= tn && tn <= bhi)) {
      tn = 0.5 * (blo + bhi);
      halley = false;
    }
    // Halley converges cubically: after a step of 1e-5 t the error is of order 1e-15 t, inside
    // the certified bracket (2e-13 t), so the step that would only confirm it is skipped (3.4
    // iterations instead of 4.4 on random pairs, and as few fallbacks as at 1e-7, 1 in 10^4; at
    // 1e-4 9 % fall back, measured). Only a guess: the certification below decides,
    // and falls back to the safe iteration.
    if (std::fabs(tn - t) <= (halley ? 1e-5 : 1e-15) * t) {
      t = tn;
      break;
    }
    t = tn;
  }
  const double tl = t * (1.0 - 0.5 * kRtol), th = t * (1.0 + 0.5 * kRtol);
  if (lo <= tl && th <= hi && Predicate(x, v, e, d, h, tl) > 0.0 &&
      Predicate(x, v, e, d, h, th) <= 0.0) {
    return tl;
  }
  return RefineSafe(x, v, e, d, h, lo, hi);
}

// Root of the cubic G1 monotone on [lo, hi] (a sign change there).
double G1Root(double p3, double p2, double p1, double p0, double lo, double hi, bool increasing) {
  double t = 0.5 * (lo + hi);
  bool probe = false;  // the previous iterate was a probe across a converged point
  for (int it = 0; it < kMaxIter; ++it) {
    const double val = ((p3 * t + p2) * t + p1) * t + p0;
    if ((val > 0.0) == increasing) {
      hi = t;
    } else {
      lo = t;
    }
    if (hi - lo <= 1e-15 * hi) break;
    const double der = (3.0 * p3 * t + 2.0 * p2) * t + p1;
    double tn = der != 0.0 ? t - val / der : 0.5 * (lo + hi);
    // Newton nears the root from one side, so the far end of the bracket stays put: once a step
    // is inside the stopping width, probe just across to close the bracket (6.9 iterations a
    // call instead of 35 by bisection, measured on random pairs). A probe that does not close
    // it bisects next.
    const double tol = 0.5e-15 * t;
    if (std::fabs(tn - t) <= tol) {
      tn = probe ? 0.5 * (lo + hi) : (t == lo ? t + tol : t - tol);
      probe = !probe;
    } else {
      probe = false;
    }
    if (!(lo < tn && tn < hi)) tn = 0.5 * (lo + hi);
    if (tn == t) break;
    t = tn;
  }
  return t;
}

// A time >= start where the predicate is <= 0, on a final piece where g decreases to -inf.
double Upper(const double x[3], const double v[3], double e, double d, double h, double start,
             double nx, double nv) {
  // |x + v t| <= |x| + |v| t: the predicate is <= 0 once |x| + |v| t <= e + d t + h t^2.
  const double bq = nv - d, cq = nx - e;
  double t;
  if (h > 0.0) {
    t = (bq + std::sqrt(bq * bq + 4.0 * h * std::max(cq, 0.0))) / (2.0 * h);
  } else {  // d > |v| on this branch
    t = std::max(cq, 0.0) / (d - nv);
  }
  t = std::max(std::max(t, start), 1e-300);
  for (int it = 0; it < 2100; ++it) {
    if (Predicate(x, v, e, d, h, t) <= 0.0) return t;
    t *= 2.0;
  }
  return kInf;
}

}  // namespace

double TauAccel(double x0, double x1, double x2, double v0, double v1, double v2, double eps,
                double accel, double delta) {
  const double nx = std::sqrt(x0 * x0 + x1 * x1 + x2 * x2);
  const double nv = std::sqrt(v0 * v0 + v1 * v1 + v2 * v2);
  const double vmax = std::max(std::max(std::fabs(v0), std::fabs(v1)), std::fabs(v2));
  if (0.0 < vmax && vmax < 1e-120) {
    // |v|^2 would underflow: solve in the time unit s (a power of two, so exactly).
    const double s = std::exp2(std::nearbyint(-std::log2(vmax)));
    if (std::isfinite(accel * s * s) && std::isfinite(delta * s)) {
      return s * TauAccel(x0, x1, x2, v0 * s, v1 * s, v2 * s, eps, accel * s * s, delta * s);
    }
  }
  const double x[3] = {x0, x1, x2}, v[3] = {v0, v1, v2};
  // The inflated problem: radius e + d t + h t^2.
  const double e = eps * (1.0 + kKappa) + kKappa * nx;
  const double d = delta * (1.0 + kKappa) + kKappa * nv;
  const double h = 0.5 * accel * (1.0 + kKappa);
  if (nx - e <= 0.0) return 0.0;
  const double a = nv * nv;
  const double b = x0 * v0 + x1 * v1 + x2 * v2;
  // G1 = g'/2 = -2h^2 t^3 - 3hd t^2 + q t + (b - e d),  G2 = g''/2 = -6h^2 t^2 - 6hd t + q.
  const double q = a - d * d - 2.0 * e * h;
  const double p0 = b - e * d;
  if (h == 0.0) {
    if (q > 0.0) {
      // g is convex: only its vertex can touch.
      if (p0 >= 0.0) return kInf;
      const double tv = -p0 / q;
      if (Predicate(x, v, e, d, h, tv) > 0.0) return kInf;
      return Refine(x, v, e, d, h, 0.0, tv);
    }
    if (q == 0.0 && p0 >= 0.0) return kInf;
    // q < 0 (or linear and decreasing): g goes to -inf past its vertex (if any).
    const double start = q < 0.0 ? std::max(-p0 / q, 0.0) : 0.0;
    if (start > 0.0 && Predicate(x, v, e, d, h, start) <= 0.0) {
      return Refine(x, v, e, d, h, 0.0, start);
    }
    if (d <= nv) {  // linear g with |v| = d: the closed-form upper bound does not apply
      double t = std::max(start, 1.0);
      for (int it = 0; it < 2100; ++it) {
        if (Predicate(x, v, e, d, h, t) <= 0.0) return Refine(x, v, e, d, h, start, t);
        t *= 2.0;
      }
      return kInf;
    }
    const double hi = Upper(x, v, e, d, h, start, nx, nv);
    return Refine(x, v, e, d, h, start, hi);
  }
  // start: before the first root, g > 0 on [0, start] and unimodal on [start, inf).
  double start = 0.0;
  if (q > 0.0 && p0 < 0.0) {
    // G2's positive root, cancellation-free; the local minimum ta of g is the only place a
    // first root can touch without a sign change of g'.
    const double t2 = 2.0 * q / (6.0 * h * d + std::sqrt(36.0 * h * h * d * d + 24.0 * h * h * q));
    const double p3 = -2.0 * h * h, p2 = -3.0 * h * d;
    if (((p3 * t2 + p2) * t2 + q) * t2 + p0 > 0.0) {
      const double ta = G1Root(p3, p2, q, p0, 0.0, t2, true);
      if (Predicate(x, v, e, d, h, ta) <= 0.0) return Refine(x, v, e, d, h, 0.0, ta);
      start = ta;
    }
  }
  const double hi = Upper(x, v, e, d, h, start, nx, nv);
  return Refine(x, v, e, d, h, start, hi);
}

double TauSpeed(double x0, double x1, double x2, double v0, double v1, double v2, double eps,
                double accel, double delta, double speed) {
  double tau = TauAccel(x0, x1, x2, v0, v1, v2, eps, accel, delta);
  if (speed < kInf && tau > 0.0) {
    const double nv = std::sqrt(v0 * v0 + v1 * v1 + v2 * v2);
    // A measured speed above the bound means the bound is broken: the term is dropped.
    if (nv <= speed) {
      const double nx = std::sqrt(x0 * x0 + x1 * x1 + x2 * x2);
      const double ts = (nx - eps * (1.0 + kKappa) - kKappa * nx) / speed * (1.0 - kKappa);
      tau = std::max(tau, ts);
    }
  }
  return tau;
}

double TauHalfspace(double gap, double normal_velocity, double accel, double delta) {
  if (gap <= 0.0) return 0.0;
  // Exact where it matters (Sterbenz): w is exactly 0 when delta cancels the approach speed.
  const double w = normal_velocity - delta;
  const double a = accel * (1.0 + kKappa);
  // sqrt(w^2 + 2 a gap) without squaring w (w * w underflows below |w| ~ 1e-154).
  const double s = std::hypot(w, std::sqrt(2.0 * a) * std::sqrt(gap));
  double t;
  if (w > 0.0) {
    if (a == 0.0) return kInf;
    t = (w + s) / a;
  } else {
    const double den = s - w;
    if (den == 0.0) return kInf;
    t = 2.0 * gap / den;
  }
  return t * (1.0 - kKappa);
}

}  // namespace dua

extern "C" {

double dua_tau_accel(double x0, double x1, double x2, double v0, double v1, double v2, double eps,
                     double accel, double delta) {
  return dua::TauAccel(x0, x1, x2, v0, v1, v2, eps, accel, delta);
}

double dua_tau_speed(double x0, double x1, double x2, double v0, double v1, double v2, double eps,
                     double accel, double delta, double speed) {
  return dua::TauSpeed(x0, x1, x2, v0, v1, v2, eps, accel, delta, speed);
}

double dua_tau_halfspace(double gap, double normal_velocity, double accel, double delta) {
  return dua::TauHalfspace(gap, normal_velocity, accel, delta);
}

int64_t dua_abi_version(void) { return DUA_ABI_VERSION; }

}  // extern "C"
