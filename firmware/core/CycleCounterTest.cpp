#include "core/CycleCounter.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>

namespace {

TEST(CycleCounterTest, OneCyclePerPeriodCountsNothingSkipped) {
  core::CycleCounter cycles;
  for (std::uint32_t expected = 1; expected <= 5; ++expected) {
    EXPECT_EQ(cycles.advance(), expected);
  }
  EXPECT_EQ(cycles.run(), 5u);
  EXPECT_EQ(cycles.skipped(), 0u);
}

TEST(CycleCounterTest, ALateWakeUpAdvancesByThePeriodsThatPassed) {
  // Periods of 10 ms, the process descheduled for 40 ms after cycle 2: the next cycle is
  // number 6, so 4 cycles (40 ms) lie between a position read at cycle 2 and one at cycle 6.
  core::CycleCounter cycles;
  cycles.advance();
  const std::uint32_t before = cycles.advance();
  const std::uint32_t after = cycles.advance(4);
  EXPECT_EQ(after - before, 4u);
  EXPECT_EQ(cycles.cycle(), 6u);
  EXPECT_EQ(cycles.run(), 3u);
  EXPECT_EQ(cycles.skipped(), 3u);
}

TEST(CycleCounterTest, NoPeriodPassedIsNoCycle) {
  core::CycleCounter cycles;
  cycles.advance(2);
  EXPECT_EQ(cycles.advance(0), 2u);
  EXPECT_EQ(cycles.run(), 1u);
  EXPECT_EQ(cycles.skipped(), 1u);
}

TEST(CycleCounterTest, TheNumberWrapsLikeTheBoardsCycleArithmetic) {
  core::CycleCounter cycles;
  cycles.advance(std::numeric_limits<std::uint32_t>::max());
  const std::uint32_t before = cycles.cycle();
  const std::uint32_t after = cycles.advance(3);
  EXPECT_EQ(after, 2u);
  EXPECT_EQ(static_cast<std::uint32_t>(after - before), 3u);  // differences survive the wrap
}

}  // namespace
