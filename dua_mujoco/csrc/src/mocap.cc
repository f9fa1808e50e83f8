// Velocities of mocap bodies, which mjData does not give: backward differences of their poses
// (dua_mujoco/build/mocap.py documents the instant and the bound this velocity obeys).
#include "mocap.h"

#include <algorithm>
#include <cmath>

#include "dua/dua.h"
#include "lanes.h"

extern "C" {

void dua_difference_poses(const double* xpos, const double* xquat, const int64_t* bodies, int64_t n,
                          double* prev_pos, double* prev_quat, double dt, const uint8_t* user,
                          double* linear, double* angular, double* twist, int64_t ntwist) {
  for (int64_t i = 0; i < n; ++i) {
    const int64_t b = bodies[i];
    const double* q = xquat + 4 * b;
    double* pq = prev_quat + 4 * i;
    // q_now * conj(q_prev), taken the short way round: its rotation vector over dt.
    const double aw = q[0], ax = q[1], ay = q[2], az = q[3];
    const double bw = pq[0], bx = -pq[1], by = -pq[2], bz = -pq[3];
    double w = aw * bw - ax * bx - ay * by - az * bz;
    double x = aw * bx + ax * bw + ay * bz - az * by;
    double y = aw * by - ax * bz + ay * bw + az * bx;
    double z = aw * bz + ax * by - ay * bx + az * bw;
    if (w < 0.0) w = -w, x = -x, y = -y, z = -z;
    const double s = std::sqrt(x * x + y * y + z * z);
    const double scale = s > 1e-12 ? 2.0 * std::atan2(s, w) / s : 2.0;
    if (!user[i]) {
      for (int k = 0; k < 3; ++k) linear[3 * i + k] = (xpos[3 * b + k] - prev_pos[3 * i + k]) / dt;
      angular[3 * i] = x * scale / dt;
      angular[3 * i + 1] = y * scale / dt;
      angular[3 * i + 2] = z * scale / dt;
    }
    for (int k = 0; k < 3; ++k) prev_pos[3 * i + k] = xpos[3 * b + k];
    for (int k = 0; k < 4; ++k) pq[k] = q[k];
    if (ntwist > 0) {
      for (int k = 0; k < 3; ++k) {
        twist[6 * b + k] = angular[3 * i + k];
        twist[6 * b + 3 + k] = linear[3 * i + k];
      }
    }
  }
}

}  // extern "C"

namespace dua {

Mocap::Mocap(const mjModel* m) {
  if (!m) return;  // free spheres: no model, no mocap bodies
  bodies.assign(m->nmocap, -1);
  pos.assign(3 * static_cast<size_t>(m->nmocap), 0.0);
  quat.assign(4 * static_cast<size_t>(m->nmocap), 0.0);
  linear.assign(3 * static_cast<size_t>(m->nmocap), 0.0);
  angular.assign(3 * static_cast<size_t>(m->nmocap), 0.0);
  twist.assign(6 * static_cast<size_t>(m->nbody), 0.0);
  user.assign(m->nmocap, 0);
  for (int b = 0; b < m->nbody; ++b) {
    if (m->body_mocapid[b] >= 0) bodies[m->body_mocapid[b]] = b;
  }
}

void Mocap::WriteTwist() {
  for (size_t i = 0; i < bodies.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      twist[6 * bodies[i] + k] = angular[3 * i + k];
      twist[6 * bodies[i] + 3 + k] = linear[3 * i + k];
    }
  }
}

void Mocap::Start(const mjData* d) {
  for (size_t i = 0; i < bodies.size(); ++i) {
    const int64_t b = bodies[i];
    std::copy(d->xpos + 3 * b, d->xpos + 3 * b + 3, pos.begin() + 3 * i);
    std::copy(d->xquat + 4 * b, d->xquat + 4 * b + 4, quat.begin() + 4 * i);
  }
  Forget();
  updates = 1;
  time = d->time;
}

DUA_HOT void Mocap::Difference(const mjData* d, double elapsed) {
  time = d->time;
  if (bodies.empty()) return;
  dua_difference_poses(d->xpos, d->xquat, bodies.data(), static_cast<int64_t>(bodies.size()),
                       pos.data(), quat.data(), elapsed, user.data(), linear.data(), angular.data(),
                       twist.data(), static_cast<int64_t>(twist.size() / 6));
  ++updates;
}

void Mocap::Update(const mjData* d) {
  if (updates == 0) {
    Start(d);
  } else if (d->time - time > 0.0) {
    Difference(d, d->time - time);
  }
}

void Mocap::Forget() {
  for (size_t i = 0; i < user.size(); ++i) {
    if (!user[i]) {
      std::fill_n(linear.begin() + 3 * i, 3, 0.0);
      std::fill_n(angular.begin() + 3 * i, 3, 0.0);
    }
  }
  WriteTwist();
  updates = 0;
}

void Mocap::Set(int64_t i, const double lin[3], const double ang[3]) {
  std::copy(lin, lin + 3, linear.begin() + 3 * i);
  std::copy(ang, ang + 3, angular.begin() + 3 * i);
  user[i] = 1;
  WriteTwist();
}

}  // namespace dua
