// InterruptCanPort, the software half of a CAN driver: frames in order through both rings, a full
// transmit ring refused (QueueFull, the frame not queued), a full receive ring counted as an
// overrun, and the indices wrapping around the ring. Runs on the emulated Cortex-M4
// (cm_platform_tests).
#include "InterruptCanPort.hpp"

#include <gtest/gtest.h>

#include <cstdint>

#include "board/cia301.hpp"

namespace cortexm {
namespace {

// Two modules' TPDO1: frames as a robot's bus carries them.
constexpr std::uint32_t kFirst = cia301::cob_id(cia301::FunctionCode::Tpdo1, 1);
constexpr std::uint32_t kSecond = cia301::cob_id(cia301::FunctionCode::Tpdo1, 2);

co::CanFrame frame_with(std::uint32_t id) {
  co::CanFrame frame;
  frame.id = id;
  frame.len = 1;
  frame.data[0] = static_cast<std::uint8_t>(id);
  return frame;
}

TEST(InterruptCanPortTest, ReceivedFramesReachTheEngineInOrder) {
  InterruptCanPort<4, 4> port;
  co::CanFrame frame;
  EXPECT_EQ(port.receive(frame), co::ReceiveResult::Empty);
  port.push_received(frame_with(kFirst));
  port.push_received(frame_with(kSecond));
  ASSERT_EQ(port.receive(frame), co::ReceiveResult::Received);
  EXPECT_EQ(frame, frame_with(kFirst));
  ASSERT_EQ(port.receive(frame), co::ReceiveResult::Received);
  EXPECT_EQ(frame, frame_with(kSecond));
  EXPECT_EQ(port.receive(frame), co::ReceiveResult::Empty);
  EXPECT_EQ(port.receive_overruns(), 0u);
}

TEST(InterruptCanPortTest, AFullReceiveRingCountsTheFrameItCannotTakeAsAnOverrun) {
  InterruptCanPort<2, 2> port;
  for (std::uint32_t id = 1; id <= 3; ++id) port.push_received(frame_with(id));
  EXPECT_EQ(port.receive_overruns(), 1u);
  co::CanFrame frame;
  ASSERT_EQ(port.receive(frame), co::ReceiveResult::Received);
  EXPECT_EQ(frame.id, 1u);  // the oldest kept, the newest dropped
  ASSERT_EQ(port.receive(frame), co::ReceiveResult::Received);
  EXPECT_EQ(frame.id, 2u);
}

TEST(InterruptCanPortTest, AFullTransmitRingRefusesTheFrameAndKeepsTheQueuedOnes) {
  InterruptCanPort<2, 2> port;
  EXPECT_EQ(port.send(frame_with(1)), co::SendResult::Sent);
  EXPECT_EQ(port.send(frame_with(2)), co::SendResult::Sent);
  EXPECT_EQ(port.send(frame_with(3)), co::SendResult::QueueFull);
  co::CanFrame frame;
  ASSERT_TRUE(port.pop_to_transmit(frame));
  EXPECT_EQ(frame.id, 1u);
  EXPECT_EQ(port.send(frame_with(4)), co::SendResult::Sent);  // room again
  ASSERT_TRUE(port.pop_to_transmit(frame));
  EXPECT_EQ(frame.id, 2u);
  ASSERT_TRUE(port.pop_to_transmit(frame));
  EXPECT_EQ(frame.id, 4u);
  EXPECT_FALSE(port.pop_to_transmit(frame));
}

TEST(InterruptCanPortTest, TheRingsKeepOrderAcrossManyWrapsOfTheirIndices) {
  InterruptCanPort<4, 4> port;
  co::CanFrame frame;
  for (std::uint32_t id = 0; id < 1000; ++id) {
    ASSERT_EQ(port.send(frame_with(id)), co::SendResult::Sent);
    if (id % 3 == 2) {  // the interrupt drains three at a time
      for (std::uint32_t expected = id - 2; expected <= id; ++expected) {
        ASSERT_TRUE(port.pop_to_transmit(frame));
        ASSERT_EQ(frame.id, expected);
      }
    }
  }
}

}  // namespace
}  // namespace cortexm
