// The byte image "store parameters" (0x1010) writes: one entry per stored object (index,
// sub-index, raw value), behind a header with magic, format version and CRC-32, so a torn,
// foreign or corrupt image is rejected instead of loaded. Board fields carry their REAL32 bits;
// communication objects (0x1005, 0x1016, 0x1017, 0x1019, 0x1020, PDO records) their integer value.
//
// Layout, little endian:
//   0: u32 magic "HILP"   4: u16 format version   6: u16 entry count   8: u32 CRC-32 (IEEE) of
//   every byte of the image except these four     12: entries
// Format 2 entries are 7 bytes: u16 index, u8 sub-index, u32 raw value.
// Format 1 (board fields only, before communication parameters were stored) is still read:
// 6-byte entries u16 index, f32 value, sub-index 0.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "board/fields.hpp"

namespace co::parameter_image {

inline constexpr std::uint32_t kMagic = 0x504C'4948u;  // "HILP" in file order
inline constexpr std::uint16_t kFormatVersion = 2;
inline constexpr std::uint16_t kFieldsOnlyFormatVersion = 1;
inline constexpr std::size_t kHeaderBytes = 12;
inline constexpr std::size_t kEntryBytes = 7;
inline constexpr std::size_t kFieldsOnlyEntryBytes = 6;
// 0x1005, 0x1017, 0x1019, 0x1020:01/02, 0x1029:01; 0x1016:01..n; per RPDO sub 1/2/3/5 +
// mapping sub 0..8; per TPDO also sub 6.
inline constexpr std::size_t kMaxCommunicationEntries =
    6 + board::kHeartbeatConsumers + board::kRpdoCount * (4 + 9) + board::kTpdoCount * (5 + 9);
inline constexpr std::size_t kMaxEntries = board::kFieldCount + kMaxCommunicationEntries;
inline constexpr std::size_t kCapacity = kHeaderBytes + kEntryBytes * kMaxEntries;

struct StoredValue {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::uint32_t raw = 0;  // REAL32 bits for board fields
};

// Communication profile objects (0x1000..0x1FFF) versus the application (board fields).
constexpr bool is_communication(std::uint16_t index) { return index < 0x2000; }

enum class Check : std::uint8_t {
  Valid,    // header, size and CRC agree
  Empty,    // no bytes at all: nothing was ever stored
  Corrupt,  // wrong magic, version, size or CRC
};

// CRC-32 as in zlib/Ethernet (reflected polynomial 0xEDB88320).
std::uint32_t crc32(std::span<const std::byte> bytes);
// The CRC-32 of a value given piece by piece: `previous` is the result for the bytes before
// these (0 for none), as zlib's crc32(bytes, previous).
std::uint32_t crc32(std::span<const std::byte> bytes, std::uint32_t previous);

// Writes `values` (at most kMaxEntries) in the current format; returns the image size.
std::size_t encode(std::span<const StoredValue> values, std::span<std::byte, kCapacity> out);

// Validates `image`; on Valid sets `entry_count`.
Check check(std::span<const std::byte> image, std::size_t& entry_count);

// Entry `i` of an image that check() found Valid (either format).
StoredValue entry(std::span<const std::byte> image, std::size_t i);

}  // namespace co::parameter_image
