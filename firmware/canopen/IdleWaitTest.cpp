// Node::us_until_next_timer: how long a loop that also wakes for every frame may sleep between
// polls. Each test drives the node in small steps and fails where a frame went out at a poll a
// sleeping loop would have slept through; and checks that the waits are long while idle.
#include <algorithm>

#include "NodeTestSupport.hpp"

namespace co::test {
namespace {

constexpr std::uint32_t kStepUs = 100;
constexpr std::uint32_t kLimitUs = 1'000'000;

class IdleWaitTest : public NodeTest {
 protected:
  static constexpr std::uint32_t kRpdo1 = cia301::cob_id(cia301::FunctionCode::Rpdo1, kNodeId);

  struct Run {
    std::uint32_t frames = 0;
    std::uint32_t longest_wait_us = 0;
  };

  // Polls every kStepUs for `span_us`; a frame sent at a poll that comes later than the wait the
  // node gave before it is a timer the sleeping loop would have missed.
  Run run_checked(std::uint32_t span_us) {
    Run run;
    for (std::uint32_t elapsed = 0; elapsed < span_us; elapsed += kStepUs) {
      const std::uint32_t wait_us = node.us_until_next_timer(now_us, kLimitUs);
      run.longest_wait_us = std::max(run.longest_wait_us, wait_us);
      advance_us(kStepUs);
      const std::size_t sent = all_sent().size();
      run.frames += static_cast<std::uint32_t>(sent);
      EXPECT_TRUE(sent == 0 || wait_us <= kStepUs)
          << sent << " frame(s) at +" << elapsed + kStepUs << " us, but the node said to sleep " << wait_us
          << " us";
    }
    return run;
  }

  void disable_tpdos() {
    for (std::uint16_t n = 0; n < board::kTpdoCount; ++n) {
      const auto communication = static_cast<std::uint16_t>(0x1800 + n);
      ASSERT_EQ(download(communication, 1, upload(communication, 1) | kInvalid, 4), SdoAbort::None);
    }
  }
};

TEST_F(IdleWaitTest, NothingTimedSleepsTheWholeLimit) {
  EXPECT_EQ(node.us_until_next_timer(now_us, kLimitUs), kLimitUs);
  EXPECT_EQ(run_checked(200'000).frames, 0u);
}

TEST_F(IdleWaitTest, HeartbeatProducerWakesOncePerPeriod) {
  ASSERT_EQ(download(0x1017, 0, 50, 2), SdoAbort::None);
  const Run run = run_checked(500'000);
  EXPECT_EQ(run.frames, 10u);
  EXPECT_GE(run.longest_wait_us, 49'900u);
}

TEST_F(IdleWaitTest, EventTpdoTimerAndInhibitTime) {
  disable_tpdos();
  // TPDO1: motor_velocity, event-driven, inhibit 10 ms, event timer 25 ms.
  ASSERT_EQ(download(0x1A00, 0, 0, 1), SdoAbort::None);
  ASSERT_EQ(download(0x1A00, 1, (std::uint32_t{index_of(board::FieldId::motor_velocity)} << 16) | 32u, 4),
            SdoAbort::None);
  ASSERT_EQ(download(0x1A00, 0, 1, 1), SdoAbort::None);
  ASSERT_EQ(download(0x1800, 2, 254, 1), SdoAbort::None);
  ASSERT_EQ(download(0x1800, 3, 100, 2), SdoAbort::None);
  ASSERT_EQ(download(0x1800, 5, 25, 2), SdoAbort::None);
  ASSERT_EQ(download(0x1800, 1, upload(0x1800, 1) & ~kInvalid, 4), SdoAbort::None);
  nmt(NmtCommand::Start);
  advance_us(0);  // the loop polls after every frame: the first transmission
  ASSERT_EQ(all_sent().size(), 1u);
  Run run = run_checked(100'000);
  EXPECT_EQ(run.frames, 4u) << "every 25 ms";
  EXPECT_GE(run.longest_wait_us, 24'000u);
  // A change right after a transmission waits for the inhibit time's end: the node must wake then.
  while (all_sent().empty()) advance_us(kStepUs);
  fields.values[FakeBoard::index(board::FieldId::motor_velocity)] += 1.0f;
  advance_us(kStepUs);
  EXPECT_TRUE(all_sent().empty()) << "inside the inhibit time";
  run = run_checked(10'000);
  EXPECT_EQ(run.frames, 1u) << "the change, when the inhibit time ends";
}

TEST_F(IdleWaitTest, RpdoDeadline) {
  ASSERT_EQ(download(0x1400, 1, kRpdo1 | kInvalid, 4), SdoAbort::None);
  ASSERT_EQ(download(0x1400, 5, 50, 2), SdoAbort::None);
  ASSERT_EQ(download(0x1400, 1, kRpdo1, 4), SdoAbort::None);
  disable_tpdos();
  nmt(NmtCommand::Start);
  all_sent();
  CanFrame frame = make_frame(kRpdo1, {});
  frame.len = 8;
  receive(frame);
  const Run run = run_checked(100'000);
  EXPECT_EQ(run.frames, 1u) << "the EMCY of the missed deadline";
}

TEST_F(IdleWaitTest, WallClockHeartbeatConsumerAndSdoTimeout) {
  ASSERT_EQ(download(0x1016, 1, (std::uint32_t{kMasterId} << 16) | 150u, 4), SdoAbort::None);
  receive(kMasterHeartbeat, {0x05});
  Run run = run_checked(300'000);
  EXPECT_EQ(run.frames, 1u) << "the EMCY of the lost heartbeat";
  // A segmented upload the client never continues: the server aborts it after its timeout.
  const auto answer = sdo({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0});  // 0x1008, device name
  ASSERT_EQ(answer[0] & 0xE0, 0x40);
  run = run_checked(1'100'000);
  EXPECT_EQ(run.frames, 1u) << "the SDO abort";
  EXPECT_GE(run.longest_wait_us, 900'000u);
}

}  // namespace
}  // namespace co::test
