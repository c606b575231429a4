#include "joint/sensors/EncoderUnwrapper.hpp"

#include <gtest/gtest.h>

#include <limits>
#include <numbers>

namespace joint {
namespace {

TEST(EncoderUnwrapper, CountsForwardAcrossTheWrap) {
  EncoderUnwrapper unwrapper;
  unwrapper.update(30000);
  unwrapper.update(60000);
  ASSERT_EQ(unwrapper.update(65530), 65530);
  EXPECT_EQ(unwrapper.update(5), 65530 + 11);
}

TEST(EncoderUnwrapper, CountsBackwardAcrossTheWrap) {
  EncoderUnwrapper unwrapper;
  unwrapper.update(5);
  EXPECT_EQ(unwrapper.update(65530), 5 - 11);
  EXPECT_EQ(unwrapper.update(35530), 5 - 11 - 30000);
}

TEST(EncoderUnwrapper, TakesTheFirstReadingAsASignedStepFromZero) {
  EncoderUnwrapper unwrapper;
  EXPECT_EQ(unwrapper.update(65535), -1);
}

TEST(EncoderUnwrapper, KeepsCountingOverManyWrapsInBothDirections) {
  EncoderUnwrapper unwrapper;
  std::uint16_t raw = 0;
  for (int i = 0; i < 1000; ++i) {  // +300 000 counts: more than four wraps
    raw = static_cast<std::uint16_t>(raw + 300);
    unwrapper.update(raw);
  }
  EXPECT_EQ(unwrapper.counts(), 300000);
  for (int i = 0; i < 2000; ++i) {  // -600 000 counts
    raw = static_cast<std::uint16_t>(raw - 300);
    unwrapper.update(raw);
  }
  EXPECT_EQ(unwrapper.counts(), -300000);
}

TEST(EncoderUnwrapper, ConvertsCountsToRadians) {
  EXPECT_FLOAT_EQ(counts_to_rad(4096, 4096.0F), 2.0F * std::numbers::pi_v<float>);
  EXPECT_FLOAT_EQ(counts_to_rad(-1024, 4096.0F), -0.5F * std::numbers::pi_v<float>);
}

TEST(EncoderUnwrapper, CounterStepIsTheSignedModularDifference) {
  EXPECT_EQ(counter_step(2, 65535), 3);
  EXPECT_EQ(counter_step(65535, 2), -3);
  EXPECT_EQ(counter_step(40000, 7233), 32767);  // the largest step forward
  EXPECT_EQ(counter_step(7233, 40000), -32767);
  EXPECT_EQ(counter_step(40000, 7232), -32768);  // half a wrap reads as backwards
}

TEST(EncoderUnwrapper, ReadsACounterValueBackFromABoardField) {
  EXPECT_EQ(counter_from_field(0.0F), 0U);
  EXPECT_EQ(counter_from_field(65535.0F), 65535U);
  EXPECT_EQ(counter_from_field(65536.0F), 0U);  // folded onto the counter, not undefined
  EXPECT_EQ(counter_from_field(-1.0F), 65535U);
  EXPECT_EQ(counter_from_field(std::numeric_limits<float>::quiet_NaN()), 0U);
}

}  // namespace
}  // namespace joint
