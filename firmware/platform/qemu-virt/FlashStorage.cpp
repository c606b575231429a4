// The CFI 01 commands (Intel/Sharp command set, as JEDEC's CFI and Intel's StrataFlash
// datasheets give them) on the virt machine's pflash: 32-bit bus, two 16-bit chips side by
// side, so each command is written to both halves of the word.
#include "FlashStorage.hpp"

#include <algorithm>
#include <cstring>

#include "Machine.hpp"
#include "canopen/ParameterImage.hpp"

namespace virt {
namespace {

constexpr std::uint32_t both_chips(std::uint32_t command) { return command | (command << 16); }
constexpr std::uint32_t kReadArray = both_chips(0xFF);
constexpr std::uint32_t kClearStatus = both_chips(0x50);
constexpr std::uint32_t kBlockErase = both_chips(0x20);
constexpr std::uint32_t kConfirm = both_chips(0xD0);
constexpr std::uint32_t kProgramWord = both_chips(0x40);
constexpr std::uint32_t kStatusReady = both_chips(0x80);
constexpr std::uint32_t kStatusErrors = both_chips(0x3A);  // erase, program, voltage, lock errors
constexpr std::uint32_t kHeaderWords = 3;

}  // namespace

bool FlashStorage::wait_ready() {
  std::uint32_t status = 0;
  for (std::uint32_t polls = 0; polls < 10'000'000u; ++polls) {
    status = mmio32(address_);
    if ((status & kStatusReady) == kStatusReady) break;
  }
  mmio32(address_) = kClearStatus;
  mmio32(address_) = kReadArray;
  return (status & kStatusReady) == kStatusReady && (status & kStatusErrors) == 0;
}

bool FlashStorage::erase() {
  mmio32(address_) = kBlockErase;
  mmio32(address_) = kConfirm;
  return wait_ready();
}

bool FlashStorage::program(std::uint32_t offset, std::uint32_t word) {
  mmio32(address_ + offset) = kProgramWord;
  mmio32(address_ + offset) = word;
  return wait_ready();
}

bool FlashStorage::save(std::span<const std::byte> image) {
  if (image.size() + 4 * kHeaderWords > block_bytes_) return false;
  if (!erase()) return false;
  // The image first, the header last: until the magic is there the record does not exist.
  const std::uint32_t length = static_cast<std::uint32_t>(image.size());
  for (std::uint32_t offset = 0; offset < length; offset += 4) {
    std::uint32_t word = 0xFFFF'FFFFu;
    std::memcpy(&word, image.data() + offset, std::min<std::uint32_t>(4, length - offset));
    if (!program(4 * kHeaderWords + offset, word)) return false;
  }
  return program(8, co::parameter_image::crc32(image)) && program(4, length) && program(0, kMagic);
}

std::size_t FlashStorage::load(std::span<std::byte> buffer) {
  if (mmio32(address_) != kMagic) return 0;
  const std::uint32_t length = mmio32(address_ + 4);
  const std::uint32_t crc = mmio32(address_ + 8);
  if (length > buffer.size() || length + 4 * kHeaderWords > block_bytes_) return 0;
  for (std::uint32_t offset = 0; offset < length; offset += 4) {
    const std::uint32_t word = mmio32(address_ + 4 * kHeaderWords + offset);
    std::memcpy(buffer.data() + offset, &word, std::min<std::uint32_t>(4, length - offset));
  }
  return co::parameter_image::crc32(buffer.first(length)) == crc ? length : 0;
}

}  // namespace virt
