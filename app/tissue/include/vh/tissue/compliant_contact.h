#pragma once
/// @file
/// Contact of the tool with yielding tissue at the servo rate. A contact i is a tool point
/// touching the tissue's rest surface at material point X_i (frame G) with outward unit normal
/// n_i; the tool point, held by the virtual coupling (stiffness k) to the device, would be
/// gap_i from that surface along n_i at the device's pose (negative: the device is inside). The
/// tool pushes the tissue with lambda_i >= 0 along -n_i; the tissue's surface recedes by
/// (W lambda)_i along -n_i, W_ij = n_i^T C(X_i, X_j) n_j with C(X_i, X_j) = sum_a sum_b
/// N_a(X_i) N_b(X_j) C_ab the condensed compliance interpolated to the points (SurfaceCompliance),
/// and the point proxy moves out by (1/k) sum_j lambda_j n_j. No point ends inside the deformed
/// surface and a point is pushed only where it touches:
///     lambda >= 0,   A lambda + gap >= 0,   lambda_i (A lambda + gap)_i = 0,
///     A = W + N^T N / k   (symmetric positive semi-definite),
/// solved by projected Gauss-Seidel (Murty 1988, "Linear complementarity, linear and nonlinear
/// programming", ch. 9), started from the caller's guess (the last tick's pushes: the contact
/// set moves little in a millisecond) and stopped at a sweep budget. Whatever overlap the budget
/// leaves is then removed by moving the proxy out along the contacts' mean normal (the pushes,
/// hence the tissue's shape, unchanged): no tool point ends inside the deformed surface on any
/// tick, and an unconverged tick only feels a little stiffer. Quasi-static: the hand feels the
/// tissue's static compliance in series with the coupling; the mass and damping act in the
/// background model that the view shows.
///
/// Real-time: solve() allocates nothing and touches only the blocks of the g corner nodes under
/// the contacts. A is never formed: the sweeps keep y = C P^T lambda (the tissue's displacement
/// at those nodes) and s = N^T lambda up to date, so a tick costs about m * 12 * 3g to set up
/// (12 weights per point on a cell face) plus m * (3g + 15) a sweep, not the lattice's size.
#include <span>
#include <vector>

#include <Eigen/Core>

#include "vh/tissue/hex_lattice.h"
#include "vh/tissue/surface_compliance.h"

namespace vh::tissue {

struct TissueContactPoint {
  Eigen::Vector3d X_G_m = Eigen::Vector3d::Zero();     ///< Material point on the rest surface, frame G [m].
  Eigen::Vector3d n_G = Eigen::Vector3d::UnitZ();      ///< Outward normal of the rest surface there (normalised here; zero: ignored).
  double gap_m = 0.0;                                   ///< Tool point's distance out of the rest surface at the device's pose [m].
  double push_guess_N = 0.0;                            ///< Starting push (the last tick's for this tool point, else 0) [N].
};

struct CompliantContactResult {
  int contacts = 0;                 ///< m.
  int sweeps = 0;                   ///< Gauss-Seidel sweeps made.
  double max_violation_m = 0.0;     ///< Largest remaining overlap or complementarity residual [m].
  int rigid_points = 0;             ///< Contacts on cells whose corners are held or not touchable (those corners do not yield).
  double projected_m = 0.0;         ///< How far the proxy was moved out after the sweeps to clear every point [m].
  int ignored_points = 0;           ///< Contacts with a zero normal (no direction to push along): left out.
  Eigen::Vector3d force_on_device_N = Eigen::Vector3d::Zero();  ///< sum lambda_i n_i: what the hand feels.
  Eigen::Vector3d proxy_offset_m = Eigen::Vector3d::Zero();     ///< (1/k) sum lambda_i n_i: proxy minus device.
};

class CompliantContact {
 public:
  /// @param max_contacts capacity m_max (>= 1); solve() takes at most that many contacts.
  /// @param max_nodes how many corner nodes a tick may gather (>= 8); a contact whose corners
  ///        would go past it is held rigid (counted in rigid_points).
  /// @throws std::invalid_argument on a capacity < 1 or max_nodes < 8.
  CompliantContact(const HexLattice& lattice, const SurfaceCompliance& compliance, int max_contacts = 64,
                   int max_nodes = 256);

  /// Solves the contacts (at most capacity(); more are ignored and counted out). Never throws,
  /// never allocates. Non-finite input gives 0 contacts.
  /// @param coupling_stiffness_N_per_m k (> 0): the coupling of the point proxy to the device.
  /// @param max_sweeps cap on Gauss-Seidel sweeps; tolerance_m the violation that ends them.
  CompliantContactResult solve(std::span<const TissueContactPoint> contacts, double coupling_stiffness_N_per_m,
                               int max_sweeps = 200, double tolerance_m = 1e-9) noexcept;

  int capacity() const noexcept { return capacity_; }
  /// lambda_i [N] of the last solve (its first `contacts` entries).
  const Eigen::VectorXd& pushes_N() const noexcept { return lambda_; }
  /// The tissue's displacement under the last solve's pushes at touchable positions (table
  /// positions of SurfaceCompliance) [m], frame G: u = C f with f = -P^T lambda the pushes on
  /// the gathered corner nodes, 3 per position into u_out (3 x positions.size()). Reads 3g
  /// columns of the table (g gathered nodes); never allocates.
  void touchableDisplacement(std::span<const int> positions, double* u_out) const noexcept;
  /// Nodal forces on the tissue of the last solve (the lattice's dof count) [N], frame G: what
  /// the background model and the view apply. Allocates: not for the servo thread.
  Eigen::VectorXd nodalForces_N(std::span<const TissueContactPoint> contacts) const;

 private:
  const HexLattice& lattice_;
  const SurfaceCompliance& compliance_;
  int capacity_;
  int max_nodes_;
  // Workspace, sized once.
  Eigen::VectorXd lambda_, gap_, diagonal_;
  Eigen::Matrix3Xd normals_;     ///< (3 x m_max): the contacts' normals, normalised (zero: ignored).
  Eigen::MatrixXd P_values_;     ///< (m_max x 24): N_a(X_i) n_i(c), the nonzero ones first.
  Eigen::MatrixXi P_columns_;    ///< (m_max x 24): the gathered dof (3 slot + c) of each; -1 ends the row.
  std::vector<int> gathered_;    ///< Table positions of the gathered corner nodes (<= max_nodes).
  std::vector<int> slot_of_;     ///< Per table position: its slot in gathered_, -1 when absent.
  /// Room for (3 max_nodes)^2: the gathered block of the table, 3 g x 3 g for g gathered nodes,
  /// stored compactly (column-major with 3 g rows, not the room's height: few pages and lines).
  Eigen::MatrixXd C_;
  /// The last solve's gathered nodes, their slots by table position (-1: absent; set only while
  /// a solve gathers) and their block C_prev_ (as C_): the pairs a solve gathers again are
  /// copied from there, the same values, instead of read from the table, whose scattered reads
  /// miss the cache (a table of tens to hundreds of MB).
  std::vector<int> prev_gathered_;
  std::vector<int> prev_slot_of_;
  Eigen::MatrixXd C_prev_;
  Eigen::MatrixXd T_;            ///< Room for (3 max_nodes x m_max): C P^T (3 g rows, compact as C_), column i the tissue's response to contact i.
  Eigen::VectorXd y_;            ///< (3 max_nodes): C P^T lambda.
  Eigen::VectorXd f_;            ///< (3 max_nodes): -P^T lambda, the pushes on the gathered nodes [N].
};

}  // namespace vh::tissue
