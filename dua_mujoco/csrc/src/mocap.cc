// Velocities of mocap bodies, which mjData does not give: backward differences of their poses
// (dua_mujoco/build/mocap.py documents the instant and the bound this velocity obeys).
#include <cmath>

#include "dua/dua.h"

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
