// The point-shell tree (kAccelerated): its node, and its depth-first walk (the tree is built in
// shell_tree.cpp). Private to the collision detector (collision_detector_impl.h).
#pragma once

#include <vector>

#include <Eigen/Core>

namespace vh::haptics::detail {

// Node of the point-shell tree (kAccelerated): a ball in T holding points order_[begin, end).
struct ShellNode {
  Eigen::Vector3d center_T_m = Eigen::Vector3d::Zero();
  double radius_m = 0.0;
  int begin = 0, end = 0;
  int left = -1, right = -1;  // children, -1 for a leaf
};

// Walks the tree `nodes` below node `root` depth first, left before right, on `stack`
// (capacity: the nodes): a node for which may_hold(node) is false is skipped with all below
// it; visit(j) is called on each point order[i] of the leaves reached, in tree order, and ends
// the walk by returning true. Returns whether a visit ended it.
template <typename MayHold, typename Visit>
bool walkShellTree(const std::vector<ShellNode>& nodes, const std::vector<int>& order, int* stack, int root,
                   MayHold&& may_hold, Visit&& visit) noexcept {
  int top = 0;
  stack[top++] = root;
  while (top > 0) {
    const ShellNode& node = nodes[stack[--top]];
    if (!may_hold(node)) continue;
    if (node.left >= 0) {
      stack[top++] = node.right;
      stack[top++] = node.left;
      continue;
    }
    for (int i = node.begin; i < node.end; ++i)
      if (visit(order[i])) return true;
  }
  return false;
}

}  // namespace vh::haptics::detail
