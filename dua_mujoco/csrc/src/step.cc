// The MuJoCo layer's fused step: the violation check, the selection, the gather of the selected
// pairs' states from MjData, tau at every level (spheres, static shapes, planes, the exact level
// through mj_geomDistance) and the reinsertion. Proofs: docs/theory.md.
#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "dua/dua.h"
#include "internal.h"
#include "lanes.h"
#include "layout.h"
#include "plan.h"

namespace dua {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr double kInf = std::numeric_limits<double>::infinity();

// ------------------------------------------------------------------------------- events

// Whether max |a + s0 x + s1 y + s2 z| over the eight sign choices exceeds bound; two upper
// bounds screen first. Exact only while the squares do not underflow (Exceeds12 below).
template <class T>
MaskOf<T> Exceeds12Squared(T a0, T a1, T a2, T x0, T x1, T x2, T y0, T y1, T y2, T z0, T z1, T z2,
                           T bound) {
  const T na = a0 * a0 + a1 * a1 + a2 * a2, nx = x0 * x0 + x1 * x1 + x2 * x2;
  const T ny = y0 * y0 + y1 * y1 + y2 * y2, nz = z0 * z0 + z1 * z1 + z2 * z2;
  const MaskOf<T> wide = Not(4.0 * (na + nx + ny + nz) <= bound * bound);
  if (!Any(wide)) return wide;
  const MaskOf<T> open = AndNot(wide, Sqrt(na) + Sqrt(nx) + Sqrt(ny) + Sqrt(nz) <= bound);
  if (!Any(open)) return open;
  T worst = T{};
  for (double sx : {-1.0, 1.0}) {
    for (double sy : {-1.0, 1.0}) {
      for (double sz : {-1.0, 1.0}) {
        const T u = a0 + sx * x0 + sy * y0 + sz * z0;
        const T v = a1 + sx * x1 + sy * y1 + sz * z1;
        const T w = a2 + sx * x2 + sy * y2 + sz * z2;
        worst = Max(worst, u * u + v * v + w * w);
      }
    }
  }
  return And(open, Sqrt(worst) > bound);
}

// Exceeds12 of q = {a, x, y, z, bound} scaled by a power of two (exact) so that the largest is
// in [1, 2): no square underflows.
bool Exceeds12Scaled(const double q[13]) {
  double big = 0.0;
  for (int j = 0; j < 13; ++j) big = std::max(big, std::fabs(q[j]));
  if (!(big > 0.0)) return 0.0 > q[12];  // every corner is 0
  const int e = std::ilogb(big);
  double s[13];
  for (int j = 0; j < 13; ++j) s[j] = std::ldexp(q[j], -e);
  return Exceeds12Squared(s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7], s[8], s[9], s[10], s[11],
                          s[12]);
}

// Exceeds12Squared, but squares below ~1e-308 underflow: with a bound below 1e-139, numbers that
// small could read as 0 and pass it (a norm of 1e-162 against a bound of 0), so such lanes are
// checked again scaled. (Above it, numbers whose squares underflow are far below the bound.)
template <class T>
MaskOf<T> Exceeds12(T a0, T a1, T a2, T x0, T x1, T x2, T y0, T y1, T y2, T z0, T z1, T z2,
                    T bound) {
  MaskOf<T> out = Exceeds12Squared(a0, a1, a2, x0, x1, x2, y0, y1, y2, z0, z1, z2, bound);
  const MaskOf<T> small = bound < 1e-139;
  if (!Any(small)) return out;
  for (int k = 0; k < LaneCount<T>(); ++k) {
    if (!LaneOf(small, k)) continue;
    const double q[13] = {LaneOf(a0, k),   LaneOf(a1, k), LaneOf(a2, k), LaneOf(x0, k),
                          LaneOf(x1, k),   LaneOf(x2, k), LaneOf(y0, k), LaneOf(y1, k),
                          LaneOf(y2, k),   LaneOf(z0, k), LaneOf(z1, k), LaneOf(z2, k),
                          LaneOf(bound, k)};
    SetLane(&out, k, Exceeds12Scaled(q));
  }
  return out;
}

// One body's inputs to the check, in one row: what it reads from MjData (its geom's pose R, P and
// the twists RigidPoint reads: tw, ref, rt, ro). Its state (StateAt: the box's centre o and half
// sizes in that frame, its bounds, and what the last steps left), which the check updates, is
// read and written where it lives.
constexpr int kRowR = 0, kRowP = 9, kRowTw = 12, kRowRef = 18, kRowRt = 21, kRowRo = 27,
              kRowLen = 30;
template <class T>
struct BodyRow {
  T v[kRowLen];
};
// Four bodies' state column as it lies in ev.prev: one vector (read as the doubles it holds).
// CheckBodies takes the lanes only where ev.prev is aligned as a vector (LanesAlignedAt): clang
// drops the alias's `aligned(8)` and a template argument loses it in either compiler.
using LanesAt = double __attribute__((vector_size(8 * kLanes), aligned(8), may_alias));

// The row's MjData fields in order (their first column and length), and where body i's come
// from.
constexpr int kFields = 6;
constexpr int kFieldAt[kFields] = {kRowR, kRowP, kRowTw, kRowRef, kRowRt, kRowRo};
constexpr int kFieldLen[kFields] = {9, 3, 6, 3, 6, 3};

// A body's row's places in the frame, from its frame geom times 3, its body times 6 and its root
// times 3 (the indices dua_reset_events writes into the state as kSIndex).
inline void Sources(const dua_frame& f, int64_t g3, int64_t b6, int64_t r3,
                    const double* src[kFields]) {
  const double* from[kFields] = {f.mat + 3 * g3,        f.pos + g3,
                                 f.twist + b6,          f.twist_ref + r3,
                                 f.root_twist + 2 * r3, f.root_origin + r3};
  std::copy(from, from + kFields, src);
}

void RowSources(const dua_events& ev, const dua_frame& f, int64_t i, const double* src[kFields]) {
  const double* rec = ev.rec + i * kBNcol;
  Sources(f, 3 * static_cast<int64_t>(rec[kBFrame]), 6 * static_cast<int64_t>(rec[kBBody]),
          3 * static_cast<int64_t>(rec[kBRoot]), src);
}

// Column j of body i's state: the state is (ceil(nbody / 4), kSNcol, 4), so that four bodies'
// column is one vector.
inline double* StateAt(const dua_events& ev, int64_t i, int j) {
  return ev.prev + ((i / kLanes) * kSNcol + j) * kLanes + i % kLanes;
}

// Record a body's box state in prev (its kSNcol columns: S is T, or LanesAt in place) and check
// the motion hypotheses over the last period (nprev earlier states there): whether the body broke
// them. The box's four vectors (centre, then its three axes) are taken one at a time: each reads
// its own columns of the last state (its corner, its chord, and for the discrepancy the last
// axis itself: (W x E)'s column j is W x E_j), then writes its new ones, so that few values stay
// live (held through the three screens, they were spilled and read back: a fifth of the check's
// instructions). What the screens need past their first test (its twelve numbers) is kept aside;
// the chord's are its state columns. Every operation and its operands are the ones of the check
// that read every column before writing any, so the flags and the state are the same bits.
template <class T, class S>
MaskOf<T> CheckBody(const BodyRow<T>* row, S* prev, int64_t nprev, double h, double inv_h,
                    double rtol) {
  const T* R = row->v + kRowR;
  const T* P = row->v + kRowP;
  const T o0 = prev[kSCenter], o1 = prev[kSCenter + 1], o2 = prev[kSCenter + 2];
  const T h0 = prev[kSHalf], h1 = prev[kSHalf + 1], h2 = prev[kSHalf + 2];
  // What the last step left that this one reads after writing its vectors: w_{k-1} and the
  // centre's velocity (the discrepancy), the scale (the round-off).
  const T px = prev[kSW], py = prev[kSW + 1], pz = prev[kSW + 2];
  const T qvx = prev[kSV], qvy = prev[kSV + 1], qvz = prev[kSV + 2];
  const T scale_prev = prev[kSScale];
  // The box's centre (its velocity as RigidPoint reads a point's, below).
  const T cx = P[0] + R[0] * o0 + R[1] * o1 + R[2] * o2;
  const T cy = P[1] + R[3] * o0 + R[4] * o1 + R[5] * o2;
  const T cz = P[2] + R[6] * o0 + R[7] * o1 + R[8] * o2;
  // Bounds every corner's coordinates: the scale of the differences' round-off (a sum over the
  // four vectors, in their order).
  T s0 = Abs(cx), s1 = Abs(cy), s2 = Abs(cz);
  // The three screens' sums of squares (first test) and their twelve numbers: the speed's are
  // the chord (written to the state), the others kept here.
  T n_speed = T{}, n_disc = T{}, n_accel = T{};
  T disc[12], accel[12];
  // Vector k of the box (0 the centre, 1-3 its axes) is e: its chord, the screens' numbers,
  // and the new state columns.
  auto vector = [&](int k, T e0, T e1, T e2) {
    const int at = 3 * k;
    const T l0 = prev[at], l1 = prev[at + 1], l2 = prev[at + 2];
    prev[at] = e0, prev[at + 1] = e1, prev[at + 2] = e2;
    if (k > 0) s0 = s0 + Abs(e0), s1 = s1 + Abs(e1), s2 = s2 + Abs(e2);
    if (nprev < 1) return;
    const T u0 = (e0 - l0) * inv_h, u1 = (e1 - l1) * inv_h, u2 = (e2 - l2) * inv_h;
    const T nu = u0 * u0 + u1 * u1 + u2 * u2;
    n_speed = k == 0 ? nu : n_speed + nu;
    // The discrepancy U_k - w_{k-1}: at the centre its velocity, on an axis W x (that axis).
    const T d0 = k == 0 ? u0 - qvx : u0 - (py * l2 - pz * l1);
    const T d1 = k == 0 ? u1 - qvy : u1 - (pz * l0 - px * l2);
    const T d2 = k == 0 ? u2 - qvz : u2 - (px * l1 - py * l0);
    disc[at] = d0, disc[at + 1] = d1, disc[at + 2] = d2;
    const T nd = d0 * d0 + d1 * d1 + d2 * d2;
    n_disc = k == 0 ? nd : n_disc + nd;
    if (nprev >= 2) {
      const T a0 = (u0 - prev[12 + at]) * inv_h, a1 = (u1 - prev[12 + at + 1]) * inv_h,
              a2 = (u2 - prev[12 + at + 2]) * inv_h;
      accel[at] = a0, accel[at + 1] = a1, accel[at + 2] = a2;
      const T na = a0 * a0 + a1 * a1 + a2 * a2;
      n_accel = k == 0 ? na : n_accel + na;
    }
    prev[12 + at] = u0, prev[12 + at + 1] = u1, prev[12 + at + 2] = u2;
  };
  vector(0, cx, cy, cz);
  // The axes: columns of R diag(half).
  vector(1, R[0] * h0, R[3] * h0, R[6] * h0);
  vector(2, R[1] * h1, R[4] * h1, R[7] * h1);
  vector(3, R[2] * h2, R[5] * h2, R[8] * h2);
  const T scale = Max(Max(s0, s1), s2);
  // The centre's velocity as RigidPoint reads a point's.
  const T* tw = row->v + kRowTw;
  const T* ref = row->v + kRowRef;
  const T* rt = row->v + kRowRt;
  const T* ro = row->v + kRowRo;
  const T w0 = tw[0], w1 = tw[1], w2 = tw[2];
  const T dx = cx - ref[0], dy = cy - ref[1], dz = cz - ref[2];
  const T m0 = rt[0], m1 = rt[1], m2 = rt[2];
  const T ex = cx - ro[0], ey = cy - ro[1], ez = cz - ro[2];
  prev[kSV] = tw[3] + w1 * dz - w2 * dy + rt[3] + m1 * ez - m2 * ey;
  prev[kSV + 1] = tw[4] + w2 * dx - w0 * dz + rt[4] + m2 * ex - m0 * ez;
  prev[kSV + 2] = tw[5] + w0 * dy - w1 * dx + rt[5] + m0 * ey - m1 * ex;
  prev[kSW] = w0 + m0, prev[kSW + 1] = w1 + m1, prev[kSW + 2] = w2 + m2;
  prev[kSScale] = scale;
  MaskOf<T> broken = T{} != T{};
  if (nprev < 1) return broken;
  const T tol_a = 8.0 * kEps * (scale + scale_prev) / (h * h);
  const T speed = prev[kSSpeed];
  // An infinite speed bound screens out (bound inf), as if skipped.
  const T b_speed = speed * (1.0 + rtol) + 0.5 * tol_a * h;
  const T tol_d = tol_a * h + 8.0 * kEps * (Abs(qvx) + Abs(qvy) + Abs(qvz));
  const T b_disc = prev[kSDisc] * (1.0 + rtol) + tol_d;
  // Exceeds12's first test (and its rescaled one) alone, which most steps pass: a screen whose
  // test passes on every lane flags none, as Exceeds12 would; any other is Exceeds12 itself.
  auto passes = [](T n, T bound) { return And(4.0 * n <= bound * bound, Not(bound < 1e-139)); };
  MaskOf<T> open = Not(And(passes(n_speed, b_speed), passes(n_disc, b_disc)));
  const T b_accel = prev[kSAccel] * (1.0 + rtol) + tol_a;
  if (nprev >= 2) open = Or(open, Not(passes(n_accel, b_accel)));
  if (__builtin_expect(!Any(open), 1)) return broken;
  const S* u = prev + 12;
  broken = Or(broken, And(speed < kInf, Exceeds12<T>(u[0], u[1], u[2], u[3], u[4], u[5], u[6], u[7],
                                                     u[8], u[9], u[10], u[11], b_speed)));
  broken = Or(broken, Exceeds12(disc[0], disc[1], disc[2], disc[3], disc[4], disc[5], disc[6],
                                disc[7], disc[8], disc[9], disc[10], disc[11], b_disc));
  if (nprev >= 2) {
    broken =
        Or(broken, Exceeds12(accel[0], accel[1], accel[2], accel[3], accel[4], accel[5], accel[6],
                             accel[7], accel[8], accel[9], accel[10], accel[11], b_accel));
  }
  return broken;
}

// CheckBody of bodies i .. i + m - 1 (m <= 4) in lanes: bit k of the result for body i + k. A
// short group repeats its last body in the spare lanes (their flags are dropped; their state
// goes to the padding).
DUA_LANES_CLONES
int CheckFour(const dua_events& ev, const dua_frame& f, int64_t i, int m, int64_t nprev, double h,
              double inv_h, double rtol) {
  // Each field read across the four bodies' sources straight into lanes (not through a copy
  // of the rows, and not written lane by lane into the vectors: narrow stores under a wide load
  // stall the store forwarding).
  // The rows' places from the state (the reset wrote them, the padding's as its last body's:
  // RowSources of body i + min(k, m - 1)).
  int32_t at[kSIndexInts];
  __builtin_memcpy(at, StateAt(ev, i, kSIndex), sizeof(at));
  const double* src[kLanes][kFields];
  for (int k = 0; k < kLanes; ++k) Sources(f, at[2 * k], at[2 * k + 1], at[8 + 2 * k], src[k]);
  BodyRow<Lanes> row;
  // Unrolled: the loops' own counting and the lengths' lookups were a fifth of the check.
  // Each field's runs of four (the pose's first eight, the twists' first four) read a vector a
  // body and transposed; the rest a double at a time.
  // The four bodies' runs of a field from double j on, one vector a body.
  auto load = [&](auto& r0, auto& r1, auto& r2, auto& r3, int field, int j) {
    __builtin_memcpy(&r0, src[0][field] + j, sizeof(r0));
    __builtin_memcpy(&r1, src[1][field] + j, sizeof(r1));
    __builtin_memcpy(&r2, src[2][field] + j, sizeof(r2));
    __builtin_memcpy(&r3, src[3][field] + j, sizeof(r3));
  };
  auto transpose = [&](int field, int j, int at) {
    Lanes r[kLanes];
    load(r[0], r[1], r[2], r[3], field, j);
    Transpose4(r, row.v + at);
  };
  transpose(0, 0, kRowR);
  transpose(0, 4, kRowR + 4);
  transpose(2, 0, kRowTw);
  transpose(4, 0, kRowRt);
  // Runs of two (the positions' first two, the twists' last two) read two doubles a body, put
  // together two bodies a half and unpacked; the rest a double at a time.
  auto pair = [&](int field, int j, int at) {
    using Half = double __attribute__((vector_size(16)));
    Half r0, r1, r2, r3;
    load(r0, r1, r2, r3, field, j);
    const Lanes t02 = __builtin_shufflevector(r0, r2, 0, 1, 2, 3);
    const Lanes t13 = __builtin_shufflevector(r1, r3, 0, 1, 2, 3);
    row.v[at] = __builtin_shufflevector(t02, t13, 0, 4, 2, 6);
    row.v[at + 1] = __builtin_shufflevector(t02, t13, 1, 5, 3, 7);
  };
  auto across = [&](int field, int j, int at) {
    row.v[at] = Lanes{src[0][field][j], src[1][field][j], src[2][field][j], src[3][field][j]};
  };
  across(0, 8, kRowR + 8);
  pair(1, 0, kRowP);
  across(1, 2, kRowP + 2);
  pair(2, 4, kRowTw + 4);
  pair(3, 0, kRowRef);
  across(3, 2, kRowRef + 2);
  pair(4, 4, kRowRt + 4);
  pair(5, 0, kRowRo);
  across(5, 2, kRowRo + 2);
  // The state's columns are whole vectors, the padding's too: a ragged last group's spare lanes
  // hold its last body's state (its inputs, and its box and bounds from the reset), so they
  // take the same paths through the screens.
  // The four bodies' columns are one block (i is a multiple of four), read and written in place
  // (copied in and out whole, they were a quarter of the check's instructions).
  LanesAt* state = reinterpret_cast<LanesAt*>(StateAt(ev, i, 0));
  const LaneMask broken = CheckBody(&row, state, nprev, h, inv_h, rtol);
  return Bits(broken) & ((1 << m) - 1);
}

// Record every body's box state and check the motion hypotheses over the last period, four
// bodies at a time unless !lanes (the same values as one at a time, lanes.h: the reference the
// tests hold the lanes to); the flagged bodies' rows go to ev.flagged. Returns their number.
DUA_SECTION int64_t CheckBodies(const dua_events& ev, const dua_frame& f, bool lanes = true) {
  const double h = ev.params[0], rtol = ev.params[1];
  const double inv_h = 1.0 / h;  // a product per chord, not a division
  const int64_t nprev = ev.meta[kMNprev];
  int64_t count = 0;
  int64_t i = 0;
  // On storage not aligned as a vector (a C caller's), one body at a time: the same values.
  lanes = lanes && LanesAlignedAt(ev.prev);
  for (; lanes && i < ev.nbody; i += kLanes) {
    const int m = static_cast<int>(std::min<int64_t>(kLanes, ev.nbody - i));
    // The flagged lanes by their bits, lowest first (most groups have none).
    for (int bits = CheckFour(ev, f, i, m, nprev, h, inv_h, rtol); bits != 0; bits &= bits - 1) {
      ev.flagged[count++] = i + __builtin_ctz(static_cast<unsigned>(bits));
    }
  }
  for (; i < ev.nbody; ++i) {
    BodyRow<double> row;
    const double* src[kFields];
    RowSources(ev, f, i, src);
    for (int field = 0; field < kFields; ++field) {
      std::copy(src[field], src[field] + kFieldLen[field], row.v + kFieldAt[field]);
    }
    double state[kSNcol];
    for (int j = 0; j < kSNcol; ++j) state[j] = *StateAt(ev, i, j);
    const bool broken = CheckBody(&row, state, nprev, h, inv_h, rtol);
    for (int j = 0; j < kSWritten; ++j) *StateAt(ev, i, j) = state[j];
    if (broken) ev.flagged[count++] = i;
  }
  ev.meta[kMNprev] = std::min<int64_t>(nprev + 1, 2);
  ev.meta[kMCount] = count;
  ev.meta[kMTotal] += count;
  return count;
}

// ------------------------------------------------------------------------------- exact level

// max m.v over the hull vertices of mesh geom g (local direction m): a hill climb on MuJoCo's
// hull graph (a linear function's local maximum over a polytope is global), from last time's
// highest vertex, or before the first climb the stored extreme vertex of the axis nearest m. Each
// step reads the vertex's climb row (its neighbours' coordinates beside their ids) and moves to
// its highest neighbour, the first of equals, while that is higher. Writes the highest vertex's
// local id to top.
double HullSupport(int64_t g, const dua_exact& x, double m0, double m1, double m2, int64_t start,
                   int64_t* top) {
  const double* rec = x.geoms + g * kGxNcol;
  const int64_t* row = x.climb_at + x.hull_at[g];
  auto height = [&](const dua_hull_entry& v) {
    return m0 * static_cast<double>(v.x) + m1 * static_cast<double>(v.y) +
           m2 * static_cast<double>(v.z);
  };
  int64_t imax = start;
  if (imax < 0) {
    const double a0 = std::fabs(m0), a1 = std::fabs(m1), a2 = std::fabs(m2);
    int seed;
    if (a0 >= a1 && a0 >= a2) {
      seed = kGxSeed + (m0 > 0.0 ? 1 : 0);
    } else if (a1 >= a2) {
      seed = kGxSeed + (m1 > 0.0 ? 3 : 2);
    } else {
      seed = kGxSeed + (m2 > 0.0 ? 5 : 4);
    }
    imax = static_cast<int64_t>(rec[seed]);
  }
  const dua_hull_entry* v = x.climb + row[imax];
  double best = height(*v);
  int64_t prev = -1;
  while (imax != prev) {
    prev = imax;
    const int32_t n = v->id;
    for (int32_t k = 1; k <= n; ++k) {
      const double val = height(v[k]);
      if (val > best) {
        best = val;
        imax = v[k].id;
      }
    }
    v = x.climb + row[imax];
  }
  *top = imax;
  return best;
}

}  // namespace

double GeomSupport(int64_t g, const dua_exact& x, const dua_frame& f, double n0, double n1,
                   double n2, int64_t start, int64_t* top) {
  const double* rec = x.geoms + g * kGxNcol;
  const double* m = f.mat + 9 * g;
  const double* p = f.pos + 3 * g;
  if (rec[kGxGraph] >= 0.0) {
    const double l0 = m[0] * n0 + m[3] * n1 + m[6] * n2;
    const double l1 = m[1] * n0 + m[4] * n1 + m[7] * n2;
    const double l2 = m[2] * n0 + m[5] * n1 + m[8] * n2;
    const double h = HullSupport(g, x, l0, l1, l2, start, top);
    return n0 * p[0] + n1 * p[1] + n2 * p[2] + h;
  }
  *top = -1;
  // The support shape's centre: the origin plus R c (c: a mesh box's centre, else 0).
  const double c0 = rec[kGxCentre], c1 = rec[kGxCentre + 1], c2 = rec[kGxCentre + 2];
  const double q0 = p[0] + m[0] * c0 + m[1] * c1 + m[2] * c2;
  const double q1 = p[1] + m[3] * c0 + m[4] * c1 + m[5] * c2;
  const double q2 = p[2] + m[6] * c0 + m[7] * c1 + m[8] * c2;
  const double k0 = m[0] * n0 + m[3] * n1 + m[6] * n2;
  const double k1 = m[1] * n0 + m[4] * n1 + m[7] * n2;
  const double k2 = m[2] * n0 + m[5] * n1 + m[8] * n2;
  return n0 * q0 + n1 * q1 + n2 * q2 +
         SupportLocal(static_cast<int>(rec[kGxKind]), rec[kGxSize], rec[kGxSize + 1],
                      rec[kGxSize + 2], k0, k1, k2);
}

namespace {

// tau of the pair's separation along unit n (first geom to second):
// d_n + (n.r - spin) t - delta t - A t^2 / 2, d_n from the supports, r the origins' relative
// velocity.
DUA_SECTION double AxisTau(double n0, double n1, double n2, int mode, double r0, double r1,
                           double r2, double spin, const double* pair, double* xrec,
                           const dua_exact& x, const dua_frame& f) {
  const int64_t g2 = static_cast<int64_t>(xrec[kXG2]);
  double low_b;
  int64_t top;
  if (mode == kModePlane) {
    low_b = n0 * f.pos[3 * g2] + n1 * f.pos[3 * g2 + 1] + n2 * f.pos[3 * g2 + 2];
  } else {  // a moving geom, or a static one (its pose in MjData is as good as the shape's)
    low_b = -GeomSupport(g2, x, f, -n0, -n1, -n2, static_cast<int64_t>(xrec[kXHull2]), &top);
    xrec[kXHull2] = static_cast<double>(top);
  }
  const int64_t g1 = static_cast<int64_t>(xrec[kXG1]);
  const double h_a = GeomSupport(g1, x, f, n0, n1, n2, static_cast<int64_t>(xrec[kXHull1]), &top);
  xrec[kXHull1] = static_cast<double>(top);
  const double scale = std::fabs(h_a) + std::fabs(low_b) + xrec[kXDist];
  const double gap = low_b - h_a - xrec[kXDist] - kGapSlack * scale;
  if (gap <= 0.0) return 0.0;
  const double vn = n0 * r0 + n1 * r1 + n2 * r2 - spin;
  const double speed = std::sqrt(r0 * r0 + r1 * r1 + r2 * r2) + spin;
  return WithGapSpeed(TauHalfspace(gap, vn, pair[kPairAccel], pair[kPairDelta] + kVelSlack * speed),
                      gap, speed, pair[kPairSpeed]);
}

// Contacts up to this many are scanned; more are indexed once a batch (sorted keys).
constexpr int kContactScan = 16;

// MuJoCo's contacts of x.data indexed by geom pair (their least distance each), when there are
// many and there is room: sorted keys min << 32 | max in x.contact_keys.
void IndexContacts(dua_exact& x) {
  const mjData* d = static_cast<const mjData*>(x.data);
  if (d->ncon <= kContactScan || d->ncon > x.contact_room) {
    x.contact_count = -2;  // scan
    return;
  }
  int64_t n = 0;
  for (int i = 0; i < d->ncon; ++i) {
    const int a = d->contact[i].geom[0], b = d->contact[i].geom[1];
    if (a < 0 || b < 0) continue;  // a flex
    x.contact_keys[n] = (static_cast<int64_t>(std::min(a, b)) << 32) | std::max(a, b);
    x.contact_dist[n++] = d->contact[i].dist;
  }
  // Sorted by key, then distance: the first of a key's entries has its least distance.
  std::vector<int64_t> order(static_cast<size_t>(n));
  for (int64_t k = 0; k < n; ++k) order[k] = k;
  std::sort(order.begin(), order.end(), [&x](int64_t p, int64_t q) {
    return x.contact_keys[p] < x.contact_keys[q] ||
           (x.contact_keys[p] == x.contact_keys[q] && x.contact_dist[p] < x.contact_dist[q]);
  });
  std::vector<int64_t> keys(static_cast<size_t>(n));
  std::vector<double> dist(static_cast<size_t>(n));
  for (int64_t k = 0; k < n; ++k)
    keys[k] = x.contact_keys[order[k]], dist[k] = x.contact_dist[order[k]];
  std::copy(keys.begin(), keys.end(), x.contact_keys);
  std::copy(dist.begin(), dist.end(), x.contact_dist);
  x.contact_count = n;
}

// Whether MuJoCo's contacts of this state hold geoms g1 and g2 within dist (the pair's contact
// distance). Then every direction's gap is at most 0, so no look can raise tau, and a query
// would only come back touching after a GJK (and an EPA when they overlap). A list from another
// state costs tightness, never safety: the pair keeps its sphere tau, a lower bound by itself.
bool InContact(dua_exact& x, int64_t g1, int64_t g2, double dist) {
  if (x.contact_count == -1) IndexContacts(x);
  if (x.contact_count >= 0) {
    const int64_t key = (std::min(g1, g2) << 32) | std::max(g1, g2);
    int64_t* end = x.contact_keys + x.contact_count;
    int64_t* it = std::lower_bound(x.contact_keys, end, key);
    return it != end && *it == key && x.contact_dist[it - x.contact_keys] <= dist;
  }
  const mjData* d = static_cast<const mjData*>(x.data);
  for (int i = 0; i < d->ncon; ++i) {
    const mjContact& c = d->contact[i];
    const bool same = (c.geom[0] == g1 && c.geom[1] == g2) || (c.geom[0] == g2 && c.geom[1] == g1);
    if (same && c.dist <= dist) return true;
  }
  return false;
}

}  // namespace

// The hull vertex side's last climb reached (0: the first geom, 1: the second), at its geom's
// pose in f (false: the geom has no hull graph, or no climb yet). A point of the geom's hull.
static bool TopPoint(const double* xrec, int side, const dua_exact& x, const dua_frame& f,
                     double out[3]) {
  const double top = xrec[side == 0 ? kXHull1 : kXHull2];
  if (!(top >= 0.0)) return false;
  const int64_t g = static_cast<int64_t>(xrec[side == 0 ? kXG1 : kXG2]);
  const dua_hull_entry& v = x.climb[x.climb_at[x.hull_at[g] + static_cast<int64_t>(top)]];
  const double local[3] = {v.x, v.y, v.z};
  GeomPoint(g, f, local, out);
  return true;
}

// Bounds every direction's separation at `below`: for every unit u, d_u + u.r below is at most
// u.(b - a + r below) for any points a of the first geom and b of the second (5.4), so at most
// min(u.w1, u.w2) for two such differences, and at most the length of any point of the segment
// from w1 to w2 (docs/theory.md, section 5, "Queries that cannot clear"). w1: the witness points
// of the latest query carried with their geoms (w); w2: the hull vertices the last climbs
// reached, when both geoms are hulls (the kept direction's supports). Writes the segment's point
// nearest the origin to q (w1 alone without w2) and the points' coordinates' magnitude to scale;
// returns 0 without a query yet, 1 with w1 alone, 2 with the segment.
int Nearest(const double* w, double r0, double r1, double r2, const double* xrec,
            const dua_exact& x, const dua_frame& f, double below, double q[3], double* scale) {
  if (!(below > 0.0) || !std::isfinite(below) || std::isnan(w[0])) return 0;
  const double r[3] = {r0 * below, r1 * below, r2 * below};
  double a[3], b[3];
  GeomPoint(static_cast<int64_t>(xrec[kXG1]), f, w, a);
  GeomPoint(static_cast<int64_t>(xrec[kXG2]), f, w + 3, b);
  *scale = 0.0;
  for (int j = 0; j < 3; ++j) {
    q[j] = b[j] - a[j] + r[j];
    *scale += std::fabs(a[j]) + std::fabs(b[j]);
  }
  if (!TopPoint(xrec, 0, x, f, a) || !TopPoint(xrec, 1, x, f, b)) return 1;
  double w2[3], dw[3], dd = 0.0, along = 0.0;
  for (int j = 0; j < 3; ++j) {
    w2[j] = b[j] - a[j] + r[j];
    dw[j] = q[j] - w2[j];
    dd += dw[j] * dw[j];
    along -= w2[j] * dw[j];
    *scale += std::fabs(a[j]) + std::fabs(b[j]);
  }
  // Any weight in [0, 1] gives a bound; the clamped least-squares one the tightest.
  const double lambda = dd > 0.0 ? std::min(1.0, std::max(0.0, along / dd)) : 1.0;
  for (int j = 0; j < 3; ++j) q[j] = w2[j] + lambda * dw[j];
  return 2;
}

namespace {

// Whether no direction can raise the pair's tau to `below`, from Nearest's point q: the right
// side of (5.3) at `below` is at most |q| - m - (spin + delta) below - A below^2 / 2 (r the
// origins' relative velocity); when that is negative, every direction's bound, concave in t and
// positive at 0, reaches m before `below` (docs/theory.md, section 5, "Queries that cannot
// clear").
bool NoDirectionClears(const double q[3], double scale, double r0, double r1, double r2,
                       double spin, const double* pair, const double* xrec, double below) {
  const double speed = std::sqrt(r0 * r0 + r1 * r1 + r2 * r2) + spin;
  // AxisTau's own allowances (its gap lowered, its delta raised), and margins far above the
  // rounding of either side: what they keep is a tightness, not a safety.
  const double most =
      std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]) * (1.0 + 1e-12) + kGapSlack * scale;
  const double delta = pair[kPairDelta] + kVelSlack * speed;
  const double least =
      xrec[kXDist] + (spin + delta) * below + 0.5 * pair[kPairAccel] * below * below;
  return most < least * (1.0 - 1e-12);
}

}  // namespace

// v scaled to unit length (false: v too short next to the geoms' radii for a direction).
bool Unit(double v[3], double radii) {
  const double length = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  if (!(length > 1e-9 * radii)) return false;
  for (int j = 0; j < 3; ++j) v[j] /= length;
  return true;
}

// The unit direction from the first witness point to the second, each carried with its geom to
// its pose in f (false: no query made yet, or the points too close for a direction).
bool CarriedDirection(const double* w, int64_t g1, int64_t g2, const dua_exact& x,
                      const dua_frame& f, double out[3]) {
  if (std::isnan(w[0])) return false;
  double a[3], b[3];
  GeomPoint(g1, f, w, a);
  GeomPoint(g2, f, w + 3, b);
  for (int j = 0; j < 3; ++j) out[j] = b[j] - a[j];
  return Unit(out, x.geoms[g1 * kGxNcol + kGxRadius] + x.geoms[g2 * kGxNcol + kGxRadius]);
}

// Stores the witness points fromto (world) in w, each in its geom's frame at f.
void KeepWitness(const double fromto[6], int64_t g1, int64_t g2, const dua_frame& f, double* w) {
  for (int side = 0; side < 2; ++side) {
    const int64_t g = side == 0 ? g1 : g2;
    const double* m = f.mat + 9 * g;
    const double* p = f.pos + 3 * g;
    const double d0 = fromto[3 * side] - p[0], d1 = fromto[3 * side + 1] - p[1],
                 d2 = fromto[3 * side + 2] - p[2];
    for (int j = 0; j < 3; ++j) w[3 * side + j] = m[j] * d0 + m[3 + j] * d1 + m[6 + j] * d2;
  }
}

namespace {

// ExactTau past the kept direction (best: what it and the coarse tau gave, below query_below,
// or no direction kept yet): the carried and the segment's directions, then MuJoCo's query.
// Out of line: most looks end at the kept direction (docs/benchmarks.md, "The exact level"),
// and the step runs cold, so the lines of this path are fetched only by the looks that take it.
DUA_APART double ExactTauFurther(const double* pair, double* xrec, double* witness, double best,
                                 dua_exact& x, const dua_frame& f, double settled_below, int mode,
                                 double r0, double r1, double r2, double spin) {
  const int64_t g1 = static_cast<int64_t>(xrec[kXG1]);
  const int64_t g2 = static_cast<int64_t>(xrec[kXG2]);
  const double n0 = xrec[kXN], n1 = xrec[kXN + 1], n2 = xrec[kXN + 2];
  if (n0 != 0.0 || n1 != 0.0 || n2 != 0.0) {
    // The pair alarms whatever direction MuJoCo would give: not asked (most of a query's cost on
    // meshes of thousands of hull vertices is GJK's climb from a cold start).
    double q[3], scale;
    const int near = Nearest(witness, r0, r1, r2, xrec, x, f, settled_below, q, &scale);
    if (near > 0 && NoDirectionClears(q, scale, r0, r1, r2, spin, pair, xrec, settled_below)) {
      return best;
    }
    // The latest query's witness points moved with their geoms: the direction between them now
    // follows the geoms' turning, which the kept (world) direction does not. Any direction is a
    // lower bound (5.1): where it clears the alarm it is kept, and MuJoCo is not asked.
    double m[3];
    if (CarriedDirection(witness, g1, g2, x, f, m)) {
      best = std::max(best, AxisTau(m[0], m[1], m[2], mode, r0, r1, r2, spin, pair, xrec, x, f));
      if (best >= x.query_below) {
        xrec[kXN] = m[0], xrec[kXN + 1] = m[1], xrec[kXN + 2] = m[2];
        return best;
      }
    }
    // Between two hulls, the direction of the segment's nearest point: the one its bound allows
    // the most separation along (a step of GJK from the two point pairs), tried likewise.
    if (near == 2 &&
        Unit(q, x.geoms[g1 * kGxNcol + kGxRadius] + x.geoms[g2 * kGxNcol + kGxRadius])) {
      best = std::max(best, AxisTau(q[0], q[1], q[2], mode, r0, r1, r2, spin, pair, xrec, x, f));
      if (best >= x.query_below) {
        xrec[kXN] = q[0], xrec[kXN + 1] = q[1], xrec[kXN + 2] = q[2];
        return best;
      }
    }
  }
  const double* p1 = f.pos + 3 * g1;
  const double* p2 = f.pos + 3 * g2;
  const double c0 = p2[0] - p1[0], c1 = p2[1] - p1[1], c2 = p2[2] - p1[2];
  // Both origins lie inside their geoms, so the distance is at most theirs: a witness.
  const double reach = std::sqrt(c0 * c0 + c1 * c1 + c2 * c2) + xrec[kXDist] + 1.0;
  mjtNum fromto[6];
  ++x.queries;
  const mjData* d = static_cast<const mjData*>(x.data);
  const double dist = mj_geomDistance(static_cast<const mjModel*>(x.model), const_cast<mjData*>(d),
                                      static_cast<int>(g1), static_cast<int>(g2), reach, fromto);
  double n[3];
  if (!(dist > xrec[kXDist]) || !WitnessDirection(fromto, x, g1, g2, xrec, n)) {
    return best;  // in contact, or no witness
  }
  KeepWitness(fromto, g1, g2, f, witness);
  return std::max(best, AxisTau(n[0], n[1], n[2], mode, r0, r1, r2, spin, pair, xrec, x, f));
}

// One pair's max(coarse, exact). Any unit direction gives a lower bound: the one that served
// last time is tried first, and MuJoCo is asked for a new one only while the pair is still
// urgent along it (below query_below). A pair MuJoCo has in contact is not looked at.
double ExactTau(const double* pair, double* xrec, double* witness, double coarse, dua_exact& x,
                const dua_frame& f, double settled_below) {
  const int mode = static_cast<int>(xrec[kXMode]);
  if (mode == kModeNone) return coarse;
  const int64_t g1 = static_cast<int64_t>(xrec[kXG1]);
  const int64_t g2 = static_cast<int64_t>(xrec[kXG2]);
  if (InContact(x, g1, g2, xrec[kXDist])) return coarse;
  double sa[6], sb[6];
  RigidPoint(g1, x.geoms, kGxNcol, f, sa);
  double spin = Spin(g1, x.geoms, f);
  // Relative velocity of the origins, second minus first.
  double r0 = -sa[3], r1 = -sa[4], r2 = -sa[5];
  if (mode == kModeGeoms) {
    RigidPoint(g2, x.geoms, kGxNcol, f, sb);
    spin += Spin(g2, x.geoms, f);
    r0 += sb[3], r1 += sb[4], r2 += sb[5];
  }
  if (mode == kModePlane) {
    // From the geom towards the plane: against the plane's outward normal (its z axis).
    const double* m = f.mat + 9 * g2;
    const double t = AxisTau(-m[2], -m[5], -m[8], mode, r0, r1, r2, spin, pair, xrec, x, f);
    return std::max(coarse, t);
  }
  double best = coarse;
  const double n0 = xrec[kXN], n1 = xrec[kXN + 1], n2 = xrec[kXN + 2];
  if (n0 != 0.0 || n1 != 0.0 || n2 != 0.0) {
    best = std::max(best, AxisTau(n0, n1, n2, mode, r0, r1, r2, spin, pair, xrec, x, f));
    if (best >= x.query_below) return best;
  }
  return ExactTauFurther(pair, xrec, witness, best, x, f, settled_below, mode, r0, r1, r2, spin);
}

// Raise out[k] of held pairs ids[k] to max(out[k], exact) where it is below exact.below,
// except where skip[k] (a plan's verdicts; skip null: none).
DUA_SECTION void ExactPass(dua_step_args& a, const int64_t* ids, int64_t count, double* out,
                           const uint8_t* skip = nullptr) {
  if (!a.exact.on) return;
  a.exact.contact_count = -1;  // the contacts are indexed at the first look that needs them
  // Below this a verdict alarms, and the deadline and select-all schedules treat every alarming
  // verdict alike (its tau sets neither the wait nor the order): a query that cannot lift the
  // pair above it is not made. The rank schedule orders by tau, so it asks as before.
  const double settled_below =
      a.schedule.kind == kRank ? -kInf : std::min(a.exact.query_below, a.schedule.horizon[0]);
  for (int64_t k = 0; k < count; ++k) {
    if (out[k] < a.exact.below && (skip == nullptr || !skip[k])) {
      const int64_t p = ids[k];
      // A height field's terrain: its own kernel (terrain.cc), never mj_geomDistance.
      if (static_cast<int>(a.exact.records[p * kXNcol + kXMode]) == kModeTerrain) {
        out[k] = std::max(out[k], TerrainExactTau(a, p));
        continue;
      }
      out[k] = ExactTau(a.pairs + p * kPairNcol, a.exact.records + p * kXNcol,
                        a.exact.witness + 6 * p, out[k], a.exact, a.frame, settled_below);
    }
  }
}

// ------------------------------------------------------------------------------- tau of pairs

// The states a batch of pairs is evaluated on: each sphere's centre and velocity, and a
// half-space pair's plane (its unit normal and offset), read from MjData (FramePoints) or given
// as arrays (FreePoints: spheres not on MuJoCo bodies, the paper's setting).
struct FramePoints {
  static constexpr bool kRows = true;  // Row: each sphere's state in place, and whether tame
  dua_step_args& a;
  void Point(int64_t i, double* out) const { PointOf(a, i, out); }
  const double* Row(int64_t i, bool* tame) const { return PointRow(a, i, tame); }
  // The plane geom of the pair (its z axis is the outward normal, through its origin).
  void Plane(const double* rec, double* out) const {
    const int64_t g = static_cast<int64_t>(rec[kPairOther]);
    const double* m = a.frame.mat + 9 * g;
    const double* p = a.frame.pos + 3 * g;
    out[0] = m[2], out[1] = m[5], out[2] = m[8];
    out[3] = out[0] * p[0] + out[1] * p[1] + out[2] * p[2];
  }
};

struct FreePoints {
  static constexpr bool kRows = false;
  const double* centers;     // (nsphere, 3)
  const double* velocities;  // (nsphere, 3)
  const double* planes;      // (nplane, 4): normal, offset
  void Point(int64_t i, double* out) const {
    out[0] = centers[3 * i], out[1] = centers[3 * i + 1], out[2] = centers[3 * i + 2];
    out[3] = velocities[3 * i], out[4] = velocities[3 * i + 1], out[5] = velocities[3 * i + 2];
  }
  void Plane(const double* rec, double* out) const {
    const double* q = planes + 4 * static_cast<int64_t>(rec[kPairSecond]);
    out[0] = q[0], out[1] = q[1], out[2] = q[2], out[3] = q[3];
  }
};

// tau of pairs ids[0:count] (records `pairs`) into out: each pair's state in 12 numbers (sphere
// i's centre and velocity, then sphere j's, or the plane's normal and offset, zeros for a static
// shape), then its tau; sphere pairs four at a time, as each fourth one is gathered. Returns -1,
// or the first pair (in ids's order) whose state is not finite (out is then partly written).
// Where skip[k] (skip null: nowhere) the state is read and checked as for any pair but no tau is
// computed and out[k] is not written: a plan's verdict replaces it (PlanCovered).
template <class Points>
DUA_SECTION int64_t TauRows(const double* pairs, const double* shapes, const Points& points,
                            const int64_t* ids, int64_t count, double* out,
                            const uint8_t* skip = nullptr) {
  // Up to four sphere pairs' rows as TauSpeedFour reads them (relative state, then bounds), and
  // where each goes in out (FreePoints: their states are copies): passed to the kernel straight
  // from here, not through a buffer of every row.
  double quad[kLanes][10];
  int64_t at[kLanes];
  int nq = 0;
  auto flush = [&] {
    for (int k = nq; k < kLanes; ++k) std::copy(quad[nq - 1], quad[nq - 1] + 10, quad[k]);
    double tau[kLanes];
    TauSpeedFour(quad, nq, tau, 1);
    for (int k = 0; k < nq; ++k) out[at[k]] = tau[k];
    nq = 0;
  };
  // Read in place (FramePoints): up to four sphere pairs' two rows and records, and where each
  // goes in out; the kernel takes the relative state's differences itself, in its lanes (the
  // same subtractions), so no row of ten is written here and read back there.
  const double* pi[kLanes];
  const double* pj[kLanes];
  const double* pr[kLanes];
  int64_t pat[kLanes];
  int np = 0;
  auto flush_pairs = [&] {
    for (int k = np; k < kLanes; ++k) {
      pi[k] = pi[np - 1], pj[k] = pj[np - 1], pr[k] = pr[np - 1], pat[k] = pat[np - 1];
    }
    double ts[kLanes];
    int speed_on;
    const int left = TauSpeedFourPairs(pi, pj, pr, np, out, pat, ts, &speed_on);
    if (left != 0) TauSpeedFourPairsLeft(pi, pj, pr, left, out, pat, ts, speed_on);
    np = 0;
  };
  for (int64_t k = 0; k < count; ++k) {
    const double* rec = pairs + ids[k] * kPairNcol;
    const int kind = static_cast<int>(rec[kPairKind]);
    if constexpr (Points::kRows) {
      if (kind == kKindSphere) {
        // The two spheres' rows read in place, not copied into a state of 12 first; the sum
        // below tested only where a sphere is not tame (both tame: it is finite).
        bool tame_i, tame_j;
        const double* si = points.Row(static_cast<int64_t>(rec[kPairFirst]), &tame_i);
        const double* sj = points.Row(static_cast<int64_t>(rec[kPairSecond]), &tame_j);
        if (!(tame_i && tame_j)) {
          double total = 0.0;
          for (int j = 0; j < 6; ++j) total += si[j];
          for (int j = 0; j < 6; ++j) total += sj[j];
          if (!std::isfinite(total)) return k;
        }
        if (skip != nullptr && skip[k]) continue;
        pi[np] = si, pj[np] = sj, pr[np] = rec;
        pat[np++] = k;
        if (np == kLanes) flush_pairs();
        continue;
      }
    }
    double s[12];
    points.Point(static_cast<int64_t>(rec[kPairFirst]), s);
    if (kind == kKindHalfspace) {
      points.Plane(rec, s + 6);
      s[10] = 0.0, s[11] = 0.0;
    } else if (kind == kKindShape) {
      s[6] = s[7] = s[8] = s[9] = s[10] = s[11] = 0.0;
    } else {
      points.Point(static_cast<int64_t>(rec[kPairSecond]), s + 6);
    }
    double total = 0.0;
    for (int j = 0; j < 12; ++j) total += s[j];
    if (!std::isfinite(total)) return k;
    if (skip != nullptr && skip[k]) continue;
    if (kind == kKindHalfspace) {
      const double along = s[6] * s[0] + s[7] * s[1] + s[8] * s[2];
      const double gap = along - s[9] - rec[kPairEps];
      const double vn = s[6] * s[3] + s[7] * s[4] + s[8] * s[5];
      const double low = gap - kGapSlack * (std::fabs(along) + std::fabs(s[9]) + rec[kPairEps]);
      const double nv = std::sqrt(s[3] * s[3] + s[4] * s[4] + s[5] * s[5]);
      out[k] = WithGapSpeed(TauHalfspace(gap, vn, rec[kPairAccel], rec[kPairDelta]), low, nv,
                            rec[kPairSpeed]);
    } else if (kind == kKindShape) {
      out[k] = TauStatic(s[0], s[1], s[2], s[3], s[4], s[5],
                         shapes + static_cast<int64_t>(rec[kPairOther]) * kShapeNcol, rec[kPairEps],
                         rec[kPairAccel], rec[kPairDelta], rec[kPairSpeed]);
    } else {
      double* row = quad[nq];
      for (int j = 0; j < 6; ++j) row[j] = s[6 + j] - s[j];
      row[6] = rec[kPairEps], row[7] = rec[kPairAccel], row[8] = rec[kPairDelta];
      row[9] = rec[kPairSpeed];
      at[nq++] = k;
      if (nq == kLanes) flush();
    }
  }
  if (nq > 0) flush();
  if (np > 0) flush_pairs();
  return -1;
}

// TauRows of held pairs on a's points (free spheres) or frame, then the exact level.
int64_t TauOf(dua_step_args& a, const int64_t* ids, int64_t count, double* out) {
  // A sphere is in several of the batch's pairs: its state is read from MjData once. A new
  // epoch each batch, since MjData may have moved on between two (PointOf).
  ++a.epoch;
  // The pairs a plan's verdict covers whatever its walks find: their states are checked, their
  // bounds' taus not computed (PlanPass writes theirs; until then out[k] is not read).
  const uint8_t* covered = nullptr;
  if (a.plan.impl != nullptr) {
    PlanCovered(a, ids, count, a.plan.planned);
    covered = a.plan.planned;
  }
  // Free spheres have no planes (nothing points at them) and no frame to read.
  const int64_t bad =
      a.points.centers
          ? TauRows(a.pairs, a.shapes, FreePoints{a.points.centers, a.points.velocities, nullptr},
                    ids, count, out, covered)
          : TauRows(a.pairs, a.shapes, FramePoints{a}, ids, count, out, covered);
  if (bad >= 0) return bad;
  // A new verdict for each: the bounds on both sides unless the plan covers it (PlanPass).
  if (a.plan.basis != nullptr) {
    for (int64_t k = 0; k < count; ++k) {
      a.plan.basis_prev[ids[k]] = a.plan.basis[ids[k]];
      a.plan.basis[ids[k]] = 0;
    }
  }
  if (a.plan.impl != nullptr) {
    // A plan's verdict replaces the motion bounds' (its hypothesis is the deviation, not the
    // bounds): the pairs it covers skip the exact level on the present state.
    PlanPass(a, ids, count, out);
    ExactPass(a, ids, count, out, a.plan.planned);
  } else {
    ExactPass(a, ids, count, out);
  }
  // A tau that is not a number (from finite tables so large that the arithmetic overflows, a
  // shape's rotation entry of 1e308) alarms now, never passes (docs/hardening.md). With
  // period > 1 the other levels' taus go on the predictor's grid as the plan's did (GridFloor).
  if (a.period <= 1) {
    // Every tau written back, a NaN as 0 (a loop without branches, which the compiler
    // vectorises: most taus are numbers, and each is written as it was).
    for (int64_t k = 0; k < count; ++k) {
      const double t = out[k];
      out[k] = std::isnan(t) ? 0.0 : t;
    }
    return -1;
  }
  const uint8_t* planned = a.plan.impl != nullptr ? a.plan.planned : nullptr;
  for (int64_t k = 0; k < count; ++k) {
    if (std::isnan(out[k])) {
      out[k] = 0.0;
    } else if (planned == nullptr || !planned[k]) {
      out[k] = GridFloor(out[k], a.timestep, a.period);
    }
  }
  return -1;
}

}  // namespace
}  // namespace dua

extern "C" {

void dua_rigid_point(int64_t i, const double* spheres, const dua_frame* f, double* out) {
  dua::RigidPoint(i, spheres, dua::kSphereNcol, *f, out);
}

void dua_point(const dua_step_args* a, int64_t i, double* out) {
  if (a->points.centers) {
    dua::FreePoints{a->points.centers, a->points.velocities, nullptr}.Point(i, out);
  } else {
    dua::RigidPoint(i, a->spheres, dua::kSphereNcol, a->frame, out);
  }
}

int64_t dua_tau_free(const double* pairs, const double* shapes, const double* centers,
                     const double* velocities, const double* planes, const int64_t* ids,
                     int64_t count, double* out) {
  return dua::TauRows(pairs, shapes, dua::FreePoints{centers, velocities, planes}, ids, count, out);
}

int64_t dua_index_by_row(const int64_t* row_of_geom, const int64_t* geom1, const int64_t* geom2,
                         int64_t n, int64_t nrow, int64_t* start, int64_t* members) {
  std::fill(start, start + nrow + 1, int64_t{0});
  for (const int64_t* geoms : {geom1, geom2}) {
    for (int64_t k = 0; k < n; ++k) {
      const int64_t r = geoms[k] >= 0 ? row_of_geom[geoms[k]] : -1;
      if (r >= 0) ++start[r + 1];
    }
  }
  for (int64_t r = 0; r < nrow; ++r) start[r + 1] += start[r];
  for (const int64_t* geoms : {geom1, geom2}) {
    for (int64_t k = 0; k < n; ++k) {
      const int64_t r = geoms[k] >= 0 ? row_of_geom[geoms[k]] : -1;
      // start[r] is the next free place of row r; shifted back below.
      if (r >= 0) members[start[r]++] = k;
    }
  }
  for (int64_t r = nrow; r > 0; --r) start[r] = start[r - 1];
  start[0] = 0;
  return start[nrow];
}

int64_t dua_check_bodies(dua_step_args* a, int64_t lanes) {
  return a->events.nbody ? dua::CheckBodies(a->events, a->frame, lanes != 0) : 0;
}

void dua_reset_events(dua_step_args* a) {
  const dua_events& ev = a->events;
  // The padding of the last group of four too, as its last body (CheckFour).
  const int64_t padded = dua::EventStateLen(ev.nbody) / dua::kSNcol;
  for (int64_t i = 0; i < padded; ++i) {
    const double* rec = ev.rec + std::min(i, ev.nbody - 1) * dua::kBNcol;
    for (int j = 0; j < dua::kSIndex - dua::kSWritten; ++j) {
      *dua::StateAt(ev, i, dua::kSWritten + j) = rec[dua::kBCenter + j];
    }
    // RowSources' indices, as int32 (MjData's arrays index with int), in the body's own lane.
    const int32_t index[4] = {3 * static_cast<int32_t>(rec[dua::kBFrame]),
                              6 * static_cast<int32_t>(rec[dua::kBBody]),
                              3 * static_cast<int32_t>(rec[dua::kBRoot]), 0};
    __builtin_memcpy(dua::StateAt(ev, i, dua::kSIndex), index, 2 * sizeof(int32_t));
    __builtin_memcpy(dua::StateAt(ev, i, dua::kSIndex + 1), index + 2, 2 * sizeof(int32_t));
  }
  ev.meta[dua::kMNprev] = 0;
  ev.meta[dua::kMTotal] = 0;
  if (ev.nbody) dua::CheckBodies(ev, a->frame);
  ev.meta[dua::kMTotal] = 0;
}

void dua_exact_pass(dua_step_args* a, const int64_t* ids, int64_t count, double* tau) {
  dua::ExactPass(*a, ids, count, tau);
}

int64_t dua_evaluate(dua_step_args* a, const int64_t* ids, int64_t count, double* out) {
  const int64_t bad = dua::TauOf(*a, ids, count, out);
  return bad >= 0 ? ids[bad] : -1;
}

DUA_HOT int64_t dua_step(dua_step_args* a, int64_t n, int64_t start) {
  dua_schedule* st = &a->schedule;
  // The violation check, then the selection: the flagged bodies' pairs go straight to it
  // (SelectMadeDue), not through step n's list.
  const dua_events& ev = a->events;
  const int64_t flagged = ev.nbody ? dua::CheckBodies(ev, a->frame) : 0;
  // A flagged body's pair that cannot reach contact within the wait (3) gives it is settled by a
  // bound from the norms of its state (docs/theory.md, section 6), not evaluated: on bodies read
  // from MjData, judged by their motion bounds (a plan's verdicts rest on other hypotheses).
  // The bound reads the spheres in this step's epoch, which TauOf then starts.
  ++a->epoch;
  const bool bounds_only =
      a->points.centers == nullptr && a->plan.impl == nullptr && a->plan.basis == nullptr;
  const bool settles = flagged > 0 && bounds_only;
  // The screen clears pairs by the bounds too, on the frame, a step at a time (period 1: a
  // cleared verdict is not on the predictor's grid); without it this step, its pairs are all
  // selected (docs/theory.md, section 3, "The screen").
  const bool screens = st->screen != nullptr && a->screen != 0 && bounds_only && a->period <= 1;
  const int64_t count = dua::SelectMadeDue(st, ev.flagged, flagged, ev.start, ev.members, n,
                                           settles ? a : nullptr, screens ? a : nullptr);
  const int64_t* w_ids = st->work + 1 * st->width;
  a->count = count;
  --a->epoch;  // TauOf's ++ returns to it: the rows read above are this batch's
  const int64_t bad = dua::TauOf(*a, w_ids, count, st->w_tau);
  if (bad >= 0) {
    a->bad = w_ids[bad];
    a->deferred = 0;
    dua_restore(st, n, count);
    return -1 - a->bad;
  }
  const int64_t nalarm = dua_reinsert(st, n, count);
  if (screens) dua::ScreenEnter(st, n, count, *a);
  const int64_t* alarms = st->work + 2 * st->width;
  const int64_t* fresh = st->work + 3 * st->width;
  for (int64_t k = 0; k < nalarm; ++k) {
    const int64_t p = alarms[k];
    a->log_pairs[start + k] = a->ids[p];
    a->log_tau[start + k] = st->last_tau[p];
    a->log_new[start + k] = fresh[k] != 0;
  }
  a->bad = -1;
  a->deferred = st->params[6];
  return nalarm;
}

}  // extern "C"

extern "C" {

int64_t dua_exceeds12(double a0, double a1, double a2, double x0, double x1, double x2, double y0,
                      double y1, double y2, double z0, double z1, double z2, double bound) {
  return dua::Exceeds12<double>(a0, a1, a2, x0, x1, x2, y0, y1, y2, z0, z1, z2, bound) ? 1 : 0;
}

}  // extern "C"
