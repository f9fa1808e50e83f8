// MuJoCo's dynamic pair filter as one rule (dua_mujoco/build/filter.py lists the conditions it
// transcribes: filterBodyPair, filterBitmask, <exclude>, the collision-function table), applied
// to given geom pairs, to every pair of a model, to count pairs without holding them, and to find
// whether any pair passes.
#include <algorithm>

#include "dua/dua.h"

namespace dua {
namespace {

bool Ok(const dua_filter& f, int64_t g1, int64_t g2) {
  const int64_t b1 = f.body[g1], b2 = f.body[g2], w1 = f.weld[g1], w2 = f.weld[g2];
  if (b1 == b2 || w1 == w2) return false;  // one body, or welded together (static-static: 0)
  if (!f.movable[g1] && !f.movable[g2]) return false;
  if (f.filterparent && w1 != 0 && w2 != 0 &&
      (w1 == f.parent_weld[g2] || w2 == f.parent_weld[g1])) {
    return false;
  }
  if ((f.contype[g1] & f.conaffinity[g2]) == 0 && (f.contype[g2] & f.conaffinity[g1]) == 0) {
    return false;
  }
  if (f.lone[g1] && f.lone[g2]) return false;
  if (f.nexclude) {
    const int64_t signature = (std::min(b1, b2) << 16) + std::max(b1, b2);
    if (std::binary_search(f.exclude, f.exclude + f.nexclude, signature)) return false;
  }
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
