// The firmware image's operator new and delete over the start-up arena (StartupArena.hpp).
#include "StartupArena.hpp"

#include <cstddef>
#include <new>

extern "C" [[noreturn]] void hil_fault(const char* what);

namespace cortexm::arena {
namespace {

alignas(std::max_align_t) std::byte g_arena[kBytes];
std::size_t g_used = 0;
std::size_t g_high_water = 0;
bool g_sealed = false;

}  // namespace

void reopen_empty() {
  g_used = 0;
  g_sealed = false;
}

void seal() { g_sealed = true; }

std::size_t high_water() { return g_high_water; }

void* allocate(std::size_t size) {
  if (g_sealed) hil_fault("allocation after start-up");
  const std::size_t aligned = (size + alignof(std::max_align_t) - 1) & ~(alignof(std::max_align_t) - 1);
  if (aligned > kBytes - g_used) hil_fault("start-up arena exhausted");
  void* block = g_arena + g_used;
  g_used += aligned;
  if (g_used > g_high_water) g_high_water = g_used;
  return block;
}

}  // namespace cortexm::arena

void* operator new(std::size_t size) { return cortexm::arena::allocate(size); }
void* operator new[](std::size_t size) { return cortexm::arena::allocate(size); }
// Blocks come back all at once (reopen_empty), not one by one.
void operator delete(void*) noexcept {}
void operator delete[](void*) noexcept {}
void operator delete(void*, std::size_t) noexcept {}
void operator delete[](void*, std::size_t) noexcept {}
