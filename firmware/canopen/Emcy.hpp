// Emergency error codes (CiA 301, 7.2.7.1) the firmware reports, and helpers that build them.
// The manufacturer part always starts with the object index (LE) of what the error is about.
#pragma once

#include <array>
#include <cstdint>

#include "board/fields.hpp"

namespace co {

// Bits of the error register 0x1001 (CiA 301, 7.5.2.2).
namespace error_register {
inline constexpr std::uint8_t kGeneric = 0x01;  // set whenever any error is active
inline constexpr std::uint8_t kCurrent = 0x02;
inline constexpr std::uint8_t kVoltage = 0x04;
inline constexpr std::uint8_t kTemperature = 0x08;
inline constexpr std::uint8_t kCommunication = 0x10;
inline constexpr std::uint8_t kDeviceProfile = 0x20;
inline constexpr std::uint8_t kManufacturer = 0x80;
}  // namespace error_register

namespace emcy_code {
inline constexpr std::uint16_t kErrorReset = 0x0000;
inline constexpr std::uint16_t kDeviceHardware = 0x5000;     // stale sensor
inline constexpr std::uint16_t kDeviceTemperature = 0x4210;  // over-temperature
inline constexpr std::uint16_t kCanOverrun = 0x8110;         // receive overrun, frames lost
inline constexpr std::uint16_t kPdoLengthError = 0x8210;     // PDO not processed: length error
inline constexpr std::uint16_t kRpdoTimeout = 0x8250;        // RPDO deadline (event timer) missed
inline constexpr std::uint16_t kOwnershipViolation = 0xFF00;  // manufacturer specific range
}  // namespace emcy_code

struct EmcyReport {
  std::uint16_t code = 0;
  std::uint8_t register_bits = 0;  // error register bits this error sets (besides kGeneric)
  std::array<std::uint8_t, 5> manufacturer{};

  friend bool operator==(const EmcyReport&, const EmcyReport&) = default;
};

namespace emcy {

constexpr std::array<std::uint8_t, 5> about_index(std::uint16_t object_index) {
  return {static_cast<std::uint8_t>(object_index & 0xFF),
          static_cast<std::uint8_t>(object_index >> 8), 0, 0, 0};
}

// A component wrote a field it does not own (the board refused and kept the value).
constexpr EmcyReport ownership_violation(board::FieldId field) {
  return {emcy_code::kOwnershipViolation, error_register::kManufacturer,
          about_index(board::info(field).index)};
}
// A sensor field was not refreshed within its allowed number of cycles.
constexpr EmcyReport stale_sensor(board::FieldId field) {
  return {emcy_code::kDeviceHardware, error_register::kGeneric, about_index(board::info(field).index)};
}
// A temperature field crossed its limit.
constexpr EmcyReport over_temperature(board::FieldId field) {
  return {emcy_code::kDeviceTemperature, error_register::kTemperature,
          about_index(board::info(field).index)};
}
// Frames were lost on reception; `object_index` names what was lost (e.g. the RPDO's 0x1400+n).
constexpr EmcyReport receive_overrun(std::uint16_t object_index) {
  return {emcy_code::kCanOverrun, error_register::kCommunication, about_index(object_index)};
}
// An RPDO shorter than its mapping arrived; `rpdo_comm_index` is 0x1400+n.
constexpr EmcyReport pdo_length_error(std::uint16_t rpdo_comm_index) {
  return {emcy_code::kPdoLengthError, error_register::kCommunication, about_index(rpdo_comm_index)};
}

// An RPDO with an event timer (deadline) was not received in time; `rpdo_comm_index` is 0x1400+n.
constexpr EmcyReport rpdo_timeout(std::uint16_t rpdo_comm_index) {
  return {emcy_code::kRpdoTimeout, error_register::kCommunication, about_index(rpdo_comm_index)};
}

}  // namespace emcy
}  // namespace co
