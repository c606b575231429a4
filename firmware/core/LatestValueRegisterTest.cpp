#include "core/LatestValueRegister.hpp"

#include <gtest/gtest.h>

#include <cstdint>

namespace core {
namespace {

TEST(LatestValueRegisterTest, ReadsDefaultValueAsNotFreshBeforeFirstWrite) {
  LatestValueRegister<std::uint16_t> encoder;
  const auto reading = encoder.read();
  EXPECT_EQ(reading.value, 0u);
  EXPECT_FALSE(reading.fresh);
  EXPECT_EQ(encoder.write_count(), 0u);
}

TEST(LatestValueRegisterTest, ValueIsFreshOnlyOnFirstReadAfterWrite) {
  LatestValueRegister<std::uint16_t> encoder;
  encoder.write(1234);
  const auto first = encoder.read();
  EXPECT_EQ(first.value, 1234u);
  EXPECT_TRUE(first.fresh);
  const auto second = encoder.read();
  EXPECT_EQ(second.value, 1234u);
  EXPECT_FALSE(second.fresh);
}

TEST(LatestValueRegisterTest, KeepsNewestValueAndCountsOverwrittenOnes) {
  LatestValueRegister<std::int16_t> current_ma;
  current_ma.write(-5);
  current_ma.write(7);
  current_ma.write(-300);
  const auto reading = current_ma.read();
  EXPECT_EQ(reading.value, -300);
  EXPECT_EQ(reading.writes_since_last_read, 3u);
  EXPECT_EQ(current_ma.write_count(), 3u);
}

TEST(LatestValueRegisterTest, PeekDoesNotConsumeFreshness) {
  LatestValueRegister<float> thermistor;
  thermistor.write(2.5f);
  EXPECT_FLOAT_EQ(thermistor.peek(), 2.5f);
  EXPECT_TRUE(thermistor.read().fresh);
}

}  // namespace
}  // namespace core
