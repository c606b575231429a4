// The on-board field recorder (the "oscilloscope"): samples chosen board fields at the end of
// every control cycle into static memory around a trigger, so a host can see at cycle
// resolution fields that no PDO carries, or not every cycle. The host configures it and
// uploads the recording over SDO; its objects and their meaning are declared in board.toml's
// [recorder] (0x3200 state, 0x3201 channels, 0x3202 divider, 0x3203 samples, 0x3204 trigger,
// 0x3205 status, 0x3206 data) and the recording's bytes in protocol/boardproto/recording.py.
//
// States (board::RecorderState): Idle -> (write Armed) -> Armed -> (trigger) -> Triggered ->
// (the last sample) -> Done. Writing Armed in any state (re-)arms: what was recorded is
// discarded. Writing Idle stops and discards.
// - Armed: every divider-th cycle (the first cycle after arming included) one sample of every
//   channel goes into a ring of `samples` rows. The trigger is looked at on each sample, but
//   only accepted once the pre-trigger share (pre = samples * percent / 100, at most
//   samples - 1) is in the ring, so a recording always holds its full pre-trigger part.
// - Trigger (board::RecorderTrigger): Immediate fires at the first sample (no pre-trigger part).
//   Level fires when the trigger field crosses the level between two samples in the edge's
//   direction: rising from below to at-or-above, falling from above to at-or-below. Flag fires
//   when a bit of the mask gets set (rising), cleared (falling) or either in the trigger field
//   read as an unsigned integer (fault_flags and its bits). The first sample after arming has
//   nothing before it: Level and Flag never fire on it (an already latched fault does not).
// - Triggered: the samples after the trigger sample are taken; after `samples - pre - 1` of
//   them the recording is Done: `pre` samples, the trigger sample, the rest.
// - Done: the recording is frozen until the recorder is armed again (sample() does nothing),
//   so a block upload that re-reads segments by offset reads the same bytes.
// - The settings (channels, divider, samples, trigger) can be written while Idle or Done and are
//   refused with SdoAbort::DeviceState while Armed or Triggered: the ring's rows are laid out
//   for the channels it was armed with, and the trigger's history is for its field. A Done
//   recording keeps the settings it was made with (its header names them), whatever is written
//   after. Arming checks that the settings fit together (channels in use, samples * channels
//   within the buffer, a trigger field unless Immediate), else SdoAbort::ParameterIncompatible.
// - recorder_data (the DOMAIN) is readable when Done (the recording) and when Idle (a header
//   without channels or samples); while Armed or Triggered it changes every cycle and aborts
//   with SdoAbort::DeviceState.
//
// Cost: Idle and Done return at the first comparison of the inline sample(); a cycle that takes
// a sample reads each channel and the trigger field once and does a fixed amount of
// bookkeeping (`make bench` counts the instructions). No heap: the sample memory is a member.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "SdoAbort.hpp"
#include "board/fields.hpp"

namespace co {

class Recorder {
 public:
  static constexpr std::size_t kMaxChannels = board::kRecorder.max_channels;
  static constexpr std::size_t kBufferValues = board::kRecorder.buffer_values;
  static constexpr std::size_t kMaxHeaderBytes = board::recorder::recording::header_bytes(kMaxChannels);

  Recorder() = default;
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  // Power-on values (NMT reset node): Idle, the settings at their EDS defaults.
  void reset();

  // At the end of a control cycle, after the components ran. `read(board::FieldId)` returns a
  // field's value now; `cycle` is the firmware's control cycle number. Idle or Done: nothing.
  template <typename ReadField>
  void sample(std::uint32_t cycle, ReadField&& read) {
    if (state_ != board::RecorderState::Armed && state_ != board::RecorderState::Triggered) return;
    if (cycles_to_next_sample_ != 0) {
      --cycles_to_next_sample_;
      return;
    }
    cycles_to_next_sample_ = static_cast<std::uint16_t>(active_.divider - 1u);
    float* row = &buffer_[next_row_ * active_.channel_count];
    for (std::size_t channel = 0; channel < active_.channel_count; ++channel) {
      row[channel] = read(active_.channels[channel]);
    }
    const bool watching = state_ == board::RecorderState::Armed &&
                          active_.source != board::RecorderTrigger::Immediate;
    sampled(cycle, watching ? read(active_.trigger_field) : 0.0f);
  }

  board::RecorderState state() const { return state_; }
  // Samples in the recording (Done), 0 otherwise.
  std::uint32_t recorded_samples() const {
    return state_ == board::RecorderState::Done ? active_.samples : 0;
  }

  // --- The object dictionary's view (the node serves board::recorder::k* through these) -----

  static bool is_recorder_object(std::uint16_t index) {
    return index >= board::recorder::kState && index <= board::recorder::kData;
  }
  // The type and access of (index, sub); SubIndexDoesNotExist / ObjectDoesNotExist otherwise.
  static SdoAbort find(std::uint16_t index, std::uint8_t sub, board::DataType& type, bool& writable);
  // The value of a non-DOMAIN object, as its little-endian bytes read (`find` said it exists).
  std::uint32_t read(std::uint16_t index, std::uint8_t sub) const;
  // Writes a non-DOMAIN object from its little-endian bytes, or returns the abort.
  SdoAbort write(std::uint16_t index, std::uint8_t sub, std::uint32_t raw);
  // The DOMAIN's bytes from `offset` on into `out` (as many as fit or are left): `length` is the
  // count, `total_size` the recording's size. DeviceState while Armed or Triggered.
  SdoAbort read_data(std::size_t offset, std::span<std::uint8_t> out, std::size_t& length,
                     std::size_t& total_size) const;

 private:
  // What the objects hold: what the next arm() uses.
  struct Settings {
    std::uint8_t channel_count = 0;
    std::array<std::uint16_t, kMaxChannels> channel_indices{};  // field object indices, 0 = none
    std::uint16_t divider = 1;
    std::uint32_t samples = board::kRecorder.default_samples;
    board::RecorderTrigger source = board::RecorderTrigger::Immediate;
    std::uint16_t trigger_index = 0;  // field object index, 0 = none
    float level = 0.0f;
    board::RecorderEdge edge = board::RecorderEdge::Rising;
    std::uint32_t mask = 0;
    std::uint8_t pre_trigger_percent = 0;
  };
  // The settings of the recording under way or done, resolved at arm().
  struct Active {
    Settings settings;
    std::size_t channel_count = 0;
    std::array<board::FieldId, kMaxChannels> channels{};
    board::FieldId trigger_field{};
    board::RecorderTrigger source = board::RecorderTrigger::Immediate;
    std::uint16_t divider = 1;
    std::uint32_t samples = 0;      // rows of the ring
    std::uint32_t pre_trigger = 0;  // samples kept before the trigger sample
  };

  bool busy() const {
    return state_ == board::RecorderState::Armed || state_ == board::RecorderState::Triggered;
  }
  SdoAbort arm();
  // After a row was written: ring position, trigger, state.
  void sampled(std::uint32_t cycle, float trigger_value);
  bool trigger_fires(float value);
  SdoAbort write_channels(std::uint8_t sub, std::uint32_t raw);
  SdoAbort write_trigger(std::uint8_t sub, std::uint32_t raw);
  std::size_t header(std::array<std::uint8_t, kMaxHeaderBytes>& out) const;
  std::uint8_t sample_byte(std::size_t offset) const;  // of the samples, unrolled oldest first

  Settings settings_;
  Active active_;
  board::RecorderState state_ = board::RecorderState::Idle;
  std::uint16_t cycles_to_next_sample_ = 0;
  std::size_t next_row_ = 0;           // ring row the next sample goes to
  std::uint32_t samples_taken_ = 0;    // since armed
  std::uint32_t samples_left_ = 0;     // Triggered: samples still to take
  bool has_previous_ = false;          // the trigger has a value to compare with
  float previous_value_ = 0.0f;        // Level: the trigger field at the last sample
  std::uint32_t previous_bits_ = 0;    // Flag: the same as bits
  std::uint32_t trigger_cycle_ = 0;
  std::uint32_t last_cycle_ = 0;
  std::size_t oldest_row_ = 0;         // Done: the ring row of sample 0
  std::array<float, kBufferValues> buffer_{};
};

}  // namespace co
