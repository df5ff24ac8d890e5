// The accelerated sweep's lanes on several cores (haptics/README.md, "Several cores"): the
// point-shell tree's upper nodes dealt to the lanes, round robin at first and then by the work
// each node cost (rebalanceLanes()), and the lanes' work joined into the caller's budget.
#include "collision_detector_impl.h"

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "vh/haptics/worker_pool.h"

namespace vh::haptics {

void CollisionDetector::Impl::setLanes(int lanes) {
  if (lanes < 1 || lanes > WorkerPool::kMaxLanes)
    throw std::invalid_argument("CollisionDetector: " + std::to_string(lanes) + " lanes, must be in [1, " +
                                std::to_string(WorkerPool::kMaxLanes) + "]");
  if (mode_ != DetectionMode::kAccelerated) return;
  pending_.active = false;  // a sweep in progress was dealt to the old lanes
  pool_.reset();
  setLanesPartition(lanes);
  if (lanes_.size() > 1) pool_ = WorkerPool::shared(static_cast<int>(lanes_.size()));
}

void CollisionDetector::Impl::setLanesPartition(int lanes) {
  // The tree's upper nodes, split until there are kRootsPerLane per lane (or nodes of at most
  // kMinRootPoints points): dealt round robin in tree order for the first sweep (then by their
  // work, rebalanceLanes()), so that the part of the tool near a surface (a spatial cluster of
  // nodes) is shared by the lanes instead of falling to one. The
  // work of a tool touching with a small part of itself (a drill's burr) lies in a few nodes of
  // the tree: at 8 roots per lane the 20,000-point drill on the CT's bone gained nothing from a
  // second lane (0.99x), at 64 it ran 1.5x faster. Nodes are not split below kMinRootPoints, so
  // a small tool keeps the culling of its upper nodes (roots that are single leaves cost a box
  // query each per tick).
  constexpr std::size_t kRootsPerLane = 64;
  constexpr int kMinRootPoints = 32;
  std::vector<int> frontier{0};
  const std::size_t wanted = static_cast<std::size_t>(lanes) * kRootsPerLane;
  while (lanes > 1 && frontier.size() < wanted) {
    std::vector<int> next;
    bool split = false;
    for (const int node : frontier) {
      if (nodes_[node].left >= 0 && nodes_[node].end - nodes_[node].begin > kMinRootPoints) {
        next.push_back(nodes_[node].left);
        next.push_back(nodes_[node].right);
        split = true;
      } else {
        next.push_back(node);
      }
    }
    frontier.swap(next);
    if (!split) break;
  }
  const int used = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(lanes), frontier.size()));
  const std::size_t n = tool_->point_shell.size();
  balanced_lanes_ = used > 1 && used <= kMaxBalancedLanes;
  lanes_.assign(static_cast<std::size_t>(used), Lane{});
  rank_of_point_.assign(n, 0);
  root_lane_.assign(frontier.size(), 0);
  std::vector<std::size_t> points(static_cast<std::size_t>(used), 0);
  for (Lane& l : lanes_) {
    l.roots.reserve(frontier.size());  // a rebalance never allocates
    l.root_ranks.reserve(frontier.size());
    if (balanced_lanes_) l.root_work.assign(frontier.size(), 0);
  }
  for (std::size_t i = 0; i < frontier.size(); ++i) {
    const int lane = static_cast<int>(i % static_cast<std::size_t>(used));
    const ShellNode& node = nodes_[frontier[i]];
    lanes_[lane].roots.push_back(frontier[i]);
    lanes_[lane].root_ranks.push_back(static_cast<int>(i));
    root_lane_[i] = lane;
    points[lane] += static_cast<std::size_t>(node.end - node.begin);
    for (int p = node.begin; p < node.end; ++p) rank_of_point_[order_[p]] = static_cast<int>(i);
  }
  for (int lane = 0; lane < used; ++lane) {
    Lane& l = lanes_[lane];
    const std::size_t room = balanced_lanes_ ? n : points[lane];  // balanced: any share fits
    l.heap.resize(std::max<std::size_t>(room, 1));
    l.active.resize(std::max<std::size_t>(room, 1));
    l.stack.resize(nodes_.size() + 1);
    l.walk_log.resize(nodes_.size() + 1);
    l.walk_logged = 0;
  }
  frontier_ = std::move(frontier);
}

void CollisionDetector::Impl::rebalanceLanes() noexcept {
  // The first deal is round robin (setLanesPartition()); from then on the nodes, in the tree's
  // order, each go to the lane with the least work so far, weighed by their work last time
  // (every node at least 1, so unworked ones spread too). Neighbouring heavy nodes (a drill's
  // burr) so go to different lanes, as round robin would deal them, and light ones fill the rest.
  const std::size_t roots = frontier_.size();
  bool measured = false;
  for (std::size_t r = 0; r < roots && !measured; ++r)
    measured = lanes_[static_cast<std::size_t>(root_lane_[r])].root_work[r] > 0;
  if (!measured) return;  // no lane has worked since the last deal (a sweep ended at its contacts)
  std::array<std::int64_t, kMaxBalancedLanes> load{};
  const int lanes = static_cast<int>(lanes_.size());
  for (Lane& lane : lanes_) {
    lane.roots.clear();  // within their reserved capacity from here on
    lane.root_ranks.clear();
  }
  for (std::size_t r = 0; r < roots; ++r) {
    // The work charged to node r since the last deal, by the lane that held it (read and
    // cleared before the node changes lanes below).
    std::int64_t& work = lanes_[static_cast<std::size_t>(root_lane_[r])].root_work[r];
    const std::int64_t weight = work + 1;
    work = 0;
    int lane = 0;
    for (int l = 1; l < lanes; ++l)
      if (load[static_cast<std::size_t>(l)] < load[static_cast<std::size_t>(lane)]) lane = l;
    load[static_cast<std::size_t>(lane)] += weight;
    root_lane_[r] = lane;
    lanes_[static_cast<std::size_t>(lane)].roots.push_back(frontier_[r]);
    lanes_[static_cast<std::size_t>(lane)].root_ranks.push_back(static_cast<int>(r));
  }
}

void CollisionDetector::Impl::startLaneWork(Lane& lane) const noexcept {
  lane.base_work = budgetWork();
  lane.counters = {};
  lane.clock = clock_;
}

void CollisionDetector::Impl::joinLaneWork() noexcept {
  // The work adds up; the budget counts the busiest lane (they ran side by side).
  std::int64_t busiest = 0, sum = 0;
  for (const Lane& lane : lanes_) {
    const std::int64_t w = lane.counters.total();
    counters_ += lane.counters;
    sum += w;
    busiest = std::max(busiest, w);
    if (lane.clock.late && !deadline_hit_) {
      deadline_hit_ = true;
      lane_late_work_ = lane.clock.late_work;
    }
  }
  parallel_credit_ += sum - busiest;
}

}  // namespace vh::haptics
