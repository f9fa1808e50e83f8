// Lanes: four doubles in lockstep, and the operations the kernels use written once for a double
// and for four (the kernels are templates over the number type). A lane computes the IEEE
// operations the scalar code computes, in the same order (no contraction: -ffp-contract=off), so
// it gets the same bits (a NaN's sign aside: the compiler may swap the operands of + and *);
// branches become masks. Functions taking lanes are inlined into one caller compiled for AVX2
// where the CPU has it (target_clones): a call between an AVX2 clone and a function compiled
// without AVX passes the vectors differently, so the clones exist only in optimised builds,
// where flatten inlines every call, and the helpers here are always inlined.
#ifndef DUA_MUJOCO_LANES_H_
#define DUA_MUJOCO_LANES_H_

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

// target_clones needs the loader's ifunc support: glibc's (not musl's or MinGW's).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__OPTIMIZE__) && \
    defined(__GLIBC__)
#define DUA_LANES_CLONES __attribute__((target_clones("avx2", "default"), flatten))
#else
#define DUA_LANES_CLONES
#endif
#define DUA_INLINE inline __attribute__((always_inline))
// A section of the step the profiler splits the plugin's cost by (benchmarks/plugin_profile.py):
// its own symbol in a profiling build (CMake's DUA_PROFILE=ON), so that its inclusive count is
// read from the profile; inlined as the compiler sees fit in every other build.
#ifdef DUA_PROFILE
#define DUA_SECTION __attribute__((noinline))
#else
#define DUA_SECTION
#endif
// A branch of the step's glue that most steps do not take (a plan's, a buffer's growth, a
// failed step), kept out of line so that the taken path reads fewer instruction lines: the
// step runs cold (MuJoCo's step evicts its code between two calls), and a line fetched for
// one instruction costs as much as one fetched for sixteen (docs/benchmarks.md, issue 42).
// DUA_COLD for the rarest (a cold section of its own), DUA_APART for a path taken at every
// step of some runs (a plan's), which stays in the hot text.
#define DUA_COLD __attribute__((cold, noinline))
#define DUA_APART __attribute__((noinline))
// The step's glue (what every step runs once: Bind, Step, the log, the watch, the schedule's
// entry points), placed together (.text.hot) so that its functions share lines and pages.
#define DUA_HOT __attribute__((hot))

namespace dua {

constexpr int kLanes = 4;
using Lanes = double __attribute__((vector_size(8 * kLanes)));
// What comparing lanes gives: 64-bit integer lanes (long for GCC, long long for clang, which
// are different types to overloads).
using LaneMask = decltype(Lanes{} < Lanes{});

template <class T>
using MaskOf = decltype(T{} < T{});

DUA_INLINE Lanes Splat(double v) { return Lanes{v, v, v, v}; }
// (lane k of) p[k][off]: four rows read at once (lanes past a batch's rows read the caller's
// pointers, a row already in it).
DUA_INLINE Lanes Gather(const double* const* p, int64_t off) {
  return Lanes{p[0][off], p[1][off], p[2][off], p[3][off]};
}

inline double Select(bool m, double a, double b) { return m ? a : b; }
DUA_INLINE Lanes Select(LaneMask m, Lanes a, Lanes b) { return m ? a : b; }
// As std::max and std::min order their operands (which one a NaN gives back).
inline double Max(double a, double b) { return std::max(a, b); }
DUA_INLINE Lanes Max(Lanes a, Lanes b) { return a < b ? b : a; }
inline double Min(double a, double b) { return std::min(a, b); }
DUA_INLINE Lanes Min(Lanes a, Lanes b) { return b < a ? b : a; }
inline double Sqrt(double a) { return std::sqrt(a); }
DUA_INLINE Lanes Sqrt(Lanes a) {
  Lanes r;
  for (int k = 0; k < kLanes; ++k) r[k] = std::sqrt(a[k]);
  return r;
}
inline double Abs(double a) { return std::fabs(a); }
DUA_INLINE Lanes Abs(Lanes a) {
  // The sign bit cleared, as fabs does (one vector and, not a call per lane).
  return (Lanes)((LaneMask)a & ~(LaneMask)Splat(-0.0));
}
inline bool And(bool a, bool b) { return a && b; }
DUA_INLINE LaneMask And(LaneMask a, LaneMask b) { return a & b; }
inline bool Or(bool a, bool b) { return a || b; }
DUA_INLINE LaneMask Or(LaneMask a, LaneMask b) { return a | b; }
inline bool Not(bool a) { return !a; }
DUA_INLINE LaneMask Not(LaneMask a) { return ~a; }
inline bool AndNot(bool a, bool b) { return a && !b; }
DUA_INLINE LaneMask AndNot(LaneMask a, LaneMask b) { return a & ~b; }
// One lane at a time (slow paths): a double or a bool is one lane.
template <class T>
constexpr int LaneCount() {
  return sizeof(T) / sizeof(double);
}
inline double LaneOf(double v, int) { return v; }
DUA_INLINE double LaneOf(Lanes v, int k) { return v[k]; }
inline bool LaneOf(bool m, int) { return m; }
DUA_INLINE bool LaneOf(LaneMask m, int k) { return m[k] != 0; }
inline void SetLane(bool* m, int, bool v) { *m = v; }
DUA_INLINE void SetLane(LaneMask* m, int k, bool v) { (*m)[k] = v ? -1 : 0; }
// Bit k set where lane k is (a mask's lanes are all ones or all zeros): one vector and, one
// fold and an or, not a test and a shift per lane.
inline int Bits(bool m) { return m ? 1 : 0; }
DUA_INLINE int Bits(LaneMask m) {
  const LaneMask w = m & LaneMask{1, 2, 4, 8};
  const LaneMask h = w | __builtin_shufflevector(w, w, 2, 3, 0, 1);
  return static_cast<int>(h[0] | h[1]);
}
// Four rows of four lanes (r[k], k < 4) as four columns (c[j]: lane k of it is lane j of r[k]).
DUA_INLINE void Transpose4(const Lanes* r, Lanes* c) {
  const Lanes lo01 = __builtin_shufflevector(r[0], r[1], 0, 4, 2, 6);
  const Lanes hi01 = __builtin_shufflevector(r[0], r[1], 1, 5, 3, 7);
  const Lanes lo23 = __builtin_shufflevector(r[2], r[3], 0, 4, 2, 6);
  const Lanes hi23 = __builtin_shufflevector(r[2], r[3], 1, 5, 3, 7);
  c[0] = __builtin_shufflevector(lo01, lo23, 0, 1, 4, 5);
  c[1] = __builtin_shufflevector(hi01, hi23, 0, 1, 4, 5);
  c[2] = __builtin_shufflevector(lo01, lo23, 2, 3, 6, 7);
  c[3] = __builtin_shufflevector(hi01, hi23, 2, 3, 6, 7);
}
// Four consecutive doubles as lanes (memcpy: p is aligned only as a double).
DUA_INLINE Lanes Load(const double* p) {
  Lanes v;
  std::memcpy(&v, p, sizeof(Lanes));
  return v;
}
// Lanes to four consecutive doubles.
DUA_INLINE void Store(double* p, Lanes v) { std::memcpy(p, &v, sizeof(Lanes)); }
inline bool Any(bool m) { return m; }
DUA_INLINE bool Any(LaneMask m) {
  // Folded in halves (two vector ors), not four extracts (the kernels' screens test it often).
  const LaneMask h = m | __builtin_shufflevector(m, m, 2, 3, 0, 1);
  return (h[0] | h[1]) != 0;
}

}  // namespace dua

#endif  // DUA_MUJOCO_LANES_H_
