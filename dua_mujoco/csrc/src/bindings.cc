// dua_mujoco._core: the native core as Python sees it (nanobind). The predictor's runtime
// (runtime.h) behind dua_mujoco.Predictor, the schedules behind dua_mujoco.core.schedules, and
// the kernels the Python side builds tables with or tests hold to their references. Python
// checks the arguments it hands over (shapes, ranges, names in errors); this module checks
// again every index it follows, so that no call can read out of bounds.
#include "bindings.h"

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "dua/dua.h"
#include "internal.h"
#include "layout.h"
#include "runtime.h"
#include "schedule.h"
#include "tables.h"

using nb::literals::operator""_a;

namespace dua {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// ------------------------------------------------------------------------------- kernels

Out<double> TauSpeedBatch(const In<double>& x, const In<double>& v, const In<double>& eps,
                          const In<double>& accel, const In<double>& delta,
                          const In<double>& speed) {
  const int64_t m = Size(x) / 3;
  Require(Size(v) == 3 * m, "x and v must both be (m, 3)");
  int64_t per_pair = 0;
  const In<double>* params[4] = {&eps, &accel, &delta, &speed};
  for (int k = 0; k < 4; ++k) {
    Require(Size(*params[k]) == 1 || Size(*params[k]) == m, "a bound must hold 1 or m entries");
    if (Size(*params[k]) != 1 || m == 1) per_pair |= Size(*params[k]) == m ? (1 << k) : 0;
  }
  std::vector<double> out(m);
  // Large batches on two threads (the kernel is four pairs at a time within each).
  const int64_t threads = m >= 1 << 16 ? 2 : 1;
  auto run = [&](int64_t i0, int64_t i1) {
    auto at = [&](int k) { return params[k]->data() + ((per_pair >> k) & 1 ? i0 : 0); };
    dua_tau_speed_batch(i1 - i0, x.data() + 3 * i0, v.data() + 3 * i0, at(0), at(1), at(2), at(3),
                        per_pair, out.data() + i0);
  };
  {
    nb::gil_scoped_release release;
    if (threads == 1) {
      run(0, m);
    } else {
      const int64_t half = m / 2 / 4 * 4;
      std::thread other(run, half, m);
      run(0, half);
      other.join();
    }
  }
  return Owned(std::move(out), {static_cast<size_t>(m)});
}

Out<double> TauHalfspaceBatch(const In<double>& gap, const In<double>& vn, const In<double>& accel,
                              const In<double>& delta) {
  const int64_t m = std::max({Size(gap), Size(vn), Size(accel), Size(delta)});
  for (const In<double>* a : {&gap, &vn, &accel, &delta}) {
    Require(Size(*a) == 1 || Size(*a) == m, "each argument must hold 1 or m entries");
  }
  auto at = [m](const In<double>& a, int64_t i) { return a.data()[Size(a) == m ? i : 0]; };
  std::vector<double> out(m);
  for (int64_t i = 0; i < m; ++i) {
    out[i] = dua_tau_halfspace(at(gap, i), at(vn, i), at(accel, i), at(delta, i));
  }
  return Owned(std::move(out), {static_cast<size_t>(m)});
}

// The records of a shape table (the rows before its terrain blocks), checked.
int64_t CheckShapes(const In<double>& shapes) {
  const int64_t n = Size(shapes) / kShapeNcol;
  Require(Size(shapes) == n * kShapeNcol, "shape records must be (n, 16)");
  // Terrain (terrain.cc): a record reads its block, which must fit.
  const int64_t bad = dua_check_shapes(shapes.data(), n);
  Require(bad < 0, "shape record " + std::to_string(bad) +
                       " is a terrain whose block does not fit the table: build it with "
                       "dua_mujoco.core.terrain.shape_table");
  const int64_t nrec = ShapeRecordCount(shapes.data(), n);
  for (int64_t i = 0; i < nrec; ++i) {
    const double k = shapes.data()[kShapeNcol * i + kShapeKind];
    Require((k >= kGeomSphere && k <= kGeomMeshBox) || k == kGeomHField,
            "shape record " + std::to_string(i) + " has no known kind");
  }
  return nrec;
}

// tau of points (n, 3) with velocities (n, 3) against static shapes ids[k] (n,).
Out<double> TauStaticBatch(const In<double>& c, const In<double>& v, const In<double>& shapes,
                           const In<int64_t>& ids, const In<double>& eps, const In<double>& accel,
                           const In<double>& delta) {
  const int64_t nshape = CheckShapes(shapes), n = Size(ids);
  Require(Size(c) == 3 * n && Size(v) == 3 * n, "centres and velocities must be (n, 3)");
  auto at = [n](const In<double>& a, int64_t i) { return a.data()[Size(a) == n ? i : 0]; };
  for (const In<double>* a : {&eps, &accel, &delta}) {
    Require(Size(*a) == 1 || Size(*a) == n, "a bound must hold 1 or n entries");
  }
  std::vector<double> out(n);
  for (int64_t k = 0; k < n; ++k) {
    const int64_t s = ids.data()[k];
    // The message is made only for a bad id (time_to_static's shape_ids: it names them so).
    if (s < 0 || s >= nshape) {
      Require(false, "shape_ids[" + std::to_string(k) + "] = " + std::to_string(s) +
                         " is out of range: shapes has " + std::to_string(nshape) +
                         " records (valid ids 0.." + std::to_string(nshape - 1) + ")");
    }
    const double* p = c.data() + 3 * k;
    const double* q = v.data() + 3 * k;
    out[k] = dua_tau_static(p[0], p[1], p[2], q[0], q[1], q[2], shapes.data() + kShapeNcol * s,
                            at(eps, k), at(accel, k), at(delta, k));
  }
  return Owned(std::move(out), {static_cast<size_t>(n)});
}

// One shape kernel over points: fn(point, record, out) with `width` outputs a point.
template <class Fn>
Out<double> OverPoints(const In<double>& points, const In<double>& shapes, const In<int64_t>& ids,
                       int width, Fn fn) {
  const int64_t nshape = CheckShapes(shapes), n = Size(ids);
  Require(Size(points) == 3 * n, "points must be (n, 3), one a shape id");
  std::vector<double> out(static_cast<size_t>(width * n));
  for (int64_t k = 0; k < n; ++k) {
    const int64_t s = ids.data()[k];
    Require(s >= 0 && s < nshape, "a shape id is out of range");
    fn(points.data() + 3 * k, shapes.data() + kShapeNcol * s, out.data() + width * k);
  }
  if (width == 1) return Owned(std::move(out), {static_cast<size_t>(n)});
  return Owned(std::move(out), {static_cast<size_t>(n), static_cast<size_t>(width)});
}

// ------------------------------------------------------------------------------- kinematics

// The instant the kinematics kernel reads, as arrays (MjData's geom_xpos (ngeom, 3), geom_xmat
// (ngeom, 9), cvel (nbody, 6), subtree_com (nbody, 3), the mocap roots' twists (nbody, 6) and xpos
// (nbody, 3)), its shapes checked; *ngeom and *nbody receive its sizes.
dua_frame FrameOfShapes(const In<double>& pos, const In<double>& mat, const In<double>& twist,
                        const In<double>& twist_ref, const In<double>& root_twist,
                        const In<double>& root_origin, int64_t* ngeom, int64_t* nbody) {
  *ngeom = Size(pos) / 3, *nbody = Size(twist) / 6;
  Require(Size(pos) == 3 * *ngeom && Size(mat) == 9 * *ngeom && Size(twist) == 6 * *nbody &&
              Size(twist_ref) == 3 * *nbody && Size(root_twist) == 6 * *nbody &&
              Size(root_origin) == 3 * *nbody,
          "the frame's arrays must be (ngeom, 3), (ngeom, 9), (nbody, 6), (nbody, 3), (nbody, 6), "
          "(nbody, 3)");
  return {pos.data(),       mat.data(),        twist.data(),
          twist_ref.data(), root_twist.data(), root_origin.data()};
}

// FrameOfShapes, and point records (n, 8) that index inside it.
dua_frame FrameOfArrays(const In<double>& pos, const In<double>& mat, const In<double>& twist,
                        const In<double>& twist_ref, const In<double>& root_twist,
                        const In<double>& root_origin, const In<double>& points) {
  int64_t ngeom, nbody;
  const dua_frame f =
      FrameOfShapes(pos, mat, twist, twist_ref, root_twist, root_origin, &ngeom, &nbody);
  const int64_t n = Size(points) / kSphereNcol;
  Require(Size(points) == n * kSphereNcol, "point records must be (n, 8)");
  for (int64_t i = 0; i < n; ++i) {
    const double* r = points.data() + kSphereNcol * i;
    const bool ok = r[kSphereFrame] >= 0 && r[kSphereFrame] < ngeom && r[kSphereBody] >= 0 &&
                    r[kSphereBody] < nbody && r[kSphereRoot] >= 0 && r[kSphereRoot] < nbody;
    // The message is made only for a bad record (made for each, it took 1 us a point).
    if (!ok) {
      Require(false, "the sphere records reference frame " + std::to_string(r[kSphereFrame]) +
                         " and body " + std::to_string(r[kSphereBody]) + " but the data has " +
                         std::to_string(ngeom) + " frames and " + std::to_string(nbody) +
                         " bodies: pass the MjData of the model the spheres were built for");
    }
  }
  return f;
}

Out<double> RigidPoints(const In<double>& points, const In<double>& pos, const In<double>& mat,
                        const In<double>& twist, const In<double>& twist_ref,
                        const In<double>& root_twist, const In<double>& root_origin,
                        const In<int64_t>& ids) {
  const dua_frame f = FrameOfArrays(pos, mat, twist, twist_ref, root_twist, root_origin, points);
  const int64_t npoint = Size(points) / kSphereNcol, n = Size(ids);
  std::vector<double> out(6 * static_cast<size_t>(n));
  for (int64_t k = 0; k < n; ++k) {
    const int64_t i = ids.data()[k];
    if (i < 0 || i >= npoint) {
      Require(false, "sphere id " + std::to_string(i) + " (ids[" + std::to_string(k) +
                         "]) is out of range: the records hold " + std::to_string(npoint) +
                         " spheres (valid ids 0.." + std::to_string(npoint - 1) + ")");
    }
    dua_rigid_point(i, points.data(), &f, out.data() + 6 * k);
  }
  return Owned(std::move(out), {static_cast<size_t>(n), 6});
}

int64_t CheckPoints(const In<double>& points, const In<double>& pos, const In<double>& mat,
                    const In<double>& twist, const In<double>& twist_ref,
                    const In<double>& root_twist, const In<double>& root_origin,
                    const In<double>& prev, InOut<double> cur, int64_t nprev, double h,
                    const In<double>& accel, const In<double>& disc, const In<double>& speed,
                    const In<uint8_t>& check_disc, double rtol, InOut<double> values,
                    InOut<uint8_t> broken) {
  const dua_frame f = FrameOfArrays(pos, mat, twist, twist_ref, root_twist, root_origin, points);
  const int64_t n = Size(points) / kSphereNcol;
  Require(Size(prev) == 9 * n && Size(cur) == 9 * n && Size(accel) == n && Size(disc) == n &&
              (Size(speed) == 0 || Size(speed) == n) && Size(check_disc) == n &&
              Size(values) == 3 * n && Size(broken) == 3 * n,
          "the check's arrays do not fit its points");
  return dua_check_points(points.data(), n, &f, prev.data(), cur.data(), nprev, h, accel.data(),
                          disc.data(), Size(speed) ? speed.data() : nullptr, check_disc.data(),
                          rtol, values.data(), broken.data());
}

// dua_check_groups. Every call checks what its reads rest on (the group records, which alone
// index the frame); the first (update 0) also that each group's points are on its record's frame,
// body and root, with its bounds (they must not change after it).
int64_t CheckGroups(const In<double>& points, const In<double>& pos, const In<double>& mat,
                    const In<double>& twist, const In<double>& twist_ref,
                    const In<double>& root_twist, const In<double>& root_origin,
                    const In<int64_t>& group_start, const In<double>& groups, InOut<double> frames,
                    InOut<int64_t> computed, int64_t update, InOut<double> prev, InOut<double> cur,
                    int64_t nprev, double h, double h_prev, const In<double>& accel,
                    const In<double>& disc, const In<double>& speed, const In<uint8_t>& check_disc,
                    double rtol, InOut<double> values, InOut<uint8_t> broken) {
  const int64_t n = Size(points) / kSphereNcol, ngroup = Size(group_start) - 1;
  Require(Size(points) == n * kSphereNcol, "point records must be (n, 8)");
  Require(Size(prev) == 9 * n && Size(cur) == 9 * n && Size(accel) == n && Size(disc) == n &&
              (Size(speed) == 0 || Size(speed) == n) && Size(check_disc) == n &&
              Size(values) == 3 * n && Size(broken) == 3 * n,
          "the check's arrays do not fit its points");
  Require(ngroup >= 0 && Size(groups) == kGroupNcol * ngroup &&
              Size(frames) == 2 * kFrameRowLen * ngroup && Size(computed) == ngroup,
          "groups, frames and computed must be (ngroup, 10), (ngroup, 2, 30), (ngroup,)");
  Require(update >= 0 && h > 0.0 && h_prev > 0.0, "update must be >= 0 and h, h_prev > 0");
  const int64_t* start = group_start.data();
  Require(ngroup == 0 ? n == 0 : start[0] == 0 && start[ngroup] == n,
          "group_start must run from 0 to the points' count");
  int64_t ngeom, nbody;
  const dua_frame f =
      FrameOfShapes(pos, mat, twist, twist_ref, root_twist, root_origin, &ngeom, &nbody);
  for (int64_t g = 0; g < ngroup; ++g) {
    const double* rec = groups.data() + kGroupNcol * g;
    const bool ok = start[g] < start[g + 1] && rec[kGroupFrame] >= 0 && rec[kGroupFrame] < ngeom &&
                    rec[kGroupBody] >= 0 && rec[kGroupBody] < nbody && rec[kGroupRoot] >= 0 &&
                    rec[kGroupRoot] < nbody;
    if (!ok) {
      Require(false, "group " + std::to_string(g) + " is empty or references frame " +
                         std::to_string(rec[kGroupFrame]) + " and body " +
                         std::to_string(rec[kGroupBody]) + " but the data has " +
                         std::to_string(ngeom) + " frames and " + std::to_string(nbody) +
                         " bodies: pass the MjData of the model the points were built for");
    }
  }
  for (int64_t g = 0; update == 0 && g < ngroup; ++g) {
    const double* rec = groups.data() + kGroupNcol * g;
    for (int64_t i = start[g]; i < start[g + 1]; ++i) {
      const double* p = points.data() + kSphereNcol * i;
      const double v = Size(speed) ? speed.data()[i] : std::numeric_limits<double>::infinity();
      const bool same = p[kSphereFrame] == rec[kGroupFrame] && p[kSphereBody] == rec[kGroupBody] &&
                        p[kSphereRoot] == rec[kGroupRoot] && accel.data()[i] == rec[kGroupAccel] &&
                        disc.data()[i] == rec[kGroupDisc] && v == rec[kGroupSpeed];
      if (!same) {
        Require(false, "point " + std::to_string(i) + " differs from its group " +
                           std::to_string(g) + "'s record in frame, body, root or bounds");
      }
    }
  }
  return dua_check_groups(points.data(), &f, start, groups.data(), ngroup, frames.data(),
                          computed.data(), update, prev.data(), cur.data(), nprev, h, h_prev,
                          accel.data(), disc.data(), Size(speed) ? speed.data() : nullptr,
                          check_disc.data(), rtol, values.data(), broken.data());
}

// ------------------------------------------------------------------------------- pair filter

// MuJoCo's pair filter over per-geom arrays (dua_mujoco/build/pairfilter.py's FilterTables).
struct Filter {
  std::vector<int64_t> body, weld, parent_weld, contype, conaffinity, exclude;
  std::vector<uint8_t> movable, lone;
  dua_filter f{};

  Filter(const In<int64_t>& b, const In<int64_t>& w, const In<int64_t>& pw, const In<uint8_t>& mv,
         const In<int64_t>& ct, const In<int64_t>& ca, const In<uint8_t>& ln, const In<int64_t>& ex,
         bool filterparent)
      : body(b.data(), b.data() + b.size()),
        weld(w.data(), w.data() + w.size()),
        parent_weld(pw.data(), pw.data() + pw.size()),
        contype(ct.data(), ct.data() + ct.size()),
        conaffinity(ca.data(), ca.data() + ca.size()),
        exclude(ex.data(), ex.data() + ex.size()),
        movable(mv.data(), mv.data() + mv.size()),
        lone(ln.data(), ln.data() + ln.size()) {
    const size_t n = body.size();
    Require(weld.size() == n && parent_weld.size() == n && contype.size() == n &&
                conaffinity.size() == n && movable.size() == n && lone.size() == n,
            "the filter's per-geom arrays must have one entry a geom");
    Require(std::is_sorted(exclude.begin(), exclude.end()), "exclude must be sorted");
    f.ngeom = static_cast<int64_t>(n);
    f.body = body.data(), f.weld = weld.data(), f.parent_weld = parent_weld.data();
    f.movable = movable.data(), f.contype = contype.data(), f.conaffinity = conaffinity.data();
    f.lone = lone.data(), f.exclude = exclude.data();
    f.nexclude = static_cast<int64_t>(exclude.size());
    f.filterparent = filterparent ? 1 : 0;
  }

  Out<bool> Mask(const In<int64_t>& g1, const In<int64_t>& g2) const {
    const int64_t n = Size(g1);
    Require(Size(g2) == n, "g1 and g2 must have the same length");
    for (int64_t k = 0; k < n; ++k) {
      Require(g1.data()[k] >= 0 && g1.data()[k] < f.ngeom && g2.data()[k] >= 0 &&
                  g2.data()[k] < f.ngeom,
              "a geom id is out of range");
    }
    std::vector<uint8_t> out(n);
    dua_filter_mask(&f, g1.data(), g2.data(), n, out.data());
    return OwnedBools(std::move(out));
  }

  std::pair<Out<int64_t>, Out<int64_t>> All() const {
    const int64_t n = dua_filter_all(&f, nullptr, nullptr, 0);
    std::vector<int64_t> g1(n), g2(n);
    dua_filter_all(&f, g1.data(), g2.data(), n);
    return {Owned(std::move(g1), {static_cast<size_t>(n)}),
            Owned(std::move(g2), {static_cast<size_t>(n)})};
  }

  std::pair<int64_t, int64_t> Count(const In<int64_t>& weight) const {
    Require(Size(weight) == f.ngeom, "weight must have one entry a geom");
    int64_t weighted = 0;
    const int64_t pairs = dua_filter_count(&f, weight.data(), &weighted);
    return {pairs, weighted};
  }

  bool Any() const { return dua_filter_any(&f) != 0; }
};

// ------------------------------------------------------------------------------- grid, reach

Out<int64_t> CandidatePairs(const In<double>& centers, const In<double>& reach, double margin) {
  const int64_t n = Size(reach);
  Require(Size(centers) == 3 * n, "centres must be (n, 3), one a reach");
  if (n < 2) return Owned(std::vector<int64_t>{}, {0, 2});
  double lo[3], hi[3];
  Require(dua_grid_bounds(centers.data(), n, lo, hi) < 0, "a centre is NaN, inf or beyond 1e150 m");
  dua_grid_plan plan{};
  std::vector<int64_t> held(256);
  std::vector<double> work(n);
  dua_grid_plan_of(reach.data(), n, margin, lo, hi, &plan, held.data(), work.data());
  const int64_t ng = n - plan.nheld;
  std::vector<int32_t> start(plan.nbucket + 1), sid(ng), found(n);
  std::vector<double> sxyz(3 * ng), sr(ng);
  std::vector<int64_t> cnt_a(n), cnt_b(n);
  std::vector<uint8_t> is_held(n);
  const dua_grid_work w{start.data(), sid.data(),   sxyz.data(),  sr.data(),
                        cnt_a.data(), cnt_b.data(), found.data(), is_held.data()};
  const int64_t k = dua_grid_count(&plan, centers.data(), reach.data(), n, margin, held.data(), &w);
  std::vector<int32_t> tmp(k);
  std::vector<int64_t> out(2 * k);
  dua_grid_fill(&plan, centers.data(), reach.data(), n, margin, held.data(), &w, tmp.data(),
                out.data());
  return Owned(std::move(out), {static_cast<size_t>(k), 2});
}

Out<double> Reaches(const In<double>& radius, const In<double>& speed, const In<double>& accel,
                    const In<double>& delta, const In<double>& vmax, double horizon) {
  const int64_t n = Size(radius);
  for (const In<double>* a : {&speed, &accel, &delta, &vmax}) {
    Require(Size(*a) == n, "every array must hold one entry a sphere");
  }
  std::vector<double> out(n);
  dua_reaches(radius.data(), speed.data(), accel.data(), delta.data(), vmax.data(), n, horizon,
              out.data());
  return Owned(std::move(out), {static_cast<size_t>(n)});
}

// Candidate pairs (k, 2) of spheres ids against every sphere by anchors (n, 3) and reaches (n,):
// the pruned step's own search (dua_reach_pairs), for tests.
Out<int64_t> ReachPairs(const In<double>& anchor, const In<double>& reach, double margin,
                        const In<int64_t>& ids) {
  const int64_t nsphere = Size(reach), n = Size(ids);
  Require(Size(anchor) == 3 * nsphere, "anchor must be (n, 3) for reach (n,)");
  for (int64_t k = 0; k < n; ++k) {
    Require(ids.data()[k] >= 0 && ids.data()[k] < nsphere, "a sphere id is out of range");
  }
  dua_reach r{};
  r.nsphere = nsphere;
  r.anchor = const_cast<double*>(anchor.data());  // read only
  r.reach = const_cast<double*>(reach.data());
  r.margin = margin;
  const int64_t count = dua_reach_pairs(&r, ids.data(), n, nullptr, 0);
  std::vector<int64_t> out(2 * static_cast<size_t>(std::max<int64_t>(count, 1)));
  Require(dua_reach_pairs(&r, ids.data(), n, out.data(), count) == count, "the pairs changed");
  out.resize(2 * static_cast<size_t>(count));
  return Owned(std::move(out), {static_cast<size_t>(count), 2});
}

// The spheres of ids (n,) that may have left the reach from anchors (Lemma 6.4): the step's own
// escape test (reach.cc), for free spheres.
Out<int64_t> Escapes(const In<double>& anchor, const In<double>& speed0, const In<double>& accel,
                     const In<double>& delta, const In<double>& vmax, const In<int64_t>& ids,
                     const In<double>& centers, const In<double>& velocities,
                     const In<double>& elapsed) {
  const int64_t nsphere = Size(speed0), n = Size(ids);
  Require(Size(anchor) == 3 * nsphere && Size(accel) == nsphere && Size(delta) == nsphere &&
              Size(vmax) == nsphere,
          "the reach's arrays must hold one entry (anchor: a row) a sphere");
  Require(Size(centers) == 3 * n && Size(velocities) == 3 * n && Size(elapsed) == n,
          "centres, velocities and elapsed times must have one row an id");
  for (int64_t k = 0; k < n; ++k) {
    Require(ids.data()[k] >= 0 && ids.data()[k] < nsphere, "a sphere id is out of range");
  }
  std::vector<double> none(nsphere, 0.0);
  std::vector<int64_t> built(nsphere, 0);
  dua_reach r{};
  r.nsphere = nsphere;
  r.radius = none.data();
  r.accel = accel.data(), r.delta = delta.data(), r.speed = vmax.data();
  r.anchor = const_cast<double*>(anchor.data());  // read only
  r.speed0 = const_cast<double*>(speed0.data());
  r.reach = none.data();
  r.built = built.data();
  std::vector<int64_t> out(std::max<int64_t>(n, 1));
  const int64_t count =
      dua_escapes(&r, ids.data(), n, centers.data(), velocities.data(), elapsed.data(), out.data());
  out.resize(count);
  return Owned(std::move(out), {static_cast<size_t>(count)});
}

// ------------------------------------------------------------------------------- pair tables

nb::tuple SpherePairs(const In<int64_t>& g1, const In<int64_t>& g2, const In<double>& dist,
                      const In<int64_t>& index, const In<int64_t>& start, const In<int64_t>& plane,
                      const In<int64_t>& shape, const In<double>& radius) {
  const int64_t ngp = Size(g1), ngeom = Size(plane), nsphere = Size(radius);
  Require(Size(g2) == ngp && Size(dist) == ngp && Size(index) == ngp,
          "the geom pairs' arrays must have one entry a pair");
  Require(Size(start) == ngeom + 1 && Size(shape) == ngeom, "per-geom arrays of the covering");
  for (int64_t k = 0; k < ngp; ++k) {
    Require(g1.data()[k] >= 0 && g1.data()[k] < ngeom && g2.data()[k] >= 0 && g2.data()[k] < ngeom,
            "a geom id is out of range");
  }
  for (int64_t g = 0; g <= ngeom; ++g) {
    Require(start.data()[g] >= 0 && start.data()[g] <= nsphere &&
                (g == 0 || start.data()[g] >= start.data()[g - 1]),
            "geom_sphere_start must increase within the spheres");
  }
  const int64_t n = dua_sphere_pairs(g1.data(), g2.data(), dist.data(), index.data(), ngp,
                                     start.data(), plane.data(), shape.data(), radius.data(), 0,
                                     nullptr, nullptr, nullptr, nullptr, nullptr);
  std::vector<int64_t> first(n), second(n), gp(n);
  std::vector<int8_t> kind(n);
  std::vector<double> eps(n);
  dua_sphere_pairs(g1.data(), g2.data(), dist.data(), index.data(), ngp, start.data(), plane.data(),
                   shape.data(), radius.data(), n, first.data(), second.data(), kind.data(),
                   gp.data(), eps.data());
  const auto sn = static_cast<size_t>(n);
  return nb::make_tuple(Owned(std::move(first), {sn}), Owned(std::move(second), {sn}),
                        Owned(std::move(kind), {sn}), Owned(std::move(gp), {sn}),
                        Owned(std::move(eps), {sn}));
}

nb::tuple PairBounds(const In<int64_t>& first, const In<int64_t>& second, const In<int8_t>& kind,
                     const In<int64_t>& sphere_body, const In<double>& accel,
                     const In<double>& delta, nb::object speed) {
  const int64_t n = Size(first), nsphere = Size(sphere_body), nbody = Size(accel);
  Require(Size(second) == n && Size(kind) == n, "first, second and kind must match");
  Require(Size(delta) == nbody, "accel and delta must have one entry a body");
  for (int64_t i = 0; i < nsphere; ++i) {
    Require(sphere_body.data()[i] >= 0 && sphere_body.data()[i] < nbody, "a body is out of range");
  }
  for (int64_t p = 0; p < n; ++p) {
    Require(first.data()[p] >= 0 && first.data()[p] < nsphere &&
                (kind.data()[p] != kKindSphere ||
                 (second.data()[p] >= 0 && second.data()[p] < nsphere)),
            "a sphere id is out of range");
  }
  In<double> spd;
  const double* speed_ptr = nullptr;
  if (!speed.is_none()) {
    spd = nb::cast<In<double>>(speed);
    Require(Size(spd) == nbody, "speed must have one entry a body");
    speed_ptr = spd.data();
  }
  std::vector<double> a(n), d(n), s(n);
  dua_pair_bounds(first.data(), second.data(), kind.data(), n, sphere_body.data(), accel.data(),
                  delta.data(), speed_ptr, a.data(), d.data(), s.data());
  const auto sn = static_cast<size_t>(n);
  return nb::make_tuple(Owned(std::move(a), {sn}), Owned(std::move(d), {sn}),
                        Owned(std::move(s), {sn}));
}

std::pair<Out<double>, Out<double>> ContactDistance(const In<double>& margin, const In<double>& gap,
                                                    const In<int64_t>& g1, const In<int64_t>& g2,
                                                    bool override_margin, double o_margin) {
  const int64_t n = Size(g1), ngeom = Size(margin);
  Require(Size(g2) == n && Size(gap) == ngeom, "per-geom margins and gaps, per-pair geoms");
  for (int64_t k = 0; k < n; ++k) {
    Require(g1.data()[k] >= 0 && g1.data()[k] < ngeom && g2.data()[k] >= 0 && g2.data()[k] < ngeom,
            "a geom id is out of range");
  }
  std::vector<double> m(n), g(n);
  dua_contact_distance(margin.data(), gap.data(), g1.data(), g2.data(), n, override_margin ? 1 : 0,
                       o_margin, m.data(), g.data());
  const auto sn = static_cast<size_t>(n);
  return {Owned(std::move(m), {sn}), Owned(std::move(g), {sn})};
}

Out<double> ExactRows(const In<double>& geoms, const In<int64_t>& geom1, const In<int64_t>& geom2,
                      const In<int8_t>& kind, const In<double>& dist) {
  const int64_t n = Size(geom1), ngeom = Size(geoms) / kGxNcol;
  Require(Size(geoms) == ngeom * kGxNcol, "geom records must be (ngeom, 24)");
  Require(Size(geom2) == n && Size(kind) == n && Size(dist) == n, "per-pair arrays must match");
  for (int64_t p = 0; p < n; ++p) {
    Require(geom1.data()[p] >= 0 && geom1.data()[p] < ngeom && geom2.data()[p] >= 0 &&
                geom2.data()[p] < ngeom,
            "a geom id is out of range");
  }
  std::vector<double> out(static_cast<size_t>(kXNcol * n));
  dua_exact_rows(geoms.data(), geom1.data(), geom2.data(), kind.data(), dist.data(), n, out.data());
  return Owned(std::move(out), {static_cast<size_t>(n), static_cast<size_t>(kXNcol)});
}

// ------------------------------------------------------------------------------- schedules

ScheduleSpec SpecOf(int64_t kind, double dt, int64_t latency, int64_t slots_per_bucket, int64_t cap,
                    int64_t max_interval, int64_t backoff, double threshold,
                    std::optional<double> alarm_horizon) {
  ScheduleSpec s;
  s.kind = kind, s.dt = dt, s.latency = latency, s.slots_per_bucket = slots_per_bucket;
  s.cap = cap, s.max_interval = max_interval, s.backoff = backoff, s.threshold = threshold;
  s.alarm_horizon = alarm_horizon.value_or(dt);  // None: one period
  const std::string bad = s.Check();
  if (!bad.empty()) Raise("InvalidInputError", bad + ".");
  return s;
}

using SchedulePtr = std::shared_ptr<Schedule>;

void CheckIds(const Schedule& s, const In<int64_t>& ids) {
  for (int64_t k = 0; k < Size(ids); ++k) {
    const int64_t p = ids.data()[k];
    if (p < 0 || p >= s.m()) {  // the message made only for a bad id
      Require(false, "pair id " + std::to_string(p) + " (ids[" + std::to_string(k) +
                         "]) is out of range: the schedule has " + std::to_string(s.m()) +
                         " pairs (valid ids 0.." + std::to_string(s.m() - 1) + ")");
    }
  }
}

// f(p) of each pair id p of ids (checked), as an (n,) array.
template <class F>
auto PerPair(const Schedule& s, const In<int64_t>& ids, F f) {
  CheckIds(s, ids);
  const auto n = static_cast<size_t>(Size(ids));
  std::vector<decltype(f(int64_t{0}))> out(n);
  for (size_t k = 0; k < n; ++k) out[k] = f(ids.data()[k]);
  return Owned(std::move(out), {n});
}

void BindSchedule(nb::module_& m) {
  nb::class_<Schedule>(m, "Schedule",
                       "A schedule's state and kernels (dua_mujoco.core.schedules wraps it).")
      .def(
          "__init__",
          [](Schedule* self, int64_t kind, double dt, int64_t latency, const In<double>& tau0,
             nb::object active, int64_t slots_per_bucket, int64_t cap, int64_t max_interval,
             int64_t backoff, double threshold, std::optional<double> alarm_horizon) {
            const ScheduleSpec spec = SpecOf(kind, dt, latency, slots_per_bucket, cap, max_interval,
                                             backoff, threshold, alarm_horizon);
            std::vector<double> tau(tau0.data(), tau0.data() + tau0.size());
            for (const double t : tau) Require(!std::isnan(t), "tau0 holds NaN");
            std::vector<uint8_t> on;
            if (!active.is_none()) {
              const auto a = nb::cast<In<uint8_t>>(active);
              Require(a.size() == tau.size(), "active must have one entry a pair");
              on.assign(a.data(), a.data() + a.size());
            }
            new (self) Schedule(spec, tau, on);
          },
          "kind"_a, "dt"_a, "latency"_a, "tau0"_a, nb::arg("active").none() = nb::none(),
          "slots_per_bucket"_a = 1, "cap"_a = 0, "max_interval"_a = 1024, "backoff"_a = 8,
          "threshold"_a = 0.0, nb::arg("alarm_horizon").none() = nb::none())
      .def(
          "select", [](Schedule& s, int64_t n) { return dua_select(s.state(), n); }, "n"_a)
      .def(
          "reinsert",
          [](Schedule& s, int64_t n, int64_t count) {
            Require(count >= 0 && count <= s.width(), "count exceeds the work width");
            return dua_reinsert(s.state(), n, count);
          },
          "n"_a, "count"_a)
      .def(
          "restore",
          [](Schedule& s, int64_t n, int64_t count) { dua_restore(s.state(), n, count); }, "n"_a,
          "count"_a)
      .def(
          "switch",
          [](Schedule& s, const In<int64_t>& ids, bool on, int64_t n_next) {
            CheckIds(s, ids);
            const int64_t changed =
                dua_switch(s.state(), ids.data(), Size(ids), on ? 1 : 0, n_next);
            if (changed) ++s.activation_changes;
            return changed;
          },
          "ids"_a, "on"_a, "n_next"_a)
      .def(
          "make_due",
          [](Schedule& s, int64_t p, int64_t n) {
            Require(p >= 0 && p < s.m(), "pair id out of range");
            dua_make_due(s.state(), p, n);
          },
          "p"_a, "n"_a)
      .def(
          "select_made_due",
          [](Schedule& s, const In<int64_t>& groups, const In<int64_t>& start,
             const In<int64_t>& members, int64_t n) {
            CheckIds(s, members);
            const int64_t ngroup = Size(start) - 1;
            Require(ngroup >= 0 && start.data()[0] == 0 && start.data()[ngroup] == Size(members),
                    "start must run from 0 to len(members)");
            for (int64_t g = 0; g < ngroup; ++g) {
              Require(start.data()[g] <= start.data()[g + 1], "start must not decrease");
            }
            for (int64_t k = 0; k < Size(groups); ++k) {
              Require(groups.data()[k] >= 0 && groups.data()[k] < ngroup,
                      "groups must lie in [0, " + std::to_string(ngroup) + ")");
            }
            return dua::SelectMadeDue(s.state(), groups.data(), Size(groups), start.data(),
                                      members.data(), n);
          },
          "groups"_a, "start"_a, "members"_a, "n"_a,
          "make_due of the members of each of groups (group g: members[start[g]:start[g + 1]]), "
          "in order, then select(n), as the native step runs them (one pass).")
      .def(
          "horizon_of",
          [](const Schedule& s, const In<int64_t>& ids) {
            return PerPair(s, ids, [&s](int64_t p) { return s.HorizonOf(p); });
          },
          "ids"_a)
      .def(
          "next_due",
          [](const Schedule& s, const In<int64_t>& ids) {
            return PerPair(s, ids, [&s](int64_t p) { return s.NextDue(p); });
          },
          "ids"_a, "The step each pair is next evaluated at (-1: a deadline pair switched off).")
      .def_prop_ro(
          "intervals",
          [](const Schedule& s) {
            std::vector<int64_t> out(s.spec().kind == kRank ? s.horizon.size() : 0);
            for (size_t k = 0; k < out.size(); ++k) out[k] = s.Interval(static_cast<int64_t>(k));
            return Ints(out);
          },
          nb::rv_policy::move, "The rank schedule's revisit interval of each bucket, steps.")
      .def_prop_ro("kind", [](const Schedule& s) { return s.spec().kind; })
      .def_prop_ro("dt", [](const Schedule& s) { return s.spec().dt; })
      .def_prop_ro("latency", [](const Schedule& s) { return s.spec().latency; })
      .def_prop_ro(
          "alarm_horizon", [](const Schedule& s) { return s.spec().alarm_horizon; },
          "The alarm horizon, seconds (one period by default).")
      .def_rw("step_count", &Schedule::step_count)
      .def_rw("activation_changes", &Schedule::activation_changes)
      .def_prop_ro("last_tau",
                   [](nb::handle h) {
                     auto& s = nb::cast<Schedule&>(h);
                     return View<double>(s.last_tau.data(), {s.last_tau.size()}, h);
                   })
      .def_prop_ro("active",
                   [](nb::handle h) {
                     auto& s = nb::cast<Schedule&>(h);
                     return View<bool>(reinterpret_cast<bool*>(s.active.data()), {s.active.size()},
                                       h);
                   })
      .def_prop_ro("ints",
                   [](nb::handle h) {
                     auto& s = nb::cast<Schedule&>(h);
                     const size_t m = static_cast<size_t>(s.m());
                     return View<int64_t>(s.ints.data(), {m ? s.ints.size() / m : 0, m}, h);
                   })
      .def_prop_ro("slots",
                   [](nb::handle h) {
                     auto& s = nb::cast<Schedule&>(h);
                     return View<int64_t>(s.slots.data(), {s.slots.size()}, h);
                   })
      .def_prop_ro("horizon",
                   [](nb::handle h) {
                     auto& s = nb::cast<Schedule&>(h);
                     return View<double>(s.horizon.data(), {s.horizon.size()}, h);
                   })
      .def_prop_ro("queue",
                   [](nb::handle h) {
                     auto& s = nb::cast<Schedule&>(h);
                     return View<int64_t>(s.queue.data(), {s.queue.size()}, h);
                   })
      .def_prop_ro("params",
                   [](nb::handle h) {
                     auto& s = nb::cast<Schedule&>(h);
                     return View<int64_t>(s.params.data(), {s.params.size()}, h);
                   })
      .def_prop_ro("work",
                   [](nb::handle h) {
                     auto& s = nb::cast<Schedule&>(h);
                     return View<int64_t>(s.work.data(), {4, s.w_tau.size()}, h);
                   })
      .def_prop_ro("w_tau", [](nb::handle h) {
        auto& s = nb::cast<Schedule&>(h);
        return View<double>(s.w_tau.data(), {s.w_tau.size()}, h);
      });
}

// ------------------------------------------------------------------------------- the runtime

// What one predictor step says: a span of the runtime's alarm log (read-only, never copied).
struct Alarms {
  std::shared_ptr<AlarmLog> log;
  int64_t start = 0, stop = 0, step = 0, deferred = 0;
  double time = 0.0;
  nb::object names;  // the model's geom names (a list), for names
};

template <class T>
nb::ndarray<nb::numpy, const T> SpanOf(nb::handle self, std::vector<T> AlarmLog::* field) {
  auto& a = nb::cast<Alarms&>(self);
  const size_t n = static_cast<size_t>(a.stop - a.start);
  return nb::ndarray<nb::numpy, const T>(((*a.log).*field).data() + a.start, {n}, self);
}

void BindAlarms(nb::module_& m) {
  nb::class_<Alarms>(m, "Alarms",
                     "The alarms of one predictor step (read-only views of the alarm log).")
      .def_ro("step", &Alarms::step, "Predictor step (0 for the initial classification).")
      .def_ro("time", &Alarms::time, "data.time when read.")
      .def_ro("deferred", &Alarms::deferred,
              "Pairs due this step but left for a later one (max_evals_per_step reached).")
      .def_prop_ro(
          "pairs", [](nb::handle h) { return SpanOf(h, &AlarmLog::pair); },
          "(k,) sphere-pair ids that raised an alarm.")
      .def_prop_ro(
          "tau", [](nb::handle h) { return SpanOf(h, &AlarmLog::tau); },
          "(k,) their tau (seconds).")
      .def_prop_ro(
          "new",
          [](nb::handle h) {
            auto& a = nb::cast<Alarms&>(h);
            const size_t n = static_cast<size_t>(a.stop - a.start);
            return nb::ndarray<nb::numpy, const bool>(
                reinterpret_cast<const bool*>(a.log->fresh.data() + a.start), {n}, h);
          },
          "(k,) bool: alarms this step raised, as opposed to ones standing from before.")
      .def_prop_ro(
          "geom1", [](nb::handle h) { return SpanOf(h, &AlarmLog::geom1); },
          "(k,) first geom of each alarmed pair.")
      .def_prop_ro(
          "geom2", [](nb::handle h) { return SpanOf(h, &AlarmLog::geom2); },
          "(k,) second geom (a plane geom for half-space pairs).")
      .def_prop_ro(
          "sphere1", [](nb::handle h) { return SpanOf(h, &AlarmLog::sphere1); },
          "(k,) first sphere of each alarmed pair.")
      .def_prop_ro(
          "sphere2", [](nb::handle h) { return SpanOf(h, &AlarmLog::sphere2); },
          "(k,) second sphere, -1 for half-space and static shape pairs.")
      .def_prop_ro(
          "names",
          [](const Alarms& a) {
            nb::list out;
            for (int64_t k = a.start; k < a.stop; ++k) {
              out.append(nb::make_tuple(a.names[nb::int_(a.log->geom1[k])],
                                        a.names[nb::int_(a.log->geom2[k])]));
            }
            return out;
          },
          "Geom names of each alarmed pair (geom<id> for unnamed geoms).")
      .def_prop_ro(
          "geom_pairs",
          [](const Alarms& a) {
            nb::set out;
            for (int64_t k = a.start; k < a.stop; ++k) {
              const int32_t g1 = a.log->geom1[k], g2 = a.log->geom2[k];
              out.add(nb::make_tuple(std::min(g1, g2), std::max(g1, g2)));
            }
            return out;
          },
          "The distinct alarmed geom pairs (g1, g2), g1 < g2.")
      .def("__len__", [](const Alarms& a) { return a.stop - a.start; })
      .def("__repr__", [](nb::handle h) {
        auto& a = nb::cast<Alarms&>(h);
        return nb::str("Alarms(step={}, time={}, pairs={}, tau={}, new={})")
            .format(a.step, nb::repr(nb::float_(a.time)), nb::repr(h.attr("pairs")),
                    nb::repr(h.attr("tau")), nb::repr(h.attr("new")));
      });
}

// The runtime as Python holds it: the model it runs on and the MjData bound to it.
struct PyRuntime {
  std::unique_ptr<Runtime> rt;
  const mjModel* m = nullptr;
  nb::object model, data, names, step_error;
  const mjData* d = nullptr;

  const mjData* Data() const {
    if (!d) Raise("SchedulerError", "no MjData is bound: call predictor.reset(data) first.");
    return d;
  }

  nb::object MakeAlarms(int64_t n) const {
    Alarms a;
    a.log = rt->log();
    a.start = rt->log_start();
    a.stop = a.start + n;
    a.step = rt->step();
    a.time = d->time;
    a.deferred = rt->deferred();
    a.names = names;
    return nb::cast(std::move(a));
  }

  // One step on the bound MjData, one period after the last: the alarms logged (or fails).
  int64_t Step() const {
    const mjData* d = Data();
    if (!rt->classified()) Fail("unclassified", nb::none());
    if (rt->ClockOf(d->time) != Runtime::Clock::kOnePeriod) {
      Fail("clock", nb::float_(d->time - rt->last_time()));
    }
    const int64_t r = rt->Step(m, d);
    if (r == Runtime::kBadState) Fail("state", nb::none());
    if (r < 0) Fail("pair", nb::int_(rt->ids()[-1 - r]));
    return r;
  }

  // What a watcher reads after a step: (counted geom pairs whose alarm started at it, the least
  // time any counted verdict still vouches for: its tau less the time since it, at least 0,
  // version of the standing set).
  nb::tuple Watched() const {
    const Runtime::Watched& w = rt->watched();
    return nb::make_tuple(w.started, MinTau(), w.version);
  }

  // The least time a counted pair's latest verdict still vouches for (watched's second entry).
  double MinTau() const {
    const double left =
        rt->watched().expiry - rt->tables().schedule.dt * static_cast<double>(rt->step());
    return std::max(left, 0.0);
  }

  // The gym wrapper's info (dua_mujoco/gym.py), written here so that its step is one native
  // call and no Python frame of its own: on Pusher (a 36 us env.step) the wrapper's Python
  // around the step ran 7.7 k instructions a step, more than the step's 4.4 k (callgrind).
  struct InfoWatch {
    enum Cost { kAlarm, kNew, kHorizon };
    Cost cost = kAlarm;
    double horizon = 0.0;
    nb::object names;      // one str a geom
    nb::object pairs;      // the counted geom pairs standing, named, as of version
    int64_t version = -1;  // (-1: not named yet)
    nb::object alarm_pairs, min_tau, cost_term, total;  // the info keys, interned
  };
  std::optional<InfoWatch> info;

  // info["alarm_pairs"] and info["min_tau"] of the latest step or classification; returns
  // (started, min_tau) for the cost.
  std::pair<int64_t, double> WriteWatched(nb::handle out) {
    InfoWatch& w = Info();
    const Runtime::Watched& watched = rt->watched();
    const double min_tau = MinTau();
    if (watched.version != w.version) {  // the set standing changed: name it again
      w.pairs = StandingNames(w.names);
      w.version = watched.version;
    }
    SetItem(out, w.alarm_pairs, w.pairs);
    SetItem(out, w.min_tau, nb::float_(min_tau));
    return {watched.started, min_tau};
  }

  // The counted geom pairs standing, in increasing (g1, g2), as (names[g1], names[g2]).
  nb::tuple StandingNames(nb::handle names) const {
    const std::vector<int64_t> v = rt->WatchedStanding();
    const auto n = static_cast<int64_t>(nb::len(names));
    nb::list out;
    for (size_t k = 0; k < v.size(); k += 2) {
      Require(v[k] < n && v[k + 1] < n, "names has fewer entries than the model's geoms");
      out.append(nb::make_tuple(names[v[k]], names[v[k + 1]]));
    }
    return nb::tuple(out);
  }

  InfoWatch& Info() {
    if (!info) Raise("SchedulerError", "no info is watched: call runtime.watch_info first.");
    return *info;
  }

  static void SetItem(nb::handle out, nb::handle key, nb::handle value) {
    if (PyObject_SetItem(out.ptr(), key.ptr(), value.ptr()) < 0) throw nb::python_error();
  }

  // The step's failure as (kind, value): Python turns it into the error it documents.
  [[noreturn]] void Fail(const char* kind, nb::object value) const {
    PyErr_SetObject(step_error.ptr(), nb::make_tuple(kind, value).ptr());
    throw nb::python_error();
  }
};

void BindMocap(nb::module_& m) {
  auto mocap_id = [](const Mocap& s, int64_t i) {
    Require(i >= 0 && i < Size(s.bodies), "mocap id " + std::to_string(i) +
                                              " is out of range: the model has " +
                                              std::to_string(s.bodies.size()) + " mocap bodies");
  };
  auto rows = [](const std::vector<double>& v) {
    return Owned(std::vector<double>(v), {v.size() / 3, 3});
  };
  nb::class_<Mocap>(m, "Mocap",
                    "The velocities of a model's mocap bodies, by mocap id: backward differences "
                    "of their poses (mocap.h), or given.")
      .def(
          "__init__", [](Mocap* self, nb::handle model) { new (self) Mocap(ModelOf(model)); },
          "model"_a)
      .def(
          "update",
          [](Mocap& s, nb::handle data) {
            const auto nbody = static_cast<int64_t>(s.twist.size() / 6);
            Require(nb::cast<int64_t>(data.attr("xpos").attr("shape")[0]) == nbody,
                    "data is not an MjData of the tracker's model (" + std::to_string(nbody) +
                        " bodies): pass the MjData of the model it was made for");
            s.Update(DataOf(data));
          },
          "data"_a,
          "Difference the poses of data against the latest record (the first call records).")
      .def("reset", &Mocap::Forget, "Forget the poses; differenced velocities zero.")
      .def(
          "set_velocity",
          [mocap_id](Mocap& s, int64_t i, const In<double>& linear, const In<double>& angular) {
            mocap_id(s, i);
            Require(Size(linear) == 3 && Size(angular) == 3, "velocities are (3,)");
            s.Set(i, linear.data(), angular.data());
          },
          "mocap"_a, "linear"_a, "angular"_a)
      .def(
          "clear_velocity",
          [mocap_id](Mocap& s, int64_t i) {
            mocap_id(s, i);
            s.Clear(i);
          },
          "mocap"_a)
      .def_prop_ro(
          "bodies", [](const Mocap& s) { return Ints(s.bodies); }, nb::rv_policy::move,
          "(nmocap,) the body of each mocap id.")
      .def_prop_ro(
          "linear", [rows](const Mocap& s) { return rows(s.linear); }, nb::rv_policy::move,
          "(nmocap, 3) linear velocities of the bodies' origins (a copy).")
      .def_prop_ro(
          "angular", [rows](const Mocap& s) { return rows(s.angular); }, nb::rv_policy::move,
          "(nmocap, 3) angular velocities (a copy).")
      .def_prop_ro(
          "twist",
          [](nb::handle self) {
            const Mocap& s = nb::cast<const Mocap&>(self);
            return View(s.twist.data(), {s.twist.size() / 6, 6}, self);
          },
          "(nbody, 6) [angular; linear] of each mocap body's tree, zero elsewhere (a view).")
      .def_ro("updates", &Mocap::updates, "Records since the last start (the start's included).");
}

// Tables from a dict of float64 arrays by name, read by `build` (BuildTables or FreeTables).
template <class Build>
std::shared_ptr<Tables> TablesOf(nb::dict arrays, const Build& build) {
  std::map<std::string, std::vector<double>> values;
  for (auto [key, value] : arrays) {
    const auto a = nb::cast<In<double>>(value);
    values[nb::cast<std::string>(key)].assign(a.data(), a.data() + a.size());
  }
  const TableSource source = [&values](const std::string& name, std::vector<double>* out,
                                       std::string* why) {
    const auto it = values.find(name);
    if (it == values.end()) {
      *why = "is missing";
      return false;
    }
    *out = it->second;
    return true;
  };
  std::string error;
  std::shared_ptr<const Tables> t = build(source, &error);
  if (!t) Raise("InvalidInputError", error);
  return std::const_pointer_cast<Tables>(t);
}

// Free spheres' centres or velocities (the caller's array `a`), checked before the runtime reads
// them: (n, 3), every entry finite. The error names the array, and the row that is not finite.
const double* FreeStates(const char* name, const In<double>& a, int64_t n) {
  if (a.ndim() != 2 || static_cast<int64_t>(a.shape(0)) != n || a.shape(1) != 3) {
    nb::list shape;
    for (size_t k = 0; k < a.ndim(); ++k) shape.append(a.shape(k));
    Raise("ShapeError", nb::str("{} has shape {}, but the predictor was built for {} spheres: pass "
                                "an ({}, 3) array, a row a sphere, at every call (a new predictor "
                                "for another number)")
                            .format(name, nb::tuple(shape), n, n)
                            .c_str());
  }
  const double* p = a.data();
  bool finite = true;  // (vectorised: NaN and inf fail the comparison)
  for (int64_t k = 0; k < 3 * n; ++k)
    finite &= std::fabs(p[k]) <= std::numeric_limits<double>::max();
  for (int64_t i = 0; !finite && i < n; ++i) {
    const double* x = p + 3 * i;
    if (std::isfinite(x[0]) && std::isfinite(x[1]) && std::isfinite(x[2])) continue;
    Raise("NonFiniteStateError",
          nb::str("{}[{}] = [{}, {}, {}] is not finite: the state diverged or was not computed; "
                  "pass finite {}")
              .format(name, i, x[0], x[1], x[2], name)
              .c_str());
  }
  return p;
}

// The free spheres' pairs (i, j), i < j, standing in alarm: (k, 2) rows in increasing order.
Out<int64_t> StandingSpheres(const Runtime& rt) {
  const std::vector<int64_t>& held = rt.standing();
  const int64_t n = rt.tables().nsphere();
  std::vector<int64_t> codes(held.size());
  for (size_t k = 0; k < held.size(); ++k) {
    const double* rec = rt.HeldRecord(held[k]);
    codes[k] = static_cast<int64_t>(rec[kPairFirst]) * n + static_cast<int64_t>(rec[kPairSecond]);
  }
  std::sort(codes.begin(), codes.end());
  std::vector<int64_t> out(2 * codes.size());
  for (size_t k = 0; k < codes.size(); ++k)
    out[2 * k] = codes[k] / n, out[2 * k + 1] = codes[k] % n;
  return Owned(std::move(out), {codes.size(), 2});
}

// Geom pairs (g1[k], g2[k]) as vectors, each id checked against the model.
std::pair<std::vector<int64_t>, std::vector<int64_t>> GeomIds(const mjModel* m,
                                                              const In<int64_t>& g1,
                                                              const In<int64_t>& g2) {
  Require(Size(g1) == Size(g2), "g1 and g2 must have the same length");
  std::vector<int64_t> a(g1.data(), g1.data() + g1.size());
  std::vector<int64_t> b(g2.data(), g2.data() + g2.size());
  for (size_t k = 0; k < a.size(); ++k) {
    Require(a[k] >= 0 && a[k] < m->ngeom && b[k] >= 0 && b[k] < m->ngeom,
            "a geom id is out of range");
  }
  return {std::move(a), std::move(b)};
}

// A flight plan's arrays as the runtime reads them: qpos (n, nq), deviation (n, nbody), bodies
// (nbody,) uint8 or empty for the default, mocap poses (n, nmocap, 3) and (n, nmocap, 4) or
// empty, relative pairs (nrel, 2) and their deviations (n, nrel) or both empty
// (dua_mujoco/runtime/flightplan.py checks the shapes; the runtime checks the values).
dua_plan_input PlanInput(const mjModel* m, const In<double>& qpos, const In<double>& deviation,
                         double start, const In<uint8_t>& bodies, const In<double>& mocap_pos,
                         const In<double>& mocap_quat, const In<int64_t>& rel_bodies,
                         const In<double>& rel_deviation) {
  Require(qpos.ndim() == 2 && static_cast<int64_t>(qpos.shape(1)) == m->nq, "qpos must be (n, nq)");
  const auto n = static_cast<int64_t>(qpos.shape(0));
  Require(deviation.ndim() == 2 && static_cast<int64_t>(deviation.shape(0)) == n &&
              static_cast<int64_t>(deviation.shape(1)) == m->nbody,
          "deviation must be (n, nbody)");
  Require(Size(bodies) == 0 || Size(bodies) == m->nbody, "bodies must be (nbody,) or empty");
  Require(Size(mocap_pos) == Size(mocap_quat) / 4 * 3 &&
              (Size(mocap_pos) == 0 || Size(mocap_pos) == 3 * n * m->nmocap) &&
              (Size(mocap_quat) == 0 || Size(mocap_quat) == 4 * n * m->nmocap),
          "mocap poses must be (n, nmocap, 3) and (n, nmocap, 4), or both empty");
  dua_plan_input in{};
  in.qpos = qpos.data();
  in.n = n;
  in.deviation = deviation.data();
  in.start = start;
  in.bodies = Size(bodies) ? bodies.data() : nullptr;
  in.mocap_pos = Size(mocap_pos) ? mocap_pos.data() : nullptr;
  in.mocap_quat = Size(mocap_quat) ? mocap_quat.data() : nullptr;
  const int64_t nrel = Size(rel_bodies) / 2;
  Require(Size(rel_bodies) == 2 * nrel && Size(rel_deviation) == n * nrel,
          "relative bodies must be (nrel, 2) and their deviations (n, nrel)");
  in.nrel = nrel;
  in.relative_bodies = nrel ? rel_bodies.data() : nullptr;
  in.relative_deviation = nrel ? rel_deviation.data() : nullptr;
  return in;
}

void BindRuntime(nb::module_& m, nb::handle step_error) {
  nb::class_<Tables>(m, "Tables", "A model's predictor tables, checked against the model.")
      .def_static(
          "build",
          [](nb::handle model, nb::dict arrays) {
            const mjModel* mm = ModelOf(model);
            return TablesOf(arrays, [mm](const TableSource& source, std::string* error) {
              return BuildTables(mm, source, "table '", "'", error);
            });
          },
          "model"_a, "arrays"_a,
          "The tables from a dict of float64 arrays (dua_mujoco/runtime/table_arrays.py), checked.")
      .def_static(
          "free",
          [](nb::dict arrays) {
            return TablesOf(arrays, [](const TableSource& source, std::string* error) {
              return FreeTables(source, "table '", "'", error);
            });
          },
          "arrays"_a,
          "Free spheres' tables (FreeTables: 'config' and 'reach'; core/spheres.py), checked.")
      .def_static(
          "load",
          [](nb::handle model, const std::string& prefix) {
            std::string error;
            std::shared_ptr<const Tables> t = LoadTables(ModelOf(model), prefix, &error);
            if (!t) Raise("InvalidInputError", error);
            return std::const_pointer_cast<Tables>(t);
          },
          "model"_a, "prefix"_a, "The tables in a model's text fields, as the plugin reads them.")
      .def_prop_ro("pruned", [](const Tables& t) { return t.pruned; })
      .def_prop_ro("exact", [](const Tables& t) { return t.exact; })
      .def_prop_ro("nsphere", [](const Tables& t) { return t.nsphere(); });

  nb::class_<PyRuntime>(m, "Runtime",
                        "The predictor at run time (runtime.h), on one MjData or free spheres.")
      .def(
          "__init__",
          [step_error](PyRuntime* self, std::shared_ptr<Tables> tables, nb::object model,
                       nb::object names, int64_t log_steps, int64_t log_min) {
            Require(tables->free == model.is_none(),
                    "free spheres' tables run without a model, a model's with it");
            new (self) PyRuntime();
            self->m = tables->free ? nullptr : ModelOf(model);
            self->model = model;
            self->names = names;
            self->step_error = nb::borrow(step_error);
            self->rt = std::make_unique<Runtime>(std::move(tables), self->m, log_steps, log_min);
          },
          "tables"_a, "model"_a.none(), "names"_a.none(), "log_steps"_a = 4, "log_min"_a = 1 << 14)
      .def(
          "bind",
          [](PyRuntime& self, nb::object data) {
            self.d = DataOf(data);
            self.data = data;
          },
          "data"_a, "Read the state from this MjData (of the runtime's model) from now on.")
      .def(
          "classify",
          [](PyRuntime& self) {
            const int64_t bad = self.rt->Classify(self.m, self.Data());
            if (bad >= 0) self.Fail("pair", nb::int_(self.rt->ids()[bad]));
            return self.MakeAlarms(self.rt->log_count());
          },
          nb::sig("def classify(self) -> Alarms"),
          "The initial classification of the bound MjData's state.")
      .def(
          "step", [](PyRuntime& self) { return self.MakeAlarms(self.Step()); },
          nb::sig("def step(self) -> Alarms"),
          "One predictor step on the bound MjData, one period after the last.")
      .def(
          "watch_info",
          [](PyRuntime& self, const nb::list& names, const std::string& cost, double horizon,
             const std::string& cost_key) {
            PyRuntime::InfoWatch w;
            if (cost == "alarm") {
              w.cost = PyRuntime::InfoWatch::kAlarm;
            } else if (cost == "new") {
              w.cost = PyRuntime::InfoWatch::kNew;
            } else {
              Require(cost == "horizon", "cost must be 'alarm', 'new' or 'horizon'");
              w.cost = PyRuntime::InfoWatch::kHorizon;
            }
            w.horizon = horizon;
            w.names = names;
            auto key = [](const char* k) { return nb::steal(PyUnicode_InternFromString(k)); };
            w.alarm_pairs = key("alarm_pairs");
            w.min_tau = key("min_tau");
            w.cost_term = key(cost_key.c_str());
            w.total = key("cost");
            self.info = std::move(w);
          },
          "names"_a, "cost"_a, "horizon"_a, "cost_key"_a,
          "Watch for the gym wrapper: step_info and observe_info write its info (names: one str "
          "a geom; cost: 'alarm', 'new' or 'horizon', below horizon seconds; cost_key: the key "
          "of the cost term).")
      .def(
          "observe_info", [](PyRuntime& self, nb::handle out) { self.WriteWatched(out); }, "info"_a,
          "info['alarm_pairs'] (the counted geom pairs standing, named) and info['min_tau'] of "
          "the latest step or classification.")
      .def(
          "step_info",
          [](PyRuntime& self, nb::handle out) {
            PyRuntime::InfoWatch& w = self.Info();
            self.Step();
            const auto [started, min_tau] = self.WriteWatched(out);
            double cost = 0.0;
            switch (w.cost) {
              case PyRuntime::InfoWatch::kAlarm:
                cost = nb::len(w.pairs) ? 1.0 : 0.0;
                break;
              case PyRuntime::InfoWatch::kNew:
                cost = static_cast<double>(started);
                break;
              case PyRuntime::InfoWatch::kHorizon:
                cost = min_tau < w.horizon ? 1.0 : 0.0;
                break;
            }
            const nb::float_ term(cost);
            PyRuntime::SetItem(out, w.cost_term, term);
            // info["cost"] = float(info.get("cost", 0.0)) + cost: the env's own cost, if any.
            nb::object before = nb::float_(0.0);
            if (PyDict_Check(out.ptr())) {
              PyObject* own = PyDict_GetItemWithError(out.ptr(), w.total.ptr());
              if (!own && PyErr_Occurred()) throw nb::python_error();
              if (own) before = nb::borrow(own);
            } else {
              before = out.attr("get")(w.total, before);
            }
            PyObject* own = PyNumber_Float(before.ptr());
            if (!own) throw nb::python_error();
            const double total = PyFloat_AS_DOUBLE(own) + cost;
            Py_DECREF(own);
            PyRuntime::SetItem(out, w.total, nb::float_(total));
            return term;
          },
          "info"_a,
          "step, then the wrapper's info (observe_info, the cost term under cost_key, added to "
          "info['cost']): one call a step for the gym wrapper; returns the cost.")
      .def(
          "classify_spheres",
          [](PyRuntime& self, const In<double>& centers, const In<double>& velocities) {
            Runtime& rt = *self.rt;
            const int64_t n = rt.tables().nsphere();
            rt.SetPoints(FreeStates("centers", centers, n),
                         FreeStates("velocities", velocities, n));
            const int64_t bad = rt.Classify(nullptr, nullptr);
            rt.SetPoints(nullptr, nullptr);
            // (The states were checked finite: no pair's can fail.)
            Require(bad < 0, "a free sphere's state was not finite");
            return StandingSpheres(rt);
          },
          "centers"_a, "velocities"_a,
          "Free spheres: the initial classification at centres and velocities (n, 3); the pairs "
          "(i, j) standing in alarm, (k, 2) in increasing order.")
      .def(
          "step_spheres",
          [](PyRuntime& self, const In<double>& centers, const In<double>& velocities) {
            Runtime& rt = *self.rt;
            if (!rt.classified()) {
              Raise("SchedulerError",
                    "step() before reset(): call reset(centers, velocities) first.");
            }
            const int64_t n = rt.tables().nsphere();
            rt.SetPoints(FreeStates("centers", centers, n),
                         FreeStates("velocities", velocities, n));
            const int64_t r = rt.Step(nullptr, nullptr);
            rt.SetPoints(nullptr, nullptr);
            Require(r >= 0, "a free sphere's state was not finite");
            const int64_t broken = rt.pruned_state().broken;
            if (broken >= 0) {
              const nb::object warning =
                  nb::module_::import_("dua_mujoco.exceptions").attr("BoundViolationWarning");
              const nb::str message =
                  nb::str(
                      "sphere {} moved farther or faster than its bounds allow since it was "
                      "anchored (its state at step {}): the guarantee does not hold there; its "
                      "pairs are renewed now. Check accel, speed and vel_uncertainty.")
                      .format(broken, rt.step());
              // Attributed to the caller of SpherePredictor.step.
              if (PyErr_WarnEx(warning.ptr(), message.c_str(), 2) < 0) throw nb::python_error();
            }
            return StandingSpheres(rt);
          },
          "centers"_a, "velocities"_a,
          "Free spheres: one step at centres and velocities (n, 3), one period after the last; "
          "the pairs (i, j) standing in alarm, (k, 2) in increasing order.")
      .def_prop_ro(
          "held_records",
          [](const PyRuntime& s) {
            const Runtime& rt = *s.rt;
            const size_t k = rt.ids().size();
            std::vector<double> out(kPairNcol * k);
            for (size_t p = 0; p < k; ++p) {
              std::copy_n(rt.HeldRecord(static_cast<int64_t>(p)), kPairNcol,
                          out.data() + kPairNcol * p);
            }
            return Owned(std::move(out), {k, static_cast<size_t>(kPairNcol)});
          },
          nb::rv_policy::move, "(held pairs, 8) the held pairs' records, in held order: a copy.")
      .def("clock_of", [](const PyRuntime& self,
                          double time) { return static_cast<int>(self.rt->ClockOf(time)); })
      .def(
          "switch",
          [](PyRuntime& self, const In<int64_t>& pairs, bool on) {
            const int64_t n = self.rt->universe().npair();
            std::vector<int64_t> ids(pairs.data(), pairs.data() + pairs.size());
            for (size_t k = 0; k < ids.size(); ++k) {
              if (ids[k] < 0 || ids[k] >= n) {  // the message made only for a bad id
                Require(false, "pair id " + std::to_string(ids[k]) + " (pairs[" +
                                   std::to_string(k) + "]) is out of range: the predictor knows " +
                                   std::to_string(n) + " sphere pairs (valid ids 0.." +
                                   std::to_string(n - 1) + ")");
              }
            }
            self.rt->Switch(ids, on);
          },
          "pairs"_a, "on"_a)
      .def(
          "pairs_between_bodies",
          [](PyRuntime& self, int body_a, int body_b) {
            Require(body_a >= 0 && body_a < self.m->nbody && body_b < self.m->nbody,
                    "a body id is out of range");
            return Ints(self.rt->PairsBetweenBodies(self.m, body_a, body_b));
          },
          "body_a"_a, "body_b"_a)
      .def(
          "geom_pair_ids",
          [](PyRuntime& self, const In<int64_t>& g1, const In<int64_t>& g2) {
            const auto [a, b] = GeomIds(self.m, g1, g2);
            return Ints(self.rt->GeomPairIds(a, b));
          },
          "g1"_a, "g2"_a)
      .def("deactivate_contacts",
           [](PyRuntime& self) { return self.rt->DeactivateContacts(self.Data()); })
      .def(
          "set_plan",
          [](PyRuntime& self, const In<double>& qpos, const In<double>& deviation, double start,
             const In<uint8_t>& bodies, const In<double>& mocap_pos, const In<double>& mocap_quat,
             const In<int64_t>& rel_bodies, const In<double>& rel_deviation) {
            const dua_plan_input in = PlanInput(self.m, qpos, deviation, start, bodies, mocap_pos,
                                                mocap_quat, rel_bodies, rel_deviation);
            std::vector<double> departures(self.m->nbody);
            const std::string error = self.rt->SetPlan(self.m, in, departures.data());
            if (!error.empty()) Raise("InvalidInputError", "the plan " + error + ".");
            return Owned(std::move(departures), {static_cast<size_t>(self.m->nbody)});
          },
          "qpos"_a, "deviation"_a, "start"_a, "bodies"_a, "mocap_pos"_a, "mocap_quat"_a,
          "rel_bodies"_a, "rel_deviation"_a,
          "Follow a flight plan (Runtime::SetPlan); returns each body's departure time from the "
          "plan it replaces (inf: none).")
      .def(
          "check_plan",
          [](PyRuntime& self) { return Ints(self.rt->CheckPlan(self.m, self.Data())); },
          "Check the plan at the bound MjData's state between steps: the bodies found beyond "
          "their deviation (counted, their pairs due at the next step).")
      .def(
          "basis_of",
          [](const PyRuntime& self, const In<int64_t>& pairs) {
            const std::vector<int64_t>& ids = self.rt->ids();
            const int64_t n = Size(pairs);
            std::vector<uint8_t> out(2 * static_cast<size_t>(n), 0);
            for (int64_t k = 0; k < n; ++k) {
              const auto it = std::lower_bound(ids.begin(), ids.end(), pairs.data()[k]);
              if (it == ids.end() || *it != pairs.data()[k]) continue;  // not held: the bounds
              out[2 * k] = self.rt->basis()[it - ids.begin()];
              out[2 * k + 1] = self.rt->basis_prev()[it - ids.begin()];
            }
            return Owned(std::move(out), {static_cast<size_t>(n), 2});
          },
          "pairs"_a,
          "(n, 2): what the latest verdict of each sphere pair, and the one before, rested on "
          "(bit 0: its first geom's side on the plan, bit 1: its second's; 0 for a pair not "
          "held).")
      .def(
          "plan_query",
          [](PyRuntime& self, const In<double>& qpos, const In<double>& deviation, double start,
             const In<uint8_t>& bodies, const In<double>& mocap_pos, const In<double>& mocap_quat,
             const In<int64_t>& rel_bodies, const In<double>& rel_deviation, const In<int64_t>& g1,
             const In<int64_t>& g2) {
            const dua_plan_input in = PlanInput(self.m, qpos, deviation, start, bodies, mocap_pos,
                                                mocap_quat, rel_bodies, rel_deviation);
            const auto [a, b] = GeomIds(self.m, g1, g2);
            if (self.rt->tables().pruned) self.rt->GeomPairIds(a, b);  // learn the pairs unmet
            std::vector<int64_t> knots;
            const std::string error = self.rt->PlanQuery(self.m, self.Data(), in, a, b, &knots);
            if (!error.empty()) Raise("InvalidInputError", "the plan " + error + ".");
            return Ints(knots);
          },
          "qpos"_a, "deviation"_a, "start"_a, "bodies"_a, "mocap_pos"_a, "mocap_quat"_a,
          "rel_bodies"_a, "rel_deviation"_a, "g1"_a, "g2"_a,
          "Each geom pair's first knot of a candidate plan at which its contact cannot be "
          "excluded (Runtime::PlanQuery); the plan is not followed.")
      .def("clear_plan", [](PyRuntime& self) { self.rt->ClearPlan(); })
      .def_prop_ro("has_plan", [](const PyRuntime& s) { return s.rt->has_plan(); })
      .def_prop_ro("plan_breaks", [](const PyRuntime& s) { return s.rt->plan_breaks(); })
      .def_prop_ro(
          "plan_relative_rises",
          [](const PyRuntime& s) {
            const Plan* p = s.rt->plan();
            std::vector<uint8_t> out;
            for (int64_t r = 0; p != nullptr && r < p->nrel(); ++r) out.push_back(p->rel_rises(r));
            return OwnedBools(std::move(out));
          },
          nb::rv_policy::move,
          "(nrel,) per relative pair of the plan (sorted by body pair) whether min(D_a + D_b, "
          "D_ab), as the walk reads them, never falls (Plan::Relative); for tests.")
      .def_prop_ro(
          "plan_tolerance",
          [](const PyRuntime& s) {
            const Plan* p = s.rt->plan();
            return p != nullptr ? p->tolerance() : 0.0;
          },
          "The tolerance the plan followed declared (Plan::tolerance; 0 without a plan).")
      .def_prop_ro(
          "plan_query_tolerance", [](const PyRuntime& s) { return s.rt->query_tolerance(); },
          "The tolerance the latest plan_query's candidate declared (Plan::tolerance); for tests.")
      .def_prop_ro("plan_queries", [](const PyRuntime& s) { return s.rt->plan_queries(); })
      .def_prop_ro("exact_queries", [](const PyRuntime& s) { return s.rt->exact_queries(); })
      .def_prop_ro(
          "plan_ok", [](const PyRuntime& s) { return OwnedBools(s.rt->plan_ok()); },
          nb::rv_policy::move, "(nbody,) bodies still within their deviation (a copy).")
      .def_prop_ro(
          "plan_span",
          [](const PyRuntime& s) {
            const Plan* p = s.rt->plan();
            return p ? nb::make_tuple(p->start(), p->h(), p->nknot()) : nb::make_tuple();
          },
          "(start, step, knots) of the plan followed, () for none.")
      .def(
          "plan_broken",
          [](const PyRuntime& self) {
            const std::vector<int64_t> out = self.rt->PlanBroken(self.m, self.Data());
            if (!out.empty() && out[0] < 0) return nb::object(nb::none());
            return nb::object(nb::cast(Ints(out)));
          },
          "The bodies of the bound MjData's state beyond their deviation at its knot (None: no "
          "plan covers it); checks only.")
      .def(
          "plan_broken_relative",
          [](const PyRuntime& self) {
            std::vector<int64_t> out = self.rt->PlanBrokenRelative(self.m, self.Data());
            const size_t n = out.size() / 2;
            return Owned(std::move(out), {n, 2});
          },
          "(n, 2) the relative pairs (body ids a < b) of the bound MjData's state beyond their "
          "relative deviation, of the plan and its shadows; checks only.")

      .def(
          "sphere_states",
          [](const PyRuntime& self, const In<int64_t>& ids) {
            const Tables& t = self.rt->tables();
            const int64_t n = Size(ids), nsphere = t.nsphere();
            const dua_frame f = FrameOf(self.Data(), self.rt->mocap().twist.data());
            std::vector<double> out(6 * static_cast<size_t>(n));
            for (int64_t k = 0; k < n; ++k) {
              const int64_t i = ids.data()[k];
              Require(i >= 0 && i < nsphere, "a sphere id is out of range");
              dua_rigid_point(i, t.spheres.data(), &f, out.data() + 6 * k);
            }
            return Owned(std::move(out), {static_cast<size_t>(n), 6});
          },
          "ids"_a, "(n, 6) centres and velocities of covering spheres ids on the bound MjData.")
      .def(
          "watch",
          [](PyRuntime& self, const In<uint8_t>& ignored_geoms, const In<int64_t>& ignored_pairs) {
            Require(Size(ignored_geoms) == self.m->ngeom, "ignored_geoms holds one flag a geom");
            self.rt->Watch(std::vector<uint8_t>(ignored_geoms.data(),
                                                ignored_geoms.data() + ignored_geoms.size()),
                           std::vector<int64_t>(ignored_pairs.data(),
                                                ignored_pairs.data() + ignored_pairs.size()));
          },
          "ignored_geoms"_a, "ignored_pairs"_a,
          "Count, from now on, the geom pairs with no ignored geom and not ignored themselves.")
      .def_prop_ro(
          "watched", [](const PyRuntime& s) { return s.Watched(); },
          "(counted geom pairs whose alarm started at the latest step, the least time a counted "
          "pair's latest verdict still vouches for: its tau less the time since, at least 0; the "
          "version of the set of counted geom pairs standing).")
      .def(
          "exact_only",
          [](PyRuntime& self, const In<int64_t>& ids, const In<double>& coarse,
             double query_below) {
            Require(Size(ids) == Size(coarse), "ids and coarse must have the same length");
            Require(self.rt->tables().exact, "the exact level is off");
            std::vector<int64_t> v(ids.data(), ids.data() + ids.size());
            for (const int64_t p : v) {
              Require(p >= 0 && p < static_cast<int64_t>(self.rt->ids().size()),
                      "a held pair is out of range");
            }
            return Owned(
                self.rt->ExactOnly(
                    self.m, self.Data(), v,
                    std::vector<double>(coarse.data(), coarse.data() + coarse.size()), query_below),
                {v.size()});
          },
          "ids"_a, "coarse"_a, "query_below"_a,
          "For tests: the exact level alone on held pairs ids (records as built), nothing kept.")
      .def(
          "check_bodies_copy",
          [](PyRuntime& self, bool lanes) {
            auto [flagged, state] = self.rt->CheckBodiesCopy(self.m, self.Data(), lanes);
            const size_t nf = flagged.size(), ns = state.size();
            return nb::make_tuple(Owned(std::move(flagged), {nf}), Owned(std::move(state), {ns}));
          },
          "lanes"_a,
          "For tests: the violation check of the bound MjData on a copy of its state: (flagged "
          "rows, the state after, (ceil(nbody / 4), 42, 4) flat).")
      .def(
          "set_escape_check", [](PyRuntime& self, bool on) { self.rt->SetEscapeCheck(on); }, "on"_a,
          "For tests: pruned pairs without the escape check (what it guards).")
      .def_prop_ro("classified", [](const PyRuntime& s) { return s.rt->classified(); })
      .def_prop_ro("step_count", [](const PyRuntime& s) { return s.rt->step(); })
      .def_prop_ro("last_time", [](const PyRuntime& s) { return s.rt->last_time(); })
      .def_prop_ro("schedule", [](const PyRuntime& s) { return s.rt->schedule(); })
      .def_prop_ro(
          "ids", [](const PyRuntime& s) { return Ints(s.rt->ids()); }, nb::rv_policy::move)
      .def_prop_ro("held_version", [](const PyRuntime& s) { return s.rt->held_version(); })
      .def_prop_ro("universe_version", [](const PyRuntime& s) { return s.rt->universe_version(); })
      .def_prop_ro("npair", [](const PyRuntime& s) { return s.rt->universe().npair(); })
      .def(
          "universe",
          [](const PyRuntime& s) {
            const Universe& u = s.rt->universe();
            const auto n = static_cast<size_t>(u.npair());
            nb::dict out;
            out["pairs"] = Owned(std::vector<double>(u.pairs), {n, kPairNcol});
            out["pair_geom"] = Ints(u.pair_geom);
            out["geom1"] = Ints(u.geom1);
            out["geom2"] = Ints(u.geom2);
            out["geom_pairs"] =
                Owned(std::vector<int64_t>(u.geom_pairs), {static_cast<size_t>(u.ngp()), 2});
            out["geom_pair_contact"] =
                Owned(std::vector<double>(u.gp_contact), {static_cast<size_t>(u.ngp()), 2});
            const size_t nx = u.exact.empty() ? 0 : n;
            out["exact"] = Owned(std::vector<double>(u.exact), {nx, static_cast<size_t>(kXNcol)});
            return out;
          },
          "The pairs known now (copies): records, geom pairs and the exact level's records.")
      .def_prop_ro(
          "on", [](const PyRuntime& s) { return OwnedBools(s.rt->on()); }, nb::rv_policy::move)
      .def_prop_ro(
          "standing",
          [](const PyRuntime& s) {
            std::vector<int64_t> out;
            const std::vector<uint8_t>& st = s.rt->stands();
            for (size_t k = 0; k < st.size(); ++k) {
              if (st[k]) out.push_back(s.rt->ids()[k]);
            }
            return Ints(out);
          },
          "Model pair ids standing in alarm now, sorted.", nb::rv_policy::move)
      .def_prop_ro("nstanding", [](const PyRuntime& s) { return s.rt->nstanding(); })
      .def_prop_ro("min_tau", [](const PyRuntime& s) { return s.rt->min_tau(); })
      .def_prop_ro("evaluated", [](const PyRuntime& s) { return s.rt->evaluated(); })
      .def_prop_ro("deferred", [](const PyRuntime& s) { return s.rt->deferred(); })
      .def_prop_ro(
          "flagged_bodies", [](const PyRuntime& s) { return Ints(s.rt->FlaggedBodies()); },
          nb::rv_policy::move)
      .def_prop_ro("flagged", [](const PyRuntime& s) { return s.rt->flagged(); })
      .def_prop_ro("violation_events", [](const PyRuntime& s) { return s.rt->violation_events(); })
      .def_prop_ro("rebuilds", [](const PyRuntime& s) { return s.rt->rebuilds(); })
      .def_prop_ro("renewals", [](const PyRuntime& s) { return s.rt->renewals(); })
      .def_prop_ro(
          "anchor_steps", [](const PyRuntime& s) { return Ints(s.rt->anchor_steps()); },
          nb::rv_policy::move)
      .def_prop_ro(
          "exact_records",
          [](const PyRuntime& s) {
            const std::vector<double>& r = s.rt->exact_records();
            const auto ncol = static_cast<size_t>(kXNcol);
            return Owned(std::vector<double>(r), {r.size() / ncol, ncol});
          },
          nb::rv_policy::move, "The exact level's records with the directions learnt: a copy.")
      .def_prop_ro(
          "exact_witness",
          [](const PyRuntime& s) {
            const std::vector<double>& w = s.rt->exact_witness();
            return Owned(std::vector<double>(w), {w.size() / 6, 6});
          },
          nb::rv_policy::move,
          "The exact level's witness points of each held pair's latest query, first geom's then "
          "second's, each in its geom's frame (NaN before the first): a copy.")
      .def(
          "reaches",
          [](const PyRuntime& s) {
            const PrunedState& ps = s.rt->pruned_state();
            const size_t n = ps.reach.size();
            nb::dict out;
            out["anchor"] = Owned(std::vector<double>(ps.anchor), {n, 3});
            out["reach"] = Owned(std::vector<double>(ps.reach), {n});
            out["built"] = Ints(ps.built);
            out["margin"] = s.rt->tables().held.margin;
            return out;
          },
          "Pruned pairs: each sphere's anchor (n, 3), reach (n,), anchor step (n,), and the "
          "largest contact distance beyond the radii (copies).")
      .def_prop_ro(
          "mocap", [](PyRuntime& s) -> Mocap& { return s.rt->mocap(); },
          nb::rv_policy::reference_internal,
          "The mocap bodies' velocities, differenced at each step (or given).");
}

}  // namespace
}  // namespace dua

NB_MODULE(_core, m) {
  using namespace dua;  // NOLINT: the module's own names
  m.doc() = "dua_mujoco's native core (libdua_mujoco) as Python calls it.";
  nb::dict layout;
  for (int64_t i = 0; dua_layout_name(i); ++i) layout[dua_layout_name(i)] = dua_layout_value(i);
  m.attr("LAYOUT") = layout;
  m.attr("TABLES_VERSION") = kTablesVersion;
  m.def(
      "structure_hash", [](nb::handle model) { return StructureHash(ModelOf(model)); }, "model"_a,
      "FNV-1a of geom_type, geom_bodyid, body_parentid (what the tables check).");

  m.def("tau_speed_batch", &TauSpeedBatch, "x"_a, "v"_a, "eps"_a, "accel"_a, "delta"_a, "speed"_a);
  m.def("tau_halfspace_batch", &TauHalfspaceBatch, "gap"_a, "vn"_a, "accel"_a, "delta"_a);
  m.def(
      "settle_tau",
      [](double x0, double x1, double x2, double v0, double v1, double v2, double eps, double accel,
         double delta, double cover) {
        const double x[3] = {x0, x1, x2}, v[3] = {v0, v1, v2};
        return SettleTau(x, v, eps, accel, delta, cover);
      },
      "x0"_a, "x1"_a, "x2"_a, "v0"_a, "v1"_a, "v2"_a, "eps"_a, "accel"_a, "delta"_a,
      "cover"_a = 0.0,
      "The bound that settles a flagged body's pair (the step's SettleBound on a sphere pair's "
      "relative state; cover > 0: just above it where it covers that long): at most TauAccel's "
      "exact first root; -inf where it does not apply.");
  m.def(
      "screen_clears",
      [](const std::vector<double>& first, const std::vector<double>& second, double eps,
         double accel, double delta, double h) {
        if (first.size() != 6 || second.size() != 6) {
          throw nb::value_error(("screen_clears takes two sphere rows of 6 numbers (centre, "
                                 "velocity), not " +
                                 std::to_string(first.size()) + " and " +
                                 std::to_string(second.size()))
                                    .c_str());
        }
        double a[4], b[4];
        ScreenRow(first.data(), Tame(first.data()), a);
        ScreenRow(second.data(), Tame(second.data()), b);
        return ScreenClearsRows(a, b, ScreenBase(eps, accel, delta, h), h);
      },
      "first"_a, "second"_a, "eps"_a, "accel"_a, "delta"_a, "h"_a,
      "The deadline schedule's screen on one sphere pair, as a step runs it (docs/theory.md, "
      "section 3, 'The screen'): whether two spheres whose rows (centre, velocity) are first "
      "and second cannot come within eps of each other in h seconds under the pair's bounds "
      "(accel, delta).");
  m.def("tau_static_batch", &TauStaticBatch, "centers"_a, "velocities"_a, "shapes"_a, "ids"_a,
        "eps"_a, "accel"_a, "delta"_a);
  m.def(
      "support",
      [](const In<double>& n, const In<double>& shapes, const In<int64_t>& ids) {
        return OverPoints(n, shapes, ids, 1, [](const double* p, const double* rec, double* out) {
          *out = dua_support(p, rec);
        });
      },
      "directions"_a, "shapes"_a, "ids"_a);
  m.def(
      "closest_point",
      [](const In<double>& c, const In<double>& shapes, const In<int64_t>& ids) {
        return OverPoints(c, shapes, ids, 3, [](const double* p, const double* rec, double* out) {
          dua_closest_point(p, rec, out);
        });
      },
      "points"_a, "shapes"_a, "ids"_a);
  m.def(
      "static_gap",
      [](const In<double>& c, const In<double>& shapes, const In<int64_t>& ids) {
        return OverPoints(c, shapes, ids, 4, [](const double* p, const double* rec, double* out) {
          dua_static_gap(p, rec, out);
        });
      },
      "points"_a, "shapes"_a, "ids"_a);
  // Terrain (dua_mujoco/core/terrain.py).
  m.def(
      "check_shapes",
      [](const In<double>& shapes) {
        Require(Size(shapes) % kShapeNcol == 0, "shape records must be (n, 16)");
        return dua_check_shapes(shapes.data(), Size(shapes) / kShapeNcol);
      },
      "shapes"_a, "The first terrain record whose block does not fit the table, or -1.");
  m.def(
      "shape_record_count",
      [](const In<double>& shapes) {
        Require(Size(shapes) % kShapeNcol == 0, "shape records must be (n, 16)");
        return ShapeRecordCount(shapes.data(), Size(shapes) / kShapeNcol);
      },
      "shapes"_a, "How many leading rows of a shape table are records (then terrain blocks).");
  m.def(
      "tau_terrain",
      [](const In<double>& table, int64_t row, const In<double>& shape, const In<double>& v,
         double spin, double eps, double accel, double delta) {
        const int64_t n = Size(table) / kShapeNcol;
        Require(Size(table) == n * kShapeNcol && dua_check_shapes(table.data(), n) < 0,
                "table must be a shape table (n, 16) whose terrain blocks fit");
        Require(row >= 0 && row < ShapeRecordCount(table.data(), n) &&
                    table.data()[kShapeNcol * row + kShapeKind] == kGeomHField,
                "row must be a terrain record of the table");
        Require(Size(shape) == kShapeNcol && Size(v) == 3, "shape must be (16,), v (3,)");
        const double k = shape.data()[kShapeKind];
        Require(k >= kGeomSphere && k <= kGeomMeshBox, "shape must be a convex shape record");
        int path = -1;
        const double tau = TauTerrain(table.data() + kShapeNcol * row, shape.data(), v.data(), spin,
                                      eps, accel, delta, &path);
        return std::make_pair(tau, path);
      },
      "table"_a, "row"_a, "shape"_a, "v"_a, "spin"_a, "eps"_a, "accel"_a, "delta"_a,
      "tau of a convex shape record moving with velocity v against terrain record `row`, and what\n"
      "decided it: 0 the base or the first cell, 1 the cells within reach one by one, 2 the\n"
      "pyramid's branch and bound (so that tests can assert the search ran).");
  m.def("deadline_interval", &dua_deadline_interval, "tau"_a, "dt"_a, "latency"_a, "max_interval"_a,
        "extra"_a = 0.0);
  m.def(
      "grid_tau", [](double tau, double h, int64_t period) { return GridFloor(tau, h, period); },
      "tau"_a, "h"_a, "period"_a,
      "A lower bound tau on the time to the first state in contact, counted in whole physics\n"
      "steps of h (rounded up) and put on the grid of `period` steps, as the step does at\n"
      "period > 1 (so that tests can hold it to the exact ceiling).");
  m.def(
      "exceeds12",
      [](const In<double>& q, double bound) {
        Require(Size(q) == 12, "q holds twelve entries");
        const double* a = q.data();
        return dua_exceeds12(a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8], a[9], a[10],
                             a[11], bound) != 0;
      },
      "q"_a, "bound"_a);
  m.def("rigid_points", &RigidPoints, "points"_a, "pos"_a, "mat"_a, "twist"_a, "twist_ref"_a,
        "root_twist"_a, "root_origin"_a, "ids"_a,
        "(n, 6) centres and velocities of points ids on a frame (dua_rigid_point).");
  m.def("check_points", &CheckPoints, "points"_a, "pos"_a, "mat"_a, "twist"_a, "twist_ref"_a,
        "root_twist"_a, "root_origin"_a, "prev"_a, "cur"_a, "nprev"_a, "h"_a, "accel"_a, "disc"_a,
        "speed"_a, "check_disc"_a, "rtol"_a, "values"_a, "broken"_a);
  m.def("check_groups", &CheckGroups, "points"_a, "pos"_a, "mat"_a, "twist"_a, "twist_ref"_a,
        "root_twist"_a, "root_origin"_a, "group_start"_a, "groups"_a, "frames"_a, "computed"_a,
        "update"_a, "prev"_a, "cur"_a, "nprev"_a, "h"_a, "h_prev"_a, "accel"_a, "disc"_a, "speed"_a,
        "check_disc"_a, "rtol"_a, "values"_a, "broken"_a);
  m.def(
      "index_by_row",
      [](const In<int64_t>& row_of_geom, const In<int64_t>& g1, const In<int64_t>& g2,
         int64_t nrow) {
        const int64_t n = Size(g1), ngeom = Size(row_of_geom);
        Require(Size(g2) == n, "g1 and g2 must have the same length");
        for (int64_t k = 0; k < n; ++k) {
          Require(g1.data()[k] >= -1 && g1.data()[k] < ngeom && g2.data()[k] >= -1 &&
                      g2.data()[k] < ngeom,
                  "a geom id is out of range");
        }
        for (int64_t g = 0; g < ngeom; ++g) {
          Require(row_of_geom.data()[g] >= -1 && row_of_geom.data()[g] < nrow,
                  "a row is out of range");
        }
        std::vector<int64_t> start(nrow + 1), members(std::max<int64_t>(2 * n, 1));
        members.resize(dua_index_by_row(row_of_geom.data(), g1.data(), g2.data(), n, nrow,
                                        start.data(), members.data()));
        const size_t ns = start.size(), nm = members.size();
        return nb::make_tuple(Owned(std::move(start), {ns}), Owned(std::move(members), {nm}));
      },
      "row_of_geom"_a, "g1"_a, "g2"_a, "nrow"_a,
      "The runtime's index of held pairs by the violation check's rows: (start, members).");
  m.def("candidate_pairs", &CandidatePairs, "centers"_a, "reach"_a, "margin"_a);
  m.def("reaches", &Reaches, "radius"_a, "speed"_a, "accel"_a, "delta"_a, "vmax"_a, "horizon"_a);
  m.def("reach_pairs", &ReachPairs, "anchor"_a, "reach"_a, "margin"_a, "ids"_a);
  m.def("escapes", &Escapes, "anchor"_a, "speed0"_a, "accel"_a, "delta"_a, "vmax"_a, "ids"_a,
        "centers"_a, "velocities"_a, "elapsed"_a);
  m.def("sphere_pairs", &SpherePairs, "g1"_a, "g2"_a, "dist"_a, "index"_a, "start"_a, "plane"_a,
        "shape"_a, "radius"_a);
  m.def("pair_bounds", &PairBounds, "first"_a, "second"_a, "kind"_a, "sphere_body"_a, "accel"_a,
        "delta"_a, nb::arg("speed").none());
  m.def("contact_distance", &ContactDistance, "margin"_a, "gap"_a, "g1"_a, "g2"_a,
        "override_margin"_a, "o_margin"_a);
  m.def("exact_rows", &ExactRows, "geoms"_a, "geom1"_a, "geom2"_a, "kind"_a, "dist"_a);

  nb::class_<Filter>(m, "Filter", "MuJoCo's dynamic pair filter over per-geom tables.")
      .def(nb::init<const In<int64_t>&, const In<int64_t>&, const In<int64_t>&, const In<uint8_t>&,
                    const In<int64_t>&, const In<int64_t>&, const In<uint8_t>&, const In<int64_t>&,
                    bool>(),
           "body"_a, "weld"_a, "parent_weld"_a, "movable"_a, "contype"_a, "conaffinity"_a, "lone"_a,
           "exclude"_a, "filterparent"_a)
      .def("mask", &Filter::Mask, "g1"_a, "g2"_a)
      .def("all", &Filter::All)
      .def("count", &Filter::Count, "weight"_a)
      .def("any", &Filter::Any);

  // The plugin's C API (dua/dua.h), for dua_mujoco.plugin.
  m.def(
      "plugin_standing",
      [](nb::handle model, nb::handle data, int instance) -> nb::object {
        const mjModel* mm = ModelOf(model);
        const mjData* d = DataOf(data);
        std::vector<int64_t> out(128);
        while (true) {
          const int64_t n = dua_plugin_standing(mm, d, instance, out.data(),
                                                static_cast<int64_t>(out.size() / 2));
          if (n < 0) return nb::none();
          if (2 * n <= static_cast<int64_t>(out.size())) {
            out.resize(2 * n);
            return nb::cast(Owned(std::move(out), {static_cast<size_t>(n), 2}));
          }
          out.resize(2 * n);
        }
      },
      "model"_a, "data"_a, "instance"_a,
      "Geom pairs standing in alarm in plugin instance `instance` ((K, 2)), or None.");
  m.def(  // issue 35: what the instance knows
      "plugin_memory",
      [](nb::handle model, nb::handle data, int instance) -> nb::object {
        std::vector<int64_t> out(256);
        while (true) {
          const int64_t n = dua_plugin_memory(ModelOf(model), DataOf(data), instance, out.data(),
                                              static_cast<int64_t>(out.size()));
          if (n < 0) return nb::none();
          if (n <= static_cast<int64_t>(out.size())) {
            out.resize(n);
            return nb::cast(Owned(std::move(out), {static_cast<size_t>(n)}));
          }
          out.resize(n);
        }
      },
      "model"_a, "data"_a, "instance"_a,
      "Plugin instance `instance`'s pairs known, geom pairs known, pairs held, geom pairs "
      "forgotten, compactions, then its known geom pairs as (g1, g2) rows, flat; or None.");
  m.def(
      "plugin_set_active",
      [](nb::handle model, nb::handle data, int instance, int body_a, int body_b, bool on) {
        return dua_plugin_set_active(ModelOf(model), const_cast<mjData*>(DataOf(data)), instance,
                                     body_a, body_b, on ? 1 : 0);
      },
      "model"_a, "data"_a, "instance"_a, "body_a"_a, "body_b"_a, "on"_a);
  m.def(
      "plugin_set_plan",
      [](nb::handle model, nb::handle data, int instance, const In<double>& qpos,
         const In<double>& deviation, double start, const In<uint8_t>& bodies,
         const In<double>& mocap_pos, const In<double>& mocap_quat, const In<int64_t>& rel_bodies,
         const In<double>& rel_deviation) {
        const mjModel* mm = ModelOf(model);
        const dua_plan_input in = PlanInput(mm, qpos, deviation, start, bodies, mocap_pos,
                                            mocap_quat, rel_bodies, rel_deviation);
        char error[512] = {0};
        std::vector<double> departures(mm->nbody);
        const int64_t r = dua_plugin_set_plan(mm, const_cast<mjData*>(DataOf(data)), instance, &in,
                                              departures.data(), error, sizeof(error));
        if (r == -3) Raise("InvalidInputError", std::string(error) + ".");
        return nb::make_tuple(r, Owned(std::move(departures), {static_cast<size_t>(mm->nbody)}));
      },
      "model"_a, "data"_a, "instance"_a, "qpos"_a, "deviation"_a, "start"_a, "bodies"_a,
      "mocap_pos"_a, "mocap_quat"_a, "rel_bodies"_a, "rel_deviation"_a,
      "dua_plugin_set_plan: (its result, each body's departure time from the plan replaced).");
  m.def(
      "mixed_stray",
      [](double t, double accel, double disc, double spin, double place, double velocity) {
        const double size[2] = {place, velocity};
        return MixedStray(t, accel, disc, spin, size);
      },
      "t"_a, "accel"_a, "disc"_a, "spin"_a, "place"_a, "velocity"_a,
      "MixedStray (plan.h): how far a free point strays in t from where its velocity read "
      "carries it ((spin + disc) t + accel t^2 / 2), rounded up, plus room for the rounding of "
      "the carried place (|place|_1 and |velocity|_1).");
  m.def("mixed_reach", &MixedReach, "t"_a, "s"_a, "accel"_a, "disc"_a, "speed"_a,
        "MixedReach (plan.h): how far any point of a free body (speed s now) can move in t: (s + "
        "disc) t + accel t^2 / 2 or speed t, whichever is less, each rounded up.");
  m.def(
      "box_within",
      [](const In<double>& box, const In<double>& pa, const In<double>& ra, const In<double>& pb,
         const In<double>& rb, double limit) {
        Require(
            Size(box) == kBNcol && Size(pa) == 3 && Size(pb) == 3 && Size(ra) == 9 && Size(rb) == 9,
            "box_within takes a box record and poses (3,) and (9,)");
        return BoxWithin(box.data(), pa.data(), ra.data(), pb.data(), rb.data(), limit);
      },
      "box"_a, "pa"_a, "ra"_a, "pb"_a, "rb"_a, "limit"_a,
      "BoxWithin (plan.h): every corner of box within limit between the poses (pa, ra) and (pb, "
      "rb), screened first by a bound that needs no corner.");
  m.def(
      "relative_within",
      [](const In<double>& box, const In<double>& pa, const In<double>& ra, const In<double>& pb,
         const In<double>& rb, const In<double>& qa, const In<double>& sa, const In<double>& qb,
         const In<double>& sb, double limit) {
        Require(Size(box) == kBNcol && Size(pa) == 3 && Size(pb) == 3 && Size(qa) == 3 &&
                    Size(qb) == 3 && Size(ra) == 9 && Size(rb) == 9 && Size(sa) == 9 &&
                    Size(sb) == 9,
                "relative_within takes a box record and poses (3,) and (9,)");
        return RelativeWithin(box.data(), pa.data(), ra.data(), pb.data(), rb.data(), qa.data(),
                              sa.data(), qb.data(), sb.data(), limit);
      },
      "box"_a, "pa"_a, "ra"_a, "pb"_a, "rb"_a, "qa"_a, "sa"_a, "qb"_a, "sb"_a, "limit"_a,
      "RelativeWithin (plan.h): b's box within limit, in a's frame, of its planned pose "
      "relative to a.");
  m.def(
      "plan_deviation",
      [](const In<double>& points, const In<double>& pos_a, const In<double>& mat_a,
         const In<double>& pos_b, const In<double>& mat_b, const In<int64_t>& frame_of) {
        // Sphere records of points (n, 8), and rows of two poses of every geom: (r, ngeom, 3)
        // and (r, ngeom, 9) each; frame_of (n,) a geom each point is measured in the frame of
        // (its geom's pose relative to that geom's, RelativePose), or (0,): in the world.
        Require(pos_a.ndim() == 3 && pos_a.shape(2) == 3, "pos_a must be (r, ngeom, 3)");
        const auto r = static_cast<int64_t>(pos_a.shape(0));
        const auto ngeom = static_cast<int64_t>(pos_a.shape(1));
        const int64_t n = Size(points) / kSphereNcol;
        Require(Size(points) == kSphereNcol * n, "points must be (n, 8) sphere records");
        Require(Size(pos_b) == 3 * r * ngeom && Size(mat_a) == 9 * r * ngeom &&
                    Size(mat_b) == 9 * r * ngeom,
                "poses must be (r, ngeom, 3) and (r, ngeom, 9), twice");
        Require(Size(frame_of) == 0 || Size(frame_of) == n, "frame_of must be (n,) or (0,)");
        std::vector<double> out(static_cast<size_t>(r * n));
        for (int64_t i = 0; i < n; ++i) {
          const double* rec = points.data() + kSphereNcol * i;
          const auto g = static_cast<int64_t>(rec[kSphereFrame]);
          const int64_t f = Size(frame_of) ? frame_of.data()[i] : -1;
          Require(g >= 0 && g < ngeom && f < ngeom && (f >= 0 || !Size(frame_of)),
                  "a point's geom is out of range");
          for (int64_t k = 0; k < r; ++k) {
            const int64_t at = k * ngeom + g;
            double a[12], b[12];
            const double *pa = pos_a.data() + 3 * at, *ra = mat_a.data() + 9 * at;
            const double *pb = pos_b.data() + 3 * at, *rb = mat_b.data() + 9 * at;
            if (f >= 0) {
              const int64_t in = k * ngeom + f;
              RelativePose(pos_a.data() + 3 * in, mat_a.data() + 9 * in, pa, ra, a, a + 3);
              RelativePose(pos_b.data() + 3 * in, mat_b.data() + 9 * in, pb, rb, b, b + 3);
              pa = a, ra = a + 3, pb = b, rb = b + 3;
            }
            out[k * n + i] = PoseDeviation(rec + kSphereOffset, pa, ra, pb, rb);
          }
        }
        return Owned(std::move(out), {static_cast<size_t>(r), static_cast<size_t>(n)});
      },
      "points"_a, "pos_a"_a, "mat_a"_a, "pos_b"_a, "mat_b"_a, "frame_of"_a,
      "(r, n): each point's deviation between two poses of its geom (in the frame of geom "
      "frame_of[i] when given), row by row: the plans' one measure (PoseDeviation, RelativePose, "
      "plan.h).");
  m.def(
      "plugin_clear_plan",
      [](nb::handle model, nb::handle data, int instance) {
        return dua_plugin_clear_plan(ModelOf(model), const_cast<mjData*>(DataOf(data)), instance);
      },
      "model"_a, "data"_a, "instance"_a);
  m.def(
      "plugin_deactivate_contacts",
      [](nb::handle model, nb::handle data, int instance) {
        return dua_plugin_deactivate_contacts(ModelOf(model), const_cast<mjData*>(DataOf(data)),
                                              instance);
      },
      "model"_a, "data"_a, "instance"_a);

  BindSchedule(m);
  BindAlarms(m);
  nb::object step_error =
      nb::steal(PyErr_NewException("dua_mujoco._core.StepError", PyExc_RuntimeError, nullptr));
  m.attr("StepError") = step_error;
  BindMocap(m);
  BindRuntime(m, step_error);
  BindCore(m);
  BindShield(m);
}
