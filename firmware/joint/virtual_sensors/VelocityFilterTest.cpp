#include "joint/virtual_sensors/VelocityFilter.hpp"

#include <gtest/gtest.h>

#include "joint/testing/BoardStandIns.hpp"

#include <cmath>
#include <numbers>

namespace joint {
namespace {

using joint::testing::kDtS;

TEST(VelocityFilter, StepResponseFollowsTheFirstOrderCurve) {
  // Equal displacements from t = 0 on are a velocity step of 2 rad/s.
  constexpr float kCutoffHz = 10.0F;
  constexpr float kStepRadS = 2.0F;
  VelocityFilter filter;
  EXPECT_FALSE(filter.has_velocity());
  for (int n = 1; n <= 200; ++n) {
    const float t_s = static_cast<float>(n) * kDtS;
    const float velocity = filter.update(kStepRadS * kDtS, kDtS, kCutoffHz);
    const float expected = kStepRadS * (1.0F - std::exp(-2.0F * std::numbers::pi_v<float> * kCutoffHz * t_s));
    ASSERT_NEAR(velocity, expected, 1e-3F) << "at t = " << t_s << " s";
  }
  EXPECT_TRUE(filter.has_velocity());
  // One time constant (1 / (2 pi 10 Hz) = 15.9 ms) gives 63 %; 200 ms is settled.
  EXPECT_NEAR(filter.velocity(), kStepRadS, 1e-3F);
}

TEST(VelocityFilter, CountsAGapAsElapsedTimeRatherThanASpike) {
  VelocityFilter filter;
  for (int n = 0; n < 500; ++n) {
    filter.update(1.0F * kDtS, kDtS, 100.0F);  // 1 rad/s
  }
  // Five cycles without a sample at the same speed: one sample of five cycles' displacement.
  EXPECT_NEAR(filter.update(5.0F * kDtS, 5.0F * kDtS, 100.0F), 1.0F, 1e-3F);
}

TEST(VelocityFilter, IgnoresASampleWithoutElapsedTime) {
  VelocityFilter filter;
  filter.update(0.001F, kDtS, 100.0F);
  const float before = filter.velocity();
  EXPECT_EQ(filter.update(1.0F, 0.0F, 100.0F), before);
}

}  // namespace
}  // namespace joint
