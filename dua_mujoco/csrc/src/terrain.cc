// Height fields held as terrain: the urgency of a moving object (a sphere's centre, or a convex
// geom) against the triangular prisms MuJoCo collides a height field as (engine_collision_convex.c,
// mjc_ConvexHField). Proof in docs/theory.md, section 9; the block a record points to is
// packed by dua_mujoco/core/terrain.py.
//
// In the height field's frame, cell (r, c) (r < nrow - 1 along y, c < ncol - 1 along x) spans
// [x_c, x_{c+1}] x [y_r, y_{r+1}], x_c = dx c - size_x and y_r = dy r - size_y as MuJoCo computes
// them, and holds two prisms from z = -base up to the triangles (r+1, c), (r, c), (r+1, c+1) and
// (r, c), (r+1, c+1), (r, c+1) of the heights h = hfield_data size_z. A contact through a cell at
// time t needs the object to reach it horizontally, and its lowest point to come down to the
// cell's top: each gives a lower bound on t (Reach, Down, Plane below), and tau is the least over
// the cells of the larger of them, found by a branch and bound on a pyramid of cell maxima.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "dua/dua.h"
#include "internal.h"
#include "layout.h"

namespace dua {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Levels of the pyramid: a grid of 2^30 cells a side is far beyond any height field.
constexpr int kMaxLevels = 32;
// Cells a search tests one by one, without the pyramid, when no more can beat its first value.
constexpr int64_t kWindow = 256;

// A terrain block read through its record.
struct Terrain {
  const double* block;
  double rx, ry, base, dx, dy;
  int64_t nrow, ncol, nlevels;
  int64_t off[kMaxLevels], nx[kMaxLevels], ny[kMaxLevels];

  double X(int64_t c) const { return dx * static_cast<double>(c) - rx; }
  double Y(int64_t r) const { return dy * static_cast<double>(r) - ry; }
  double H(int64_t r, int64_t c) const {
    return block[static_cast<int64_t>(block[kTerHeights]) + r * ncol + c];
  }
  // The cell row (column) holding y (x), clamped to the grid.
  int64_t RowOf(double y) const { return Clamp(std::floor((y + ry) / dy), nrow - 2); }
  int64_t ColOf(double x) const { return Clamp(std::floor((x + rx) / dx), ncol - 2); }
  static int64_t Clamp(double k, int64_t last) {
    return k > 0.0 ? (k < static_cast<double>(last) ? static_cast<int64_t>(k) : last) : 0;
  }
  double Max(int level, int64_t i, int64_t j) const {
    return block[off[level] + i * nx[level] + j];
  }
};

// The record's terrain; the block is the record's table kTerrainBlock rows on.
Terrain ViewOf(const double* rec) {
  Terrain t;
  t.block = rec + static_cast<int64_t>(rec[kTerrainBlock]) * kShapeNcol;
  const double* b = t.block;
  t.rx = b[kTerRx], t.ry = b[kTerRy], t.base = b[kTerBase];
  t.nrow = static_cast<int64_t>(b[kTerNrow]), t.ncol = static_cast<int64_t>(b[kTerNcol]);
  t.nlevels = static_cast<int64_t>(b[kTerLevels]);
  // MuJoCo's grid steps, by its own expression.
  t.dx = (2.0 * t.rx) / static_cast<double>(t.ncol - 1);
  t.dy = (2.0 * t.ry) / static_cast<double>(t.nrow - 1);
  int64_t at = kTerHeader, ny = t.nrow - 1, nx = t.ncol - 1;
  for (int64_t l = 0; l < t.nlevels; ++l) {
    t.off[l] = at, t.ny[l] = ny, t.nx[l] = nx;
    at += ny * nx;
    ny = (ny + 1) / 2, nx = (nx + 1) / 2;
  }
  return t;
}

// The least over the cells of leaf(r, c, best) and best (a value already found), by a
// depth-first branch and bound over the pyramid, stopping once it is at most floor. node(level, i,
// j, best) is inf when no cell under the node has leaf < best (the node is pruned), else a key: the
// children of a node are visited in increasing key order. A node is tested when pushed and again
// when popped (best may have fallen since). leaf(r, c, best) may return any value >= best for a
// cell whose leaf is >= best.
template <class Node, class Leaf>
double MinOverCells(const Terrain& t, Node node, Leaf leaf, double floor, double best) {
  struct Item {
    int level;
    int64_t i, j;
    double key;
  };
  Item stack[4 * kMaxLevels + 4];
  int top = 0;
  const int root = static_cast<int>(t.nlevels) - 1;
  stack[top++] = {root, 0, 0, 0.0};
  while (top > 0) {
    const Item it = stack[--top];
    if (!(node(it.level, it.i, it.j, best) < kInf)) continue;
    if (it.level == 0) {
      best = std::min(best, leaf(it.i, it.j, best));
      if (best <= floor) return best;
      continue;
    }
    const int l = it.level - 1;
    Item kids[4];
    int n = 0;
    for (int64_t i = 2 * it.i; i < std::min(2 * it.i + 2, t.ny[l]); ++i) {
      for (int64_t j = 2 * it.j; j < std::min(2 * it.j + 2, t.nx[l]); ++j) {
        const double key = node(l, i, j, best);
        if (key < kInf) kids[n++] = {l, i, j, key};
      }
    }
    // Largest key pushed first, so the smallest is popped next (an insertion sort of four).
    for (int k = 1; k < n; ++k) {
      const Item key = kids[k];
      int m = k;
      for (; m > 0 && kids[m - 1].key < key.key; --m) kids[m] = kids[m - 1];
      kids[m] = key;
    }
    for (int k = 0; k < n; ++k) stack[top++] = kids[k];
  }
  return best;
}

// The rectangle of node (level, i, j): cells [i 2^level, (i + 1) 2^level) of the rows, clipped.
inline void NodeRect(const Terrain& t, int level, int64_t i, int64_t j, double* x0, double* x1,
                     double* y0, double* y1) {
  const int64_t c0 = j << level, c1 = std::min((j + 1) << level, t.ncol - 1);
  const int64_t r0 = i << level, r1 = std::min((i + 1) << level, t.nrow - 1);
  *x0 = t.X(c0), *x1 = t.X(c1), *y0 = t.Y(r0), *y1 = t.Y(r1);
}

// Horizontal distance between the box [lo, hi] (x, y) and the rectangle [x0, x1] x [y0, y1].
inline double RectGap(const double* lo, const double* hi, double x0, double x1, double y0,
                      double y1) {
  const double gx = std::max(0.0, std::max(x0 - hi[0], lo[0] - x1));
  const double gy = std::max(0.0, std::max(y0 - hi[1], lo[1] - y1));
  return std::sqrt(gx * gx + gy * gy);
}

// The moving object in the terrain's frame: its box [lo, hi], the centre m and the rotation M
// (terrain frame to the object's own) of its support, its velocity u, and the bounds. Its points
// stay within delta t + accel t^2 / 2 + spin t of the translate by u t (docs/theory.md, (5.2)).
struct Object {
  int kind;
  bool point;  // a sphere's centre: its support is n.m
  double size[3];
  double m[3], M[9];
  double lo[3], hi[3];
  double u[3];
  double w;  // the horizontal speed bound of its points: |u_xy| + spin
  double spin, eps, accel, delta;
  double slack;  // the gaps' rounding allowance
};

// Lowest n.a over the object (n a direction in the terrain's frame).
inline double Lowest(const Object& o, const double* n) {
  if (o.point) return n[0] * o.m[0] + n[1] * o.m[1] + n[2] * o.m[2];
  const double k0 = o.M[0] * n[0] + o.M[1] * n[1] + o.M[2] * n[2];
  const double k1 = o.M[3] * n[0] + o.M[4] * n[1] + o.M[5] * n[2];
  const double k2 = o.M[6] * n[0] + o.M[7] * n[1] + o.M[8] * n[2];
  return n[0] * o.m[0] + n[1] * o.m[1] + n[2] * o.m[2] -
         SupportLocal(o.kind, o.size[0], o.size[1], o.size[2], k0, k1, k2);
}

// Reach: the first t at which some point can be within eps of a rectangle d away horizontally.
inline double Reach(const Object& o, double d) {
  return TauHalfspace(d - o.eps - o.slack, -o.w, o.accel, o.delta);
}

// Each bound below is the first root of gap + (vn - delta) t - accel t^2 / 2, TauHalfspace's.

// Down: the lowest point's gap above a top no higher than h.
inline double DownGap(const Object& o, double h) { return o.lo[2] - h - o.eps - o.slack; }

// Plane: the gap and normal speed of the object above the half-space below the plane through
// triangle (a, b, c), which holds the triangle's prism; false for a degenerate triangle (no
// bound of its own).
bool PlaneGap(const Object& o, const double* a, const double* b, const double* c, double* gap,
              double* vn) {
  const double e0 = b[0] - a[0], e1 = b[1] - a[1], e2 = b[2] - a[2];
  const double f0 = c[0] - a[0], f1 = c[1] - a[1], f2 = c[2] - a[2];
  double n[3] = {e1 * f2 - e2 * f1, e2 * f0 - e0 * f2, e0 * f1 - e1 * f0};
  const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  if (!(len > 0.0)) return false;
  const double s = n[2] > 0.0 ? 1.0 / len : -1.0 / len;  // upward
  n[0] *= s, n[1] *= s, n[2] *= s;
  // The prism's support along n: its top vertices (n_z >= 0 puts the base below them).
  const double top = std::max(
      std::max(n[0] * a[0] + n[1] * a[1] + n[2] * a[2], n[0] * b[0] + n[1] * b[1] + n[2] * b[2]),
      n[0] * c[0] + n[1] * c[1] + n[2] * c[2]);
  *gap = Lowest(o, n) - top - o.eps - o.slack;
  *vn = n[0] * o.u[0] + n[1] * o.u[1] + n[2] * o.u[2] - o.spin;
  return true;
}

// What no cell can beat once a value best is found: a node farther than reach (horizontally) or
// lower than floor cannot be touched before best (docs/theory.md, Theorem 9.4). Both are
// pushed out by a relative 1e-12, far beyond their rounding, so that a node pruned in floating
// point is pruned in exact arithmetic too.
struct Cutoff {
  double best = -1.0;
  double grow = 0.0;     // accel best^2 / 2
  double reach2 = kInf;  // squared horizontal distance
  double floor = -kInf;  // height
  void At(const Object& o, double t) {
    if (t == best) return;
    best = t;
    if (!(t < kInf)) {
      grow = kInf, reach2 = kInf, floor = -kInf;
      return;
    }
    grow = 0.5 * o.accel * t * t;
    const double r = ((o.w + o.delta) * t + grow + o.eps + o.slack) * (1.0 + 1e-12);
    reach2 = r * r * (1.0 + 1e-12);
    const double g0 = o.lo[2] - o.eps - o.slack;
    const double drift = (o.u[2] - o.spin - o.delta) * t;
    floor = std::min(g0, g0 + drift - grow) - 1e-12 * (std::fabs(g0) + std::fabs(drift) + grow);
  }
  // Whether gap + (vn - delta) t - accel t^2 / 2 stays positive on [0, best], with room to spare
  // (1e-12 of its terms, far beyond their rounding): then its first root is beyond best. (It
  // is concave in t, so positive at 0 and at best means positive between.)
  bool Beyond(const Object& o, double gap, double vn) const {
    if (!(gap > 0.0 && best < kInf)) return false;
    const double drift = (vn - o.delta) * best;
    return gap + drift - grow > 1e-12 * (gap + std::fabs(drift) + grow);
  }
};

// tau of the object against the terrain (docs/theory.md, Theorem 9.3). *path (if given) says
// what decided it, for the tests: kPathFirst (the base or the first cell: no search), kPathWindow
// (the cells within reach, one by one) or kPathPyramid (the branch and bound).
double TauObject(const Terrain& t, const Object& o, int* path) {
  // From below, the highest point must come up to the base.
  const double under =
      TauHalfspace(-t.base - o.eps - o.hi[2] - o.slack, -(o.u[2] + o.spin), o.accel, o.delta);
  Cutoff cut;
  auto node = [&](int level, int64_t i, int64_t j, double best) {
    cut.At(o, best);
    double x0, x1, y0, y1;
    NodeRect(t, level, i, j, &x0, &x1, &y0, &y1);
    const double gx = std::max(0.0, std::max(x0 - o.hi[0], o.lo[0] - x1));
    const double gy = std::max(0.0, std::max(y0 - o.hi[1], o.lo[1] - y1));
    const double h = t.Max(level, i, j);
    if (gx * gx + gy * gy > cut.reach2 || h < cut.floor) return kInf;
    // Nearest and highest first: a bound on the distance to the node's column.
    return std::max(std::max(gx, gy), o.lo[2] - h);
  };
  auto leaf = [&](int64_t r, int64_t c, double best) {
    cut.At(o, best);
    const double x0 = t.X(c), x1 = t.X(c + 1), y0 = t.Y(r), y1 = t.Y(r + 1);
    const double v00[3] = {x0, y0, t.H(r, c)}, v01[3] = {x1, y0, t.H(r, c + 1)};
    const double v10[3] = {x0, y1, t.H(r + 1, c)}, v11[3] = {x1, y1, t.H(r + 1, c + 1)};
    // MuJoCo's two triangles of the cell, each with the vertical bound of its highest corner and
    // its plane's; one that cannot beat best is left out before any root is taken.
    const double* tri[2][3] = {{v10, v00, v11}, {v00, v11, v01}};
    double value = kInf;
    for (const auto& v : tri) {
      const double down = DownGap(o, std::max(std::max(v[0][2], v[1][2]), v[2][2]));
      const double down_vn = o.u[2] - o.spin;
      if (cut.Beyond(o, down, down_vn)) continue;
      double plane = -kInf, plane_vn = 0.0;
      if (PlaneGap(o, v[0], v[1], v[2], &plane, &plane_vn) && cut.Beyond(o, plane, plane_vn)) {
        continue;
      }
      value = std::min(value, std::max(TauHalfspace(down, down_vn, o.accel, o.delta),
                                       TauHalfspace(plane, plane_vn, o.accel, o.delta)));
    }
    if (!(value < best)) return value;
    return std::max(value, Reach(o, RectGap(o.lo, o.hi, x0, x1, y0, y1)));
  };
  // A first value from the cell under the object's centre; then, while the cells that could
  // beat it are few, every one of them in turn (no pyramid), else the pyramid's search.
  const int64_t r0 = t.RowOf(o.m[1]), c0 = t.ColOf(o.m[0]);
  double best = leaf(r0, c0, kInf);
  if (path != nullptr) *path = kPathFirst;
  if (best <= under) return under;
  cut.At(o, best);
  const double reach = std::sqrt(cut.reach2);
  // One cell more on every side than the division says: rounding cannot leave one out.
  const int64_t rlo = t.RowOf(o.lo[1] - reach) - 1, rhi = t.RowOf(o.hi[1] + reach) + 1;
  const int64_t clo = t.ColOf(o.lo[0] - reach) - 1, chi = t.ColOf(o.hi[0] + reach) + 1;
  if ((rhi - rlo + 1) * (chi - clo + 1) > kWindow) {
    if (path != nullptr) *path = kPathPyramid;
    return std::max(under, MinOverCells(t, node, leaf, under, best));
  }
  if (path != nullptr) *path = kPathWindow;
  // Row by row: the tests of node(0, r, c, best), with each row's part computed once.
  const double* level0 = t.block + t.off[0];
  for (int64_t r = std::max<int64_t>(rlo, 0); r <= std::min(rhi, t.nrow - 2); ++r) {
    const double gy = std::max(0.0, std::max(t.Y(r) - o.hi[1], o.lo[1] - t.Y(r + 1)));
    const double* heights = level0 + r * t.nx[0];
    for (int64_t c = std::max<int64_t>(clo, 0); c <= std::min(chi, t.ncol - 2); ++c) {
      const double gx = std::max(0.0, std::max(t.X(c) - o.hi[0], o.lo[0] - t.X(c + 1)));
      if (gx * gx + gy * gy > cut.reach2 || heights[c] < cut.floor) continue;
      best = std::min(best, leaf(r, c, best));
      cut.At(o, best);
    }
    if (best <= under) return under;
  }
  return std::max(under, best);
}

// The object of a shape record `shape` (world) moving with velocity v, in the terrain's frame.
Object ObjectOf(const double* rec, const double* shape, const double* v, double spin, double eps,
                double accel, double delta) {
  Object o;
  const double* R = rec + kShapeMat;  // terrain to world, row-major
  const double* p = rec + kShapePos;
  const double* G = shape + kShapeMat;  // object to world
  const double* q = shape + kShapePos;
  o.kind = static_cast<int>(shape[kShapeKind]);
  for (int k = 0; k < 3; ++k) o.size[k] = shape[kShapeSize + k];
  o.point = o.kind == kGeomSphere && o.size[0] == 0.0;
  const double d0 = q[0] - p[0], d1 = q[1] - p[1], d2 = q[2] - p[2];
  for (int k = 0; k < 3; ++k) {
    o.m[k] = R[k] * d0 + R[3 + k] * d1 + R[6 + k] * d2;
    o.u[k] = R[k] * v[0] + R[3 + k] * v[1] + R[6 + k] * v[2];
  }
  // M = G^T R: a terrain direction n is M n in the object's frame.
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) {
      o.M[3 * a + b] = G[a] * R[b] + G[3 + a] * R[3 + b] + G[6 + a] * R[6 + b];
    }
  }
  double extent = 0.0;
  for (int k = 0; k < 3; ++k) {
    // Every kind is symmetric about its centre: the support along -e_k is the one along e_k.
    const double s =
        SupportLocal(o.kind, o.size[0], o.size[1], o.size[2], o.M[k], o.M[3 + k], o.M[6 + k]);
    o.lo[k] = o.m[k] - s, o.hi[k] = o.m[k] + s;
    extent += s;
  }
  o.spin = spin, o.eps = eps, o.accel = accel;
  o.w = std::hypot(o.u[0], o.u[1]) + spin;
  const double nv = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  o.delta = delta + kVelSlack * (nv + spin);
  // Every gap is a difference of numbers no larger than these, each a few roundings off.
  const double* b = rec + static_cast<int64_t>(rec[kTerrainBlock]) * kShapeNcol;
  const double scale = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]) +
                       std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) + extent + b[kTerRx] +
                       b[kTerRy] + b[kTerBase] + b[kTerHabs] + eps;
  o.slack = kGapSlack * scale;
  return o;
}

// c in the terrain's frame.
void ToTerrain(const double* rec, const double* c, double* l) {
  const double* R = rec + kShapeMat;
  const double* p = rec + kShapePos;
  const double d0 = c[0] - p[0], d1 = c[1] - p[1], d2 = c[2] - p[2];
  for (int k = 0; k < 3; ++k) l[k] = R[k] * d0 + R[3 + k] * d1 + R[6 + k] * d2;
}

// The top surface over (x, y) of the grid: MuJoCo's triangle of the cell holding it.
double Surface(const Terrain& t, double x, double y) {
  const int64_t c =
      std::min<int64_t>(std::max<int64_t>(std::floor((x + t.rx) / t.dx), 0), t.ncol - 2);
  const int64_t r =
      std::min<int64_t>(std::max<int64_t>(std::floor((y + t.ry) / t.dy), 0), t.nrow - 2);
  const double fx = std::min(std::max((x - t.X(c)) / t.dx, 0.0), 1.0);
  const double fy = std::min(std::max((y - t.Y(r)) / t.dy, 0.0), 1.0);
  const double h00 = t.H(r, c), h01 = t.H(r, c + 1), h10 = t.H(r + 1, c), h11 = t.H(r + 1, c + 1);
  // The diagonal runs from (r, c) to (r + 1, c + 1): above it (fy > fx) the first triangle.
  if (fy >= fx) return h00 + fx * (h11 - h10) + fy * (h10 - h00);
  return h00 + fx * (h01 - h00) + fy * (h11 - h01);
}

}  // namespace

double TerrainSupport(const double* n, const double* rec) {
  const Terrain t = ViewOf(rec);
  const double* R = rec + kShapeMat;
  const double* p = rec + kShapePos;
  double l[3];
  for (int k = 0; k < 3; ++k) l[k] = R[k] * n[0] + R[3 + k] * n[1] + R[6 + k] * n[2];
  // The prisms' vertices: the grid's tops and the base under its corners.
  double best = -kInf;
  for (int64_t r = 0; r < t.nrow; ++r) {
    for (int64_t c = 0; c < t.ncol; ++c) {
      best = std::max(best, l[0] * t.X(c) + l[1] * t.Y(r) + l[2] * t.H(r, c));
    }
  }
  for (const double x : {-t.rx, t.rx}) {
    for (const double y : {-t.ry, t.ry}) best = std::max(best, l[0] * x + l[1] * y - l[2] * t.base);
  }
  return n[0] * p[0] + n[1] * p[1] + n[2] * p[2] + best;
}

void TerrainClosest(const double* c, const double* rec, double* out) {
  const Terrain t = ViewOf(rec);
  double l[3];
  ToTerrain(rec, c, l);
  const double x = std::min(std::max(l[0], -t.rx), t.rx);
  const double y = std::min(std::max(l[1], -t.ry), t.ry);
  const double z = std::min(std::max(l[2], -t.base), Surface(t, x, y));
  const double* R = rec + kShapeMat;
  const double* p = rec + kShapePos;
  for (int k = 0; k < 3; ++k) out[k] = p[k] + R[3 * k] * x + R[3 * k + 1] * y + R[3 * k + 2] * z;
}

double TerrainGap(const double* c, const double* rec, double* n) {
  const Terrain t = ViewOf(rec);
  double l[3];
  ToTerrain(rec, c, l);
  const double* R = rec + kShapeMat;
  n[0] = R[2], n[1] = R[5], n[2] = R[8];  // the terrain's up axis
  const double below = -t.base - l[2];
  auto node = [&](int level, int64_t i, int64_t j, double best) {
    double x0, x1, y0, y1;
    NodeRect(t, level, i, j, &x0, &x1, &y0, &y1);
    const double bound =
        std::max(std::max(RectGap(l, l, x0, x1, y0, y1), l[2] - t.Max(level, i, j)), below);
    return bound < best ? bound : kInf;
  };
  auto leaf = [&](int64_t r, int64_t c0, double) {
    const double x0 = t.X(c0), x1 = t.X(c0 + 1), y0 = t.Y(r), y1 = t.Y(r + 1);
    const double h00 = t.H(r, c0), h01 = t.H(r, c0 + 1), h10 = t.H(r + 1, c0),
                 h11 = t.H(r + 1, c0 + 1);
    // The distance to a prism is at least to its rectangle, above its highest corner and below
    // its base.
    const double up = std::min(l[2] - std::max(std::max(h10, h00), h11),
                               l[2] - std::max(std::max(h00, h11), h01));
    return std::max(std::max(RectGap(l, l, x0, x1, y0, y1), up), below);
  };
  return MinOverCells(t, node, leaf, -kInf, kInf);
}

double TauTerrain(const double* rec, const double* shape, const double* v, double spin, double eps,
                  double accel, double delta, int* path) {
  const Terrain t = ViewOf(rec);
  return TauObject(t, ObjectOf(rec, shape, v, spin, eps, accel, delta), path);
}

double TauTerrainSphere(double c0, double c1, double c2, double v0, double v1, double v2,
                        const double* rec, double eps, double accel, double delta) {
  // A point: a sphere of radius 0 (its radius is in eps).
  const double point[kShapeNcol] = {kGeomSphere, 0, 0, 0, c0, c1, c2, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  const double v[3] = {v0, v1, v2};
  return TauTerrain(rec, point, v, 0.0, eps, accel, delta);
}

namespace {

// The support shape (a shape record, world) of the exact level's geom record gx at pose (pos,
// mat): a mesh as its box, about the box's centre.
void GeomShape(const double* gx, const double* pos, const double* mat, double* shape) {
  shape[kShapeKind] = gx[kGxKind];
  for (int k = 0; k < 3; ++k) {
    shape[kShapeSize + k] = gx[kGxSize + k];
    shape[kShapePos + k] = pos[k] + mat[3 * k] * gx[kGxCentre] +
                           mat[3 * k + 1] * gx[kGxCentre + 1] + mat[3 * k + 2] * gx[kGxCentre + 2];
  }
  for (int k = 0; k < 9; ++k) shape[kShapeMat + k] = mat[k];
}

// Theorem 9.3 for an object at rest whose points may move at unit speed (u = 0, sigma = 0, A =
// 0, delta = 1): no contact before t iff the object is farther than eps + t from the terrain,
// so the bound is at most dist - eps (docs/theory.md, Lemma 9.5).
constexpr double kRest[3] = {0.0, 0.0, 0.0};

}  // namespace

double TerrainPointGap(const double* c, const double* rec, double eps) {
  return TauTerrainSphere(c[0], c[1], c[2], 0.0, 0.0, 0.0, rec, eps, 0.0, 1.0);
}

double TerrainGeomGap(const double* gx, const double* pos, const double* mat, const double* rec,
                      double eps) {
  double shape[kShapeNcol];
  GeomShape(gx, pos, mat, shape);
  return TauTerrain(rec, shape, kRest, 0.0, eps, 0.0, 1.0);
}

double TerrainExactTau(const dua_step_args& a, int64_t p) {
  const double* pair = a.pairs + p * kPairNcol;
  const double* xrec = a.exact.records + p * kXNcol;
  const int64_t g = static_cast<int64_t>(xrec[kXG1]);
  const double* gx = a.exact.geoms + g * kGxNcol;
  // The origin's state: the record's first columns are a sphere record of it.
  double s[6];
  dua_rigid_point(0, gx, &a.frame, s);
  const int64_t b = static_cast<int64_t>(gx[kSphereBody]);
  const int64_t r = static_cast<int64_t>(gx[kSphereRoot]);
  const double* tw = a.frame.twist + 6 * b;
  const double* rt = a.frame.root_twist + 6 * r;
  const double w0 = tw[0] + rt[0], w1 = tw[1] + rt[1], w2 = tw[2] + rt[2];
  const double spin = std::sqrt(w0 * w0 + w1 * w1 + w2 * w2) * gx[kGxRadius];
  // The geom's support shape at its pose (a mesh as its box).
  double shape[kShapeNcol];
  GeomShape(gx, a.frame.pos + 3 * g, a.frame.mat + 9 * g, shape);
  const double* rec = a.shapes + static_cast<int64_t>(pair[kPairOther]) * kShapeNcol;
  return TauTerrain(rec, shape, s + 3, spin, xrec[kXDist], pair[kPairAccel], pair[kPairDelta]);
}

int64_t ShapeRecordCount(const double* shapes, int64_t nrows) {
  // The records come first; the first block a terrain record points to ends them.
  int64_t end = nrows;
  for (int64_t i = 0; i < end; ++i) {
    const double* rec = shapes + i * kShapeNcol;
    if (rec[kShapeKind] != kGeomHField) continue;
    const double off = rec[kTerrainBlock];
    if (off >= 1 && off == std::floor(off) && off < static_cast<double>(nrows)) {
      end = std::min(end, i + static_cast<int64_t>(off));
    }
  }
  return end;
}

}  // namespace dua

extern "C" {

int64_t dua_check_shapes(const double* shapes, int64_t nrows) {
  // The records come first; the first block a terrain record points to ends them.
  int64_t end = nrows;
  for (int64_t i = 0; i < end; ++i) {
    const double* rec = shapes + i * dua::kShapeNcol;
    // Other records read their own row only (a placeholder row of zeros included).
    if (rec[dua::kShapeKind] != dua::kGeomHField) continue;
    for (int k = 0; k < dua::kShapeNcol; ++k) {
      if (!std::isfinite(rec[k])) return i;
    }
    const double off = rec[dua::kTerrainBlock], rows = rec[dua::kTerrainRows];
    // Within the table (and far below 2^53, where the doubles stop being exact integers).
    if (!(off >= 1 && off == std::floor(off) && rows >= 1 && rows == std::floor(rows) &&
          off < static_cast<double>(nrows) && rows <= static_cast<double>(nrows - i - off))) {
      return i;
    }
    const int64_t start = i + static_cast<int64_t>(off);
    const int64_t len = static_cast<int64_t>(rows) * dua::kShapeNcol;
    end = std::min(end, start);
    const double* b = shapes + start * dua::kShapeNcol;
    for (int64_t k = 0; k < len; ++k) {
      if (!std::isfinite(b[k])) return i;
    }
    const double nr = b[dua::kTerNrow], nc = b[dua::kTerNcol];
    if (!(b[dua::kTerRx] > 0 && b[dua::kTerRy] > 0 && b[dua::kTerBase] >= 0 && nr >= 2 && nc >= 2 &&
          nr == std::floor(nr) && nc == std::floor(nc) && nr * nc <= len)) {
      return i;
    }
    // The pyramid's levels down to one cell, then the heights, inside the block.
    int64_t at = dua::kTerHeader, ny = static_cast<int64_t>(nr) - 1,
            nx = static_cast<int64_t>(nc) - 1;
    int64_t levels = 1;
    for (; ny > 1 || nx > 1; ++levels) {
      at += ny * nx;
      ny = (ny + 1) / 2, nx = (nx + 1) / 2;
      if (at > len) return i;
    }
    at += 1;
    const int64_t heights = static_cast<int64_t>(b[dua::kTerHeights]);
    if (!(b[dua::kTerLevels] == static_cast<double>(levels) && levels <= 32 &&
          b[dua::kTerHeights] == static_cast<double>(heights) && heights >= at &&
          heights + static_cast<int64_t>(nr * nc) <= len && b[dua::kTerHabs] >= 0)) {
      return i;
    }
  }
  return -1;
}

double dua_tau_terrain(const double* rec, const double* shape, const double* v, double spin,
                       double eps, double accel, double delta) {
  return dua::TauTerrain(rec, shape, v, spin, eps, accel, delta);
}

}  // extern "C"
