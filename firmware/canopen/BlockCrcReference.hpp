// An independent CRC for checking SDO block transfers in tests and the fuzzer: CRC-16/CCITT as
// CiA 301 defines it (polynomial 0x1021, initial value 0), written in the byte-wise shift form
// so that it shares no code or shape with the server's bitwise loop. Not used by the firmware.
#pragma once

#include <cstdint>
#include <span>

namespace co::test {

inline std::uint16_t reference_crc(std::span<const std::uint8_t> bytes) {
  std::uint16_t crc = 0;
  for (const std::uint8_t byte : bytes) {
    auto x = static_cast<std::uint16_t>((crc >> 8) ^ byte);
    x = static_cast<std::uint16_t>(x ^ (x >> 4));
    crc = static_cast<std::uint16_t>((crc << 8) ^ (x << 12) ^ (x << 5) ^ x);
  }
  return crc;
}

}  // namespace co::test
