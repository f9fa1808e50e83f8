// Flight plans (docs/theory.md, section 8): the motion the caller expects over the coming physics
// steps, as joint positions at each of them (an MPC's or a planner's trajectory, or a rollout of
// known controls) and, if it plans mocap bodies, their poses; the bodies it holds; and a bound on
// how far every point of each of them may stray from where the plan puts it. Each body is, at
// each step, *planned* (held by the plan and found within its deviation so far; static bodies
// always, with deviation 0), or follows its motion bounds (not held, or found beyond its
// deviation until the next plan). A pair of two planned bodies has the plan's tau (8): the time
// to the first knot at which the plan's geometry, less both deviations, may touch. A pair of a
// planned body and one that follows its bounds has the mixed tau: the planned geom at each knot,
// less its deviation, against the other's reach from where it is now, from its own bounds (speed
// and separation monitoring). No acceleration bound of a planned body enters either.
#ifndef DUA_MUJOCO_PLAN_H_
#define DUA_MUJOCO_PLAN_H_

#include <mujoco/mujoco.h>

#include <algorithm>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "dua/dua.h"

namespace dua {

class KnotKinematics;

// How far the point of frame coordinates q of a geom lies between two poses of it, (pa, ra)
// and (pb, rb): |(pa - pb) + (ra - rb) q|, rounded up past its own rounding (0 exactly for equal
// poses). The one measure of a deviation: the step's check, a replan's departures and
// dua_mujoco.runtime.plans.deviation_profile all take it at the corners of each body's box.
DUA_API double PoseDeviation(const double* q, const double* pa, const double* ra, const double* pb,
                             const double* rb);
// The largest PoseDeviation over the eight corners of box (a violation-check record: its frame
// geom's coordinates, kBCenter +- kBHalf) between that geom's poses (pa, ra) and (pb, rb). Every
// point the plan's gaps rely on lies in the box, and a point's deviation is convex in its
// coordinates, so this bounds all of them (docs/theory.md, Lemma 8.1).
DUA_API double BoxDeviation(const double* box, const double* pa, const double* ra, const double* pb,
                            const double* rb);
// Whether BoxDeviation(box, pa, ra, pb, rb) <= limit, screened first by a bound over the box
// that costs no corner (equal poses pass at once): the same verdict as the comparison itself.
DUA_API bool BoxWithin(const double* box, const double* pa, const double* ra, const double* pb,
                       const double* rb, double limit);
// How far a box's corners reach from its frame's origin, per axis (|centre_j| + half_j):
// BoxWithin's constants, taken once by a caller that checks one box at many knots (a replan's
// nesting: each check is a few dozen operations).
struct BoxReach {
  explicit BoxReach(const double* box);
  double qmax[3];
};
// BoxWithin with the box's reach taken already: the same numbers, the same verdict.
bool BoxWithin(const double* box, const BoxReach& reach, const double* pa, const double* ra,
               const double* pb, const double* rb, double limit);

// Whether every corner of box (a violation-check record of body b's frame geom) lies, in the frame
// of geom A (a geom of body a), within limit of where the plan puts it relative to A: the
// relative deviation of docs/theory.md, Lemma 8.2d. (pa, ra) and (pb, rb) are A's and b's frame
// geom's actual poses, (qa, sa) and (qb, sb) their planned ones; b's pose in A's frame is
// (ra^T (pb - pa), ra^T rb). Equal poses pass at once (a plan that is the run); otherwise the
// relative poses' own rounding (a few ulps of the lengths involved) is taken off the limit.
DUA_API bool RelativeWithin(const double* box, const double* pa, const double* ra, const double* pb,
                            const double* rb, const double* qa, const double* sa, const double* qb,
                            const double* sb, double limit);
// RelativeWithin on relative poses already taken (12 each: position, rotation), as a plan keeps
// its own (Plan::rel_pose).
bool RelativePoseWithin(const double* box, const double* actual, const double* planned,
                        double limit);
bool RelativePoseWithin(const double* box, const BoxReach& reach, const double* actual,
                        const double* planned, double limit);
class Plan;
// The first of `count` knots in turn (plan's from jn, old's from jo) at which relative pair rn of
// plan leaves the tube of old's pair r (RelativePoseWithin of old's box, within D_old - D_new),
// or count: a replan's relative nesting (Runtime::RelativeDepartures).
int64_t RelativeDeparture(const Plan& plan, int64_t rn, int64_t jn, const Plan& old, int64_t r,
                          int64_t jo, int64_t count);
// The first of `count` knots in turn (plan's from jn, old's from jo) at which the body of box (a
// violation-check record, reach its BoxReach) leaves old's tube (BoxWithin between the poses of
// its frame, within D_old - D_new), or count: a replan's nesting of the bodies (Runtime::SetPlan).
int64_t BodyDeparture(const Plan& plan, int64_t jn, const Plan& old, int64_t jo, const double* box,
                      const BoxReach& reach, int64_t count);
// How far a free point can stray in t from where its velocity read carries it, rounded up, with
// room for the rounding of the carried place (the mixed tau's Stray, plan.cc; size: |place|_1,
// |velocity|_1).
DUA_API double MixedStray(double t, double accel, double disc, double spin, const double size[2]);
// How far any point of a free body (speed s now) can move in t while its bounds hold: (s + disc)
// t + accel t^2 / 2 or speed t, whichever is less, each rounded up (the mixed tau's Reach,
// plan.cc).
DUA_API double MixedReach(double t, double s, double accel, double disc, double speed);
// b's pose in the frame of pose (pa, ra): (ra^T (pb - pa), ra^T rb), into (pos 3, mat 9).
DUA_API void RelativePose(const double* pa, const double* ra, const double* pb, const double* rb,
                          double* pos, double* mat);

// An allocator whose elements are default-initialised (a double's value left unspecified): a
// plan writes every entry of its pose buffers before any read, and zeroing them first was 5 %
// of sawyer's set_plan.
template <class T>
struct Uninitialised : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = Uninitialised<U>;
  };
  Uninitialised() = default;
  template <class U>
  Uninitialised(const Uninitialised<U>&) noexcept {}
  template <class U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};
using Buffer = std::vector<double, Uninitialised<double>>;

// Buffers of plans gone, for the plans that follow: a plan's poses are as large as hundreds
// of kilobytes, and fresh memory for each (a replan every few steps) costs its page faults.
struct PlanPool {
  std::mutex mutex;
  std::vector<Buffer> free;
  // A buffer of n entries (their values unspecified), recycled when one is free.
  Buffer Take(size_t n);
  void Give(Buffer&& v);
};

class Plan {
 public:
  Plan() = default;
  Plan(const Plan&) = delete;
  Plan& operator=(const Plan&) = delete;
  ~Plan();

  // The plan `in` (dua_plan_input), h the model's timestep; spheres (nsphere, 8) the covering's
  // records, whose centres the sweeps bound too. The poses and sweeps kept are those of
  // `geoms` (sorted ids: every geom a pair, a check or a plane may read; any other reads as not
  // a number, its sweep +inf), each knot's computed by `kinematics` (or a KnotKinematics of its
  // own; mj_kinematics on scratch, an mjData of m, with flexes or sleep), or copied from `prev`
  // (the plan replaced, or null) where it has a knot at the same time with the same rows (joint
  // positions and mocap poses, bit for bit: the same poses). Every deviation is widened by the
  // model's knot tolerance (KnotKinematics::tolerance; relative ones by three times it).
  // pool (or null) recycles the buffers. Returns an error message naming the bad input, or "".
  std::string Build(const mjModel* m, mjData* scratch, const dua_plan_input& in, double h,
                    const double* spheres, int64_t nsphere, const std::vector<int64_t>& geoms,
                    const Plan* prev, std::shared_ptr<PlanPool> pool,
                    KnotKinematics* kinematics = nullptr);
  // A plan whose knots' geom poses are known already (pos (n, ngeom, 3) and mat (n, ngeom, 9):
  // a rollout's geom_xpos and geom_xmat at each knot), holding the moving bodies of bodies
  // (nbody flags; mocap trees are never held), deviation (n, nbody); geoms as Build's. Values
  // are not checked beyond the poses being finite: the caller made them. It has no rows: never
  // pass it as Build's prev.
  std::string FromPoses(const mjModel* m, int64_t n, const double* pos, const double* mat,
                        const uint8_t* bodies, const double* deviation, double start, double h,
                        const double* spheres, int64_t nsphere, const std::vector<int64_t>& geoms);

  // The knot at `time` (-1: not one of the plan's, within a millionth of a step).
  int64_t KnotOf(double time) const;
  // Body b is a moving body the plan holds / a static body (planned, deviation 0).
  bool holds(int64_t b) const { return holds_[b] != 0; }
  bool fixed(int64_t b) const { return fixed_[b] != 0; }
  // Appends to broken the bodies the plan holds, with ok[b] set (null: all), found beyond their
  // deviation at knot k with the geoms at poses (pos, mat) (MjData's geom_xpos, geom_xmat): a
  // corner of the body's box (boxes, nbox rows of the violation check) farther from its planned
  // place than the deviation (BoxDeviation), or a plane geom of the body off its planned pose
  // (a plane reaches arbitrarily far).
  void Check(const double* pos, const double* mat, int64_t k, const double* boxes, int64_t nbox,
             const uint8_t* ok, std::vector<int64_t>* broken) const;
  // The frames of the relative pairs (each body's box's geom in the violation check: boxes its
  // rows, row[body] each body's, which must outlive the plan) and each pair's planned relative
  // pose at each knot. Before any use of the pairs (Runtime::SetPlan, PlanQuery).
  void SetRelativeFrames(const double* boxes, const int64_t* row);
  // Appends to broken the relative pairs r with ok[r] set (null: all) whose bodies are both
  // within ok_body (null: all) found beyond their relative deviation at knot k (RelativeWithin
  // on b's box in a's frame).
  void CheckRelative(const double* pos, const double* mat, int64_t k, const uint8_t* ok,
                     const uint8_t* ok_body, std::vector<int64_t>* broken) const;
  // Relative pair r's planned pose at knot k (12: b's frame geom's position and rotation in
  // a's), its box (b's row of the violation check), its frame geoms.
  const double* rel_pose(int64_t k, int64_t r) const {
    return rel_pose_.data() + 12 * (nknot_ * r + k);
  }
  const double* rel_box(int64_t r) const { return rel_box_[r]; }
  const BoxReach& rel_reach(int64_t r) const { return rel_reach_[r]; }
  // Relative pairs (Lemma 8.2d): nrel body pairs (rel_a(r), rel_b(r)), rel_a < rel_b, sorted;
  // rel_dev(k, r) the bound at knot k; RelOf the pair of two bodies (either order; -1: none).
  int64_t nrel() const { return static_cast<int64_t>(rel_key_.size()); }
  int64_t rel_a(int64_t r) const { return rel_key_[r] / nbody_; }
  int64_t rel_b(int64_t r) const { return rel_key_[r] % nbody_; }
  double rel_dev(int64_t k, int64_t r) const { return rel_dev_[nknot_ * r + k]; }
  int64_t RelOf(int64_t b1, int64_t b2) const {
    if (rel_key_.empty()) return -1;
    const int64_t key = b1 < b2 ? b1 * nbody_ + b2 : b2 * nbody_ + b1;
    const auto it = std::lower_bound(rel_key_.begin(), rel_key_.end(), key);
    return it != rel_key_.end() && *it == key ? it - rel_key_.begin() : -1;
  }
  // Whether min(D_a + D_b, D_ab) of relative pair r is non-decreasing over the knots (the knot
  // walk's search then applies, as dev_rises for the sum).
  bool rel_rises(int64_t r) const { return rel_rises_[r] != 0; }

  int64_t nknot() const { return nknot_; }
  double start() const { return start_; }
  double h() const { return h_; }
  double TimeOf(int64_t k) const { return start_ + static_cast<double>(k) * h_; }
  // Geom g's planned position (3) and rotation (9) at knot k (not numbers for a geom not kept).
  const double* pos(int64_t k, int64_t g) const {
    const int64_t s = slot_[g];
    return s < 0 ? kNoPose : pos_.data() + 3 * (nslot_ * k + s);
  }
  const double* mat(int64_t k, int64_t g) const {
    const int64_t s = slot_[g];
    return s < 0 ? kNoPose : mat_.data() + 9 * (nslot_ * k + s);
  }
  // How far any point of geom g, and any centre of its covering spheres, may have moved along
  // the plan from knot 0 to knot k (a prefix sum of each step's bound; +inf once a plane geom
  // moves, and for a geom not kept). Non-decreasing in k.
  double sweep(int64_t k, int64_t g) const {
    const int64_t s = slot_[g];
    return s < 0 ? kNoSweep : sweep_[nslot_ * k + s];
  }
  double dev(int64_t k, int64_t b) const { return dev_[nbody_ * k + b]; }
  // The knots' tolerance (metres) every deviation was widened by (KnotKinematics::tolerance).
  double tolerance() const { return tolerance_; }
  // Whether body b's deviation is non-decreasing over the knots (a knot walk may then search
  // for the first knot its carried gap does not clear, docs/theory.md, section 8).
  bool dev_rises(int64_t b) const { return rises_[b] != 0; }

 private:
  // Whether this plan's knot j and prev's knot i have the same rows (qpos, mocap poses).
  bool SameRow(int64_t j, const Plan& prev, int64_t i) const;
  // The relative pairs of `in` checked (bodies the plan holds, each pair once, deviations
  // finite and >= 0) and kept, sorted by body pair. Returns an error message, or "".
  // Each relative deviation is widened by three times tolerance (the knots' poses' from
  // mj_kinematics', docs/theory.md, section 8).
  std::string Relative(const mjModel* m, const dua_plan_input& in,
                       const std::vector<uint8_t>& holds, double tolerance);
  // The columns (slots) of `geoms` and the buffers of n knots.
  void Slots(int64_t n, int64_t ngeom, const std::vector<int64_t>& geoms,
             std::shared_ptr<PlanPool> pool);
  // The rest of a build once the knots' poses are in place: their check, the sweeps, the
  // deviations and bodies. ready(j) (if given) puts knot j's poses, and every earlier knot's,
  // in place, before they are first read.
  // deviation is widened by tolerance (the knots' poses' from mj_kinematics') on moving bodies.
  std::string Finish(const mjModel* m, int64_t n, const std::vector<int64_t>& geoms,
                     const double* deviation, double tolerance, double start, double h,
                     const double* spheres, int64_t nsphere, std::vector<uint8_t> holds,
                     std::vector<uint8_t> fixed, const std::vector<uint8_t>* still = nullptr,
                     const std::function<void(int64_t)>& ready = {});

  static const double kNoPose[9];
  static const double kNoSweep;
  int64_t nknot_ = 0, ngeom_ = 0, nbody_ = 0, nq_ = 0, nmocap_ = 0, nslot_ = 0;
  double start_ = 0.0, h_ = 0.0;
  double tolerance_ = 0.0;     // how far the knots' poses may lie from mj_kinematics'
  std::vector<int64_t> slot_;  // (ngeom,) each geom's column of the poses (-1: not kept)
  Buffer pos_, mat_, sweep_;   // (nknot, nslot, 3 / 9 / 1)
  std::vector<double> dev_;    // (nknot, nbody)
  std::vector<double> qpos_, mocap_pos_, mocap_quat_;  // the rows (mocap: empty if unplanned)
  std::vector<uint8_t> holds_, fixed_, rises_, rel_rises_;
  std::vector<int64_t> rel_key_;  // (nrel,) a * nbody + b of each relative pair, sorted
  // Pair by pair (a pair's knots together: a replan's nesting and a walk read one pair's
  // knots in turn).
  Buffer rel_dev_;   // (nrel, nknot), every entry written by Relative
  Buffer rel_pose_;  // (nrel, nknot, 12) SetRelativeFrames
  std::vector<const double*> rel_box_;
  std::vector<BoxReach> rel_reach_;  // (nrel,) each box's reach, for its checks
  std::vector<int64_t> rel_ga_, rel_gb_;
  std::vector<int64_t> planes_;  // plane geoms on bodies the plan holds
  std::vector<int> geom_body_;
  std::shared_ptr<PlanPool> pool_;
};

// tau of held pairs ids[0:count] under a.plan where it covers them (a.plan.planned[k] set and
// out[k] replaced): the plan's tau when both bodies are planned, the mixed tau when one is and
// the other follows its bounds; elsewhere planned[k] = 0 and out[k] kept. Each pair's basis
// (dua_plan.basis) is written. MuJoCo's distance queries at knots are counted in a.plan.queries.
void PlanPass(dua_step_args& a, const int64_t* ids, int64_t count, double* out);

// Into covered[k]: whether PlanPass replaces out[k] of held pair ids[k] whatever its walks
// find (both bodies planned and within the plan, or static: the plan's tau, a knot >= a.plan.knot
// always), so that the bounds' tau of such a pair is never read. Reads no state and writes
// nothing else.
void PlanCovered(const dua_step_args& a, const int64_t* ids, int64_t count, uint8_t* covered);

// The knot (of `plan`, from knot k) at which the contact of pair record p (a.pairs, with its
// exact record in a.exact.records if the level is on) can first not be excluded under the plan,
// whose bodies in ok[] are planned (plan.nknot() if none); -1 when neither geom is on a moving
// planned body (the plan says nothing of the pair). The same code as PlanPass.
int64_t PlanKnot(dua_step_args& a, const Plan& plan, const uint8_t* ok, int64_t k, int64_t p,
                 int64_t g1, int64_t g2);

}  // namespace dua

#endif  // DUA_MUJOCO_PLAN_H_
