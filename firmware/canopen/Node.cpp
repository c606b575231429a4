// NMT slave, heartbeat producer, SYNC consumer, frame dispatch, EMCY producer, store/restore.
#include "Node.hpp"

#include <algorithm>

#include "ObjectTables.hpp"

namespace co {
namespace {

constexpr std::uint32_t kNmtCobId = 0x000;
constexpr std::uint32_t kEmcyCobIdBase = 0x080;
constexpr std::uint32_t kSdoRequestCobIdBase = 0x600;
constexpr std::uint32_t kSdoResponseCobIdBase = 0x580;
constexpr std::uint32_t kErrorControlCobIdBase = 0x700;  // boot-up and heartbeat
constexpr std::uint8_t kNmtBroadcast = 0;

static_assert(tables::hil_inputs_fit_int32(),
              "every HIL I/O object needs an integer type; inputs must fit int32 (HilIo)");
static_assert(board::kNode.device_name.size() <= SdoServer::kBufferBytes &&
                  board::kNode.hardware_version.size() <= SdoServer::kBufferBytes &&
                  board::kNode.software_version.size() <= SdoServer::kBufferBytes,
              "string objects must fit the SDO server's segment buffer");

}  // namespace

Node::Node(std::uint8_t node_id, CanPort& port, FieldAccess& fields, HilIo& hil,
           ParameterStorage& storage, std::uint32_t serial_number)
    : node_id_(node_id),
      port_(port),
      fields_(fields),
      hil_(hil),
      storage_(storage),
      serial_number_(serial_number),
      sdo_(object_access(*this)) {}

void Node::start(std::uint32_t now_us) {
  parameter_load_ = load_stored_parameters();
  reset_communication(now_us);
}

bool Node::send(std::uint32_t id, std::span<const std::uint8_t> data) {
  CanFrame frame;
  frame.id = id;
  frame.len = static_cast<std::uint8_t>(data.size());
  std::copy(data.begin(), data.end(), frame.data.begin());
  if (port_.send(frame) != SendResult::Sent) {
    ++counters_.send_failures;  // dropped: CANopen has no retransmission of these services
    return false;
  }
  return true;
}

ProcessResult Node::process(const CanFrame& frame, std::uint32_t now_us) {
  ProcessResult result;
  ++counters_.frames_received;
  constexpr std::uint32_t kFlags =
      CanFrame::kExtendedFlag | CanFrame::kRemoteFlag | CanFrame::kErrorFlag;
  if ((frame.id & kFlags) != 0 || frame.len > 8 || state_ == NmtState::Initialising) {
    ++counters_.frames_ignored;
    return result;
  }
  if (frame.id == kNmtCobId) {
    handle_nmt(frame, now_us, result);
    return result;
  }
  if (frame.id == (sync_cob_id_ & 0x7FFu) && state_ != NmtState::Stopped) {
    handle_sync(frame, result);
    return result;
  }
  if (state_ == NmtState::Stopped) {  // stopped: NMT only (heartbeat still goes out)
    ++counters_.frames_ignored;
    return result;
  }
  if (frame.id == kSdoRequestCobIdBase + node_id_) {
    handle_sdo(frame, now_us);
    return result;
  }
  if (state_ == NmtState::Operational) {
    for (std::size_t n = 0; n < rpdos_.size(); ++n) {
      if (rpdos_[n].valid() && rpdos_[n].can_id() == frame.id) {
        receive_rpdo(n, frame, now_us);
        return result;
      }
    }
  }
  ++counters_.frames_ignored;
  return result;
}

void Node::handle_nmt(const CanFrame& frame, std::uint32_t now_us, ProcessResult& result) {
  if (frame.len != 2) {
    ++counters_.frames_malformed;
    return;
  }
  const std::uint8_t target = frame.data[1];
  if (target != kNmtBroadcast && target != node_id_) {
    ++counters_.frames_ignored;
    return;
  }
  ++counters_.nmt_commands;
  switch (static_cast<NmtCommand>(frame.data[0])) {
    case NmtCommand::Start: enter(NmtState::Operational); return;
    case NmtCommand::Stop: enter(NmtState::Stopped); return;
    case NmtCommand::EnterPreOperational: enter(NmtState::PreOperational); return;
    case NmtCommand::ResetNode:
      apply_power_on_values();
      result.application_reset = true;
      reset_communication(now_us);
      return;
    case NmtCommand::ResetCommunication: reset_communication(now_us); return;
  }
  --counters_.nmt_commands;
  ++counters_.frames_malformed;  // unknown command specifier
}

void Node::enter(NmtState state) {
  if (state == state_) return;
  if (state == NmtState::Operational) reset_pdo_runtime();
  if (state == NmtState::Stopped) sdo_.reset();
  state_ = state;
}

void Node::reset_communication(std::uint32_t now_us) {
  sdo_.reset();
  sync_cob_id_ = 0x80;
  heartbeat_ms_ = board::kNode.heartbeat_ms;
  load_default_pdos();
  state_ = NmtState::PreOperational;
  last_heartbeat_us_ = now_us;
  const std::array<std::uint8_t, 1> boot_up = {static_cast<std::uint8_t>(NmtState::Initialising)};
  send(kErrorControlCobIdBase + node_id_, boot_up);
}

void Node::handle_sync(const CanFrame& frame, ProcessResult& result) {
  if (frame.len > 1) {  // SYNC carries nothing or a one-byte counter
    ++counters_.frames_malformed;
    return;
  }
  ++counters_.syncs_received;
  result.sync = true;
  result.sync_has_counter = frame.len == 1;
  result.sync_counter = frame.len == 1 ? frame.data[0] : 0;
  if (state_ != NmtState::Operational) return;
  // Synchronous RPDOs received since the last SYNC take effect now, before the control cycle.
  for (Pdo& pdo : rpdos_) {
    if (!pdo.buffered) continue;
    pdo.buffered = false;
    apply_rpdo(pdo, std::span<const std::uint8_t>(pdo.buffer.data(), pdo.payload_bytes));
  }
  for (Pdo& pdo : tpdos_) {
    if (!pdo.valid() || pdo.transmission_type > 240) continue;
    if (pdo.transmission_type == 0) {
      pdo.due_at_sync = true;
      continue;
    }
    if (++pdo.syncs_since_sent >= pdo.transmission_type) {
      pdo.syncs_since_sent = 0;
      pdo.due_at_sync = true;
    }
  }
}

void Node::handle_sdo(const CanFrame& frame, std::uint32_t now_us) {
  if (frame.len != 8) {  // SDO frames always carry 8 bytes (CiA 301, 7.2.4.3)
    ++counters_.frames_malformed;
    return;
  }
  ++counters_.sdo_requests;
  std::array<std::uint8_t, 8> response{};
  const std::uint32_t aborts_before = sdo_.aborts_sent();
  if (sdo_.handle(std::span<const std::uint8_t, 8>(frame.data), now_us, response)) {
    send(kSdoResponseCobIdBase + node_id_, response);
  }
  counters_.sdo_aborts_sent += sdo_.aborts_sent() - aborts_before;
}

void Node::poll(std::uint32_t now_us) {
  if (state_ == NmtState::Initialising) return;
  const std::uint32_t period_us = std::uint32_t{heartbeat_ms_} * 1000u;
  if (period_us != 0 && now_us - last_heartbeat_us_ >= period_us) {
    // Keep the cadence when poll() is a little late; restart it after a long gap.
    last_heartbeat_us_ += period_us;
    if (now_us - last_heartbeat_us_ >= period_us) last_heartbeat_us_ = now_us;
    const std::array<std::uint8_t, 1> heartbeat = {static_cast<std::uint8_t>(state_)};
    if (send(kErrorControlCobIdBase + node_id_, heartbeat)) ++counters_.heartbeats_sent;
  }
  if (state_ != NmtState::Stopped) {
    std::array<std::uint8_t, 8> response{};
    if (sdo_.check_timeout(now_us, response)) {
      ++counters_.sdo_aborts_sent;
      send(kSdoResponseCobIdBase + node_id_, response);
    }
  }
  if (state_ == NmtState::Operational) {
    poll_event_tpdos(now_us);
    poll_rpdo_deadlines(now_us);
  }
}

// --- Power-on values and parameter storage -------------------------------------------------

void Node::apply_power_on_values() {
  for (std::size_t i = 0; i < board::kFieldCount; ++i) {
    const board::FieldInfo& field = board::kFields[i];
    if (field.access != board::Access::ReadWrite) continue;
    if (fields_.write(static_cast<board::FieldId>(i), field.default_value) == WriteResult::Refused) {
      ++counters_.field_writes_refused;
    }
  }
  parameter_load_ = load_stored_parameters();
}

ParameterLoad Node::load_stored_parameters() {
  const std::size_t size = storage_.load(image_);
  const std::span<const std::byte> image(image_.data(), std::min(size, image_.size()));
  std::size_t count = 0;
  switch (parameter_image::check(image, count)) {
    case parameter_image::Check::Empty: return ParameterLoad::NothingStored;
    case parameter_image::Check::Corrupt: return ParameterLoad::Rejected;
    case parameter_image::Check::Valid: break;
  }
  for (std::size_t i = 0; i < count; ++i) {
    const parameter_image::StoredValue stored = parameter_image::entry(image, i);
    const auto field = tables::field_at(stored.index);
    // Entries of fields this firmware no longer stores are skipped, as are values outside
    // today's range: the default stays, which is safer than a clamped value.
    if (!field || !board::info(*field).stored) continue;
    (void)write_field(*field, stored.value);
  }
  return ParameterLoad::Loaded;
}

bool Node::store_parameters() {
  const std::size_t size = parameter_image::encode(fields_, image_);
  return storage_.save(std::span<const std::byte>(image_.data(), size));
}

bool Node::restore_default_parameters() {
  // Defaults apply at once (a rig wants to see them without a reset) and are stored, so they
  // are also what the next start-up loads.
  bool all_accepted = true;
  for (std::size_t i = 0; i < board::kFieldCount; ++i) {
    const board::FieldInfo& field = board::kFields[i];
    if (!field.stored) continue;
    if (fields_.write(static_cast<board::FieldId>(i), field.default_value) == WriteResult::Refused) {
      ++counters_.field_writes_refused;
      all_accepted = false;
    }
  }
  return store_parameters() && all_accepted;
}

// --- EMCY -----------------------------------------------------------------------------------

bool Node::may_send_emcy() const {
  return state_ == NmtState::PreOperational || state_ == NmtState::Operational;
}

void Node::send_emcy(std::uint16_t code, const std::array<std::uint8_t, 5>& manufacturer) {
  if (!may_send_emcy()) return;
  std::array<std::uint8_t, 8> data = {static_cast<std::uint8_t>(code & 0xFF),
                                      static_cast<std::uint8_t>(code >> 8), error_register_};
  std::copy(manufacturer.begin(), manufacturer.end(), data.begin() + 3);
  if (send(kEmcyCobIdBase + node_id_, data)) ++counters_.emcy_sent;
}

void Node::update_error_register() {
  std::uint8_t bits = 0;
  bool any = false;
  for (const ActiveError& error : active_errors_) {
    if (!error.active) continue;
    any = true;
    bits |= error.report.register_bits;
  }
  error_register_ = any ? static_cast<std::uint8_t>(bits | error_register::kGeneric) : 0;
}

bool Node::report_emcy(const EmcyReport& report) {
  for (const ActiveError& error : active_errors_) {
    if (error.active && error.report == report) return false;  // already reported
  }
  bool tracked = false;
  for (ActiveError& error : active_errors_) {
    if (!error.active) {
      error = {report, true};
      tracked = true;
      break;
    }
  }
  update_error_register();
  // A full table still reports (frame, history, register); such an error is only cleared by
  // clear_all_emcy().
  if (!tracked) {
    error_register_ |= static_cast<std::uint8_t>(report.register_bits | error_register::kGeneric);
  }
  // 0x1003: newest first; upper 16 bits carry the first two manufacturer bytes (the index).
  std::copy_backward(error_history_.begin(), error_history_.end() - 1, error_history_.end());
  error_history_[0] = report.code | (std::uint32_t{report.manufacturer[0]} << 16) |
                      (std::uint32_t{report.manufacturer[1]} << 24);
  error_history_count_ = static_cast<std::uint8_t>(
      std::min<std::size_t>(error_history_count_ + 1u, kErrorHistoryDepth));
  send_emcy(report.code, report.manufacturer);
  return true;
}

bool Node::report_emcy(std::uint16_t error_code, std::uint8_t error_register_bits,
                       const std::array<std::uint8_t, 5>& manufacturer) {
  return report_emcy(EmcyReport{error_code, error_register_bits, manufacturer});
}

bool Node::clear_emcy(const EmcyReport& report) {
  bool cleared = false;
  for (ActiveError& error : active_errors_) {
    if (error.active && error.report.code == report.code &&
        error.report.manufacturer == report.manufacturer) {
      error.active = false;
      cleared = true;
    }
  }
  if (!cleared) return false;
  update_error_register();
  send_emcy(emcy_code::kErrorReset, {});
  return true;
}

bool Node::clear_emcy(std::uint16_t error_code) {
  bool cleared = false;
  for (ActiveError& error : active_errors_) {
    if (error.active && error.report.code == error_code) {
      error.active = false;
      cleared = true;
    }
  }
  if (!cleared) return false;
  update_error_register();
  send_emcy(emcy_code::kErrorReset, {});
  return true;
}

bool Node::clear_all_emcy() {
  bool cleared = false;
  for (ActiveError& error : active_errors_) {
    cleared = cleared || error.active;
    error.active = false;
  }
  if (!cleared && error_register_ == 0) return false;
  update_error_register();
  send_emcy(emcy_code::kErrorReset, {});
  return true;
}

}  // namespace co
