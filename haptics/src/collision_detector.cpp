// The collision detector's facade (paper section 2.3): its calls forwarded to the parts
// (collision_detector_impl.h), construction of every part's working memory (no member
// allocates after it), sweep()'s dispatch to the paper's or the accelerated sweep, and the
// stop clearance of a finished sweep's hit. The parts, one job a file:
//   paper_sweep.cpp          the paper's sweep: a point's path, the segment test with its
//                            bisection, the time-ordered queue over all points
//   accelerated_sweep.cpp    the accelerated sweep: the point-shell walk, the run tests and the
//                            per-lane search, resumable where the work budget cut it
//   sweep_lanes.cpp          its lanes on several cores: the shares of the tree and their balance
//   shell_tree.cpp           the point-shell tree and the ball query against the min-max tree
//   contact_set.cpp          the contact set: measure, prune (step 2), add, reduce to the cap
//   embedded_points.cpp      embedded points and the field over the shell (isovalue changes)
//   edge_test.cpp            the edge test between the points (edgesCrossAt(), addEdgeContact())
//   edge_certificates.cpp    the edge test's clearance certificates, kept across ticks
#include "vh/haptics/collision_detector.h"

#include "collision_detector_impl.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace vh::haptics {

const char* toString(DetectionMode mode) noexcept {
  return mode == DetectionMode::kPaper ? "paper" : "accelerated";
}

const char* toString(SegmentTest test) noexcept {
  return test == SegmentTest::kExact ? "exact" : "end-sample";
}

CollisionDetector::CollisionDetector(const ScalarVolume& volume, const ToolModel& tool, double epsilon_m,
                                     std::size_t max_contacts, DetectionMode mode, double segment_fraction,
                                     SegmentTest segment_test)
    : impl_(std::make_unique<Impl>(volume, tool, epsilon_m, max_contacts, mode, segment_fraction, segment_test)) {}

CollisionDetector::~CollisionDetector() = default;
CollisionDetector::CollisionDetector(CollisionDetector&&) noexcept = default;
CollisionDetector& CollisionDetector::operator=(CollisionDetector&&) noexcept = default;

// The facade's calls, forwarded.
DetectionMode CollisionDetector::mode() const noexcept { return impl_->mode(); }
SegmentTest CollisionDetector::segmentTest() const noexcept { return impl_->segmentTest(); }
double CollisionDetector::maxSagitta_m() const noexcept { return impl_->maxSagitta_m(); }
double CollisionDetector::epsilon_m() const noexcept { return impl_->epsilon_m(); }
double CollisionDetector::featureSize_m() const noexcept { return impl_->featureSize_m(); }
double CollisionDetector::shellRadius_m() const noexcept { return impl_->shellRadius_m(); }
SweepResult CollisionDetector::sweep(const RigidMotion& motion, double isovalue) noexcept {
  return impl_->sweep(motion, isovalue);
}
bool CollisionDetector::sweepPending() const noexcept { return impl_->sweepPending(); }
const RigidMotion& CollisionDetector::pendingMotion() const noexcept { return impl_->pendingMotion(); }
SweepResult CollisionDetector::resumeSweep() noexcept { return impl_->resumeSweep(); }
void CollisionDetector::abandonSweep() noexcept { impl_->abandonSweep(); }
void CollisionDetector::releaseClearContacts(const Pose& X_WP, double isovalue, double clearance_m) noexcept {
  impl_->releaseClearContacts(X_WP, isovalue, clearance_m);
}
void CollisionDetector::forgetFieldProofs(double max_rise) noexcept {
  impl_->abandonSweep();
  impl_->noteFieldRise(max_rise);
}
void CollisionDetector::pruneContacts(const Pose& X_WP, const Pose& X_WD, double isovalue) noexcept {
  impl_->pruneContacts(X_WP, X_WD, isovalue);
}
void CollisionDetector::addContactsAt(const RigidMotion& motion, const SweepResult& hit, double isovalue) noexcept {
  impl_->addContactsAt(motion, hit, isovalue);
}
bool CollisionDetector::refineStuckContact(const RigidMotion& motion, const SweepResult& hit) noexcept {
  return impl_->refineStuckContact(motion, hit);
}
void CollisionDetector::refreshPositions(const Pose& X_WP) noexcept { impl_->refreshPositions(X_WP); }
int CollisionDetector::updateEmbedded(const Pose& X_WP, double isovalue) noexcept {
  return impl_->updateEmbedded(X_WP, isovalue);
}
double CollisionDetector::maxFieldOnShell(const Pose& X_WP, double floor) noexcept {
  return impl_->maxFieldOnShell(X_WP, floor);
}
bool CollisionDetector::edgesCrossAt(const Pose& X_WP, double isovalue) noexcept {
  return impl_->edgesCrossAt(X_WP, isovalue);
}
bool CollisionDetector::edgeTestCut() const noexcept { return impl_->edgeTestCut(); }
bool CollisionDetector::listedEdgesCrossAt(const Pose& X_WP, double isovalue) noexcept {
  return impl_->listedEdgesCrossAt(X_WP, isovalue);
}
void CollisionDetector::clearCrossingEdges() noexcept { impl_->clearCrossingEdges(); }
const Contact* CollisionDetector::addEdgeContact(const Pose& X_WP, double isovalue) noexcept {
  return impl_->addEdgeContact(X_WP, isovalue);
}
const ShellEdges& CollisionDetector::shellEdges() const noexcept { return impl_->shellEdges(); }
int CollisionDetector::releaseEmbedded(const Pose& X_WP, double isovalue) noexcept {
  return impl_->releaseEmbedded(X_WP, isovalue);
}
int CollisionDetector::embeddedCount() const noexcept { return impl_->embeddedCount(); }
void CollisionDetector::clearContacts() noexcept { impl_->clearContacts(); }
std::span<const Contact> CollisionDetector::contacts() const noexcept { return impl_->contacts(); }
std::int64_t CollisionDetector::sampleCount() const noexcept { return impl_->sampleCount(); }
std::int64_t CollisionDetector::boxQueryCount() const noexcept { return impl_->boxQueryCount(); }
std::int64_t CollisionDetector::treeNodeCount() const noexcept { return impl_->treeNodeCount(); }
std::int64_t CollisionDetector::cellCount() const noexcept { return impl_->cellCount(); }
std::int64_t CollisionDetector::cellsWalkedCount() const noexcept { return impl_->cellsWalkedCount(); }
EdgeTestCounts CollisionDetector::edgeTestCounts() const noexcept { return impl_->edgeTestCounts(); }
std::int64_t CollisionDetector::work() const noexcept { return impl_->work(); }
std::int64_t CollisionDetector::budgetWork() const noexcept { return impl_->budgetWork(); }
void CollisionDetector::setContactCap(std::size_t cap) noexcept { impl_->setContactCap(cap); }
std::size_t CollisionDetector::contactCap() const noexcept { return impl_->contactCap(); }
void CollisionDetector::setWorkBudget(std::int64_t units) noexcept { impl_->setWorkBudget(units); }
void CollisionDetector::setDeadline(std::chrono::steady_clock::time_point deadline) noexcept {
  impl_->setDeadline(deadline);
}
void CollisionDetector::clearDeadline() noexcept { impl_->clearDeadline(); }
bool CollisionDetector::deadlineReached() const noexcept { return impl_->deadlineReached(); }
void CollisionDetector::setWorkDeadline(std::int64_t work) noexcept { impl_->setWorkDeadline(work); }
std::int64_t CollisionDetector::deadlineWork() const noexcept { return impl_->deadlineWork(); }
void CollisionDetector::setLanes(int lanes) { impl_->setLanes(lanes); }
int CollisionDetector::lanes() const noexcept { return impl_->lanes(); }
void CollisionDetector::addWork(std::int64_t units) noexcept { impl_->addWork(units); }
bool CollisionDetector::budgetSpent() const noexcept { return impl_->budgetSpent(); }
std::int64_t CollisionDetector::workBudget() const noexcept { return impl_->workBudget(); }
void CollisionDetector::resetSampleCount() noexcept { impl_->resetSampleCount(); }

CollisionDetector::Impl::Impl(const ScalarVolume& volume, const ToolModel& tool, double epsilon_m,
                              std::size_t max_contacts, DetectionMode mode, double segment_fraction,
                              SegmentTest segment_test)
    : volume_(&volume), tool_(&tool), mode_(mode), segment_test_(segment_test), feature_(volume.featureSize_m()) {
  if (!(segment_fraction > 0.0 && segment_fraction <= 1.0))
    throw std::invalid_argument("CollisionDetector: segment_fraction " + std::to_string(segment_fraction) +
                                " must be in (0, 1]");
  segment_length_m_ = feature_ * segment_fraction;
  if (tool.point_shell.empty()) throw std::invalid_argument("CollisionDetector: the point shell is empty");
  if (volume.empty()) throw std::invalid_argument("CollisionDetector: the volume is empty");
  epsilon_ = epsilon_m > 0.0 ? epsilon_m : 0.125 * feature_;  // f / 8: bench accuracy
  bisection_tolerance_ = epsilon_ / 8.0;
  if (!(epsilon_ < feature_) || !std::isfinite(epsilon_))
    throw std::invalid_argument("CollisionDetector: epsilon " + std::to_string(epsilon_) +
                                " m must be smaller than the feature size " + std::to_string(feature_) + " m");
  // A rotating point's arc leaves its chord by at most this much; the exact test lowers the
  // threshold by the Lipschitz bound times it (README, "Never through").
  if (segment_test_ == SegmentTest::kExact) max_sagitta_ = epsilon_ / 64.0;
  for (const auto& p : tool.point_shell.points_T_m())
    shell_radius_m_ = std::max(shell_radius_m_, (p - tool.mass.p_TCm_m).norm());
  const std::size_t n = tool.point_shell.size();
  pt_.assign(n, PointState{});
  search_.assign(n, PointSearch{});
  started_.assign(n, 0u);
  heap_.resize(n);
  embedded_.assign(n, 0);
  in_set_.assign(n, 0);
  contacts_.resize(std::max<std::size_t>(max_contacts, 1));
  if (mode_ == DetectionMode::kAccelerated) {
    order_.resize(n);
    for (std::size_t j = 0; j < n; ++j) order_[j] = static_cast<int>(j);
    nodes_.reserve(2 * n);
    buildShellTree(0, static_cast<int>(n), 0);
    stack_.resize(nodes_.size() + 1);
    node_near_.assign(nodes_.size(), 0);
    active_.resize(n);
    setLanesPartition(1);
  }
  candidate_.resize(n);
  setup_work_ = std::max<std::int64_t>(1, static_cast<std::int64_t>(n) / 5000);
  reduce_position_.resize(n + contacts_.size());
  reduce_distance_.resize(n + contacts_.size());
  reduce_chosen_.resize(n + contacts_.size());
  grid_per_m_ = volume.geometry().spacing_m.cwiseInverse();
  grid_from_W_ = grid_per_m_.asDiagonal() * volume.geometry().direction_W.transpose();
  edges_ = makeShellEdges(tool.point_shell);
  edge_reach_m_.assign(n, 0.0);
  edge_clearance_.assign(2 * n, EdgeClearance{});
  edge_slot_.assign(n, 0);
  for (std::size_t j = 0; j < n; ++j)
    for (int e = edges_.offsets[j]; e < edges_.offsets[j + 1]; ++e)
      edge_reach_m_[j] = std::max(edge_reach_m_[j], (tool.point_shell.points_T_m()[static_cast<std::size_t>(edges_.targets[e])] -
                                                     tool.point_shell.points_T_m()[j]).norm());
  node_edge_near_.assign(nodes_.size(), 0);
  // The certificates in tree order where there is a tree: a leaf's points read theirs together.
  edge_clearance_index_.resize(n);
  for (std::size_t j = 0; j < n; ++j) edge_clearance_index_[j] = static_cast<int>(j);
  if (!order_.empty())
    for (std::size_t i = 0; i < n; ++i) edge_clearance_index_[static_cast<std::size_t>(order_[i])] = static_cast<int>(i);
}

SweepResult CollisionDetector::Impl::sweep(const RigidMotion& motion, double isovalue) noexcept {
  if (++chord_stamp_ == 0) {  // wrapped: forget every cached chord end
    for (PointSearch& q : search_) q.chord_end_stamp = 0u;
    chord_stamp_ = 1;
  }
  // The largest chord sagitta of any point this sweep (for the point-shell tree's node tests):
  // every point's sagitta is <= min(max_sagitta_, R angle^2 / 8), R the shell's radius.
  const double angle = motion.angle_rad();
  sweep_sagitta_ = max_sagitta_ > 0.0 && angle > 0.0
      ? std::min(max_sagitta_, shell_radius_m_ * angle * angle / 8.0) * (1.0 + 1e-9)
      : 0.0;
  return stopClear(mode_ == DetectionMode::kAccelerated ? sweepAccelerated(motion, isovalue) : sweepPaper(motion, isovalue));
}

SweepResult CollisionDetector::Impl::stopClear(SweepResult result) const noexcept {
  // The bisection's outside end may lie a rounding error from the surface; a contact that then
  // turns along the surface (a probe spun on a ball) has chords that dip under it by less than
  // any sagitta can be made, and would be held for good. Stopping the hit point a further
  // epsilon / 128 of its own travel earlier (proven free: it is before the first hit) leaves it
  // a clearance that the arc refinement resolves (its finest sagitta is epsilon / 262,144).
  if (result.hit_point < 0 || result.budget_cut || !(result.t > 0.0)) return result;
  const double path = pt_[static_cast<std::size_t>(result.hit_point)].path;
  if (path > 0.0) result.t = std::max(0.0, result.t - kStopClearanceFraction * epsilon_ / path);
  return result;
}

}  // namespace vh::haptics
