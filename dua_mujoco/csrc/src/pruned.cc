// Pruned pairs (pruned.h): the held set chosen from the spheres' reaches and renewed for the
// spheres that may have left theirs.
#include "pruned.h"

#include <algorithm>
#include <cmath>

#include "layout.h"

namespace dua {

std::string PrunedTables::Build(const std::vector<double>& reach_table,
                                const std::vector<double>& spheres, int64_t nbody, double horizon_s,
                                double margin_m, int64_t stride_steps) {
  nsphere = static_cast<int64_t>(spheres.size() / kSphereNcol);
  if (static_cast<int64_t>(reach_table.size()) != 4 * nsphere) return "the reach table";
  if (!(horizon_s > 0.0) || !(margin_m >= 0.0) || !std::isfinite(horizon_s) ||
      !std::isfinite(margin_m) || stride_steps < 1) {
    return "the horizon, margin or stride";
  }
  horizon = horizon_s;
  margin = margin_m;
  stride = stride_steps;
  radius.resize(nsphere), accel.resize(nsphere), delta.resize(nsphere), speed.resize(nsphere);
  for (int64_t i = 0; i < nsphere; ++i) {
    radius[i] = reach_table[4 * i];
    accel[i] = reach_table[4 * i + 1];
    delta[i] = reach_table[4 * i + 2];
    speed[i] = reach_table[4 * i + 3];
    // Finite and >= 0 (a speed bound may be inf: none), as dua_reaches requires.
    const bool finite = std::isfinite(radius[i]) && std::isfinite(accel[i]) &&
                        std::isfinite(delta[i]) && !std::isnan(speed[i]);
    if (!finite || radius[i] < 0 || accel[i] < 0 || delta[i] < 0 || speed[i] < 0) {
      return "the reach table's values";
    }
  }
  // Spheres by body: a counting sort, each body's in id order.
  body_start.assign(nbody + 1, 0);
  for (int64_t i = 0; i < nsphere; ++i) {
    const auto b = static_cast<int64_t>(spheres[kSphereNcol * i + kSphereBody]);
    if (b < 0 || b >= nbody) return "the sphere records";
    ++body_start[b + 1];
  }
  for (int64_t b = 0; b < nbody; ++b) body_start[b + 1] += body_start[b];
  body_spheres.resize(nsphere);
  std::vector<int64_t> cursor(body_start.begin(), body_start.end() - 1);
  for (int64_t i = 0; i < nsphere; ++i) {
    body_spheres[cursor[static_cast<int64_t>(spheres[kSphereNcol * i + kSphereBody])]++] = i;
  }
  return "";
}

void PrunedState::Known(const LearnTables& learn, Universe* u, int64_t k,
                        std::vector<int64_t>* ids) {
  // Look the candidates up; learn the geom pairs of those the universe lacks (MuJoCo's filter
  // decides), then look them up again.
  std::vector<int64_t> unknown;
  const size_t at = ids->size();
  u->Lookup(cand.data(), k, ids, &unknown);
  if (unknown.empty()) return;
  std::vector<int64_t> g1(unknown.size()), g2(unknown.size());
  for (size_t q = 0; q < unknown.size(); ++q) {
    g1[q] = learn.sphere_geom[cand[2 * unknown[q]]];
    g2[q] = learn.sphere_geom[cand[2 * unknown[q] + 1]];
  }
  if (u->Learn(learn, g1.data(), g2.data(), static_cast<int64_t>(g1.size())) > 0) {
    ids->resize(at);
    u->Lookup(cand.data(), k, ids, nullptr);
  }
}

void PrunedState::Allocate(const PrunedTables& t) {
  anchor.assign(3 * t.nsphere, 0.0);
  speed0.assign(t.nsphere, 0.0);
  reach.assign(t.nsphere, 0.0);
  built.assign(t.nsphere, 0);
  escapes.clear();
  built_at = 0;
}

dua_reach PrunedState::Reach(const PrunedTables& t) {
  dua_reach r{};
  r.nsphere = t.nsphere;
  r.radius = t.radius.data();
  r.body_start = t.body_start.data();
  r.body_spheres = t.body_spheres.data();
  r.accel = t.accel.data();
  r.delta = t.delta.data();
  r.speed = t.speed.data();
  r.anchor = anchor.data();
  r.speed0 = speed0.data();
  r.reach = reach.data();
  r.built = built.data();
  r.dt = 0.0;  // set by the caller that needs it (the escape check)
  r.horizon = t.horizon;
  r.margin = t.margin;
  return r;
}

bool PrunedState::Select(const PrunedTables& t, const LearnTables& learn, Universe* u,
                         const dua_step_args& a, int64_t step, std::vector<int64_t>* ids) {
  const int64_t n = t.nsphere;
  std::vector<double> centers(3 * static_cast<size_t>(n)), speeds(n);
  double state[6];
  for (int64_t i = 0; i < n; ++i) {
    dua_point(&a, i, state);
    for (int c = 0; c < 6; ++c) {
      if (!std::isfinite(state[c])) return false;  // nothing anchored
    }
    std::copy(state, state + 3, centers.begin() + 3 * i);
    speeds[i] = std::sqrt(state[3] * state[3] + state[4] * state[4] + state[5] * state[5]);
  }
  // A centre beyond 1e150 m (its squares overflow) is a diverged state, as one not finite is
  // (the Python predictor raises for both).
  double lo[3], hi[3];
  if (dua_grid_bounds(centers.data(), n, lo, hi) >= 0) return false;
  anchor = std::move(centers);
  speed0 = std::move(speeds);
  std::fill(built.begin(), built.end(), step);
  dua_reaches(t.radius.data(), speed0.data(), t.accel.data(), t.delta.data(), t.speed.data(), n,
              t.horizon, reach.data());
  ids->assign(u->always.begin(), u->always.end());
  if (n < 2) return true;
  dua_grid_plan plan{};
  held_out.resize(256);
  work.resize(n);
  dua_grid_plan_of(reach.data(), n, t.margin, lo, hi, &plan, held_out.data(), work.data());
  const int64_t ng = n - plan.nheld;
  start.resize(plan.nbucket + 1), sid.resize(ng), sxyz.resize(3 * ng), sr.resize(ng);
  cnt_a.resize(n), cnt_b.resize(n), found.resize(n), is_held.resize(n);
  const dua_grid_work w{start.data(), sid.data(),   sxyz.data(),  sr.data(),
                        cnt_a.data(), cnt_b.data(), found.data(), is_held.data()};
  const int64_t k =
      dua_grid_count(&plan, anchor.data(), reach.data(), n, t.margin, held_out.data(), &w);
  tmp.resize(k);
  cand.resize(2 * k);
  dua_grid_fill(&plan, anchor.data(), reach.data(), n, t.margin, held_out.data(), &w, tmp.data(),
                cand.data());
  Known(learn, u, k, ids);
  std::sort(ids->begin(), ids->end());
  return true;
}

bool PrunedState::Renew(const PrunedTables& t, const LearnTables& learn, Universe* u,
                        const dua_step_args& a, int64_t step, std::vector<int64_t>* ids) {
  dua_reach r = Reach(t);
  const auto n = static_cast<int64_t>(escapes.size());
  cand.resize(2 * std::max<int64_t>(4 * n, 16));
  int64_t count = 0;
  while (true) {
    const auto capacity = static_cast<int64_t>(cand.size() / 2);
    count = dua_renew(&a, &r, escapes.data(), n, step, cand.data(), capacity);
    if (count < 0) return false;
    if (count <= capacity) break;
    cand.resize(2 * count);
  }
  ids->clear();
  Known(learn, u, count, ids);
  std::sort(ids->begin(), ids->end());
  ids->erase(std::unique(ids->begin(), ids->end()), ids->end());
  return true;
}

void PrunedState::FindEscapes(const PrunedTables& t, const dua_step_args& a, int64_t step) {
  dua_reach r = Reach(t);
  r.dt = a.schedule.dt;
  escapes.resize(t.nsphere);
  escapes.resize(dua_escaped_spheres(&a, &r, step, escapes.data()));
  // Free spheres have no violation check of their own: the escapes say which broke their bounds.
  broken = a.points.centers ? dua_proven_broken(&a, &r, escapes.data(),
                                                static_cast<int64_t>(escapes.size()), step)
                            : -1;
}

}  // namespace dua
