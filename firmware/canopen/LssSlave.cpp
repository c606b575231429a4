#include "LssSlave.hpp"

#include "ParameterImage.hpp"
#include "board/cia301.hpp"

namespace co {
namespace {

constexpr std::uint32_t kStoredMagic = 0x3153'534C;  // "LSS1" in file order

std::uint32_t get_u32(std::span<const std::uint8_t> data, std::size_t at) {
  return static_cast<std::uint32_t>(data[at]) | static_cast<std::uint32_t>(data[at + 1]) << 8 |
         static_cast<std::uint32_t>(data[at + 2]) << 16 | static_cast<std::uint32_t>(data[at + 3]) << 24;
}

void put_u32(std::span<std::uint8_t> data, std::size_t at, std::uint32_t value) {
  for (std::size_t i = 0; i < 4; ++i) data[at + i] = static_cast<std::uint8_t>(value >> (8 * i));
}

bool valid_node_id(std::uint8_t node_id) {
  return cia301::is_node_id(node_id) || node_id == cia305::kNodeIdUnconfigured;
}

std::uint8_t error_byte(cia305::LssError error) { return static_cast<std::uint8_t>(error); }

void answer(LssOutcome& outcome, LssCommand command) {
  outcome.answer = true;
  outcome.answer_data.fill(0);
  outcome.answer_data[0] = static_cast<std::uint8_t>(command);
}

// Where the switch state selective and identify remote slave sequences stand: the number of
// parts received in order and matching, or kFailed until the sequence starts again.
constexpr std::uint8_t kFailed = 0xFF;

}  // namespace

LssSlave::LssSlave(const LssIdentity& identity, std::uint8_t node_id)
    : identity_(identity),
      active_node_id_(valid_node_id(node_id) ? node_id : cia305::kNodeIdUnconfigured),
      pending_node_id_(active_node_id_) {}

bool LssSlave::load() {
  if (storage_ == nullptr) return false;
  std::array<std::byte, kStoredBytes + 1> raw{};  // one more: a longer file is not ours
  if (storage_->load(raw) != kStoredBytes) return false;
  std::array<std::uint8_t, kStoredBytes> bytes{};
  for (std::size_t i = 0; i < kStoredBytes; ++i) bytes[i] = std::to_integer<std::uint8_t>(raw[i]);
  const std::uint32_t crc = parameter_image::crc32(std::span<const std::byte>(raw.data(), 6));
  if (get_u32(bytes, 0) != kStoredMagic || get_u32(bytes, 6) != crc || !valid_node_id(bytes[4]) ||
      cia305::bit_timing_kbits(bytes[5]) == 0) {
    return false;
  }
  active_node_id_ = pending_node_id_ = bytes[4];
  pending_bit_timing_ = bytes[5];
  return true;
}

bool LssSlave::store() {
  std::array<std::uint8_t, kStoredBytes> bytes{};
  put_u32(bytes, 0, kStoredMagic);
  bytes[4] = pending_node_id_;
  bytes[5] = pending_bit_timing_;
  std::array<std::byte, kStoredBytes> raw{};
  for (std::size_t i = 0; i < 6; ++i) raw[i] = static_cast<std::byte>(bytes[i]);
  put_u32(bytes, 6, parameter_image::crc32(std::span<const std::byte>(raw.data(), 6)));
  for (std::size_t i = 6; i < kStoredBytes; ++i) raw[i] = static_cast<std::byte>(bytes[i]);
  return storage_->save(raw);
}

std::uint8_t LssSlave::activate_pending_node_id() {
  active_node_id_ = pending_node_id_;
  return active_node_id_;
}

LssOutcome LssSlave::process(std::span<const std::uint8_t> data) {
  LssOutcome outcome;
  if (data.size() != cia305::kFrameBytes) {
    ++counters_.malformed;
    return outcome;
  }
  ++counters_.requests;
  const auto command = static_cast<LssCommand>(data[0]);
  const std::uint32_t value = get_u32(data, 1);
  bool served = enabled_;
  if (served) {
    switch (command) {
      case LssCommand::SwitchStateGlobal: switch_state_global(data[1], outcome); break;
      case LssCommand::SwitchStateSelectiveVendorId:
      case LssCommand::SwitchStateSelectiveProductCode:
      case LssCommand::SwitchStateSelectiveRevision:
      case LssCommand::SwitchStateSelectiveSerial:
        served = state_ == LssState::Waiting;
        if (served) switch_state_selective(command, value, outcome);
        break;
      case LssCommand::IdentifyRemoteVendorId:
      case LssCommand::IdentifyRemoteProductCode:
      case LssCommand::IdentifyRemoteRevisionLow:
      case LssCommand::IdentifyRemoteRevisionHigh:
      case LssCommand::IdentifyRemoteSerialLow:
      case LssCommand::IdentifyRemoteSerialHigh: identify_remote(command, value, outcome); break;
      case LssCommand::IdentifyNonConfiguredRemote:
        served = non_configured();
        if (served) answer(outcome, LssCommand::IdentifyNonConfiguredSlave);
        break;
      case LssCommand::Fastscan:
        served = state_ == LssState::Waiting && non_configured();
        if (served) fastscan(data, outcome);
        break;
      default:
        served = state_ == LssState::Configuration;
        if (served) configure(data, outcome);
        break;
    }
  }
  if (!served) ++counters_.ignored;
  if (outcome.answer) ++counters_.answers;
  return outcome;
}

void LssSlave::switch_state_global(std::uint8_t mode, LssOutcome& outcome) {
  if (mode == static_cast<std::uint8_t>(LssState::Configuration)) {
    state_ = LssState::Configuration;
    return;
  }
  if (mode != static_cast<std::uint8_t>(LssState::Waiting)) return;  // reserved mode: no change
  // A node that had no id and was given one takes it now (its boot-up tells the master).
  if (state_ == LssState::Configuration && active_node_id_ == cia305::kNodeIdUnconfigured &&
      pending_node_id_ != cia305::kNodeIdUnconfigured) {
    outcome.action = LssAction::ActivateNodeId;
  }
  state_ = LssState::Waiting;
  selective_step_ = 0;
}

void LssSlave::switch_state_selective(LssCommand command, std::uint32_t value, LssOutcome& outcome) {
  const auto step = static_cast<std::uint8_t>(static_cast<std::uint8_t>(command) -
                                              static_cast<std::uint8_t>(LssCommand::SwitchStateSelectiveVendorId));
  if (step == 0) selective_step_ = 0;
  if (selective_step_ != step) {  // out of order, or an earlier part did not match
    selective_step_ = kFailed;
    return;
  }
  if (value != identity_.part(step)) {
    selective_step_ = kFailed;
    return;
  }
  selective_step_ = static_cast<std::uint8_t>(step + 1);
  if (command == LssCommand::SwitchStateSelectiveSerial) {
    selective_step_ = 0;
    state_ = LssState::Configuration;
    answer(outcome, LssCommand::SwitchStateSelectiveResponse);
  }
}

void LssSlave::identify_remote(LssCommand command, std::uint32_t value, LssOutcome& outcome) {
  const auto step = static_cast<std::uint8_t>(static_cast<std::uint8_t>(command) -
                                              static_cast<std::uint8_t>(LssCommand::IdentifyRemoteVendorId));
  if (step == 0) identify_step_ = 0;
  if (identify_step_ != step) {
    identify_step_ = kFailed;
    return;
  }
  bool match = true;
  switch (command) {
    case LssCommand::IdentifyRemoteVendorId: match = value == identity_.vendor_id; break;
    case LssCommand::IdentifyRemoteProductCode: match = value == identity_.product_code; break;
    case LssCommand::IdentifyRemoteRevisionLow:
    case LssCommand::IdentifyRemoteSerialLow: identify_low_ = value; break;
    case LssCommand::IdentifyRemoteRevisionHigh:
      match = identify_low_ <= identity_.revision && identity_.revision <= value;
      break;
    default:  // IdentifyRemoteSerialHigh
      match = identify_low_ <= identity_.serial_number && identity_.serial_number <= value;
      break;
  }
  if (!match) {
    identify_step_ = kFailed;
    return;
  }
  identify_step_ = static_cast<std::uint8_t>(step + 1);
  if (command == LssCommand::IdentifyRemoteSerialHigh) {
    identify_step_ = 0;
    answer(outcome, LssCommand::IdentifySlave);
  }
}

void LssSlave::fastscan(std::span<const std::uint8_t> data, LssOutcome& outcome) {
  const std::uint32_t id_number = get_u32(data, 1);
  const std::uint8_t bit_check = data[5];
  const std::uint8_t sub = data[6];
  const std::uint8_t next = data[7];
  if ((bit_check > cia305::kFastscanHighestBit && bit_check != cia305::kFastscanConfirm) ||
      sub >= cia305::kIdentityParts || next >= cia305::kIdentityParts) {
    return;  // not a valid fastscan request: no answer
  }
  if (bit_check == cia305::kFastscanConfirm) {  // every non-configured slave starts again
    fastscan_part_ = 0;
    answer(outcome, LssCommand::IdentifySlave);
    return;
  }
  if (fastscan_part_ != sub) return;  // dropped out of this scan earlier
  const std::uint32_t mask = 0xFFFF'FFFFu << bit_check;
  if ((identity_.part(sub) & mask) != (id_number & mask)) return;
  fastscan_part_ = next;
  // Bit 0 of a part with the scan going back to an earlier one: the whole address matched.
  if (bit_check == 0 && next < sub) state_ = LssState::Configuration;
  answer(outcome, LssCommand::IdentifySlave);
}

void LssSlave::configure(std::span<const std::uint8_t> data, LssOutcome& outcome) {
  const auto command = static_cast<LssCommand>(data[0]);
  switch (command) {
    case LssCommand::ConfigureNodeId: {
      const bool ok = valid_node_id(data[1]);
      if (ok) pending_node_id_ = data[1];
      answer(outcome, command);
      outcome.answer_data[1] = error_byte(ok ? cia305::LssError::Success : cia305::LssError::Refused);
      return;
    }
    case LssCommand::ConfigureBitTiming: {
      const bool ok = data[1] == cia305::kBitTimingStandardTable && cia305::bit_timing_kbits(data[2]) != 0;
      if (ok) pending_bit_timing_ = data[2];
      answer(outcome, command);
      outcome.answer_data[1] = error_byte(ok ? cia305::LssError::Success : cia305::LssError::Refused);
      return;
    }
    case LssCommand::ActivateBitTiming:
      outcome.action = LssAction::ActivateBitTiming;
      outcome.switch_delay_ms = static_cast<std::uint16_t>(data[1] | data[2] << 8);
      return;
    case LssCommand::StoreConfiguration: {
      cia305::LssError error = cia305::LssError::Success;
      if (storage_ == nullptr) {
        error = cia305::LssError::Refused;
      } else if (!store()) {
        error = cia305::LssError::StorageFailed;
      }
      answer(outcome, command);
      outcome.answer_data[1] = error_byte(error);
      return;
    }
    case LssCommand::InquireVendorId:
    case LssCommand::InquireProductCode:
    case LssCommand::InquireRevision:
    case LssCommand::InquireSerial: {
      const auto part = static_cast<std::size_t>(static_cast<std::uint8_t>(command) -
                                                 static_cast<std::uint8_t>(LssCommand::InquireVendorId));
      answer(outcome, command);
      put_u32(outcome.answer_data, 1, identity_.part(part));
      return;
    }
    case LssCommand::InquireNodeId:
      answer(outcome, command);
      outcome.answer_data[1] = active_node_id_;
      return;
    default: return;  // a specifier CiA 305 does not define: no answer
  }
}

}  // namespace co
