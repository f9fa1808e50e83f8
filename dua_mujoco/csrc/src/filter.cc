// MuJoCo's dynamic pair filter as one rule (dua_mujoco/build/filter.py lists the conditions it
// transcribes: filterBodyPair, filterBitmask, <exclude>, the collision-function table), applied
// to given geom pairs, to every pair of a model, to count pairs without holding them, and to find
// whether any pair passes.
#include <algorithm>
#include <tuple>
#include <vector>

#include "dua/dua.h"

namespace dua {
namespace {

// Whether the two geoms are related: one body, one weld group, parent and child (the parent
// filter) or an <exclude>d body pair. Few pairs are, and they can be listed (CountByClass).
bool Related(const dua_filter& f, int64_t g1, int64_t g2) {
  const int64_t b1 = f.body[g1], b2 = f.body[g2], w1 = f.weld[g1], w2 = f.weld[g2];
  if (b1 == b2 || w1 == w2) return true;  // one body, or welded together (static-static: 0)
  if (f.filterparent && w1 != 0 && w2 != 0 &&
      (w1 == f.parent_weld[g2] || w2 == f.parent_weld[g1])) {
    return true;
  }
  if (f.nexclude) {
    const int64_t signature = (std::min(b1, b2) << 16) + std::max(b1, b2);
    if (std::binary_search(f.exclude, f.exclude + f.nexclude, signature)) return true;
  }
  return false;
}

// The rest of the rule: it reads only a geom's class (movable, contype, conaffinity, lone).
bool ClassOk(const dua_filter& f, int64_t g1, int64_t g2) {
  if (!f.movable[g1] && !f.movable[g2]) return false;
  if ((f.contype[g1] & f.conaffinity[g2]) == 0 && (f.contype[g2] & f.conaffinity[g1]) == 0) {
    return false;
  }
  return !(f.lone[g1] && f.lone[g2]);
}

bool Ok(const dua_filter& f, int64_t g1, int64_t g2) {
  return ClassOk(f, g1, g2) && !Related(f, g1, g2);
}

// Geom ids sorted by key(g), and the run [first, last) of those whose key is k.
template <class Key>
struct Sorted {
  std::vector<int64_t> ids;
  Key key;
  Sorted(int64_t n, Key k) : ids(n), key(k) {
    for (int64_t g = 0; g < n; ++g) ids[g] = g;
    std::stable_sort(ids.begin(), ids.end(), [&](int64_t a, int64_t b) { return key(a) < key(b); });
  }
  std::pair<const int64_t*, const int64_t*> Run(int64_t k) const {
    const auto lo =
        std::partition_point(ids.begin(), ids.end(), [&](int64_t g) { return key(g) < k; });
    const auto hi = std::partition_point(lo, ids.end(), [&](int64_t g) { return key(g) <= k; });
    return {ids.data() + (lo - ids.begin()), ids.data() + (hi - ids.begin())};
  }
};

// dua_filter_count without visiting every pair: the pairs whose classes pass, summed over class
// pairs from each class's size and weights, less the related pairs among them, listed (within
// weld groups, across parent joints, excluded body pairs). Both sums are exact integers, so the
// result is the pair loop's. False (nothing written) when the classes or the related pairs are
// so many that the pair loop is as cheap, or <exclude> signatures cannot be decoded.
bool CountByClass(const dua_filter& f, const int64_t* weight, int64_t* pairs, int64_t* weighted) {
  const int64_t n = f.ngeom;
  auto cls = [&f](int64_t g) {
    return std::tuple(f.movable[g], f.contype[g], f.conaffinity[g], f.lone[g]);
  };
  const Sorted by_class(n, cls);
  const std::vector<int64_t>& order = by_class.ids;
  std::vector<int64_t> rep, size, wsum, wsq;  // per class: a geom, geoms, sum of w, of w^2
  for (int64_t k = 0; k < n; ++k) {
    const int64_t g = order[k], w = weight[g];
    if (k == 0 || cls(order[k - 1]) != cls(g)) {
      rep.push_back(g), size.push_back(0), wsum.push_back(0), wsq.push_back(0);
    }
    ++size.back(), wsum.back() += w, wsq.back() += w * w;
  }
  const int64_t nclass = static_cast<int64_t>(rep.size());
  if (4 * nclass * nclass > n * n) return false;
  const Sorted weld(n, [&f](int64_t g) { return f.weld[g]; });
  const Sorted body(n, [&f](int64_t g) { return f.body[g]; });
  // The related pairs to list: within weld groups, across parent joints, excluded.
  int64_t listed = 0;
  for (int64_t k = 0, j = 0; k < n; k = j) {
    while (j < n && f.weld[weld.ids[j]] == f.weld[weld.ids[k]]) ++j;
    listed += (j - k) * (j - k - 1) / 2;
  }
  for (int64_t g = 0; f.filterparent && g < n; ++g) {
    if (f.weld[g] != 0 && f.parent_weld[g] != 0) {
      const auto [lo, hi] = weld.Run(f.parent_weld[g]);
      listed += hi - lo;
    }
  }
  for (int64_t e = 0; e < f.nexclude; ++e) {
    const int64_t b1 = f.exclude[e] >> 16, b2 = f.exclude[e] & 0xFFFF;
    if (f.exclude[e] < 0 || b1 > b2 || (n && f.body[body.ids[n - 1]] > 0xFFFF)) return false;
    const auto [lo1, hi1] = body.Run(b1);
    const auto [lo2, hi2] = body.Run(b2);
    listed += (hi1 - lo1) * (hi2 - lo2);
  }
  if (4 * listed > n * n) return false;
  int64_t p = 0, t = 0;
  for (int64_t c = 0; c < nclass; ++c) {
    for (int64_t d = c; d < nclass; ++d) {
      if (!ClassOk(f, rep[c], rep[d])) continue;
      if (c == d) {
        p += size[c] * (size[c] - 1) / 2, t += (wsum[c] * wsum[c] - wsq[c]) / 2;
      } else {
        p += size[c] * size[d], t += wsum[c] * wsum[d];
      }
    }
  }
  auto drop = [&](int64_t g, int64_t h) {
    if (ClassOk(f, g, h)) --p, t -= weight[g] * weight[h];
  };
  for (int64_t k = 0, j = 0; k < n; k = j) {  // within a weld group (one body included)
    while (j < n && f.weld[weld.ids[j]] == f.weld[weld.ids[k]]) ++j;
    for (int64_t a = k; a < j; ++a) {
      for (int64_t b = a + 1; b < j; ++b) drop(weld.ids[a], weld.ids[b]);
    }
  }
  for (int64_t h = 0; f.filterparent && h < n; ++h) {  // g in the weld group of h's parent
    const int64_t wh = f.weld[h];
    if (wh == 0 || f.parent_weld[h] == 0) continue;
    const auto [lo, hi] = weld.Run(f.parent_weld[h]);
    for (const int64_t* g = lo; g < hi; ++g) {
      // Listed from both ends when each is the other's parent: kept once.
      if (f.weld[*g] != wh && (f.parent_weld[*g] != wh || *g < h)) drop(*g, h);
    }
  }
  for (int64_t e = 0; e < f.nexclude; ++e) {
    if (e && f.exclude[e] == f.exclude[e - 1]) continue;
    const auto [lo1, hi1] = body.Run(f.exclude[e] >> 16);
    const auto [lo2, hi2] = body.Run(f.exclude[e] & 0xFFFF);
    for (const int64_t* g = lo1; g < hi1; ++g) {
      for (const int64_t* h = lo2; h < hi2; ++h) {
        const int64_t wg = f.weld[*g], wh = f.weld[*h];
        const bool parent = f.filterparent && wg != 0 && wh != 0 &&
                            (wg == f.parent_weld[*h] || wh == f.parent_weld[*g]);
        if (wg != wh && !parent) drop(*g, *h);  // else listed above
      }
    }
  }
  *pairs = p, *weighted = t;
  return true;
}

}  // namespace
}  // namespace dua

extern "C" {

int64_t dua_filter_mask(const dua_filter* f, const int64_t* g1, const int64_t* g2, int64_t n,
                        uint8_t* out) {
  int64_t count = 0;
  for (int64_t k = 0; k < n; ++k) {
    out[k] = g1[k] != g2[k] && dua::Ok(*f, g1[k], g2[k]);
    count += out[k];
  }
  return count;
}

int64_t dua_filter_all(const dua_filter* f, int64_t* g1, int64_t* g2, int64_t capacity) {
  int64_t count = 0;
  for (int64_t i = 0; i < f->ngeom; ++i) {
    for (int64_t j = i + 1; j < f->ngeom; ++j) {
      if (!dua::Ok(*f, i, j)) continue;
      if (count < capacity) g1[count] = i, g2[count] = j;
      ++count;
    }
  }
  return count;
}

int64_t dua_filter_count(const dua_filter* f, const int64_t* weight, int64_t* weighted) {
  int64_t pairs = 0, total = 0;
  if (dua::CountByClass(*f, weight, &pairs, weighted)) return pairs;
  for (int64_t i = 0; i < f->ngeom; ++i) {
    int64_t w = 0;
    for (int64_t j = i + 1; j < f->ngeom; ++j) {
      if (dua::Ok(*f, i, j)) ++pairs, w += weight[j];
    }
    total += weight[i] * w;
  }
  *weighted = total;
  return pairs;
}

int64_t dua_filter_any(const dua_filter* f) {
  for (int64_t i = 0; i < f->ngeom; ++i) {
    for (int64_t j = i + 1; j < f->ngeom; ++j) {
      if (dua::Ok(*f, i, j)) return 1;
    }
  }
  return 0;
}

}  // extern "C"
