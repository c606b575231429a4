#include "SoftwareVersion.hpp"

#include <array>
#include <cstring>

#include "board/cia302.hpp"
#include "board/fields.hpp"

namespace linuxhw {
namespace {

using Slot = std::array<char, cia302::kImageVersionBytes>;

constexpr Slot slot_of(std::string_view version) {
  Slot slot{};
  for (std::size_t i = 0; i < version.size() && i < slot.size(); ++i) slot[i] = version[i];
  return slot;
}
static_assert(board::kNode.software_version.size() < cia302::kImageVersionBytes);

}  // namespace

// Not in the anonymous namespace and `used`: the linker keeps it under its section name.
__attribute__((section(HIL_SOFTWARE_VERSION_SECTION), used)) constinit const Slot hil_software_version =
    slot_of(board::kNode.software_version);

std::string_view software_version() {
  // The compiler knows the initializer; the bytes in the file are what counts (they may have
  // been stamped after the build), so the read goes through an opaque pointer.
  const char* bytes = hil_software_version.data();
  asm volatile("" : "+r"(bytes));
  return {bytes, ::strnlen(bytes, cia302::kImageVersionBytes)};
}

}  // namespace linuxhw
