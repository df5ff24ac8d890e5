#include "vh/haptics/cone_projection.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <span>
#include <stdexcept>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <Eigen/QR>

namespace vh::haptics {
namespace {

constexpr int kDim = 6;

// Least-squares coefficients mu of y on the columns cols[0..k) (modified Gram-Schmidt with
// re-orthogonalisation; k <= 6). Returns false when a column is (numerically) dependent.
bool leastSquares(const Vector6d* const* cols, int k, const Vector6d& y, double* mu) {
  std::array<Vector6d, kDim> Q;
  double R[kDim][kDim] = {};
  for (int c = 0; c < k; ++c) {
    Vector6d v = *cols[c];
    const double norm0 = v.norm();
    for (int pass = 0; pass < 2; ++pass)
      for (int q = 0; q < c; ++q) {
        const double d = Q[q].dot(v);
        R[q][c] += d;
        v -= d * Q[q];
      }
    const double nv = v.norm();
    if (!(nv > 1e-10 * norm0)) return false;
    R[c][c] = nv;
    Q[c] = v / nv;
  }
  double qty[kDim];
  for (int c = 0; c < k; ++c) qty[c] = Q[c].dot(y);
  for (int c = k - 1; c >= 0; --c) {
    double s = qty[c];
    for (int q = c + 1; q < k; ++q) s -= R[c][q] * mu[q];
    mu[c] = s / R[c][c];
  }
  return true;
}

// Distance of g from the span of cols[0..k), relative to |g|.
double relativeResidual(const Vector6d* const* cols, int k, const Vector6d& g) {
  if (k == 0) return 1.0;
  double mu[kDim];
  if (!leastSquares(cols, k, g, mu)) return 0.0;
  Vector6d r = g;
  for (int c = 0; c < k; ++c) r -= mu[c] * *cols[c];
  return r.norm() / g.norm();
}

// Mass metric -> Euclidean: M = L L^T, generators g_i = L^-1 j_i (rows that are zero or not
// finite are excluded), all multipliers zero.
inline void setUpGenerators(const Eigen::LLT<Matrix6d>& llt, std::span<const Vector6d> J_rows, int m,
                            std::vector<Vector6d>& g, std::vector<double>& gnorm, std::vector<double>& lambda,
                            std::vector<unsigned char>& excluded) noexcept {
  const auto L = llt.matrixL();
  for (int i = 0; i < m; ++i) {
    g[i] = L.solve(J_rows[i]);
    gnorm[i] = g[i].norm();
    lambda[i] = 0.0;
    excluded[i] = !(gnorm[i] > 0.0) || !g[i].allFinite();
  }
}

// Warm start: the guessed face's independent rows, then drop non-positive coefficients until
// the least-squares coefficients on the face are all positive (z is then the projection of y
// onto that face's cone, a valid Wilhelmsen iterate). Returns the active set's size k
// (active[0..k), their lambda > 0); 0 for a cold start.
inline int warmStart(std::span<const int> warm_start, int m, const Vector6d& y, const std::vector<Vector6d>& g,
                     std::vector<double>& lambda, const std::vector<unsigned char>& excluded, int* active) noexcept {
  int k = 0;
  for (const int i : warm_start) {
    if (k == kDim || i < 0 || i >= m || excluded[i] || lambda[i] != 0.0) continue;
    const Vector6d* cols[kDim];
    for (int c = 0; c < k; ++c) cols[c] = &g[active[c]];
    if (k > 0 && relativeResidual(cols, k, g[i]) < 1e-9) continue;
    active[k++] = i;
    lambda[i] = 1.0;  // marks "in the guess" until the coefficients are known
  }
  while (k > 0) {
    const Vector6d* cols[kDim];
    for (int c = 0; c < k; ++c) cols[c] = &g[active[c]];
    double mu[kDim];
    if (!leastSquares(cols, k, y, mu)) {  // cannot happen for independent rows; start cold
      for (int c = 0; c < k; ++c) lambda[active[c]] = 0.0;
      k = 0;
      break;
    }
    int kept = 0;
    for (int c = 0; c < k; ++c) {
      if (mu[c] > 0.0) {
        lambda[active[c]] = mu[c];
        active[kept++] = active[c];
      } else {
        lambda[active[c]] = 0.0;
      }
    }
    if (kept == k) break;
    for (int c = 0; c < kept; ++c) lambda[active[c]] = 1.0;
    k = kept;
  }
  return k;
}

// Wilhelmsen's algorithm from the iterate z = sum lambda_i g_i over active[0..k): grow the
// active set by the generator that most reduces the distance to y, project onto the active
// span, and when a coefficient would turn negative walk back to the face where it vanishes and
// drop it. Returns the iterations used; converged: no generator reduces the distance by > tol.
inline int wilhelmsen(int m, const Vector6d& y, double tol, const std::vector<Vector6d>& g,
                      const std::vector<double>& gnorm, std::vector<double>& lambda,
                      std::vector<unsigned char>& excluded, int* active, int& k, Vector6d& z,
                      bool& converged) noexcept {
  const int max_iterations = 4 * m + 40;
  int it = 0;
  for (; it < max_iterations; ++it) {
    const Vector6d r = y - z;
    int best = -1;
    double best_w = tol;
    for (int i = 0; i < m; ++i) {
      if (excluded[i] || lambda[i] > 0.0) continue;
      const double w = g[i].dot(r) / gnorm[i];
      if (w > best_w) {
        best_w = w;
        best = i;
      }
    }
    if (best < 0) {
      converged = true;
      break;
    }
    const Vector6d* cols[kDim];
    for (int c = 0; c < k; ++c) cols[c] = &g[active[c]];
    if (k == kDim || relativeResidual(cols, k, g[best]) < 1e-9) {
      excluded[best] = 1;  // (numerically) in the span of the active set: cannot reduce further
      continue;
    }
    active[k++] = best;
    // Inner loop: restore positive coefficients.
    for (int inner = 0; inner < kDim + 2; ++inner) {
      for (int c = 0; c < k; ++c) cols[c] = &g[active[c]];
      double mu[kDim];
      if (!leastSquares(cols, k, y, mu)) {
        excluded[active[k - 1]] = 1;
        lambda[active[k - 1]] = 0.0;
        --k;
        continue;
      }
      bool all_positive = true;
      for (int c = 0; c < k; ++c) all_positive &= mu[c] > 0.0;
      if (all_positive) {
        for (int c = 0; c < k; ++c) lambda[active[c]] = mu[c];
        break;
      }
      double theta = 1.0;
      for (int c = 0; c < k; ++c)
        if (mu[c] <= 0.0) {
          const double l = lambda[active[c]];
          theta = std::min(theta, l / (l - mu[c]));
        }
      int kept = 0;
      for (int c = 0; c < k; ++c) {
        double& l = lambda[active[c]];
        l += theta * (mu[c] - l);
        if (l > 1e-15 * (1.0 + std::abs(mu[c]))) {
          active[kept++] = active[c];
        } else {
          if (active[c] == best && theta == 0.0) excluded[best] = 1;  // no progress possible with it
          l = 0.0;
        }
      }
      k = kept;
      if (k == 0) break;
    }
    z.setZero();
    for (int c = 0; c < k; ++c) z += lambda[active[c]] * g[active[c]];
  }
  return it;
}

// The result: the final active set, a_c = L^-T (x + z) (P_C(x) back in the mass metric), the
// multipliers; a non-finite a_c becomes zero (never hand a NaN to the collision detector).
inline void finishProjection(const Eigen::LLT<Matrix6d>& llt, const Vector6d& x, const Vector6d& z, int it,
                             bool converged, int k, const int* active, int m, const std::vector<double>& lambda,
                             std::span<double> lambda_out, ConeProjection& out) noexcept {
  const auto L = llt.matrixL();
  out.iterations = it;
  out.converged = converged;
  out.active = k;
  for (int c = 0; c < k; ++c) out.active_rows[static_cast<std::size_t>(c)] = active[c];
  out.a_c = L.transpose().solve(x + z);
  for (int i = 0; i < m && i < static_cast<int>(lambda_out.size()); ++i) lambda_out[i] = lambda[i];
  if (!out.a_c.allFinite()) {  // stay still
    out.a_c.setZero();
    out.converged = false;
  }
}

}  // namespace

ConeProjector::ConeProjector(std::size_t max_constraints)
    : g_(max_constraints), gnorm_(max_constraints), lambda_(max_constraints), excluded_(max_constraints) {}

ConeProjection ConeProjector::project(const Matrix6d& M, const Vector6d& a_u, std::span<const Vector6d> J_rows,
                                      std::span<double> lambda_out, std::span<const int> warm_start) noexcept {
  ConeProjection out;
  const int m = static_cast<int>(std::min(J_rows.size(), g_.size()));
  for (double& l : lambda_out) l = 0.0;
  if (m == 0) {
    out.a_c = a_u;
    out.converged = true;
    return out;
  }
  // Mass metric -> Euclidean (section 2.4, eq. 3-4): M = L L^T, b = L^T a, generators g_i = L^-1 j_i.
  const Eigen::LLT<Matrix6d> llt(M);
  const Vector6d x = llt.matrixL().transpose() * a_u;
  const Vector6d y = -x;  // P_C(x) = x + P_K(-x), K = cone(g_i)
  setUpGenerators(llt, J_rows, m, g_, gnorm_, lambda_, excluded_);
  const double ynorm = y.norm();
  const double tol = 1e-13 * std::max(ynorm, std::numeric_limits<double>::min());

  int active[kDim];
  int k = warmStart(warm_start, m, y, g_, lambda_, excluded_, active);
  Vector6d z = Vector6d::Zero();
  for (int c = 0; c < k; ++c) z += lambda_[active[c]] * g_[active[c]];
  bool converged = false;
  const int it = wilhelmsen(m, y, tol, g_, gnorm_, lambda_, excluded_, active, k, z, converged);
  finishProjection(llt, x, z, it, converged, k, active, m, lambda_, lambda_out, out);
  return out;
}

Vector6d projectOntoConeReference(const Matrix6d& M, const Vector6d& a_u, std::span<const Vector6d> J_rows) {
  const int m = static_cast<int>(J_rows.size());
  if (m > 16) throw std::invalid_argument("projectOntoConeReference: at most 16 constraints");
  const Eigen::LLT<Matrix6d> llt(M);
  const Eigen::Matrix<double, 6, 6> L = llt.matrixL();
  const Vector6d x = L.transpose() * a_u;
  const Vector6d y = -x;
  std::vector<Vector6d> g(m);
  for (int i = 0; i < m; ++i) g[i] = L.triangularView<Eigen::Lower>().solve(J_rows[i]);
  Vector6d best_z = Vector6d::Zero();
  double best_d = y.squaredNorm();
  for (unsigned mask = 1; mask < (1u << m); ++mask) {
    const int k = __builtin_popcount(mask);
    if (k > 6) continue;
    Eigen::Matrix<double, 6, Eigen::Dynamic> A(6, k);
    int c = 0;
    for (int i = 0; i < m; ++i)
      if (mask & (1u << i)) A.col(c++) = g[i];
    Eigen::ColPivHouseholderQR<Eigen::Matrix<double, 6, Eigen::Dynamic>> qr(A);
    qr.setThreshold(1e-10);
    if (qr.rank() < k) continue;
    const Eigen::VectorXd mu = qr.solve(y);
    if ((mu.array() < 0.0).any()) continue;
    const Vector6d z = A * mu;
    const double d = (y - z).squaredNorm();
    if (d < best_d) {
      best_d = d;
      best_z = z;
    }
  }
  return L.transpose().triangularView<Eigen::Upper>().solve(x + best_z);
}

Vector6d projectOntoConeHildreth(const Matrix6d& M, const Vector6d& a_u, std::span<const Vector6d> J_rows) {
  const int m = static_cast<int>(J_rows.size());
  const Matrix6d Minv = M.inverse();
  std::vector<Vector6d> Minv_j(m);
  std::vector<double> d(m);
  for (int i = 0; i < m; ++i) {
    Minv_j[i] = Minv * J_rows[i];
    d[i] = J_rows[i].dot(Minv_j[i]);
  }
  std::vector<double> lambda(m, 0.0);
  Vector6d a = a_u;
  const double scale = std::max(a_u.norm(), 1e-300);
  // Exact projection onto {J_S a = 0} in the metric M, for the support S (pseudo-inverse: any
  // rank), and its KKT check against all rows.
  auto polish = [&](Vector6d& out) -> bool {
    std::vector<int> S;
    double lmax = 0.0;
    for (double l : lambda) lmax = std::max(lmax, l);
    for (int i = 0; i < m; ++i)
      if (lambda[i] > 1e-7 * lmax) S.push_back(i);
    if (S.empty()) {
      out = a_u;
    } else {
      Eigen::MatrixXd J(S.size(), 6);
      for (std::size_t r = 0; r < S.size(); ++r) J.row(static_cast<Eigen::Index>(r)) = J_rows[S[r]].transpose();
      const Eigen::MatrixXd A = J * Minv * J.transpose();
      const Eigen::VectorXd mu = A.completeOrthogonalDecomposition().solve(-(J * a_u));
      out = a_u + Minv * J.transpose() * mu;
    }
    // KKT certificate: out feasible, and M (out - a_u) in the cone of the rows tight at out
    // (checked by Moreau: its projection onto the polar cone {x : j . x <= 0, j tight} is zero,
    // found by the exhaustive reference). With more than 16 tight rows, fall back to Hildreth's
    // own multipliers (stationarity to 1e-5 |M a_u|, which screens the support).
    std::vector<Vector6d> tight;
    for (int i = 0; i < m; ++i) {
      const double g = J_rows[i].dot(out);
      if (g < -1e-10 * scale * J_rows[i].norm()) return false;
      if (g <= 1e-10 * scale * J_rows[i].norm()) tight.push_back(-J_rows[i]);
    }
    const Vector6d v = M * (out - a_u);
    if (tight.size() <= 10) {
      const Vector6d polar = projectOntoConeReference(Matrix6d::Identity(), v, tight);
      return polar.norm() <= 1e-9 * std::max(v.norm(), (M * a_u).norm());
    }
    Vector6d residual = v;
    for (int i = 0; i < m; ++i) residual -= lambda[i] * J_rows[i];
    return residual.norm() <= 1e-5 * (M * a_u).norm();
  };
  int next_check = 16;
  for (int sweep = 1; sweep <= 200000; ++sweep) {
    for (int i = 0; i < m; ++i) {
      if (!(d[i] > 0.0)) continue;
      const double next = std::max(0.0, lambda[i] - J_rows[i].dot(a) / d[i]);
      a += (next - lambda[i]) * Minv_j[i];
      lambda[i] = next;
    }
    if (sweep == next_check) {
      next_check *= 2;
      Vector6d polished;
      if (polish(polished)) return polished;
    }
  }
  throw std::runtime_error("projectOntoConeHildreth: no convergence in 200000 sweeps");
}

}  // namespace vh::haptics
