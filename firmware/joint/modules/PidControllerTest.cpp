#include "joint/modules/PidController.hpp"

#include <gtest/gtest.h>

#include "joint/testing/BoardStandIns.hpp"

namespace joint {
namespace {

using joint::testing::kDtS;

TEST(PidController, ClampsTheOutputToTheLimit) {
  PidController pid;
  EXPECT_FLOAT_EQ(pid.update(100.0F, 0.0F, kDtS, {.kp = 1.0F}, 0.5F), 0.5F);
  EXPECT_FLOAT_EQ(pid.update(-100.0F, 0.0F, kDtS, {.kp = 1.0F}, 0.5F), -0.5F);
  EXPECT_FLOAT_EQ(pid.update(100.0F, 0.0F, kDtS, {.kp = 1.0F}, -1.0F), 0.0F);
}

TEST(PidController, AddsProportionalAndIntegralActions) {
  PidController pid;
  // e = 2: P = 0.2, I = 5 * 2 * 0.001 = 0.01 per step.
  EXPECT_FLOAT_EQ(pid.update(2.0F, 0.0F, kDtS, {.kp = 0.1F, .ki = 5.0F}, 1.0F), 0.21F);
  EXPECT_FLOAT_EQ(pid.update(2.0F, 0.0F, kDtS, {.kp = 0.1F, .ki = 5.0F}, 1.0F), 0.22F);
}

TEST(PidController, StopsIntegratingWhileSaturated) {
  PidController pid;
  const PidGains gains{.kp = 0.1F, .ki = 10.0F};
  for (int i = 0; i < 10000; ++i) {  // 10 s of a large error with the output pinned
    pid.update(20.0F, 0.0F, kDtS, gains, 1.0F);
  }
  // P = 2 alone saturates, so the integrator never moved; a clamp-only integrator
  // would sit at the limit (1.0) here.
  EXPECT_EQ(pid.integral(), 0.0F);
  // So reversing the error reverses the output at once.
  EXPECT_LT(pid.update(-1.0F, 0.0F, kDtS, gains, 1.0F), 0.0F);
}

TEST(PidController, SettlesWithoutSteadyStateErrorAfterSaturating) {
  // First-order plant y' = (u - y) / tau; the first setpoint is out of reach.
  PidController pid;
  const PidGains gains{.kp = 0.5F, .ki = 5.0F};
  float y = 0.0F;
  float setpoint = 2.0F;
  for (int i = 0; i < 20000; ++i) {
    if (i == 5000) {
      setpoint = 0.5F;
    }
    const float u = pid.update(setpoint, y, kDtS, gains, 1.0F);
    y += (u - y) / 0.05F * kDtS;
  }
  EXPECT_NEAR(y, 0.5F, 1e-3F);
  EXPECT_NEAR(pid.integral(), 0.5F, 1e-3F);  // the integrator carries the whole steady-state duty
}

TEST(PidController, DerivativeActsOnTheMeasurementSoASetpointStepGivesNoKick) {
  PidController pid;
  const PidGains gains{.kd = 1.0F};
  pid.update(0.0F, 0.0F, kDtS, gains, 10.0F);
  EXPECT_FLOAT_EQ(pid.update(5.0F, 0.0F, kDtS, gains, 10.0F), 0.0F);
  // A measurement rising at 1 unit/s opposes with kd * 1.
  EXPECT_FLOAT_EQ(pid.update(5.0F, 0.001F, kDtS, gains, 10.0F), -1.0F);
}

// The derivative is of the measurement since the last update, not since zero: a measurement that
// holds still away from 0 gives no derivative action, however long it has held.
TEST(PidController, ASteadyMeasurementAwayFromZeroGivesNoDerivativeAction) {
  PidController pid;
  const PidGains gains{.kd = 0.01F};
  pid.update(2.0F, 2.0F, kDtS, gains, 10.0F);
  EXPECT_FLOAT_EQ(pid.update(2.0F, 2.0F, kDtS, gains, 10.0F), 0.0F);
  EXPECT_FLOAT_EQ(pid.update(2.0F, 2.0F, kDtS, gains, 10.0F), 0.0F);
  // And a step of the measurement acts once, in its cycle: 0.01 * 0.5 / 0.001 = 5.
  EXPECT_FLOAT_EQ(pid.update(2.0F, 2.5F, kDtS, gains, 10.0F), -5.0F);
  EXPECT_FLOAT_EQ(pid.update(2.0F, 2.5F, kDtS, gains, 10.0F), 0.0F);
}

// Saturated the other way the integrator is not updated (anti-windup), but a limit lowered since
// still bounds what it holds, on either side.
TEST(PidController, ALoweredLimitBoundsTheIntegralEvenWhileSaturated) {
  for (const float sign : {1.0F, -1.0F}) {
    PidController pid;
    for (int i = 0; i < 800; ++i) pid.update(sign, 0.0F, kDtS, {.ki = 1.0F}, 1.0F);
    ASSERT_NEAR(pid.integral(), 0.8F * sign, 1e-3F);
    EXPECT_FLOAT_EQ(pid.update(-20.0F * sign, 0.0F, kDtS, {.kp = 0.1F, .ki = 1.0F}, 0.5F), -0.5F * sign);
    EXPECT_FLOAT_EQ(pid.integral(), 0.5F * sign) << "sign " << sign;
  }
}

TEST(PidController, ResetForgetsTheIntegral) {
  PidController pid;
  for (int i = 0; i < 100; ++i) {
    pid.update(1.0F, 0.0F, kDtS, {.ki = 1.0F}, 1.0F);
  }
  ASSERT_GT(pid.integral(), 0.0F);
  pid.reset();
  EXPECT_EQ(pid.integral(), 0.0F);
}

}  // namespace
}  // namespace joint
