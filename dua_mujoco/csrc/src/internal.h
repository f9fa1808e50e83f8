// Kernels shared between the native core's translation units (not part of the C API).
#ifndef DUA_MUJOCO_INTERNAL_H_
#define DUA_MUJOCO_INTERNAL_H_

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <new>
#include <string>

#include "dua/dua.h"
#include "lanes.h"
#include "layout.h"

namespace dua {

// A bad value as a refusal names it (%g: "nan", "inf", "1e+308").
inline std::string Shown(double x) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g", x);
  return buf;
}

// Events (dua_mujoco/build/events.py): body record and state columns, meta entries.
constexpr int kBFrame = 0, kBBody = 1, kBRoot = 2, kBCenter = 3, kBHalf = 6, kBAccel = 9,
              kBDisc = 10, kBSpeed = 11, kBNcol = 12;
// State columns 0..30 are what the check writes each step; 31..39 the body's box and bounds
// (kBCenter .. kBSpeed), copied from its record at the reset so that the lanes read them as
// vectors too; 40..41 (kSIndex) the four bodies' rows in MjData's arrays, 16 int32 set at the
// reset (StateIndex), so that the check reads its inputs' places from the state's lines, not
// from four records' (and converts no doubles to integers).
constexpr int kSV = 24, kSW = 27, kSScale = 30, kSWritten = 31, kSCenter = 31, kSHalf = 34,
              kSAccel = 37, kSDisc = 38, kSSpeed = 39, kSIndex = 40, kSNcol = 42;
// The int32 of kSIndex (a group's 16), each body's in its own lane (a double's 8 bytes): lane
// k's frame geom times 3 at 2k, its body times 6 at 2k + 1, its root times 3 at 8 + 2k (and 0).
constexpr int kSIndexInts = 16;
// Length of the state of nbody bodies: (ceil(nbody / 4), kSNcol, 4), so that a column of four
// bodies is one vector of the check's lanes.
inline int64_t EventStateLen(int64_t nbody) {
  return (nbody + kLanes - 1) / kLanes * kSNcol * kLanes;
}
// The check's lanes read a column of the state as one vector where it lies; a std::vector's
// storage is aligned only as malloc's (16 bytes), and a compiler may load a vector type as
// aligned to its size (clang drops an alias's `aligned(8)`): the runtime keeps the state on a
// vector's alignment, and the check goes one body at a time on storage that is not.
constexpr std::size_t kLanesAlign = sizeof(Lanes);
template <class T>
struct LanesAligned {
  using value_type = T;
  LanesAligned() = default;
  template <class U>
  LanesAligned(const LanesAligned<U>&) {}  // NOLINT: the allocator concept's rebind
  T* allocate(std::size_t n) {
    return static_cast<T*>(::operator new(n * sizeof(T), std::align_val_t{kLanesAlign}));
  }
  void deallocate(T* p, std::size_t) { ::operator delete(p, std::align_val_t{kLanesAlign}); }
  template <class U>
  bool operator==(const LanesAligned<U>&) const {
    return true;
  }
  template <class U>
  bool operator!=(const LanesAligned<U>&) const {
    return false;
  }
};
inline bool LanesAlignedAt(const double* p) {
  return reinterpret_cast<std::uintptr_t>(p) % kLanesAlign == 0;
}
constexpr int kMNprev = 0, kMCount = 1, kMTotal = 2;

double TauAccel(double x0, double x1, double x2, double v0, double v1, double v2, double eps,
                double accel, double delta);
double TauSpeed(double x0, double x1, double x2, double v0, double v1, double v2, double eps,
                double accel, double delta, double speed);
// TauSpeed of n rows {x0, x1, x2, v0, v1, v2, eps, accel, delta, speed}, row i at rows + i *
// stride, into out[i * out_stride]; four at a time (the same values).
void TauSpeedRows(int64_t n, const double* rows, int64_t stride, double* out, int64_t out_stride);
// TauSpeed of rows r[0:m] (m <= 4; the rest repeat a row, as padding) into out[k * out_stride].
void TauSpeedFour(const double r[kLanes][10], int m, double* out, int64_t out_stride);
// TauSpeed of four sphere pairs, in lanes (the AVX2 clone where the CPU has it): pair k's state
// sj[k] - si[k] (each sphere's centre and velocity, 6 numbers, the subtraction taken in the
// lanes), its eps, accel, delta and speed from its pair record rec[k] (the same values as
// TauSpeedFour of those rows). Lane k's tau goes to out[at[k]], each of the four (a padding lane
// repeats a pair, so it writes that pair's value); returns the lanes below m the lanes did not
// settle (bit k), whose out[at[k]] TauSpeedFourPairsLeft then writes, from *ts and *speed_on.
int TauSpeedFourPairs(const double* const si[kLanes], const double* const sj[kLanes],
                      const double* const rec[kLanes], int m, double* out, const int64_t at[kLanes],
                      double ts[kLanes], int* speed_on);
void TauSpeedFourPairsLeft(const double* const si[kLanes], const double* const sj[kLanes],
                           const double* const rec[kLanes], int left, double* out,
                           const int64_t at[kLanes], const double ts[kLanes], int speed_on);
// A lower bound on TauAccel's first root from the two norms |x| and |v| alone (docs/theory.md,
// section 6, "Settling a made-due pair", Lemma 6.8): cover (1 + 1e-12) where the bound covers
// `cover` seconds (cover > 0; found without the root), else the bound itself, or -inf where it
// does not apply (in contact, or numbers out of the range where its rounding is accounted for).
// Never above TauAccel's exact root.
DUA_API double SettleTau(const double x[3], const double v[3], double eps, double accel,
                         double delta, double cover = 0.0);
double TauHalfspace(double gap, double normal_velocity, double accel, double delta);
// tau of a sphere (centre c, velocity v) against a static shape record; speed: the bound on the
// sphere's speed (inf: none).
double TauStatic(double c0, double c1, double c2, double v0, double v1, double v2,
                 const double* rec, double eps, double accel, double delta, double speed);
// tau raised by a speed bound (inf: none) on how fast a gap may close: a gap of `gap` (a lower
// bound, its rounding allowed for) between a point set and a static one, or two point sets,
// whose points move at most `bound` apart per second, lasts at least gap / bound. Like the
// sphere pairs' speed term, it is dropped when the speed measured now (`now`) is above the
// bound (the bound is broken: the acceleration term stands alone).
double WithGapSpeed(double tau, double gap, double now, double bound);
// tau of an object (a shape record at its pose, moving with velocity v, its points within spin t
// more of the translate) against the terrain of record rec, and of a sphere's centre
// (terrain.cc). *path, if given, says what decided it (the tests assert the search ran).
constexpr int kPathFirst = 0, kPathWindow = 1, kPathPyramid = 2;
DUA_API double TauTerrain(const double* rec, const double* shape, const double* v, double spin,
                          double eps, double accel, double delta, int* path = nullptr);
double TauTerrainSphere(double c0, double c1, double c2, double v0, double v1, double v2,
                        const double* rec, double eps, double accel, double delta);
// The support of the terrain's prisms along n (world), a point of the terrain over or under c
// (for drawing), and a lower bound of dist(c, terrain) with the terrain's up axis in n.
double TerrainSupport(const double* n, const double* rec);
void TerrainClosest(const double* c, const double* rec, double* out);
double TerrainGap(const double* c, const double* rec, double* n);
// The exact level's tau of held pair p, a geom against a terrain (ExactMode TERRAIN).
double TerrainExactTau(const dua_step_args& a, int64_t p);
// How many leading rows of a shape table (nrows rows of 16) are records: the rest are the
// blocks terrain records point to (terrain.cc).
DUA_API int64_t ShapeRecordCount(const double* shapes, int64_t nrows);

// Under a flight plan (docs/theory.md, section 9): a lower bound on dist(c, terrain) - eps for
// a point c, and on dist(geom, terrain) - eps for the exact level's geom record gx at pose (pos,
// mat); Theorem 9.3's bound of the object at rest with a unit velocity uncertainty (the first
// time at unit speed), 0 when it cannot exclude a contact now.
double TerrainPointGap(const double* c, const double* rec, double eps);
double TerrainGeomGap(const double* gx, const double* pos, const double* mat, const double* rec,
                      double eps);
// (n.c - h_S(n), n, |c| + |p| + h_local) of a point c and a static shape record, n the unit
// closest-point direction: a lower bound on c's distance to the shape (shapes.cc).
double StaticGap(double c0, double c1, double c2, const double* rec, double n[3], double* scale);
// Support of geom g of the exact level's tables at its pose in f along n (a mesh over its
// hull's vertices when MuJoCo has its hull graph, else over its box), the hill climb starting at
// hull vertex `start` (-1: the seed); *top receives the highest vertex (step.cc).
double GeomSupport(int64_t g, const dua_exact& x, const dua_frame& f, double n0, double n1,
                   double n2, int64_t start, int64_t* top);

// The point nearest the origin of the segment from w1 = b - a + r below to w2 = b' - a' + r below
// (step.cc; docs/theory.md, section 5, "Queries that cannot clear"): a, b the witness points w
// of the pair's latest query carried with their geoms to f, a', b' the hull vertices its last
// climbs reached (w2 only when both geoms are hulls), r = (r0, r1, r2). Writes it to q and the
// points' coordinates' magnitude to scale; returns 0 without a query yet (or below not > 0), 1
// with w1 alone, 2 with the segment. Every unit u has d_u + u.r below <= |q| (d_u the geoms'
// separation along u).
int Nearest(const double* w, double r0, double r1, double r2, const double* xrec,
            const dua_exact& x, const dua_frame& f, double below, double q[3], double* scale);
// v scaled to unit length (false: v too short next to the geoms' radii for a direction; step.cc).
bool Unit(double v[3], double radii);
// The unit direction from the first witness point w to the second, each carried with its geom to
// its pose in f (false: no query made yet, or the points too close for a direction; step.cc).
bool CarriedDirection(const double* w, int64_t g1, int64_t g2, const dua_exact& x,
                      const dua_frame& f, double out[3]);
// Stores the witness points fromto (world) in w, each in its geom's frame at f (step.cc).
void KeepWitness(const double fromto[6], int64_t g1, int64_t g2, const dua_frame& f, double* w);

// Where the point at coordinates l of a frame at pose (p, r) sits: p + r l (a sphere's centre,
// l its record's offset; a plan's knot; a witness point carried with its geom).
inline void PosePoint(const double* p, const double* r, const double* l, double* out) {
  const double o0 = l[0], o1 = l[1], o2 = l[2];
  for (int k = 0; k < 3; ++k) out[k] = p[k] + r[3 * k] * o0 + r[3 * k + 1] * o1 + r[3 * k + 2] * o2;
}

// Geom g's point at local coordinates l, at its pose in f.
inline void GeomPoint(int64_t g, const dua_frame& f, const double* l, double* out) {
  PosePoint(f.pos + 3 * g, f.mat + 9 * g, l, out);
}

// The rows of a frame one point reads (its geom's pose, its body's twist, its root's twist_ref,
// root_twist and root_origin), gathered in one row of kFrameRowLen (the monitor's screened check
// keeps them to rebuild a point later: checks.cc).
constexpr int kFrameR = 0, kFrameP = 9, kFrameTw = 12, kFrameRef = 18, kFrameRt = 21, kFrameRo = 27,
              kFrameRowLen = 30;

// Centre and velocity of point rec on the frame rows its RigidPoint reads (p, r: its geom's
// pose; tw: its body's twist; ref, rt, ro: its root's twist_ref, root_twist, root_origin):
// out[0:3] centre, out[3:6] velocity. The velocity is the body twist [w; v_ref] about cvel's
// reference point (subtree_com of the root), plus the twist of a mocap root (zero elsewhere).
inline void RigidPointOn(const double* rec, const double* p, const double* r, const double* tw,
                         const double* ref, const double* rt, const double* ro, double* out) {
  PosePoint(p, r, rec + kSphereOffset, out);
  const double dx = out[0] - ref[0], dy = out[1] - ref[1], dz = out[2] - ref[2];
  out[3] = tw[3] + tw[1] * dz - tw[2] * dy;
  out[4] = tw[4] + tw[2] * dx - tw[0] * dz;
  out[5] = tw[5] + tw[0] * dy - tw[1] * dx;
  // Whether some entry is not +-0 (NaN too), as rt[j] != 0.0 for some j, in one test of the
  // bits with the signs shifted out (zero but under a mocap root: six compares a point).
  uint64_t bits = 0;
  for (int j = 0; j < 6; ++j) {
    uint64_t b;
    std::memcpy(&b, rt + j, sizeof(b));
    bits |= b;
  }
  if (bits << 1 != 0) {
    const double ex = out[0] - ro[0], ey = out[1] - ro[1], ez = out[2] - ro[2];
    out[3] += rt[3] + rt[1] * ez - rt[2] * ey;
    out[4] += rt[4] + rt[2] * ex - rt[0] * ez;
    out[5] += rt[5] + rt[0] * ey - rt[1] * ex;
  }
}

// RigidPointOn of point i of a record table (sphere records, or the exact level's geom records,
// whose first columns are the same) on frame f.
inline void RigidPoint(int64_t i, const double* recs, int64_t ncol, const dua_frame& f,
                       double* out) {
  const double* rec = recs + i * ncol;
  const int64_t g = static_cast<int64_t>(rec[kSphereFrame]);
  const int64_t b = static_cast<int64_t>(rec[kSphereBody]);
  const int64_t r = static_cast<int64_t>(rec[kSphereRoot]);
  RigidPointOn(rec, f.pos + 3 * g, f.mat + 9 * g, f.twist + 6 * b, f.twist_ref + 3 * r,
               f.root_twist + 6 * r, f.root_origin + 3 * r, out);
}

// |w| r of geom g: how fast rotation can move its points away from translation.
inline double Spin(int64_t g, const double* geoms, const dua_frame& f) {
  const double* rec = geoms + g * kGxNcol;
  const int64_t b = static_cast<int64_t>(rec[kSphereBody]);
  const int64_t r = static_cast<int64_t>(rec[kSphereRoot]);
  const double w0 = f.twist[6 * b] + f.root_twist[6 * r];
  const double w1 = f.twist[6 * b + 1] + f.root_twist[6 * r + 1];
  const double w2 = f.twist[6 * b + 2] + f.root_twist[6 * r + 2];
  return std::sqrt(w0 * w0 + w1 * w1 + w2 * w2) * rec[kGxRadius];
}

// Below this magnitude a sphere's six numbers are tame: twelve of them (a pair's state) sum to
// a finite number (12e300 < DBL_MAX), so the gather's test of that sum can be skipped.
constexpr double kTame = 1e300;

// Whether a sphere's six numbers are tame (NaN is not).
inline bool Tame(const double* row) {
  bool ok = true;
  for (int j = 0; j < 6; ++j) ok &= std::fabs(row[j]) <= kTame;
  return ok;
}

// Sphere i's row of point_state (RigidPoint, read from MjData at its first use in this epoch),
// and in *tame whether its six numbers are all finite and at most kTame in magnitude.
// point_epoch holds 2 epoch + tame (an arithmetic shift gives the epoch back: -1, the start,
// reads as -1).
inline const double* PointRow(const dua_step_args& a, int64_t i, bool* tame) {
  double* state = a.point_state + 6 * i;
  int64_t e = a.point_epoch[i];
  if ((e >> 1) != a.epoch) {
    RigidPoint(i, a.spheres, kSphereNcol, a.frame, state);
    e = 2 * a.epoch + (Tame(state) ? 1 : 0);
    a.point_epoch[i] = e;
  }
  *tame = (e & 1) != 0;
  return state;
}

// PointRow's numbers copied into out.
inline void PointOf(const dua_step_args& a, int64_t i, double* out) {
  bool tame;
  const double* state = PointRow(a, i, &tame);
  // Six stores (std::copy became a call to memmove).
  out[0] = state[0], out[1] = state[1], out[2] = state[2];
  out[3] = state[3], out[4] = state[4], out[5] = state[5];
}

// SettleTau's inflation (Lemma 6.8).
constexpr double kSettleKappa = 1e-12;
// The least positive acceleration bound the sphere kernels solve with: a smaller one is raised
// to it (a larger bound only brings tau earlier; below it h^2 |v|^2 can underflow in the sphere
// kernel's test for g's interior minimum, docs/theory.md, section 1). The settling bound
// raises it alike, so that it stays below the kernel's tau (section 6).
constexpr double kAccelFloor = 1e-30;

// SettleTau (urgency.cc: the bindings' entry) on the relative state's six numbers, inline here so
// that the step's SettleBound pays no call a settled pair (the same operations in the same
// order, so the same bits; the build contracts nothing into fused multiply-adds).
// |x + v t| >= |x| - |v| t, so the predicate stays positive until |x| - |v| t = e + d t + h t^2:
// the positive root of h t^2 + (|v| + d) t - (|x| - e), in its cancellation-free form. The
// problem is inflated by kSettleKappa (as Inflate does, 250 times more) and the root lowered by
// it: the dozen roundings here are each 2^-53 relative, far inside it. The range test keeps the
// sum under the square root normal and finite (an underflowed b^2 would raise the root).
inline double SettleTauOf(double x0, double x1, double x2, double v0, double v1, double v2,
                          double eps, double accel, double delta, double cover) {
  const double nx = std::sqrt(x0 * x0 + x1 * x1 + x2 * x2);
  const double nv = std::sqrt(v0 * v0 + v1 * v1 + v2 * v2);
  // The norms within 2 units of 2^-53 (the proof's rounding) need the largest square normal:
  // |x| from 1e-100, |v| from 1e-100 or exactly zero. Below, the squares underflow (|x| of
  // 1.6e-162 came out 41 % long) and the pair is evaluated instead.
  if (!(nx >= 1e-100) || (nv < 1e-100 && (v0 != 0.0 || v1 != 0.0 || v2 != 0.0))) {
    return -std::numeric_limits<double>::infinity();
  }
  const double e = eps * (1.0 + kSettleKappa) + kSettleKappa * nx;
  const double d = delta * (1.0 + kSettleKappa) + kSettleKappa * nv;
  const double bound = 0.0 < accel && accel < kAccelFloor ? kAccelFloor : accel;
  const double h = 0.5 * bound * (1.0 + kSettleKappa);
  const double gap = nx - e, b = nv + d;
  // The cover first (no square root, no division): phi at t2 = cover (1 + 2k) positive means
  // the root is above t2, so cover (1 + k), below it and above the cover, is a lower bound.
  // Its rounding, a few units of 2^-53 of |x| (the largest term while phi > 0), is inside the
  // k |x| of e; the range test keeps every term finite and normal.
  if (cover > 1e-100 && cover < 1e100 && nx < 1e100 && b < 1e100 && h < 1e100) {
    const double t2 = cover * (1.0 + 2.0 * kSettleKappa);
    if (gap - t2 * (b + h * t2) > 0.0) return cover * (1.0 + kSettleKappa);
  }
  const double q = b * b + 4.0 * h * gap;
  if (!(gap > 0.0 && h >= 0.0 && b >= 0.0 && q >= 1e-280 && q <= 1e300)) {
    return -std::numeric_limits<double>::infinity();
  }
  return 2.0 * gap / (b + std::sqrt(q)) * (1.0 - kSettleKappa);
}

// The unit direction of MuJoCo's witness segment fromto (first geom to second) between the geoms
// of an exact record, written into the record (the next look starts from it, whether or not it
// helps now); false when the witness is too short for a direction (1e-9 of the two radii).
inline bool WitnessDirection(const double fromto[6], const dua_exact& x, int64_t g1, int64_t g2,
                             double* xrec, double n[3]) {
  n[0] = fromto[3] - fromto[0], n[1] = fromto[4] - fromto[1], n[2] = fromto[5] - fromto[2];
  const double length = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  const double radii = x.geoms[g1 * kGxNcol + kGxRadius] + x.geoms[g2 * kGxNcol + kGxRadius];
  if (!(length > 1e-9 * radii)) return false;
  n[0] /= length, n[1] /= length, n[2] /= length;
  xrec[kXN] = n[0], xrec[kXN + 1] = n[1], xrec[kXN + 2] = n[2];
  return true;
}

// The screen's reach test (docs/theory.md, section 3, "The screen", Lemma 3.9): two spheres at
// offset x whose speeds sum to at most `speeds`, under a pair's bounds that make `base` = eps +
// delta h + A h^2 / 2, cannot come within eps of each other in the next h seconds when |x| is
// past base + speeds h. Squared (no root a pair), with a relative margin far above the dozen
// roundings; h normal and below 1e50 s (h+ within 2^-52 of h, and an underflowed speed's loss,
// 5.6e-162 h, inside the margin), base at least kScreenLeastBase (so a cleared |x|^2 is above
// 1e-200, normal) and |x|^2 below 1e300; NaN and inf fail: the kernel takes those.
constexpr double kScreenMargin = 1.0 + 1e-9;
constexpr double kScreenLeastBase = 1e-100;
// The test's conditions on h: the same for every pair of a step (the pass tests them once).
inline bool ScreenHorizon(double h) { return h >= 0x1p-1022 && h < 1e50; }

// The bounds' part of a pair's reach over h: eps + delta h + A h^2 / 2.
inline double ScreenBase(double eps, double accel, double delta, double h) {
  return eps + delta * h + 0.5 * accel * h * h;
}

// A sphere's row as the screen reads it (4 numbers): its centre, and its speed, the norm of its
// velocity, or +inf where its row is not tame (no pair of it is cleared).
inline void ScreenRow(const double* row, bool tame, double* out) {
  out[0] = row[0], out[1] = row[1], out[2] = row[2];
  out[3] = tame ? std::sqrt(row[3] * row[3] + row[4] * row[4] + row[5] * row[5])
                : std::numeric_limits<double>::infinity();
}

// ScreenRow of sphere i as the step reads it (PointRow: in a's epoch, shared with the kernel).
inline void ScreenRowOf(const dua_step_args& a, int64_t i, double* out) {
  bool tame;
  const double* row = PointRow(a, i, &tame);
  ScreenRow(row, tame, out);
}

// The test on the screen rows si and sj of a pair's spheres (offset sj - si), for h that
// ScreenHorizon passes and base at least kScreenLeastBase (a screened pair's: its base was checked
// as it entered): then reach >= base, so a cleared |x|^2 > reach^2 (1 + 1e-9) is above 1e-200
// without a test of its own.
inline bool ScreenedPairClears(const double* si, const double* sj, double base, double h) {
  const double x0 = sj[0] - si[0], x1 = sj[1] - si[1], x2 = sj[2] - si[2];
  const double speeds = si[3] + sj[3];
  const double d2 = x0 * x0 + x1 * x1 + x2 * x2;
  const double reach = base + speeds * h;
  return d2 < 1e300 && d2 > reach * reach * kScreenMargin;
}

// The whole test, its conditions on h and base included: where a pair enters the screen, and
// the bindings' entry (screen_clears).
inline bool ScreenClearsRows(const double* si, const double* sj, double base, double h) {
  return ScreenHorizon(h) && base >= kScreenLeastBase && ScreenedPairClears(si, sj, base, h);
}

// The deadline schedule's screen at step n (schedule.cc; docs/theory.md, section 3, "The
// screen"): each screened pair that a's state clears keeps a verdict of step n (LAST_STEP n, tau
// just above the horizon); each one it does not (every one when a is null: no state to test, or
// the step may not screen) leaves the screen and is appended to the selection w_ids[count:].
// Entries of pairs that left the screen between steps are dropped. Returns the new count.
int64_t ScreenPass(dua_schedule* st, int64_t n, int64_t count, const dua_step_args* a);
// Every screened pair back on the wheel, due at step n (its verdict kept).
void Unscreen(dua_schedule* st, int64_t n);
// After the reinsertion of step n's count evaluated pairs: each sphere pair out of alarm that
// the reach test clears on this step's state moves from the wheel to the screen.
void ScreenEnter(dua_schedule* st, int64_t n, int64_t count, const dua_step_args& a);

// dua_make_due of pairs ids[0:count] at step n (schedule.cc).
void MakeDue(dua_schedule* st, const int64_t* ids, int64_t count, int64_t n);
// MakeDue of the pairs of groups[0:ngroups] (group g: members[start[g]:start[g + 1]]), in that
// order, then dua_select at step n: the same selection, in the same order (schedule.cc). With
// the step's arguments `settle` (deadline schedules), a made-due pair that does not stand in
// alarm and whose SettleBound on them does not alarm is settled instead: the bound is its
// verdict of step n, linked where (3) puts it, and it is not selected (docs/theory.md, section
// 6, "Settling a made-due pair").
DUA_API int64_t SelectMadeDue(dua_schedule* st, const int64_t* groups, int64_t ngroups,
                              const int64_t* start, const int64_t* members, int64_t n,
                              const dua_step_args* settle = nullptr,
                              const dua_step_args* screen = nullptr);

// Bucket floor(log2(slot + 1)) of a rank slot.
inline int64_t BucketOf(int64_t slot) {
  int64_t k = 0;
  while ((int64_t{2} << k) - 1 <= slot) ++k;
  return k;
}

// Rounding allowances of the static-shape and exact-level gaps (docs/static-shapes.md): a gap's
// rounding is a few units of 2^-53 times the magnitudes it is made of (1e-14 is ~45 of them),
// and n.v's rounding is treated as extra velocity uncertainty.
constexpr double kGapSlack = 1e-14, kVelSlack = 1e-14;

// Support of a shape in its own frame along m (any length: every form is homogeneous); kind is
// MuJoCo's mjtGeom code (7: a mesh held as its box).
inline double SupportLocal(int kind, double s0, double s1, double s2, double m0, double m1,
                           double m2) {
  switch (kind) {
    case kGeomSphere:
      return s0 * std::sqrt(m0 * m0 + m1 * m1 + m2 * m2);
    case kGeomCapsule:
      return std::fabs(m2) * s1 + s0 * std::sqrt(m0 * m0 + m1 * m1 + m2 * m2);
    case kGeomCylinder:  // r |m_xy|, no cancellation
      return std::fabs(m2) * s1 + s0 * std::hypot(m0, m1);
    case kGeomEllipsoid: {
      const double a = s0 * m0, b = s1 * m1, c = s2 * m2;
      return std::sqrt(a * a + b * b + c * c);
    }
    default:  // box, and a mesh's box (which bounds its hull's support)
      return std::fabs(m0) * s0 + std::fabs(m1) * s1 + std::fabs(m2) * s2;
  }
}

// ------------------------------------------------------------------ the predictor's grid
// Every tau the schedule acts on lies on the predictor's grid: whole periods of p physics steps
// of h, shaved (docs/theory.md, section 8). The deadline rule (3) keeps a verdict while
// (w + latency) dt + extra < tau, which gives the alarm horizon's lead only for a tau on the
// grid of dt: a contact s = q p + r steps ahead (0 < r < p) could otherwise be covered until
// (q - N - latency + 1) periods and flagged only H + latency dt - r h before it. Rounding down
// to q p steps keeps the lead, and q p steps are still no more than the contact's. On the grid
// the test compares two roundings of the same number: (alarm steps + w) dt can round below the
// tau and let a pair wait one step past the one at which it must stand in alarm; 1e-9 relative
// is far above those roundings (a few ulps) and far below a step.
constexpr double kGridShave = 1e-9;

// A tau s whole steps of h ahead (a plan's) on the grid of period p: floor(s / p) p h, shaved.
// With p = 1 only the shave, since s h is on the grid already.
inline double GridTau(int64_t s, double h, int64_t p) {
  const int64_t grid = p > 1 ? s / p * p : s;
  return static_cast<double>(grid) * h * (1.0 - kGridShave);
}

// Any lower bound tau (seconds; the motion bounds', the exact level's) on the time from the read
// to the pair's first state in contact, on the grid of period p > 1. That state is at a physics
// step, so at least ceil(tau / h) steps ahead: GridTau of s = ceil of the computed tau / h, never
// above the true ceiling (the division is correctly rounded and every whole number up to 2^53 is
// a double, so a quotient at or below k never rounds above k; the build has no fast-math).
// Steps are counted up to 2^52 (the grid of a farther tau is that of 2^52 steps). 0 and below
// (an alarm whatever its value) and +inf (no contact ever) are left as they are, and so is NaN
// (the step makes it 0).
inline double GridFloor(double tau, double h, int64_t p) {
  constexpr double kFar = 4503599627370496.0;  // 2^52
  if (!(tau > 0.0) || std::isinf(tau)) return tau;
  const double s = std::min(std::ceil(tau / h), kFar);
  return GridTau(static_cast<int64_t>(s), h, p);
}

// A lower bound on made-due held pair p's tau from the state of step n, cheaper than its
// evaluation (at most the horizon, -inf included, where it settles nothing): SettleTau on the
// frame against the time its present wait covers (cover; it may return just above it when it
// covers), a sphere pair's two rows read as the gather reads them (each sphere once a step: the
// epoch the step's TauOf uses next), on the predictor's grid with period > 1; -inf (not
// settled) for other kinds and untamed states. Inline: SelectMadeDue calls it for most of a
// flagged body's pairs (through a function pointer, the call was 4 % of yam's plugin).
inline double SettleBound(const dua_step_args& a, int64_t p, double cover) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const double* rec = a.pairs + p * kPairNcol;
  if (static_cast<int>(rec[kPairKind]) != kKindSphere) return -kInf;
  bool tame_i, tame_j;
  const double* si = PointRow(a, static_cast<int64_t>(rec[kPairFirst]), &tame_i);
  const double* sj = PointRow(a, static_cast<int64_t>(rec[kPairSecond]), &tame_j);
  if (!(tame_i && tame_j)) return -kInf;
  // With period > 1 every tau goes on the grid, which the cover's (just above a step) is not.
  const bool grid = a.period > 1;
  const double t = SettleTauOf(sj[0] - si[0], sj[1] - si[1], sj[2] - si[2], sj[3] - si[3],
                               sj[4] - si[4], sj[5] - si[5], rec[kPairEps], rec[kPairAccel],
                               rec[kPairDelta], grid ? 0.0 : cover);
  return grid ? GridFloor(t, a.timestep, a.period) : t;
}

}  // namespace dua

#endif  // DUA_MUJOCO_INTERNAL_H_
