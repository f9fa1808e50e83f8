// Urgency: conservative lower bounds on the time to collision. The proof that none of these
// returns more than the exact first root is in docs/theory.md, section 1; the comments here only
// say which step of it a line carries out.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "dua/dua.h"
#include "internal.h"
#include "lanes.h"

namespace dua {
namespace {

// Four pairs in lockstep (TauSpeedBatch): one chain of Halley iterations carries four roots, so
// the branch mispredictions and latencies that bound the scalar kernel are paid once for four.
// The pieces both run are templates over the number type (lanes.h).

// Relative inflation of the problem: it dominates the predicate's rounding (~4.5 u), ~8x.
constexpr double kKappa = 4e-15;
// Relative bracket width at which refinement stops (the result is the bracket's lower end).
constexpr double kRtol = 2e-13;
constexpr int kMaxIter = 200;
constexpr double kInf = std::numeric_limits<double>::infinity();

// |x + v t| - (e + d t + h t^2): positive while the reachable ball misses B(0, e).
template <class T>
inline T Predicate(const T x[3], const T v[3], T e, T d, T h, T t) {
  const T y0 = x[0] + v[0] * t, y1 = x[1] + v[1] * t, y2 = x[2] + v[2] * t;
  return Sqrt(y0 * y0 + y1 * y1 + y2 * y2) - (e + t * (d + h * t));
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

// Halley on the expanded quartic, from hi: a guess at the root in [lo, hi], cheap (no square
// roots) and only a guess (Certify decides). Lanes that stop keep their t. Always inlined: with
// two lane callers GCC would otherwise keep one copy out of line, compiled without AVX, and the
// AVX2 clones would pass it their vectors as it does not read them.
template <class T>
DUA_INLINE T HalleyGuess(const T x[3], const T v[3], T e, T d, T h, T lo, T hi, MaskOf<T> run) {
  const T a = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
  const T b = x[0] * v[0] + x[1] * v[1] + x[2] * v[2];
  const T c = x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
  const T c4 = -h * h, c3 = -2.0 * h * d, c2 = a - d * d - 2.0 * e * h;
  const T c1 = 2.0 * (b - e * d), c0 = c - e * e;
  // g, g' and g'' by Estrin's scheme: shorter dependency chains than Horner's (the loop is
  // latency-bound; 5 % of the kernel, measured).
  const T k4 = 4.0 * c4, k3 = 3.0 * c3, k2 = 2.0 * c2, k12 = 12.0 * c4, k6 = 6.0 * c3;
  T blo = lo, bhi = hi, t = hi;
  for (int it = 0; it < 16 && Any(run); ++it) {
    const T t2 = t * t;
    const T g = (c4 * t2 + (c3 * t + c2)) * t2 + (c1 * t + c0);
    const T g1 = (k4 * t + k3) * t2 + (k2 * t + c1);
    const T g2 = k12 * t2 + (k6 * t + k2);
    const MaskOf<T> above = g > 0.0;
    blo = Select(above, Max(blo, t), blo);
    bhi = Select(above, bhi, Min(bhi, t));
    const T den = 2.0 * g1 * g1 - g * g2;
    const T step = t - 2.0 * g * g1 / den;
    const MaskOf<T> halley = And(And(g1 < 0.0, den > 0.0), And(blo <= step, step <= bhi));
    const T tn = Select(halley, step, 0.5 * (blo + bhi));
    // Halley converges cubically: after a step of 1e-5 t the error is of order 1e-15 t, inside
    // the certified bracket (2e-13 t), so the step that would only confirm it is skipped (3.4
    // iterations instead of 4.4 on random pairs, and as few fallbacks as at 1e-7, 1 in 10^4; at
    // 1e-4 9 % fall back, measured).
    const T tol = Select(halley, T{} + 1e-5, T{} + 1e-15) * t;
    const MaskOf<T> stop = Abs(tn - t) <= tol;
    t = Select(run, tn, t);
    run = AndNot(run, stop);
  }
  return t;
}

// Whether [t (1 - r/2), t (1 + r/2)] lies in [lo, hi] with the predicate positive at its lower
// end, *tl, and non-positive at its upper end: then the root lies in it (one root in [lo, hi]).
template <class T>
MaskOf<T> Certify(const T x[3], const T v[3], T e, T d, T h, T lo, T hi, T t, T* tl) {
  *tl = t * (1.0 - 0.5 * kRtol);
  const T th = t * (1.0 + 0.5 * kRtol);
  return And(And(lo <= *tl, th <= hi),
             And(Predicate(x, v, e, d, h, *tl) > 0.0, Predicate(x, v, e, d, h, th) <= 0.0));
}

// Lower end of a tight bracket of the single root in [lo, hi]: the certified guess, else the
// safe iteration (correctness rests on the predicate alone).
double Refine(const double x[3], const double v[3], double e, double d, double h, double lo,
              double hi) {
  double tl;
  if (Certify(x, v, e, d, h, lo, hi, HalleyGuess(x, v, e, d, h, lo, hi, true), &tl)) return tl;
  return RefineSafe(x, v, e, d, h, lo, hi);
}

// Steps G1Root may take: enough for bisection alone to close a bracket from the largest double
// down to the smallest (1,100 halvings from DBL_MAX to the subnormals, then 50 to 1e-15 of the
// root). Newton cannot help while its step cancels: t - G1(t) / G1'(t) for G1 ~ q t + p0 at t
// far above the root rounds to 0, so a bracket t_2 over 2^253 times the root takes that many
// bisections first (a pair a metre away closing at 1 m/s under A below 6e-77 m/s^2). A cap of
// 200 stopped there and returned a point past the minimum, and TauAccel then started its
// bracket beyond the first root (docs/theory.md, section 1).
constexpr int kG1MaxIter = 2200;

// Root of the cubic G1 monotone on [lo, hi] (a sign change there).
double G1Root(double p3, double p2, double p1, double p0, double lo, double hi, bool increasing) {
  double t = 0.5 * (lo + hi);
  bool probe = false;  // the previous iterate was a probe across a converged point
  for (int it = 0; it < kG1MaxIter; ++it) {
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

// |x + v t| <= |x| + |v| t: the predicate is <= 0 once |x| + |v| t <= e + d t + h t^2, from
// the returned time on (h > 0), if it is at least start (and not 0, which doubling cannot grow).
template <class T>
T UpperGuess(T nx, T nv, T e, T d, T h, T start) {
  const T bq = nv - d, cq = nx - e;
  const T t = (bq + Sqrt(bq * bq + 4.0 * h * Max(cq, T{}))) / (2.0 * h);
  return Max(Max(t, start), T{} + 1e-300);
}

// A time >= start where the predicate is <= 0, on a final piece where g decreases to -inf.
double Upper(const double x[3], const double v[3], double e, double d, double h, double start,
             double nx, double nv) {
  double t;
  if (h > 0.0) {
    t = UpperGuess(nx, nv, e, d, h, start);
  } else {  // d > |v| on this branch
    t = std::max(std::max(std::max(nx - e, 0.0) / (d - nv), start), 1e-300);
  }
  for (int it = 0; it < 2100; ++it) {
    if (Predicate(x, v, e, d, h, t) <= 0.0) return t;
    t *= 2.0;
  }
  return kInf;
}

// Whether |v|^2 would underflow, from vmax = max |v_i|: the kernel then rescales time.
template <class T>
MaskOf<T> Underflows(T vmax) {
  return And(0.0 < vmax, vmax < 1e-120);
}

template <class T>
T MaxAbs(const T v[3]) {
  return Max(Max(Abs(v[0]), Abs(v[1])), Abs(v[2]));
}

// The inflated problem: radius e + d t + h t^2. With G1 = g'/2 = -2h^2 t^3 - 3hd t^2 + q t + p0
// and G2 = g''/2 = -6h^2 t^2 - 6hd t + q.
template <class T>
struct Inflated {
  T nx, nv, e, d, h, q, p0;
};

template <class T>
Inflated<T> Inflate(const T x[3], const T v[3], T eps, T accel, T delta) {
  Inflated<T> p;
  p.nx = Sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
  p.nv = Sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  p.e = eps * (1.0 + kKappa) + kKappa * p.nx;
  p.d = delta * (1.0 + kKappa) + kKappa * p.nv;
  // kAccelFloor (internal.h): with |v| >= 1e-120 (smaller velocities are rescaled first), a
  // bound below it lets h^2 |v|^2 underflow in HasMinimum's t_2, which then misses g's interior
  // minimum, and the bracket [0, hi] holds three roots.
  const T bound = Select(And(0.0 < accel, accel < kAccelFloor), T{} + kAccelFloor, accel);
  p.h = 0.5 * bound * (1.0 + kKappa);
  const T a = p.nv * p.nv;
  const T b = x[0] * v[0] + x[1] * v[1] + x[2] * v[2];
  p.q = a - p.d * p.d - 2.0 * p.e * p.h;
  p.p0 = b - p.e * p.d;
  return p;
}

// Whether g (h > 0) has an interior local minimum, the only place a first root can touch
// without a sign change of g': G1 < 0 at 0 and > 0 at G2's positive root, *t2.
template <class T>
MaskOf<T> HasMinimum(const Inflated<T>& p, T* t2) {
  const MaskOf<T> may = And(p.q > 0.0, p.p0 < 0.0);
  if (!Any(may)) return may;
  const T h = p.h, d = p.d;
  // Cancellation-free.
  *t2 = 2.0 * p.q / (6.0 * h * d + Sqrt(36.0 * h * h * d * d + 24.0 * h * h * p.q));
  const T p3 = -2.0 * h * h, p2 = -3.0 * h * d;
  return And(may, ((p3 * *t2 + p2) * *t2 + p.q) * *t2 + p.p0 > 0.0);
}

// TauSpeed's speed term: the relative position also stays in B(x, V t), so no contact comes
// before ts = (|x| - eps) / V (inflated as the kernel inflates). The term applies under a finite
// bound that the measured speed |v| keeps (one above it means the bound is broken: the term is
// dropped), to a positive tau. The scalar kernel and the lanes (TauSpeedFour) both use these.
template <class T>
MaskOf<T> SpeedApplies(T nv, T speed) {
  return And(speed < kInf, nv <= speed);
}
template <class T>
T SpeedTerm(T nx, T eps, T speed) {
  return (nx - eps * (1.0 + kKappa) - kKappa * nx) / speed * (1.0 - kKappa);
}
double WithSpeedTerm(double tau, bool applies, double ts) {
  if (applies && tau > 0.0) {
    tau = std::max(tau, ts);
  }
  return tau;
}

double WithSpeed(double tau, double x0, double x1, double x2, double v0, double v1, double v2,
                 double eps, double speed) {
  const double nv = std::sqrt(v0 * v0 + v1 * v1 + v2 * v2);
  const double nx = std::sqrt(x0 * x0 + x1 * x1 + x2 * x2);
  return WithSpeedTerm(tau, SpeedApplies(nv, speed), SpeedTerm(nx, eps, speed));
}

// TauAccel's common path, four pairs at once: h > 0, no interior minimum, the closed-form upper
// end brackets the root, the guess is certified. The lanes it settles (the returned mask) hold
// TauSpeed's value bit for bit in *tau (TauAccel's, the same operations in the same order, then
// WithSpeedTerm's, in lanes); the rest are TauAccel's to compute. Also WithSpeed's term of every
// lane, from the same norms: *ts, and bit k of *speed_on where it applies (a finite speed bound
// the measured speed keeps). Inlined into its two loaders below (their AVX2 clones).
DUA_INLINE int AccelLanes(const Lanes x[3], const Lanes v[3], Lanes eps, Lanes accel, Lanes delta,
                          Lanes speed, Lanes* tau, Lanes* ts, int* speed_on) {
  const Inflated<Lanes> p = Inflate(x, v, eps, accel, delta);
  // WithSpeed's term (p.nx and p.nv are its norms, bit for bit).
  const LaneMask on = SpeedApplies(p.nv, speed);
  const Lanes term = SpeedTerm(p.nx, eps, speed);
  *ts = term;
  *speed_on = Bits(on);
  const LaneMask inside = p.nx - p.e <= 0.0;  // tau = 0
  LaneMask ok = AndNot(p.h > 0.0, Underflows(MaxAbs(v)));
  Lanes t2;
  ok = AndNot(ok, HasMinimum(p, &t2));
  const Lanes hi = UpperGuess(p.nx, p.nv, p.e, p.d, p.h, Lanes{});
  ok = AndNot(And(ok, Predicate(x, v, p.e, p.d, p.h, hi) <= 0.0), inside);
  Lanes out = {};
  if (Any(ok)) {
    Lanes tl;
    const Lanes t = HalleyGuess(x, v, p.e, p.d, p.h, Lanes{}, hi, ok);
    ok = And(ok, Certify(x, v, p.e, p.d, p.h, Lanes{}, hi, t, &tl));
    out = Select(ok, tl, out);
  }
  ok = ok | inside;
  // WithSpeedTerm in lanes (std::max(a, b) is Max(a, b): a unless a < b).
  *tau = Select(And(on, out > 0.0), Max(out, term), out);
  return Bits(ok);
}

// AccelLanes of four rows {x0, x1, x2, v0, v1, v2, eps, accel, delta, speed}.
DUA_LANES_CLONES
int TauAccelLanes(const double r[kLanes][10], double tau[kLanes], double ts[kLanes],
                  int* speed_on) {
  Lanes x[3], v[3], eps, accel, delta, speed;
  for (int k = 0; k < kLanes; ++k) {
    for (int j = 0; j < 3; ++j) x[j][k] = r[k][j], v[j][k] = r[k][3 + j];
    eps[k] = r[k][6], accel[k] = r[k][7], delta[k] = r[k][8], speed[k] = r[k][9];
  }
  Lanes out, term;
  const int done = AccelLanes(x, v, eps, accel, delta, speed, &out, &term, speed_on);
  for (int k = 0; k < kLanes; ++k) tau[k] = out[k], ts[k] = term[k];
  return done;
}

}  // namespace

// AccelLanes of four sphere pairs read in place (internal.h). The bounds, four consecutive
// numbers of each record, come as four vectors transposed; the spheres' rows element by element
// (a row may have been written just before, as six numbers: a vector read of them would wait
// for the stores).
DUA_LANES_CLONES
int TauSpeedFourPairs(const double* const si[kLanes], const double* const sj[kLanes],
                      const double* const rec[kLanes], int m, double* out, const int64_t at[kLanes],
                      double ts[kLanes], int* speed_on) {
  static_assert(
      kPairAccel == kPairEps + 1 && kPairDelta == kPairEps + 2 && kPairSpeed == kPairEps + 3,
      "the bounds are four consecutive columns of a pair record");
  Lanes x[3], v[3];
  for (int j = 0; j < 3; ++j) {
    x[j] = Lanes{sj[0][j], sj[1][j], sj[2][j], sj[3][j]} -
           Lanes{si[0][j], si[1][j], si[2][j], si[3][j]};
    v[j] = Lanes{sj[0][3 + j], sj[1][3 + j], sj[2][3 + j], sj[3][3 + j]} -
           Lanes{si[0][3 + j], si[1][3 + j], si[2][3 + j], si[3][3 + j]};
  }
  // Each record's four bounds as one vector read (not through a copy on the stack), then
  // transposed: Load, as a record is aligned only as a double.
  const Lanes r[kLanes] = {Load(rec[0] + kPairEps), Load(rec[1] + kPairEps),
                           Load(rec[2] + kPairEps), Load(rec[3] + kPairEps)};
  Lanes c[kLanes];
  Transpose4(r, c);
  const Lanes eps = c[0], accel = c[1], delta = c[2], speed = c[3];
  Lanes tau, term;
  const int done = AccelLanes(x, v, eps, accel, delta, speed, &tau, &term, speed_on);
  std::memcpy(ts, &term, sizeof(Lanes));
  for (int k = 0; k < kLanes; ++k) out[at[k]] = tau[k];
  return ~done & ((1 << m) - 1);
}

void TauSpeedFourPairsLeft(const double* const si[kLanes], const double* const sj[kLanes],
                           const double* const rec[kLanes], int left, double* out,
                           const int64_t at[kLanes], const double ts[kLanes], int speed_on) {
  for (int k = 0; k < kLanes; ++k) {
    if (((left >> k) & 1) == 0) continue;
    const double *a = si[k], *b = sj[k], *q = rec[k];
    const double t = TauAccel(b[0] - a[0], b[1] - a[1], b[2] - a[2], b[3] - a[3], b[4] - a[4],
                              b[5] - a[5], q[kPairEps], q[kPairAccel], q[kPairDelta]);
    out[at[k]] = WithSpeedTerm(t, (speed_on >> k) & 1, ts[k]);
  }
}

double WithGapSpeed(double tau, double gap, double now, double bound) {
  if (bound < kInf && gap > 0.0 && now <= bound && tau > 0.0) {
    tau = std::max(tau, gap / bound * (1.0 - kKappa));
  }
  return tau;
}

double TauAccel(double x0, double x1, double x2, double v0, double v1, double v2, double eps,
                double accel, double delta) {
  const double v[3] = {v0, v1, v2};
  const double vmax = MaxAbs(v);
  if (Underflows(vmax)) {
    // Solve in the time unit s (a power of two, so exactly).
    const double s = std::exp2(std::nearbyint(-std::log2(vmax)));
    if (std::isfinite(accel * s * s) && std::isfinite(delta * s)) {
      return s * TauAccel(x0, x1, x2, v0 * s, v1 * s, v2 * s, eps, accel * s * s, delta * s);
    }
  }
  const double x[3] = {x0, x1, x2};
  const Inflated<double> p = Inflate(x, v, eps, accel, delta);
  const double nx = p.nx, nv = p.nv, e = p.e, d = p.d, h = p.h, q = p.q, p0 = p.p0;
  if (nx - e <= 0.0) return 0.0;
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
      // g has a root, but |x + v t|^2 overflowed before the predicate read it (|x + v t| past
      // 1.3e154): no time past start is certified.
      return start;
    }
    const double hi = Upper(x, v, e, d, h, start, nx, nv);
    return Refine(x, v, e, d, h, start, hi);
  }
  // start: before the first root, g > 0 on [0, start] and unimodal on [start, inf).
  double start = 0.0, t2;
  if (HasMinimum(p, &t2)) {
    const double ta = G1Root(-2.0 * h * h, -3.0 * h * d, q, p0, 0.0, t2, true);
    if (Predicate(x, v, e, d, h, ta) <= 0.0) return Refine(x, v, e, d, h, 0.0, ta);
    start = ta;
  }
  const double hi = Upper(x, v, e, d, h, start, nx, nv);
  return Refine(x, v, e, d, h, start, hi);
}

double SettleTau(const double x[3], const double v[3], double eps, double accel, double delta,
                 double cover) {
  return SettleTauOf(x[0], x[1], x[2], v[0], v[1], v[2], eps, accel, delta, cover);
}

double TauSpeed(double x0, double x1, double x2, double v0, double v1, double v2, double eps,
                double accel, double delta, double speed) {
  return WithSpeed(TauAccel(x0, x1, x2, v0, v1, v2, eps, accel, delta), x0, x1, x2, v0, v1, v2, eps,
                   speed);
}

void TauSpeedFour(const double r[kLanes][10], int m, double* out, int64_t out_stride) {
  double tau[kLanes], ts[kLanes];
  int speed_on;
  const int done = TauAccelLanes(r, tau, ts, &speed_on);
  for (int k = 0; k < m; ++k) {
    if ((done >> k) & 1) {
      out[k * out_stride] = tau[k];  // the speed term in already
    } else {
      const double* q = r[k];
      const double t = TauAccel(q[0], q[1], q[2], q[3], q[4], q[5], q[6], q[7], q[8]);
      out[k * out_stride] = WithSpeedTerm(t, (speed_on >> k) & 1, ts[k]);
    }
  }
}

namespace {

// TauSpeed of n rows into out[i * out_stride]; load(i, r) writes row i's
// {x0, x1, x2, v0, v1, v2, eps, accel, delta, speed} to r.
template <class Load>
void TauSpeedBatch(int64_t n, const Load& load, double* out, int64_t out_stride) {
  for (int64_t i = 0; i < n; i += kLanes) {
    const int64_t m = std::min<int64_t>(kLanes, n - i);
    double r[kLanes][10];
    for (int64_t k = 0; k < kLanes; ++k) load(i + std::min(k, m - 1), r[k]);  // pad: a repeat
    TauSpeedFour(r, static_cast<int>(m), out + i * out_stride, out_stride);
  }
}

}  // namespace

void TauSpeedRows(int64_t n, const double* rows, int64_t stride, double* out, int64_t out_stride) {
  // Ten assignments: std::copy became a call to memmove a row (dmc_dog: 5 % of the plugin's
  // instructions).
  TauSpeedBatch(
      n,
      [&](int64_t i, double* r) {
        const double* row = rows + i * stride;
        for (int j = 0; j < 10; ++j) r[j] = row[j];
      },
      out, out_stride);
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

void dua_tau_speed_batch(int64_t n, const double* x, const double* v, const double* eps,
                         const double* accel, const double* delta, const double* speed,
                         int64_t per_pair, double* out) {
  // Bit k of per_pair: the k-th of eps, accel, delta, speed has n entries (else one, for all).
  const double* param[4] = {eps, accel, delta, speed};
  int64_t step[4];
  for (int k = 0; k < 4; ++k) step[k] = (per_pair >> k) & 1;
  dua::TauSpeedBatch(
      n,
      [&](int64_t i, double* r) {
        for (int j = 0; j < 3; ++j) r[j] = x[3 * i + j], r[3 + j] = v[3 * i + j];
        for (int k = 0; k < 4; ++k) r[6 + k] = param[k][i * step[k]];
      },
      out, 1);
}

int64_t dua_abi_version(void) { return DUA_ABI_VERSION; }

}  // extern "C"
