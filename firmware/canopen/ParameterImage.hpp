// The byte image "store parameters" (0x1010) writes: every `stored` board field as
// (object index, REAL32), behind a header with magic, format version and CRC-32, so a torn,
// foreign or corrupt image is rejected instead of loaded.
//
// Layout, little endian:
//   0: u32 magic "HILP"   4: u16 format version   6: u16 entry count   8: u32 CRC-32 (IEEE) of
//   every byte of the image except these four     12: entries, 6 bytes each: u16 index, f32 value
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "Interfaces.hpp"
#include "board/fields.hpp"

namespace co::parameter_image {

inline constexpr std::uint32_t kMagic = 0x504C'4948u;  // "HILP" in file order
inline constexpr std::uint16_t kFormatVersion = 1;
inline constexpr std::size_t kHeaderBytes = 12;
inline constexpr std::size_t kEntryBytes = 6;
inline constexpr std::size_t kCapacity = kHeaderBytes + kEntryBytes * board::kFieldCount;

struct StoredValue {
  std::uint16_t index;
  float value;
};

enum class Check : std::uint8_t {
  Valid,    // header, size and CRC agree
  Empty,    // no bytes at all: nothing was ever stored
  Corrupt,  // wrong magic, version, size or CRC
};

// CRC-32 as in zlib/Ethernet (reflected polynomial 0xEDB88320).
std::uint32_t crc32(std::span<const std::byte> bytes);

// Writes the current value of every stored field; returns the image size (<= kCapacity).
std::size_t encode(FieldAccess& fields, std::span<std::byte, kCapacity> out);

// Validates `image`; on Valid sets `entry_count`.
Check check(std::span<const std::byte> image, std::size_t& entry_count);

// Entry `i` of an image that check() found Valid.
StoredValue entry(std::span<const std::byte> image, std::size_t i);

}  // namespace co::parameter_image
