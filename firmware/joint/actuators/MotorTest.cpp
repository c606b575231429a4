#include "joint/actuators/Motor.hpp"

#include <gtest/gtest.h>

#include <limits>

#include "core/Scheduler.hpp"
#include "joint/actuators/StatusLed.hpp"
#include "joint/drivers/HilRegisters.hpp"
#include "joint/testing/BoardStandIns.hpp"

namespace joint {
namespace {

using board::FieldId;

TEST(DutyToRaw, ScalesDutyToTheBridgeRange) {
  EXPECT_EQ(duty_to_raw(0.5F, 1.0F), 5000);
  EXPECT_EQ(duty_to_raw(-0.25F, 1.0F), -2500);
  EXPECT_EQ(duty_to_raw(0.0F, 1.0F), 0);
}

TEST(DutyToRaw, ClampsToMaxDuty) {
  EXPECT_EQ(duty_to_raw(1.0F, 0.95F), 9500);
  EXPECT_EQ(duty_to_raw(-3.0F, 0.95F), -9500);
  EXPECT_EQ(duty_to_raw(1.0F, 0.0F), 0);
  EXPECT_EQ(duty_to_raw(std::numeric_limits<float>::quiet_NaN(), 0.95F), 0);
}

class ActuatorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    for (core::MessageBoardUser* component : std::initializer_list<core::MessageBoardUser*>{&motor, &led, &modules}) {
      ASSERT_TRUE(scheduler.add(*component));
    }
    const core::StartupStatus status = scheduler.start();
    ASSERT_TRUE(status) << status.message();
  }

  core::MessageBoard board;
  core::Scheduler scheduler{board};
  HilRegisters registers;
  Motor motor{board, registers.drivers().motor_duty};
  StatusLed led{board, registers.drivers().status_led};
  testing::FieldSource<core::Module> modules{
      board, "modules", {FieldId::motor_duty_command, FieldId::safe_state, FieldId::led_pattern_command}};
};

TEST_F(ActuatorTest, SafeStateZeroesTheMotor) {
  modules.hold(FieldId::motor_duty_command, 0.5F);
  modules.hold(FieldId::safe_state, 0.0F);
  scheduler.run_cycle(1);
  ASSERT_EQ(registers.motor_duty_raw(), 5000);
  modules.hold(FieldId::safe_state, 1.0F);
  scheduler.run_cycle(2);
  EXPECT_EQ(registers.motor_duty_raw(), 0);
}

TEST_F(ActuatorTest, StatusLedShowsTheCommandedPattern) {
  modules.hold(FieldId::led_pattern_command, 2.0F);
  scheduler.run_cycle(1);
  EXPECT_EQ(registers.led_pattern_raw(), 2);
  modules.hold(FieldId::led_pattern_command, 3.0F);
  scheduler.run_cycle(2);
  EXPECT_EQ(registers.led_pattern_raw(), 3);
}

TEST_F(ActuatorTest, StatusLedDrivesEveryPatternOfTheTableAsItsNumber) {
  std::uint32_t cycle = 0;
  for (const LedPattern pattern : board::kLedPatternValues) {
    modules.hold(FieldId::led_pattern_command, board::to_value(pattern));
    scheduler.run_cycle(++cycle);
    EXPECT_EQ(registers.led_pattern_raw(), static_cast<std::uint8_t>(pattern)) << board::to_string(pattern);
  }
}

TEST_F(ActuatorTest, StatusLedShowsANumberThatIsNoPatternAsTheFaultPattern) {
  std::uint32_t cycle = 0;
  for (const float command : {1.5F, 4.0F, -1.0F, std::numeric_limits<float>::quiet_NaN()}) {
    modules.hold(FieldId::led_pattern_command, 0.0F);
    scheduler.run_cycle(++cycle);
    modules.hold(FieldId::led_pattern_command, command);
    scheduler.run_cycle(++cycle);
    EXPECT_EQ(registers.led_pattern_raw(), static_cast<std::uint8_t>(LedPattern::FastBlink)) << command;
  }
}

}  // namespace
}  // namespace joint
