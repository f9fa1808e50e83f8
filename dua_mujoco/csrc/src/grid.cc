// The hashed uniform grid behind candidate pairs of reachable balls: every pair i < j with
// |c_i - c_j|^2 <= ((reach_i + reach_j) + margin)^2 (1 + 2^-44), and no other; every buffer is the
// caller's. The runtime chooses a pruned predictor's pairs with it (pruned.cc).
//
// Motion model of sphere `i`: centre `c_i`, velocity `v_i`, radius `r_i`, a bound `A_i` on the norm
// of the centre's acceleration, an optional bound `delta_i` on the error of the measured velocity
// and an optional speed bound `V_i`. The reach (`dua_reaches`, reach.cc) is `reach_i = r_i +
// R_i(T)` with `R_i(T) = min(|v_i| T + delta_i T + A_i T^2 / 2, V_i T)`; the grid returns every
// pair `i < j` with `|c_i - c_j| <= reach_i + reach_j + margin` and no other.
//
// Guarantee: a pair that the grid leaves out cannot come within `r_i + r_j + margin` (centre
// distance) at any time in `[0, T]`, whatever its motion within the bounds. Proof: the true
// velocity `u_i(s)` satisfies `|u_i(0)| <= |v_i| + delta_i` and `|u_i(s) - u_i(0)| <= A_i s`, so
// `|x_i(t) - c_i| <= (|v_i| + delta_i) t + A_i t^2 / 2`; a speed bound gives `|x_i(t) - c_i| <= V_i
// t` as well, so `|x_i(t) - c_i| <= R_i(t) <= R_i(T)` since every term is non-decreasing in `t`. By
// the triangle inequality `|x_i(t) - x_j(t)| >= |c_i - c_j| - R_i(T) - R_j(T) > r_i + r_j + margin`
// for every left-out pair. Floating point: the test is evaluated as `d2 <= s * s * ROUNDING_SLACK`
// with `d2 = dx*dx + dy*dy + dz*dz` and `s = (reach_i + reach_j) + margin` in float64 (this exact
// expression is the contract; tests/reference_grid.py holds the grid to it). `ROUNDING_SLACK = 1 +
// 2**-44` exceeds the at most ~12 ulp of relative error of `d2` and `s * s`, so every pair meeting
// the test in exact arithmetic is returned; the extra pairs lie within a relative `3e-14` of the
// boundary.
//
// Algorithm: a uniform grid of cubic cells of edge `h >= 2 rcut + margin` (`rcut`: the largest
// reach in the grid), so every pair to report lies in the same or adjacent cells. Cells map to `2^b
// >= 2 N` buckets by wrapping the cell index onto a power-of-two torus (x fastest): a locality-
// preserving hash, so a row of three neighbour cells is a run of adjacent buckets, and sweeping the
// spheres in bucket order reads memory almost sequentially (a mixing hash made every probe a cache
// miss). If the grid has at most `2^b` cells with `h` up to twice the minimum, the smallest such
// `h` is used and nothing wraps. Spheres are counting-sorted by bucket (no comparison sort, no
// dict); each is tested against the rest of its bucket and the 13 cells after its own in (z, y, x)
// order, five runs of buckets, so each pair is tested once. The `k` spheres of largest reach may be
// held out of the grid and tested against every sphere instead (`k N` tests), `k` minimising a cost
// model `k N + 14 N (1 + occupancy)` with the occupancy estimated from the bounding box: one 2 m
// sphere among 1 cm ones then costs `N` tests instead of growing every cell 200 times (8e6 times
// the volume). Pairs are counted in a first pass and written in a second into arrays allocated at
// their exact size; two counting sorts (by `j`, then stably by `i`) order them. Time and memory are
// `O(N + K)`, plus `N k` tests for held-out spheres, and the tests in the grid are at most a
// constant times `N + K` unless the extent of the centres exceeds `2^31 h` (cells are then grown to
// keep indices exact: a cluster plus a far outlier). Cells are grown by `1 + 2^-16` beyond `2 rcut
// + margin` so that a pair at distance `<= s <=` the edge (after rounding, `< 1e-13` relative)
// never lands two cells apart: the rounding of `floor((x - lo) / h)` stays below `2^-21` cells with
// at most `2^31` cells an axis. Its work arrays take ~70 bytes per sphere plus 20 per pair
// (`_core.grid_plan` shows a plan).
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "dua/dua.h"

namespace dua {
namespace {

constexpr double kRoundingSlack = 1.0 + 1.0 / 17592186044416.0;  // 1 + 2^-44
constexpr double kMaxMagnitude = 1e150;
constexpr double kGridGrow = 1.0 + 1.0 / 65536.0;  // 1 + 2^-16
constexpr double kMaxCells = 2147483648.0;         // 2^31
constexpr double kGrowMax = 2.0;
constexpr int kGrowSteps = 6;
constexpr int64_t kMaxHeldOut = 256;
constexpr double kCellCost = 14.0;

struct Cell {
  int64_t x, y, z;
};

inline Cell CellOf(double x, double y, double z, const dua_grid_plan& g) {
  return {static_cast<int64_t>(std::floor((x - g.lo[0]) / g.h)),
          static_cast<int64_t>(std::floor((y - g.lo[1]) / g.h)),
          static_cast<int64_t>(std::floor((z - g.lo[2]) / g.h))};
}

// The cell index wrapped onto a 2^bx x 2^by x 2^bz torus, x fastest: a locality-preserving
// hash, so a row of neighbour cells is a run of adjacent buckets (a mixing hash made every
// probe a cache miss, ~3x slower at N = 1e5).
inline int64_t Bucket(int64_t kx, int64_t ky, int64_t kz, const dua_grid_plan& g) {
  return (kx & g.mask[0]) | ((ky & g.mask[1]) << g.shift_y) | ((kz & g.mask[2]) << g.shift_z);
}

inline bool Near(double xi, double yi, double zi, double ri, double xj, double yj, double zj,
                 double rj, double m) {
  const double dx = xi - xj, dy = yi - yj, dz = zi - zj;
  const double s = (ri + rj) + m;
  return dx * dx + dy * dy + dz * dz <= s * s * kRoundingSlack;
}

// >= extent / 2^31 keeps cell indices small enough for the rounding argument; a zero edge (all
// reaches and the margin zero, all centres equal) becomes 1 m, any size works.
inline double CellEdge(double rcut, double margin, double extent) {
  const double h = std::max((2.0 * rcut + margin) * kGridGrow, extent / kMaxCells);
  return h > 0.0 ? h : 1.0;
}

inline int BitLength(double cells) {
  auto v = static_cast<uint64_t>(cells);
  int bits = 0;
  while (v) ++bits, v >>= 1;
  return bits;
}

// Buckets [first, stop) holding cells kx - 1 .. kx + 1 of row (ny, nz), as one run (true), or
// false when a wrapped x axis puts the torus seam inside the row: the caller then looks the
// three cells up one by one. Clipped to the grid on an axis that does not wrap (no sphere lies
// outside, and a clipped index must not wrap onto another row); empty if the row is outside.
inline bool ScanRow(int64_t kx, int64_t ny, int64_t nz, const dua_grid_plan& g, int64_t* first,
                    int64_t* stop) {
  const int64_t mx = g.mask[0];
  *first = *stop = 0;
  if (!g.wrap[1] && (ny < 0 || ny > g.mask[1])) return true;
  if (!g.wrap[2] && nz > g.mask[2]) return true;
  if (!g.wrap[0]) {
    const int64_t xa = kx > 0 ? kx - 1 : kx, xb = kx < mx ? kx + 1 : kx;
    *first = Bucket(xa, ny, nz, g);
    *stop = *first + xb - xa + 1;
    return true;
  }
  *first = Bucket(kx - 1, ny, nz, g);
  *stop = *first + 3;
  return ((kx - 1) & mx) + 2 == ((kx + 1) & mx);
}

// Count (fill false) or write (fill true) the hits of one pair found from sphere i's side.
inline void Hit(int64_t i, int64_t j, bool fill, const dua_grid_work& w, int32_t* tmp) {
  const int64_t a = std::min(i, j), c = std::max(i, j);
  // Count: pairs per smaller id (cnt_a) and per larger id (cnt_b). Fill: cnt_b is each larger
  // id's cursor, the smaller id goes there (the first counting sort, by the larger id).
  if (fill) {
    tmp[w.cnt_b[c]++] = static_cast<int32_t>(a);
  } else {
    ++w.cnt_a[a];
    ++w.cnt_b[c];
  }
}

// Every candidate pair tested once. A grid sphere is tested against the later members of its own
// bucket and the 13 cells (dx, dy, dz) after (0, 0, 0) in (dz, dy, dx) order: five rows of
// adjacent buckets. No cell check: an entry of an aliased cell is >= 3 cells away (the torus is
// >= 4 wide), so the exact test rejects it; the 27 neighbour cells' buckets are distinct, so no
// neighbour is scanned twice. The count pass records each sphere's hits in found; the fill pass
// skips the spheres without any.
void Visit(const dua_grid_plan& g, const double* centers, const double* reach, int64_t n,
           double margin, const int64_t* held, const dua_grid_work& w, bool fill, int32_t* tmp) {
  const int64_t ng = n - g.nheld, mx = g.mask[0];
  const int32_t* start = w.start;
  int64_t ranges[16][2];
  for (int64_t p = 0; p < ng; ++p) {
    if (fill && w.found[p] == 0) continue;
    const double x = w.sxyz[3 * p], y = w.sxyz[3 * p + 1], z = w.sxyz[3 * p + 2], ri = w.sr[p];
    const int64_t i = w.sid[p];
    const Cell k = CellOf(x, y, z, g);
    const int64_t b = Bucket(k.x, k.y, k.z, g);
    // Own row: the rest of the own bucket, then the cell at +x (the next bucket unless the row
    // ends there: the grid's edge, or the torus seam).
    int nr = 1;
    ranges[0][0] = p + 1;
    if ((k.x & mx) != mx) {
      ranges[0][1] = start[b + 2];
    } else {
      ranges[0][1] = start[b + 1];
      if (g.wrap[0]) {
        const int64_t bb = Bucket(k.x + 1, k.y, k.z, g);
        ranges[1][0] = start[bb];
        ranges[1][1] = start[bb + 1];
        nr = 2;
      }
    }
    for (int r = 0; r < 4; ++r) {
      const int64_t ny = r == 0 ? k.y + 1 : k.y + r - 2, nz = r == 0 ? k.z : k.z + 1;
      int64_t first, stop;
      if (ScanRow(k.x, ny, nz, g, &first, &stop)) {
        ranges[nr][0] = start[first];
        ranges[nr][1] = start[stop];
        ++nr;
      } else {
        for (int64_t nx = k.x - 1; nx <= k.x + 1; ++nx) {
          const int64_t bb = Bucket(nx, ny, nz, g);
          ranges[nr][0] = start[bb];
          ranges[nr][1] = start[bb + 1];
          ++nr;
        }
      }
    }
    int32_t hits = 0;
    for (int t = 0; t < nr; ++t) {
      for (int64_t q = ranges[t][0]; q < ranges[t][1]; ++q) {
        if (Near(x, y, z, ri, w.sxyz[3 * q], w.sxyz[3 * q + 1], w.sxyz[3 * q + 2], w.sr[q],
                 margin)) {
          ++hits;
          Hit(i, w.sid[q], fill, w, tmp);
        }
      }
    }
    w.found[p] = hits;
  }
  // Held-out spheres against everyone; a pair of two held-out spheres from the smaller id.
  for (int64_t t = 0; t < g.nheld; ++t) {
    if (fill && w.found[ng + t] == 0) continue;
    const int64_t i = held[t];
    const double* ci = centers + 3 * i;
    int32_t hits = 0;
    for (int64_t j = 0; j < n; ++j) {
      if (j == i || (w.is_held[j] && j < i)) continue;
      const double* cj = centers + 3 * j;
      if (Near(ci[0], ci[1], ci[2], reach[i], cj[0], cj[1], cj[2], reach[j], margin)) {
        ++hits;
        Hit(i, j, fill, w, tmp);
      }
    }
    w.found[ng + t] = hits;
  }
}

int64_t ExclusivePrefix(int64_t* a, int64_t n) {
  int64_t total = 0;
  for (int64_t i = 0; i < n; ++i) {
    const int64_t c = a[i];
    a[i] = total;
    total += c;
  }
  return total;
}

}  // namespace
}  // namespace dua

extern "C" {

int64_t dua_grid_bounds(const double* centers, int64_t n, double* lo, double* hi) {
  for (int a = 0; a < 3; ++a) lo[a] = INFINITY, hi[a] = -INFINITY;
  for (int64_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      const double x = centers[3 * i + a];
      if (!(std::fabs(x) <= dua::kMaxMagnitude)) return i;  // NaN fails it too
      lo[a] = std::min(lo[a], x);
      hi[a] = std::max(hi[a], x);
    }
  }
  return -1;
}

void dua_grid_plan_of(const double* reach, int64_t n, double margin, const double* lo,
                      const double* hi, dua_grid_plan* plan, int64_t* held, double* work) {
  dua_grid_plan& g = *plan;
  // No sphere: an empty box (the bounds of nothing are inf, -inf).
  const double extent[3] = {n ? hi[0] - lo[0] : 0.0, n ? hi[1] - lo[1] : 0.0,
                            n ? hi[2] - lo[2] : 0.0};
  const double widest = std::max({extent[0], extent[1], extent[2]});
  // Held out: the k spheres of largest reach, k minimising k N + 14 N (1 + occupancy), the
  // occupancy estimated from the bounding box with the cell the rest would need.
  const int64_t kmax = std::min(n - 1, dua::kMaxHeldOut);
  g.nheld = 0;
  g.rcut = n ? *std::max_element(reach, reach + n) : 0.0;
  if (kmax > 0) {
    // The kmax + 1 largest reaches (ties by id), found on a copy of the values: a selection
    // over doubles, then two scans, instead of a selection of ids through the reaches.
    std::copy(reach, reach + n, work);
    std::nth_element(work, work + (n - 1 - kmax), work + n);
    const double tau = work[n - 1 - kmax];
    int64_t top[dua::kMaxHeldOut + 1];
    int64_t count = 0;
    for (int64_t i = 0; i < n; ++i) {
      if (reach[i] > tau) top[count++] = i;
    }
    for (int64_t i = 0; i < n && count <= kmax; ++i) {
      if (reach[i] == tau) top[count++] = i;
    }
    auto larger = [reach](int64_t a, int64_t b) {
      return reach[a] > reach[b] || (reach[a] == reach[b] && a < b);
    };
    // Fewer only with a NaN reach (the callers refuse them): then none is held out.
    if (count == kmax + 1) {
      std::sort(top, top + kmax + 1, larger);
      int64_t best = 0;
      double best_cost = INFINITY;
      const auto nn = static_cast<double>(n);
      for (int64_t k = 0; k <= kmax; ++k) {
        const double h = dua::CellEdge(reach[top[k]], margin, widest);
        double vol = 1.0;
        for (double e : extent) vol *= std::max(e, h);
        const double occupancy = std::min(nn, nn * h * h * h / vol);
        const auto kk = static_cast<double>(k);
        const double cost = kk * nn + dua::kCellCost * (nn - kk) * (1.0 + occupancy);
        if (cost < best_cost) best_cost = cost, best = k;
      }
      g.nheld = best;
      g.rcut = reach[top[best]];
      std::copy(top, top + best, held);
      std::sort(held, held + best);
    }
  }
  const int64_t ng = n - g.nheld;
  const double h_min = dua::CellEdge(g.rcut, margin, widest);
  // A budget of 2^b >= 2 ng buckets (>= 6 bits: a wrapped axis keeps >= 4 cells). The smallest
  // edge up to 2 h_min whose grid fits is used, bucket = cell; else 2 h_min, the longest axes
  // wrapped.
  const int budget = std::max(6, dua::BitLength(static_cast<double>(ng)) + 1);
  int need[3] = {0, 0, 0};
  double h = h_min;
  for (int step = 0; step <= dua::kGrowSteps; ++step) {
    h = h_min * std::pow(dua::kGrowMax, static_cast<double>(step) / dua::kGrowSteps);
    for (int a = 0; a < 3; ++a) need[a] = dua::BitLength(std::floor(extent[a] / h));
    if (need[0] + need[1] + need[2] <= budget) break;
  }
  int bits[3] = {need[0], need[1], need[2]};
  while (bits[0] + bits[1] + bits[2] > budget) {
    // Wrap the longest axis first, so aliased cells are as far apart as the budget allows.
    int longest = 0;
    for (int a = 1; a < 3; ++a) {
      if (bits[a] > bits[longest]) longest = a;
    }
    --bits[longest];
  }
  for (int a = 0; a < 3; ++a) {
    g.lo[a] = lo[a];
    g.mask[a] = (int64_t{1} << bits[a]) - 1;
    g.wrap[a] = bits[a] < need[a] ? 1 : 0;
  }
  g.h = h;
  g.shift_y = bits[0];
  g.shift_z = bits[0] + bits[1];
  g.nbucket = int64_t{1} << (bits[0] + bits[1] + bits[2]);
}

int64_t dua_grid_count(const dua_grid_plan* plan, const double* centers, const double* reach,
                       int64_t n, double margin, const int64_t* held, const dua_grid_work* work) {
  const dua_grid_plan& g = *plan;
  const dua_grid_work& w = *work;
  std::fill(w.is_held, w.is_held + n, uint8_t{0});
  for (int64_t t = 0; t < g.nheld; ++t) w.is_held[held[t]] = 1;
  // Counting sort of the grid's spheres by bucket; placing backwards leaves start[b] at the
  // bucket's start (no cursor array) and each bucket in id order. The bucket is recomputed
  // rather than stored: the same float expression gives the same cell.
  std::fill(w.start, w.start + g.nbucket + 1, 0);
  for (int64_t i = 0; i < n; ++i) {
    if (w.is_held[i]) continue;
    const dua::Cell k = dua::CellOf(centers[3 * i], centers[3 * i + 1], centers[3 * i + 2], g);
    ++w.start[dua::Bucket(k.x, k.y, k.z, g)];
  }
  for (int64_t u = 1; u < g.nbucket; ++u) w.start[u] += w.start[u - 1];
  w.start[g.nbucket] = static_cast<int32_t>(n - g.nheld);
  for (int64_t i = n - 1; i >= 0; --i) {
    if (w.is_held[i]) continue;
    const double x = centers[3 * i], y = centers[3 * i + 1], z = centers[3 * i + 2];
    const dua::Cell k = dua::CellOf(x, y, z, g);
    const int32_t p = --w.start[dua::Bucket(k.x, k.y, k.z, g)];
    w.sid[p] = static_cast<int32_t>(i);
    w.sxyz[3 * p] = x, w.sxyz[3 * p + 1] = y, w.sxyz[3 * p + 2] = z;
    w.sr[p] = reach[i];
  }
  std::fill(w.cnt_a, w.cnt_a + n, int64_t{0});
  std::fill(w.cnt_b, w.cnt_b + n, int64_t{0});
  dua::Visit(g, centers, reach, n, margin, held, w, false, nullptr);
  const int64_t count = dua::ExclusivePrefix(w.cnt_a, n);
  dua::ExclusivePrefix(w.cnt_b, n);
  return count;
}

void dua_grid_fill(const dua_grid_plan* plan, const double* centers, const double* reach, int64_t n,
                   double margin, const int64_t* held, const dua_grid_work* work, int32_t* tmp,
                   int64_t* out) {
  const dua_grid_work& w = *work;
  dua::Visit(*plan, centers, reach, n, margin, held, w, true, tmp);
  // Second counting sort, stable, by the smaller id: walking j upwards leaves each i's block
  // sorted by j. cnt_b[j] is now the end of j's block in tmp (the fill pass's cursor).
  int64_t lo = 0;
  for (int64_t j = 0; j < n; ++j) {
    const int64_t hi = w.cnt_b[j];
    for (int64_t q = lo; q < hi; ++q) {
      const int64_t i = tmp[q];
      const int64_t p = w.cnt_a[i]++;
      out[2 * p] = i;
      out[2 * p + 1] = j;
    }
    lo = hi;
  }
}

}  // extern "C"
