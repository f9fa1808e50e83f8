// The shield's brake (brake.h).
#include "brake.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "internal.h"

namespace dua {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

const char* DynName(int v) {
  switch (v) {
    case mjDYN_NONE:
      return "none";
    case mjDYN_INTEGRATOR:
      return "integrator";
    case mjDYN_FILTER:
      return "filter";
    case mjDYN_FILTEREXACT:
      return "filterexact";
    case mjDYN_MUSCLE:
      return "muscle";
    default:
      return "user";
  }
}

const char* GainName(int v) {
  switch (v) {
    case mjGAIN_FIXED:
      return "fixed";
    case mjGAIN_AFFINE:
      return "affine";
    case mjGAIN_MUSCLE:
      return "muscle";
    default:
      return "user";
  }
}

const char* BiasName(int v) {
  switch (v) {
    case mjBIAS_NONE:
      return "none";
    case mjBIAS_AFFINE:
      return "affine";
    case mjBIAS_MUSCLE:
      return "muscle";
    default:
      return "user";
  }
}

}  // namespace

std::unique_ptr<Brake> Brake::Make(const mjModel* m, const std::vector<int>& actuators,
                                   double time_constant, std::string* error) {
  if (actuators.empty()) {
    *error = "the brake needs at least one actuator";
    return nullptr;
  }
  std::vector<uint8_t> seen(m->nu, 0);
  for (const int a : actuators) {
    if (a < 0 || a >= m->nu) {
      *error = "actuator id " + std::to_string(a) + " is out of range: the model has " +
               std::to_string(m->nu) + " actuators";
      return nullptr;
    }
    if (seen[a]++) {
      *error = "actuator id " + std::to_string(a) + " is given twice";
      return nullptr;
    }
  }
  if (!(time_constant > 0.0) || !std::isfinite(time_constant)) {
    *error = "time_constant must be a positive number of seconds, not " + Shown(time_constant);
    return nullptr;
  }
  std::string bad;
  for (const int a : actuators) {
    const int dyn = m->actuator_dyntype[a], gain = m->actuator_gaintype[a];
    const int bias = m->actuator_biastype[a];
    if (dyn == mjDYN_NONE && (gain == mjGAIN_FIXED || gain == mjGAIN_AFFINE) &&
        (bias == mjBIAS_NONE || bias == mjBIAS_AFFINE) && m->actuator_plugin[a] < 0) {
      continue;
    }
    const char* name = mj_id2name(m, mjOBJ_ACTUATOR, a);
    if (!bad.empty()) bad += "; ";
    bad += (name && *name ? std::string(name) : "actuator " + std::to_string(a)) + " (dyntype " +
           DynName(dyn) + ", gaintype " + GainName(gain) + ", biastype " + BiasName(bias) +
           (m->actuator_plugin[a] >= 0 ? ", a plugin" : "") + ")";
  }
  if (!bad.empty()) {
    *error =
        "the brake needs actuators whose force is affine in this step's control (dyntype none, "
        "gaintype fixed or affine, biastype none or affine: motor, position and velocity without "
        "timeconst, general of those types); not: " +
        bad + ". Give the shield a failsafe policy of your own for these";
    return nullptr;
  }
  std::unique_ptr<Brake> b(new Brake());
  b->acts_ = actuators;
  b->tc_ = time_constant;
  // The trees the actuators move, from their moment arms at qpos0.
  mjData* d = mj_makeData(m);
  if (!d) {
    *error = "MuJoCo could not allocate an mjData";
    return nullptr;
  }
  mj_kinematics(m, d);
  mj_comPos(m, d);
  mj_tendon(m, d);
  mj_transmission(m, d);
  std::vector<uint8_t> tree(m->ntree + 1, 0);
  for (const int a : actuators) {
    for (int k = d->moment_rowadr[a]; k < d->moment_rowadr[a] + d->moment_rownnz[a]; ++k) {
      if (d->actuator_moment[k] != 0.0) tree[m->dof_treeid[d->moment_colind[k]]] = 1;
    }
  }
  mj_deleteData(d);
  b->dof_index_.assign(m->nv, -1);
  for (int i = 0; i < m->nv; ++i) {
    if (tree[m->dof_treeid[i]]) {
      b->dof_index_[i] = static_cast<int>(b->dofs_.size());
      b->dofs_.push_back(i);
    }
  }
  for (int i = 0; i < m->nbody; ++i) {
    if (m->body_treeid[i] >= 0 && tree[m->body_treeid[i]]) b->bodies_.push_back(i);
  }
  if (b->dofs_.empty()) {
    *error = "the actuators move no degree of freedom (their moment arms are 0 at qpos0)";
    return nullptr;
  }
  for (const int i : b->dofs_) {
    const int j = m->dof_jntid[i];
    const bool limited = m->jnt_actfrclimited[j];
    b->tau_lo_.push_back(limited ? m->jnt_actfrcrange[2 * j] : -kInf);
    b->tau_hi_.push_back(limited ? m->jnt_actfrcrange[2 * j + 1] : kInf);
  }
  if (m->opt.integrator == mjINT_EULER) {
    b->implicit_ = (m->opt.disableflags & mjDSBL_EULERDAMP) ? 0 : 1;
  } else if (m->opt.integrator == mjINT_IMPLICIT || m->opt.integrator == mjINT_IMPLICITFAST) {
    b->implicit_ = 2;
  }
  const size_t nd = b->dofs_.size(), na = actuators.size();
  b->full_m_.resize(static_cast<size_t>(m->nv) * m->nv);
  b->all_moment_.resize(static_cast<size_t>(m->nu) * nd);
  b->k_.resize(nd * nd);
  b->kinv_b_.resize(nd * na);
  b->h_.resize(na * na);
  b->qp_h_.resize(na * na);
  b->r_.resize(na * (na + 7));
  for (auto* v : {&b->g_, &b->force_, &b->lo_, &b->hi_, &b->gain_, &b->bias_, &b->clo_, &b->chi_,
                  &b->g_free_, &b->lo_free_, &b->hi_free_, &b->x_free_}) {
    v->resize(na);
  }
  b->tau_.resize(nd);
  b->free_.resize(na);
  b->moves_.resize(m->nu);
  return b;
}

void Brake::Prepare(const mjModel* m, mjData* d) {
  mj_kinematics(m, d);
  mj_comPos(m, d);
  mj_tendon(m, d);
  mj_makeM(m, d);
  mj_transmission(m, d);
  // The actuator and tendon velocities, cvel, the passive forces and qfrc_bias (with the tendon
  // armature's): what mj_step1 computes. d's constraint rows are its own (none unless d made
  // them), so the constraint references it also computes read nothing.
  mj_fwdVelocity(m, d);
}

void Brake::Compute(const mjModel* m, const mjData* d, const double* target, double* ctrl) {
  const int nv = m->nv, nu = m->nu;
  const int nd = static_cast<int>(dofs_.size()), na = static_cast<int>(acts_.size());
  const double h = m->opt.timestep;
  mj_fullM(m, d, full_m_.data());
  for (int i = 0; i < nd; ++i) {
    for (int j = 0; j < nd; ++j) k_[i * nd + j] = full_m_[dofs_[i] * nv + dofs_[j]];
  }
  // Every actuator's moment arms on the robot's DOFs (the implicit damping sums them all).
  std::fill(all_moment_.begin(), all_moment_.end(), 0.0);
  std::fill(moves_.begin(), moves_.end(), 0);
  for (int u = 0; u < nu; ++u) {
    for (int k = d->moment_rowadr[u]; k < d->moment_rowadr[u] + d->moment_rownnz[u]; ++k) {
      const int i = dof_index_[d->moment_colind[k]];
      if (i < 0) continue;
      all_moment_[u * nd + i] = d->actuator_moment[k];
      if (d->actuator_moment[k] != 0.0) moves_[u] = 1;
    }
  }
  if (implicit_ >= 1) {
    for (int i = 0; i < nd; ++i) k_[i * nd + i] += h * m->dof_damping[dofs_[i]];
  }
  if (implicit_ == 2) {
    // -d(force)/d(qvel) of every actuator: the velocity terms of its gain and bias.
    for (int u = 0; u < nu; ++u) {
      double s = 0.0;
      if (m->actuator_biastype[u] == mjBIAS_AFFINE) s -= m->actuator_biasprm[u * mjNBIAS + 2];
      if (m->actuator_gaintype[u] == mjGAIN_AFFINE) {
        s -= m->actuator_gainprm[u * mjNGAIN + 2] * d->ctrl[u];
      }
      // An actuator of another tree (the other arm's) adds only zeros: skipped.
      if (s == 0.0 || !moves_[u]) continue;
      const double* row = all_moment_.data() + u * nd;
      for (int i = 0; i < nd; ++i) {
        for (int j = 0; j < nd; ++j) k_[i * nd + j] += h * s * row[i] * row[j];
      }
    }
  }
  // The joint forces wanted: tau = K a + bias - passive, within the joints' force ranges.
  for (int i = 0; i < nd; ++i) {
    double s = 0.0;
    for (int j = 0; j < nd; ++j) {
      const double goal = target ? target[j] : 0.0;
      s += k_[i * nd + j] * ((goal - d->qvel[dofs_[j]]) / tc_);
    }
    s += d->qfrc_bias[dofs_[i]] - d->qfrc_passive[dofs_[i]];
    tau_[i] = std::min(std::max(s, tau_lo_[i]), tau_hi_[i]);
  }
  // Each actuator's affine law and the forces its control and force ranges allow.
  const bool clamp = !(m->opt.disableflags & mjDSBL_CLAMPCTRL);
  for (int k = 0; k < na; ++k) {
    const int a = acts_[k];
    const double len = d->actuator_length[a], vel = d->actuator_velocity[a];
    const double* gp = m->actuator_gainprm + a * mjNGAIN;
    const double* bp = m->actuator_biasprm + a * mjNBIAS;
    gain_[k] = gp[0];
    if (m->actuator_gaintype[a] == mjGAIN_AFFINE) gain_[k] += gp[1] * len + gp[2] * vel;
    bias_[k] = m->actuator_biastype[a] == mjBIAS_NONE ? 0.0 : bp[0] + bp[1] * len + bp[2] * vel;
    const bool climited = clamp && m->actuator_ctrllimited[a];
    clo_[k] = climited ? m->actuator_ctrlrange[2 * a] : -kInf;
    chi_[k] = climited ? m->actuator_ctrlrange[2 * a + 1] : kInf;
    const bool flimited = m->actuator_forcelimited[a];
    const double flo = flimited ? m->actuator_forcerange[2 * a] : -kInf;
    const double fhi = flimited ? m->actuator_forcerange[2 * a + 1] : kInf;
    double e1 = gain_[k] * clo_[k] + bias_[k], e2 = gain_[k] * chi_[k] + bias_[k];
    if (std::isnan(e1)) e1 = bias_[k];  // gain 0 with an unbounded control
    if (std::isnan(e2)) e2 = bias_[k];
    lo_[k] = std::min(std::max(std::min(e1, e2), flo), fhi);
    hi_[k] = std::min(std::max(std::max(e1, e2), flo), fhi);
  }
  // The least squares in the metric K^-1: H = B K^-1 B^T, g = -B K^-1 tau, B the robot's
  // actuators' moment arms (na x nd).
  mju_cholFactor(k_.data(), nd, mjMINVAL);
  for (int k = 0; k < na; ++k) {
    mju_cholSolve(kinv_b_.data() + k * nd, k_.data(), all_moment_.data() + acts_[k] * nd, nd);
  }
  for (int k = 0; k < na; ++k) {
    const double* bk = all_moment_.data() + acts_[k] * nd;
    for (int l = 0; l < na; ++l) h_[k * na + l] = mju_dot(bk, kinv_b_.data() + l * nd, nd);
    g_[k] = -mju_dot(kinv_b_.data() + k * nd, tau_.data(), nd);
  }
  // Forces with a single allowed value are fixed; the others solve the box QP on their own.
  int nfree = 0;
  for (int k = 0; k < na; ++k) {
    force_[k] = std::min(std::max(0.0, lo_[k]), hi_[k]);
    if (lo_[k] < hi_[k]) free_[nfree++] = k;
  }
  if (nfree > 0) {
    // The free forces' QP, in the workspace (nfree <= na): Compute runs every physics step.
    double *hf = qp_h_.data(), *gf = g_free_.data(), *lf = lo_free_.data();
    double *uf = hi_free_.data(), *xf = x_free_.data();
    for (int i = 0; i < nfree; ++i) {
      const int p = free_[i];
      gf[i] = g_[p];
      for (int k = 0; k < na; ++k) {
        if (!(lo_[k] < hi_[k])) gf[i] += h_[p * na + k] * force_[k];
      }
      for (int j = 0; j < nfree; ++j) hf[i * nfree + j] = h_[p * na + free_[j]];
      lf[i] = lo_[p], uf[i] = hi_[p], xf[i] = force_[p];
    }
    // Actuators that act alike (two on one joint) make H singular: a ridge far below its scale
    // picks one of the equally good answers.
    if (mju_boxQP(xf, r_.data(), nullptr, hf, gf, nfree, lf, uf) < 0) {
      double top = 0.0;
      for (int i = 0; i < nfree; ++i) top = std::max(top, hf[i * nfree + i]);
      for (int i = 0; i < nfree; ++i) {
        hf[i * nfree + i] += 1e-12 * top + mjMINVAL;
        xf[i] = force_[free_[i]];
      }
      mju_boxQP(xf, r_.data(), nullptr, hf, gf, nfree, lf, uf);
    }
    for (int i = 0; i < nfree; ++i) force_[free_[i]] = xf[i];
  }
  std::copy_n(d->ctrl, nu, ctrl);
  for (int k = 0; k < na; ++k) {
    const int a = acts_[k];
    const double want = gain_[k] != 0.0 ? (force_[k] - bias_[k]) / gain_[k] : d->ctrl[a];
    ctrl[a] = std::min(std::max(want, clo_[k]), chi_[k]);
  }
}

std::unique_ptr<Evade> Evade::Make(const mjModel* m, std::unique_ptr<Brake> brake, int x, int y,
                                   const std::vector<int>& obstacles,
                                   const std::vector<double>& radius,
                                   const std::vector<double>& room, double gain, double still,
                                   bool sideways, std::string* error) {
  const std::vector<int>& dofs = brake->dofs();
  const auto slot = [&](int i) {
    const auto it = std::find(dofs.begin(), dofs.end(), i);
    return it == dofs.end() ? -1 : static_cast<int>(it - dofs.begin());
  };
  const auto slide = [&](int i) {
    return i >= 0 && i < m->nv && m->jnt_type[m->dof_jntid[i]] == mjJNT_SLIDE && slot(i) >= 0;
  };
  if (!slide(x) || !slide(y) || x == y) {
    *error = "the evasive failsafe needs two distinct slide DOFs of the robot (x, y), not " +
             std::to_string(x) + ", " + std::to_string(y);
  } else if (obstacles.size() != radius.size()) {
    *error = "obstacles and radius must have the same length, not " +
             std::to_string(obstacles.size()) + " and " + std::to_string(radius.size());
  } else if (!(room.empty() || room.size() == 4)) {
    *error =
        "room must be none or (xlo, xhi, ylo, yhi), not " + std::to_string(room.size()) + " values";
  } else if (!room.empty() && !(room[0] < room[1] && room[2] < room[3])) {
    *error = "room = (" + Shown(room[0]) + ", " + Shown(room[1]) + ", " + Shown(room[2]) + ", " +
             Shown(room[3]) +
             ") is invalid: pass (xlo, xhi, ylo, yhi) with xlo < xhi and ylo < yhi (the inner "
             "faces of the walls)";
  } else if (!(gain >= 0.0 && gain < 1.0)) {
    *error = "gain must be in [0, 1) (1 never stops), not " + Shown(gain);
  } else if (!(still > 0.0) || !std::isfinite(still)) {
    *error = "still must be a positive finite speed (m/s), not " + Shown(still);
  }
  for (const int b : obstacles) {
    if (error->empty() && (b < 1 || b >= m->nbody)) {
      *error = "obstacle body id " + std::to_string(b) + " is out of range";
    }
  }
  for (const double r : radius) {
    if (error->empty() && (!(r >= 0.0) || !std::isfinite(r))) {
      *error = "an obstacle's radius must be a finite distance >= 0, not " + Shown(r);
    }
  }
  for (const double w : room) {
    if (error->empty() && !std::isfinite(w)) *error = "room must be finite, not " + Shown(w);
  }
  if (!error->empty()) return nullptr;
  std::unique_ptr<Evade> e(new Evade());
  e->x_ = x, e->y_ = y;
  e->xq_ = m->jnt_qposadr[m->dof_jntid[x]], e->yq_ = m->jnt_qposadr[m->dof_jntid[y]];
  e->xi_ = slot(x), e->yi_ = slot(y);
  e->obstacles_ = obstacles, e->radius_ = radius, e->room_ = room;
  e->gain_ = gain, e->still_ = still, e->sideways_ = sideways;
  e->target_.assign(dofs.size(), 0.0);
  e->brake_ = std::move(brake);
  return e;
}

void Evade::Away(const mjData* d, double x, double y, double* ux, double* uy) const {
  // tests/reference_evade.py's law, in its order of operations (the same doubles).
  double px = 0.0, py = 0.0;
  for (size_t k = 0; k < obstacles_.size(); ++k) {
    const double* o = d->xpos + 3 * obstacles_[k];
    const double gx = x - o[0], gy = y - o[1];
    const double dist = std::sqrt(gx * gx + gy * gy);
    if (dist == 0.0) continue;
    const double clear = std::max(dist - radius_[k], 0.05);
    const double w = 1.0 / (dist * clear * clear);
    px = px + gx * w, py = py + gy * w;
  }
  if (!room_.empty()) {
    const double w = std::max(x - room_[0], 0.05), e = std::max(room_[1] - x, 0.05);
    const double s = std::max(y - room_[2], 0.05), n = std::max(room_[3] - y, 0.05);
    px += 1.0 / (w * w) - 1.0 / (e * e);
    py += 1.0 / (s * s) - 1.0 / (n * n);
  }
  const double top = std::max(std::fabs(px), std::fabs(py));
  *ux = top > 0.0 ? px / top : 0.0;
  *uy = top > 0.0 ? py / top : 0.0;
}

void Evade::Compute(const mjModel* m, const mjData* d, double* ctrl) {
  const double vx = d->qvel[x_], vy = d->qvel[y_];
  const double s = std::max(std::fabs(vx), std::fabs(vy));
  if (s <= still_) {
    brake_->Compute(m, d, nullptr, ctrl);
    return;
  }
  double ux, uy;
  Away(d, d->qpos[xq_], d->qpos[yq_], &ux, &uy);
  if (sideways_) {
    // Across the velocity (s > still > 0: it has a direction), to the side u points to.
    const double norm = std::sqrt(vx * vx + vy * vy);
    double qx = -vy / norm, qy = vx / norm;
    if (qx * ux + qy * uy < 0.0) qx = -qx, qy = -qy;
    const double top = std::max(std::fabs(qx), std::fabs(qy));
    ux = qx / top, uy = qy / top;
  }
  target_[xi_] = gain_ * s * ux;
  target_[yi_] = gain_ * s * uy;
  brake_->Compute(m, d, target_.data(), ctrl);
}

}  // namespace dua
