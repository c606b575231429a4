#include "Recorder.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

#include "ObjectTables.hpp"

namespace co {
namespace {

using board::DataType;
using board::RecorderState;
using board::RecorderTrigger;
namespace object = board::recorder;
namespace layout = board::recorder::recording;

// The bits a flag trigger watches: the field's value as an unsigned integer (a bitset travels in
// a REAL32 field, exact up to 2^24); anything that is no such number has no bits set.
std::uint32_t bits_of(float value) {
  if (!(value >= 0.0f) || value >= 4294967296.0f) return 0;
  return static_cast<std::uint32_t>(value);
}

template <typename Value, std::size_t N>
bool is_one_of(const std::array<Value, N>& values, std::uint32_t raw) {
  return board::from_value(values, static_cast<float>(raw)).has_value();
}

// 0 (none) or the object index of a board field.
bool is_field_or_none(std::uint32_t raw) {
  return raw == 0 || (raw <= 0xFFFF && tables::field_at(static_cast<std::uint16_t>(raw)).has_value());
}

}  // namespace

void Recorder::reset() {
  settings_ = Settings{};
  active_ = Active{};
  state_ = RecorderState::Idle;
  samples_taken_ = 0;
  samples_left_ = 0;
}

SdoAbort Recorder::find(std::uint16_t index, std::uint8_t sub, DataType& type, bool& writable) {
  auto variable = [&](DataType variable_type) {
    if (sub != 0) return SdoAbort::SubIndexDoesNotExist;
    type = variable_type;
    writable = index != object::kData;
    return SdoAbort::None;
  };
  switch (index) {
    case object::kState: return variable(DataType::Unsigned8);
    case object::kDivider: return variable(DataType::Unsigned16);
    case object::kSamples: return variable(DataType::Unsigned32);
    case object::kData: return variable(DataType::Domain);
    case object::kChannels:
      if (sub > kMaxChannels) return SdoAbort::SubIndexDoesNotExist;
      type = sub == 0 ? DataType::Unsigned8 : DataType::Unsigned16;
      writable = true;
      return SdoAbort::None;
    case object::kTrigger:
      writable = sub != 0;
      switch (sub) {
        case 0:
        case object::trigger_sub::kSource:
        case object::trigger_sub::kEdge:
        case object::trigger_sub::kPreTriggerPercent: type = DataType::Unsigned8; return SdoAbort::None;
        case object::trigger_sub::kField: type = DataType::Unsigned16; return SdoAbort::None;
        case object::trigger_sub::kLevel: type = DataType::Real32; return SdoAbort::None;
        case object::trigger_sub::kMask: type = DataType::Unsigned32; return SdoAbort::None;
        default: return SdoAbort::SubIndexDoesNotExist;
      }
    case object::kStatus:
      if (sub > object::status_sub::kHighest) return SdoAbort::SubIndexDoesNotExist;
      type = sub == 0 ? DataType::Unsigned8 : DataType::Unsigned32;
      writable = false;
      return SdoAbort::None;
    default: return SdoAbort::ObjectDoesNotExist;
  }
}

std::uint32_t Recorder::read(std::uint16_t index, std::uint8_t sub) const {
  switch (index) {
    case object::kState: return static_cast<std::uint32_t>(state_);
    case object::kDivider: return settings_.divider;
    case object::kSamples: return settings_.samples;
    case object::kChannels:
      return sub == 0 ? settings_.channel_count : settings_.channel_indices[sub - 1u];
    case object::kTrigger:
      switch (sub) {
        case 0: return object::trigger_sub::kHighest;
        case object::trigger_sub::kSource: return static_cast<std::uint32_t>(settings_.source);
        case object::trigger_sub::kField: return settings_.trigger_index;
        case object::trigger_sub::kLevel: return std::bit_cast<std::uint32_t>(settings_.level);
        case object::trigger_sub::kEdge: return static_cast<std::uint32_t>(settings_.edge);
        case object::trigger_sub::kMask: return settings_.mask;
        default: return settings_.pre_trigger_percent;
      }
    case object::kStatus:
      switch (sub) {
        case 0: return object::status_sub::kHighest;
        case object::status_sub::kSamplesTaken: return busy() || state_ == RecorderState::Done ? samples_taken_ : 0;
        default:
          if (state_ == RecorderState::Armed) return active_.samples - active_.pre_trigger;
          return state_ == RecorderState::Triggered ? samples_left_ : 0;
      }
    default: return 0;
  }
}

SdoAbort Recorder::write(std::uint16_t index, std::uint8_t sub, std::uint32_t raw) {
  if (index == object::kState) {
    if (raw == static_cast<std::uint32_t>(RecorderState::Armed)) return arm();
    if (raw != static_cast<std::uint32_t>(RecorderState::Idle)) return SdoAbort::ValueRangeExceeded;
    state_ = RecorderState::Idle;
    samples_taken_ = 0;
    return SdoAbort::None;
  }
  // The ring is laid out for the settings it was armed with.
  if (busy()) return SdoAbort::DeviceState;
  switch (index) {
    case object::kChannels: return write_channels(sub, raw);
    case object::kTrigger: return write_trigger(sub, raw);
    case object::kDivider:
      if (raw == 0) return SdoAbort::ValueTooLow;
      settings_.divider = static_cast<std::uint16_t>(raw);
      return SdoAbort::None;
    case object::kSamples:
      if (raw == 0) return SdoAbort::ValueTooLow;
      if (raw > kBufferValues) return SdoAbort::ValueTooHigh;
      settings_.samples = raw;
      return SdoAbort::None;
    default: return SdoAbort::ReadOnly;
  }
}

SdoAbort Recorder::write_channels(std::uint8_t sub, std::uint32_t raw) {
  if (sub == 0) {
    if (raw > kMaxChannels) return SdoAbort::ValueRangeExceeded;
    // As with a PDO mapping: the channels in use must all name a field.
    for (std::size_t n = 0; n < raw; ++n) {
      if (settings_.channel_indices[n] == 0) return SdoAbort::ParameterIncompatible;
    }
    settings_.channel_count = static_cast<std::uint8_t>(raw);
    return SdoAbort::None;
  }
  if (!is_field_or_none(raw)) return SdoAbort::ValueRangeExceeded;
  if (raw == 0 && sub <= settings_.channel_count) return SdoAbort::ParameterIncompatible;
  settings_.channel_indices[sub - 1u] = static_cast<std::uint16_t>(raw);
  return SdoAbort::None;
}

SdoAbort Recorder::write_trigger(std::uint8_t sub, std::uint32_t raw) {
  switch (sub) {
    case object::trigger_sub::kSource:
      if (!is_one_of(board::kRecorderTriggerValues, raw)) return SdoAbort::ValueRangeExceeded;
      settings_.source = static_cast<RecorderTrigger>(raw);
      return SdoAbort::None;
    case object::trigger_sub::kField:
      if (!is_field_or_none(raw)) return SdoAbort::ValueRangeExceeded;
      settings_.trigger_index = static_cast<std::uint16_t>(raw);
      return SdoAbort::None;
    case object::trigger_sub::kLevel: {
      const float level = std::bit_cast<float>(raw);
      if (!std::isfinite(level)) return SdoAbort::ValueRangeExceeded;
      settings_.level = level;
      return SdoAbort::None;
    }
    case object::trigger_sub::kEdge:
      if (!is_one_of(board::kRecorderEdgeValues, raw)) return SdoAbort::ValueRangeExceeded;
      settings_.edge = static_cast<board::RecorderEdge>(raw);
      return SdoAbort::None;
    case object::trigger_sub::kMask:
      settings_.mask = raw;
      return SdoAbort::None;
    case object::trigger_sub::kPreTriggerPercent:
      if (raw > 100) return SdoAbort::ValueTooHigh;
      settings_.pre_trigger_percent = static_cast<std::uint8_t>(raw);
      return SdoAbort::None;
    default: return SdoAbort::ReadOnly;
  }
}

SdoAbort Recorder::arm() {
  const Settings& settings = settings_;
  if (settings.channel_count == 0 ||
      std::size_t{settings.samples} * settings.channel_count > kBufferValues ||
      (settings.source != RecorderTrigger::Immediate && settings.trigger_index == 0)) {
    return SdoAbort::ParameterIncompatible;
  }
  Active active;
  active.settings = settings;
  active.channel_count = settings.channel_count;
  for (std::size_t n = 0; n < active.channel_count; ++n) {
    const auto field = tables::field_at(settings.channel_indices[n]);
    if (!field) return SdoAbort::ParameterIncompatible;  // unreachable: writes check it
    active.channels[n] = *field;
  }
  if (settings.source != RecorderTrigger::Immediate) {
    const auto field = tables::field_at(settings.trigger_index);
    if (!field) return SdoAbort::ParameterIncompatible;
    active.trigger_field = *field;
  }
  active.source = settings.source;
  active.divider = settings.divider;
  active.samples = settings.samples;
  active.pre_trigger = settings.source == RecorderTrigger::Immediate
                           ? 0
                           : std::min(settings.samples * settings.pre_trigger_percent / 100u,
                                      settings.samples - 1u);
  active_ = active;
  state_ = RecorderState::Armed;
  cycles_to_next_sample_ = 0;  // the first cycle after arming takes a sample
  next_row_ = 0;
  samples_taken_ = 0;
  samples_left_ = 0;
  has_previous_ = false;
  return SdoAbort::None;
}

void Recorder::sampled(std::uint32_t cycle, float trigger_value) {
  const std::uint32_t taken_before = samples_taken_++;
  last_cycle_ = cycle;
  next_row_ = next_row_ + 1 == active_.samples ? 0 : next_row_ + 1;
  if (state_ == RecorderState::Armed) {
    // Edges need the value before; the pre-trigger share must be in the ring.
    const bool fires = trigger_fires(trigger_value);
    if (!fires || taken_before < active_.pre_trigger) return;
    state_ = RecorderState::Triggered;
    trigger_cycle_ = cycle;
    samples_left_ = active_.samples - active_.pre_trigger - 1u;
  } else {
    --samples_left_;
  }
  if (samples_left_ == 0) {
    // The ring holds the last `samples` rows: the oldest is the one written next.
    state_ = RecorderState::Done;
    oldest_row_ = next_row_;
  }
}

bool Recorder::trigger_fires(float value) {
  const Settings& trigger = active_.settings;
  bool rising = false;
  bool falling = false;
  switch (active_.source) {
    case RecorderTrigger::Immediate: return true;
    case RecorderTrigger::Level:
      rising = has_previous_ && previous_value_ < trigger.level && value >= trigger.level;
      falling = has_previous_ && previous_value_ > trigger.level && value <= trigger.level;
      previous_value_ = value;
      break;
    case RecorderTrigger::Flag: {
      const std::uint32_t bits = bits_of(value);
      rising = has_previous_ && (bits & ~previous_bits_ & trigger.mask) != 0;
      falling = has_previous_ && (~bits & previous_bits_ & trigger.mask) != 0;
      previous_bits_ = bits;
      break;
    }
  }
  has_previous_ = true;
  switch (trigger.edge) {
    case board::RecorderEdge::Rising: return rising;
    case board::RecorderEdge::Falling: return falling;
    case board::RecorderEdge::Either: return rising || falling;
  }
  return false;
}

std::size_t Recorder::header(std::array<std::uint8_t, kMaxHeaderBytes>& out) const {
  out.fill(0);
  const bool done = state_ == RecorderState::Done;
  const std::size_t channels = done ? active_.channel_count : 0;
  const std::size_t bytes = layout::header_bytes(channels);
  auto put = [&](std::size_t offset, std::size_t size, std::uint32_t value) {
    // Little-endian; bounded by the array itself (GCC cannot tell that channels <= kMaxChannels).
    for (std::size_t i = 0; i < size && offset + i < out.size(); ++i) {
      out[offset + i] = static_cast<std::uint8_t>(value >> (8 * i));
    }
  };
  put(layout::kVersionOffset, 1, layout::kLayoutVersion);
  put(layout::kChannelCountOffset, 1, static_cast<std::uint32_t>(channels));
  put(layout::kHeaderBytesOffset, 2, static_cast<std::uint32_t>(bytes));
  put(layout::kDividerOffset, 2, done ? active_.divider : settings_.divider);
  if (!done) return bytes;
  put(layout::kSampleCountOffset, 4, active_.samples);
  put(layout::kTriggerSampleOffset, 4, active_.pre_trigger);
  // On the divider's grid (exact when no period was skipped; the measured cycles tell).
  put(layout::kFirstCycleOffset, 4, trigger_cycle_ - active_.pre_trigger * active_.divider);
  put(layout::kTriggerCycleOffset, 4, trigger_cycle_);
  put(layout::kLastCycleOffset, 4, last_cycle_);
  for (std::size_t n = 0; n < channels; ++n) {
    put(layout::kChannelsOffset + 2 * n, 2, active_.settings.channel_indices[n]);
  }
  return bytes;
}

std::uint8_t Recorder::sample_byte(std::size_t offset) const {
  const std::size_t value = offset / 4;
  const std::size_t sample = value / active_.channel_count;
  std::size_t row = oldest_row_ + sample;
  if (row >= active_.samples) row -= active_.samples;
  const float sampled = buffer_[row * active_.channel_count + value % active_.channel_count];
  return static_cast<std::uint8_t>(std::bit_cast<std::uint32_t>(sampled) >> (8 * (offset % 4)));
}

SdoAbort Recorder::read_data(std::size_t offset, std::span<std::uint8_t> out, std::size_t& length,
                             std::size_t& total_size) const {
  if (busy()) return SdoAbort::DeviceState;  // the samples change every cycle
  std::array<std::uint8_t, kMaxHeaderBytes> head{};
  const std::size_t header_size = header(head);
  const std::size_t sample_bytes = std::size_t{4} * recorded_samples() * active_.channel_count;
  total_size = header_size + sample_bytes;
  const std::size_t start = std::min(offset, total_size);
  length = std::min(out.size(), total_size - start);
  for (std::size_t i = 0; i < length; ++i) {
    const std::size_t at = start + i;
    out[i] = at < header_size ? head[at] : sample_byte(at - header_size);
  }
  return SdoAbort::None;
}

}  // namespace co
