// Process data objects: configuration over SDO (CiA 301, 7.5.2.35..7.5.2.38), reception of
// RPDOs and transmission of synchronous and event-driven TPDOs.
#include <algorithm>
#include <bit>
#include <cmath>

#include "Node.hpp"
#include "ObjectTables.hpp"
#include "TimeLeft.hpp"

namespace co {
namespace {

// TPDO: 1 = no RTR allowed. The node does not answer remote frames (CiA AN 802 advises
// against RTR; a remote-requested TPDO would also arrive between two SYNCs and break the
// lockstep rig's one-frame-per-cycle accounting), so a TPDO COB-ID always has it set. A write
// that disables the PDO (bit 31) is taken whatever bit 30 says and stored with it set, as
// CANopenNode does (its tests disable TPDO1 with 0x80000184).
constexpr std::uint32_t kRtrBit = 0x4000'0000u;
constexpr std::uint8_t kLastSynchronousType = 240;
constexpr std::uint8_t kEventManufacturer = 254;
constexpr std::uint8_t kEventProfile = 255;

constexpr bool is_synchronous(std::uint8_t type) { return type <= kLastSynchronousType; }
constexpr bool is_event_driven(std::uint8_t type) {
  return type == kEventManufacturer || type == kEventProfile;
}

constexpr std::uint32_t mapping_entry(const board::PdoMapEntry& e) {
  return (std::uint32_t{e.index} << 16) | (std::uint32_t{e.subindex} << 8) | e.bits;
}

}  // namespace

SdoAbort Node::resolve_mapping(std::uint32_t entry, bool is_rpdo, MappedObject& mapped) const {
  const auto index = static_cast<std::uint16_t>(entry >> 16);
  const auto sub = static_cast<std::uint8_t>((entry >> 8) & 0xFF);
  const auto bits = static_cast<std::uint8_t>(entry & 0xFF);
  Entry object;
  if (find_entry(index, sub, object) != SdoAbort::None) return SdoAbort::ObjectCannotBeMapped;
  // RPDOs write: only writable fields and HIL inputs. TPDOs read: fields and HIL outputs.
  bool mappable = false;
  switch (object.target) {
    case Target::Field: mappable = !is_rpdo || object.writable; break;
    case Target::HilInput: mappable = is_rpdo; break;
    case Target::HilOutput: mappable = !is_rpdo; break;
    case Target::Communication: mappable = !is_rpdo && index == 0x1001; break;  // error register
    case Target::Recorder:  // settings and a recording: SDO only
    case Target::Program:          // program download (CiA 302-3): SDO only
    case Target::FieldArrayCount: break;  // a constant
  }
  // Whole objects only: the bit length must be the object's.
  if (!mappable || bits != object.size * 8u) return SdoAbort::ObjectCannotBeMapped;
  mapped = {object.target, object.id, object.size, object.type};
  return SdoAbort::None;
}

SdoAbort Node::write_pdo_communication(Pdo& pdo, bool is_rpdo, std::uint8_t sub,
                                       std::uint32_t value) {
  switch (sub) {
    case 1: {
      const bool valid = (value & tables::kPdoInvalidBit) == 0;
      const std::uint32_t can_id = value & cia301::kStandardIdMask;
      // bit 29 (29-bit id) and bits 11..28 must be zero; the id may change only while the
      // PDO is invalid; an enabled PDO needs a usable id and a mapping.
      if ((value & 0x3FFF'F800u) != 0) return SdoAbort::ValueRangeExceeded;
      // An enabled TPDO cannot be "RTR allowed": the node would not keep that promise.
      if (!is_rpdo && valid && (value & kRtrBit) == 0) return SdoAbort::ValueRangeExceeded;
      if (valid && pdo.valid() && can_id != pdo.can_id()) return SdoAbort::ValueRangeExceeded;
      if (valid && (cia301::is_restricted_cob_id(can_id) || pdo.mapping_count == 0)) {
        return SdoAbort::ValueRangeExceeded;
      }
      const bool enabling = valid && !pdo.valid();
      pdo.cob_id = (value & (tables::kPdoInvalidBit | kRtrBit | cia301::kStandardIdMask)) | (is_rpdo ? 0u : kRtrBit);
      if (enabling) {
        pdo.received_once = false;
        pdo.sent_once = false;
        pdo.change_held = false;
        pdo.syncs_since_sent = 0;
        pdo.due_at_sync = false;
        pdo.sync_started = false;
        pdo.buffered = false;
      }
      return SdoAbort::None;
    }
    case 2:
      if (!is_synchronous(static_cast<std::uint8_t>(value)) &&
          !is_event_driven(static_cast<std::uint8_t>(value))) {
        return SdoAbort::ValueRangeExceeded;  // 241..251 reserved, 252/253 RTR-only unsupported
      }
      pdo.transmission_type = static_cast<std::uint8_t>(value);
      pdo.syncs_since_sent = 0;
      return SdoAbort::None;
    case 3:  // RPDO: kept, but CiA 301 gives the inhibit time no meaning for reception
      pdo.inhibit_time_100us = static_cast<std::uint16_t>(value);
      return SdoAbort::None;
    case 5:  // TPDO: event timer; RPDO: deadline for the next reception
      pdo.event_timer_ms = static_cast<std::uint16_t>(value);
      return SdoAbort::None;
    case 6:  // TPDO only: SYNC start value; changed only while the PDO is invalid
      if (is_rpdo) return SdoAbort::SubIndexDoesNotExist;
      // Like the COB-ID, it may change only while the PDO is invalid (0x06090030 as there).
      if (value > kLastSynchronousType || pdo.valid()) return SdoAbort::ValueRangeExceeded;
      pdo.sync_start_value = static_cast<std::uint8_t>(value);
      return SdoAbort::None;
    default: return SdoAbort::SubIndexDoesNotExist;
  }
}

SdoAbort Node::write_pdo_mapping(Pdo& pdo, bool is_rpdo, std::uint8_t sub, std::uint32_t value) {
  // CiA 301 procedure (7.5.2.36/38): PDO invalid, sub0 = 0 while entries change. A write out
  // of that order is "unsupported access" (0x06010000), one of the codes the clause names.
  if (pdo.valid()) return SdoAbort::UnsupportedAccess;
  // Remapping in operational is optional in CiA 301; this node remaps in pre-operational only.
  if (state_ == NmtState::Operational) return SdoAbort::DeviceState;
  if (sub != 0) {
    if (pdo.mapping_count != 0) return SdoAbort::UnsupportedAccess;
    MappedObject mapped;
    if (value != 0) {  // 0 = empty entry, allowed while the mapping is disabled
      if (const SdoAbort r = resolve_mapping(value, is_rpdo, mapped); r != SdoAbort::None) return r;
    }
    pdo.mapping[sub - 1u] = value;
    return SdoAbort::None;
  }

  // More entries than the record has: "number and length of objects exceeds PDO length".
  if (value > kMaxMappedObjects) return SdoAbort::PdoLengthExceeded;
  std::array<MappedObject, kMaxMappedObjects> mapped{};
  std::size_t bytes = 0;
  for (std::size_t i = 0; i < value; ++i) {
    if (const SdoAbort r = resolve_mapping(pdo.mapping[i], is_rpdo, mapped[i]); r != SdoAbort::None) {
      return r;
    }
    bytes += mapped[i].size;
  }
  if (bytes > 8) return SdoAbort::PdoLengthExceeded;
  pdo.mapping_count = static_cast<std::uint8_t>(value);
  pdo.mapped = mapped;
  pdo.payload_bytes = static_cast<std::uint8_t>(bytes);
  return SdoAbort::None;
}

void Node::load_default_pdo(Pdo& pdo, const board::PdoDefault& defaults, bool is_rpdo) {
  pdo = Pdo{};
  pdo.cob_id = (defaults.cob_id_base + node_id_) | (defaults.enabled ? 0u : tables::kPdoInvalidBit) |
               (is_rpdo ? 0u : kRtrBit);
  pdo.transmission_type = defaults.transmission_type;
  pdo.inhibit_time_100us = defaults.inhibit_time_100us;
  pdo.event_timer_ms = defaults.event_timer_ms;
  const std::size_t count = std::min<std::size_t>(defaults.count, kMaxMappedObjects);
  std::size_t bytes = 0;
  for (std::size_t i = 0; i < count; ++i) {
    pdo.mapping[i] = mapping_entry(defaults.entries[i]);
    if (resolve_mapping(pdo.mapping[i], is_rpdo, pdo.mapped[i]) != SdoAbort::None) {
      ++counters_.default_pdo_errors;  // a table bug: leave this PDO disabled and empty
      pdo.cob_id |= tables::kPdoInvalidBit;
      pdo.mapping_count = 0;
      pdo.payload_bytes = 0;
      return;
    }
    bytes += pdo.mapped[i].size;
  }
  if (bytes > 8) {
    ++counters_.default_pdo_errors;
    pdo.cob_id |= tables::kPdoInvalidBit;
    return;
  }
  pdo.mapping_count = static_cast<std::uint8_t>(count);
  pdo.payload_bytes = static_cast<std::uint8_t>(bytes);
}

void Node::load_default_pdos() {
  for (std::size_t n = 0; n < board::kRpdoCount; ++n) {
    load_default_pdo(rpdos_[n], board::kDefaultRpdos[n], true);
  }
  for (std::size_t n = 0; n < board::kTpdoCount; ++n) {
    load_default_pdo(tpdos_[n], board::kDefaultTpdos[n], false);
  }
}

void Node::reset_pdo_runtime() {
  for (Pdo& pdo : rpdos_) {
    pdo.buffered = false;
    pdo.received_once = false;  // deadlines restart with the first frame
  }
  for (Pdo& pdo : tpdos_) {
    pdo.syncs_since_sent = 0;
    pdo.due_at_sync = false;
    pdo.sent_once = false;
    pdo.change_held = false;
    pdo.sync_started = false;
  }
}

void Node::receive_rpdo(std::size_t number, const CanFrame& frame, std::uint32_t now_us) {
  Pdo& pdo = rpdos_[number];
  const auto communication_index =
      static_cast<std::uint16_t>(tables::kRpdoCommunicationBase + number);
  const EmcyReport length_error = emcy::pdo_length_error(communication_index);
  if (frame.len < pdo.payload_bytes) {
    ++counters_.rpdo_length_errors;
    report_emcy(length_error);
    return;
  }
  ++counters_.rpdos_received;
  clear_emcy(length_error);  // a well-formed frame ends the length error, if it was active
  pdo.received_once = true;
  pdo.last_received_us = timeout_now(now_us);  // the deadline runs on the timeout clock
  if (pdo.deadline_missed) {
    pdo.deadline_missed = false;
    clear_emcy(emcy::rpdo_timeout(communication_index));
  }
  // Extra bytes beyond the mapping are ignored (CiA 301 allows longer RPDOs).
  if (is_synchronous(pdo.transmission_type)) {
    pdo.buffer = frame.data;
    pdo.buffered = true;  // takes effect at the next SYNC
    return;
  }
  apply_rpdo(pdo, std::span<const std::uint8_t>(frame.data.data(), pdo.payload_bytes));
}

void Node::apply_rpdo(const Pdo& pdo, std::span<const std::uint8_t> data) {
  std::size_t offset = 0;
  for (std::size_t i = 0; i < pdo.mapping_count; ++i) {
    const MappedObject& object = pdo.mapped[i];
    const std::uint32_t raw = tables::get_le(data.subspan(offset, object.size));
    offset += object.size;
    SdoAbort result = SdoAbort::None;
    if (object.target == Target::Field) {
      const auto id = static_cast<board::FieldId>(object.id);
      result = write_field(id, tables::field_value(board::info(id), raw));
    } else if (object.target == Target::HilInput) {
      result = write_hil_input(static_cast<board::HilInputId>(object.id), raw);
    }
    // Out of range or refused: that value is dropped, never clamped; the others still apply.
    if (result != SdoAbort::None) ++counters_.rpdo_values_rejected;
  }
}

std::uint8_t Node::build_tpdo(const Pdo& pdo, std::array<std::uint8_t, 8>& data) {
  data = {};
  std::size_t offset = 0;
  for (std::size_t i = 0; i < pdo.mapping_count; ++i) {
    const MappedObject& object = pdo.mapped[i];
    std::uint32_t raw = 0;
    if (object.target == Target::Field) {
      const auto id = static_cast<board::FieldId>(object.id);
      raw = tables::field_raw(board::info(id), fields_.read(id));
    } else if (object.target == Target::HilOutput) {
      raw = static_cast<std::uint32_t>(hil_.read_output(static_cast<board::HilOutputId>(object.id)));
    } else if (object.target == Target::Communication) {
      raw = error_register_;  // the only mappable communication object
    }
    tables::put_le(std::span<std::uint8_t>(data).subspan(offset, object.size), raw);
    offset += object.size;
  }
  return static_cast<std::uint8_t>(offset);
}

void Node::send_tpdo(Pdo& pdo, const std::array<std::uint8_t, 8>& data, std::uint8_t len,
                     std::uint32_t now_us) {
  if (send(pdo.can_id(), std::span<const std::uint8_t>(data.data(), len))) ++counters_.tpdos_sent;
  pdo.last_payload = data;
  pdo.last_sent_us = now_us;
  pdo.sent_once = true;
  pdo.change_held = false;
}

void Node::transmit_synchronous_pdos(std::uint32_t now_us) {
  if (state_ != NmtState::Operational) return;
  // First the event TPDOs that the cycle changed or whose timer ended with it, and the EMCY of
  // an RPDO deadline that ended with it: a master that takes a SYNC's frames until its
  // synchronous TPDOs are in then has them among that SYNC's (sent by the poll after, each
  // would land in this SYNC's or the next's as the host schedules).
  poll_event_tpdos(timeout_now(now_us));
  poll_rpdo_deadlines(timeout_now(now_us));
  for (Pdo& pdo : tpdos_) {
    if (!pdo.due_at_sync) continue;
    pdo.due_at_sync = false;
    std::array<std::uint8_t, 8> data{};
    const std::uint8_t len = build_tpdo(pdo, data);
    // Type 0 (acyclic): only when the mapped values changed since the last transmission.
    if (pdo.transmission_type == 0 && pdo.sent_once && data == pdo.last_payload) continue;
    send_tpdo(pdo, data, len, now_us);
  }
}

void Node::poll_rpdo_deadlines(std::uint32_t now_us) {
  // CiA 301: an RPDO's event timer is a deadline, monitored from its first reception.
  for (std::size_t n = 0; n < rpdos_.size(); ++n) {
    Pdo& pdo = rpdos_[n];
    if (!pdo.valid() || pdo.event_timer_ms == 0 || !pdo.received_once || pdo.deadline_missed) {
      continue;
    }
    if (now_us - pdo.last_received_us < std::uint32_t{pdo.event_timer_ms} * 1000u) continue;
    pdo.deadline_missed = true;
    report_emcy(emcy::rpdo_timeout(static_cast<std::uint16_t>(tables::kRpdoCommunicationBase + n)));
  }
}

std::uint32_t Node::us_until_pdo_timer(std::uint32_t now_us, std::uint32_t limit_us) const {
  std::uint32_t soonest = limit_us;
  for (const Pdo& pdo : rpdos_) {
    // On the control clock a deadline moves only with a cycle, and poll() follows every cycle.
    if (timeout_clock_ == TimeoutClock::ControlCycles) break;
    if (!pdo.valid() || pdo.event_timer_ms == 0 || !pdo.received_once || pdo.deadline_missed) continue;
    soonest = std::min(soonest, time_left_us(now_us, pdo.last_received_us, std::uint32_t{pdo.event_timer_ms} * 1000u));
  }
  for (const Pdo& pdo : tpdos_) {
    if (!pdo.valid() || !is_event_driven(pdo.transmission_type)) continue;
    if (!pdo.sent_once) return 0;  // poll_event_tpdos sends it at once
    // On the control clock these timers move only with a cycle, and poll() follows every cycle.
    if (timeout_clock_ == TimeoutClock::ControlCycles) continue;
    if (pdo.event_timer_ms != 0) {
      soonest = std::min(soonest, time_left_us(now_us, pdo.last_sent_us, std::uint32_t{pdo.event_timer_ms} * 1000u));
    }
    // A change held back by the inhibit time goes out when it ends.
    if (pdo.change_held) {
      soonest = std::min(soonest, time_left_us(now_us, pdo.last_sent_us, std::uint32_t{pdo.inhibit_time_100us} * 100u));
    }
  }
  return soonest;
}

void Node::poll_event_tpdos(std::uint32_t now_us) {
  for (Pdo& pdo : tpdos_) {
    if (!pdo.valid() || !is_event_driven(pdo.transmission_type)) continue;
    std::array<std::uint8_t, 8> data{};
    const std::uint8_t len = build_tpdo(pdo, data);
    const std::uint32_t since_sent_us = now_us - pdo.last_sent_us;
    const bool changed = !pdo.sent_once || data != pdo.last_payload;
    const bool timer_expired =
        pdo.event_timer_ms != 0 && since_sent_us >= std::uint32_t{pdo.event_timer_ms} * 1000u;
    if (!changed && !timer_expired) continue;
    // The inhibit time is the minimum gap between two transmissions; a change inside it is
    // sent when it ends (this poll re-evaluates it every call).
    if (pdo.sent_once && since_sent_us < std::uint32_t{pdo.inhibit_time_100us} * 100u) {
      pdo.change_held = true;
      continue;
    }
    send_tpdo(pdo, data, len, now_us);
  }
}

}  // namespace co
