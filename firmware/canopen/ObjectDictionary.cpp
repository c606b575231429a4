// The object dictionary as the SDO server sees it: communication objects (0x1000..0x1FFF)
// implemented natively, then every board field (at index/0, or sub 1..n of an ARRAY of fields) and
// the HIL I/O objects.
#include <algorithm>
#include <bit>
#include <cmath>

#include "Node.hpp"
#include "ObjectTables.hpp"

namespace co {
namespace {

using board::DataType;

constexpr std::uint8_t kRpdoCommunicationHighestSub = 5;
constexpr std::uint8_t kTpdoCommunicationHighestSub = 6;  // + SYNC start value
constexpr std::uint8_t kStoreHighestSub = 3;               // all, communication, application
constexpr std::uint8_t kVerifyConfigurationHighestSub = 2;  // date, time
// 0x1010/0x1011 sub 1..3 read: bit 0 = saves/restores on command, bit 1 = no autonomous save.
constexpr std::uint32_t kSavesOnCommand = 0x0000'0001u;
constexpr std::uint8_t kIdentityHighestSub = 4;

// Offset of `index` within a block of `count` objects starting at `base`, if inside.
constexpr bool in_block(std::uint16_t index, std::uint16_t base, std::size_t count,
                        std::size_t& offset) {
  if (index < base || index >= base + count) return false;
  offset = static_cast<std::size_t>(index - base);
  return true;
}

}  // namespace

SdoAbort Node::find_entry(std::uint16_t index, std::uint8_t sub, Entry& entry) const {
  auto simple = [&](DataType type, bool writable) {
    if (sub != 0) return SdoAbort::SubIndexDoesNotExist;
    entry = {type, tables::size_of(type), true, writable, Target::Communication, 0};
    return SdoAbort::None;
  };
  auto record = [&](DataType type, bool writable) {
    entry = {type, tables::size_of(type), true, writable, Target::Communication, 0};
    return SdoAbort::None;
  };

  switch (index) {
    case 0x1000: return simple(DataType::Unsigned32, false);
    case 0x1001: return simple(DataType::Unsigned8, false);
    case 0x1003:
      if (sub == 0) return record(DataType::Unsigned8, true);
      if (sub <= kErrorHistoryDepth) return record(DataType::Unsigned32, false);
      return SdoAbort::SubIndexDoesNotExist;
    case 0x1005: return simple(DataType::Unsigned32, true);
    case 0x1008:
    case 0x1009:
    case 0x100A: {
      if (sub != 0) return SdoAbort::SubIndexDoesNotExist;
      entry = {DataType::VisibleString, static_cast<std::uint8_t>(string_value(index).size()), true,
               false, Target::Communication, 0};
      return SdoAbort::None;
    }
    case 0x1010:
    case 0x1011:
      if (sub == 0) return record(DataType::Unsigned8, false);
      if (sub <= kStoreHighestSub) return record(DataType::Unsigned32, true);
      return SdoAbort::SubIndexDoesNotExist;
    case 0x1014: return simple(DataType::Unsigned32, false);
    case HeartbeatConsumer::kIndex:
      if (sub == 0) return record(DataType::Unsigned8, false);
      if (sub <= HeartbeatConsumer::kEntries) return record(DataType::Unsigned32, true);
      return SdoAbort::SubIndexDoesNotExist;
    case 0x1017: return simple(DataType::Unsigned16, true);
    case 0x1019: return simple(DataType::Unsigned8, true);
    case 0x1020:
      if (sub == 0) return record(DataType::Unsigned8, false);
      if (sub <= kVerifyConfigurationHighestSub) return record(DataType::Unsigned32, true);
      return SdoAbort::SubIndexDoesNotExist;
    case 0x1018:
      if (sub == 0) return record(DataType::Unsigned8, false);
      if (sub <= kIdentityHighestSub) return record(DataType::Unsigned32, false);
      return SdoAbort::SubIndexDoesNotExist;
    case cia301::kErrorBehaviourIndex:  // sub 1 only: communication errors
      if (sub == 0) return record(DataType::Unsigned8, false);
      if (sub == 1) return record(DataType::Unsigned8, true);
      return SdoAbort::SubIndexDoesNotExist;
    default: break;
  }

  std::size_t n = 0;
  // RPDO and TPDO communication records share sub 1..5; sub 6 (SYNC start value) is TPDO only.
  const bool tpdo_communication = in_block(index, tables::kTpdoCommunicationBase, board::kTpdoCount, n);
  if (tpdo_communication || in_block(index, tables::kRpdoCommunicationBase, board::kRpdoCount, n)) {
    if (sub == 0) return record(DataType::Unsigned8, false);
    if (sub == 1) return record(DataType::Unsigned32, true);
    if (sub == 2) return record(DataType::Unsigned8, true);
    if (sub == 3 || sub == 5) return record(DataType::Unsigned16, true);
    if (sub == 6 && tpdo_communication) return record(DataType::Unsigned8, true);
    return SdoAbort::SubIndexDoesNotExist;  // 4 is reserved by CiA 301
  }
  if (in_block(index, tables::kRpdoMappingBase, board::kRpdoCount, n) ||
      in_block(index, tables::kTpdoMappingBase, board::kTpdoCount, n)) {
    if (sub == 0) return record(DataType::Unsigned8, true);
    if (sub <= kMaxMappedObjects) return record(DataType::Unsigned32, true);
    return SdoAbort::SubIndexDoesNotExist;
  }

  if (index == cia302::kProgramDataIndex || index == cia302::kProgramControlIndex ||
      index == cia302::kSoftwareIdIndex || index == cia302::kFlashStatusIndex) {
    if (sub == 0) {
      entry = {DataType::Unsigned8, 1, true, false, Target::Program, 0};
      return SdoAbort::None;
    }
    if (sub != cia302::kProgramNumber) return SdoAbort::SubIndexDoesNotExist;
    switch (index) {
      case cia302::kProgramDataIndex:  // write-only, any size: streamed (check_writable)
        entry = {DataType::Domain, 0, false, true, Target::Program, 0};
        break;
      case cia302::kProgramControlIndex:
        entry = {DataType::Unsigned8, 1, true, true, Target::Program, 0};
        break;
      default:
        entry = {DataType::Unsigned32, 4, true, false, Target::Program, 0};
        break;
    }
    return SdoAbort::None;
  }
  if (recorder_ != nullptr && Recorder::is_recorder_object(index)) {
    DataType type = DataType::Unsigned8;
    bool writable = false;
    if (const SdoAbort found = Recorder::find(index, sub, type, writable); found != SdoAbort::None) {
      return found;
    }
    entry = {type, tables::size_of(type), true, writable, Target::Recorder, 0};
    return SdoAbort::None;
  }
  if (const board::FieldArrayInfo* array = tables::field_array_at(index)) {
    if (sub == 0) {  // the number of members: constant, so served like a communication object's
      entry = {DataType::Unsigned8, 1, true, false, Target::FieldArrayCount, array->count};
      return SdoAbort::None;
    }
    const auto member = tables::field_at(index, sub);
    if (!member) return SdoAbort::SubIndexDoesNotExist;
    const board::FieldInfo& info = board::info(*member);
    entry = {info.type, tables::size_of(info.type), true, info.access == board::Access::ReadWrite,
             Target::Field, static_cast<std::uint8_t>(*member)};
    return SdoAbort::None;
  }
  if (const auto field = tables::field_at(index)) {
    if (sub != 0) return SdoAbort::SubIndexDoesNotExist;
    const board::FieldInfo& info = board::info(*field);
    entry = {info.type, tables::size_of(info.type), true, info.access == board::Access::ReadWrite,
             Target::Field, static_cast<std::uint8_t>(*field)};
    return SdoAbort::None;
  }
  if (const auto input = tables::hil_input_at(index)) {
    if (sub != 0) return SdoAbort::SubIndexDoesNotExist;
    const DataType type = board::kHilInputs[static_cast<std::size_t>(*input)].type;
    entry = {type, tables::size_of(type), true, true, Target::HilInput,
             static_cast<std::uint8_t>(*input)};
    return SdoAbort::None;
  }
  if (const auto output = tables::hil_output_at(index)) {
    if (sub != 0) return SdoAbort::SubIndexDoesNotExist;
    const DataType type = board::kHilOutputs[static_cast<std::size_t>(*output)].type;
    entry = {type, tables::size_of(type), true, false, Target::HilOutput,
             static_cast<std::uint8_t>(*output)};
    return SdoAbort::None;
  }
  return SdoAbort::ObjectDoesNotExist;
}

std::string_view Node::string_value(std::uint16_t index) const {
  switch (index) {
    case 0x1008: return board::kNode.device_name;
    case 0x1009: return board::kNode.hardware_version;
    case 0x100A: return software_version_;
    default: return {};
  }
}

std::uint32_t Node::read_communication(std::uint16_t index, std::uint8_t sub) const {
  switch (index) {
    case 0x1000: return board::kNode.device_type;
    case 0x1001: return error_register_;
    case 0x1003: return sub == 0 ? error_history_count_ : error_history_[sub - 1u];
    case 0x1005: return sync_cob_id_;
    case 0x1010:
    case 0x1011: return sub == 0 ? kStoreHighestSub : kSavesOnCommand;
    case 0x1014: return cia301::cob_id(cia301::FunctionCode::SyncEmcy, node_id_);
    case HeartbeatConsumer::kIndex:
      return sub == 0 ? HeartbeatConsumer::kEntries : heartbeat_consumer_.entry(sub);
    case 0x1017: return heartbeat_ms_;
    case 0x1019: return sync_overflow_;
    case 0x1020:
      if (sub == 0) return kVerifyConfigurationHighestSub;
      return sub == 1 ? configuration_date_ : configuration_time_;
    case 0x1018:
      switch (sub) {
        case 0: return kIdentityHighestSub;
        case 1: return board::kNode.vendor_id;
        case 2: return board::kNode.product_code;
        case 3: return board::kNode.revision;
        default: return serial_number_;
      }
    case cia301::kErrorBehaviourIndex:
      return sub == 0 ? 1u : static_cast<std::uint32_t>(communication_error_);
    default: break;
  }
  std::size_t n = 0;
  if (in_block(index, tables::kRpdoCommunicationBase, board::kRpdoCount, n) ||
      in_block(index, tables::kTpdoCommunicationBase, board::kTpdoCount, n)) {
    const bool is_rpdo = index < tables::kTpdoCommunicationBase;
    const Pdo& pdo = is_rpdo ? rpdos_[n] : tpdos_[n];
    switch (sub) {
      case 0: return is_rpdo ? kRpdoCommunicationHighestSub : kTpdoCommunicationHighestSub;
      case 1: return pdo.cob_id;
      case 2: return pdo.transmission_type;
      case 3: return pdo.inhibit_time_100us;
      case 5: return pdo.event_timer_ms;
      default: return pdo.sync_start_value;
    }
  }
  if (in_block(index, tables::kRpdoMappingBase, board::kRpdoCount, n) ||
      in_block(index, tables::kTpdoMappingBase, board::kTpdoCount, n)) {
    const Pdo& pdo = index < tables::kTpdoMappingBase ? rpdos_[n] : tpdos_[n];
    return sub == 0 ? pdo.mapping_count : pdo.mapping[sub - 1u];
  }
  return 0;
}

ObjectAccess Node::object_access(Node& node) {
  ObjectAccess access;
  access.context = &node;
  access.check_writable = [](void* self, std::uint16_t index, std::uint8_t sub,
                             std::size_t& size) {
    return static_cast<Node*>(self)->check_writable(index, sub, size);
  };
  access.read = [](void* self, std::uint16_t index, std::uint8_t sub,
                   std::span<std::uint8_t> out, std::size_t& length) {
    return static_cast<Node*>(self)->read(index, sub, out, length);
  };
  access.write = [](void* self, std::uint16_t index, std::uint8_t sub,
                    std::span<const std::uint8_t> data, std::uint32_t now_us) {
    return static_cast<Node*>(self)->write(index, sub, data, now_us);
  };
  access.stream_open = [](void* self, std::uint16_t, std::uint8_t, std::size_t announced_size) {
    return static_cast<Node*>(self)->program_.open(announced_size);
  };
  access.stream_append = [](void* self, std::span<const std::uint8_t> data) {
    return static_cast<Node*>(self)->program_.append(data);
  };
  access.stream_close = [](void* self, std::uint32_t) { return static_cast<Node*>(self)->program_.close(); };
  access.stream_cancel = [](void* self) { static_cast<Node*>(self)->program_.cancel(); };
  access.read_at = [](void* self, std::uint16_t index, std::uint8_t sub, std::size_t offset,
                      std::span<std::uint8_t> out, std::size_t& length, std::size_t& total_size) {
    return static_cast<Node*>(self)->read_at(index, sub, offset, out, length, total_size);
  };
  return access;
}

SdoAbort Node::check_writable(std::uint16_t index, std::uint8_t sub, std::size_t& size) {
  Entry entry;
  if (const SdoAbort found = find_entry(index, sub, entry); found != SdoAbort::None) return found;
  if (!entry.writable) return SdoAbort::ReadOnly;
  size = entry.target == Target::Program && entry.type == DataType::Domain ? SdoServer::kStreamedSize : entry.size;
  return SdoAbort::None;
}

SdoAbort Node::read(std::uint16_t index, std::uint8_t sub, std::span<std::uint8_t> out,
                    std::size_t& length) {
  Entry entry;
  if (const SdoAbort found = find_entry(index, sub, entry); found != SdoAbort::None) return found;
  if (!entry.readable) return SdoAbort::WriteOnly;
  if (entry.size > out.size()) return SdoAbort::GeneralError;
  length = entry.size;
  std::uint32_t raw = 0;
  switch (entry.target) {
    case Target::Field:
      raw = tables::field_raw(board::info(static_cast<board::FieldId>(entry.id)),
                              fields_.read(static_cast<board::FieldId>(entry.id)));
      break;
    case Target::HilInput:
      raw = static_cast<std::uint32_t>(hil_input_value(static_cast<board::HilInputId>(entry.id)));
      break;
    case Target::HilOutput:
      raw = static_cast<std::uint32_t>(hil_.read_output(static_cast<board::HilOutputId>(entry.id)));
      break;
    case Target::FieldArrayCount: raw = entry.id; break;
    case Target::Program:
      raw = program_.read(index, sub);
      break;
    case Target::Recorder:
      if (entry.type == DataType::Domain) {
        std::size_t total = 0;
        const SdoAbort result = recorder_->read_data(0, out, length, total);
        if (result == SdoAbort::None && total > length) return SdoAbort::OutOfMemory;
        return result;
      }
      raw = recorder_->read(index, sub);
      break;
    case Target::Communication:
      if (entry.type == DataType::VisibleString) {
        const std::string_view text = string_value(index);
        std::copy(text.begin(), text.end(), out.begin());
        return SdoAbort::None;
      }
      raw = read_communication(index, sub);
      break;
  }
  tables::put_le(out.first(length), raw);
  return SdoAbort::None;
}

SdoAbort Node::read_at(std::uint16_t index, std::uint8_t sub, std::size_t offset,
                       std::span<std::uint8_t> out, std::size_t& length, std::size_t& total_size) {
  // The recorder's DOMAIN is served from its sample memory, by offset.
  if (recorder_ != nullptr && index == board::recorder::kData) {
    Entry entry;
    if (const SdoAbort found = find_entry(index, sub, entry); found != SdoAbort::None) return found;
    return recorder_->read_data(offset, out, length, total_size);
  }
  // Every other object is small: read it whole and hand out the part asked for.
  std::array<std::uint8_t, SdoServer::kBufferBytes> value{};
  std::size_t size = 0;
  if (const SdoAbort result = read(index, sub, value, size); result != SdoAbort::None) return result;
  const std::size_t start = std::min(offset, size);
  length = std::min(out.size(), size - start);
  std::copy_n(value.begin() + static_cast<long>(start), length, out.begin());
  total_size = size;
  return SdoAbort::None;
}

SdoAbort Node::write(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                     std::uint32_t now_us) {
  Entry entry;
  if (const SdoAbort found = find_entry(index, sub, entry); found != SdoAbort::None) return found;
  if (!entry.writable) return SdoAbort::ReadOnly;
  // Program data takes block downloads only (SdoServer streams them, never through here).
  if (entry.target == Target::Program && entry.type == DataType::Domain) return SdoAbort::UnsupportedAccess;
  if (data.size() > entry.size) return SdoAbort::LengthTooHigh;
  if (data.size() < entry.size) return SdoAbort::LengthTooLow;
  const std::uint32_t raw = tables::get_le(data);
  switch (entry.target) {
    case Target::Field:
      return write_field(static_cast<board::FieldId>(entry.id),
                         tables::field_value(board::info(static_cast<board::FieldId>(entry.id)), raw));
    case Target::HilInput:
      return write_hil_input(static_cast<board::HilInputId>(entry.id), raw);
    case Target::HilOutput:
    case Target::FieldArrayCount: return SdoAbort::ReadOnly;
    case Target::Recorder: return recorder_->write(index, sub, raw);
    case Target::Program: return write_program_control(raw);  // 0x1F50 is streamed, never here
    case Target::Communication: break;
  }
  return write_communication(index, sub, raw, now_us);
}

SdoAbort Node::write_program_control(std::uint32_t value) {
  const SdoAbort result = program_.control(value);
  // Stop stops the application on the bus as NMT would: no PDOs until it is started again.
  if (result == SdoAbort::None && value == static_cast<std::uint32_t>(cia302::ProgramControl::Stop) &&
      state_ == NmtState::Operational) {
    enter(NmtState::PreOperational);
  }
  return result;
}

SdoAbort Node::write_field(board::FieldId id, float value) {
  const board::FieldInfo& field = board::info(id);
  if (std::isnan(value)) return SdoAbort::ValueRangeExceeded;
  if (value > field.max) return SdoAbort::ValueTooHigh;
  if (value < field.min) return SdoAbort::ValueTooLow;
  if (fields_.write(id, value) == WriteResult::Refused) {
    ++counters_.field_writes_refused;
    return SdoAbort::DataCannotBeStored;
  }
  return SdoAbort::None;
}

SdoAbort Node::write_hil_input(board::HilInputId id, std::uint32_t raw) {
  const board::IoInfo& io = board::kHilInputs[static_cast<std::size_t>(id)];
  const std::int64_t value = tables::integer_value(io.type, raw);
  if (value > io.max) return SdoAbort::ValueTooHigh;
  if (value < io.min) return SdoAbort::ValueTooLow;
  // Range checked against int32-sized limits (static_assert in Node.cpp).
  hil_inputs_[static_cast<std::size_t>(id)] = static_cast<std::int32_t>(value);
  hil_.write_input(id, static_cast<std::int32_t>(value));
  return SdoAbort::None;
}

std::int32_t Node::hil_input_value(board::HilInputId id) const {
  return hil_inputs_[static_cast<std::size_t>(id)];
}

SdoAbort Node::write_communication(std::uint16_t index, std::uint8_t sub, std::uint32_t value,
                                   std::uint32_t now_us) {
  switch (index) {
    case 0x1003:
      // Only "0" is allowed: it clears the history (CiA 301, 7.5.2.4).
      if (value != 0) return SdoAbort::ValueRangeExceeded;
      error_history_count_ = 0;
      error_history_.fill(0);
      return SdoAbort::None;
    case 0x1005:
      // bit 30 = "this node produces SYNC" (not supported), bit 29 = 29-bit id (not supported).
      if ((value & 0x7FFF'F800u) != 0) return SdoAbort::ValueRangeExceeded;
      // A restricted id would shadow NMT, SDO or error control: e.g. 0x600+id turns every SDO
      // request into a SYNC and leaves the node deaf to SDO until a reset (found by fuzzing).
      if (cia301::is_restricted_cob_id(value & cia301::kStandardIdMask)) return SdoAbort::ValueRangeExceeded;
      sync_cob_id_ = value;
      return SdoAbort::None;
    case 0x1010:
      if (value != kStoreSignature) return SdoAbort::DataCannotBeStored;
      return store_parameters(static_cast<ParameterGroup>(sub)) ? SdoAbort::None
                                                                : SdoAbort::DataCannotBeStored;
    case 0x1011:
      if (value != kRestoreSignature) return SdoAbort::DataCannotBeStored;
      return restore_default_parameters(static_cast<ParameterGroup>(sub))
                 ? SdoAbort::None
                 : SdoAbort::DataCannotBeStored;
    case HeartbeatConsumer::kIndex: {
      const SdoAbort result = heartbeat_consumer_.configure(sub, value);
      tell_heartbeat_listener(false);  // an entry that was lost waits afresh
      return result;
    }
    case 0x1017:
      heartbeat_ms_ = static_cast<std::uint16_t>(value);
      last_heartbeat_us_ = now_us;  // the new period counts from now
      return SdoAbort::None;
    case 0x1019:
      // 0: SYNC without counter; 2..240: counter overflow value; 1 and 241..255 reserved.
      // (CiA 301 refuses changes while 0x1006 is not 0; this node has no 0x1006.)
      if (value == 1 || value > 240) return SdoAbort::ValueRangeExceeded;
      sync_overflow_ = static_cast<std::uint8_t>(value);
      for (Pdo& pdo : tpdos_) pdo.sync_started = false;  // start values apply to the new count
      return SdoAbort::None;
    case 0x1020:
      // Written by a configuration tool, then stored with 0x1010 (CiA 301, 7.5.2.23).
      (sub == 1 ? configuration_date_ : configuration_time_) = value;
      return SdoAbort::None;
    case cia301::kErrorBehaviourIndex:
      // 0 pre-operational, 1 no change, 2 stopped; 3..127 reserved, 128..255 profile-defined.
      if (value > static_cast<std::uint32_t>(cia301::ErrorBehaviour::Stopped)) {
        return SdoAbort::ValueRangeExceeded;
      }
      communication_error_ = static_cast<cia301::ErrorBehaviour>(value);
      return SdoAbort::None;
    default: break;
  }
  std::size_t n = 0;
  if (in_block(index, tables::kRpdoCommunicationBase, board::kRpdoCount, n)) {
    return write_pdo_communication(rpdos_[n], true, sub, value);
  }
  if (in_block(index, tables::kTpdoCommunicationBase, board::kTpdoCount, n)) {
    return write_pdo_communication(tpdos_[n], false, sub, value);
  }
  if (in_block(index, tables::kRpdoMappingBase, board::kRpdoCount, n)) {
    return write_pdo_mapping(rpdos_[n], true, sub, value);
  }
  if (in_block(index, tables::kTpdoMappingBase, board::kTpdoCount, n)) {
    return write_pdo_mapping(tpdos_[n], false, sub, value);
  }
  return SdoAbort::ObjectDoesNotExist;
}

}  // namespace co
