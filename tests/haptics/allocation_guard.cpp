#include "allocation_guard.h"

#include <cstdlib>
#include <new>

namespace {
thread_local bool g_counting = false;
thread_local std::size_t g_count = 0;
}  // namespace

namespace vh::test {
AllocationGuard::AllocationGuard() { g_count = 0; g_counting = true; }
AllocationGuard::~AllocationGuard() { g_counting = false; }
std::size_t AllocationGuard::count() const { return g_count; }
}  // namespace vh::test

void* operator new(std::size_t size) {
  if (g_counting) ++g_count;
  if (void* p = std::malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
void* operator new(std::size_t size, std::align_val_t al) {
  if (g_counting) ++g_count;
  const std::size_t a = static_cast<std::size_t>(al);
  if (void* p = std::aligned_alloc(a, (size + a - 1) / a * a)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size, std::align_val_t al) { return operator new(size, al); }
// The nothrow forms too (std::stable_sort's temporary buffer uses them): without them the
// runtime's nothrow new paired with the free() below (an ASan alloc-dealloc-mismatch) and those
// allocations escaped the count.
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  if (g_counting) ++g_count;
  return std::malloc(size ? size : 1);
}
void* operator new[](std::size_t size, const std::nothrow_t& t) noexcept { return operator new(size, t); }
void* operator new(std::size_t size, std::align_val_t al, const std::nothrow_t&) noexcept {
  if (g_counting) ++g_count;
  const std::size_t a = static_cast<std::size_t>(al);
  return std::aligned_alloc(a, (size + a - 1) / a * a);
}
void* operator new[](std::size_t size, std::align_val_t al, const std::nothrow_t& t) noexcept {
  return operator new(size, al, t);
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }
