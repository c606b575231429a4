#include "core/SampleBuffer.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <vector>

namespace core {
namespace {

TEST(SampleBufferTest, DrainsSamplesOldestFirst) {
  SampleBuffer<std::int16_t, 8> buffer;
  for (const std::int16_t sample : std::array<std::int16_t, 5>{3, 1, 4, 1, 5}) {
    EXPECT_TRUE(buffer.push(sample));
  }
  std::vector<std::int16_t> drained;
  EXPECT_EQ(buffer.drain([&](std::int16_t sample) { drained.push_back(sample); }), 5u);
  EXPECT_EQ(drained, (std::vector<std::int16_t>{3, 1, 4, 1, 5}));
  EXPECT_EQ(buffer.size(), 0u);
}

TEST(SampleBufferTest, DropsAndCountsSamplesPushedIntoFullBuffer) {
  SampleBuffer<std::int16_t, 4> buffer;
  for (std::int16_t sample = 0; sample < 6; ++sample) {
    EXPECT_EQ(buffer.push(sample), sample < 4);
  }
  EXPECT_EQ(buffer.overflow_count(), 2u);
  std::vector<std::int16_t> drained;
  buffer.drain([&](std::int16_t sample) { drained.push_back(sample); });
  EXPECT_EQ(drained, (std::vector<std::int16_t>{0, 1, 2, 3}));
}

TEST(SampleBufferTest, AcceptsSamplesAgainAfterDrain) {
  SampleBuffer<std::uint32_t, 4> buffer;
  for (std::uint32_t round = 0; round < 10; ++round) {  // the indices wrap around the ring
    EXPECT_TRUE(buffer.push(round));
    EXPECT_TRUE(buffer.push(round + 100));
    std::vector<std::uint32_t> drained;
    buffer.drain([&](std::uint32_t sample) { drained.push_back(sample); });
    EXPECT_EQ(drained, (std::vector<std::uint32_t>{round, round + 100}));
  }
  EXPECT_EQ(buffer.overflow_count(), 0u);
}

TEST(SampleBufferTest, DrainIntoArrayLeavesWhatDoesNotFit) {
  SampleBuffer<float, 8> buffer;
  for (int i = 0; i < 5; ++i) {
    EXPECT_TRUE(buffer.push(static_cast<float>(i)));
  }
  std::array<float, 3> out{};
  EXPECT_EQ(buffer.drain_into(out), 3u);
  EXPECT_EQ(out, (std::array<float, 3>{0.0f, 1.0f, 2.0f}));
  EXPECT_EQ(buffer.size(), 2u);
  EXPECT_EQ(buffer.drain_into(out), 2u);
  EXPECT_FLOAT_EQ(out[0], 3.0f);
  EXPECT_FLOAT_EQ(out[1], 4.0f);
  EXPECT_EQ(buffer.drain_into(out), 0u);
}

}  // namespace
}  // namespace core
