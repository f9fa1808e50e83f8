// Flight plans (plan.h). The proofs of what the taus below keep: docs/theory.md, section 8.
#include "plan.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "internal.h"
#include "kinematics.h"
#include "lanes.h"
#include "layout.h"

namespace dua {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kEpsilon = std::numeric_limits<double>::epsilon();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Whether every v[i] (i < count) is finite and, if nonneg, >= 0, two at a time by arithmetic
// alone (a plan holds a few thousand numbers; the message's search for the entry it names runs
// only when this fails): x - x is 0 for a finite x and NaN otherwise, x - |x| is 0 for x >= 0
// and negative otherwise, so each sum stays 0 exactly when every entry passes (a sum of terms
// <= 0 that are not all 0 is below 0). Masks would be taken apart lane by lane here, in code
// built for baseline x86-64.
using Pair = double __attribute__((vector_size(16)));
using PairBits = uint64_t __attribute__((vector_size(16)));
bool AllFinite(const double* v, int64_t count, bool nonneg) {
  const PairBits magnitude = {~(uint64_t{1} << 63), ~(uint64_t{1} << 63)};
  Pair spread{}, below{};
  int64_t i = 0;
  for (; i + 2 <= count; i += 2) {
    Pair x;
    std::memcpy(&x, v + i, sizeof(x));
    PairBits bits;
    std::memcpy(&bits, &x, sizeof(x));
    bits &= magnitude;
    Pair abs;
    std::memcpy(&abs, &bits, sizeof(x));
    spread += x - x;
    below += x - abs;
  }
  bool all =
      spread[0] == 0.0 && spread[1] == 0.0 && (!nonneg || (below[0] == 0.0 && below[1] == 0.0));
  for (; i < count; ++i) all = all && (!nonneg || v[i] >= 0.0) && std::isfinite(v[i]);
  return all;
}

// A bound on how far any point of a geom moves between poses (p0, r0) and (p1, r1): the
// origin's displacement plus |R1 - R0|_F (>= the spectral norm) times the geom's bounding radius
// about its origin. A plane reaches arbitrarily far: any change is unbounded. *finite is cleared
// when a difference is not a finite number's square (a pose not finite, or so large that the
// squares overflow).
double Displacement(const double* p0, const double* r0, const double* p1, const double* r1,
                    double radius, bool plane, bool* finite) {
  double dp = 0.0, dr = 0.0;
  for (int i = 0; i < 3; ++i) dp += (p1[i] - p0[i]) * (p1[i] - p0[i]);
  for (int i = 0; i < 9; ++i) dr += (r1[i] - r0[i]) * (r1[i] - r0[i]);
  if (!(dp + dr < kInf)) *finite = false;
  if (plane) return dp == 0.0 && dr == 0.0 ? 0.0 : kInf;
  // Rounded up by a few ulps: the bound must not fall below the true displacement.
  return (std::sqrt(dp) + std::sqrt(dr) * radius) * (1.0 + 8.0 * kEpsilon);
}

// The sweeps of knot j (poses pj, rj; the knot before 3 nslot and 9 nslot back, its sweeps
// nslot back) for the slots `moving` (their Displacement) and `still` (a step taken once):
// Plan::Finish's loop, in an AVX2 clone where the CPU has one (the same operations in the same
// order: the same bits). Returns false when a squared difference is not finite.
DUA_LANES_CLONES bool SweepKnot(const double* pj, const double* rj, int64_t nslot,
                                const std::vector<int64_t>& moving,
                                const std::vector<std::pair<int64_t, double>>& still,
                                const double* reach, const uint8_t* plane, double* sw) {
  bool finite = true;
  for (const int64_t c : moving) {
    const double step = Displacement(pj - 3 * nslot + 3 * c, rj - 9 * nslot + 9 * c, pj + 3 * c,
                                     rj + 9 * c, reach[c], plane[c] != 0, &finite);
    sw[c] = (sw[c - nslot] + step) * (1.0 + 4.0 * kEpsilon);
  }
  for (const auto& [c, step] : still) sw[c] = (sw[c - nslot] + step) * (1.0 + 4.0 * kEpsilon);
  return finite;
}

// |a - b| - eps of two centres, lowered by the rounding allowance of the sphere gaps.
double CentreGap(const double* a, const double* b, double eps) {
  const double d0 = b[0] - a[0], d1 = b[1] - a[1], d2 = b[2] - a[2];
  const double dist = std::sqrt(d0 * d0 + d1 * d1 + d2 * d2);
  return dist - eps - kGapSlack * (dist + eps);
}

// Sphere i's centre at knot j of the plan.
inline void PlannedCentre(const Plan& plan, int64_t j, const double* spheres, int64_t i,
                          double* out) {
  const double* rec = spheres + i * kSphereNcol;
  const auto g = static_cast<int64_t>(rec[kSphereFrame]);
  PosePoint(plan.pos(j, g), plan.mat(j, g), rec + kSphereOffset, out);
}

// The pair's gap at the sphere level at the plan's knot j: a lower bound on the distance
// between its two spheres (a sphere and a plane, a static shape or a terrain) less the pair's
// contact distance, so a lower bound on the geoms' too.
double SphereGap(const double* rec, const double* spheres, const double* shapes, const Plan& plan,
                 int64_t j) {
  double a[3];
  PlannedCentre(plan, j, spheres, static_cast<int64_t>(rec[kPairFirst]), a);
  const int kind = static_cast<int>(rec[kPairKind]);
  const double eps = rec[kPairEps];
  if (kind == kKindHalfspace) {
    const int64_t g = static_cast<int64_t>(rec[kPairOther]);
    const double* r = plan.mat(j, g);
    const double* p = plan.pos(j, g);
    const double n0 = r[2], n1 = r[5], n2 = r[8];
    const double along = n0 * a[0] + n1 * a[1] + n2 * a[2];
    const double off = n0 * p[0] + n1 * p[1] + n2 * p[2];
    return along - off - eps - kGapSlack * (std::fabs(along) + std::fabs(off) + eps);
  }
  if (kind == kKindShape) {
    const double* shape = shapes + static_cast<int64_t>(rec[kPairOther]) * kShapeNcol;
    // A height field: its prisms' own bound (Lemma 9.5), never a convex shape's.
    if (static_cast<int>(shape[kShapeKind]) == kGeomHField) return TerrainPointGap(a, shape, eps);
    double n[3], scale;
    const double gap = StaticGap(a[0], a[1], a[2], shape, n, &scale);
    return gap - eps - kGapSlack * (scale + eps);
  }
  double b[3];
  PlannedCentre(plan, j, spheres, static_cast<int64_t>(rec[kPairSecond]), b);
  return CentreGap(a, b, eps);
}

// The geoms' gap along unit n (first to second) on frame f, less the contact distance: a lower
// bound on their distance less it (a separating direction's gap). The hull vertices the climbs
// reach are kept in the record, as the step's exact level keeps them: the next climb (the next
// knot's, a pose or two away) starts there. In exact arithmetic a climb's start changes no
// support (a hull's local maximum is its maximum; in floating point see docs/theory.md, section
// 5, on nearly flat faces), and any vertex of a geom's hull is a point of the geom, which is all
// the step's screen of queries that cannot clear reads from them (docs/theory.md, section 5).
double AxisGap(double* xrec, const dua_exact& x, const dua_frame& f, double n0, double n1,
               double n2, int mode) {
  const int64_t g1 = static_cast<int64_t>(xrec[kXG1]);
  const int64_t g2 = static_cast<int64_t>(xrec[kXG2]);
  int64_t top;
  double low_b;
  if (mode == kModePlane) {
    low_b = n0 * f.pos[3 * g2] + n1 * f.pos[3 * g2 + 1] + n2 * f.pos[3 * g2 + 2];
  } else {
    low_b = -GeomSupport(g2, x, f, -n0, -n1, -n2, static_cast<int64_t>(xrec[kXHull2]), &top);
    xrec[kXHull2] = static_cast<double>(top);
  }
  const double h_a = GeomSupport(g1, x, f, n0, n1, n2, static_cast<int64_t>(xrec[kXHull1]), &top);
  xrec[kXHull1] = static_cast<double>(top);
  const double scale = std::fabs(h_a) + std::fabs(low_b) + xrec[kXDist];
  return low_b - h_a - xrec[kXDist] - kGapSlack * scale;
}

// A geom's pose: its position (3) and rotation (9).
struct Pose {
  const double* pos;
  const double* mat;
};

// The exact level's gap of pair record `pair` with geom ga at pose pa and geom gb at pose pb (the
// record's two geoms, in either order): against a terrain its prisms' bound; else the direction
// that served last, then MuJoCo's witness direction at these poses (asked only while the gap is
// not above `need`, and only when some direction could lift it above: docs/theory.md, section
// 8, "Queries that cannot clear, at the knots"), written into the record (any unit direction is
// valid for any pose), its witness points into `witness` (the pair's row of the exact level's;
// null: none read or kept, as in a shield's query, whose records are its own).
double PosedGap(const double* pair, double* xrec, double* witness, dua_exact& x, dua_plan& plan,
                mjData* d, const double* shapes, int64_t ga, Pose pa, int64_t gb, Pose pb,
                double need) {
  const int mode = static_cast<int>(xrec[kXMode]);
  if (mode == kModeNone) return -kInf;
  const int64_t g1 = static_cast<int64_t>(xrec[kXG1]);
  const int64_t g2 = static_cast<int64_t>(xrec[kXG2]);
  const Pose p1 = g1 == ga ? pa : pb;
  if (mode == kModeTerrain) {
    const double* rec = shapes + static_cast<int64_t>(pair[kPairOther]) * kShapeNcol;
    return TerrainGeomGap(x.geoms + g1 * kGxNcol, p1.pos, p1.mat, rec, xrec[kXDist]);
  }
  const Pose p2 = g2 == gb ? pb : pa;
  // The two poses in d, which MuJoCo's distance reads and the frame below points at.
  std::copy_n(p1.pos, 3, d->geom_xpos + 3 * g1);
  std::copy_n(p1.mat, 9, d->geom_xmat + 9 * g1);
  std::copy_n(p2.pos, 3, d->geom_xpos + 3 * g2);
  std::copy_n(p2.mat, 9, d->geom_xmat + 9 * g2);
  const dua_frame f{d->geom_xpos, d->geom_xmat, nullptr, nullptr, nullptr, nullptr};
  if (mode == kModePlane) {
    const double* m = f.mat + 9 * g2;
    return AxisGap(xrec, x, f, -m[2], -m[5], -m[8], mode);
  }
  double best = -kInf;
  const double n0 = xrec[kXN], n1 = xrec[kXN + 1], n2 = xrec[kXN + 2];
  if (n0 != 0.0 || n1 != 0.0 || n2 != 0.0) {
    best = AxisGap(xrec, x, f, n0, n1, n2, mode);
    if (best > need) return best;
  }
  // Every direction's gap is at most |q| less the contact distance (q: the point nearest the
  // origin of the segment between two differences of the geoms' points, the latest query's
  // witness points and the last climbs' hull vertices at these poses): when that is not above
  // `need`, no direction MuJoCo could give clears the knot, and it is not asked. The margins
  // are the step's (NoDirectionClears), far above either side's rounding.
  double q[3], scale;
  const int near =
      witness != nullptr ? Nearest(witness, 0.0, 0.0, 0.0, xrec, x, f, 1.0, q, &scale) : 0;
  if (near > 0) {
    const double most =
        std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]) * (1.0 + 1e-12) + kGapSlack * scale;
    if (most < (xrec[kXDist] + need) * (1.0 - 1e-12)) return best;
    // The latest query's witness points moved with their geoms: the direction between them at
    // these poses follows the geoms' turning since, which the kept (world) direction does not;
    // then, between two hulls, the direction of the segment's nearest point (a step of GJK
    // from the two pairs of points). Any unit direction is a lower bound: where one clears the
    // knot it becomes the pair's direction, and MuJoCo is not asked (as at the step, section 5).
    double u[3];
    if (CarriedDirection(witness, g1, g2, x, f, u)) {
      best = std::max(best, AxisGap(xrec, x, f, u[0], u[1], u[2], mode));
      if (best > need) {
        xrec[kXN] = u[0], xrec[kXN + 1] = u[1], xrec[kXN + 2] = u[2];
        return best;
      }
    }
    if (near == 2 &&
        Unit(q, x.geoms[g1 * kGxNcol + kGxRadius] + x.geoms[g2 * kGxNcol + kGxRadius])) {
      best = std::max(best, AxisGap(xrec, x, f, q[0], q[1], q[2], mode));
      if (best > need) {
        xrec[kXN] = q[0], xrec[kXN + 1] = q[1], xrec[kXN + 2] = q[2];
        return best;
      }
    }
  }
  const double* q1 = f.pos + 3 * g1;
  const double* q2 = f.pos + 3 * g2;
  const double c0 = q2[0] - q1[0], c1 = q2[1] - q1[1], c2 = q2[2] - q1[2];
  const double reach = std::sqrt(c0 * c0 + c1 * c1 + c2 * c2) + xrec[kXDist] + 1.0;
  mjtNum fromto[6];
  ++plan.queries;
  const double dist = mj_geomDistance(static_cast<const mjModel*>(x.model), d, static_cast<int>(g1),
                                      static_cast<int>(g2), reach, fromto);
  double n[3];
  if (!(dist > xrec[kXDist]) || !WitnessDirection(fromto, x, g1, g2, xrec, n)) {
    return best;  // touching, or no witness
  }
  if (witness != nullptr) KeepWitness(fromto, g1, g2, f, witness);
  return std::max(best, AxisGap(xrec, x, f, n[0], n[1], n[2], mode));
}

// The first index in (j, n) at which skip is false, or n; skip(j) is true and skip falls
// (once false, false at every later index): the last index first (most walks clear every knot
// left: one evaluation), then galloping from j and bisection below it.
template <class Skip>
int64_t FirstKept(int64_t j, int64_t n, const Skip& skip) {
  if (n - 1 > j) {
    if (skip(n - 1)) return n;
    --n;  // n - 1 is kept, so the first kept is at most it: never asked again
  }
  int64_t lo = j, step = 1, hi = j + 1;
  while (hi < n && skip(hi)) lo = hi, step *= 2, hi = lo + step;
  hi = std::min(hi, n);
  while (hi - lo > 1) {
    const int64_t mid = lo + (hi - lo) / 2;
    (skip(mid) ? lo : hi) = mid;
  }
  return hi;
}

// (8): the first knot j >= k at which a lower bound on the pair's planned gap does not exceed
// both bodies' deviations there, or nknot when none does (the earliest state a contact could
// start past the plan). The bound at a knot is the sphere level's, then the exact level's;
// between two knots it is carried by the geoms' sweeps (a planned gap G at knot i is at least
// G - S1(i, j) - S2(i, j) at knot j), so that most knots cost a few flops. Where both
// deviations rise with the knots, the knots the carried gap clears are a run that ends where
// it first does not (the sweeps rise too: docs/theory.md, section 8), found by a search.
DUA_SECTION int64_t BothWalk(dua_step_args& a, const Plan& plan, mjData* d, int64_t k, int64_t p,
                             int64_t g1, int64_t g2, int64_t b1, int64_t b2, int64_t r) {
  const double* rec = a.pairs + p * kPairNcol;
  double* xrec = a.exact.on ? a.exact.records + p * kXNcol : nullptr;
  double* witness = a.exact.on && a.exact.witness != nullptr ? a.exact.witness + 6 * p : nullptr;
  const int64_t n = plan.nknot();
  const bool rising = r >= 0 ? plan.rel_rises(r) : plan.dev_rises(b1) && plan.dev_rises(b2);
  double gap = -kInf;  // a lower bound on the planned gap at knot `base`
  int64_t base = -1;
  // Each sum rounded up (a few ulps over its roundings), and the margin asked to exceed the
  // roundings of its own difference: a skipped knot is one whose gap is surely above. With a
  // relative pair r within its bound, the smaller of the sum and the relative deviation
  // (Lemma 8.2d: either bounds how far the pair's distance may fall below the planned one).
  const auto allowed = [&](int64_t j) {
    const double sum = (plan.dev(j, b1) + plan.dev(j, b2)) * (1.0 + 4.0 * kEpsilon);
    return r >= 0 ? std::min(sum, plan.rel_dev(j, r) * (1.0 + 4.0 * kEpsilon)) : sum;
  };
  const auto carried = [&](int64_t j) {
    const double moved =
        ((plan.sweep(j, g1) - plan.sweep(base, g1)) + (plan.sweep(j, g2) - plan.sweep(base, g2))) *
        (1.0 + 8.0 * kEpsilon);
    const double margin = gap - moved - allowed(j);
    return margin > 4.0 * kEpsilon * (std::fabs(gap) + moved + allowed(j));
  };
  for (int64_t j = k; j < n; ++j) {
    if (base >= 0 && carried(j)) {
      if (rising) {
        j = FirstKept(j, n, carried);
      } else {
        while (++j < n && carried(j)) {
        }
      }
      if (j >= n) break;
    }
    const double allow = allowed(j);
    gap = SphereGap(rec, a.spheres, a.shapes, plan, j);
    if (gap <= allow && xrec != nullptr) {
      const Pose p1{plan.pos(j, g1), plan.mat(j, g1)};
      const Pose p2{plan.pos(j, g2), plan.mat(j, g2)};
      gap = std::max(
          gap, PosedGap(rec, xrec, witness, a.exact, a.plan, d, a.shapes, g1, p1, g2, p2, allow));
    }
    base = j;
    if (!(gap > allow)) return j;
  }
  return n;
}

// BothWalk from the step's knot k, unless an earlier walk of this pair under the same plan
// already ended at or past k (`cleared`: the knot it ended at, -1 for none; null: none kept):
// a knot's bound reads only the plan (its poses, sweeps and deviations) and the static tables,
// never the state, so the knots that walk cleared stay cleared while the plan stands, and its
// end is this walk's end too (docs/theory.md, Lemma 8.2c). A pair re-evaluated under one plan
// (every step while it stands in alarm) then walks no knot at all until the step passes that
// end. The step's knot never goes back under one plan (a reset or a jump of the clock drops it).
int64_t BothKnot(dua_step_args& a, const Plan& plan, mjData* d, int64_t k, int64_t p, int64_t g1,
                 int64_t g2, int64_t b1, int64_t b2, int64_t r, int64_t* cleared) {
  if (cleared != nullptr && *cleared >= k) return *cleared;
  // (-2 - knot: the replaced plan's walk cleared the knots before it, Runtime::CarryCleared.)
  const int64_t from = cleared != nullptr && *cleared <= -2 ? std::max(k, -2 - *cleared) : k;
  const int64_t j = BothWalk(a, plan, d, from, p, g1, g2, b1, b2, r);
  if (cleared != nullptr) *cleared = j;
  return j;
}

// A free body's reach: how far any of its points (speed s now) can move in t while its bounds
// hold (accel A, one-step discrepancy D >= its velocity uncertainty, speed V), rounded up.
inline double Reach(double t, double s, double accel, double disc, double speed) {
  const double quad = ((s + disc) * t + 0.5 * accel * t * t) * (1.0 + 8.0 * kEpsilon);
  return std::min(quad, speed * t * (1.0 + 2.0 * kEpsilon));
}

// How far a free point can stray in t from where its velocity read carries it (discrete-time.md,
// section 2: |y(t) - y - t w| <= D t + A t^2 / 2), rounded up, with room for the rounding of the
// carried place y + t w (|y|_1 + t |w|_1: each coordinate a product and a sum). `spin` bounds how
// much faster than the carried point any other point of the geom moves (|w| r; 0 for a centre).
inline double Stray(double t, double accel, double disc, double spin, const double size[2]) {
  return ((spin + disc) * t + 0.5 * accel * t * t) * (1.0 + 8.0 * kEpsilon) +
         4.0 * kEpsilon * (size[0] + t * size[1]);
}

// The mixed tau's knot (Lemma 8.3): planned geom ga (body ba, sphere sa) at each knot j >= k,
// less its deviation, against free geom gb (body bb, sphere sb) where it is now, less its reach
// over (j - k) h from its own bounds (its row of the violation check), or where its velocity
// read carries it by then, less how far it may stray from there. The first knot at which no
// level (the sphere's, the exact one's) can separate them either way, or nknot; -1 when gb's
// body has no bounds to read (the pair falls back to the motion bounds).
DUA_SECTION int64_t MixedKnot(dua_step_args& a, const Plan& plan, mjData* d, int64_t k, int64_t p,
                              int64_t ga, int64_t ba, int64_t sa, int64_t gb, int64_t sb) {
  const int64_t row = a.plan.geom_row[gb];
  if (row < 0) return -1;
  const double* box = a.events.rec + row * kBNcol;
  const double accel = box[kBAccel], disc = box[kBDisc], speed = box[kBSpeed];
  const double* rec = a.pairs + p * kPairNcol;
  const double eps = rec[kPairEps];
  // The free side now: its sphere's centre and velocity, and (exact level) its geom's pose, the
  // velocity of its reference point and the spin part of its points' speeds, |w| r (section 5).
  double sb_state[6];
  PointOf(a, sb, sb_state);
  const double ss =
      std::sqrt(sb_state[3] * sb_state[3] + sb_state[4] * sb_state[4] + sb_state[5] * sb_state[5]);
  double size_s[2] = {0.0, 0.0}, size_g[2] = {0.0, 0.0};  // |place|_1, |velocity|_1 (Stray)
  for (int e = 0; e < 3; ++e) {
    size_s[0] += std::fabs(sb_state[e]), size_s[1] += std::fabs(sb_state[3 + e]);
  }
  double* xrec = nullptr;
  double* witness = nullptr;
  double sg = 0.0, vg = 0.0, spin = 0.0;
  double o[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  if (a.exact.on && static_cast<int>(a.exact.records[p * kXNcol + kXMode]) == kModeGeoms) {
    xrec = a.exact.records + p * kXNcol;
    if (a.exact.witness != nullptr) witness = a.exact.witness + 6 * p;
    RigidPoint(gb, a.exact.geoms, kGxNcol, a.frame, o);
    vg = std::sqrt(o[3] * o[3] + o[4] * o[4] + o[5] * o[5]);
    spin = Spin(gb, a.exact.geoms, a.frame);
    sg = vg + spin;
    for (int e = 0; e < 3; ++e) {
      size_g[0] += std::fabs(a.frame.pos[3 * gb + e]), size_g[1] += std::fabs(o[3 + e]);
    }
  }
  const Pose now{a.frame.pos + 3 * gb, a.frame.mat + 9 * gb};
  const double* sphere_a = a.spheres + sa * kSphereNcol;
  const int64_t n = plan.nknot();
  const double h = plan.h();
  // Lower bounds on the gaps at knot `base`, each level's: against the free side where it is
  // (gs, gg) and where its velocity carries it (cs, cg).
  double gs = -kInf, gg = -kInf, cs = -kInf, cg = -kInf;
  int64_t base = -1;
  // The knot's time, deviation and the free side's reach at each level, each rounded up: all
  // rise with the knot when the deviation does (then a search finds the end of a carried run).
  const auto time = [&](int64_t j) {
    return static_cast<double>(j - k) * h * (1.0 + 2.0 * kEpsilon);
  };
  const auto deviation = [&](int64_t j) { return plan.dev(j, ba) * (1.0 + 4.0 * kEpsilon); };
  const auto carried = [&](int64_t j) {
    const double t = time(j), dev = deviation(j);
    const double rs = Reach(t, ss, accel, disc, speed);
    const double rg = xrec ? Reach(t, sg, accel, disc, speed) : kInf;
    // The free geom does not move in the gap; the planned one by its sweep. The carried place
    // moves by the speed read times the time since `base`.
    const double moved = (plan.sweep(j, ga) - plan.sweep(base, ga)) * (1.0 + 8.0 * kEpsilon);
    const double since = (t - time(base)) * (1.0 + 4.0 * kEpsilon);
    const double ds = moved + ss * since + Stray(t, accel, disc, 0.0, size_s);
    const double dg = xrec ? moved + vg * since + Stray(t, accel, disc, spin, size_g) : kInf;
    const double ms = gs - moved - dev - rs, mg = gg - moved - dev - rg;
    const double mcs = cs - ds - dev, mcg = cg - dg - dev;
    return ms > 4.0 * kEpsilon * (std::fabs(gs) + moved + dev + rs) ||
           mg > 4.0 * kEpsilon * (std::fabs(gg) + moved + dev + rg) ||
           mcs > 4.0 * kEpsilon * (std::fabs(cs) + ds + dev) ||
           mcg > 4.0 * kEpsilon * (std::fabs(cg) + dg + dev);
  };
  for (int64_t j = k; j < n; ++j) {
    if (base >= 0 && carried(j)) {
      if (plan.dev_rises(ba)) {
        j = FirstKept(j, n, carried);
      } else {
        while (++j < n && carried(j)) {
        }
      }
      if (j >= n) break;
    }
    const double t = time(j), dev = deviation(j);
    const double rs = Reach(t, ss, accel, disc, speed);
    double ca[3];
    PosePoint(plan.pos(j, ga), plan.mat(j, ga), sphere_a + kSphereOffset, ca);
    gs = CentreGap(ca, sb_state, eps);
    bool clear = gs > dev + rs;
    // Where it heads, asked only when where it is does not clear the knot (most knots clear on
    // the first: the cheaper order; the knot is clear when either clears it).
    cs = gg = cg = -kInf;
    if (!clear) {
      double cb[3];
      for (int e = 0; e < 3; ++e) cb[e] = sb_state[e] + t * sb_state[3 + e];
      cs = CentreGap(ca, cb, eps);
      clear = cs > dev + Stray(t, accel, disc, 0.0, size_s);
    }
    if (!clear && xrec != nullptr) {
      const Pose planned{plan.pos(j, ga), plan.mat(j, ga)};
      const double rg = Reach(t, sg, accel, disc, speed);
      gg = PosedGap(rec, xrec, witness, a.exact, a.plan, d, a.shapes, ga, planned, gb, now,
                    dev + rg);
      clear = gg > dev + rg;
      if (!clear) {
        const double rc = Stray(t, accel, disc, spin, size_g);
        double at[3];
        for (int e = 0; e < 3; ++e) at[e] = now.pos[e] + t * o[3 + e];
        cg = PosedGap(rec, xrec, witness, a.exact, a.plan, d, a.shapes, ga, planned, gb,
                      {at, now.mat}, dev + rc);
        clear = cg > dev + rc;
      }
    }
    base = j;
    if (!clear) return j;
  }
  return n;
}

// How a pair's side stands: a static body (planned, deviation 0), a planned one, or one that
// follows its bounds.
enum Side { kFree = 0, kPlanned = 1, kFixed = 2 };

inline Side SideOf(const Plan& plan, const uint8_t* ok, int64_t b) {
  if (plan.fixed(b)) return kFixed;
  return ok[b] ? kPlanned : kFree;
}

// Whether neither side of a pair follows its bounds (each planned, or static): the pair then
// takes the plan's tau (8), a knot at or past the step's whatever its walk finds. The one
// place this is decided: Judge takes that case by it, and PlanCovered spares those pairs the
// bounds' tau by it.
inline bool NeitherFree(Side s1, Side s2) { return s1 != kFree && s2 != kFree; }

// A pair's knot under the plan (-1: the plan does not cover it) and its basis bits.
struct Judged {
  int64_t knot;
  uint8_t basis;
};

Judged Judge(dua_step_args& a, const Plan& plan, const uint8_t* ok, mjData* d, int64_t k, int64_t p,
             int64_t g1, int64_t g2) {
  const int64_t b1 = a.plan.geom_body[g1], b2 = a.plan.geom_body[g2];
  const Side s1 = SideOf(plan, ok, b1), s2 = SideOf(plan, ok, b2);
  const uint8_t basis = static_cast<uint8_t>((s1 != kFree ? 1 : 0) | (s2 != kFree ? 2 : 0));
  if (NeitherFree(s1, s2)) {
    int64_t* cleared = a.plan.cleared != nullptr ? a.plan.cleared + p : nullptr;
    // The bodies' relative pair, unless found beyond its bound (rel_ok null: a candidate plan,
    // every bound assumed, as its bodies are).
    int64_t r = plan.RelOf(b1, b2);
    if (r >= 0 && a.plan.rel_ok != nullptr && !a.plan.rel_ok[r]) r = -1;
    const auto rb = static_cast<uint8_t>(basis | (r >= 0 ? 4 : 0));
    return {BothKnot(a, plan, d, k, p, g1, g2, b1, b2, r, cleared), rb};
  }
  // One moving planned body against one that follows its bounds: the mixed tau (sphere pairs:
  // both bodies move). A static body against a free one keeps the motion bounds' tau.
  const double* rec = a.pairs + p * kPairNcol;
  if ((s1 == kPlanned) != (s2 == kPlanned) && s1 != kFixed && s2 != kFixed &&
      static_cast<int>(rec[kPairKind]) == kKindSphere) {
    const auto first = static_cast<int64_t>(rec[kPairFirst]);
    const auto second = static_cast<int64_t>(rec[kPairSecond]);
    const int64_t j = s1 == kPlanned ? MixedKnot(a, plan, d, k, p, g1, b1, first, g2, second)
                                     : MixedKnot(a, plan, d, k, p, g2, b2, second, g1, first);
    if (j >= 0) return {j, basis};
  }
  return {-1, 0};
}

// A body's name for a refusal ("" when it has none).
std::string NameOf(const mjModel* m, int64_t b) {
  const int adr = m->name_bodyadr[b];
  return adr >= 0 ? std::string(m->names + adr) : std::string();
}

}  // namespace

double MixedStray(double t, double accel, double disc, double spin, const double size[2]) {
  return Stray(t, accel, disc, spin, size);
}

double MixedReach(double t, double s, double accel, double disc, double speed) {
  return Reach(t, s, accel, disc, speed);
}

double PoseDeviation(const double* q, const double* pa, const double* ra, const double* pb,
                     const double* rb) {
  // Each difference of two numbers is rounded relative to itself, so the sum below is within a
  // few ulps of the terms' magnitudes (`scale`) of its exact value: that allowance is added.
  double v[3], scale = 0.0;
  for (int i = 0; i < 3; ++i) {
    double s = pa[i] - pb[i];
    double magnitude = std::fabs(s);
    for (int j = 0; j < 3; ++j) {
      const double term = (ra[3 * i + j] - rb[3 * i + j]) * q[j];
      s += term;
      magnitude += std::fabs(term);
    }
    v[i] = s;
    scale += magnitude;
  }
  return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) * (1.0 + 4.0 * kEpsilon) +
         8.0 * kEpsilon * scale;
}

double BoxDeviation(const double* box, const double* pa, const double* ra, const double* pb,
                    const double* rb) {
  double worst = 0.0;
  for (const double sx : {-1.0, 1.0}) {
    for (const double sy : {-1.0, 1.0}) {
      for (const double sz : {-1.0, 1.0}) {
        // The corners as Python's BodyBoxes.corners computes them (centre + sign * half).
        const double q[3] = {box[kBCenter] + sx * box[kBHalf],
                             box[kBCenter + 1] + sy * box[kBHalf + 1],
                             box[kBCenter + 2] + sz * box[kBHalf + 2]};
        const double dev = PoseDeviation(q, pa, ra, pb, rb);
        if (std::isnan(dev)) return dev;  // a pose that is not a number is within no bound
        worst = std::max(worst, dev);
      }
    }
  }
  return worst;
}

BoxReach::BoxReach(const double* box) {
  for (int j = 0; j < 3; ++j) qmax[j] = std::fabs(box[kBCenter + j]) + box[kBHalf + j];
}

namespace {

// BoxBound's first screen, (|e| + sum_j |F e_j| qmax_j) (1 + 2e-9) (the column norms of F),
// from the differences e(i) = pa[i] - pb[i] (i < 3) and f(m) = ra[m] - rb[m] (m < 9, row-major:
// column j is f(j), f(3 + j), f(6 + j)): of one check (T double) or of four in lanes (Lanes),
// each lane taking the same operations in the same order (the same bits).
template <class T, class E, class F>
DUA_INLINE T NormBound(const E& e, const F& f, const T* qmax) {
  T dp{};
  for (int i = 0; i < 3; ++i) dp += e(i) * e(i);
  T bound = Sqrt(dp);
  for (int j = 0; j < 3; ++j) {
    T column{};
    for (int i = 0; i < 3; ++i) column += f(3 * i + j) * f(3 * i + j);
    bound += Sqrt(column) * qmax[j];
  }
  return bound * (1.0 + 2e-9);
}

// A box's reach in every lane: NormBound's qmax for four checks of one box.
DUA_INLINE void SplatReach(const BoxReach& reach, Lanes* qmax) {
  for (int j = 0; j < 3; ++j) qmax[j] = Splat(reach.qmax[j]);
}

// RelativeBound's limit less the relative poses' own rounding (1e-12 of the lengths they
// combine), of one check or of four in lanes (as NormBound).
template <class T, class Pose>
DUA_INLINE T RelativeRoom(const double* box, const Pose& actual, const Pose& planned, T limit) {
  T scale{};
  scale += 1.0;
  for (int i = 0; i < 3; ++i) {
    scale += Abs(actual[i]) + Abs(planned[i]) + std::fabs(box[kBCenter + i]) + box[kBHalf + i];
  }
  return limit - 1e-12 * scale;
}

// Equal poses (a replan that keeps to the plan it replaces, a plan that is the run): 0.
bool SamePose(const double* pa, const double* ra, const double* pb, const double* rb) {
  return std::equal(pa, pa + 3, pb) && std::equal(ra, ra + 9, rb);
}

// BoxWithin past its test of equal poses.
bool BoxBound(const double* box, const BoxReach& reach, const double* pa, const double* ra,
              const double* pb, const double* rb, double limit);

// RelativePoseWithin past its test of equal poses.
bool RelativeBound(const double* box, const BoxReach& reach, const double* actual,
                   const double* planned, double limit);

}  // namespace

bool BoxWithin(const double* box, const double* pa, const double* ra, const double* pb,
               const double* rb, double limit) {
  if (SamePose(pa, ra, pb, rb)) return 0.0 <= limit;
  return BoxBound(box, BoxReach(box), pa, ra, pb, rb, limit);
}

bool BoxWithin(const double* box, const BoxReach& reach, const double* pa, const double* ra,
               const double* pb, const double* rb, double limit) {
  if (SamePose(pa, ra, pb, rb)) return 0.0 <= limit;
  return BoxBound(box, reach, pa, ra, pb, rb, limit);
}

namespace {

bool BoxBound(const double* box, const BoxReach& reach, const double* pa, const double* ra,
              const double* pb, const double* rb, double limit) {
  // |(pa - pb) + (ra - rb) q| <= |pa - pb| + sum_j |(ra - rb) e_j| |q_j| <= |e| + sum_j c_j
  // qmax_j for every corner q (qmax_j = |centre_j| + half_j, c_j the norm of F's column j), with
  // room past every rounding of the corners' own sum: PoseDeviation's allowance is at most 8
  // ulps of `scale` below (sum_i |e_i| + sum_ij |f_ij| qmax_j), and by Cauchy-Schwarz, a column
  // at a time (sum_i |f_ij| <= sqrt(3) c_j), scale <= sqrt(3) (|e| + sum_j c_j qmax_j), so 16
  // ulps of it are within 28 ulps of the bound's own terms: a factor 1 + 2e-9 covers them and
  // the 1e-9 the first screen always allowed (docs/theory.md, Lemma 8.1), with no pass over the
  // differences' magnitudes. (The columns' norms, not |F|_F |qmax|, which is at least their sum
  // by Cauchy-Schwarz: fewer checks go on to the corners.)
  const auto e = [&](int i) { return pa[i] - pb[i]; };
  const auto f = [&](int m) { return ra[m] - rb[m]; };
  if (NormBound(e, f, reach.qmax) <= limit) return true;
  double scale = 0.0;
  const double* qmax = reach.qmax;
  for (int i = 0; i < 3; ++i) {
    scale += std::fabs(pa[i] - pb[i]);
    for (int j = 0; j < 3; ++j) scale += std::fabs(ra[3 * i + j] - rb[3 * i + j]) * qmax[j];
  }
  const double slack = 16.0 * kEpsilon * scale;
  // The largest corner exactly, up to rounding, in dot products: with v the centre's deviation
  // and u_j the half extents' columns, |v + sum_j s_j u_j|^2 expands into |v|^2 + sum |u_j|^2 +
  // 2 sum s_j v.u_j + 2 sum s_i s_j u_i.u_j, whose rounding is a few ulps of (|v| + sum
  // |u_j|)^2 (32 of them allowed); the corners' own roundings are within `slack`. A pass here
  // is a pass of BoxDeviation; a failure goes to it (a corner-by-corner check costs 8 norms).
  double v[3], u[3][3];
  for (int i = 0; i < 3; ++i) {
    v[i] = pa[i] - pb[i];
    for (int j = 0; j < 3; ++j) {
      const double f = ra[3 * i + j] - rb[3 * i + j];
      v[i] += f * box[kBCenter + j];
      u[j][i] = f * box[kBHalf + j];
    }
  }
  const auto dot = [](const double* x, const double* y) {
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
  };
  const double vu[3] = {dot(v, u[0]), dot(v, u[1]), dot(v, u[2])};
  const double uu[3] = {dot(u[1], u[2]), dot(u[0], u[2]), dot(u[0], u[1])};  // (yz, xz, xy)
  const double base = dot(v, v) + dot(u[0], u[0]) + dot(u[1], u[1]) + dot(u[2], u[2]);
  double worst = 0.0;
  for (const double sx : {-1.0, 1.0}) {
    for (const double sy : {-1.0, 1.0}) {
      for (const double sz : {-1.0, 1.0}) {
        const double cross = sx * vu[0] + sy * vu[1] + sz * vu[2] + sy * sz * uu[0] +
                             sx * sz * uu[1] + sx * sy * uu[2];
        worst = std::max(worst, base + 2.0 * cross);
      }
    }
  }
  const double length = std::sqrt(dot(v, v)) + std::sqrt(dot(u[0], u[0])) +
                        std::sqrt(dot(u[1], u[1])) + std::sqrt(dot(u[2], u[2]));
  const double corner = std::sqrt(worst + 32.0 * kEpsilon * length * length);
  if (corner * (1.0 + 1e-9) + slack <= limit) return true;
  return BoxDeviation(box, pa, ra, pb, rb) <= limit;
}

bool RelativeBound(const double* box, const BoxReach& reach, const double* actual,
                   const double* planned, double limit) {
  // Each relative entry is a sum of three products, rounded within a few ulps of the lengths
  // it combines (|pb - pa|, |qb - qa|: the relative positions' lengths; and 1 for a rotation's
  // entries, times the box's reach); MuJoCo's rotations are orthonormal to as many ulps. 1e-12
  // of them is far above both and far below any distance a plan's gap resolves.
  const double room = RelativeRoom(box, actual, planned, limit);
  // The relative poses differ (RelativePoseWithin's test), so their rotation or position does.
  return room >= 0.0 && BoxBound(box, reach, actual, actual + 3, planned, planned + 3, room);
}

}  // namespace

void RelativePose(const double* pa, const double* ra, const double* pb, const double* rb,
                  double* pos, double* mat) {
  const double d[3] = {pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]};
  for (int i = 0; i < 3; ++i) {
    pos[i] = ra[i] * d[0] + ra[3 + i] * d[1] + ra[6 + i] * d[2];
    for (int j = 0; j < 3; ++j) {
      mat[3 * i + j] = ra[i] * rb[j] + ra[3 + i] * rb[3 + j] + ra[6 + i] * rb[6 + j];
    }
  }
}

bool RelativeWithin(const double* box, const double* pa, const double* ra, const double* pb,
                    const double* rb, const double* qa, const double* sa, const double* qb,
                    const double* sb, double limit) {
  double actual[12], planned[12];
  RelativePose(pa, ra, pb, rb, actual, actual + 3);
  RelativePose(qa, sa, qb, sb, planned, planned + 3);
  return RelativePoseWithin(box, actual, planned, limit);
}

bool RelativePoseWithin(const double* box, const double* actual, const double* planned,
                        double limit) {
  // A plan that is the run: the same relative pose, bit for bit.
  if (std::equal(actual, actual + 12, planned)) return 0.0 <= limit;
  return RelativeBound(box, BoxReach(box), actual, planned, limit);
}

bool RelativePoseWithin(const double* box, const BoxReach& reach, const double* actual,
                        const double* planned, double limit) {
  if (std::equal(actual, actual + 12, planned)) return 0.0 <= limit;
  return RelativeBound(box, reach, actual, planned, limit);
}

std::string Plan::Build(const mjModel* m, mjData* s, const dua_plan_input& in, double h,
                        const double* spheres, int64_t nsphere, const std::vector<int64_t>& geoms,
                        const Plan* prev, std::shared_ptr<PlanPool> pool,
                        KnotKinematics* kinematics) {
  const int64_t n = in.n;
  if (n < 1) return "holds no knot: pass at least one row of qpos";
  if (!std::isfinite(in.start)) {
    return "starts at a time that is not finite (" + Shown(in.start) + ")";
  }
  if (!(h > 0.0) || !std::isfinite(h)) return "has a step that is not a positive time";
  if ((in.mocap_pos == nullptr) != (in.mocap_quat == nullptr)) {
    return "gives mocap positions without orientations or the reverse: give both, (n, nmocap, "
           "3) and (n, nmocap, 4)";
  }
  const int64_t nq = m->nq, ngeom = m->ngeom, nbody = m->nbody, nmocap = m->nmocap;
  const bool mocap = in.mocap_pos != nullptr;
  std::vector<uint8_t> holds(nbody, 0), fixed(nbody, 0);
  for (int64_t b = 0; b < nbody; ++b) {
    const bool in_mocap = m->body_mocapid[m->body_rootid[b]] >= 0;
    fixed[b] = StillBody(m, b);
    if (fixed[b]) continue;
    if (in.bodies == nullptr) {
      holds[b] = !in_mocap || mocap;
    } else if (in.bodies[b]) {
      if (in_mocap && !mocap) {
        return "holds body " + std::to_string(b) + " ('" + NameOf(m, b) +
               "'), in a mocap tree, without mocap poses: give mocap_pos and mocap_quat, or leave "
               "the body out";
      }
      holds[b] = 1;
    }
  }
  // Each check a branch-free pass first (it vectorises; a plan holds a few thousand numbers),
  // the entry the message names searched only when one fails.
  for (int64_t i = AllFinite(in.deviation, n * nbody, true) ? n * nbody : 0; i < n * nbody; ++i) {
    if (!(in.deviation[i] >= 0.0) || !std::isfinite(in.deviation[i])) {
      const int64_t b = i % nbody;
      return "holds a deviation that is not a finite distance >= 0 (knot " +
             std::to_string(i / nbody) + ", body " + std::to_string(b) + ": " +
             Shown(in.deviation[i]) + ") for body '" + NameOf(m, b) +
             "': pass a finite distance >= 0 (0 where the plan is exact)";
    }
  }
  for (int64_t i = 0; mocap && i < n * nmocap * 3; ++i) {
    if (!std::isfinite(in.mocap_pos[i])) {
      return "holds a mocap position that is not finite (knot " + std::to_string(i / 3 / nmocap) +
             ", mocap " + std::to_string(i / 3 % nmocap) + ": " + Shown(in.mocap_pos[i]) + ")";
    }
  }
  for (int64_t i = 0; mocap && i < n * nmocap; ++i) {
    const double* q = in.mocap_quat + 4 * i;
    const double norm = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    if (!(norm > 0.0) || !std::isfinite(norm)) {
      return "holds a mocap orientation that is not a finite non-zero quaternion (knot " +
             std::to_string(i / nmocap) + ", mocap " + std::to_string(i % nmocap) + ")";
    }
  }
  for (int64_t i = AllFinite(in.qpos, n * nq, false) ? n * nq : 0; i < n * nq; ++i) {
    if (!std::isfinite(in.qpos[i])) {
      return "holds a qpos that is not finite (knot " + std::to_string(i / nq) + ", qpos[" +
             std::to_string(i % nq) + "]: " + Shown(in.qpos[i]) + ")";
    }
  }
  nknot_ = n, ngeom_ = ngeom, nbody_ = nbody, nq_ = nq, nmocap_ = mocap ? nmocap : 0;
  // Flexes and sleeping trees read more of the model than KnotKinematics does: those run
  // mj_kinematics on m.
  const bool own = m->nflex == 0 && !(m->opt.enableflags & mjENBL_SLEEP);
  std::unique_ptr<KnotKinematics> mine(own && kinematics == nullptr ? new KnotKinematics(m, geoms)
                                                                    : nullptr);
  KnotKinematics* km = !own ? nullptr : kinematics != nullptr ? kinematics : mine.get();
  // How far the knots' poses may lie from mj_kinematics' (their hinges by polynomials,
  // kinematics.h), added to every deviation the plan declares (docs/theory.md, section 8, "The
  // knots' hinges"): the model's, whichever way these knots are computed, so that every plan of
  // a runtime declares the same.
  if (km != nullptr)
    km->ReadyHinges(n, in.qpos, mocap ? n : 1, mocap ? in.mocap_pos : s->mocap_pos);
  const KnotKinematics* tk = km != nullptr ? km : kinematics;
  // A knot copied from the plan replaced (below) keeps its poses, so this plan declares at least
  // that plan's tolerance: a query on a model whose flexes or sleep call for mj_kinematics (no
  // kinematics of its own) may copy knots that the polynomials computed.
  const double tolerance =
      std::max(tk != nullptr ? tk->tolerance() : 0.0, prev != nullptr ? prev->tolerance() : 0.0);
  std::string why = Relative(m, in, holds, tolerance);
  if (!why.empty()) return why;
  qpos_.assign(in.qpos, in.qpos + n * nq);
  mocap_pos_.clear(), mocap_quat_.clear();
  if (mocap) {
    mocap_pos_.assign(in.mocap_pos, in.mocap_pos + n * nmocap * 3);
    mocap_quat_.assign(in.mocap_quat, in.mocap_quat + n * nmocap * 4);
  }
  Slots(n, ngeom, geoms, std::move(pool));
  int64_t computed = -1;  // the last knot computed
  // The knots KnotKinematics computes, gathered for RunKnots (four at a time in lanes), and
  // their indices.
  std::vector<const double*> kq, kmp, kmq;
  std::vector<double*> kpos, kmat;
  std::vector<int64_t> kat;
  for (int64_t j = 0; j < n; ++j) {
    double* pj = pos_.data() + 3 * nslot_ * j;
    double* rj = mat_.data() + 9 * nslot_ * j;
    // The same rows at the same time in the plan replaced: its poses, bit for bit.
    const int64_t i = prev != nullptr ? prev->KnotOf(in.start + static_cast<double>(j) * h) : -1;
    if (i >= 0 && prev->slot_ == slot_ && SameRow(j, *prev, i)) {
      std::copy_n(prev->pos_.data() + 3 * nslot_ * i, 3 * nslot_, pj);
      std::copy_n(prev->mat_.data() + 9 * nslot_ * i, 9 * nslot_, rj);
    } else if (km) {
      // MuJoCo's arithmetic on the bodies and geoms read, written in place below (kinematics.h).
      kq.push_back(qpos_.data() + nq * j);
      kmp.push_back(mocap ? in.mocap_pos + 3 * nmocap * j : s->mocap_pos);
      kmq.push_back(mocap ? in.mocap_quat + 4 * nmocap * j : s->mocap_quat);
      kpos.push_back(pj), kmat.push_back(rj);
      kat.push_back(j);
      computed = j;
    } else {
      std::copy_n(qpos_.data() + nq * j, nq, s->qpos);
      if (mocap) {
        std::copy_n(in.mocap_pos + 3 * nmocap * j, 3 * nmocap, s->mocap_pos);
        std::copy_n(in.mocap_quat + 4 * nmocap * j, 4 * nmocap, s->mocap_quat);
      }
      mj_kinematics(m, s);
      for (int64_t c = 0; c < nslot_; ++c) {
        std::copy_n(s->geom_xpos + 3 * geoms[c], 3, pj + 3 * c);
        std::copy_n(s->geom_xmat + 9 * geoms[c], 9, rj + 9 * c);
      }
    }
  }
  if (mocap && computed >= 0) {
    // The scratch's mocap poses as mj_kinematics on it would have left them (the last knot
    // computed): a later plan without mocap poses reads them for the mocap bodies it does not
    // hold.
    std::copy_n(in.mocap_pos + 3 * nmocap * computed, 3 * nmocap, s->mocap_pos);
    std::copy_n(in.mocap_quat + 4 * nmocap * computed, 4 * nmocap, s->mocap_quat);
  }
  // The knots gathered are computed as Finish's sweeps reach them, a lanes' batch at a time
  // (each knot's poses then read by its sweep while they are in the cache: computed all first,
  // they were read again from farther out). The same poses: RunKnots' are Run's, bit for bit,
  // however the knots are batched.
  size_t done = 0;  // the knots gathered computed so far
  const auto ready = [&](int64_t j) {
    while (done < kat.size() && kat[done] <= j) {
      const size_t count = std::min<size_t>(kLanes, kat.size() - done);
      km->RunKnots(static_cast<int64_t>(count), kq.data() + done, kmp.data() + done,
                   kmq.data() + done, kpos.data() + done, kmat.data() + done);
      done += count;
    }
  };
  // A geom on a static body has the same pose at every knot (mj_kinematics reads no qpos or
  // mocap pose for it, and a copied knot is one it computed): its sweep's step too.
  std::vector<uint8_t> still(static_cast<size_t>(nslot_));
  for (int64_t c = 0; c < nslot_; ++c) still[c] = fixed[m->geom_bodyid[geoms[c]]];
  why = Finish(m, n, geoms, in.deviation, tolerance, in.start, h, spheres, nsphere,
               std::move(holds), std::move(fixed), &still, ready);
  return why;
}

std::string Plan::Relative(const mjModel* m, const dua_plan_input& in,
                           const std::vector<uint8_t>& holds, double tolerance) {
  rel_key_.clear(), rel_dev_.clear(), rel_rises_.clear();
  if (in.nrel == 0) return "";
  const int64_t nbody = m->nbody, n = in.n;
  if (in.nrel < 0 || in.relative_bodies == nullptr || in.relative_deviation == nullptr) {
    return "gives " + std::to_string(in.nrel) +
           " relative pairs without their bodies or deviations: pass both, (nrel, 2) body ids "
           "and (n, nrel) metres, or neither";
  }
  std::vector<std::pair<int64_t, int64_t>> order;  // (key, column given)
  for (int64_t r = 0; r < in.nrel; ++r) {
    const int64_t a = in.relative_bodies[2 * r], b = in.relative_bodies[2 * r + 1];
    // Named only for an error (a string a pair was 3 % of sawyer's set_plan).
    auto which = [&] {
      return "relative pair " + std::to_string(r) + " (bodies " + std::to_string(a) + ", " +
             std::to_string(b) + ")";
    };
    if (a < 0 || b < 0 || a >= nbody || b >= nbody) {
      return "holds " + which() + ", not bodies of the model's " + std::to_string(nbody) +
             ": pass body ids";
    }
    if (a == b || !holds[a] || !holds[b]) {
      return "holds " + which() + " ('" + NameOf(m, a) + "', '" + NameOf(m, b) +
             "'), not two distinct moving bodies the plan holds: pass pairs of two bodies the "
             "plan holds (a static body's deviation is 0 already)";
    }
    order.emplace_back(std::min(a, b) * nbody + std::max(a, b), r);
  }
  std::sort(order.begin(), order.end());
  for (size_t i = 1; i < order.size(); ++i) {
    if (order[i].first == order[i - 1].first) {
      const int64_t a = order[i].first / nbody, b = order[i].first % nbody;
      return "holds the relative pair of bodies '" + NameOf(m, a) + "' and '" + NameOf(m, b) +
             "' twice (pairs " + std::to_string(order[i - 1].second) + " and " +
             std::to_string(order[i].second) + "): give each body pair once";
    }
  }
  const int64_t nr = in.nrel;
  for (int64_t i = 0; i < n * nr; ++i) {
    const double v = in.relative_deviation[i];
    if (!(v >= 0.0) || !std::isfinite(v)) {
      return "holds a relative deviation that is not a finite distance >= 0 (knot " +
             std::to_string(i / nr) + ", pair " + std::to_string(i % nr) + ": " + Shown(v) +
             "): pass a finite distance >= 0";
    }
  }
  rel_key_.resize(nr);
  rel_dev_.resize(n * nr);
  for (int64_t c = 0; c < nr; ++c) rel_key_[c] = order[c].first;
  // Pair by pair (the caller gives them knot by knot), a block of 8 knots at a time (each
  // pair's column then written a cache line at a time, the block's rows read while they are in
  // the cache; a column over every knot read a row's line a knot); and where min(D_a + D_b,
  // D_ab) rises over the knots, as the sum's own rises_ (a min of two non-decreasing sequences
  // is one; the walk's search needs only the min). D_a and D_b as given: the plan's own
  // deviations (Finish) are those of the bodies it holds, which a pair's two are.
  rel_rises_.assign(nr, 1);
  std::vector<double> last(static_cast<size_t>(nr), 0.0);
  for (int64_t j0 = 0; j0 < n; j0 += 8) {
    const int64_t j1 = std::min<int64_t>(n, j0 + 8);
    for (int64_t c = 0; c < nr; ++c) {
      const int64_t col = order[c].second, a = rel_a(c), b = rel_b(c);
      for (int64_t j = j0; j < j1; ++j) {
        // Widened as the walk reads them (docs/theory.md, section 8, "The knots' hinges"):
        // each body's fl(D + T) (Finish), the pair's fl(D_ab + 3T); the rises are of those.
        const double wide = in.relative_deviation[nr * j + col] + 3.0 * tolerance;
        rel_dev_[n * c + j] = wide;
        const double da = in.deviation[nbody * j + a] + tolerance;
        const double db = in.deviation[nbody * j + b] + tolerance;
        const double now = std::min(da + db, wide);
        if (j > 0 && now < last[c]) rel_rises_[c] = 0;
        last[c] = now;
      }
    }
  }
  return "";
}

void Plan::Slots(int64_t n, int64_t ngeom, const std::vector<int64_t>& geoms,
                 std::shared_ptr<PlanPool> pool) {
  // Only the geoms read are kept, each in its column (slot); the others read as not numbers.
  slot_.assign(ngeom, -1);
  nslot_ = static_cast<int64_t>(geoms.size());
  for (int64_t i = 0; i < nslot_; ++i) slot_[geoms[i]] = i;
  pool_ = std::move(pool);
  auto take = [&](size_t size) { return pool_ ? pool_->Take(size) : Buffer(size); };
  // (One number past the positions: a frame's position is read as four, BodyDeparture.)
  pos_ = take(3 * nslot_ * n + 1), mat_ = take(9 * nslot_ * n), sweep_ = take(nslot_ * n);
  pos_[3 * nslot_ * n] = 0.0;
}

std::string Plan::FromPoses(const mjModel* m, int64_t n, const double* pos, const double* mat,
                            const uint8_t* bodies, const double* deviation, double start, double h,
                            const double* spheres, int64_t nsphere,
                            const std::vector<int64_t>& geoms) {
  const int64_t nbody = m->nbody, ngeom = m->ngeom;
  std::vector<uint8_t> holds(nbody, 0), fixed(nbody, 0);
  for (int64_t b = 0; b < nbody; ++b) {
    const bool in_mocap = m->body_mocapid[m->body_rootid[b]] >= 0;
    fixed[b] = StillBody(m, b);
    holds[b] = !fixed[b] && bodies[b] && !in_mocap;
  }
  // No rows: a plan made from poses is never the `prev` of a Build (SameRow compares rows).
  rel_key_.clear(), rel_dev_.clear(), rel_rises_.clear();
  nknot_ = n, ngeom_ = ngeom, nbody_ = nbody, nq_ = 0, nmocap_ = 0;
  qpos_.clear(), mocap_pos_.clear(), mocap_quat_.clear();
  Slots(n, ngeom, geoms, nullptr);
  for (int64_t j = 0; j < n; ++j) {
    for (int64_t c = 0; c < nslot_; ++c) {
      std::copy_n(pos + 3 * (ngeom * j + geoms[c]), 3, pos_.data() + 3 * (nslot_ * j + c));
      std::copy_n(mat + 9 * (ngeom * j + geoms[c]), 9, mat_.data() + 9 * (nslot_ * j + c));
    }
  }
  return Finish(m, n, geoms, deviation, 0.0, start, h, spheres, nsphere, std::move(holds),
                std::move(fixed));
}

std::string Plan::Finish(const mjModel* m, int64_t n, const std::vector<int64_t>& geoms,
                         const double* deviation, double tolerance, double start, double h,
                         const double* spheres, int64_t nsphere, std::vector<uint8_t> holds,
                         std::vector<uint8_t> fixed, const std::vector<uint8_t>* still,
                         const std::function<void(int64_t)>& ready) {
  // Knot j's poses (and every earlier knot's) in place before they are read.
  const auto need = [&](int64_t j) {
    if (ready) ready(j);
  };
  const int64_t ngeom = m->ngeom, nbody = m->nbody;
  // Each geom's reach about its origin: its bounding radius, or farther for a covering sphere
  // whose centre lies outside it (a grid cell of a mesh's or a cylinder's box).
  std::vector<double> radius(m->geom_rbound, m->geom_rbound + ngeom);
  for (int64_t i = 0; i < nsphere; ++i) {
    const double* rec = spheres + i * kSphereNcol;
    const auto g = static_cast<int64_t>(rec[kSphereFrame]);
    const double* o = rec + kSphereOffset;
    radius[g] = std::max(radius[g], std::sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]));
  }
  // Finite joint positions so large that MuJoCo's kinematics overflows (a slide of 1e308): the
  // first pose of a knot that is not finite, named. Knot 0 is scanned; a later knot only when
  // one of its sweep's squared differences is not finite, which a pose that is not finite makes
  // when the knot before is finite (so the same first pose is named, with no scan of the knots
  // that are).
  const auto unfinite = [&](int64_t j) -> std::string {
    const double* pj = pos_.data() + 3 * nslot_ * j;
    const double* rj = mat_.data() + 9 * nslot_ * j;
    for (int64_t c = 0; c < nslot_; ++c) {
      const int64_t g = geoms[c];
      double bad = 0.0;  // x - x is 0 for every finite x, not a number otherwise
      for (int e = 0; e < 3; ++e) bad += pj[3 * c + e] - pj[3 * c + e];
      if (bad != 0.0) {
        return "puts geom " + std::to_string(g) + " where its position is not finite (knot " +
               std::to_string(j) + "): a qpos too large";
      }
      for (int e = 0; e < 9; ++e) bad += rj[9 * c + e] - rj[9 * c + e];
      if (bad != 0.0) {
        return "puts geom " + std::to_string(g) + " where its rotation is not finite (knot " +
               std::to_string(j) + "): a qpos too large";
      }
    }
    return "";
  };
  if (n > 0) {
    need(n > 1 ? 1 : 0);
    std::string why = unfinite(0);
    if (!why.empty()) return why;
    std::fill_n(sweep_.data(), nslot_, 0.0);
  }
  std::vector<double> reach(static_cast<size_t>(nslot_));
  std::vector<uint8_t> plane(static_cast<size_t>(nslot_));
  for (int64_t c = 0; c < nslot_; ++c) {
    reach[c] = radius[geoms[c]];
    plane[c] = m->geom_type[geoms[c]] == mjGEOM_PLANE;
  }
  // The slots whose poses move from knot to knot; a still one's step (the same poses at every
  // knot: the same Displacement, a pure function of them) is taken once, at knot 1.
  std::vector<int64_t> moving;
  std::vector<std::pair<int64_t, double>> fixed_step;
  for (int64_t c = 0; c < nslot_; ++c) {
    if (still != nullptr && (*still)[c] && n > 1) {
      bool finite = true;
      const double* p = pos_.data() + 3 * c;
      const double* r = mat_.data() + 9 * c;
      fixed_step.emplace_back(
          c, Displacement(p, r, p + 3 * nslot_, r + 9 * nslot_, reach[c], plane[c] != 0, &finite));
    } else {
      moving.push_back(c);
    }
  }
  for (int64_t j = 1; j < n; ++j) {
    need(j);
    const double* pj = pos_.data() + 3 * nslot_ * j;
    const double* rj = mat_.data() + 9 * nslot_ * j;
    double* sw = sweep_.data() + nslot_ * j;
    if (!SweepKnot(pj, rj, nslot_, moving, fixed_step, reach.data(), plane.data(), sw)) {
      std::string why = unfinite(j);
      if (!why.empty()) return why;
    }
  }
  start_ = start, h_ = h, tolerance_ = tolerance;
  dev_.assign(deviation, deviation + n * nbody);
  // The knots' tolerance on every moving body (its poses within it of mj_kinematics'); a static
  // body never moves: its deviation is 0 whatever was given.
  if (tolerance > 0.0) {
    for (double& d : dev_) d += tolerance;
  }
  std::vector<int64_t> static_bodies;
  for (int64_t b = 0; b < nbody; ++b) {
    if (fixed[b]) static_bodies.push_back(b);
  }
  for (int64_t j = 0; j < n; ++j) {
    for (const int64_t b : static_bodies) dev_[nbody * j + b] = 0.0;
  }
  // Per body, the sum over the knots of fall + |fall| (fall: the last knot's deviation less this
  // one's; finite, the deviations checked): 0 exactly when it never falls. Sums over the bodies
  // in vectors, where a test a knot and body with its branch was 15 instructions.
  std::vector<double> falls(static_cast<size_t>(nbody), 0.0);
  for (int64_t j = 1; j < n; ++j) {
    const double* now = dev_.data() + nbody * j;
    const double* before = now - nbody;
    for (int64_t b = 0; b < nbody; ++b) {
      const double fall = before[b] - now[b];
      falls[b] += fall + std::fabs(fall);
    }
  }
  rises_.resize(nbody);
  for (int64_t b = 0; b < nbody; ++b) rises_[b] = falls[b] == 0.0;
  holds_ = std::move(holds), fixed_ = std::move(fixed);
  planes_.clear();
  for (int64_t g = 0; g < ngeom; ++g) {
    if (m->geom_type[g] == mjGEOM_PLANE && holds_[m->geom_bodyid[g]]) planes_.push_back(g);
  }
  geom_body_.assign(m->geom_bodyid, m->geom_bodyid + ngeom);
  return "";
}

const double Plan::kNoPose[9] = {kNaN, kNaN, kNaN, kNaN, kNaN, kNaN, kNaN, kNaN, kNaN};
const double Plan::kNoSweep = kInf;

Buffer PlanPool::Take(size_t n) {
  Buffer v;
  {
    // The smallest buffer that holds n (no new pages), else the largest (the fewest).
    std::lock_guard<std::mutex> lock(mutex);
    size_t best = free.size();
    for (size_t i = 0; i < free.size(); ++i) {
      const size_t c = free[i].capacity();
      if (best == free.size()) {
        best = i;
        continue;
      }
      const size_t b = free[best].capacity();
      if ((c >= n && (b < n || c < b)) || (b < n && c > b)) best = i;
    }
    if (best < free.size()) {
      v = std::move(free[best]);
      free.erase(free.begin() + static_cast<std::ptrdiff_t>(best));
    }
  }
  v.clear();  // no old entry is read: a buffer that grows copies none
  v.resize(n);
  return v;
}

void PlanPool::Give(Buffer&& v) {
  std::lock_guard<std::mutex> lock(mutex);
  // A few plans' worth: as many as are alive at once (the plan and its shadows).
  if (free.size() < 32) free.push_back(std::move(v));
}

Plan::~Plan() {
  if (!pool_) return;
  pool_->Give(std::move(pos_));
  pool_->Give(std::move(mat_));
  pool_->Give(std::move(sweep_));
  pool_->Give(std::move(rel_pose_));
}

bool Plan::SameRow(int64_t j, const Plan& prev, int64_t i) const {
  if (nq_ != prev.nq_ || nmocap_ != prev.nmocap_) return false;
  const double* a = qpos_.data() + nq_ * j;
  if (!std::equal(a, a + nq_, prev.qpos_.data() + nq_ * i)) return false;
  const int64_t np = 3 * nmocap_, nr = 4 * nmocap_;
  return std::equal(mocap_pos_.data() + np * j, mocap_pos_.data() + np * (j + 1),
                    prev.mocap_pos_.data() + np * i) &&
         std::equal(mocap_quat_.data() + nr * j, mocap_quat_.data() + nr * (j + 1),
                    prev.mocap_quat_.data() + nr * i);
}

int64_t Plan::KnotOf(double time) const {
  const double k = std::nearbyint((time - start_) / h_);
  if (!(std::fabs(time - start_ - k * h_) <= 1e-6 * h_)) return -1;
  if (k < 0.0 || k >= static_cast<double>(nknot_)) return -1;
  return static_cast<int64_t>(k);
}

void Plan::Check(const double* pos, const double* mat, int64_t k, const double* boxes, int64_t nbox,
                 const uint8_t* ok, std::vector<int64_t>* broken) const {
  const size_t first = broken->size();
  for (int64_t i = 0; i < nbox; ++i) {
    const double* box = boxes + i * kBNcol;
    const auto b = static_cast<int64_t>(box[kBBody]);
    if (!holds_[b] || (ok != nullptr && !ok[b])) continue;
    const auto g = static_cast<int64_t>(box[kBFrame]);
    // A pose that is not a number is not within any deviation (docs/hardening.md).
    if (!BoxWithin(box, pos + 3 * g, mat + 9 * g, this->pos(k, g), this->mat(k, g), dev(k, b))) {
      broken->push_back(b);
    }
  }
  for (const int64_t g : planes_) {
    const int64_t b = geom_body_[g];
    if ((ok != nullptr && !ok[b]) || std::find(broken->begin() + static_cast<std::ptrdiff_t>(first),
                                               broken->end(), b) != broken->end()) {
      continue;
    }
    // Any change of a plane's pose moves some of its points arbitrarily far.
    const bool same = std::equal(pos + 3 * g, pos + 3 * g + 3, this->pos(k, g)) &&
                      std::equal(mat + 9 * g, mat + 9 * g + 9, this->mat(k, g));
    if (!same) broken->push_back(b);
  }
}

namespace {

// RelativePose at n knots, the two frames' poses a knot's stride apart (3 sp, 9 sp), into out
// (12 a knot): the same function at each, in an AVX2 clone where the CPU has one (no
// contraction, no reordering: the same bits). (A pair's poses a block of knots at a time for
// every pair, the block's frames read while in the cache, cut SetRelativeFrames' first-level
// read misses 94 % on g1 but took 55 % more instructions: not kept, docs/benchmarks.md.)
DUA_LANES_CLONES void RelativePoses(const double* pa, const double* ra, const double* pb,
                                    const double* rb, int64_t sp, int64_t n, double* out) {
  for (int64_t k = 0; k < n; ++k, out += 12) {
    RelativePose(pa, ra, pb, rb, out, out + 3);
    pa += 3 * sp, pb += 3 * sp, ra += 9 * sp, rb += 9 * sp;
  }
}

}  // namespace

void Plan::SetRelativeFrames(const double* boxes, const int64_t* row) {
  const int64_t nr = nrel();
  rel_box_.assign(nr, nullptr);
  rel_reach_.clear();
  rel_reach_.reserve(static_cast<size_t>(nr));
  rel_ga_.assign(nr, -1), rel_gb_.assign(nr, -1);
  rel_pose_ = pool_ ? pool_->Take(12 * nknot_ * nr) : Buffer(12 * nknot_ * nr);
  for (int64_t r = 0; r < nr; ++r) {
    rel_box_[r] = boxes + row[rel_b(r)] * kBNcol;
    rel_reach_.emplace_back(rel_box_[r]);
    rel_ga_[r] = static_cast<int64_t>(boxes[row[rel_a(r)] * kBNcol + kBFrame]);
    rel_gb_[r] = static_cast<int64_t>(rel_box_[r][kBFrame]);
    const int64_t ga = rel_ga_[r], gb = rel_gb_[r];
    double* out = rel_pose_.data() + 12 * nknot_ * r;
    if (slot_[ga] < 0 || slot_[gb] < 0) {  // a frame not kept: not a number, as pos() reads it
      std::fill(out, out + 12 * nknot_, std::nan(""));
      continue;
    }
    // Knot by knot, the two frames' columns a knot's stride apart (pos(k, g), mat(k, g)).
    RelativePoses(pos(0, ga), mat(0, ga), pos(0, gb), mat(0, gb), nslot_, nknot_, out);
  }
}

// The first of count knots s at which within(s) fails, or count when none does: a block of four
// knots whose screen passes(s) passes (in lanes; no knot it passes can fail within) is skipped
// whole, a block it does not pass is checked knot by knot, and the last knots one at a time. The
// nesting's two checks (RelativeDeparture, BodyDeparture), each with its own screen and test.
namespace {

template <class Passes, class Within>
DUA_INLINE int64_t FirstDeparture(int64_t count, const Passes& passes, const Within& within) {
  int64_t s = 0;
  for (; s + kLanes <= count; s += kLanes) {
    if (passes(s)) continue;
    for (int k = 0; k < kLanes; ++k) {
      if (!within(s + k)) return s + k;
    }
  }
  for (; s < count; ++s) {
    if (!within(s)) return s;
  }
  return count;
}

}  // namespace

DUA_LANES_CLONES int64_t RelativeDeparture(const Plan& plan, int64_t rn, int64_t jn,
                                           const Plan& old, int64_t r, int64_t jo, int64_t count) {
  const double* box = old.rel_box(r);
  const BoxReach& reach = old.rel_reach(r);
  // In a's frame, |x - old| <= |x - new| + |new - old| <= D_new + (D_old - D_new): the
  // same nesting as the bodies' (Runtime::SetPlan), of the relative poses.
  const auto within = [&](int64_t s) {
    return RelativePoseWithin(box, reach, plan.rel_pose(jn + s, rn), old.rel_pose(jo + s, r),
                              old.rel_dev(jo + s, r) - plan.rel_dev(jn + s, rn));
  };
  // Four knots at a time (a pair's relative poses follow each other, 12 a knot): RelativeBound's
  // room and BoxBound's first screen in lanes, each lane the same operations in the same order
  // (the same bits). Where a lane passes both, RelativePoseWithin passes (its test of equal
  // poses needs 0 <= limit, which room >= 0 implies).
  const auto passes = [&](int64_t s) {
    const double* a = plan.rel_pose(jn + s, rn);
    const double* p = old.rel_pose(jo + s, r);
    // The 12 entries' differences (d[c], lane k of knot s + k: the poses' 4 x 12 read as three
    // 4 x 4 blocks, transposed), and the positions for the room (the first block's columns).
    Lanes d[12], actual[4], planned[4];
    for (int c = 0; c < 12; c += 4) {
      Lanes ra[kLanes], rp[kLanes], rd[kLanes];
      for (int k = 0; k < kLanes; ++k) {
        ra[k] = Load(a + 12 * k + c), rp[k] = Load(p + 12 * k + c);
        rd[k] = ra[k] - rp[k];
      }
      Transpose4(rd, d + c);
      if (c == 0) Transpose4(ra, actual), Transpose4(rp, planned);
    }
    Lanes limit;
    for (int k = 0; k < kLanes; ++k) {
      limit[k] = old.rel_dev(jo + s + k, r) - plan.rel_dev(jn + s + k, rn);
    }
    const Lanes room = RelativeRoom(box, actual, planned, limit);
    const auto e = [&](int i) { return d[i]; };
    const auto f = [&](int m) { return d[3 + m]; };
    Lanes qmax[3];
    SplatReach(reach, qmax);
    const Lanes bound = NormBound(e, f, qmax);
    return !Any(Not(And(room >= Splat(0.0), bound <= room)));
  };
  return FirstDeparture(count, passes, within);
}

DUA_LANES_CLONES int64_t BodyDeparture(const Plan& plan, int64_t jn, const Plan& old, int64_t jo,
                                       const double* box, const BoxReach& reach, int64_t count) {
  const auto b = static_cast<int64_t>(box[kBBody]);
  const auto g = static_cast<int64_t>(box[kBFrame]);
  // |x - old| <= |x - new| + |new - old| <= D_new + (D_old - D_new): the difference's rounding
  // (an ulp of D_old) is within the 4 ulps the plan's taus allow above D_old.
  const auto within = [&](int64_t s) {
    return BoxWithin(box, reach, plan.pos(jn + s, g), plan.mat(jn + s, g), old.pos(jo + s, g),
                     old.mat(jo + s, g), old.dev(jo + s, b) - plan.dev(jn + s, b));
  };
  // Four knots at a time: BoxBound's first screen in lanes, each lane the same operations in the
  // same order (the same bits). A lane that passes it passes BoxWithin (equal poses give a bound
  // of 0, which passes as their test does, 0 <= limit). Each knot's frame read as rows of four
  // (its position and the next three numbers, its rotation's first eight) and transposed, the
  // rotation's last entry lane by lane: the position's fourth number, the next slot's (or the
  // padding past the last), is read and left.
  const auto passes = [&](int64_t s) {
    Lanes rp[kLanes], r0[kLanes], r4[kLanes], f8;
    for (int k = 0; k < kLanes; ++k) {
      const double *pa = plan.pos(jn + s + k, g), *ra = plan.mat(jn + s + k, g);
      const double *pb = old.pos(jo + s + k, g), *rb = old.mat(jo + s + k, g);
      rp[k] = Load(pa) - Load(pb);
      r0[k] = Load(ra) - Load(rb);
      r4[k] = Load(ra + 4) - Load(rb + 4);
      f8[k] = ra[8] - rb[8];
    }
    Lanes ep[kLanes], fm[2 * kLanes];
    Transpose4(rp, ep), Transpose4(r0, fm), Transpose4(r4, fm + kLanes);
    Lanes limit;
    for (int k = 0; k < kLanes; ++k) limit[k] = old.dev(jo + s + k, b) - plan.dev(jn + s + k, b);
    Lanes qmax[3];
    SplatReach(reach, qmax);
    const auto e = [&](int i) { return ep[i]; };
    const auto f = [&](int m) { return m < 8 ? fm[m] : f8; };
    return !Any(Not(NormBound(e, f, qmax) <= limit));
  };
  return FirstDeparture(count, passes, within);
}

// In an AVX2 clone where the CPU has one (the same operations in the same order: the same bits).
DUA_LANES_CLONES void Plan::CheckRelative(const double* pos, const double* mat, int64_t k,
                                          const uint8_t* ok, const uint8_t* ok_body,
                                          std::vector<int64_t>* broken) const {
  for (int64_t r = 0; r < nrel(); ++r) {
    const int64_t a = rel_a(r), b = rel_b(r);
    if ((ok != nullptr && !ok[r]) || (ok_body != nullptr && (!ok_body[a] || !ok_body[b]))) {
      continue;
    }
    // b's box in the frame of a's box's geom (any frame fixed to a gives the same distances).
    const int64_t ga = rel_ga_[r], gb = rel_gb_[r];
    double actual[12];
    RelativePose(pos + 3 * ga, mat + 9 * ga, pos + 3 * gb, mat + 9 * gb, actual, actual + 3);
    if (!RelativePoseWithin(rel_box_[r], rel_reach_[r], actual, rel_pose(k, r), rel_dev(k, r))) {
      broken->push_back(r);
    }
  }
}

void PlanPass(dua_step_args& a, const int64_t* ids, int64_t count, double* out) {
  dua_plan& pl = a.plan;
  const Plan& plan = *static_cast<const Plan*>(pl.impl);
  auto* d = static_cast<mjData*>(pl.data);
  for (int64_t k = 0; k < count; ++k) {
    const int64_t p = ids[k];
    const int64_t mp = a.ids[p];
    const Judged v = Judge(a, plan, pl.body_ok, d, pl.knot, p, pl.geom1[mp], pl.geom2[mp]);
    pl.planned[k] = v.knot >= 0;
    if (v.knot < 0) continue;
    out[k] = GridTau(v.knot - pl.knot, plan.h(), a.period);
    if (pl.basis != nullptr) pl.basis[p] = v.basis;
  }
}

void PlanCovered(const dua_step_args& a, const int64_t* ids, int64_t count, uint8_t* covered) {
  const dua_plan& pl = a.plan;
  const Plan& plan = *static_cast<const Plan*>(pl.impl);
  for (int64_t k = 0; k < count; ++k) {
    const int64_t mp = a.ids[ids[k]];
    // Judge's first case: BothKnot returns a knot (its walk's, >= the present one).
    covered[k] = NeitherFree(SideOf(plan, pl.body_ok, pl.geom_body[pl.geom1[mp]]),
                             SideOf(plan, pl.body_ok, pl.geom_body[pl.geom2[mp]]));
  }
}

int64_t PlanKnot(dua_step_args& a, const Plan& plan, const uint8_t* ok, int64_t k, int64_t p,
                 int64_t g1, int64_t g2) {
  return Judge(a, plan, ok, static_cast<mjData*>(a.plan.data), k, p, g1, g2).knot;
}

}  // namespace dua
