#pragma once
// Counts heap allocations made by the current thread while a guard is alive (Drake's
// "LimitMalloc" idea): the servo tick must allocate nothing.
#include <cstddef>

namespace vh::test {
class AllocationGuard {
 public:
  AllocationGuard();
  ~AllocationGuard();
  /// Allocations since construction on this thread.
  std::size_t count() const;
};
}  // namespace vh::test
