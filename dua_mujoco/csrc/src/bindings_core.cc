// What dua_mujoco.core needs of _core beyond bindings.cc: tau of given pairs of free spheres and
// the fused step on them, each checking only the records it follows (a step of a few pairs out
// of a million stays O(its pairs)), and the candidate grid's plan (tests hold its cells to the
// contract of csrc/src/grid.cc).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>

#include <algorithm>
#include <cstdint>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "bindings.h"
#include "dua/dua.h"
#include "kinematics.h"
#include "layout.h"
#include "schedule.h"
#include "tables.h"

using nb::literals::operator""_a;

namespace dua {
namespace {

// Rows from which tau of pairs runs on two threads (as tau_speed_batch does).
constexpr int64_t kThreadedRows = int64_t{1} << 16;

// The sizes of the arrays a free-sphere evaluation reads.
struct FreeSizes {
  int64_t npair, nsphere, nplane, nshape;
};

FreeSizes SizesOf(const In<double>& pairs, const In<double>& centers, const In<double>& velocities,
                  const In<double>& planes, const In<double>& shapes) {
  const FreeSizes s{Size(pairs) / kPairNcol, Size(centers) / 3, Size(planes) / 4,
                    Size(shapes) / kShapeNcol};
  Require(Size(pairs) == s.npair * kPairNcol, "pair records must be (m, 8)");
  Require(Size(centers) == 3 * s.nsphere && Size(velocities) == Size(centers),
          "centres and velocities must be (n, 3) alike");
  Require(Size(planes) == 4 * s.nplane, "planes must be (nplane, 4)");
  Require(Size(shapes) == s.nshape * kShapeNcol, "shape records must be (nshape, 16)");
  return s;
}

// Whether every index pair p's record leads to lies inside the arrays given.
bool RecordOk(const double* pairs, const FreeSizes& s, int64_t p) {
  if (p < 0 || p >= s.npair) return false;
  const double* r = pairs + kPairNcol * p;
  const double kind = r[kPairKind];
  return r[kPairFirst] >= 0 && r[kPairFirst] < s.nsphere &&
         ((kind == kKindSphere && r[kPairSecond] >= 0 && r[kPairSecond] < s.nsphere) ||
          (kind == kKindHalfspace && r[kPairSecond] >= 0 && r[kPairSecond] < s.nplane) ||
          (kind == kKindShape && r[kPairOther] >= 0 && r[kPairOther] < s.nshape));
}

[[noreturn]] void BadRecord(const FreeSizes& s, int64_t p) {
  if (p < 0 || p >= s.npair) {
    Raise("InvalidInputError",
          "pair id " + std::to_string(p) + " is out of range [0, " + std::to_string(s.npair) + ")");
  }
  Raise("InvalidInputError", "pair record " + std::to_string(p) +
                                 " indexes outside the spheres, planes or shapes given");
}

// tau of pairs ids[0:n] into out[0:n]: -1, or the first k whose state is not finite.
int64_t TauOfIds(const In<double>& pairs, const int64_t* ids, int64_t n, const In<double>& centers,
                 const In<double>& velocities, const In<double>& planes, const In<double>& shapes,
                 double* out) {
  auto run = [&](int64_t k0, int64_t k1) {
    const int64_t bad = dua_tau_free(pairs.data(), shapes.data(), centers.data(), velocities.data(),
                                     planes.data(), ids + k0, k1 - k0, out + k0);
    return bad < 0 ? bad : k0 + bad;
  };
  if (n < kThreadedRows) return run(0, n);
  const int64_t half = n / 2;
  int64_t second = -1;
  {
    nb::gil_scoped_release release;
    std::thread other([&] { second = run(half, n); });
    const int64_t first = run(0, half);
    other.join();
    if (first >= 0) return first;
  }
  return second;
}

// tau of pairs ids (n,) of free spheres: (tau (n,), the first k whose state is not finite or -1).
std::pair<Out<double>, int64_t> TauPairs(const In<double>& pairs, const In<int64_t>& ids,
                                         const In<double>& centers, const In<double>& velocities,
                                         const In<double>& planes, const In<double>& shapes) {
  const FreeSizes s = SizesOf(pairs, centers, velocities, planes, shapes);
  const int64_t n = Size(ids);
  for (int64_t k = 0; k < n; ++k) {
    if (!RecordOk(pairs.data(), s, ids.data()[k])) BadRecord(s, ids.data()[k]);
  }
  std::vector<double> out(n);
  const int64_t bad =
      TauOfIds(pairs, ids.data(), n, centers, velocities, planes, shapes, out.data());
  return {Owned(std::move(out), {static_cast<size_t>(n)}), bad};
}

// The fused step on free spheres: select, tau of the selected pairs, reinsert. Returns the
// number of alarms, or -1 - p for the first pair p whose state is not finite (the selection
// undone: the step can be taken again); *count receives the pairs evaluated.
int64_t Step(Schedule& sched, const In<double>& pairs, const In<double>& centers,
             const In<double>& velocities, const In<double>& planes, const In<double>& shapes,
             int64_t* count) {
  const FreeSizes s = SizesOf(pairs, centers, velocities, planes, shapes);
  Require(s.npair == sched.m(), "the pair records must be (m, 8), one a pair of the schedule");
  dua_schedule* st = sched.state();
  const int64_t n = sched.step_count + 1;
  *count = dua_select(st, n);
  const int64_t* ids = st->work + st->width;  // the W_IDS row
  for (int64_t k = 0; k < *count; ++k) {
    if (!RecordOk(pairs.data(), s, ids[k])) {
      const int64_t p = ids[k];
      dua_restore(st, n, *count);
      BadRecord(s, p);
    }
  }
  const int64_t bad = TauOfIds(pairs, ids, *count, centers, velocities, planes, shapes, st->w_tau);
  if (bad >= 0) {
    const int64_t p = ids[bad];
    dua_restore(st, n, *count);
    return -1 - p;
  }
  const int64_t nalarm = dua_reinsert(st, n, *count);
  sched.step_count = n;
  return nalarm;
}

// Step as Schedule.step_points returns it: (alarms, bad pair or -1, evaluated).
nb::tuple StepFree(Schedule& sched, const In<double>& pairs, const In<double>& centers,
                   const In<double>& velocities, const In<double>& planes,
                   const In<double>& shapes) {
  int64_t count = 0;
  const int64_t r = Step(sched, pairs, centers, velocities, planes, shapes, &count);
  return r >= 0 ? nb::make_tuple(r, -1, count) : nb::make_tuple(0, -1 - r, count);
}

// StepFree bound to a schedule, its pair records, planes and shapes, so that a step hands over
// only the sphere states (each array crossing costs about as much as a small step's work).
class FreeStep {
 public:
  FreeStep(nb::handle schedule, const In<double>& pairs, const In<double>& planes,
           const In<double>& shapes)
      : owner_(nb::borrow(schedule)),
        sched_(&nb::cast<Schedule&>(schedule)),
        pairs_(pairs),
        planes_(planes),
        shapes_(shapes) {
    Require(Size(pairs) == kPairNcol * sched_->m(),
            "the pair records must be (m, 8), one a pair of the schedule");
  }

  // The alarms (>= 0), or -1 - p for the first pair p whose state is not finite (undone).
  int64_t Run(const In<double>& centers, const In<double>& velocities) {
    int64_t count = 0;
    return Step(*sched_, pairs_, centers, velocities, planes_, shapes_, &count);
  }

 private:
  nb::object owner_;  // keeps the schedule alive
  Schedule* sched_;
  In<double> pairs_, planes_, shapes_;  // hold their arrays
};

// Whether pairs ids (n,) stand in alarm: the schedule's own rule (Schedule::Stands), O(n).
Out<bool> Stands(const Schedule& sched, const In<int64_t>& ids) {
  const int64_t n = Size(ids), m = sched.m();
  std::vector<uint8_t> out(n);
  for (int64_t k = 0; k < n; ++k) {
    const int64_t p = ids.data()[k];
    Require(p >= 0 && p < m, "pair ids must lie in [0, the schedule's pairs)");
    out[k] = sched.Stands(p) ? 1 : 0;
  }
  return OwnedBools(std::move(out));
}

// The candidate grid's plan for spheres of reach (n,) (n >= 2) within bounds lo, hi.
nb::dict GridPlan(const In<double>& reach, double margin, const In<double>& lo,
                  const In<double>& hi) {
  const int64_t n = Size(reach);
  Require(n >= 2, "a grid plan needs at least two spheres");
  Require(Size(lo) == 3 && Size(hi) == 3, "lo and hi are (3,)");
  dua_grid_plan plan{};
  std::vector<int64_t> held(256);
  std::vector<double> work(n);
  dua_grid_plan_of(reach.data(), n, margin, lo.data(), hi.data(), &plan, held.data(), work.data());
  held.resize(plan.nheld);
  nb::dict out;
  out["lo"] = nb::make_tuple(plan.lo[0], plan.lo[1], plan.lo[2]);
  out["h"] = plan.h;
  out["mask"] = nb::make_tuple(plan.mask[0], plan.mask[1], plan.mask[2]);
  out["shift_y"] = plan.shift_y;
  out["shift_z"] = plan.shift_z;
  out["wrap"] = nb::make_tuple(plan.wrap[0], plan.wrap[1], plan.wrap[2]);
  out["nbucket"] = plan.nbucket;
  out["nheld"] = plan.nheld;
  out["rcut"] = plan.rcut;
  out["held"] = Owned(std::move(held), {static_cast<size_t>(plan.nheld)});
  return out;
}

// KnotKinematics (kinematics.h) on one row: the bodies computed (ids, parents first), their
// frames (xpos, xquat, xmat) and the geoms' (geom_xpos, geom_xmat), for tests to hold to
// mj_kinematics bit for bit.
nb::tuple KnotKinematicsOf(nb::handle model, const In<int64_t>& geoms, const In<double>& qpos,
                           const In<double>& mocap_pos, const In<double>& mocap_quat, bool exact) {
  const mjModel* m = ModelOf(model);
  Require(
      Size(qpos) == m->nq && Size(mocap_pos) == 3 * m->nmocap && Size(mocap_quat) == 4 * m->nmocap,
      "knot_kinematics takes qpos (nq,), mocap_pos (nmocap, 3) and mocap_quat (nmocap, 4)");
  std::vector<int64_t> ids(geoms.data(), geoms.data() + Size(geoms));
  for (const int64_t g : ids) Require(g >= 0 && g < m->ngeom, "a geom id is out of range");
  KnotKinematics k(m, ids);
  k.SetExactHinges(exact);
  const size_t n = ids.size();
  std::vector<double> pos(3 * n), mat(9 * n);
  k.Run(qpos.data(), mocap_pos.data(), mocap_quat.data(), pos.data(), mat.data());
  const size_t nb = k.bodies().size();
  return nb::make_tuple(Owned(std::vector<int64_t>(k.bodies().begin(), k.bodies().end()), {nb}),
                        Owned(k.xpos(), {nb, 3}), Owned(k.xquat(), {nb, 4}),
                        Owned(k.xmat(), {nb, 9}), Owned(std::move(pos), {n, 3}),
                        Owned(std::move(mat), {n, 9}));
}

// StaticRecords (tables.h) of static geoms `geoms`, (n, kStaticNcol): the "static" table.
Out<double> StaticRecordsOf(nb::handle model, const In<int64_t>& geoms) {
  const mjModel* m = ModelOf(model);
  std::vector<int64_t> ids(geoms.data(), geoms.data() + Size(geoms));
  for (const int64_t g : ids) {
    Require(g >= 0 && g < m->ngeom, "a geom id is out of range");
    const int b = m->geom_bodyid[g];
    Require(b == 0 || StillBody(m, b), "a geom moves (its body is not welded to the world)");
  }
  return Owned(StaticRecords(m, ids), {ids.size(), static_cast<size_t>(kStaticNcol)});
}

// StaticMismatch (tables.h): the first static geom the model no longer has as `records` do.
std::string StaticMismatchOf(nb::handle model, const In<double>& records) {
  const mjModel* m = ModelOf(model);
  Require(Size(records) % kStaticNcol == 0, "static records must be (n, 18)");
  std::vector<double> r(records.data(), records.data() + Size(records));
  for (size_t s = 0; s < r.size(); s += kStaticNcol) {
    const double g = r[s + kStaticGeom];
    Require(g >= 0 && g < m->ngeom && g == static_cast<double>(static_cast<int64_t>(g)),
            "a static record's geom is out of range");
    const int b = m->geom_bodyid[static_cast<int64_t>(g)];
    Require(b == 0 || StillBody(m, b), "a static record's geom moves");
  }
  return StaticMismatch(m, r);
}

// KnotKinematics::RunKnots (kinematics.h) on n rows, as Plan::Build calls it (ReadyHinges
// first, or every hinge exact): the geoms' poses (n, ngeom, 3) and (n, ngeom, 9) with lanes on
// or off (and, with fault, a flipped bit in the lanes' first pose for the self-check to catch),
// whether lanes computed them, and the model's tolerance (a plan adds it to its deviations).
nb::tuple KnotKinematicsRows(nb::handle model, const In<int64_t>& geoms, const In<double>& qpos,
                             const In<double>& mocap_pos, const In<double>& mocap_quat, bool lanes,
                             bool fault, bool exact) {
  const mjModel* m = ModelOf(model);
  const int64_t n = m->nq ? Size(qpos) / m->nq : 0;
  Require(n >= 1 && Size(qpos) == n * m->nq && Size(mocap_pos) == n * 3 * m->nmocap &&
              Size(mocap_quat) == n * 4 * m->nmocap,
          "knot_kinematics_rows takes qpos (n, nq), mocap_pos (n, nmocap, 3) and mocap_quat (n, "
          "nmocap, 4)");
  std::vector<int64_t> ids(geoms.data(), geoms.data() + Size(geoms));
  for (const int64_t g : ids) Require(g >= 0 && g < m->ngeom, "a geom id is out of range");
  KnotKinematics k(m, ids);
  k.SetLanes(lanes);
  k.SetLaneFault(fault);
  if (exact) {
    k.SetExactHinges(true);
  } else {
    k.ReadyHinges(n, qpos.data(), n, mocap_pos.data());
  }
  const double tolerance = k.tolerance();
  const size_t ng = ids.size();
  std::vector<double> pos(3 * ng * n), mat(9 * ng * n);
  std::vector<const double*> q, mp, mq;
  std::vector<double*> p, r;
  for (int64_t j = 0; j < n; ++j) {
    q.push_back(qpos.data() + m->nq * j);
    mp.push_back(mocap_pos.data() + 3 * m->nmocap * j);
    mq.push_back(mocap_quat.data() + 4 * m->nmocap * j);
    p.push_back(pos.data() + 3 * ng * j), r.push_back(mat.data() + 9 * ng * j);
  }
  k.RunKnots(n, q.data(), mp.data(), mq.data(), p.data(), r.data());
  const size_t rows = static_cast<size_t>(n);
  return nb::make_tuple(Owned(std::move(pos), {rows, ng, 3}), Owned(std::move(mat), {rows, ng, 9}),
                        k.lanes(), tolerance);
}

// HalfAngleSinCosOf (kinematics.h): the knots' hinges' sine and cosine of x.
nb::tuple HalfAngleSinCosArrays(const In<double>& x, bool lanes) {
  const size_t n = static_cast<size_t>(Size(x));
  for (size_t i = 0; i < n; ++i) {
    Require(std::fabs(x.data()[i]) <= kHalfAngleMax,
            "half_angle_sincos takes |x| <= HALF_ANGLE_MAX (64): past it the knots call sin and "
            "cos");
  }
  std::vector<double> sn(n), cs(n);
  HalfAngleSinCosOf(static_cast<int64_t>(n), x.data(), sn.data(), cs.data(), lanes);
  return nb::make_tuple(Owned(std::move(sn), {n}), Owned(std::move(cs), {n}));
}

}  // namespace

void BindCore(nb::module_& m) {
  m.def("static_records", &StaticRecordsOf, "model"_a, "geoms"_a,
        "The static guard's records (n, STATIC_NCOL) of static geoms: geom, pose as "
        "mj_kinematics places it, geom_size, digest of its height field or mesh.");
  m.def("static_mismatch", &StaticMismatchOf, "model"_a, "records"_a,
        "The first static geom the model no longer places, sizes or shapes as static_records "
        "recorded it, and how (empty: none).");
  m.def("knot_kinematics", &KnotKinematicsOf, "model"_a, "geoms"_a, "qpos"_a, "mocap_pos"_a,
        "mocap_quat"_a, "exact"_a = false,
        "KnotKinematics (kinematics.h) on one row: (bodies, xpos, xquat, xmat, geom_xpos, "
        "geom_xmat), the bodies computed and the geoms given, as mj_kinematics computes them "
        "(exact=True: bit for bit; else a hinge by the knots' polynomials).");
  m.def("knot_kinematics_rows", &KnotKinematicsRows, "model"_a, "geoms"_a, "qpos"_a, "mocap_pos"_a,
        "mocap_quat"_a, "lanes"_a = true, "fault"_a = false, "exact"_a = false,
        "KnotKinematics::RunKnots (kinematics.h) on n rows, as set_plan calls it: (geom_xpos "
        "(n, ngeom, 3), geom_xmat (n, ngeom, 9), whether lanes computed them, the tolerance "
        "the plan adds to its deviations); lanes=False computes one knot at a time, fault=True "
        "flips a bit of the lanes' first pose (the self-check then turns lanes off), exact=True "
        "computes every hinge by libmujoco's call.");
  m.def("half_angle_sincos", &HalfAngleSinCosArrays, "x"_a, "lanes"_a = true,
        "The knots' hinges' (sin x, cos x), |x| <= HALF_ANGLE_MAX, four at a time in lanes or "
        "one at a time.");
  m.attr("HALF_ANGLE_MAX") = kHalfAngleMax;
  m.attr("SIN_COS_ERROR") = kSinCosError;
  m.attr("TOLERANCE_UNIT") = KnotKinematics::kToleranceUnit;
  m.attr("WORLD_REACH") = KnotKinematics::kWorldReach;
  // The select-all kind, beside RANK and DEADLINE (the schedule's own constant, schedule.h).
  nb::dict layout = nb::borrow<nb::dict>(m.attr("LAYOUT"));
  layout["ALL"] = kAll;

  m.def("tau_pairs", &TauPairs, "pairs"_a, "ids"_a, "centers"_a, "velocities"_a, "planes"_a,
        "shapes"_a,
        "tau of pairs ids (n,) of free spheres, checking the records of ids only: (tau (n,), "
        "the first k whose state is not finite or -1).");
  m.def("step_free", &StepFree, "schedule"_a, "pairs"_a, "centers"_a, "velocities"_a, "planes"_a,
        "shapes"_a,
        "Schedule.step_points checking the selected pairs' records only: (alarms, bad pair or "
        "-1, evaluated).");
  m.def("stands", &Stands, "schedule"_a, "ids"_a,
        "(n,) bool: whether each pair stands in alarm, by the schedule's own rule.");
  m.def("grid_plan", &GridPlan, "reach"_a, "margin"_a, "lo"_a, "hi"_a,
        "The candidate grid's plan (cell edge, bucket map, held-out ids) as a dict.");

  nb::class_<FreeStep>(m, "FreeStep",
                       "step_free bound to a schedule and its pairs' records, planes and shapes.")
      .def(nb::init<nb::handle, const In<double>&, const In<double>&, const In<double>&>(),
           "schedule"_a, "pairs"_a, "planes"_a, "shapes"_a)
      .def("step", &FreeStep::Run, "centers"_a, "velocities"_a,
           "One fused step: its number of alarms, or -1 - p for a pair p whose state is not "
           "finite (the step undone).");
}

}  // namespace dua
