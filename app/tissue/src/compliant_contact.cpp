#include "vh/tissue/compliant_contact.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "vh/tissue/hex_element.h"

namespace vh::tissue {

CompliantContact::CompliantContact(const HexLattice& lattice, const SurfaceCompliance& compliance, int max_contacts,
                                   int max_nodes)
    : lattice_(lattice), compliance_(compliance), capacity_(max_contacts), max_nodes_(max_nodes) {
  if (max_contacts < 1) throw std::invalid_argument("compliant contact: the capacity must be >= 1");
  if (max_nodes < 8) throw std::invalid_argument("compliant contact: at least 8 corner nodes a tick");
  const auto m = static_cast<Eigen::Index>(max_contacts);
  const auto dofs = static_cast<Eigen::Index>(3 * max_nodes);
  lambda_ = Eigen::VectorXd::Zero(m);
  gap_ = Eigen::VectorXd::Zero(m);
  diagonal_ = Eigen::VectorXd::Zero(m);
  normals_ = Eigen::Matrix3Xd::Zero(3, m);
  P_values_ = Eigen::MatrixXd::Zero(m, 24);
  P_columns_ = Eigen::MatrixXi::Constant(m, 24, -1);
  gathered_.reserve(static_cast<std::size_t>(max_nodes));
  prev_gathered_.reserve(static_cast<std::size_t>(max_nodes));
  slot_of_.assign(static_cast<std::size_t>(compliance.nodeCount()), -1);
  prev_slot_of_.assign(static_cast<std::size_t>(compliance.nodeCount()), -1);
  C_ = Eigen::MatrixXd::Zero(dofs, dofs);
  C_prev_ = Eigen::MatrixXd::Zero(dofs, dofs);
  T_ = Eigen::MatrixXd::Zero(dofs, m);
  y_ = Eigen::VectorXd::Zero(dofs);
  f_ = Eigen::VectorXd::Zero(dofs);
}

CompliantContactResult CompliantContact::solve(std::span<const TissueContactPoint> contacts, double k, int max_sweeps,
                                               double tolerance_m) noexcept {
  CompliantContactResult r;
  f_.setZero();  // no pushes until this solve gives them
  if (!(k > 0.0) || !std::isfinite(k)) return r;
  const int m = static_cast<int>(std::min<std::size_t>(contacts.size(), static_cast<std::size_t>(capacity_)));
  for (int i = 0; i < m; ++i) {
    const TissueContactPoint& c = contacts[static_cast<std::size_t>(i)];
    if (!c.X_G_m.allFinite() || !c.n_G.allFinite() || !std::isfinite(c.gap_m) || !std::isfinite(c.push_guess_N)) return r;
  }
  for (const int s : gathered_) slot_of_[static_cast<std::size_t>(s)] = -1;
  // The last solve's nodes and block become the previous ones (swaps: no copy, no allocation).
  gathered_.swap(prev_gathered_);
  C_.swap(C_prev_);
  gathered_.clear();
  // P: each contact's nonzero corner weights N_a(X_i) n_i(c) (12 on a cell face, 24 inside).
  for (int i = 0; i < m; ++i) {
    const TissueContactPoint& c = contacts[static_cast<std::size_t>(i)];
    gap_(i) = c.gap_m;
    P_columns_.row(i).setConstant(-1);
    const double length = c.n_G.norm();
    normals_.col(i) = length > 1e-9 ? Eigen::Vector3d(c.n_G / length) : Eigen::Vector3d::Zero();
    if (length <= 1e-9) {  // no direction to push along: not a contact
      ++r.ignored_points;
      continue;
    }
    const Eigen::Vector3d n = normals_.col(i);
    const HexLattice::Location at = lattice_.locate(c.X_G_m);
    if (at.element < 0) {
      ++r.rigid_points;
      continue;
    }
    const Eigen::Matrix<double, 8, 1> N = hexShapeFunctions(at.xi);
    // The corners' table positions, and room for the new ones.
    int positions[8];
    int new_nodes = 0;
    for (int a = 0; a < 8; ++a) {
      positions[a] = N(a) == 0.0 ? -2 : compliance_.indexOf(lattice_.elementNodes(at.element)[static_cast<std::size_t>(a)]);
      if (positions[a] >= 0 && slot_of_[static_cast<std::size_t>(positions[a])] < 0) ++new_nodes;
    }
    if (static_cast<int>(gathered_.size()) + new_nodes > max_nodes_) {
      ++r.rigid_points;
      continue;
    }
    int entries = 0;
    bool all_touchable = true;
    for (int a = 0; a < 8; ++a) {
      if (positions[a] == -2) continue;  // zero weight: the point is on the opposite face
      if (positions[a] < 0) {
        all_touchable = false;  // a held or untouchable corner does not yield
        continue;
      }
      int& slot = slot_of_[static_cast<std::size_t>(positions[a])];
      if (slot < 0) {
        slot = static_cast<int>(gathered_.size());
        gathered_.push_back(positions[a]);
      }
      for (int d = 0; d < 3; ++d) {
        if (n(d) == 0.0) continue;
        P_columns_(i, entries) = 3 * slot + d;
        P_values_(i, entries) = N(a) * n(d);
        ++entries;
      }
    }
    if (!all_touchable) ++r.rigid_points;
  }
  // C: the gathered block of the table, contiguous (3 g x 3 g, column-major with 3 g rows: the
  // block's columns adjacent, not a column of the workspace's full height apart, so that it
  // spans few pages and cache lines): a pair of nodes the last solve gathered too from its
  // block (the same values), the others from the table.
  const int g = static_cast<int>(gathered_.size());
  const auto ld = static_cast<std::ptrdiff_t>(3 * g);
  const auto prev_ld = static_cast<std::ptrdiff_t>(3 * prev_gathered_.size());
  for (std::size_t b = 0; b < prev_gathered_.size(); ++b)
    prev_slot_of_[static_cast<std::size_t>(prev_gathered_[b])] = static_cast<int>(b);
  for (int b = 0; b < g; ++b) {
    const int old_b = prev_slot_of_[static_cast<std::size_t>(gathered_[static_cast<std::size_t>(b)])];
    for (int cb = 0; cb < 3; ++cb) {
      const float* column = compliance_.column(3 * gathered_[static_cast<std::size_t>(b)] + cb);
      const double* old = old_b >= 0 ? C_prev_.data() + (3 * old_b + cb) * prev_ld : nullptr;
      double* out = C_.data() + (3 * b + cb) * ld;
      for (int a = 0; a < g; ++a) {
        const int old_a = old != nullptr ? prev_slot_of_[static_cast<std::size_t>(gathered_[static_cast<std::size_t>(a)])] : -1;
        if (old_a >= 0) {
          out[3 * a] = old[3 * old_a];
          out[3 * a + 1] = old[3 * old_a + 1];
          out[3 * a + 2] = old[3 * old_a + 2];
          continue;
        }
        const float* src = column + 3 * gathered_[static_cast<std::size_t>(a)];
        out[3 * a] = src[0];
        out[3 * a + 1] = src[1];
        out[3 * a + 2] = src[2];
      }
    }
  }
  for (const int s : prev_gathered_) prev_slot_of_[static_cast<std::size_t>(s)] = -1;
  // T_i = C P_i^T and the diagonal A_ii = P_i T_i + 1 / k.
  const int rows = 3 * g;
  for (int i = 0; i < m; ++i) {
    double* t = T_.data() + i * static_cast<std::ptrdiff_t>(rows);
    std::fill(t, t + rows, 0.0);
    double diagonal = normals_.col(i).squaredNorm() / k;
    for (int l = 0; l < 24 && P_columns_(i, l) >= 0; ++l) {
      const double weight = P_values_(i, l);
      const double* column = C_.data() + P_columns_(i, l) * ld;
      for (int row = 0; row < rows; ++row) t[row] += weight * column[row];
    }
    for (int l = 0; l < 24 && P_columns_(i, l) >= 0; ++l) diagonal += P_values_(i, l) * t[P_columns_(i, l)];
    diagonal_(i) = diagonal;
  }
  // Projected Gauss-Seidel from the caller's guess (deterministic: a replay gives the same
  // guesses), keeping y = C P^T lambda and s = N^T lambda.
  std::fill(y_.data(), y_.data() + rows, 0.0);
  Eigen::Vector3d s = Eigen::Vector3d::Zero();
  for (int i = 0; i < m; ++i) {
    const double guess = contacts[static_cast<std::size_t>(i)].push_guess_N;
    lambda_(i) = diagonal_(i) > 0.0 && guess > 0.0 && guess < 1e6 ? guess : 0.0;  // an absurd guess starts from 0
    if (lambda_(i) == 0.0) continue;
    const double* t = T_.data() + i * static_cast<std::ptrdiff_t>(rows);
    for (int row = 0; row < rows; ++row) y_(row) += lambda_(i) * t[row];
    s += lambda_(i) * normals_.col(i);
  }
  const auto residual = [&](int i) {
    double w = gap_(i) + normals_.col(i).dot(s) / k;
    for (int l = 0; l < 24 && P_columns_(i, l) >= 0; ++l) w += P_values_(i, l) * y_(P_columns_(i, l));
    return w;
  };
  r.contacts = m;
  for (int sweep = 0; sweep < max_sweeps && m > 0; ++sweep) {
    double violation = 0.0;
    for (int i = 0; i < m; ++i) {
      if (!(diagonal_(i) > 0.0)) continue;  // an ignored point
      const double updated = std::max(0.0, lambda_(i) - residual(i) / diagonal_(i));
      const double change = updated - lambda_(i);
      violation = std::max(violation, std::abs(change) * diagonal_(i));
      if (change == 0.0) continue;
      lambda_(i) = updated;
      const double* t = T_.data() + i * static_cast<std::ptrdiff_t>(rows);
      for (int row = 0; row < rows; ++row) y_(row) += change * t[row];
      s += change * normals_.col(i);
    }
    r.sweeps = sweep + 1;
    r.max_violation_m = violation;
    if (violation < tolerance_m) break;
  }
  r.force_on_device_N = s;
  r.proxy_offset_m = s / k;
  // The pushes gathered on the corner nodes, for touchableDisplacement().
  std::fill(f_.data(), f_.data() + rows, 0.0);
  for (int i = 0; i < m; ++i)
    for (int l = 0; l < 24 && P_columns_(i, l) >= 0; ++l) f_(P_columns_(i, l)) -= lambda_(i) * P_values_(i, l);
  // What the sweeps left inside: move the proxy out along the mean normal until every point with
  // a positive component along it is clear (the tissue's pushes unchanged).
  Eigen::Vector3d mean_normal = Eigen::Vector3d::Zero();
  for (int i = 0; i < m; ++i) mean_normal += normals_.col(i);
  if (m > 0 && mean_normal.norm() > 0.0) {
    const Eigen::Vector3d d = mean_normal.normalized();
    double out = 0.0;
    for (int i = 0; i < m; ++i) {
      if (!(diagonal_(i) > 0.0)) continue;
      const double w = residual(i);
      const double along = normals_.col(i).dot(d);
      if (w < 0.0 && along > 1e-6) out = std::max(out, -w / along);
    }
    r.projected_m = out;
    r.proxy_offset_m += out * d;
    r.force_on_device_N += k * out * d;
  }
  return r;
}

void CompliantContact::touchableDisplacement(std::span<const int> positions, double* u_out) const noexcept {
  std::fill(u_out, u_out + 3 * positions.size(), 0.0);
  const int g = static_cast<int>(gathered_.size());
  for (int dof = 0; dof < 3 * g; ++dof) {
    const double f = f_(dof);
    if (f == 0.0) continue;
    const float* column = compliance_.column(3 * gathered_[static_cast<std::size_t>(dof / 3)] + dof % 3);
    for (std::size_t w = 0; w < positions.size(); ++w) {
      const float* src = column + 3 * positions[w];
      u_out[3 * w] += f * src[0];
      u_out[3 * w + 1] += f * src[1];
      u_out[3 * w + 2] += f * src[2];
    }
  }
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
      f.segment<3>(3 * lattice_.elementNodes(at.element)[static_cast<std::size_t>(a)]) -= lambda_(i) * N(a) * normals_.col(i);
  }
  return f;
}

}  // namespace vh::tissue
