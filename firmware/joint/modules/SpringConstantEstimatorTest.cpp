#include "joint/modules/SpringConstantEstimator.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "core/Scheduler.hpp"
#include "joint/testing/BoardStandIns.hpp"

namespace joint {
namespace {

using board::FieldId;

using joint::testing::kDtS;
constexpr float kGearRatio = 50.0F;  // table default

class SpringConstantEstimatorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    for (core::MessageBoardUser* component :
         std::initializer_list<core::MessageBoardUser*>{&estimator, &current, &measurements}) {
      ASSERT_TRUE(scheduler.add(*component));
    }
    const core::StartupStatus status = scheduler.start();
    ASSERT_TRUE(status) << status.message();
  }

  // One cycle of a slow twist: deflection 0.04 rad * sin(2 pi 0.5 Hz t), the motor
  // current that balances the true spring through the gearbox, and a motor
  // velocity that changes by `velocity_step_rad_s` per cycle.
  void run_cycle(float true_k, float velocity_step_rad_s) {
    const float t_s = static_cast<float>(cycle) * kDtS;
    const float deflection_rad = 0.04F * std::sin(2.0F * std::numbers::pi_v<float> * 0.5F * t_s);
    const float current_a = true_k * deflection_rad / (board::info(FieldId::motor_torque_constant).default_value * kGearRatio);
    current.hold(FieldId::motor_current, std::round(current_a * 1000.0F) / 1000.0F);  // 1 mA ADC steps
    measurements.hold(FieldId::spring_deflection, deflection_rad);
    motor_velocity_rad_s += velocity_step_rad_s;
    measurements.hold(FieldId::motor_velocity, motor_velocity_rad_s);
    scheduler.run_cycle(++cycle);
  }

  core::MessageBoard board;
  core::Scheduler scheduler{board};
  SpringConstantEstimator estimator{board, kDtS};
  testing::FieldSource<core::Sensor> current{board, "current", {FieldId::motor_current}};
  testing::FieldSource<core::VirtualSensor> measurements{
      board, "measurements", {FieldId::spring_deflection, FieldId::motor_velocity}};
  float motor_velocity_rad_s = 0.0F;
  std::uint32_t cycle = 0;
};

TEST_F(SpringConstantEstimatorTest, EstimatesTheTrueStiffnessFromMotorCurrentWithinFivePercent) {
  for (int i = 0; i < 4000; ++i) {
    run_cycle(70.0F, 0.0F);
  }
  EXPECT_NEAR(board.get(FieldId::spring_constant_estimate), 70.0F, 3.5F);
  EXPECT_GT(board.get(FieldId::spring_constant_confidence), 0.8F);
}

TEST_F(SpringConstantEstimatorTest, IgnoresSamplesWhileTheMotorAccelerates) {
  // 0.2 rad/s per 1 ms cycle = 200 rad/s^2: above the quasi-static gate.
  for (int i = 0; i < 4000; ++i) {
    run_cycle(70.0F, 0.2F);
  }
  EXPECT_EQ(board.get(FieldId::spring_constant_estimate), 50.0F);  // still the nominal start value
  EXPECT_EQ(board.get(FieldId::spring_constant_confidence), 0.0F);
}

}  // namespace
}  // namespace joint
