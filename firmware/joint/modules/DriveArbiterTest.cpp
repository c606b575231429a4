#include "joint/modules/DriveArbiter.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <initializer_list>
#include <limits>

#include "joint/FaultBits.hpp"

namespace joint {
namespace {

DriveInputs inputs(ControlMode mode) {
  return {.mode = mode,
          .safe_state = false,
          .velocity_controller_output = 0.3F,
          .torque_controller_output = -0.4F,
          .max_duty = 0.95F,
          .thermal_derate = 1.0F};
}

TEST(DriveArbiter, PassesTheLoopOfTheActiveMode) {
  EXPECT_FLOAT_EQ(arbitrate_duty(inputs(ControlMode::Velocity)), 0.3F);
  EXPECT_FLOAT_EQ(arbitrate_duty(inputs(ControlMode::Position)), 0.3F);
  EXPECT_FLOAT_EQ(arbitrate_duty(inputs(ControlMode::Torque)), -0.4F);
  EXPECT_FLOAT_EQ(arbitrate_duty(inputs(ControlMode::Disabled)), 0.0F);
}

TEST(DriveArbiter, CommandsZeroInTheSafeState) {
  DriveInputs in = inputs(ControlMode::Velocity);
  in.safe_state = true;
  EXPECT_FLOAT_EQ(arbitrate_duty(in), 0.0F);
}

TEST(DriveArbiter, TheSafeStateCutsUnlessTheFaultReactionRampsOnFaultsThatKeepTheSensors) {
  const auto flags = [](std::initializer_list<FaultBit> bits) {
    std::uint32_t mask = 0;
    for (const FaultBit bit : bits) mask |= fault_mask(bit);
    return static_cast<float>(mask);
  };
  EXPECT_FALSE(safe_state_cuts_the_drive(0.0F, 0.0F, 0.0F));
  EXPECT_TRUE(safe_state_cuts_the_drive(1.0F, flags({FaultBit::CommandWatchdog}), 0.0F)) << "no ramp asked";
  for (const FaultBit bit : {FaultBit::CommandWatchdog, FaultBit::OwnershipViolation, FaultBit::MasterHeartbeatLost}) {
    EXPECT_FALSE(safe_state_cuts_the_drive(1.0F, flags({bit}), 1.0F)) << static_cast<int>(bit);
  }
  for (const FaultBit bit : {FaultBit::MotorEncoderStale, FaultBit::OutputEncoderStale, FaultBit::ThermistorStale,
                             FaultBit::OverTemperature}) {
    EXPECT_TRUE(safe_state_cuts_the_drive(1.0F, flags({bit}), 1.0F)) << static_cast<int>(bit);
    EXPECT_TRUE(safe_state_cuts_the_drive(1.0F, flags({FaultBit::CommandWatchdog, bit}), 1.0F)) << static_cast<int>(bit);
  }
}

TEST(DriveArbiter, LimitsToMaxDutyTimesThermalDerate) {
  DriveInputs in = inputs(ControlMode::Velocity);
  in.velocity_controller_output = 1.0F;
  EXPECT_FLOAT_EQ(arbitrate_duty(in), 0.95F);
  in.thermal_derate = 0.5F;
  EXPECT_FLOAT_EQ(arbitrate_duty(in), 0.475F);
}

TEST(DriveArbiter, TreatsAnUnknownModeAsDisabled) {
  EXPECT_EQ(control_mode_from_field(1.5F), ControlMode::Disabled);
  EXPECT_EQ(control_mode_from_field(7.0F), ControlMode::Disabled);
  EXPECT_EQ(control_mode_from_field(-1.0F), ControlMode::Disabled);
  EXPECT_EQ(control_mode_from_field(std::numeric_limits<float>::quiet_NaN()), ControlMode::Disabled);
  EXPECT_EQ(control_mode_from_field(1.0F), ControlMode::Velocity);
  EXPECT_EQ(control_mode_from_field(3.0F), ControlMode::Position);
  EXPECT_EQ(control_mode_from_field(2.0F), ControlMode::Torque);
}

}  // namespace
}  // namespace joint
