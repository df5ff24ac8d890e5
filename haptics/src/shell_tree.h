// The point-shell tree's depth-first walk (CollisionDetector::walkShellTree(); the tree is built
// in shell_tree.cpp). Private to the collision detector.
#pragma once

#include "vh/haptics/collision_detector.h"

namespace vh::haptics {

template <typename MayHold, typename Visit>
bool CollisionDetector::walkShellTree(int* stack, int root, MayHold&& may_hold, Visit&& visit) const noexcept {
  int top = 0;
  stack[top++] = root;
  while (top > 0) {
    const ShellNode& node = nodes_[stack[--top]];
    if (!may_hold(node)) continue;
    if (node.left >= 0) {
      stack[top++] = node.right;
      stack[top++] = node.left;
      continue;
    }
    for (int i = node.begin; i < node.end; ++i)
      if (visit(order_[i])) return true;
  }
  return false;
}

}  // namespace vh::haptics

