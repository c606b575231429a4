// Emergency (EMCY) reports (CiA 301, 7.2.7.1) and helpers that build them. The codes and the
// error register bit each sets are board.toml's [[emcy]] entries, generated into board/fields.hpp
// (board::EmcyId, board::info(EmcyId), board::emcy_code). The manufacturer part always starts
// with the object index (LE) of what the error is about.
#pragma once

#include <array>
#include <cstdint>

#include "HeartbeatConsumer.hpp"
#include "board/cia301.hpp"
#include "board/fields.hpp"

namespace co {

// Bits of the error register 0x1001 (CiA 301, 7.5.2.2).
namespace error_register = board::error_register;

namespace emcy_code {
inline constexpr std::uint16_t kErrorReset = cia301::kEmcyErrorReset;  // "error reset or no error"
}  // namespace emcy_code

// The manufacturer-specific error field of an EMCY frame (its last bytes, CiA 301 7.2.7.3.1).
using EmcyManufacturerBytes = std::array<std::uint8_t, cia301::emcy_layout::kManufacturerBytes>;

struct EmcyReport {
  std::uint16_t code = 0;
  std::uint8_t register_bits = 0;  // error register bits this error sets (besides kGeneric)
  EmcyManufacturerBytes manufacturer{};

  friend bool operator==(const EmcyReport&, const EmcyReport&) = default;
};

namespace emcy {

constexpr EmcyManufacturerBytes about_index(std::uint16_t object_index) {
  return {static_cast<std::uint8_t>(object_index & 0xFF),
          static_cast<std::uint8_t>(object_index >> 8), 0, 0, 0};
}

// The board's EMCY `id` about the object at `object_index`.
constexpr EmcyReport report(board::EmcyId id, std::uint16_t object_index) {
  const board::EmcyInfo& emcy = board::info(id);
  return {emcy.code, emcy.register_bit, about_index(object_index)};
}

// A component wrote a field it does not own (the board refused and kept the value).
constexpr EmcyReport ownership_violation(board::FieldId field) {
  return report(board::EmcyId::ownership_violation, board::info(field).index);
}
// A sensor field was not refreshed within its allowed number of cycles.
constexpr EmcyReport stale_sensor(board::FieldId field) {
  return report(board::EmcyId::stale_sensor, board::info(field).index);
}
// A temperature field crossed its limit.
constexpr EmcyReport over_temperature(board::FieldId field) {
  return report(board::EmcyId::over_temperature, board::info(field).index);
}
// Frames were lost on reception; `object_index` names what was lost (e.g. the RPDO's 0x1400+n).
constexpr EmcyReport receive_overrun(std::uint16_t object_index) {
  return report(board::EmcyId::receive_overrun, object_index);
}
// The CAN controller went bus-off (its driver reports it once it is back on the bus).
constexpr EmcyReport bus_off() { return report(board::EmcyId::bus_off, 0); }
// An RPDO shorter than its mapping arrived; `rpdo_comm_index` is 0x1400+n.
constexpr EmcyReport pdo_length_error(std::uint16_t rpdo_comm_index) {
  return report(board::EmcyId::pdo_length_error, rpdo_comm_index);
}
// An RPDO with an event timer (deadline) was not received in time; `rpdo_comm_index` is 0x1400+n.
constexpr EmcyReport rpdo_timeout(std::uint16_t rpdo_comm_index) {
  return report(board::EmcyId::rpdo_timeout, rpdo_comm_index);
}

// A heartbeat the node consumes timed out (0x1016); manufacturer byte 2 names the lost node.
constexpr EmcyReport heartbeat_error(std::uint8_t lost_node_id) {
  EmcyReport error = report(board::EmcyId::heartbeat_error, HeartbeatConsumer::kIndex);
  error.manufacturer[2] = lost_node_id;
  return error;
}

}  // namespace emcy
}  // namespace co
