// Heartbeat producer (CiA 301, 7.2.8.3.2.2) and its period object 0x1017.
#include "NodeTestSupport.hpp"

namespace co::test {
namespace {

class HeartbeatTest : public NodeTest {
 protected:
  std::size_t heartbeats_within(std::uint32_t span_us, std::uint32_t step_us = 1'000) {
    std::size_t count = 0;
    for (std::uint32_t t = 0; t < span_us; t += step_us) {
      advance_us(step_us);
      for (const CanFrame& frame : all_sent()) count += frame.id == kHeartbeat ? 1 : 0;
    }
    return count;
  }
};

TEST_F(HeartbeatTest, DefaultPeriodComesFromTheTable) {
  // SetUp switched it off; reset communication brings the default back.
  nmt(NmtCommand::ResetCommunication);
  all_sent();
  const std::uint32_t period_us = std::uint32_t{board::kNode.heartbeat_ms} * 1000u;
  if (period_us == 0) {
    EXPECT_EQ(heartbeats_within(1'000'000), 0u);
    return;
  }
  advance_us(period_us - 1);
  EXPECT_TRUE(all_sent().empty());
  advance_us(1);
  EXPECT_EQ(next_sent(), make_frame(kHeartbeat, {0x7F}));
}

TEST_F(HeartbeatTest, PeriodChangedThrough0x1017) {
  ASSERT_EQ(download(0x1017, 0, 50, 2), SdoAbort::None);
  EXPECT_EQ(upload(0x1017, 0), 50u);
  EXPECT_EQ(heartbeats_within(1'000'000), 20u);
  ASSERT_EQ(download(0x1017, 0, 200, 2), SdoAbort::None);
  EXPECT_EQ(heartbeats_within(1'000'000), 5u);
}

TEST_F(HeartbeatTest, ZeroPeriodDisablesTheHeartbeat) {
  ASSERT_EQ(download(0x1017, 0, 10, 2), SdoAbort::None);
  EXPECT_GT(heartbeats_within(100'000), 0u);
  ASSERT_EQ(download(0x1017, 0, 0, 2), SdoAbort::None);
  EXPECT_EQ(heartbeats_within(1'000'000), 0u);
}

TEST_F(HeartbeatTest, CarriesTheStateByteAndContinuesWhenStopped) {
  ASSERT_EQ(download(0x1017, 0, 10, 2), SdoAbort::None);
  advance_us(10'000);
  EXPECT_EQ(next_sent(), make_frame(kHeartbeat, {0x7F}));
  nmt(NmtCommand::Start);
  advance_us(10'000);
  EXPECT_EQ(next_sent(), make_frame(kHeartbeat, {0x05}));
  nmt(NmtCommand::Stop);
  advance_us(10'000);
  EXPECT_EQ(next_sent(), make_frame(kHeartbeat, {0x04}));
  EXPECT_EQ(node.counters().heartbeats_sent, 3u);
}

TEST_F(HeartbeatTest, LatePollKeepsTheCadence) {
  ASSERT_EQ(download(0x1017, 0, 10, 2), SdoAbort::None);
  advance_us(10'300);  // 0.3 ms late
  EXPECT_EQ(all_sent().size(), 1u);
  advance_us(9'700);   // the next one is due 10 ms after the previous due time
  EXPECT_EQ(all_sent().size(), 1u);
}

}  // namespace
}  // namespace co::test
