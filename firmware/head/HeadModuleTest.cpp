// The whole head on one board, driven cycle by cycle through its HIL registers as the node
// would: the rail trips and stays off until cleared, the LEDs follow their commands and the rail,
// a low battery latches after its debounce, a silent IMU latches imu_stale.
#include "head/HeadModule.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "core/Scheduler.hpp"
#include "head/drivers/HeadRegisters.hpp"
#include "joint/testing/BoardStandIns.hpp"

namespace head {
namespace {

using board::FieldId;
using board::HilInputId;
using board::HilOutputId;
using Bit = board::FaultFlagsBit;

class HeadModuleTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(module.add_to(scheduler));
    ASSERT_TRUE(scheduler.add(bus));
    ASSERT_TRUE(scheduler.start().ok());
  }

  // One lockstep cycle: the two sensor frames in (unless the IMU is silent), then the cycle.
  void run_cycle() {
    if (imu_streaming) {
      registers.write_input(HilInputId::accel_x_counts, 0);
      registers.write_input(HilInputId::accel_y_counts, 0);
      registers.write_input(HilInputId::accel_z_counts, 4096);  // +1 g
      registers.write_input(HilInputId::gyro_x_counts, 0);
      registers.write_input(HilInputId::gyro_y_counts, 0);
      registers.write_input(HilInputId::gyro_z_counts, 164);  // 10 deg/s
    }
    registers.write_input(HilInputId::rail_current_adc, rail_milliamps);
    registers.write_input(HilInputId::battery_adc, battery_millivolts);
    scheduler.run_cycle(++cycle);
  }

  void run_cycles(int n) {
    for (int i = 0; i < n; ++i) run_cycle();
  }

  bool latched(Bit bit) const {
    return (static_cast<std::uint32_t>(board.get(FieldId::fault_flags)) & board::mask(bit)) != 0;
  }

  core::MessageBoard board;
  core::Scheduler scheduler{board};
  HeadRegisters registers;
  HeadModule module{board, registers.drivers()};
  joint::testing::BusStandIn bus{board};
  bool imu_streaming = true;
  std::int32_t rail_milliamps = 500;
  std::int32_t battery_millivolts = 12000;
  std::uint32_t cycle = 0;
};

TEST_F(HeadModuleTest, ScalesTheImuIntoSiUnitsAndLevelAttitude) {
  run_cycle();
  EXPECT_NEAR(board.get(FieldId::accel_z), 9.80665F, 1e-4F);
  EXPECT_NEAR(board.get(FieldId::gyro_z), 10.0F * 3.14159265F / 180.0F, 1e-3F);
  EXPECT_FLOAT_EQ(board.get(FieldId::head_pitch), 0.0F);
  EXPECT_FLOAT_EQ(board.get(FieldId::head_roll), 0.0F);
  EXPECT_FLOAT_EQ(board.get(FieldId::rail_current), 0.5F);
  EXPECT_FLOAT_EQ(board.get(FieldId::battery_voltage), 12.0F);
  EXPECT_EQ(board.get(FieldId::fault_flags), 0.0F);
}

TEST_F(HeadModuleTest, LedsFollowTheirCommandsWhileTheRailIsOn) {
  ASSERT_EQ(bus.write(FieldId::led_red, 1.0F), core::SetResult::Ok);
  ASSERT_EQ(bus.write(FieldId::led_green, 0.5F), core::SetResult::Ok);
  run_cycle();
  EXPECT_EQ(registers.read_output(HilOutputId::rail_switch), 1);
  EXPECT_EQ(registers.read_output(HilOutputId::led_red_pwm), 255);
  EXPECT_EQ(registers.read_output(HilOutputId::led_green_pwm), 128);
  EXPECT_EQ(registers.read_output(HilOutputId::led_blue_pwm), 0);

  ASSERT_EQ(bus.write(FieldId::rail_enable, 0.0F), core::SetResult::Ok);
  run_cycle();
  EXPECT_EQ(registers.read_output(HilOutputId::rail_switch), 0);
  EXPECT_EQ(registers.read_output(HilOutputId::led_red_pwm), 0) << "the LED hangs on the rail";
  EXPECT_EQ(board.get(FieldId::fault_flags), 0.0F) << "switching the rail off is no fault";
}

TEST_F(HeadModuleTest, RailTripsAfterItsDelayAndStaysOffUntilCleared) {
  rail_milliamps = 2500;  // above the 2 A default limit
  run_cycles(4);
  EXPECT_FALSE(latched(Bit::RailOverCurrent)) << "an inrush shorter than rail_trip_cycles passes";
  EXPECT_EQ(registers.read_output(HilOutputId::rail_switch), 1);
  run_cycle();
  EXPECT_TRUE(latched(Bit::RailOverCurrent));
  EXPECT_EQ(board.get(FieldId::rail_on), 0.0F);
  EXPECT_EQ(registers.read_output(HilOutputId::rail_switch), 0);

  rail_milliamps = 0;  // the switch is open
  run_cycles(3);
  EXPECT_TRUE(latched(Bit::RailOverCurrent)) << "latched until cleared";
  ASSERT_EQ(bus.write(FieldId::fault_clear, 1.0F), core::SetResult::Ok);
  run_cycle();
  EXPECT_FALSE(latched(Bit::RailOverCurrent));
  EXPECT_EQ(registers.read_output(HilOutputId::rail_switch), 1);
}

TEST_F(HeadModuleTest, LowBatteryLatchesAfterItsDebounce) {
  battery_millivolts = 10400;  // below 10.5 V
  run_cycles(49);
  EXPECT_FALSE(latched(Bit::BatteryLow));
  run_cycle();
  EXPECT_TRUE(latched(Bit::BatteryLow));
  ASSERT_EQ(bus.write(FieldId::fault_clear, 1.0F), core::SetResult::Ok);
  run_cycle();
  EXPECT_TRUE(latched(Bit::BatteryLow)) << "the cause is still there: latched again at once";
}

TEST_F(HeadModuleTest, BatteryNeverMeasuredIsNoLowBattery) {
  HeadRegisters silent;
  core::MessageBoard other;
  core::Scheduler other_scheduler{other};
  HeadModule other_module{other, silent.drivers()};
  ASSERT_TRUE(other_module.add_to(other_scheduler));
  ASSERT_TRUE(other_scheduler.start().ok());
  for (std::uint32_t c = 1; c <= 100; ++c) other_scheduler.run_cycle(c);
  const auto flags = static_cast<std::uint32_t>(other.get(FieldId::fault_flags));
  EXPECT_EQ(flags & board::mask(Bit::BatteryLow), 0u);
  EXPECT_NE(flags & board::mask(Bit::ImuStale), 0u) << "an IMU that never spoke is stale";
}

TEST_F(HeadModuleTest, SilentImuLatchesImuStale) {
  run_cycles(5);
  imu_streaming = false;
  run_cycles(19);
  EXPECT_FALSE(latched(Bit::ImuStale));
  run_cycle();
  EXPECT_TRUE(latched(Bit::ImuStale));
}

// One new axis register makes the whole sample new, once, whichever axis it is.
TEST(HeadRegisters, AnImuSampleIsFreshWhenAnyOneAxisIsNew) {
  for (const HilInputId axis : {HilInputId::accel_x_counts, HilInputId::accel_y_counts, HilInputId::accel_z_counts,
                                HilInputId::gyro_x_counts, HilInputId::gyro_y_counts, HilInputId::gyro_z_counts}) {
    HeadRegisters registers;
    ImuInput& imu = registers.drivers().imu;
    EXPECT_FALSE(imu.read().fresh);
    registers.write_input(axis, 1);
    EXPECT_TRUE(imu.read().fresh) << "axis " << static_cast<int>(axis);
    EXPECT_FALSE(imu.read().fresh) << "once";
  }
}

TEST(HeadAttitude, PitchAndRollFromGravity) {
  const float g = 9.80665F;
  const float tilt = 0.3F;
  // Nose down by `tilt`: forward axis partly down, so the upward specific force has -x.
  const Attitude nose_down = attitude_from_gravity(-g * std::sin(tilt), 0.0F, g * std::cos(tilt));
  EXPECT_NEAR(nose_down.pitch_rad, tilt, 1e-6F);
  EXPECT_NEAR(nose_down.roll_rad, 0.0F, 1e-6F);
  const Attitude left_up = attitude_from_gravity(0.0F, g * std::sin(tilt), g * std::cos(tilt));
  EXPECT_NEAR(left_up.roll_rad, tilt, 1e-6F);
  const Attitude none = attitude_from_gravity(0.0F, 0.0F, 0.0F);
  EXPECT_EQ(none.pitch_rad, 0.0F);
  EXPECT_EQ(none.roll_rad, 0.0F);
  // Upside down: gravity along +z of the head, so the upward force is -z; only all three axes at
  // 0 are "no measurement".
  const Attitude upside_down = attitude_from_gravity(0.0F, 0.0F, -g);
  EXPECT_NEAR(std::fabs(upside_down.roll_rad), std::numbers::pi_v<float>, 1e-6F);
  EXPECT_NEAR(upside_down.pitch_rad, 0.0F, 1e-6F);
}

TEST(Debounce, CountsOnlyConsecutiveCycles) {
  Debounce debounce;
  EXPECT_FALSE(debounce.update(true, 3));
  EXPECT_FALSE(debounce.update(true, 3));
  EXPECT_FALSE(debounce.update(false, 3));
  EXPECT_FALSE(debounce.update(true, 3));
  EXPECT_FALSE(debounce.update(true, 3));
  EXPECT_TRUE(debounce.update(true, 3));
  EXPECT_TRUE(debounce.update(true, 0)) << "0 cycles counts as 1";
}

TEST(PowerModules, DutyAndPwmClampNanAndRange) {
  EXPECT_EQ(pwm_from_duty(std::nanf("")), 0);
  EXPECT_EQ(pwm_from_duty(-0.5F), 0);
  EXPECT_EQ(pwm_from_duty(2.0F), 255);
  EXPECT_EQ(pwm_from_duty(0.25F), 64);
  EXPECT_TRUE(rail_closed(1.0F, 0.0F));
  EXPECT_FALSE(rail_closed(0.0F, 0.0F));
  EXPECT_FALSE(rail_closed(1.0F, static_cast<float>(board::mask(Bit::RailOverCurrent))));
  EXPECT_TRUE(rail_closed(1.0F, static_cast<float>(board::mask(Bit::BatteryLow))))
      << "a low battery leaves the rail to the master";
}

}  // namespace
}  // namespace head
