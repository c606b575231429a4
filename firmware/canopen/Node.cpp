// NMT slave, heartbeat producer and consumer, SYNC consumer, frame dispatch, EMCY producer,
// store/restore.
#include "Node.hpp"

#include <algorithm>
#include <bit>

#include "ObjectTables.hpp"
#include "TimeLeft.hpp"

namespace co {
namespace {

using cia301::FunctionCode;
using cia301::kStandardIdMask;

static_assert(tables::hil_inputs_fit_int32(),
              "every HIL I/O object needs an integer type; inputs must fit int32 (HilIo)");
static_assert(board::kNode.device_name.size() <= SdoServer::kBufferBytes &&
                  board::kNode.hardware_version.size() <= SdoServer::kBufferBytes &&
                  board::kNode.software_version.size() <= SdoServer::kBufferBytes,
              "string objects must fit the SDO server's segment buffer");

// A raw HIL input register starts at 0, or at the nearest end of its range if 0 is outside it
// (the EDS states the same DefaultValue).
std::int32_t hil_input_power_on_value(const board::IoInfo& io) {
  return static_cast<std::int32_t>(std::min<std::int64_t>(std::max<std::int64_t>(0, io.min), io.max));
}

}  // namespace

Node::Node(std::uint8_t node_id, CanPort& port, FieldAccess& fields, HilIo& hil,
           ParameterStorage& storage, std::uint32_t serial_number)
    : node_id_(node_id),
      port_(port),
      fields_(fields),
      hil_(hil),
      storage_(storage),
      serial_number_(serial_number),
      sdo_(object_access(*this)),
      lss_({board::kNode.vendor_id, board::kNode.product_code, board::kNode.revision, serial_number},
           node_id) {
  for (std::size_t i = 0; i < board::kHilInputCount; ++i) {
    hil_inputs_[i] = hil_input_power_on_value(board::kHilInputs[i]);
  }
}

void Node::start(std::uint32_t now_us) {
  (void)lss_.load();  // a node id stored by LSS wins over the one the node was built with
  started_ = true;
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
  last_now_us_ = now_us;
  constexpr std::uint32_t kFlags =
      CanFrame::kExtendedFlag | CanFrame::kRemoteFlag | CanFrame::kErrorFlag;
  if ((frame.id & kFlags) != 0 || frame.len > 8 || !started_) {
    ++counters_.frames_ignored;
    return result;
  }
  if (frame.id == cia305::kMasterCobId) {  // LSS, in every state
    handle_lss(frame, now_us);
    return result;
  }
  if (state_ == NmtState::Initialising) {  // no node id yet: LSS only (CiA 305); or booting
    if (booting_ && timeout_clock_ == TimeoutClock::ControlCycles &&
        frame.id == (sync_cob_id_ & kStandardIdMask)) {
      ++counters_.syncs_received;
      result.boot_sync = true;  // the boot time's clock; no control cycle
      return result;
    }
    ++counters_.frames_ignored;
    return result;
  }
  if (frame.id == cia301::kNmtCobId) {
    handle_nmt(frame, now_us, result);
    return result;
  }
  if (frame.id == (sync_cob_id_ & kStandardIdMask) && state_ != NmtState::Stopped) {
    handle_sync(frame, result);
    return result;
  }
  // Error control, like NMT, works in every state but initialising (stopped too).
  if (handle_heartbeat(frame, now_us)) return result;
  if (state_ == NmtState::Stopped) {  // stopped: NMT only (heartbeat still goes out)
    ++counters_.frames_ignored;
    return result;
  }
  if (frame.id == cia301::cob_id(FunctionCode::SdoRequest, node_id_)) {
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

std::size_t Node::accepted_ids(std::span<std::uint32_t, kMaxAcceptedIds> out) const {
  // The same rules process() and handle_heartbeat() apply, read from the same state.
  std::size_t count = 0;
  if (!cia301::is_node_id(node_id_)) {  // no node id yet: LSS only
    out[count++] = cia305::kMasterCobId;
    return count;
  }
  out[count++] = cia301::kNmtCobId;
  out[count++] = sync_cob_id_ & kStandardIdMask;
  out[count++] = cia301::cob_id(FunctionCode::SdoRequest, node_id_);
  for (const Pdo& rpdo : rpdos_) {
    if (rpdo.valid()) out[count++] = rpdo.can_id();
  }
  for (std::uint8_t sub = 1; sub <= HeartbeatConsumer::kEntries; ++sub) {
    const std::uint32_t entry = heartbeat_consumer_.entry(sub);
    if (HeartbeatConsumer::is_used(entry)) {
      out[count++] = cia301::cob_id(FunctionCode::Heartbeat, HeartbeatConsumer::node_id_of(entry));
    }
  }
  out[count++] = cia305::kMasterCobId;
  std::sort(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(count));
  return static_cast<std::size_t>(std::unique(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(count)) -
                                  out.begin());
}

void Node::set_acceptance_listener(AcceptanceListener* listener) {
  acceptance_listener_ = listener;
  told_accepted_count_ = 0;  // a new listener hears the set whatever the last one heard
  if (state_ != NmtState::Initialising || booting_) tell_acceptance_listener();
}

void Node::tell_acceptance_listener() {
  if (acceptance_listener_ == nullptr) return;
  std::array<std::uint32_t, kMaxAcceptedIds> ids{};
  const std::size_t count = accepted_ids(ids);
  if (count == told_accepted_count_ &&
      std::equal(ids.begin(), ids.begin() + static_cast<std::ptrdiff_t>(count), told_accepted_ids_.begin())) {
    return;
  }
  told_accepted_ids_ = ids;
  told_accepted_count_ = count;
  acceptance_listener_->accepted_ids_changed(std::span<const std::uint32_t>(ids.data(), count));
}

void Node::handle_nmt(const CanFrame& frame, std::uint32_t now_us, ProcessResult& result) {
  if (frame.len != 2) {
    ++counters_.frames_malformed;
    return;
  }
  const std::uint8_t target = frame.data[1];
  if (target != cia301::kNmtAllNodes && target != node_id_) {
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
      reset_communication(now_us, boot_time_us_ == 0);
      return;
    case NmtCommand::ResetCommunication: reset_communication(now_us, boot_time_us_ == 0); return;
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

void Node::reset_communication(std::uint32_t now_us, bool boot_at_once) {
  node_id_ = lss_.activate_pending_node_id();  // an id LSS configured takes effect here
  sdo_.reset();
  booting_ = false;
  if (!cia301::is_node_id(node_id_)) {  // none yet: LSS only, no boot-up (CiA 305)
    state_ = NmtState::Initialising;
    heartbeat_consumer_.reset();
    tell_heartbeat_listener(false);
    tell_acceptance_listener();
    return;
  }
  sync_cob_id_ = cia301::kSyncCobId;
  sync_overflow_ = 0;
  configuration_date_ = 0;
  configuration_time_ = 0;
  heartbeat_ms_ = board::kNode.heartbeat_ms;
  heartbeat_consumer_.reset();
  communication_error_ = cia301::ErrorBehaviour::PreOperational;
  load_default_pdos();
  state_ = NmtState::PreOperational;  // stored PDO mappings replay under pre-operational rules
  load_stored_communication();
  tell_heartbeat_listener(false);
  // Stored COB-IDs are back: the filter takes them before the boot-up invites the master.
  tell_acceptance_listener();
  if (boot_at_once) {
    send_boot_up(now_us);
    return;
  }
  state_ = NmtState::Initialising;  // booting: silent until check_boot() sends the boot-up
  booting_ = true;
  boot_started_us_ = timeout_now(now_us);
}

void Node::check_boot(std::uint32_t clock_now_us, std::uint32_t now_us) {
  if (!booting_ || clock_now_us - boot_started_us_ < boot_time_us_) return;
  booting_ = false;
  send_boot_up(now_us);
}

void Node::send_boot_up(std::uint32_t now_us) {
  state_ = NmtState::PreOperational;
  last_heartbeat_us_ = now_us;  // the heartbeat producer's first period starts here
  const std::array<std::uint8_t, 1> boot_up = {static_cast<std::uint8_t>(NmtState::Initialising)};
  send(cia301::cob_id(FunctionCode::Heartbeat, node_id_), boot_up);
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
    if (!pdo.valid() || pdo.transmission_type > cia301::kLastSynchronousType) continue;
    if (pdo.transmission_type == 0) {
      pdo.due_at_sync = true;
      continue;
    }
    // SYNC start value (0x1800+n:06), used only when the SYNC carries a counter (0x1019 != 0):
    // the first transmission is at the SYNC whose counter equals it, then every n-th SYNC.
    if (sync_overflow_ != 0 && pdo.sync_start_value != 0 && !pdo.sync_started) {
      if (!result.sync_has_counter || result.sync_counter != pdo.sync_start_value) continue;
      pdo.sync_started = true;
      pdo.syncs_since_sent = 0;
      pdo.due_at_sync = true;
      continue;
    }
    if (++pdo.syncs_since_sent >= pdo.transmission_type) {
      pdo.syncs_since_sent = 0;
      pdo.due_at_sync = true;
    }
  }
}

bool Node::handle_heartbeat(const CanFrame& frame, std::uint32_t now_us) {
  // The heartbeat (or boot-up) of node id 1..127; only watched nodes are served.
  const std::uint32_t heartbeat_base = static_cast<std::uint32_t>(FunctionCode::Heartbeat);
  const std::uint32_t node_id = frame.id - heartbeat_base;
  if (frame.id < heartbeat_base || !cia301::is_node_id(node_id) ||
      !heartbeat_consumer_.watches(static_cast<std::uint8_t>(node_id))) {
    return false;
  }
  if (frame.len != 1) {  // the state byte, nothing else (CiA 301, 7.2.8.3.2.2)
    ++counters_.frames_malformed;
    return true;
  }
  ++counters_.heartbeats_consumed;
  heartbeat_consumer_.heartbeat(static_cast<std::uint8_t>(node_id), timeout_now(now_us));
  tell_heartbeat_listener(false);  // a lost heartbeat may be back
  return true;
}

std::uint32_t Node::timeout_now(std::uint32_t now_us) const {
  return timeout_clock_ == TimeoutClock::WallTime ? now_us : control_time_us_;
}

void Node::advance_control_time(std::uint32_t elapsed_us) {
  control_time_us_ += elapsed_us;
  if (timeout_clock_ == TimeoutClock::ControlCycles) check_boot(control_time_us_, last_now_us_);
  if (state_ == NmtState::Initialising || timeout_clock_ != TimeoutClock::ControlCycles) return;
  check_heartbeat_timeouts(control_time_us_);
  check_sdo_timeout(control_time_us_);
}

void Node::check_heartbeat_timeouts(std::uint32_t consumer_now_us) {
  bool event = false;
  heartbeat_consumer_.check_timeouts(consumer_now_us, [&](std::uint8_t lost_node_id) {
    event = true;
    ++counters_.heartbeat_events;
    report_emcy(emcy::heartbeat_error(lost_node_id));
  });
  if (!event) return;
  tell_heartbeat_listener(true);
  // CiA 301 7.5.2.32: after the EMCY (a stopped node sends none), the NMT state follows 0x1029.
  switch (communication_error_) {
    case cia301::ErrorBehaviour::PreOperational:
      if (state_ == NmtState::Operational) enter(NmtState::PreOperational);
      break;
    case cia301::ErrorBehaviour::NoChange: break;
    case cia301::ErrorBehaviour::Stopped: enter(NmtState::Stopped); break;
  }
}

void Node::check_sdo_timeout(std::uint32_t server_now_us) {
  if (state_ == NmtState::Stopped) return;  // a stopped node serves no SDO
  std::array<std::uint8_t, 8> response{};
  if (sdo_.check_timeout(server_now_us, response)) {
    ++counters_.sdo_aborts_sent;
    send(cia301::cob_id(FunctionCode::SdoResponse, node_id_), response);
  }
}

void Node::tell_heartbeat_listener(bool event) {
  const std::uint8_t lost = heartbeat_consumer_.lost_entries();
  if (!event && lost == told_lost_heartbeats_) return;
  told_lost_heartbeats_ = lost;
  if (heartbeat_listener_ != nullptr) heartbeat_listener_->heartbeat_status(lost, event);
}

void Node::handle_sdo(const CanFrame& frame, std::uint32_t now_us) {
  if (frame.len != 8) {  // SDO frames always carry 8 bytes (CiA 301, 7.2.4.3)
    ++counters_.frames_malformed;
    return;
  }
  ++counters_.sdo_requests;
  std::array<std::uint8_t, 8> response{};
  const std::uint32_t aborts_before = sdo_.aborts_sent();
  const bool answered =
      sdo_.handle(std::span<const std::uint8_t, 8>(frame.data), timeout_now(now_us), response);
  // A write may have changed the accepted set (0x1005, 0x1016, an RPDO's COB-ID). Once the
  // master has the answer it may send on the new id at once, so the filter changes first.
  tell_acceptance_listener();
  if (answered) send(cia301::cob_id(FunctionCode::SdoResponse, node_id_), response);
  counters_.sdo_aborts_sent += sdo_.aborts_sent() - aborts_before;
  send_sdo_segments(now_us);
}

void Node::handle_lss(const CanFrame& frame, std::uint32_t now_us) {
  if (frame.len != cia305::kFrameBytes) {  // LSS frames always carry 8 bytes (CiA 305)
    ++counters_.frames_malformed;
    return;
  }
  ++counters_.lss_requests;
  const LssOutcome outcome = lss_.process(std::span<const std::uint8_t>(frame.data.data(), frame.len));
  if (outcome.answer) send(cia305::kSlaveCobId, outcome.answer_data);
  // A node without an id got one: it starts as after reset communication, with its boot-up.
  if (outcome.action == LssAction::ActivateNodeId) reset_communication(now_us);
}

void Node::send_sdo_segments(std::uint32_t now_us) {
  const std::uint32_t aborts_before = sdo_.aborts_sent();
  std::array<std::uint8_t, 8> segment{};
  segment_send_refused_ = false;
  for (std::size_t n = 0; n < kSdoSegmentsPerCall && sdo_.peek_segment(segment); ++n) {
    // Refused (transmit queue full): the server keeps it for the next poll rather than leave
    // a gap the client would have to ask for again.
    if (!send(cia301::cob_id(FunctionCode::SdoResponse, node_id_), segment)) {
      segment_send_refused_ = true;
      break;
    }
    sdo_.segment_sent(timeout_now(now_us));
  }
  counters_.sdo_aborts_sent += sdo_.aborts_sent() - aborts_before;
}

void Node::poll(std::uint32_t now_us) {
  last_now_us_ = now_us;
  if (timeout_clock_ == TimeoutClock::WallTime) check_boot(now_us, now_us);
  if (state_ == NmtState::Initialising) return;
  if (timeout_clock_ == TimeoutClock::WallTime) check_heartbeat_timeouts(now_us);
  const std::uint32_t period_us = std::uint32_t{heartbeat_ms_} * 1000u;
  if (period_us != 0 && now_us - last_heartbeat_us_ >= period_us) {
    // Keep the cadence when poll() is a little late; restart it after a long gap.
    last_heartbeat_us_ += period_us;
    if (now_us - last_heartbeat_us_ >= period_us) last_heartbeat_us_ = now_us;
    const std::array<std::uint8_t, 1> heartbeat = {static_cast<std::uint8_t>(state_)};
    if (send(cia301::cob_id(FunctionCode::Heartbeat, node_id_), heartbeat)) ++counters_.heartbeats_sent;
  }
  if (timeout_clock_ == TimeoutClock::WallTime) check_sdo_timeout(now_us);
  if (state_ != NmtState::Stopped) send_sdo_segments(now_us);
  if (state_ == NmtState::Operational) {
    poll_event_tpdos(timeout_now(now_us));
    poll_rpdo_deadlines(timeout_now(now_us));
  }
}

std::uint32_t Node::us_until_next_timer(std::uint32_t now_us, std::uint32_t limit_us) const {
  if (booting_ && timeout_clock_ == TimeoutClock::WallTime) {
    return std::min(limit_us, time_left_us(now_us, boot_started_us_, boot_time_us_));
  }
  if (state_ == NmtState::Initialising) return limit_us;
  std::uint32_t soonest = limit_us;
  const std::uint32_t period_us = std::uint32_t{heartbeat_ms_} * 1000u;
  if (period_us != 0) soonest = std::min(soonest, time_left_us(now_us, last_heartbeat_us_, period_us));
  if (timeout_clock_ == TimeoutClock::WallTime) {
    soonest = std::min(soonest, heartbeat_consumer_.us_until_timeout(now_us));
    if (state_ != NmtState::Stopped) soonest = std::min(soonest, sdo_.us_until_timeout(now_us));
  }
  if (state_ == NmtState::Operational) soonest = std::min(soonest, us_until_pdo_timer(now_us, limit_us));
  return soonest;
}

// --- Power-on values and parameter storage -------------------------------------------------
//
// Power-on value of an object = its stored value if 0x1010 stored one, else its default.
// Reset node sets the application's (board fields, HIL inputs) and then, through reset
// communication, the communication objects' power-on values.

namespace {

using parameter_image::StoredValue;

bool groups_include(ParameterGroup group, bool communication) {
  return group == ParameterGroup::All ||
         group == (communication ? ParameterGroup::Communication : ParameterGroup::Application);
}

}  // namespace

void Node::apply_power_on_values() {
  // The platform resets its components, board and registers first; what the node holds
  // follows. A HIL input's register is the application's; the node keeps what reads show.
  if (application_reset_ != nullptr) application_reset_->reset_application();
  if (recorder_ != nullptr) recorder_->reset();
  for (std::size_t i = 0; i < board::kFieldCount; ++i) {
    const board::FieldInfo& field = board::kFields[i];
    if (field.access != board::Access::ReadWrite) continue;
    if (fields_.write(static_cast<board::FieldId>(i), field.default_value) == WriteResult::Refused) {
      ++counters_.field_writes_refused;
    }
  }
  for (std::size_t i = 0; i < board::kHilInputCount; ++i) {
    hil_inputs_[i] = hil_input_power_on_value(board::kHilInputs[i]);
  }
  // 0x1001 and 0x1003 are not stored: back to "no error" as at power-on (no error reset frame:
  // the boot-up message that follows tells the master the node started afresh).
  for (ActiveError& error : active_errors_) error.active = false;
  error_register_ = 0;
  error_history_.fill(0);
  error_history_count_ = 0;
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
    const StoredValue stored = parameter_image::entry(image, i);
    const auto field = tables::field_at(stored.index, stored.sub);
    // Entries of fields this firmware no longer stores are skipped, as are values outside
    // today's range: the default stays, which is safer than a clamped value.
    if (!field || !board::info(*field).stored) continue;
    (void)write_field(*field, std::bit_cast<float>(stored.raw));
  }
  return ParameterLoad::Loaded;
}

void Node::load_stored_communication() {
  const std::size_t size = storage_.load(image_);
  const std::span<const std::byte> image(image_.data(), std::min(size, image_.size()));
  std::size_t count = 0;
  if (parameter_image::check(image, count) != parameter_image::Check::Valid) return;
  for (std::size_t i = 0; i < count; ++i) {
    const StoredValue stored = parameter_image::entry(image, i);
    // The same checks as an SDO write: a value today's firmware refuses keeps its default.
    switch (stored.index) {
      case 0x1005:
      case 0x1017:
      case 0x1019:
      case 0x1020:
      case cia301::kErrorBehaviourIndex: (void)write_communication(stored.index, stored.sub, stored.raw, 0); break;
      case HeartbeatConsumer::kIndex:
        // An image from a firmware with more entries: the ones this one has are kept.
        if (stored.sub >= 1 && stored.sub <= HeartbeatConsumer::kEntries) {
          (void)write_communication(stored.index, stored.sub, stored.raw, 0);
        }
        break;
      default: break;
    }
  }
  for (std::size_t n = 0; n < rpdos_.size(); ++n) {
    if (!load_stored_pdo(rpdos_[n], true, static_cast<std::uint16_t>(tables::kRpdoCommunicationBase + n),
                         static_cast<std::uint16_t>(tables::kRpdoMappingBase + n), image, count)) {
      load_default_pdo(rpdos_[n], board::kDefaultRpdos[n], true);
    }
  }
  for (std::size_t n = 0; n < tpdos_.size(); ++n) {
    if (!load_stored_pdo(tpdos_[n], false, static_cast<std::uint16_t>(tables::kTpdoCommunicationBase + n),
                         static_cast<std::uint16_t>(tables::kTpdoMappingBase + n), image, count)) {
      load_default_pdo(tpdos_[n], board::kDefaultTpdos[n], false);
    }
  }
}

bool Node::load_stored_pdo(Pdo& pdo, bool is_rpdo, std::uint16_t communication_index,
                           std::uint16_t mapping_index, std::span<const std::byte> image,
                           std::size_t count) {
  // Start from today's value of every sub-index, overlay what is stored, then replay it in the
  // CiA 301 order (invalid, parameters, mapping count 0, entries, count, COB-ID) so the SDO
  // checks apply. false: a stored value is refused now; the caller restores the defaults.
  std::array<std::uint32_t, 7> communication = {0, pdo.cob_id, pdo.transmission_type,
                                                pdo.inhibit_time_100us, 0, pdo.event_timer_ms,
                                                pdo.sync_start_value};
  std::array<std::uint32_t, kMaxMappedObjects + 1> mapping{};
  mapping[0] = pdo.mapping_count;
  std::copy(pdo.mapping.begin(), pdo.mapping.end(), mapping.begin() + 1);
  bool stored_any = false;
  for (std::size_t i = 0; i < count; ++i) {
    const StoredValue stored = parameter_image::entry(image, i);
    if (stored.index == communication_index && stored.sub >= 1 && stored.sub < communication.size()) {
      communication[stored.sub] = stored.raw;
      stored_any = true;
    } else if (stored.index == mapping_index && stored.sub < mapping.size()) {
      mapping[stored.sub] = stored.raw;
      stored_any = true;
    }
  }
  if (!stored_any) return true;
  auto ok = [](SdoAbort result) { return result == SdoAbort::None; };
  if (!ok(write_pdo_communication(pdo, is_rpdo, 1, communication[1] | tables::kPdoInvalidBit)) ||
      !ok(write_pdo_communication(pdo, is_rpdo, 2, communication[2])) ||
      !ok(write_pdo_communication(pdo, is_rpdo, 3, communication[3])) ||
      !ok(write_pdo_communication(pdo, is_rpdo, 5, communication[5])) ||
      (!is_rpdo && !ok(write_pdo_communication(pdo, is_rpdo, 6, communication[6]))) ||
      !ok(write_pdo_mapping(pdo, is_rpdo, 0, 0))) {
    return false;
  }
  for (std::uint8_t sub = 1; sub <= kMaxMappedObjects; ++sub) {
    if (!ok(write_pdo_mapping(pdo, is_rpdo, sub, mapping[sub]))) return false;
  }
  return ok(write_pdo_mapping(pdo, is_rpdo, 0, mapping[0])) &&
         ok(write_pdo_communication(pdo, is_rpdo, 1, communication[1]));
}

std::size_t Node::collect_communication(std::span<StoredValue> out) const {
  std::size_t n = 0;
  auto add = [&](std::uint16_t index, std::uint8_t sub) {
    if (n < out.size()) out[n++] = {index, sub, read_communication(index, sub)};
  };
  add(0x1005, 0);
  for (std::uint8_t sub = 1; sub <= HeartbeatConsumer::kEntries; ++sub) {
    add(HeartbeatConsumer::kIndex, sub);
  }
  add(0x1017, 0);
  add(0x1019, 0);
  add(0x1020, 1);
  add(0x1020, 2);
  add(cia301::kErrorBehaviourIndex, 1);
  for (std::size_t i = 0; i < rpdos_.size(); ++i) {
    const auto communication = static_cast<std::uint16_t>(tables::kRpdoCommunicationBase + i);
    for (const int sub : {1, 2, 3, 5}) add(communication, static_cast<std::uint8_t>(sub));
    for (std::uint8_t sub = 0; sub <= kMaxMappedObjects; ++sub) {
      add(static_cast<std::uint16_t>(tables::kRpdoMappingBase + i), sub);
    }
  }
  for (std::size_t i = 0; i < tpdos_.size(); ++i) {
    const auto communication = static_cast<std::uint16_t>(tables::kTpdoCommunicationBase + i);
    for (const int sub : {1, 2, 3, 5, 6}) add(communication, static_cast<std::uint8_t>(sub));
    for (std::uint8_t sub = 0; sub <= kMaxMappedObjects; ++sub) {
      add(static_cast<std::uint16_t>(tables::kTpdoMappingBase + i), sub);
    }
  }
  return n;
}

std::size_t Node::collect_application(std::span<StoredValue> out) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < board::kFieldCount && n < out.size(); ++i) {
    const board::FieldInfo& field = board::kFields[i];
    if (!field.stored) continue;
    out[n++] = {field.index, field.subindex,
                std::bit_cast<std::uint32_t>(fields_.read(static_cast<board::FieldId>(i)))};
  }
  return n;
}

std::size_t Node::stored_entries(std::span<StoredValue> out, bool communication) {
  // What storage holds today for one group; nothing when the image is missing or corrupt.
  const std::size_t size = storage_.load(image_);
  const std::span<const std::byte> image(image_.data(), std::min(size, image_.size()));
  std::size_t count = 0;
  if (parameter_image::check(image, count) != parameter_image::Check::Valid) return 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < count && n < out.size(); ++i) {
    const StoredValue stored = parameter_image::entry(image, i);
    if (parameter_image::is_communication(stored.index) == communication) out[n++] = stored;
  }
  return n;
}

bool Node::save_image(std::span<const StoredValue> values, std::size_t count) {
  const std::size_t size = parameter_image::encode(values.first(count), image_);
  return storage_.save(std::span<const std::byte>(image_.data(), size));
}

bool Node::store_parameters(ParameterGroup group) {
  // The group not named keeps what storage holds for it (0x1010:02 leaves stored gains alone).
  std::size_t n = 0;
  const std::span<StoredValue> all(staged_);
  n += groups_include(group, true) ? collect_communication(all.subspan(n))
                                   : stored_entries(all.subspan(n), true);
  n += groups_include(group, false) ? collect_application(all.subspan(n))
                                    : stored_entries(all.subspan(n), false);
  return save_image(staged_, n);
}

bool Node::restore_default_parameters(ParameterGroup group) {
  // Application defaults apply at once (a rig wants to see them without a reset) and are
  // stored, so they are also what the next start-up loads. Communication defaults leave
  // storage and take effect at the next reset (changing PDOs under a running master would
  // surprise it). Either way the boot-up configuration changed: 0x1020 no longer matches.
  bool all_accepted = true;
  const bool application = groups_include(group, false);
  if (application) {
    for (std::size_t i = 0; i < board::kFieldCount; ++i) {
      const board::FieldInfo& field = board::kFields[i];
      if (!field.stored) continue;
      if (fields_.write(static_cast<board::FieldId>(i), field.default_value) == WriteResult::Refused) {
        ++counters_.field_writes_refused;
        all_accepted = false;
      }
    }
  }
  configuration_date_ = 0;
  configuration_time_ = 0;
  std::size_t n = 0;
  const std::span<StoredValue> all(staged_);
  if (!groups_include(group, true)) {
    const std::size_t kept = stored_entries(all, true);
    for (std::size_t i = 0; i < kept; ++i) {
      if (staged_[i].index != 0x1020) staged_[n++] = staged_[i];
    }
  }
  n += application ? collect_application(all.subspan(n)) : stored_entries(all.subspan(n), false);
  return save_image(staged_, n) && all_accepted;
}

// --- EMCY -----------------------------------------------------------------------------------

bool Node::may_send_emcy() const {
  return state_ == NmtState::PreOperational || state_ == NmtState::Operational;
}

void Node::send_emcy(std::uint16_t code, const EmcyManufacturerBytes& manufacturer) {
  if (!may_send_emcy()) return;
  namespace layout = cia301::emcy_layout;
  std::array<std::uint8_t, layout::kFrameBytes> data{};
  data[layout::kErrorCodeOffset] = static_cast<std::uint8_t>(code & 0xFF);
  data[layout::kErrorCodeOffset + 1] = static_cast<std::uint8_t>(code >> 8);
  data[layout::kErrorRegisterOffset] = error_register_;
  std::copy(manufacturer.begin(), manufacturer.end(), data.begin() + layout::kManufacturerOffset);
  if (send(cia301::cob_id(FunctionCode::SyncEmcy, node_id_), data)) ++counters_.emcy_sent;
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
                       const EmcyManufacturerBytes& manufacturer) {
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
