#include "joint/virtual_sensors/VelocityFilter.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace joint {
namespace {

constexpr float kDtS = 0.001F;

TEST(VelocityFilter, StepResponseFollowsTheFirstOrderCurve) {
  // A position ramp starting at t = 0 is a velocity step of 2 rad/s.
  constexpr float kCutoffHz = 10.0F;
  constexpr float kStepRadS = 2.0F;
  VelocityFilter filter;
  filter.update(0.0F, kDtS, kCutoffHz);
  EXPECT_FALSE(filter.has_velocity());
  for (int n = 1; n <= 200; ++n) {
    const float t_s = static_cast<float>(n) * kDtS;
    const float velocity = filter.update(kStepRadS * t_s, kDtS, kCutoffHz);
    const float expected = kStepRadS * (1.0F - std::exp(-2.0F * std::numbers::pi_v<float> * kCutoffHz * t_s));
    ASSERT_NEAR(velocity, expected, 1e-3F) << "at t = " << t_s << " s";
  }
  // One time constant (1 / (2 pi 10 Hz) = 15.9 ms) gives 63 %; 200 ms is settled.
  EXPECT_NEAR(filter.velocity(), kStepRadS, 1e-3F);
}

TEST(VelocityFilter, CountsAGapAsElapsedTimeRatherThanASpike) {
  VelocityFilter filter;
  float position = 0.0F;
  for (int n = 0; n < 500; ++n) {
    position += 1.0F * kDtS;  // 1 rad/s
    filter.update(position, kDtS, 100.0F);
  }
  position += 5.0F * kDtS;  // five cycles without a sample at the same speed
  EXPECT_NEAR(filter.update(position, 5.0F * kDtS, 100.0F), 1.0F, 1e-3F);
}

}  // namespace
}  // namespace joint
