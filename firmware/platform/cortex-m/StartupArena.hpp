// The firmware image's only dynamic memory: a fixed arena in .bss for what the core's scheduler
// builds at start-up (its update order and, on a failure, the message), handed out by the
// image's operator new and never freed piece by piece. Once the application has started the
// arena is sealed: an allocation in the control cycle stops the firmware (hil_fault) instead of
// growing anything. NMT reset node rebuilds the application from an empty arena. There is no
// malloc and no _sbrk in the image at all (CMakeLists.txt makes a call to one a link error).
#pragma once

#include <cstddef>

namespace cortexm::arena {

// A few times what the demo joint's start-up takes (its high-water mark, g_high_water, read in
// qemu); the boot check (cortex_m.firmware_boots) starts the application from it.
inline constexpr std::size_t kBytes = 4 * 1024;

// Allocations allowed again, from an empty arena: only when nothing allocated is alive.
void reopen_empty();
// No allocation from now on.
void seal();
// The most the arena has held.
std::size_t high_water();

}  // namespace cortexm::arena
