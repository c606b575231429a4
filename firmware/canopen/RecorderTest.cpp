// The field recorder: sampling, divider, triggers and pre-trigger share, the recording's bytes
// (oldest first from the ring), settings refused while recording; then through the node: its
// objects over SDO and a block upload of a full recording, frame by frame.
#include <bit>
#include <limits>
#include <vector>

#include "BlockCrcReference.hpp"
#include "NodeTestSupport.hpp"
#include "ObjectTables.hpp"
#include "Recorder.hpp"

namespace co::test {
namespace {

using board::FieldId;
using board::RecorderEdge;
using board::RecorderState;
using board::RecorderTrigger;
namespace object = board::recorder;
namespace layout = board::recorder::recording;
namespace trigger_sub = board::recorder::trigger_sub;
namespace status_sub = board::recorder::status_sub;

constexpr FieldId kVelocity = FieldId::motor_velocity;
constexpr FieldId kTorque = FieldId::joint_torque;
constexpr FieldId kFaults = FieldId::fault_flags;

std::uint32_t raw(RecorderState state) { return static_cast<std::uint32_t>(state); }
std::uint32_t raw(RecorderTrigger source) { return static_cast<std::uint32_t>(source); }
std::uint32_t raw(RecorderEdge edge) { return static_cast<std::uint32_t>(edge); }

// A recording decoded from the DOMAIN's bytes, as the host does (boardproto.recording).
struct Decoded {
  std::uint8_t version = 0;
  std::size_t channel_count = 0;
  std::size_t header_bytes = 0;
  std::uint16_t divider = 0;
  std::uint32_t samples = 0;
  std::uint32_t trigger_sample = 0;
  std::uint32_t first_cycle = 0, trigger_cycle = 0, last_cycle = 0;
  std::vector<std::uint16_t> channels;
  std::vector<std::vector<float>> rows;
};

std::uint32_t le(const std::vector<std::uint8_t>& bytes, std::size_t offset, std::size_t size) {
  return tables::get_le(std::span(bytes).subspan(offset, size));
}

Decoded decode(const std::vector<std::uint8_t>& bytes) {
  Decoded d;
  EXPECT_GE(bytes.size(), layout::kFixedHeaderBytes);
  if (bytes.size() < layout::kFixedHeaderBytes) return d;
  d.version = bytes[layout::kVersionOffset];
  d.channel_count = bytes[layout::kChannelCountOffset];
  d.header_bytes = le(bytes, layout::kHeaderBytesOffset, 2);
  d.divider = static_cast<std::uint16_t>(le(bytes, layout::kDividerOffset, 2));
  d.samples = le(bytes, layout::kSampleCountOffset, 4);
  d.trigger_sample = le(bytes, layout::kTriggerSampleOffset, 4);
  d.first_cycle = le(bytes, layout::kFirstCycleOffset, 4);
  d.trigger_cycle = le(bytes, layout::kTriggerCycleOffset, 4);
  d.last_cycle = le(bytes, layout::kLastCycleOffset, 4);
  EXPECT_EQ(d.header_bytes, layout::header_bytes(d.channel_count));
  EXPECT_EQ(bytes.size(), d.header_bytes + 4 * d.channel_count * d.samples);
  if (bytes.size() != d.header_bytes + 4 * d.channel_count * d.samples) return d;
  for (std::size_t n = 0; n < d.channel_count; ++n) {
    d.channels.push_back(static_cast<std::uint16_t>(le(bytes, layout::kChannelsOffset + 2 * n, 2)));
  }
  for (std::size_t k = 0; k < d.samples; ++k) {
    std::vector<float> row;
    for (std::size_t c = 0; c < d.channel_count; ++c) {
      row.push_back(std::bit_cast<float>(le(bytes, d.header_bytes + 4 * (k * d.channel_count + c), 4)));
    }
    d.rows.push_back(row);
  }
  return d;
}

// --- The recorder alone -------------------------------------------------------------------------

class RecorderTest : public ::testing::Test {
 protected:
  void SetUp() override { recorder.reset(); }

  SdoAbort set(std::uint16_t index, std::uint8_t sub, std::uint32_t value) {
    return recorder.write(index, sub, value);
  }
  void channels(std::initializer_list<FieldId> ids) {
    ASSERT_EQ(set(object::kChannels, 0, 0), SdoAbort::None);
    std::uint8_t sub = 1;
    for (const FieldId id : ids) ASSERT_EQ(set(object::kChannels, sub++, index_of(id)), SdoAbort::None);
    ASSERT_EQ(set(object::kChannels, 0, static_cast<std::uint32_t>(ids.size())), SdoAbort::None);
  }
  void trigger(RecorderTrigger source, FieldId field, float level, RecorderEdge edge,
               std::uint8_t pre_trigger_percent, std::uint32_t mask = 0) {
    ASSERT_EQ(set(object::kTrigger, trigger_sub::kSource, raw(source)), SdoAbort::None);
    ASSERT_EQ(set(object::kTrigger, trigger_sub::kField, index_of(field)), SdoAbort::None);
    ASSERT_EQ(set(object::kTrigger, trigger_sub::kLevel, float_bits(level)), SdoAbort::None);
    ASSERT_EQ(set(object::kTrigger, trigger_sub::kEdge, raw(edge)), SdoAbort::None);
    ASSERT_EQ(set(object::kTrigger, trigger_sub::kMask, mask), SdoAbort::None);
    ASSERT_EQ(set(object::kTrigger, trigger_sub::kPreTriggerPercent, pre_trigger_percent), SdoAbort::None);
  }
  SdoAbort arm() { return set(object::kState, 0, raw(RecorderState::Armed)); }

  // One control cycle: the next cycle number, then the recorder samples the board.
  void cycle() {
    ++cycle_number;
    recorder.sample(cycle_number, [this](FieldId id) {
      ++reads;
      return values[static_cast<std::size_t>(id)];
    });
  }
  float& value(FieldId id) { return values[static_cast<std::size_t>(id)]; }

  std::vector<std::uint8_t> data(std::size_t chunk = 7) {
    std::vector<std::uint8_t> bytes;
    std::array<std::uint8_t, 64> out{};
    std::size_t total = 0;
    for (std::size_t offset = 0;; offset += chunk) {
      std::size_t length = 0;
      EXPECT_EQ(recorder.read_data(offset, std::span(out).first(chunk), length, total), SdoAbort::None);
      bytes.insert(bytes.end(), out.begin(), out.begin() + static_cast<long>(length));
      if (length < chunk) break;
    }
    EXPECT_EQ(bytes.size(), total);
    return bytes;
  }
  SdoAbort data_abort() {
    std::array<std::uint8_t, 8> out{};
    std::size_t length = 0, total = 0;
    return recorder.read_data(0, out, length, total);
  }

  Recorder recorder;
  std::array<float, board::kFieldCount> values{};
  std::uint32_t cycle_number = 1000;
  std::uint32_t reads = 0;
};

TEST_F(RecorderTest, StartsIdleWithTheTablesDefaults) {
  EXPECT_EQ(recorder.state(), RecorderState::Idle);
  EXPECT_EQ(recorder.read(object::kChannels, 0), 0u);
  EXPECT_EQ(recorder.read(object::kDivider, 0), 1u);
  EXPECT_EQ(recorder.read(object::kSamples, 0), board::kRecorder.default_samples);
  EXPECT_EQ(recorder.read(object::kTrigger, 0), trigger_sub::kHighest);
  EXPECT_EQ(recorder.read(object::kTrigger, trigger_sub::kSource), raw(RecorderTrigger::Immediate));
  EXPECT_EQ(recorder.read(object::kStatus, 0), status_sub::kHighest);
  EXPECT_GE(Recorder::kMaxChannels, 8u);
}

TEST_F(RecorderTest, IdleDomainIsAHeaderWithoutSamples) {
  const Decoded d = decode(data());
  EXPECT_EQ(d.version, layout::kLayoutVersion);
  EXPECT_EQ(d.channel_count, 0u);
  EXPECT_EQ(d.samples, 0u);
  EXPECT_EQ(data().size(), layout::kFixedHeaderBytes);
}

TEST_F(RecorderTest, IdleAndDoneCostNoRead) {
  for (int i = 0; i < 10; ++i) cycle();
  EXPECT_EQ(reads, 0u);
  channels({kVelocity});
  ASSERT_EQ(set(object::kSamples, 0, 2), SdoAbort::None);
  ASSERT_EQ(arm(), SdoAbort::None);
  cycle();
  cycle();
  ASSERT_EQ(recorder.state(), RecorderState::Done);
  reads = 0;
  for (int i = 0; i < 10; ++i) cycle();
  EXPECT_EQ(reads, 0u);
}

TEST_F(RecorderTest, ImmediateTriggerRecordsTheCyclesAfterArming) {
  channels({kVelocity, kTorque});
  ASSERT_EQ(set(object::kSamples, 0, 5), SdoAbort::None);
  ASSERT_EQ(arm(), SdoAbort::None);
  EXPECT_EQ(recorder.state(), RecorderState::Armed);
  EXPECT_EQ(data_abort(), SdoAbort::DeviceState) << "the samples change every cycle";
  for (int k = 0; k < 5; ++k) {
    value(kVelocity) = static_cast<float>(k);
    value(kTorque) = -static_cast<float>(k) / 2;
    cycle();
    EXPECT_EQ(recorder.state(), k < 4 ? RecorderState::Triggered : RecorderState::Done) << k;
  }
  const Decoded d = decode(data());
  EXPECT_EQ(d.channel_count, 2u);
  EXPECT_EQ(d.channels, (std::vector<std::uint16_t>{index_of(kVelocity), index_of(kTorque)}));
  EXPECT_EQ(d.divider, 1u);
  EXPECT_EQ(d.samples, 5u);
  EXPECT_EQ(d.trigger_sample, 0u);
  EXPECT_EQ(d.first_cycle, 1001u);
  EXPECT_EQ(d.trigger_cycle, 1001u);
  EXPECT_EQ(d.last_cycle, 1005u);
  ASSERT_EQ(d.rows.size(), 5u);
  for (std::size_t k = 0; k < 5; ++k) {
    EXPECT_EQ(d.rows[k], (std::vector<float>{static_cast<float>(k), -static_cast<float>(k) / 2})) << k;
  }
  EXPECT_EQ(recorder.recorded_samples(), 5u);
}

TEST_F(RecorderTest, DividerSamplesEveryNthCycleFromTheFirst) {
  channels({kVelocity});
  ASSERT_EQ(set(object::kDivider, 0, 3), SdoAbort::None);
  ASSERT_EQ(set(object::kSamples, 0, 4), SdoAbort::None);
  ASSERT_EQ(arm(), SdoAbort::None);
  for (int k = 0; k < 12; ++k) {
    value(kVelocity) = static_cast<float>(cycle_number + 1);  // the cycle number it is read at
    cycle();
  }
  EXPECT_EQ(recorder.state(), RecorderState::Done);
  const Decoded d = decode(data());
  EXPECT_EQ(d.divider, 3u);
  EXPECT_EQ(d.first_cycle, 1001u);
  EXPECT_EQ(d.last_cycle, 1010u);
  ASSERT_EQ(d.rows.size(), 4u);
  for (std::size_t k = 0; k < 4; ++k) {
    EXPECT_EQ(d.rows[k][0], static_cast<float>(d.first_cycle + 3 * k)) << "sample k at first + k * divider";
  }
}

TEST_F(RecorderTest, LevelTriggerKeepsThePreTriggerShareOldestFirstAcrossTheRingsWrap) {
  channels({kVelocity, kTorque});
  ASSERT_EQ(set(object::kSamples, 0, 10), SdoAbort::None);
  trigger(RecorderTrigger::Level, kTorque, 5.0f, RecorderEdge::Rising, 40);  // 4 samples before
  ASSERT_EQ(arm(), SdoAbort::None);
  // 37 samples below the level: the 10-row ring wraps several times before the trigger.
  for (int k = 0; k < 37; ++k) {
    value(kVelocity) = static_cast<float>(k);
    value(kTorque) = 1.0f;
    cycle();
  }
  EXPECT_EQ(recorder.state(), RecorderState::Armed);
  EXPECT_EQ(recorder.read(object::kStatus, status_sub::kSamplesTaken), 37u);
  EXPECT_EQ(recorder.read(object::kStatus, status_sub::kSamplesLeft), 6u) << "the trigger sample and 5 after";
  const std::uint32_t trigger_cycle = cycle_number + 1;
  for (int k = 37; k < 60; ++k) {
    value(kVelocity) = static_cast<float>(k);
    value(kTorque) = 5.0f;  // reaches the level at k = 37
    cycle();
    if (k == 37) {
      EXPECT_EQ(recorder.state(), RecorderState::Triggered);
      EXPECT_EQ(recorder.read(object::kStatus, status_sub::kSamplesLeft), 5u);
    }
  }
  ASSERT_EQ(recorder.state(), RecorderState::Done);
  const Decoded d = decode(data());
  EXPECT_EQ(d.samples, 10u);
  EXPECT_EQ(d.trigger_sample, 4u);
  EXPECT_EQ(d.trigger_cycle, trigger_cycle);
  EXPECT_EQ(d.first_cycle, trigger_cycle - 4);
  EXPECT_EQ(d.last_cycle, trigger_cycle + 5);
  ASSERT_EQ(d.rows.size(), 10u);
  for (std::size_t k = 0; k < 10; ++k) {
    EXPECT_EQ(d.rows[k][0], static_cast<float>(33 + k)) << "oldest first, no gap: " << k;
    EXPECT_EQ(d.rows[k][1], k < 4 ? 1.0f : 5.0f) << k;
  }
}

TEST_F(RecorderTest, TriggerWaitsUntilThePreTriggerShareIsRecorded) {
  channels({kVelocity});
  ASSERT_EQ(set(object::kSamples, 0, 10), SdoAbort::None);
  trigger(RecorderTrigger::Level, kVelocity, 0.5f, RecorderEdge::Either, 50);  // 5 before
  ASSERT_EQ(arm(), SdoAbort::None);
  const std::array<float, 8> early{0, 1, 0, 1, 0, 0, 0, 0};  // crossings at samples 1..4: too early
  for (const float v : early) {
    value(kVelocity) = v;
    cycle();
  }
  EXPECT_EQ(recorder.state(), RecorderState::Armed);
  value(kVelocity) = 1.0f;  // sample 8: 8 samples before it, 5 needed
  cycle();
  EXPECT_EQ(recorder.state(), RecorderState::Triggered);
  for (int k = 0; k < 4; ++k) cycle();
  ASSERT_EQ(recorder.state(), RecorderState::Done);
  const Decoded d = decode(data());
  EXPECT_EQ(d.trigger_sample, 5u);
  EXPECT_EQ(d.rows[4][0], 0.0f);
  EXPECT_EQ(d.rows[5][0], 1.0f);
}

TEST_F(RecorderTest, LevelEdgesFireOnlyInTheirDirection) {
  struct Case {
    RecorderEdge edge;
    std::array<float, 4> values;
    bool fires;
  };
  const std::array<Case, 6> cases{{
      {RecorderEdge::Rising, {0, 1, 2, 3}, true},     // 2 reaches the level from below
      {RecorderEdge::Rising, {3, 2, 1, 0}, false},
      {RecorderEdge::Falling, {3, 2, 1, 0}, true},    // 2 reaches it from above
      {RecorderEdge::Falling, {0, 1, 2, 3}, false},
      {RecorderEdge::Either, {3, 3, 1, 1}, true},
      {RecorderEdge::Rising, {2, 2, 2, 2}, false},     // at the level from the start: no crossing
  }};
  for (const Case& c : cases) {
    recorder.reset();
    channels({kVelocity});
    ASSERT_EQ(set(object::kSamples, 0, 100), SdoAbort::None);
    trigger(RecorderTrigger::Level, kVelocity, 2.0f, c.edge, 0);
    ASSERT_EQ(arm(), SdoAbort::None);
    for (const float v : c.values) {
      value(kVelocity) = v;
      cycle();
    }
    EXPECT_EQ(recorder.state() == RecorderState::Triggered, c.fires)
        << "edge " << static_cast<int>(c.edge) << " from " << c.values[0];
  }
}

TEST_F(RecorderTest, FlagTriggerFiresOnAMaskedBitNotAlreadyLatched) {
  channels({kFaults});
  ASSERT_EQ(set(object::kSamples, 0, 4), SdoAbort::None);
  const std::uint32_t watched = board::mask(board::FaultFlagsBit::CommandWatchdog);
  trigger(RecorderTrigger::Flag, kFaults, 0.0f, RecorderEdge::Rising, 50, watched);
  value(kFaults) = static_cast<float>(watched);  // latched before arming: no trigger
  ASSERT_EQ(arm(), SdoAbort::None);
  for (int k = 0; k < 5; ++k) cycle();
  EXPECT_EQ(recorder.state(), RecorderState::Armed);
  value(kFaults) = 0.0f;
  cycle();
  value(kFaults) = static_cast<float>(board::mask(board::FaultFlagsBit::OverTemperature));  // not watched
  cycle();
  EXPECT_EQ(recorder.state(), RecorderState::Armed);
  value(kFaults) = static_cast<float>(board::mask(board::FaultFlagsBit::OverTemperature) | watched);
  cycle();
  EXPECT_EQ(recorder.state(), RecorderState::Triggered);
  cycle();
  ASSERT_EQ(recorder.state(), RecorderState::Done);
  const Decoded d = decode(data());
  EXPECT_EQ(d.trigger_sample, 2u);
  EXPECT_EQ(static_cast<std::uint32_t>(d.rows[2][0]) & watched, watched);
  EXPECT_EQ(static_cast<std::uint32_t>(d.rows[1][0]) & watched, 0u);
}

TEST_F(RecorderTest, FlagTriggerOnAFallingEdgeFiresWhenTheBitClears) {
  channels({kFaults});
  ASSERT_EQ(set(object::kSamples, 0, 3), SdoAbort::None);
  trigger(RecorderTrigger::Flag, kFaults, 0.0f, RecorderEdge::Falling, 0, 0x3);
  value(kFaults) = 3.0f;
  ASSERT_EQ(arm(), SdoAbort::None);
  cycle();
  value(kFaults) = 7.0f;  // bit 2 sets: not watched, not a clear
  cycle();
  EXPECT_EQ(recorder.state(), RecorderState::Armed);
  value(kFaults) = 6.0f;  // bit 0 clears
  cycle();
  EXPECT_EQ(recorder.state(), RecorderState::Triggered);
  value(kFaults) = -1.0f;  // not a set of bits: reads as none
  cycle();
  cycle();
  EXPECT_EQ(recorder.state(), RecorderState::Done);
}

TEST_F(RecorderTest, DoneIsFrozenUntilArmedAgain) {
  channels({kVelocity});
  ASSERT_EQ(set(object::kSamples, 0, 3), SdoAbort::None);
  ASSERT_EQ(arm(), SdoAbort::None);
  for (int k = 0; k < 3; ++k) {
    value(kVelocity) = static_cast<float>(k + 1);
    cycle();
  }
  const std::vector<std::uint8_t> recording = data();
  value(kVelocity) = 99.0f;
  for (int k = 0; k < 50; ++k) cycle();
  EXPECT_EQ(data(), recording);
  EXPECT_EQ(data(3), recording) << "any read pattern, the same bytes";
  // Settings may change when done; the recording keeps the ones it was made with.
  channels({kTorque, kVelocity});
  ASSERT_EQ(set(object::kDivider, 0, 7), SdoAbort::None);
  EXPECT_EQ(data(), recording);
  // Re-arming discards it.
  ASSERT_EQ(arm(), SdoAbort::None);
  EXPECT_EQ(recorder.state(), RecorderState::Armed);
  EXPECT_EQ(recorder.recorded_samples(), 0u);
  EXPECT_EQ(data_abort(), SdoAbort::DeviceState);
  EXPECT_EQ(recorder.read(object::kStatus, status_sub::kSamplesTaken), 0u);
}

TEST_F(RecorderTest, WritingArmedWhileRecordingStartsAgain) {
  channels({kVelocity});
  ASSERT_EQ(set(object::kSamples, 0, 4), SdoAbort::None);
  trigger(RecorderTrigger::Level, kVelocity, 1.0f, RecorderEdge::Rising, 0);
  ASSERT_EQ(arm(), SdoAbort::None);
  for (int k = 0; k < 6; ++k) cycle();
  EXPECT_EQ(recorder.read(object::kStatus, status_sub::kSamplesTaken), 6u);
  ASSERT_EQ(arm(), SdoAbort::None);
  EXPECT_EQ(recorder.read(object::kStatus, status_sub::kSamplesTaken), 0u);
  // Stopping discards.
  cycle();
  ASSERT_EQ(set(object::kState, 0, raw(RecorderState::Idle)), SdoAbort::None);
  EXPECT_EQ(recorder.state(), RecorderState::Idle);
  EXPECT_EQ(decode(data()).samples, 0u);
}

TEST_F(RecorderTest, SettingsAreRefusedWhileArmedOrTriggered) {
  channels({kVelocity});
  ASSERT_EQ(set(object::kSamples, 0, 4), SdoAbort::None);
  trigger(RecorderTrigger::Level, kVelocity, 1.0f, RecorderEdge::Rising, 0);
  ASSERT_EQ(arm(), SdoAbort::None);
  auto expect_all_refused = [&](const char* when) {
    EXPECT_EQ(set(object::kChannels, 0, 0), SdoAbort::DeviceState) << when;
    EXPECT_EQ(set(object::kChannels, 2, index_of(kTorque)), SdoAbort::DeviceState) << when;
    EXPECT_EQ(set(object::kDivider, 0, 2), SdoAbort::DeviceState) << when;
    EXPECT_EQ(set(object::kSamples, 0, 8), SdoAbort::DeviceState) << when;
    for (std::uint8_t sub = 1; sub <= trigger_sub::kHighest; ++sub) {
      EXPECT_EQ(set(object::kTrigger, sub, 0), SdoAbort::DeviceState) << when << " trigger sub " << int{sub};
    }
  };
  expect_all_refused("armed");
  cycle();
  value(kVelocity) = 2.0f;
  cycle();
  ASSERT_EQ(recorder.state(), RecorderState::Triggered);
  expect_all_refused("triggered");
  EXPECT_EQ(recorder.read(object::kChannels, 1), index_of(kVelocity)) << "unchanged";
  EXPECT_EQ(recorder.read(object::kSamples, 0), 4u);
}

TEST_F(RecorderTest, SettingsAreCheckedWhenWritten) {
  EXPECT_EQ(set(object::kChannels, 1, 0x3000), SdoAbort::ValueRangeExceeded) << "a HIL input, no field";
  EXPECT_EQ(set(object::kChannels, 1, 0x12345), SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(set(object::kChannels, 0, 1), SdoAbort::ParameterIncompatible) << "channel 1 names nothing";
  EXPECT_EQ(set(object::kChannels, 0, Recorder::kMaxChannels + 1), SdoAbort::ValueRangeExceeded);
  ASSERT_EQ(set(object::kChannels, 1, index_of(kVelocity)), SdoAbort::None);
  ASSERT_EQ(set(object::kChannels, 0, 1), SdoAbort::None);
  EXPECT_EQ(set(object::kChannels, 1, 0), SdoAbort::ParameterIncompatible) << "channel 1 is in use";
  EXPECT_EQ(set(object::kChannels, 2, 0), SdoAbort::None);
  EXPECT_EQ(set(object::kDivider, 0, 0), SdoAbort::ValueTooLow);
  EXPECT_EQ(set(object::kSamples, 0, 0), SdoAbort::ValueTooLow);
  EXPECT_EQ(set(object::kSamples, 0, Recorder::kBufferValues + 1), SdoAbort::ValueTooHigh);
  EXPECT_EQ(set(object::kTrigger, trigger_sub::kSource, 7), SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(set(object::kTrigger, trigger_sub::kEdge, 7), SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(set(object::kTrigger, trigger_sub::kField, 0x3100), SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(set(object::kTrigger, trigger_sub::kLevel, 0x7FC0'0000), SdoAbort::ValueRangeExceeded) << "NaN";
  EXPECT_EQ(set(object::kTrigger, trigger_sub::kLevel, float_bits(std::numeric_limits<float>::infinity())), SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(set(object::kTrigger, trigger_sub::kPreTriggerPercent, 101), SdoAbort::ValueTooHigh);
  EXPECT_EQ(set(object::kState, 0, raw(RecorderState::Triggered)), SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(set(object::kState, 0, raw(RecorderState::Done)), SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(recorder.state(), RecorderState::Idle);
}

TEST_F(RecorderTest, ArmingChecksThatTheSettingsFitTogether) {
  EXPECT_EQ(arm(), SdoAbort::ParameterIncompatible) << "no channels";
  channels({kVelocity, kTorque});
  ASSERT_EQ(set(object::kSamples, 0, Recorder::kBufferValues / 2 + 1), SdoAbort::None);
  EXPECT_EQ(arm(), SdoAbort::ParameterIncompatible) << "samples * channels past the buffer";
  ASSERT_EQ(set(object::kSamples, 0, Recorder::kBufferValues / 2), SdoAbort::None);
  ASSERT_EQ(set(object::kTrigger, trigger_sub::kSource, raw(RecorderTrigger::Level)), SdoAbort::None);
  EXPECT_EQ(arm(), SdoAbort::ParameterIncompatible) << "a level trigger needs a field";
  ASSERT_EQ(set(object::kTrigger, trigger_sub::kField, index_of(kTorque)), SdoAbort::None);
  EXPECT_EQ(arm(), SdoAbort::None);
}

TEST_F(RecorderTest, FullPreTriggerShareStillLeavesTheTriggerSample) {
  channels({kVelocity});
  ASSERT_EQ(set(object::kSamples, 0, 4), SdoAbort::None);
  trigger(RecorderTrigger::Level, kVelocity, 1.0f, RecorderEdge::Rising, 100);
  ASSERT_EQ(arm(), SdoAbort::None);
  for (int k = 0; k < 5; ++k) cycle();
  value(kVelocity) = 1.0f;
  cycle();
  ASSERT_EQ(recorder.state(), RecorderState::Done) << "3 before, the trigger sample, none after";
  const Decoded d = decode(data());
  EXPECT_EQ(d.trigger_sample, 3u);
  EXPECT_EQ(d.rows[3][0], 1.0f);
}

TEST_F(RecorderTest, FullBufferOfMaxChannelsReadsBackInAnyChunks) {
  std::array<FieldId, Recorder::kMaxChannels> ids{};
  for (std::size_t c = 0; c < ids.size(); ++c) ids[c] = static_cast<FieldId>(c);
  ASSERT_EQ(set(object::kChannels, 0, 0), SdoAbort::None);
  for (std::size_t c = 0; c < ids.size(); ++c) {
    ASSERT_EQ(set(object::kChannels, static_cast<std::uint8_t>(c + 1), index_of(ids[c])), SdoAbort::None);
  }
  ASSERT_EQ(set(object::kChannels, 0, Recorder::kMaxChannels), SdoAbort::None);
  const auto samples = static_cast<std::uint32_t>(Recorder::kBufferValues / Recorder::kMaxChannels);
  ASSERT_EQ(set(object::kSamples, 0, samples), SdoAbort::None);
  trigger(RecorderTrigger::Level, ids[0], 0.5f, RecorderEdge::Rising, 25);
  ASSERT_EQ(arm(), SdoAbort::None);
  std::uint32_t k = 0;
  for (; k < samples + 321; ++k) {  // wraps before the trigger
    for (std::size_t c = 0; c < ids.size(); ++c) value(ids[c]) = static_cast<float>(k * 10 + c) / 1000.0f;
    value(ids[0]) = 0.0f;
    cycle();
  }
  while (recorder.state() != RecorderState::Done) {
    for (std::size_t c = 0; c < ids.size(); ++c) value(ids[c]) = static_cast<float>(k * 10 + c) / 1000.0f;
    value(ids[0]) = 1.0f;
    cycle();
    ++k;
  }
  const std::vector<std::uint8_t> whole = data(64);
  EXPECT_EQ(whole.size(), layout::header_bytes(Recorder::kMaxChannels) + 4 * Recorder::kBufferValues);
  EXPECT_EQ(data(7), whole);
  EXPECT_EQ(data(5), whole);
  const Decoded d = decode(whole);
  ASSERT_EQ(d.rows.size(), samples);
  EXPECT_EQ(d.trigger_sample, samples / 4);
  const std::uint32_t first_k = samples + 321 - samples / 4;
  for (std::size_t row = 0; row < samples; ++row) {
    const auto sample_k = static_cast<std::uint32_t>(first_k + row);
    EXPECT_EQ(d.rows[row][3], static_cast<float>(sample_k * 10 + 3) / 1000.0f) << row;
  }
}

TEST_F(RecorderTest, ResetGoesBackToPowerOn) {
  channels({kVelocity});
  ASSERT_EQ(set(object::kDivider, 0, 5), SdoAbort::None);
  ASSERT_EQ(arm(), SdoAbort::None);
  recorder.reset();
  EXPECT_EQ(recorder.state(), RecorderState::Idle);
  EXPECT_EQ(recorder.read(object::kChannels, 0), 0u);
  EXPECT_EQ(recorder.read(object::kDivider, 0), 1u);
}

TEST_F(RecorderTest, ObjectsHaveTheTypesTheEdsLists) {
  board::DataType type{};
  bool writable = false;
  EXPECT_EQ(Recorder::find(object::kData, 0, type, writable), SdoAbort::None);
  EXPECT_EQ(type, board::DataType::Domain);
  EXPECT_FALSE(writable);
  EXPECT_EQ(Recorder::find(object::kData, 1, type, writable), SdoAbort::SubIndexDoesNotExist);
  EXPECT_EQ(Recorder::find(object::kChannels, Recorder::kMaxChannels, type, writable), SdoAbort::None);
  EXPECT_EQ(type, board::DataType::Unsigned16);
  EXPECT_EQ(Recorder::find(object::kChannels, Recorder::kMaxChannels + 1, type, writable),
            SdoAbort::SubIndexDoesNotExist);
  EXPECT_EQ(Recorder::find(object::kTrigger, trigger_sub::kLevel, type, writable), SdoAbort::None);
  EXPECT_EQ(type, board::DataType::Real32);
  EXPECT_EQ(Recorder::find(object::kStatus, status_sub::kSamplesLeft, type, writable), SdoAbort::None);
  EXPECT_FALSE(writable);
}

// --- Through the node ---------------------------------------------------------------------------

using Frame = std::array<std::uint8_t, 8>;


class RecorderNodeTest : public NodeTest {
 protected:
  SdoAbort set(std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size) {
    return download(index, sub, value, size);
  }
  void cycle() {
    ++cycle_number;
    recorder.sample(cycle_number, [this](FieldId id) { return fields.read(id); });
  }
  // The frames answering one request and every poll after it until the node falls silent; also
  // how many frames each call (process, then each poll) sent.
  std::vector<Frame> exchange(const Frame& request, std::vector<std::size_t>* per_call = nullptr) {
    CanFrame frame;
    frame.id = kSdoRx;
    frame.len = 8;
    frame.data = request;
    node.process(frame, now_us);
    std::vector<Frame> out;
    for (int calls = 0; calls < 1000; ++calls) {
      const std::vector<CanFrame> sent = all_sent();
      if (sent.empty()) break;
      if (per_call != nullptr) per_call->push_back(sent.size());
      for (const CanFrame& f : sent) out.push_back(f.data);
      node.poll(now_us);
    }
    return out;
  }

  std::uint32_t cycle_number = 0;
};

TEST_F(RecorderNodeTest, ObjectsAnswerOverSdoAndAreNotMappable) {
  EXPECT_EQ(upload(object::kState, 0), raw(RecorderState::Idle));
  EXPECT_EQ(upload(object::kSamples, 0), board::kRecorder.default_samples);
  EXPECT_EQ(set(object::kChannels, 1, index_of(kVelocity), 2), SdoAbort::None);
  EXPECT_EQ(set(object::kChannels, 0, 1, 1), SdoAbort::None);
  EXPECT_EQ(upload(object::kChannels, 1), index_of(kVelocity));
  EXPECT_EQ(set(object::kTrigger, 0, 3, 1), SdoAbort::ReadOnly);
  EXPECT_EQ(set(object::kStatus, 1, 3, 4), SdoAbort::ReadOnly);
  EXPECT_EQ(set(object::kDivider, 0, 1, 4), SdoAbort::LengthTooHigh) << "UNSIGNED16";
  EXPECT_EQ(upload_abort(object::kData, 1), SdoAbort::SubIndexDoesNotExist);
  // TPDO1 mapping: the recorder's objects travel by SDO only.
  const std::uint32_t cob_id = upload(0x1800, 1);
  ASSERT_EQ(set(0x1800, 1, cob_id | 0x8000'0000u, 4), SdoAbort::None);  // invalid while remapped
  ASSERT_EQ(set(0x1A00, 0, 0, 1), SdoAbort::None);
  EXPECT_EQ(set(0x1A00, 1, (std::uint32_t{object::kState} << 16) | 8, 4), SdoAbort::ObjectCannotBeMapped);
  EXPECT_EQ(set(0x1A00, 1, (std::uint32_t{object::kDivider} << 16) | 16, 4), SdoAbort::ObjectCannotBeMapped);
}

TEST_F(RecorderNodeTest, WhileArmedSettingsAndDataAbortWithTheDeviceStateCode) {
  ASSERT_EQ(set(object::kChannels, 1, index_of(kVelocity), 2), SdoAbort::None);
  ASSERT_EQ(set(object::kChannels, 0, 1, 1), SdoAbort::None);
  ASSERT_EQ(set(object::kState, 0, raw(RecorderState::Armed), 1), SdoAbort::None);
  EXPECT_EQ(upload(object::kState, 0), raw(RecorderState::Armed));
  EXPECT_EQ(set(object::kChannels, 1, index_of(kTorque), 2), SdoAbort::DeviceState);
  EXPECT_EQ(sdo({0x40, static_cast<std::uint8_t>(object::kData), static_cast<std::uint8_t>(object::kData >> 8), 0}),
            abort_data(object::kData, 0, SdoAbort::DeviceState));
  EXPECT_EQ(to_code(SdoAbort::DeviceState), 0x0800'0022u);  // protocol-literal: the spec's code
  // Reset node: the recorder is back at power-on.
  nmt(NmtCommand::ResetNode);
  all_sent();
  EXPECT_EQ(upload(object::kState, 0), raw(RecorderState::Idle));
  EXPECT_EQ(upload(object::kChannels, 0), 0u);
}

TEST_F(RecorderNodeTest, BlockUploadOfAFullRecordingFrameByFrame) {
  // 8 channels, as many samples as the buffer holds: the largest recording there is.
  for (std::uint8_t c = 0; c < Recorder::kMaxChannels; ++c) {
    ASSERT_EQ(set(object::kChannels, static_cast<std::uint8_t>(c + 1), index_of(static_cast<FieldId>(c)), 2),
              SdoAbort::None);
  }
  ASSERT_EQ(set(object::kChannels, 0, Recorder::kMaxChannels, 1), SdoAbort::None);
  const auto samples = static_cast<std::uint32_t>(Recorder::kBufferValues / Recorder::kMaxChannels);
  ASSERT_EQ(set(object::kSamples, 0, samples, 4), SdoAbort::None);
  ASSERT_EQ(set(object::kState, 0, raw(RecorderState::Armed), 1), SdoAbort::None);
  for (std::uint32_t k = 0; k < samples; ++k) {
    for (std::size_t c = 0; c < Recorder::kMaxChannels; ++c) {
      fields.values[c] = static_cast<float>(k) + static_cast<float>(c) / 8.0f;
    }
    cycle();
  }
  ASSERT_EQ(upload(object::kState, 0), raw(RecorderState::Done));
  const std::size_t size = layout::header_bytes(Recorder::kMaxChannels) + 4 * Recorder::kBufferValues;

  // Initiate (CRC, blksize 127): the size is announced.
  const Frame initiate = sdo({0xA4, static_cast<std::uint8_t>(object::kData),
                              static_cast<std::uint8_t>(object::kData >> 8), 0, 127, 0});
  ASSERT_EQ(initiate[0], 0xC6);
  EXPECT_EQ(tables::get_le(std::span(initiate).subspan(4, 4)), size);

  std::vector<std::uint8_t> value;
  std::vector<std::size_t> per_call;
  std::vector<Frame> segments = exchange({0xA3}, &per_call);  // start
  std::size_t sub_blocks = 0;
  for (; sub_blocks < 200; ++sub_blocks) {
    ASSERT_FALSE(segments.empty());
    bool last = false;
    for (std::size_t s = 0; s < segments.size(); ++s) {
      ASSERT_EQ(segments[s][0] & 0x7F, s + 1) << "sequence numbers 1..blksize";
      last = (segments[s][0] & 0x80) != 0;
      value.insert(value.end(), segments[s].begin() + 1, segments[s].end());
    }
    // Lose segment 60 of the first sub-block once: the ack says 59, the rest is sent again and
    // read again by offset from the frozen recording.
    const auto acknowledged = static_cast<std::uint8_t>(sub_blocks == 0 ? 59 : segments.size());
    if (sub_blocks == 0) value.resize(value.size() - 7 * (segments.size() - 59));
    segments = exchange({0xA2, acknowledged, 127});
    if (last && sub_blocks != 0) break;
  }
  ASSERT_EQ(segments.size(), 1u);
  const Frame end = segments.front();
  ASSERT_EQ(end[0] & 0xE3, 0xC1) << "end block upload";
  value.resize(value.size() - ((end[0] >> 2) & 0x7));
  ASSERT_EQ(value.size(), size);
  EXPECT_EQ(static_cast<std::uint16_t>(end[1] | (end[2] << 8)), reference_crc(value));
  EXPECT_TRUE(exchange({0xA1}).empty());
  EXPECT_EQ(node.counters().sdo_aborts_sent, 0u);
  EXPECT_GT(sub_blocks, 70u) << "a recording of ~64 KiB is many sub-blocks of 127 segments";

  // The first sub-block went out at most kSdoSegmentsPerCall segments a call.
  ASSERT_GE(per_call.size(), 127u / Node::kSdoSegmentsPerCall);
  for (const std::size_t n : per_call) EXPECT_LE(n, Node::kSdoSegmentsPerCall);
  EXPECT_EQ(per_call.front(), Node::kSdoSegmentsPerCall);

  // The bytes are the recording.
  const Decoded d = decode(value);
  ASSERT_EQ(d.rows.size(), samples);
  EXPECT_EQ(d.first_cycle, 1u);
  EXPECT_EQ(d.last_cycle, samples);
  for (std::uint32_t k = 0; k < samples; k += 97) {
    for (std::size_t c = 0; c < Recorder::kMaxChannels; ++c) {
      EXPECT_EQ(d.rows[k][c], static_cast<float>(k) + static_cast<float>(c) / 8.0f) << k << "/" << c;
    }
  }
}

TEST_F(RecorderNodeTest, SegmentsDueTellsTheLoopNotToSleepMidSubBlock) {
  ASSERT_EQ(set(object::kChannels, 1, index_of(kTorque), 2), SdoAbort::None);
  ASSERT_EQ(set(object::kChannels, 0, 1, 1), SdoAbort::None);
  ASSERT_EQ(set(object::kSamples, 0, 400, 4), SdoAbort::None);  // 1600+ bytes: over 127 segments
  ASSERT_EQ(set(object::kState, 0, raw(RecorderState::Armed), 1), SdoAbort::None);
  for (int k = 0; k < 400; ++k) cycle();
  ASSERT_EQ(upload(object::kState, 0), raw(RecorderState::Done));
  EXPECT_FALSE(node.sdo_segments_due());
  const Frame initiate = sdo({0xA4, static_cast<std::uint8_t>(object::kData),
                              static_cast<std::uint8_t>(object::kData >> 8), 0, 127, 0});
  ASSERT_EQ(initiate[0], 0xC6);
  EXPECT_FALSE(node.sdo_segments_due()) << "nothing to send before the client's start";

  CanFrame start;
  start.id = kSdoRx;
  start.len = 8;
  start.data = {0xA3};
  node.process(start, now_us);
  std::size_t sent = all_sent().size();
  EXPECT_EQ(sent, Node::kSdoSegmentsPerCall);
  EXPECT_TRUE(node.sdo_segments_due()) << "119 segments of the sub-block still to go";
  int polls = 0;
  while (node.sdo_segments_due() && polls < 100) {
    node.poll(now_us);
    sent += all_sent().size();
    ++polls;
  }
  EXPECT_EQ(sent, 127u) << "the whole sub-block, then silence until the ack";
  EXPECT_FALSE(node.sdo_segments_due());
  EXPECT_TRUE(exchange({0xA2, 127, 127}).size() > 0) << "the next sub-block after the ack";
}

TEST_F(RecorderNodeTest, SegmentedUploadOfARecordingAlsoWorks) {
  ASSERT_EQ(set(object::kChannels, 1, index_of(kTorque), 2), SdoAbort::None);
  ASSERT_EQ(set(object::kChannels, 0, 1, 1), SdoAbort::None);
  ASSERT_EQ(set(object::kSamples, 0, 3, 4), SdoAbort::None);
  ASSERT_EQ(set(object::kState, 0, raw(RecorderState::Armed), 1), SdoAbort::None);
  for (int k = 0; k < 3; ++k) {
    fields.values[FakeBoard::index(kTorque)] = static_cast<float>(k) * 1.5f;
    cycle();
  }
  const Frame initiate = sdo({0x40, static_cast<std::uint8_t>(object::kData),
                              static_cast<std::uint8_t>(object::kData >> 8), 0});
  ASSERT_EQ(initiate[0], 0x41);
  const std::size_t size = tables::get_le(std::span(initiate).subspan(4, 4));
  ASSERT_EQ(size, layout::header_bytes(1) + 12);
  std::vector<std::uint8_t> value;
  std::uint8_t toggle = 0;
  while (value.size() < size) {
    const Frame segment = sdo({static_cast<std::uint8_t>(0x60 | toggle)});
    ASSERT_EQ(segment[0] & 0x10, toggle);
    const std::size_t unused = (segment[0] >> 1) & 0x7;
    value.insert(value.end(), segment.begin() + 1, segment.end() - static_cast<long>(unused));
    toggle ^= 0x10;
    if ((segment[0] & 0x01) != 0) break;
  }
  const Decoded d = decode(value);
  ASSERT_EQ(d.rows.size(), 3u);
  EXPECT_EQ(d.rows[2][0], 3.0f);
}

}  // namespace
}  // namespace co::test
