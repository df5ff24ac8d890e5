#pragma once
/// @file
/// Where the tissue model meets the rendering algorithm: the configuration solver, its collision
/// detector, the crossing check and the edge test feel the deformed tissue through the very
/// ScalarVolume they feel a rigid scan through. Each servo tick, before the renderer's tick:
///
///   1. The tool's points at the device's pose that lie in, or within a margin of, the tissue's
///      rest surface become the contacts of the tissue's complementarity problem (depth: the
///      first-order distance (s - F) / |grad F| within a voxel of the surface, deeper the
///      exact distance transform of the voxels outside it, DistanceField).
///   2. CompliantContact solves it: how far the tissue gives under the tool held by the
///      coupling's stiffness (the pushes lambda, exact for the linear model, quasi-static).
///   3. The deformed field is written into the renderer's own copy of the volume over a window
///      about the contacts: each voxel centre p takes F(X) at its material point X + u(X) = p
///      (chord steps with the lattice cell's Jacobian), F the scan as loaded, so the scan's own
///      voxels keep carrying the surface (the isosurface of the deformed tissue, to trilinear
///      interpolation of the resampled voxels). Voxels the last window wrote and this one does not go back to rest.
///   4. No point of the proxy may end inside: where the new field would swallow one (tissue
///      springing back onto a tool that has not yet moved), the field is written only that
///      fraction alpha of the way from the old one that swallows none (the trilinear field is
///      linear in the voxels, so alpha is exact up to the stored type's rounding, which a
///      check after the write catches: then nothing changes this tick). The rest follows on
///      the next ticks as the proxy moves: the "felt deformation", as a lowered isovalue is felt
///      only as far as it swallows nothing.
///   5. The renderer is told (HapticRenderer::noteFieldChanged()) with the most any written
///      voxel's value rose: its proofs about the old field are dropped, but for the edge test's
///      directional certificates with margin left beyond that rise. Its tick then moves the proxy
///      against the deformed surface as against any other: first contact along each point's
///      motion, the edge test between points.
///
/// Frames: W the volume's world frame; G the scan's grid frame (the tissue's, tissue_region.h):
/// p_W = origin_W + D G. Units SI. The isovalue is fixed for a scene (the region, the depth
/// field and the compliance belong to it). Limits: the surface cannot bulge out of the lattice's
/// cells (a voxel in an empty cell keeps its rest value); beyond the window the hand feels the
/// rest surface (the window grows with the contacts' spread); no friction, no cutting of tissue.
#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "vh/haptics/distance_field.h"
#include "vh/haptics/haptic_renderer.h"
#include "vh/haptics/scalar_volume.h"
#include "vh/haptics/worker_pool.h"
#include "vh/tissue/compliant_contact.h"
#include "vh/tissue/static_solver.h"
#include "vh/tissue/surface_compliance.h"
#include "vh/tissue/tissue_region.h"

namespace vh::tissue {

struct DeformableSceneOptions {
  /// Tool points at the device pose within this distance outside the rest surface join the
  /// contact problem [m]; 0: one voxel (the smallest spacing).
  double contact_margin_m = 0.0;
  /// Most tool points in the contact problem (the deepest are kept), >= 1.
  int max_contacts = 128;
  /// Most lattice nodes under the contacts in one tick (CompliantContact), >= 8.
  int max_nodes = 512;
  /// Gauss-Seidel sweeps per tick at most (warm-started from the last tick's pushes).
  int max_sweeps = 30;
  /// The window written about the contacts' material points: their box grown by this [m];
  /// 0: one lattice cell. (Measured on vh_tissue_tick_report's gel, 2 mm cells: one cell and two
  /// give the same forces with windows of 6,292 and 18,000 voxels; 1 mm let the window's edge,
  /// where the field returns to rest, meet the sliding ball: peak force 0.96 N against 0.28 N.)
  double window_margin_m = 0.0;
  /// Most voxels written in one tick (the window is clipped about the deepest contact beyond it);
  /// sets the workspace, allocated once.
  int max_window_voxels = 40 * 40 * 40;
  /// Cell layers under the region's outside whose nodes the compliance table holds
  /// (outerLayerNodes()), >= 1: the deformed field is written only in cells whose eight corners
  /// it holds, so the surface (blurred over a few voxels) and how deep it is pushed must lie in
  /// them. The table's memory grows as the square of its nodes.
  int touchable_layers = 2;
  /// Worker threads for the compliance table at construction (>= 1).
  int compliance_threads = 1;
  /// Largest compliance table accepted [bytes] (9 S^2 floats for S touchable nodes): a region
  /// whose table would be larger is refused before any solve, with its figures.
  double max_table_bytes = 1024.0 * 1024.0 * 1024.0;
  /// Most proxy points checked against the new field in one step (the workspace); a step with
  /// more of them in its window writes nothing (the tool's surface is never entered).
  int max_proxy_points = 65536;
};

/// What one step() did.
struct DeformableStep {
  CompliantContactResult contact;   ///< The complementarity solve (pushes, force, sweeps).
  int tool_points_near = 0;         ///< Tool points within the margin of the rest surface (before the cap).
  int voxels_written = 0;           ///< Voxels rewritten this tick (window and what goes back to rest).
  /// The fraction of the way to the solved deformation written (1: all; below 1: a proxy point
  /// would have been swallowed, the rest follows; 0: nothing changed this tick).
  double felt_fraction = 1.0;
  double max_displacement_m = 0.0;  ///< Largest |u| over the window's touchable nodes [m].
  /// The indentation [m]: how far the surface gave where the tool pushes, the largest recession
  /// along its normal over the pushed contacts (the linear model's n . u at them); 0 untouched.
  double indentation_m = 0.0;
  bool window_clipped = false;      ///< The window exceeded max_window_voxels and was clipped.
  /// How far the springing-back surface carried the proxy this step [m] (0: not carried).
  double proxy_carried_m = 0.0;
  double step_us = 0.0;             ///< Wall time of step() [us]; its parts below.
  double gather_us = 0.0;           ///< The tool's points near the rest surface (1.).
  double solve_us = 0.0;            ///< The complementarity solve (2.).
  double displace_us = 0.0;         ///< u at the window's nodes from the table.
  double resample_us = 0.0;         ///< The window's voxels resampled (3.).
  double write_us = 0.0;            ///< Written, checked against the proxy (4.) and the volume's bounds refreshed.
  int window_voxels = 0;            ///< Voxels of the window and of the last one (what was resampled or restored).
};

/// The deformed tissue as the view shows it: the box of voxels (the scan's grid, indices
/// inclusive) outside which the felt volume is the scan at rest, and the felt field there.
struct DeformedWindow {
  std::array<int, 3> lo{0, 0, 0};
  std::array<int, 3> hi{-1, -1, -1};  ///< hi < lo on an axis: the tissue at rest everywhere.
  /// F at the box's voxels [data units], x fastest: (hi - lo + 1) per axis, multiplied.
  std::vector<float> values_F;
  std::uint64_t step = 0;  ///< The step() that published it (counts from 1).
  double indentation_m = 0.0;  ///< That step's DeformableStep::indentation_m [m].
  double push_N = 0.0;         ///< That step's net push on the tissue, |force_on_device_N| [N].
  double felt_fraction = 1.0;  ///< That step's DeformableStep::felt_fraction.
  bool empty() const noexcept { return hi[0] < lo[0] || hi[1] < lo[1] || hi[2] < lo[2]; }
};

/// A scan whose tissue region yields under the tool. Owns the model, its factorisation and the
/// compliance table (built in the constructor: seconds for thousands of nodes), and the volume
/// the renderer feels (feltVolume(), a copy of the scan that step() rewrites).
class DeformableScene {
 public:
  /// @param scan the scan as loaded (never written); its geometry is the region's grid.
  /// @param region the tissue cut from it (buildTissueRegion() on the scan's grid: frame G).
  /// @param isovalue the surface felt, F = s [data units].
  /// @throws std::invalid_argument on an empty scan, a region whose lattice leaves the scan's
  ///         grid, a non-finite isovalue, bad options, a region with no touchable node, or one
  ///         whose compliance table would exceed max_table_bytes (the message gives its size).
  DeformableScene(std::shared_ptr<const haptics::ScalarVolume> scan, TissueRegion region, double isovalue,
                  const DeformableSceneOptions& options = {});

  /// The volume to give the renderer (its private copy; step() writes it between ticks).
  std::shared_ptr<const haptics::ScalarVolume> feltVolume() const noexcept { return felt_; }
  /// The scan as loaded (the rest state; never written).
  const haptics::ScalarVolume& scan() const noexcept { return *scan_; }

  /// Back to rest, as built: the felt volume the scan again, no contact, no warm start; the view
  /// is told at the next step. For new haptic threads on the same scene and surface (the model,
  /// its factorisation and the compliance table, the costly part, are kept). Only while no
  /// renderer ticks on feltVolume(). Never allocates.
  void reset() noexcept;
  const TissueRegion& region() const noexcept { return region_; }
  const SurfaceCompliance& compliance() const noexcept { return *compliance_; }
  double isovalue() const noexcept { return isovalue_; }

  /// Cores step() runs its two loops over points and voxels on, the tool's points near the rest
  /// surface (1. above) and the resampling (3.): the caller plus lanes - 1 threads of the
  /// process's shared pool (haptics::WorkerPool::shared(), the configuration solver's, whose
  /// threads spin between forks: give it only cores the coupling thread does not need); 1, as
  /// built: no thread. The lanes claim the tool's points and the window's rows a few at a time
  /// (a lane the system holds back delays the step by what it claimed, not by a share of the
  /// work); a row is solved in the order one lane solves it and the contacts are taken in the
  /// tool's order, so the contacts and the field written do not depend on the lanes, bit for bit. Not on the servo path (it may
  /// start threads and allocates a workspace of max_proxy_points contacts), and only while no
  /// step() runs.
  /// @throws std::invalid_argument for lanes outside [1, haptics::WorkerPool::kMaxLanes]; as
  ///         haptics::WorkerPool::shared().
  void setLanes(int lanes);
  int lanes() const noexcept { return lanes_; }

  /// Step before the renderer's tick: solves the tissue's contact for the device pose X_WD with
  /// the coupling's linear stiffness, writes the felt deformation into feltVolume() and tells
  /// `renderer` (which must feel feltVolume()). A non-finite pose leaves everything as it was.
  /// Never throws, never allocates.
  DeformableStep step(const haptics::Pose& X_WD, haptics::HapticRenderer& renderer) noexcept;

  /// The pushes of the last step [N] on the tissue, per contact, and the contacts themselves
  /// (material points and normals in G): what the background model and the view apply.
  std::span<const TissueContactPoint> lastContacts() const noexcept {
    return {contacts_.data(), static_cast<std::size_t>(contact_count_)};
  }
  const CompliantContact& contact() const noexcept { return *contact_; }

  /// For the view, on one other thread: the latest deformed window step() published, copied into
  /// `out` (which may allocate: the reader's thread). step() publishes at most every
  /// `kViewPublishInterval_ms` while the field changes, and always the state it settles in,
  /// through a lock-free triple buffer (the servo never waits for the view).
  /// @return false (out untouched) when nothing was published since the last call.
  bool takeDeformedWindow(DeformedWindow& out);
  static constexpr double kViewPublishInterval_ms = 10.0;

 private:
  // W -> G.
  Eigen::Vector3d toG(const Eigen::Vector3d& p_W) const noexcept { return D_W_.transpose() * (p_W - origin_W_); }
  // Gathers the tool points near the rest surface at X_WD into contacts_ (the deepest kept).
  void gatherContacts(const haptics::Pose& X_WD, const haptics::ToolModel& tool, DeformableStep& out) noexcept;
  // A tool point near the rest surface: its contact's material point, normal (G) and gap.
  struct NearPoint {
    Eigen::Vector3d X_G_m = Eigen::Vector3d::Zero();
    Eigen::Vector3d n_G = Eigen::Vector3d::Zero();
    double gap_m = 0.0;
  };
  // Whether the tool point at p_W lies within the margin of the rest surface (in the lattice's
  // box lo..hi grown by the margin, G), and its contact then.
  bool nearPoint(const Eigen::Vector3d& p_W, const Eigen::Vector3d& box_lo, const Eigen::Vector3d& box_hi,
                 NearPoint& near) const noexcept;
  // Tool point j near the surface joins the contacts (its warm start; the deepest kept at the cap).
  void addContact(int j, const NearPoint& near, DeformableStep& out) noexcept;
  // The index of lattice grid cell (a, b, c), x fastest (cell_touchable_).
  std::size_t cellIndex(int a, int b, int c) const noexcept {
    const Eigen::Vector3i& cells = region_.model.lattice().geometry().cells;
    return static_cast<std::size_t>(a) +
           static_cast<std::size_t>(cells.x()) * (static_cast<std::size_t>(b) + static_cast<std::size_t>(cells.y()) * static_cast<std::size_t>(c));
  }
  // Whether a proxy point p_W is in the written box grown by a voxel (G, box_lo..box_hi) and in
  // the volume: the points whose F before the write step() keeps (proxy_points_W_), in order.
  bool inWrittenBox(const Eigen::Vector3d& p_W, const Eigen::Vector3d& box_lo, const Eigen::Vector3d& box_hi) const noexcept {
    const Eigen::Vector3d g = toG(p_W);
    return !(g.array() < box_lo.array()).any() && !(g.array() > box_hi.array()).any() && felt_->inBounds(p_W);
  }
  // Where the tissue springs back onto the proxy at X_WP (its points in proxy_points_W_ with F
  // before the write in proxy_old_F_; the written box in G, box_lo..box_hi): the shortest push
  // dp_W [m] along the surface's outward normal (at most half a voxel) after which no point of
  // `tool` that was outside is inside the field as written. False when there is none.
  bool carryOut(const haptics::ToolModel& tool, const haptics::Pose& X_WP, const Eigen::Vector3d& box_lo,
                const Eigen::Vector3d& box_hi, Eigen::Vector3d& dp_W) const noexcept;
  // A lattice cell as displacementAt() reads it: its corners' displacements and the inverse of
  // I + grad u at its centre.
  struct CellCorners {
    std::array<int, 3> cell{-1, -1, -1};  // the lattice cell held; -1: none yet
    bool touchable = false;               // its eight corners touchable (else u is 0 there)
    double u[3][8] = {};                  // [m] per component, corner a = dx + 2 dy + 4 dz
    Eigen::Matrix3d inverse_gradient = Eigen::Matrix3d::Identity();  // (I + grad u)^-1 at the centre
  };
  // The two cells last read, the least recently used replaced: a voxel's iterations go between
  // the cell of its centre and the cell of its material point (a cell apart under a deep push),
  // and the next voxel's mostly between the same two, so each is read once for many evaluations.
  // Valid while u_grid_ is unchanged (one step's resampling). It also carries the last solved
  // voxel's material point X and dX_dx = J^-1 s_x (how X moves per voxel along the row, J the
  // cell's I + grad u): the row's next voxel starts from X + dX_dx, within a voxel's curvature
  // of its own material point, so its first step is mostly the last.
  struct CornerCache {
    std::array<CellCorners, 2> cells;
    int recent = 0;  // the entry used last
    bool has_last = false;                      // last_voxel, last_X_G_m and dX_dx_m are set
    std::array<int, 3> last_voxel{0, 0, 0};     // the voxel whose material point was solved last
    Eigen::Vector3d last_X_G_m = Eigen::Vector3d::Zero();  // its material point [m], in G
    Eigen::Vector3d dX_dx_m = Eigen::Vector3d::Zero();     // J^-1 s_x there [m], in G
  };
  // u(X) [m] at a material point, and the cell it lies in; nullptr (u untouched) outside cells
  // whose corners are all touchable: u is 0 there.
  const CellCorners* displacementAt(const Eigen::Vector3d& X_G, CornerCache& cache, Eigen::Vector3d& u) const noexcept;
  // Whether voxel (i, j, k), displaced by displacement_m, may move the isosurface (band_).
  bool inBand(int i, int j, int k, double displacement_m) const noexcept;
  // The deformed F at the centre of voxel (i, j, k).
  double deformedValue(int i, int j, int k, CornerCache& cache) const noexcept;
  // One step's resampling (3.): the box u_lo..u_hi (this window and the last one), of which the
  // voxels in lo..hi are resampled when `window`, the others restored; its rows dealt to lanes.
  struct Resampling {
    DeformableScene* scene = nullptr;
    std::array<int, 3> u_lo{}, u_hi{}, lo{}, hi{};
    bool window = false;
    double max_displacement_m = 0.0;
    std::atomic<int> next_row{0};  // the first row no lane has claimed yet
  };
  // Rows of the box (x rows, z slowest) claimed by lane `lane` a few at a time until none is
  // left (a lane the system holds back delays the step by its claim, not by a share of the
  // rows): old_raw_ and new_raw_ there.
  void resampleRows(Resampling& job, int lane) noexcept;

  std::shared_ptr<const haptics::ScalarVolume> scan_;
  std::shared_ptr<haptics::ScalarVolume> felt_;
  // The lanes (setLanes()), their pool (null for one lane), one corner cache per lane (valid
  // within one step's resampling: cleared at its start) and, with several lanes, per tool point
  // whether it is near the surface and its contact (max_proxy_points of each).
  int lanes_ = 1;
  std::shared_ptr<haptics::WorkerPool> pool_;
  std::vector<CornerCache> lane_caches_ = std::vector<CornerCache>(1);
  std::vector<std::uint8_t> point_near_;
  std::vector<NearPoint> near_points_;
  TissueRegion region_;
  double isovalue_;
  DeformableSceneOptions options_;
  std::unique_ptr<StaticSolver> solver_;
  std::unique_ptr<SurfaceCompliance> compliance_;
  std::unique_ptr<CompliantContact> contact_;
  haptics::DistanceField outside_depth_;  // distance to the nearest voxel outside the rest surface
  // Per voxel of the box about the lattice (x fastest): voxel steps to the rest surface, 255 far.
  std::vector<std::uint8_t> band_;
  std::array<int, 3> band_lo_{0, 0, 0}, band_dims_{0, 0, 0};
  Eigen::Vector3d origin_W_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d D_W_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d spacing_m_ = Eigen::Vector3d::Ones();
  double margin_m_ = 0.0, window_margin_m_ = 0.0;
  // Workspace, sized once.
  std::vector<TissueContactPoint> contacts_;
  std::vector<int> contact_point_;   // the tool point of each contact
  std::vector<int> prev_point_;      // the last step's contacts' tool points (-1 ends the list)
  std::vector<double> prev_push_N_;  // ... and their pushes (the warm start)
  int contact_count_ = 0;
  Eigen::Vector3i node_dims_ = Eigen::Vector3i::Ones();  // the lattice's grid of nodes (cells + 1)
  double inverse_cell_m_ = 1.0;      // 1 / the lattice's cell side [1/m]
  std::vector<double> u_grid_;       // 3 per grid node, x fastest: u of the window's nodes, zero elsewhere
  std::vector<int> window_nodes_;    // touchable positions whose u was computed this step
  std::vector<std::size_t> window_grid_nodes_;  // ... their grid nodes
  std::vector<double> window_u_;     // their u, 3 each
  std::vector<std::uint8_t> cell_touchable_;  // per grid cell (x fastest): a cell whose 8 corners are all touchable
  std::vector<double> old_raw_, new_raw_;     // the window's voxels before and as solved
  std::vector<Eigen::Vector3d> proxy_points_W_;
  std::vector<double> proxy_old_F_;
  std::array<int, 3> last_lo_{0, 0, 0}, last_hi_{-1, -1, -1};  // the last window written (voxels)
  // The view's triple buffer: the servo fills slots_[view_write_], then swaps it with the middle
  // (view_middle_, kFresh set); the reader swaps the middle with slots_[view_read_].
  static constexpr unsigned kFresh = 4;
  void publishView(std::chrono::steady_clock::time_point now, bool changed, const DeformableStep& step) noexcept;
  std::array<DeformedWindow, 3> view_slots_;
  std::atomic<unsigned> view_middle_{1};
  unsigned view_write_ = 0, view_read_ = 2;
  bool view_dirty_ = false;
  std::uint64_t steps_ = 0;
  std::chrono::steady_clock::time_point view_published_{};
};

}  // namespace vh::tissue
