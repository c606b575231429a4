#include "joint/DemoJoint.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "core/Scheduler.hpp"
#include "joint/FaultBits.hpp"
#include "joint/drivers/HilRegisters.hpp"
#include "joint/testing/BoardStandIns.hpp"

namespace joint {
namespace {

using board::FieldId;

using joint::testing::kDtS;

// A tiny plant: the motor's speed follows duty * no-load speed with a first-order
// lag, the load follows the gearbox rigidly (spring at rest). Encoders with
// the table's default resolutions, wrapping like the hardware counters.
class FirstOrderJointPlant {
 public:
  static constexpr double kNoLoadMotorSpeedRadS = 480.0;  // 24 V / 0.05 V*s/rad
  static constexpr double kTimeConstantS = 0.02;
  static constexpr double kGearRatio = 50.0;

  void step(double duty, double dt_s) {
    motor_velocity_rad_s += (duty * kNoLoadMotorSpeedRadS - motor_velocity_rad_s) / kTimeConstantS * dt_s;
    motor_angle_rad += motor_velocity_rad_s * dt_s;
  }
  std::uint16_t motor_counts() const { return wrap(motor_angle_rad / (2.0 * std::numbers::pi) * 4096.0); }
  std::uint16_t output_counts() const {
    return wrap(motor_angle_rad / kGearRatio / (2.0 * std::numbers::pi) * 16384.0);
  }

  double motor_angle_rad = 0.0;
  double motor_velocity_rad_s = 0.0;

 private:
  static std::uint16_t wrap(double counts) { return static_cast<std::uint16_t>(std::llround(counts) & 0xFFFF); }
};

class DemoJointTest : public ::testing::Test {
 protected:
  core::StartupStatus start() {
    EXPECT_TRUE(joint.add_to(scheduler));
    EXPECT_TRUE(scheduler.add(bus));
    return scheduler.start();
  }

  // One lockstep cycle: sensor frame and setpoint frame in, cycle, plant step.
  void run_cycle(bool stream_setpoints = true) {
    registers.write_motor_encoder(plant.motor_counts());
    registers.write_output_encoder(plant.output_counts());
    registers.write_thermistor_adc(thermistor_adc);
    registers.write_motor_current(0);
    if (stream_setpoints) {
      ASSERT_EQ(bus.write(FieldId::velocity_setpoint, velocity_setpoint_rad_s), core::SetResult::Ok);
      ASSERT_EQ(bus.write(FieldId::torque_setpoint, 0.0F), core::SetResult::Ok);
    }
    scheduler.run_cycle(++cycle);
    plant.step(registers.motor_duty_raw() / 10000.0, kDtS);
  }

  core::MessageBoard board;
  core::Scheduler scheduler{board};
  HilRegisters registers;
  DemoJoint joint{board, registers.drivers(), kDtS};
  testing::BusStandIn bus{board};
  FirstOrderJointPlant plant;
  float velocity_setpoint_rad_s = 0.0F;
  std::uint16_t thermistor_adc = 2048;  // 25 degC
  std::uint32_t cycle = 0;
};

// The ADC reading of the winding NTC at `temperature_c` (board.toml defaults).
std::uint16_t thermistor_adc_at(double temperature_c) {
  const double ntc_ohm = 10000.0 * std::exp(3950.0 * (1.0 / (temperature_c + 273.15) - 1.0 / 298.15));
  return static_cast<std::uint16_t>(std::lround(4095.0 * ntc_ohm / (ntc_ohm + 10000.0)));
}

TEST_F(DemoJointTest, SchedulesAllComponentsWithoutError) {
  const core::StartupStatus status = start();
  ASSERT_TRUE(status) << status.message();
  EXPECT_EQ(scheduler.order().size(), 21U);
  EXPECT_FALSE(joint.add_to(scheduler));  // too late once started
}

TEST_F(DemoJointTest, PrintedScheduleRunsSensorsThenVirtualSensorsThenModulesThenActuators) {
  const core::StartupStatus status = start();
  ASSERT_TRUE(status) << status.message();
  const std::string text = scheduler.schedule_text();
  const std::map<std::string, int> rank{{"sensor", 0}, {"virtual sensor", 1}, {"module", 2}, {"actuator", 3}};
  std::vector<int> ranks;
  std::vector<std::string> names;
  std::istringstream lines{text};
  for (std::string line; std::getline(lines, line);) {
    // "  3. virtual sensor 'motor_velocity'"
    const std::size_t dot = line.find(". ");
    const std::size_t quote = line.find(" '");
    if (dot == std::string::npos || quote == std::string::npos || line.find("writes:") != std::string::npos ||
        line.find("reads:") != std::string::npos || line.find("  - ") == 0) {
      continue;
    }
    const std::string kind = line.substr(dot + 2, quote - dot - 2);
    ASSERT_TRUE(rank.contains(kind)) << "unexpected kind '" << kind << "' in:\n" << text;
    ranks.push_back(rank.at(kind));
    names.push_back(line.substr(quote + 2, line.size() - quote - 3));
  }
  ASSERT_EQ(ranks.size(), 21U) << text;
  EXPECT_TRUE(std::is_sorted(ranks.begin(), ranks.end())) << text;
  for (int kind = 0; kind < 4; ++kind) {
    EXPECT_NE(std::find(ranks.begin(), ranks.end(), kind), ranks.end()) << "kind rank " << kind << " missing";
  }
  const auto position = [&](const std::string& name) {
    return std::find(names.begin(), names.end(), name) - names.begin();
  };
  // Within a kind, writers before readers.
  EXPECT_LT(position("spring_deflection"), position("joint_torque")) << text;
  EXPECT_LT(position("thermal_protection"), position("fault_manager")) << text;
  EXPECT_LT(position("command_watchdog"), position("fault_manager")) << text;
  EXPECT_LT(position("heartbeat"), position("fault_manager")) << text;
  EXPECT_LT(position("fault_manager"), position("velocity_controller")) << text;
  EXPECT_LT(position("velocity_controller"), position("drive_arbiter")) << text;
  EXPECT_LT(position("torque_controller"), position("drive_arbiter")) << text;
}

TEST_F(DemoJointTest, ReachesAVelocitySetpointInClosedLoop) {
  const core::StartupStatus status = start();
  ASSERT_TRUE(status) << status.message();
  ASSERT_EQ(bus.write(FieldId::control_mode, 1.0F), core::SetResult::Ok);
  velocity_setpoint_rad_s = 2.0F;
  for (int i = 0; i < 3000; ++i) {
    run_cycle();
  }
  EXPECT_NEAR(plant.motor_velocity_rad_s / FirstOrderJointPlant::kGearRatio, 2.0, 0.02);
  EXPECT_NEAR(board.get(FieldId::output_velocity), 2.0F, 0.05F);
  EXPECT_NEAR(board.get(FieldId::motor_velocity), 100.0F, 1.0F);
  EXPECT_NEAR(board.get(FieldId::spring_deflection), 0.0F, 2e-3F);
  EXPECT_EQ(board.get(FieldId::fault_flags), 0.0F);
  EXPECT_EQ(registers.led_pattern_raw(), 1);
  // Steady state needs 100 / 480 of full duty.
  EXPECT_NEAR(registers.motor_duty_raw(), 2083, 30);
}

TEST_F(DemoJointTest, SilentSetpointStreamStopsTheMotorAndShowsTheFault) {
  const core::StartupStatus status = start();
  ASSERT_TRUE(status) << status.message();
  ASSERT_EQ(bus.write(FieldId::control_mode, 1.0F), core::SetResult::Ok);
  velocity_setpoint_rad_s = 2.0F;
  for (int i = 0; i < 500; ++i) {
    run_cycle();
  }
  ASSERT_NE(registers.motor_duty_raw(), 0);
  for (int i = 0; i < 50; ++i) {  // default watchdog_cycles
    run_cycle(false);
  }
  EXPECT_EQ(board.get(FieldId::safe_state), 1.0F);
  EXPECT_EQ(static_cast<std::uint32_t>(board.get(FieldId::fault_flags)), fault_mask(FaultBit::CommandWatchdog));
  EXPECT_EQ(registers.motor_duty_raw(), 0);
  EXPECT_EQ(registers.led_pattern_raw(), 3);
}

// The node's heartbeat consumer reports the master lost: safe state, zero duty, in that cycle.
TEST_F(DemoJointTest, LostMasterHeartbeatStopsTheMotorUntilItIsBackAndCleared) {
  const core::StartupStatus status = start();
  ASSERT_TRUE(status) << status.message();
  ASSERT_EQ(bus.write(FieldId::control_mode, 1.0F), core::SetResult::Ok);
  velocity_setpoint_rad_s = 2.0F;
  for (int i = 0; i < 500; ++i) {
    run_cycle();
  }
  ASSERT_NE(registers.motor_duty_raw(), 0);
  registers.write_heartbeat_status(1, true);
  run_cycle();
  EXPECT_EQ(board.get(FieldId::heartbeat_lost), 1.0F);
  EXPECT_EQ(board.get(FieldId::safe_state), 1.0F);
  EXPECT_EQ(static_cast<std::uint32_t>(board.get(FieldId::fault_flags)), fault_mask(FaultBit::MasterHeartbeatLost));
  EXPECT_EQ(registers.motor_duty_raw(), 0);

  registers.write_heartbeat_status(0, false);  // the master's heartbeat is back
  run_cycle();
  EXPECT_EQ(board.get(FieldId::heartbeat_lost), 0.0F);
  EXPECT_EQ(registers.motor_duty_raw(), 0) << "latched until cleared";
  ASSERT_EQ(bus.write(FieldId::fault_clear, 1.0F), core::SetResult::Ok);
  run_cycle();
  EXPECT_EQ(board.get(FieldId::fault_flags), 0.0F);
  run_cycle();
  EXPECT_NE(registers.motor_duty_raw(), 0);
}

TEST_F(DemoJointTest, ReachesAPositionSetpointInPositionMode) {
  const core::StartupStatus status = start();
  ASSERT_TRUE(status) << status.message();
  ASSERT_EQ(bus.write(FieldId::control_mode, 3.0F), core::SetResult::Ok);
  ASSERT_EQ(bus.write(FieldId::position_setpoint, 1.5F), core::SetResult::Ok);
  for (int i = 0; i < 4000; ++i) {
    run_cycle();
  }
  EXPECT_NEAR(plant.motor_angle_rad / FirstOrderJointPlant::kGearRatio, 1.5, 0.01);
  EXPECT_NEAR(board.get(FieldId::output_position), 1.5F, 0.01F);
}

TEST_F(DemoJointTest, HotWindingDeratesThenStopsTheMotorUntilCooledAndCleared) {
  const core::StartupStatus status = start();
  ASSERT_TRUE(status) << status.message();
  ASSERT_EQ(bus.write(FieldId::control_mode, 1.0F), core::SetResult::Ok);
  velocity_setpoint_rad_s = 2.0F;
  thermistor_adc = thermistor_adc_at(90.0);  // halfway between warning (80) and limit (100)
  for (int i = 0; i < 200; ++i) {
    run_cycle();
  }
  EXPECT_NEAR(board.get(FieldId::thermal_derate), 0.5F, 0.02F);
  EXPECT_EQ(board.get(FieldId::safe_state), 0.0F);

  thermistor_adc = thermistor_adc_at(105.0);
  run_cycle();
  EXPECT_EQ(static_cast<std::uint32_t>(board.get(FieldId::fault_flags)), fault_mask(FaultBit::OverTemperature));
  EXPECT_EQ(registers.motor_duty_raw(), 0);

  // Cooled below the limit but not by the hysteresis (10 K): a clear does not hold.
  thermistor_adc = thermistor_adc_at(95.0);
  run_cycle();
  ASSERT_EQ(bus.write(FieldId::fault_clear, 1.0F), core::SetResult::Ok);
  run_cycle();
  EXPECT_EQ(board.get(FieldId::safe_state), 1.0F);

  thermistor_adc = thermistor_adc_at(85.0);
  run_cycle();
  ASSERT_EQ(bus.write(FieldId::fault_clear, 1.0F), core::SetResult::Ok);
  run_cycle();
  EXPECT_EQ(board.get(FieldId::safe_state), 0.0F);
  EXPECT_EQ(board.get(FieldId::fault_flags), 0.0F);
  run_cycle();
  EXPECT_NE(registers.motor_duty_raw(), 0);
}

}  // namespace
}  // namespace joint
