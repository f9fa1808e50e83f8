// A pruned predictor's reach: the escape check of Lemma 6.4 (docs/theory.md, section 6) and the
// candidate pairs of spheres whose reach is renewed (docs/many-objects.md).
#include <algorithm>
#include <cmath>
#include <vector>

#include "dua/dua.h"
#include "internal.h"

namespace dua {
namespace {

// The grid's pair contract (grid.cc's ROUNDING_SLACK): 1 + 2^-44.
constexpr double kRoundingSlack = 1.0 + 1.0 / 17592186044416.0;
// Rounding allowance of the escape test, relative: a sphere within it of its reach's edge counts
// as escaped (in doubt, renewed: a renewal is cheap and always safe, while a sphere let through
// that far outside would leave a pair out by that much).
constexpr double kEscapeSlack = 1e-9;

// Whether sphere s, at centre c with measured velocity v t seconds after its anchor, may have
// left its reach: a centre farther from the anchor than min((s0 + delta) t + A t^2 / 2, V t), or
// a measured speed above min(s0 + A t, V - delta).
bool Escapes(const dua_reach& r, int64_t s, const double* c, const double* v, double t) {
  const double s0 = r.speed0[s], a = r.accel[s], d = r.delta[s], vmax = r.speed[s];
  double allow = (s0 + d) * t + 0.5 * a * t * t;
  if (std::isfinite(vmax)) allow = std::min(allow, vmax * t);
  const double top = std::min(s0 + a * t, vmax - d);
  const double* o = r.anchor + 3 * s;
  const double dx = c[0] - o[0], dy = c[1] - o[1], dz = c[2] - o[2];
  const double dist = std::sqrt(dx * dx + dy * dy + dz * dz);
  const double speed = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  // Rounding: positions scale with their magnitude, speeds with the bound.
  const double scale = std::max({1.0, std::fabs(c[0]), std::fabs(c[1]), std::fabs(c[2])});
  const double tol = kEscapeSlack * (allow + std::fabs(top)) + 1e-12 * scale;
  // Written so that a state that is not finite escapes (its renewal then reports it). At the
  // anchor's own step the state is the anchor's, exactly: no rounding to allow for. Later, it
  // passes only with room to spare for the rounding of dist and speed.
  if (t == 0.0) return !(dist <= allow && speed <= top);
  return !(dist + tol <= allow && speed + tol <= top);
}

// Whether sphere s's state, t seconds after its anchor, proves its bounds broken since then: with
// the bounds kept, its centre stays within min((s0 + delta) t + A t^2 / 2, V t) of the anchor and
// its measured speed below min(s0 + 2 delta + A t, V + delta) (the true speed within delta of
// both measurements); a state beyond either by more than rounding broke them.
bool Breaks(const dua_reach& r, int64_t s, const double* c, const double* v, double t) {
  const double s0 = r.speed0[s], a = r.accel[s], d = r.delta[s], vmax = r.speed[s];
  const double free = (s0 + d) * t + 0.5 * a * t * t;
  // With no speed bound V t is inf and never replaces the free-motion allowance.
  const double allow = vmax * t < free ? vmax * t : free;
  const double top = std::min(s0 + 2.0 * d + a * t, vmax + d);
  const double* o = r.anchor + 3 * s;
  const double dx = c[0] - o[0], dy = c[1] - o[1], dz = c[2] - o[2];
  const double dist = std::sqrt(dx * dx + dy * dy + dz * dz);
  const double speed = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  const double scale = std::max({1.0, std::fabs(o[0]), std::fabs(o[1]), std::fabs(o[2])});
  const double tol = kEscapeSlack * (allow + top) + 2e-12 * scale;
  return !(dist <= allow + tol && speed <= top + tol);
}

double Reach(double radius, double speed, double accel, double delta, double vmax, double t) {
  const double free = (speed + delta) * t + 0.5 * accel * (t * t);
  // inf * 0 is NaN: with no speed bound (or T = 0) the free-motion bound is the answer.
  return radius + (std::isinf(vmax) ? free : std::min(free, vmax * t));
}

}  // namespace
}  // namespace dua

extern "C" {

int64_t dua_escapes(const dua_reach* r, const int64_t* ids, int64_t n, const double* centers,
                    const double* velocities, const double* elapsed, int64_t* out) {
  int64_t count = 0;
  for (int64_t k = 0; k < n; ++k) {
    if (dua::Escapes(*r, ids[k], centers + 3 * k, velocities + 3 * k, elapsed[k])) {
      out[count++] = ids[k];
    }
  }
  return count;
}

int64_t dua_escaped_spheres(const dua_step_args* a, const dua_reach* r, int64_t step,
                            int64_t* out) {
  int64_t count = 0;
  const double* c = a->points.centers;
  if (c) {
    // Free spheres: no violation check flags them, so the escape test is theirs, every step
    // (their states read in place: this loop is most of a large free step).
    const double* v = a->points.velocities;
    for (int64_t s = 0; s < r->nsphere; ++s) {
      const double t = static_cast<double>(step - r->built[s]) * r->dt;
      if (dua::Escapes(*r, s, c + 3 * s, v + 3 * s, t)) out[count++] = s;
    }
    return count;
  }
  const dua_events& ev = a->events;
  const int64_t flagged = ev.nbody ? ev.meta[dua::kMCount] : 0;
  double state[6];
  for (int64_t k = 0; k < flagged; ++k) {
    const double* rec = ev.rec + ev.flagged[k] * dua::kBNcol;
    const auto body = static_cast<int64_t>(rec[dua::kBBody]);
    for (int64_t m = r->body_start[body]; m < r->body_start[body + 1]; ++m) {
      const int64_t s = r->body_spheres[m];
      dua_rigid_point(s, a->spheres, &a->frame, state);
      const double t = static_cast<double>(step - r->built[s]) * r->dt;
      if (dua::Escapes(*r, s, state, state + 3, t)) out[count++] = s;
    }
  }
  return count;
}

int64_t dua_proven_broken(const dua_step_args* a, const dua_reach* r, const int64_t* ids, int64_t n,
                          int64_t step) {
  double state[6];
  for (int64_t k = 0; k < n; ++k) {
    dua_point(a, ids[k], state);
    const double t = static_cast<double>(step - r->built[ids[k]]) * r->dt;
    if (dua::Breaks(*r, ids[k], state, state + 3, t)) return ids[k];
  }
  return -1;
}

void dua_reaches(const double* radius, const double* speed, const double* accel,
                 const double* delta, const double* vmax, int64_t n, double horizon, double* out) {
  for (int64_t i = 0; i < n; ++i) {
    out[i] = dua::Reach(radius[i], speed[i], accel[i], delta[i], vmax[i], horizon);
  }
}

int64_t dua_renew(const dua_step_args* a, dua_reach* r, const int64_t* ids, int64_t n, int64_t step,
                  int64_t* out, int64_t capacity) {
  std::vector<double> states(static_cast<size_t>(6 * n));
  for (int64_t k = 0; k < n; ++k) {
    double* x = states.data() + 6 * k;
    dua_point(a, ids[k], x);
    for (int c = 0; c < 6; ++c) {
      if (!std::isfinite(x[c])) return -1 - k;
    }
  }
  for (int64_t k = 0; k < n; ++k) {
    const int64_t s = ids[k];
    const double* x = states.data() + 6 * k;
    for (int c = 0; c < 3; ++c) r->anchor[3 * s + c] = x[c];
    const double s0 = std::sqrt(x[3] * x[3] + x[4] * x[4] + x[5] * x[5]);
    r->speed0[s] = s0;
    r->reach[s] = dua::Reach(r->radius[s], s0, r->accel[s], r->delta[s], r->speed[s], r->horizon);
    r->built[s] = step;
  }
  return dua_reach_pairs(r, ids, n, out, capacity);
}

int64_t dua_reach_pairs(const dua_reach* r, const int64_t* ids, int64_t n, int64_t* out,
                        int64_t capacity) {
  // A pair of two listed spheres is reported from its smaller member only.
  std::vector<uint8_t> listed(static_cast<size_t>(r->nsphere), 0);
  for (int64_t k = 0; k < n; ++k) listed[static_cast<size_t>(ids[k])] = 1;
  const double m = r->margin;
  int64_t count = 0;
  for (int64_t k = 0; k < n; ++k) {
    const int64_t i = ids[k];
    if (listed[static_cast<size_t>(i)] == 2) continue;  // listed twice
    listed[static_cast<size_t>(i)] = 2;
    const double* ci = r->anchor + 3 * i;
    const double xi = ci[0], yi = ci[1], zi = ci[2], ri = r->reach[i];
    for (int64_t j = 0; j < r->nsphere; ++j) {
      if (j == i || (listed[static_cast<size_t>(j)] && j < i)) continue;
      const double* cj = r->anchor + 3 * j;
      // The grid's test, operation for operation (grid.cc's contract).
      const double dx = xi - cj[0], dy = yi - cj[1], dz = zi - cj[2];
      const double s = (ri + r->reach[j]) + m;
      if (dx * dx + dy * dy + dz * dz <= s * s * dua::kRoundingSlack) {
        if (count < capacity) {
          out[2 * count] = std::min(i, j);
          out[2 * count + 1] = std::max(i, j);
        }
        ++count;
      }
    }
  }
  return count;
}

}  // extern "C"
