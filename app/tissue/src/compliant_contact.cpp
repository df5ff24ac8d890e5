#include "vh/tissue/compliant_contact.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "vh/tissue/hex_element.h"

namespace vh::tissue {

CompliantContact::CompliantContact(const HexLattice& lattice, const SurfaceCompliance& compliance, int max_contacts)
    : lattice_(lattice), compliance_(compliance), capacity_(max_contacts) {
  if (max_contacts < 1) throw std::invalid_argument("compliant contact: the capacity must be >= 1");
  const auto m = static_cast<Eigen::Index>(max_contacts);
  lambda_ = Eigen::VectorXd::Zero(m);
  gap_ = Eigen::VectorXd::Zero(m);
  A_ = Eigen::MatrixXd::Zero(m, m);
  P_values_ = Eigen::MatrixXd::Zero(m, 24);
  P_columns_ = Eigen::MatrixXi::Constant(m, 24, -1);
  gathered_.reserve(static_cast<std::size_t>(8 * max_contacts));
  slot_of_.assign(static_cast<std::size_t>(compliance.nodeCount()), -1);
  T_ = Eigen::MatrixXd::Zero(24 * m, m);
}

CompliantContactResult CompliantContact::solve(std::span<const TissueContactPoint> contacts, double k, int max_sweeps,
                                               double tolerance_m) noexcept {
  CompliantContactResult r;
  if (!(k > 0.0) || !std::isfinite(k)) return r;
  const int m = static_cast<int>(std::min<std::size_t>(contacts.size(), static_cast<std::size_t>(capacity_)));
  for (int i = 0; i < m; ++i) {
    const TissueContactPoint& c = contacts[static_cast<std::size_t>(i)];
    if (!c.X_G_m.allFinite() || !c.n_G.allFinite() || !std::isfinite(c.gap_m)) return r;
  }
  for (const int s : gathered_) slot_of_[static_cast<std::size_t>(s)] = -1;
  gathered_.clear();
  // P: each contact's 24 corner dofs with their weights N_a n_i(c).
  for (int i = 0; i < m; ++i) {
    const TissueContactPoint& c = contacts[static_cast<std::size_t>(i)];
    gap_(i) = c.gap_m;
    P_columns_.row(i).setConstant(-1);
    const HexLattice::Location at = lattice_.locate(c.X_G_m);
    if (at.element < 0) {
      ++r.rigid_points;
      continue;
    }
    const Eigen::Matrix<double, 8, 1> N = hexShapeFunctions(at.xi);
    bool all_touchable = true;
    for (int a = 0; a < 8; ++a) {
      const int s = compliance_.indexOf(lattice_.elementNodes(at.element)[static_cast<std::size_t>(a)]);
      if (s < 0) {
        all_touchable = false;
        continue;
      }
      int& slot = slot_of_[static_cast<std::size_t>(s)];
      if (slot < 0) {
        slot = static_cast<int>(gathered_.size());
        gathered_.push_back(s);
      }
      for (int d = 0; d < 3; ++d) {
        P_columns_(i, 3 * a + d) = 3 * slot + d;
        P_values_(i, 3 * a + d) = N(a) * c.n_G(d);
      }
    }
    if (!all_touchable) ++r.rigid_points;
  }
  // T = C P^T over the gathered dofs, then W = P T; A = W + N^T N / k.
  const int g = static_cast<int>(gathered_.size());
  // Column by column of the table (contiguous reads), accumulated into T's column i.
  for (int i = 0; i < m; ++i) {
    double* t = T_.col(i).data();
    std::fill(t, t + 3 * g, 0.0);
    for (int l = 0; l < 24; ++l) {
      const int col = P_columns_(i, l);
      if (col < 0) continue;
      const double weight = P_values_(i, l);
      const float* column = compliance_.column(3 * gathered_[static_cast<std::size_t>(col / 3)] + col % 3);
      for (int slot = 0; slot < g; ++slot) {
        const float* c = column + 3 * gathered_[static_cast<std::size_t>(slot)];
        t[3 * slot] += weight * c[0];
        t[3 * slot + 1] += weight * c[1];
        t[3 * slot + 2] += weight * c[2];
      }
    }
  }
  for (int i = 0; i < m; ++i)
    for (int j = 0; j <= i; ++j) {
      double w = 0.0;
      for (int l = 0; l < 24; ++l) {
        const int row = P_columns_(i, l);
        if (row >= 0) w += P_values_(i, l) * T_(row, j);
      }
      const double a = w + contacts[static_cast<std::size_t>(i)].n_G.dot(contacts[static_cast<std::size_t>(j)].n_G) / k;
      A_(i, j) = a;
      A_(j, i) = a;
    }
  // Projected Gauss-Seidel from the caller's guess (deterministic: a replay gives the same guesses).
  for (int i = 0; i < m; ++i) lambda_(i) = std::max(0.0, contacts[static_cast<std::size_t>(i)].push_guess_N);
  r.contacts = m;
  for (int sweep = 0; sweep < max_sweeps; ++sweep) {
    double violation = 0.0;
    for (int i = 0; i < m; ++i) {
      double residual = gap_(i);
      for (int j = 0; j < m; ++j) residual += A_(i, j) * lambda_(j);
      const double updated = std::max(0.0, lambda_(i) - residual / A_(i, i));
      violation = std::max(violation, std::abs(updated - lambda_(i)) * A_(i, i));
      lambda_(i) = updated;
    }
    r.sweeps = sweep + 1;
    r.max_violation_m = violation;
    if (violation < tolerance_m) break;
  }
  Eigen::Vector3d mean_normal = Eigen::Vector3d::Zero();
  for (int i = 0; i < m; ++i) {
    r.force_on_device_N += lambda_(i) * contacts[static_cast<std::size_t>(i)].n_G;
    mean_normal += contacts[static_cast<std::size_t>(i)].n_G;
  }
  r.proxy_offset_m = r.force_on_device_N / k;
  // What the sweeps left inside: move the proxy out along the mean normal until every point with
  // a positive component along it is clear (the tissue's pushes unchanged).
  if (m > 0 && mean_normal.norm() > 0.0) {
    const Eigen::Vector3d d = mean_normal.normalized();
    double out = 0.0;
    for (int i = 0; i < m; ++i) {
      double w = gap_(i);
      for (int j = 0; j < m; ++j) w += A_(i, j) * lambda_(j);
      const double along = contacts[static_cast<std::size_t>(i)].n_G.dot(d);
      if (w < 0.0 && along > 1e-6) out = std::max(out, -w / along);
    }
    r.projected_m = out;
    r.proxy_offset_m += out * d;
    r.force_on_device_N += k * out * d;
  }
  return r;
}

Eigen::VectorXd CompliantContact::nodalForces_N(std::span<const TissueContactPoint> contacts) const {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(lattice_.dofCount());
  const int m = static_cast<int>(std::min<std::size_t>(contacts.size(), static_cast<std::size_t>(capacity_)));
  for (int i = 0; i < m; ++i) {
    const TissueContactPoint& c = contacts[static_cast<std::size_t>(i)];
    const HexLattice::Location at = lattice_.locate(c.X_G_m);
    if (at.element < 0) continue;
    const Eigen::Matrix<double, 8, 1> N = hexShapeFunctions(at.xi);
    for (int a = 0; a < 8; ++a)
      f.segment<3>(3 * lattice_.elementNodes(at.element)[static_cast<std::size_t>(a)]) -= lambda_(i) * N(a) * c.n_G;
  }
  return f;
}

}  // namespace vh::tissue
