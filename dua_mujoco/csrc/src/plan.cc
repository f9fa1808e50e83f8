// Flight plans (plan.h). The proofs of what the tau below keeps: docs/theory.md, section 8.
#include "plan.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "internal.h"
#include "layout.h"

namespace dua {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kEpsilon = std::numeric_limits<double>::epsilon();

// A bound on how far any point of a geom moves between poses (p0, r0) and (p1, r1): the
// origin's displacement plus |R1 - R0|_F (>= the spectral norm) times the geom's bounding radius
// about its origin. A plane reaches arbitrarily far: any change is unbounded.
double Displacement(const double* p0, const double* r0, const double* p1, const double* r1,
                    double radius, bool plane) {
  double dp = 0.0, dr = 0.0;
  for (int i = 0; i < 3; ++i) dp += (p1[i] - p0[i]) * (p1[i] - p0[i]);
  for (int i = 0; i < 9; ++i) dr += (r1[i] - r0[i]) * (r1[i] - r0[i]);
  if (plane) return dp == 0.0 && dr == 0.0 ? 0.0 : kInf;
  // Rounded up by a few ulps: the bound must not fall below the true displacement.
  return (std::sqrt(dp) + std::sqrt(dr) * radius) * (1.0 + 8.0 * kEpsilon);
}

// The pair's gap at the sphere level on knot poses (pos, mat): a lower bound on the distance
// between its two spheres (a sphere and a plane, a sphere and a static shape) less the pair's
// contact distance, so a lower bound on the geoms' too.
double SphereGap(const double* rec, const double* spheres, const double* shapes, const double* pos,
                 const double* mat) {
  auto centre = [&](int64_t i, double* c) { PointCentre(spheres + i * kSphereNcol, pos, mat, c); };
  double a[3];
  centre(static_cast<int64_t>(rec[kPairFirst]), a);
  const int kind = static_cast<int>(rec[kPairKind]);
  const double eps = rec[kPairEps];
  if (kind == kKindHalfspace) {
    const int64_t g = static_cast<int64_t>(rec[kPairOther]);
    const double* r = mat + 9 * g;
    const double* p = pos + 3 * g;
    const double n0 = r[2], n1 = r[5], n2 = r[8];
    const double along = n0 * a[0] + n1 * a[1] + n2 * a[2];
    const double off = n0 * p[0] + n1 * p[1] + n2 * p[2];
    return along - off - eps - kGapSlack * (std::fabs(along) + std::fabs(off) + eps);
  }
  if (kind == kKindShape) {
    double n[3], scale;
    const double gap = StaticGap(
        a[0], a[1], a[2], shapes + static_cast<int64_t>(rec[kPairOther]) * kShapeNcol, n, &scale);
    return gap - eps - kGapSlack * (scale + eps);
  }
  double b[3];
  centre(static_cast<int64_t>(rec[kPairSecond]), b);
  const double d0 = b[0] - a[0], d1 = b[1] - a[1], d2 = b[2] - a[2];
  const double dist = std::sqrt(d0 * d0 + d1 * d1 + d2 * d2);
  return dist - eps - kGapSlack * (dist + eps);
}

// The geoms' gap along unit n (first to second) at knot poses f, less the contact distance:
// a lower bound on their distance less it (a separating direction's gap).
double AxisGap(const double* xrec, const dua_exact& x, const dua_frame& f, double n0, double n1,
               double n2, int mode) {
  const int64_t g1 = static_cast<int64_t>(xrec[kXG1]);
  const int64_t g2 = static_cast<int64_t>(xrec[kXG2]);
  int64_t top;
  double low_b;
  if (mode == kModePlane) {
    low_b = n0 * f.pos[3 * g2] + n1 * f.pos[3 * g2 + 1] + n2 * f.pos[3 * g2 + 2];
  } else {
    low_b = -GeomSupport(g2, x, f, -n0, -n1, -n2, static_cast<int64_t>(xrec[kXHull2]), &top);
  }
  const double h_a = GeomSupport(g1, x, f, n0, n1, n2, static_cast<int64_t>(xrec[kXHull1]), &top);
  const double scale = std::fabs(h_a) + std::fabs(low_b) + xrec[kXDist];
  return low_b - h_a - xrec[kXDist] - kGapSlack * scale;
}

// The exact level's gap at knot poses f: the direction that served last, then MuJoCo's witness
// direction at the knot (asked only while the gap is not above `need`). Writes the direction
// MuJoCo gave into the record (any unit direction is valid for any pose).
double ExactGap(double* xrec, dua_exact& x, const dua_frame& f, dua_plan& plan, double need) {
  const int mode = static_cast<int>(xrec[kXMode]);
  if (mode == kModeNone) return -kInf;
  const int64_t g1 = static_cast<int64_t>(xrec[kXG1]);
  const int64_t g2 = static_cast<int64_t>(xrec[kXG2]);
  if (mode == kModePlane) {
    const double* m = f.mat + 9 * g2;
    return AxisGap(xrec, x, f, -m[2], -m[5], -m[8], mode);
  }
  double best = -kInf;
  double n0 = xrec[kXN], n1 = xrec[kXN + 1], n2 = xrec[kXN + 2];
  if (n0 != 0.0 || n1 != 0.0 || n2 != 0.0) {
    best = AxisGap(xrec, x, f, n0, n1, n2, mode);
    if (best > need) return best;
  }
  // MuJoCo's distance at the knot: the two geoms' planned poses in the plan's own mjData.
  mjData* d = static_cast<mjData*>(plan.data);
  for (const int64_t g : {g1, g2}) {
    std::copy_n(f.pos + 3 * g, 3, d->geom_xpos + 3 * g);
    std::copy_n(f.mat + 9 * g, 9, d->geom_xmat + 9 * g);
  }
  const double* p1 = f.pos + 3 * g1;
  const double* p2 = f.pos + 3 * g2;
  const double c0 = p2[0] - p1[0], c1 = p2[1] - p1[1], c2 = p2[2] - p1[2];
  const double reach = std::sqrt(c0 * c0 + c1 * c1 + c2 * c2) + xrec[kXDist] + 1.0;
  mjtNum fromto[6];
  ++plan.queries;
  const double dist = mj_geomDistance(static_cast<const mjModel*>(x.model), d, static_cast<int>(g1),
                                      static_cast<int>(g2), reach, fromto);
  double n[3];
  if (!(dist > xrec[kXDist]) || !WitnessDirection(fromto, x, g1, g2, xrec, n)) {
    return best;  // touching, or no witness
  }
  return std::max(best, AxisGap(xrec, x, f, n[0], n[1], n[2], mode));
}

// A plan's tau, s steps of h, shaved. A plan's taus fall on the step grid, where the deadline
// scheduler's test (w + latency) dt + extra < tau compares two roundings of the same number:
// (alarm steps + w) dt can round below s h and let a pair wait one step past the one at which
// it must stand in alarm (an onset one step short of the horizon). 1e-9 relative is far above
// those roundings (a few ulps) and far below a step; a smaller tau is still a lower bound.
constexpr double kGridShave = 1e-9;
inline double GridTau(int64_t s, double h) {
  return static_cast<double>(s) * h * (1.0 - kGridShave);
}

// tau of held pair p under the plan from knot k: (j - k) h for the first knot j >= k at which
// a lower bound on the pair's planned gap does not exceed both bodies' deviations there, or
// (nknot - k) h when none does (the earliest step a contact could start past the plan). The
// bound at a knot is the sphere level's, then the exact level's; between two knots it is
// carried by the geoms' sweeps (a planned gap G at knot i is at least G - S1(i, j) - S2(i, j)
// at knot j), so that most knots cost a few flops. The tau returned is a whole number of steps
// shaved by kGridShave (GridTau): a lower bound still, and one the scheduler's rounded sums
// cannot cover past its own step.
double PlanTau(dua_step_args& a, const Plan& plan, int64_t p, int64_t g1, int64_t g2, int64_t b1,
               int64_t b2) {
  const double* rec = a.pairs + p * kPairNcol;
  double* xrec = a.exact.on ? a.exact.records + p * kXNcol : nullptr;
  const int64_t k = a.plan.knot, n = plan.nknot();
  double gap = -kInf;  // a lower bound on the planned gap at knot `base`
  int64_t base = -1;
  for (int64_t j = k; j < n; ++j) {
    // Each sum rounded up (a few ulps over its roundings), and the margin asked to exceed the
    // roundings of its own difference: a skipped knot is one whose gap is surely above.
    const double allowed = (plan.dev(j, b1) + plan.dev(j, b2)) * (1.0 + 4.0 * kEpsilon);
    if (base >= 0) {
      const double moved = ((plan.sweep(j, g1) - plan.sweep(base, g1)) +
                            (plan.sweep(j, g2) - plan.sweep(base, g2))) *
                           (1.0 + 8.0 * kEpsilon);
      const double margin = gap - moved - allowed;
      if (margin > 4.0 * kEpsilon * (std::fabs(gap) + moved + allowed)) continue;
    }
    gap = SphereGap(rec, a.spheres, a.shapes, plan.pos(j), plan.mat(j));
    if (gap <= allowed && xrec != nullptr) {
      const dua_frame f{plan.pos(j), plan.mat(j), nullptr, nullptr, nullptr, nullptr};
      gap = std::max(gap, ExactGap(xrec, a.exact, f, a.plan, allowed));
    }
    base = j;
    if (!(gap > allowed)) return GridTau(j - k, plan.h());
  }
  return GridTau(n - k, plan.h());
}

// A bad value as a refusal names it (%g: "nan", "inf", "1e+308").
std::string Shown(double x) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g", x);
  return buf;
}

}  // namespace

std::string Plan::Build(const mjModel* m, mjData* s, const double* qpos, int64_t n,
                        const double* dev, double start, double h) {
  if (n < 1) return "holds no knot: pass at least one row of qpos";
  if (!std::isfinite(start)) return "starts at a time that is not finite (" + Shown(start) + ")";
  if (!(h > 0.0) || !std::isfinite(h)) return "has a step that is not a positive time";
  const int64_t nq = m->nq, ngeom = m->ngeom, nbody = m->nbody;
  for (int64_t i = 0; i < n * nbody; ++i) {
    if (!(dev[i] >= 0.0) || !std::isfinite(dev[i])) {
      return "holds a deviation that is not a finite distance >= 0 (knot " +
             std::to_string(i / nbody) + ", body " + std::to_string(i % nbody) + ": " +
             Shown(dev[i]) + ")";
    }
  }
  std::vector<double> pos(3 * ngeom * n), mat(9 * ngeom * n), sweep(ngeom * n, 0.0);
  for (int64_t j = 0; j < n; ++j) {
    const double* q = qpos + nq * j;
    for (int64_t i = 0; i < nq; ++i) {
      if (!std::isfinite(q[i])) {
        return "holds a qpos that is not finite (knot " + std::to_string(j) + ", qpos[" +
               std::to_string(i) + "]: " + Shown(q[i]) + ")";
      }
    }
    std::copy_n(q, nq, s->qpos);
    mj_kinematics(m, s);
    std::copy_n(s->geom_xpos, 3 * ngeom, pos.begin() + 3 * ngeom * j);
    std::copy_n(s->geom_xmat, 9 * ngeom, mat.begin() + 9 * ngeom * j);
    if (j == 0) continue;
    for (int64_t g = 0; g < ngeom; ++g) {
      const double step = Displacement(
          pos.data() + 3 * (ngeom * (j - 1) + g), mat.data() + 9 * (ngeom * (j - 1) + g),
          pos.data() + 3 * (ngeom * j + g), mat.data() + 9 * (ngeom * j + g), m->geom_rbound[g],
          m->geom_type[g] == mjGEOM_PLANE);
      sweep[ngeom * j + g] = (sweep[ngeom * (j - 1) + g] + step) * (1.0 + 4.0 * kEpsilon);
    }
  }
  // Finite joint positions so large that MuJoCo's kinematics overflows (a slide of 1e308).
  for (int64_t i = 0; i < 3 * ngeom * n; ++i) {
    if (!std::isfinite(pos[i])) {
      return "puts geom " + std::to_string(i / 3 % ngeom) +
             " where its position is not finite (knot " + std::to_string(i / 3 / ngeom) +
             "): a qpos too large";
    }
  }
  for (int64_t i = 0; i < 9 * ngeom * n; ++i) {
    if (!std::isfinite(mat[i])) {
      return "puts geom " + std::to_string(i / 9 % ngeom) +
             " where its rotation is not finite (knot " + std::to_string(i / 9 / ngeom) +
             "): a qpos too large";
    }
  }
  nknot_ = n, ngeom_ = ngeom, nbody_ = nbody;
  start_ = start, h_ = h;
  pos_ = std::move(pos), mat_ = std::move(mat), sweep_ = std::move(sweep);
  dev_.assign(dev, dev + n * nbody);
  return "";
}

int64_t Plan::KnotOf(double time) const {
  const double k = std::nearbyint((time - start_) / h_);
  if (!(std::fabs(time - start_ - k * h_) <= 1e-6 * h_)) return -1;
  if (k < 0.0 || k >= static_cast<double>(nknot_)) return -1;
  return static_cast<int64_t>(k);
}

void Plan::Check(const mjModel* m, const mjData* d, int64_t k, std::vector<int64_t>* broken) const {
  const double* p = pos(k);
  const double* r = mat(k);
  const size_t first = broken->size();
  for (int64_t g = 0; g < ngeom_; ++g) {
    const int64_t b = m->geom_bodyid[g];
    const double moved =
        Displacement(d->geom_xpos + 3 * g, d->geom_xmat + 9 * g, p + 3 * g, r + 9 * g,
                     m->geom_rbound[g], m->geom_type[g] == mjGEOM_PLANE);
    // A pose that is not a number is not within any deviation (docs/hardening.md).
    if (!(moved <= dev(k, b)) && std::find(broken->begin() + static_cast<std::ptrdiff_t>(first),
                                           broken->end(), b) == broken->end()) {
      broken->push_back(b);
    }
  }
}

void PlanPass(dua_step_args& a, const int64_t* ids, int64_t count, double* out) {
  dua_plan& pl = a.plan;
  const Plan& plan = *static_cast<const Plan*>(pl.impl);
  for (int64_t k = 0; k < count; ++k) {
    const int64_t p = ids[k];
    const int64_t mp = a.ids[p];
    const int64_t g1 = pl.geom1[mp], g2 = pl.geom2[mp];
    const int64_t b1 = pl.geom_body[g1], b2 = pl.geom_body[g2];
    // A terrain's pair is left to the motion bounds: the plan's gaps (StaticGap,
    // mj_geomDistance) are no lower bounds on a height field (docs/theory.md, section 9).
    const double* rec = a.pairs + p * kPairNcol;
    const bool terrain =
        static_cast<int>(rec[kPairKind]) == kKindShape &&
        static_cast<int>(
            a.shapes[static_cast<int64_t>(rec[kPairOther]) * kShapeNcol + kShapeKind]) ==
            kGeomHField;
    pl.planned[k] = !terrain && pl.body_ok[b1] && pl.body_ok[b2];
    if (pl.planned[k]) out[k] = PlanTau(a, plan, p, g1, g2, b1, b2);
  }
}

}  // namespace dua
