// The pairs a plugin instance knows, and learning the ones its candidates bring in (universe.h).
#include "universe.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "layout.h"

namespace dua {
namespace {

// Merge the sorted (key, id) rows of `add` into the sorted `keys`, `ids`.
void MergeSorted(std::vector<int64_t>* keys, std::vector<int64_t>* ids,
                 std::vector<std::pair<int64_t, int64_t>> add) {
  std::sort(add.begin(), add.end());
  std::vector<int64_t> k(keys->size() + add.size()), v(k.size());
  size_t a = 0, b = 0, o = 0;
  while (a < keys->size() || b < add.size()) {
    if (b == add.size() || (a < keys->size() && (*keys)[a] < add[b].first)) {
      k[o] = (*keys)[a], v[o++] = (*ids)[a++];
    } else {
      k[o] = add[b].first, v[o++] = add[b++].second;
    }
  }
  keys->swap(k);
  ids->swap(v);
}

}  // namespace

void LearnTables::Point() {
  filter.ngeom = static_cast<int64_t>(body.size());
  filter.body = body.data();
  filter.weld = weld.data();
  filter.parent_weld = parent_weld.data();
  filter.movable = movable.data();
  filter.contype = contype.data();
  filter.conaffinity = conaffinity.data();
  filter.lone = lone.data();
  filter.exclude = exclude.data();
  filter.nexclude = static_cast<int64_t>(exclude.size());
}

int64_t Universe::GeomPair(int64_t g1, int64_t g2) const {
  const int64_t key = (g1 << 32) | g2;
  const auto it = std::lower_bound(gp_keys.begin(), gp_keys.end(), key);
  return it != gp_keys.end() && *it == key ? gp_ids[it - gp_keys.begin()] : -1;
}

std::string Universe::Index(const std::vector<double>& spheres, int64_t ngeom) {
  nsphere = static_cast<int64_t>(spheres.size() / kSphereNcol);
  const int64_t n = npair(), ng = ngp();
  if (static_cast<int64_t>(pairs.size()) != kPairNcol * n) return "the pair records";
  std::vector<std::pair<int64_t, int64_t>> keyed;
  for (int64_t k = 0; k < ng; ++k) {
    const int64_t a = geom_pairs[2 * k], b = geom_pairs[2 * k + 1];
    if (a < 0 || b <= a || b >= ngeom) return "the geom pairs";
    keyed.emplace_back((a << 32) | b, k);
  }
  gp_keys.clear(), gp_ids.clear();
  MergeSorted(&gp_keys, &gp_ids, keyed);
  for (size_t k = 1; k < gp_keys.size(); ++k) {
    if (gp_keys[k] == gp_keys[k - 1]) return "the geom pairs (one twice)";
  }
  geom1.resize(n), geom2.resize(n);
  keyed.clear();
  always.clear();
  for (int64_t p = 0; p < n; ++p) {
    const double* rec = pairs.data() + kPairNcol * p;
    const int64_t gp = pair_geom[p];
    if (gp < 0 || gp >= ng) return "the pairs' geom pairs";
    if (!(rec[kPairFirst] >= 0 && rec[kPairFirst] < static_cast<double>(nsphere))) {
      return "the pair records";
    }
    const auto first = static_cast<int64_t>(rec[kPairFirst]);
    const auto g = static_cast<int64_t>(spheres[kSphereNcol * first + kSphereFrame]);
    const int64_t a = geom_pairs[2 * gp], b = geom_pairs[2 * gp + 1];
    if (g != a && g != b) return "the pair records (a first sphere not on its geom pair)";
    geom1[p] = g;
    geom2[p] = g == a ? b : a;
    if (rec[kPairKind] != kKindSphere) {
      always.push_back(p);
      continue;
    }
    if (!(rec[kPairSecond] >= 0 && rec[kPairSecond] < static_cast<double>(nsphere))) {
      return "the pair records";
    }
    const auto second = static_cast<int64_t>(rec[kPairSecond]);
    if (static_cast<int64_t>(spheres[kSphereNcol * second + kSphereFrame]) != geom2[p]) {
      return "the pair records (a second sphere not on its geom pair)";
    }
    keyed.emplace_back(std::min(first, second) * nsphere + std::max(first, second), p);
  }
  codes.clear(), code_ids.clear();
  MergeSorted(&codes, &code_ids, keyed);
  for (size_t k = 1; k < codes.size(); ++k) {
    if (codes[k] == codes[k - 1]) return "the pair records (a sphere pair twice)";
  }
  return "";
}

void Universe::Lookup(const int64_t* cand, int64_t n, std::vector<int64_t>* ids,
                      std::vector<int64_t>* unknown) const {
  for (int64_t k = 0; k < n; ++k) {
    const int64_t key = cand[2 * k] * nsphere + cand[2 * k + 1];
    const auto it = std::lower_bound(codes.begin(), codes.end(), key);
    if (it != codes.end() && *it == key) {
      ids->push_back(code_ids[it - codes.begin()]);
    } else if (unknown) {
      unknown->push_back(k);
    }
  }
}

int64_t Universe::Learn(const LearnTables& lt, const int64_t* g1, const int64_t* g2, int64_t n) {
  // The geom pairs, once each, that the universe lacks, in key order.
  std::vector<int64_t> keys;
  for (int64_t k = 0; k < n; ++k) {
    const int64_t lo = std::min(g1[k], g2[k]), hi = std::max(g1[k], g2[k]);
    if (GeomPair(lo, hi) < 0) keys.push_back((lo << 32) | hi);
  }
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  if (keys.empty() || !lt.contacts) return 0;
  const auto m = static_cast<int64_t>(keys.size());
  std::vector<int64_t> lo(m), hi(m);
  for (int64_t k = 0; k < m; ++k) lo[k] = keys[k] >> 32, hi[k] = keys[k] & 0xffffffffLL;
  std::vector<uint8_t> pass(m, 1);
  if (!lt.points) dua_filter_mask(&lt.filter, lo.data(), hi.data(), m, pass.data());
  std::vector<int64_t> a, b, id;
  std::vector<std::pair<int64_t, int64_t>> keyed;
  for (int64_t k = 0; k < m; ++k) {
    if (!pass[k]) continue;
    id.push_back(ngp());
    keyed.emplace_back(keys[k], ngp());
    a.push_back(lo[k]), b.push_back(hi[k]);
    geom_pairs.push_back(lo[k]), geom_pairs.push_back(hi[k]);
  }
  if (a.empty()) return 0;
  MergeSorted(&gp_keys, &gp_ids, keyed);
  const auto ng = static_cast<int64_t>(a.size());
  std::vector<double> margin(ng, lt.o_margin), gap(ng, 0.0), dist(ng);
  if (!lt.points) {
    dua_contact_distance(lt.margin.data(), lt.gap.data(), a.data(), b.data(), ng,
                         lt.override_margin ? 1 : 0, lt.o_margin, margin.data(), gap.data());
  }
  for (int64_t k = 0; k < ng; ++k) {
    dist[k] = margin[k] + gap[k];
    gp_contact.push_back(margin[k]), gp_contact.push_back(gap[k]);
  }
  // Their sphere pairs and tables, as sphere_pairs, bounded_pairs, pack_pairs and
  // exact_records make them (the same native kernels).
  const int64_t count = dua_sphere_pairs(
      a.data(), b.data(), dist.data(), id.data(), ng, lt.geom_start.data(), lt.geom_plane.data(),
      lt.geom_shape.data(), lt.radius, 0, nullptr, nullptr, nullptr, nullptr, nullptr);
  std::vector<int64_t> first(count), second(count), gp(count);
  std::vector<int8_t> kind(count);
  std::vector<double> eps(count), accel(count), delta(count), speed(count);
  dua_sphere_pairs(a.data(), b.data(), dist.data(), id.data(), ng, lt.geom_start.data(),
                   lt.geom_plane.data(), lt.geom_shape.data(), lt.radius, count, first.data(),
                   second.data(), kind.data(), gp.data(), eps.data());
  dua_pair_bounds(first.data(), second.data(), kind.data(), count, lt.sphere_body.data(),
                  lt.accel.data(), lt.delta.data(), lt.has_speed ? lt.speed.data() : nullptr,
                  accel.data(), delta.data(), speed.data());
  const int64_t base = npair();
  std::vector<int64_t> ga(count), gb(count);
  std::vector<double> pair_dist(count);
  keyed.clear();
  for (int64_t p = 0; p < count; ++p) {
    const int64_t s = second[p];
    double rec[kPairNcol];
    rec[kPairFirst] = static_cast<double>(first[p]);
    rec[kPairSecond] = static_cast<double>(s);
    rec[kPairKind] = static_cast<double>(kind[p]);
    rec[kPairEps] = eps[p], rec[kPairAccel] = accel[p], rec[kPairDelta] = delta[p];
    rec[kPairSpeed] = speed[p];
    rec[kPairOther] = kind[p] == kKindHalfspace ? static_cast<double>(lt.plane_geom[s])
                      : kind[p] == kKindShape   ? static_cast<double>(s)
                                                : 0.0;
    pairs.insert(pairs.end(), rec, rec + kPairNcol);
    ga[p] = lt.sphere_geom[first[p]];
    gb[p] = kind[p] == kKindHalfspace ? lt.plane_geom[s]
            : kind[p] == kKindShape   ? lt.shape_geom[s]
                                      : lt.sphere_geom[s];
    pair_dist[p] = dist[gp[p] - id[0]];
    pair_geom.push_back(gp[p]);
    geom1.push_back(ga[p]);
    geom2.push_back(gb[p]);
    if (kind[p] != kKindSphere) {
      always.push_back(base + p);
    } else {
      keyed.emplace_back(std::min(first[p], s) * nsphere + std::max(first[p], s), base + p);
    }
  }
  MergeSorted(&codes, &code_ids, keyed);
  if (lt.exact_geoms) {
    const size_t at = exact.size();
    exact.resize(at + kXNcol * count);
    dua_exact_rows(lt.exact_geoms, ga.data(), gb.data(), kind.data(), pair_dist.data(), count,
                   exact.data() + at);
  }
  return count;
}

std::string Universe::Forget(const std::vector<uint8_t>& keep_gp,
                             const std::vector<double>& spheres, int64_t ngeom,
                             std::vector<int64_t>* pair_map, std::vector<int64_t>* gp_map) {
  // The geom pair is the unit: a geom pair known has all its sphere pairs known (Learn adds them
  // together and Lookup learns nothing of a geom pair it knows), so none is dropped alone.
  const int64_t n = npair(), ng = ngp();
  gp_map->assign(ng, -1);
  int64_t kept_gp = 0;
  for (int64_t k = 0; k < ng; ++k) {
    if (keep_gp[k]) (*gp_map)[k] = kept_gp++;
  }
  pair_map->assign(n, -1);
  int64_t kept = 0;
  for (int64_t p = 0; p < n; ++p) {
    if ((*gp_map)[pair_geom[p]] >= 0) (*pair_map)[p] = kept++;
  }
  // Fresh vectors of the kept size: the memory of the forgotten rows goes back to the heap.
  const bool has_exact = !exact.empty();
  std::vector<double> new_pairs(kPairNcol * kept), new_exact(has_exact ? kXNcol * kept : 0);
  std::vector<int64_t> new_pair_geom(kept), new_geom_pairs(2 * kept_gp);
  std::vector<double> new_contact(2 * kept_gp);
  for (int64_t p = 0; p < n; ++p) {
    const int64_t q = (*pair_map)[p];
    if (q < 0) continue;
    std::copy_n(pairs.begin() + kPairNcol * p, kPairNcol, new_pairs.begin() + kPairNcol * q);
    if (has_exact) std::copy_n(exact.begin() + kXNcol * p, kXNcol, new_exact.begin() + kXNcol * q);
    new_pair_geom[q] = (*gp_map)[pair_geom[p]];
  }
  for (int64_t k = 0; k < ng; ++k) {
    const int64_t j = (*gp_map)[k];
    if (j < 0) continue;
    std::copy_n(geom_pairs.begin() + 2 * k, 2, new_geom_pairs.begin() + 2 * j);
    std::copy_n(gp_contact.begin() + 2 * k, 2, new_contact.begin() + 2 * j);
  }
  pairs.swap(new_pairs), exact.swap(new_exact), pair_geom.swap(new_pair_geom);
  geom_pairs.swap(new_geom_pairs), gp_contact.swap(new_contact);
  // The lookups derived anew, in vectors of their own size.
  std::vector<int64_t>().swap(geom1), std::vector<int64_t>().swap(geom2);
  std::vector<int64_t>().swap(gp_keys), std::vector<int64_t>().swap(gp_ids);
  std::vector<int64_t>().swap(codes), std::vector<int64_t>().swap(code_ids);
  std::vector<int64_t>().swap(always);
  std::string bad = Index(spheres, ngeom);
  always.shrink_to_fit(), geom1.shrink_to_fit(), geom2.shrink_to_fit();
  return bad;
}

}  // namespace dua
