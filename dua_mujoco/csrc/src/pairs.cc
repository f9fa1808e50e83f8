// The model's sphere pairs and their per-pair tables, from per-geom, per-sphere and per-body
// ones: what dua_mujoco/build/filter.py (sphere_pairs), pairbounds.py (bounded_pairs) and exact.py
// (exact_records) compute, for the pairs a predictor knows from the start and for those a pruned
// one meets later (docs/many-objects.md).
#include <cmath>

#include "dua/dua.h"
#include "layout.h"

extern "C" {

int64_t dua_sphere_pairs(const int64_t* g1, const int64_t* g2, const double* dist,
                         const int64_t* index, int64_t ngp, const int64_t* start,
                         const int64_t* plane, const int64_t* shape, const double* radius,
                         int64_t capacity, int64_t* first, int64_t* second, int8_t* kind,
                         int64_t* geom_pair, double* eps) {
  int64_t n = 0;
  for (int64_t k = 0; k < ngp; ++k) {
    // A plane or a static shape is one object, paired with every sphere of the other geom,
    // which comes first.
    const bool lone1 = plane[g1[k]] >= 0 || shape[g1[k]] >= 0;
    const int64_t ga = lone1 ? g2[k] : g1[k], gb = lone1 ? g1[k] : g2[k];
    const int64_t pk = plane[gb] >= 0   ? dua::kKindHalfspace
                       : shape[gb] >= 0 ? dua::kKindShape
                                        : dua::kKindSphere;
    const int64_t nb = pk == dua::kKindSphere ? start[gb + 1] - start[gb] : 1;
    for (int64_t i = start[ga]; i < start[ga + 1]; ++i) {
      for (int64_t j = 0; j < nb; ++j, ++n) {
        if (n >= capacity) continue;
        first[n] = i;
        second[n] = pk == dua::kKindHalfspace ? plane[gb]
                    : pk == dua::kKindShape   ? shape[gb]
                                              : start[gb] + j;
        kind[n] = static_cast<int8_t>(pk);
        geom_pair[n] = index[k];
        const double r2 = pk == dua::kKindSphere ? radius[second[n]] : 0.0;
        eps[n] = radius[i] + r2 + dist[k];
      }
    }
  }
  return n;
}

void dua_contact_distance(const double* gmargin, const double* ggap, const int64_t* g1,
                          const int64_t* g2, int64_t n, int64_t override_margin, double o_margin,
                          double* margin, double* gap) {
  for (int64_t k = 0; k < n; ++k) {
    margin[k] = override_margin ? o_margin : gmargin[g1[k]] + gmargin[g2[k]];
    gap[k] = ggap[g1[k]] + ggap[g2[k]];
  }
}

void dua_pair_bounds(const int64_t* first, const int64_t* second, const int8_t* kind, int64_t n,
                     const int64_t* sphere_body, const double* accel, const double* delta,
                     const double* speed, double* out_accel, double* out_delta, double* out_speed) {
  for (int64_t p = 0; p < n; ++p) {
    const int64_t b1 = sphere_body[first[p]];
    // Planes and static shapes are the world body's (bound 0).
    const bool lone = kind[p] != dua::kKindSphere;
    const int64_t b2 = lone ? 0 : sphere_body[second[p]];
    out_accel[p] = accel[b1] + accel[b2];
    out_delta[p] = delta[b1] + delta[b2];
    out_speed[p] = !speed ? INFINITY : lone ? speed[b1] : speed[b1] + speed[b2];
  }
}

void dua_exact_rows(const double* geoms, const int64_t* geom1, const int64_t* geom2,
                    const int8_t* kind, const double* dist, int64_t n, double* out) {
  for (int64_t p = 0; p < n; ++p) {
    double* rec = out + dua::kXNcol * p;
    for (int c = 0; c < dua::kXNcol; ++c) rec[c] = 0.0;
    const bool halfspace = kind[p] == dua::kKindHalfspace;
    // Geoms with a support of their own have kinds from kGeomSphere on; a height field held as
    // terrain (a shape pair) is read through its grid instead.
    const double k2 = geoms[dua::kGxNcol * geom2[p] + dua::kGxKind];
    const bool terrain = kind[p] == dua::kKindShape && k2 == dua::kGeomHField;
    const bool ok = geoms[dua::kGxNcol * geom1[p] + dua::kGxKind] >= dua::kGeomSphere &&
                    (halfspace || terrain || k2 >= dua::kGeomSphere);
    const double mode = halfspace                    ? dua::kModePlane
                        : terrain                    ? dua::kModeTerrain
                        : kind[p] == dua::kKindShape ? dua::kModeShape
                                                     : dua::kModeGeoms;
    rec[dua::kXMode] = ok ? mode : dua::kModeNone;
    rec[dua::kXG1] = static_cast<double>(geom1[p]);
    rec[dua::kXG2] = static_cast<double>(geom2[p]);
    rec[dua::kXDist] = dist[p];
    rec[dua::kXHull1] = rec[dua::kXHull2] = -1.0;
  }
}

}  // extern "C"
