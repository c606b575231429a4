#include "joint/modules/FaultManager.hpp"

#include <gtest/gtest.h>

#include "core/Scheduler.hpp"
#include "joint/FaultBits.hpp"
#include "joint/testing/BoardStandIns.hpp"

namespace joint {
namespace {

using board::FieldId;

class FaultManagerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    for (core::MessageBoardUser* component :
         std::initializer_list<core::MessageBoardUser*>{&manager, &sensors, &heartbeat, &thermal, &watchdog, &bus}) {
      ASSERT_TRUE(scheduler.add(*component));
    }
    const core::StartupStatus status = scheduler.start();
    ASSERT_TRUE(status) << status.message();
    sensors.hold(FieldId::motor_position, 0.0F);
    sensors.hold(FieldId::output_position, 0.0F);
    sensors.hold(FieldId::thermistor_resistance, 10000.0F);
    heartbeat.hold(FieldId::heartbeat_lost, 0.0F);
    thermal.hold(FieldId::thermal_derate, 1.0F);
    watchdog.hold(FieldId::watchdog_tripped, 0.0F);
  }

  void run_cycles(int count) {
    for (int i = 0; i < count; ++i) {
      scheduler.run_cycle(++cycle);
    }
  }
  std::uint32_t flags() const { return static_cast<std::uint32_t>(board.get(FieldId::fault_flags)); }
  bool safe() const { return board.get(FieldId::safe_state) == 1.0F; }
  void clear_faults() { ASSERT_EQ(bus.write(FieldId::fault_clear, 1.0F), core::SetResult::Ok); }
  // The watchdog trips for one cycle and releases again.
  void pulse_watchdog() {
    watchdog.hold(FieldId::watchdog_tripped, 1.0F);
    run_cycles(1);
    watchdog.hold(FieldId::watchdog_tripped, 0.0F);
    run_cycles(1);
  }

  core::MessageBoard board;
  core::Scheduler scheduler{board};
  FaultManager manager{board};
  testing::FieldSource<core::Sensor> sensors{
      board, "sensors", {FieldId::motor_position, FieldId::output_position, FieldId::thermistor_resistance}};
  testing::FieldSource<core::Sensor> heartbeat{board, "heartbeat", {FieldId::heartbeat_lost}};
  testing::FieldSource<core::Module> thermal{board, "thermal", {FieldId::thermal_derate}};
  testing::FieldSource<core::Module> watchdog{board, "watchdog", {FieldId::watchdog_tripped}};
  testing::BusStandIn bus{board};
  std::uint32_t cycle = 0;
};

TEST_F(FaultManagerTest, ReportsNoFaultWhileEverythingIsFine) {
  run_cycles(200);
  EXPECT_EQ(flags(), 0U);
  EXPECT_FALSE(safe());
}

TEST_F(FaultManagerTest, LatchesAStaleMotorEncoderAfterEncoderStaleCycles) {
  run_cycles(5);
  sensors.stop(FieldId::motor_position);
  run_cycles(19);  // default encoder_stale_cycles: 20
  ASSERT_EQ(flags(), 0U);
  run_cycles(1);
  EXPECT_EQ(flags(), fault_mask(FaultBit::MotorEncoderStale));
  EXPECT_TRUE(safe());
}

TEST_F(FaultManagerTest, KeepsAFaultLatchedAfterItsCauseEndsUntilCleared) {
  sensors.stop(FieldId::output_position);
  run_cycles(30);
  ASSERT_EQ(flags(), fault_mask(FaultBit::OutputEncoderStale));
  sensors.hold(FieldId::output_position, 0.0F);
  run_cycles(10);
  EXPECT_EQ(flags(), fault_mask(FaultBit::OutputEncoderStale));
  EXPECT_TRUE(safe());
  clear_faults();
  run_cycles(1);
  EXPECT_EQ(flags(), 0U);
  EXPECT_FALSE(safe());
}

TEST_F(FaultManagerTest, RelatchesAtOnceWhileTheCausePersists) {
  thermal.hold(FieldId::thermal_derate, 0.0F);  // over-temperature, still hot
  run_cycles(3);
  ASSERT_EQ(flags(), fault_mask(FaultBit::OverTemperature));
  clear_faults();
  run_cycles(1);
  EXPECT_EQ(flags(), fault_mask(FaultBit::OverTemperature));
  EXPECT_TRUE(safe());
  // Cooled down (derate back above 0): now a clear works.
  thermal.hold(FieldId::thermal_derate, 0.6F);
  run_cycles(1);
  clear_faults();
  run_cycles(1);
  EXPECT_EQ(flags(), 0U);
}

TEST_F(FaultManagerTest, ClearsOnlyOnAWriteOfOne) {
  pulse_watchdog();
  ASSERT_EQ(flags(), fault_mask(FaultBit::CommandWatchdog));
  ASSERT_EQ(bus.write(FieldId::fault_clear, 0.0F), core::SetResult::Ok);
  run_cycles(1);
  EXPECT_EQ(flags(), fault_mask(FaultBit::CommandWatchdog));
  clear_faults();
  run_cycles(1);
  EXPECT_EQ(flags(), 0U);
  // fault_clear still reads 1, but without a new write nothing is cleared.
  pulse_watchdog();
  EXPECT_EQ(flags(), fault_mask(FaultBit::CommandWatchdog));
  clear_faults();  // the same value again is a new command
  run_cycles(1);
  EXPECT_EQ(flags(), 0U);
}

TEST_F(FaultManagerTest, LatchesAnOwnershipViolation) {
  run_cycles(2);
  ASSERT_EQ(bus.write(FieldId::safe_state, 0.0F), core::SetResult::NotOwner);  // not the node's field
  run_cycles(1);
  EXPECT_EQ(flags(), fault_mask(FaultBit::OwnershipViolation));
  clear_faults();
  run_cycles(1);
  EXPECT_EQ(flags(), 0U);  // an event, not a lasting cause
}

TEST_F(FaultManagerTest, LatchesALostMasterHeartbeatUntilItIsBackAndCleared) {
  run_cycles(5);
  heartbeat.hold(FieldId::heartbeat_lost, 1.0F);
  run_cycles(1);
  EXPECT_EQ(flags(), fault_mask(FaultBit::MasterHeartbeatLost));
  EXPECT_TRUE(safe());
  clear_faults();
  run_cycles(1);
  EXPECT_EQ(flags(), fault_mask(FaultBit::MasterHeartbeatLost)) << "still lost: latched again";
  heartbeat.hold(FieldId::heartbeat_lost, 0.0F);
  run_cycles(10);
  EXPECT_TRUE(safe()) << "back, but latched until cleared";
  clear_faults();
  run_cycles(1);
  EXPECT_EQ(flags(), 0U);
  EXPECT_FALSE(safe());
}

TEST_F(FaultManagerTest, GivesSensorsEncoderStaleCyclesToStart) {
  sensors.stop(FieldId::motor_position);
  sensors.stop(FieldId::output_position);
  run_cycles(19);
  EXPECT_EQ(flags(), 0U);
  run_cycles(1);
  EXPECT_EQ(flags(), fault_mask(FaultBit::MotorEncoderStale) | fault_mask(FaultBit::OutputEncoderStale));
}

TEST_F(FaultManagerTest, LatchesAStaleThermistor) {
  sensors.stop(FieldId::thermistor_resistance);
  run_cycles(static_cast<int>(board::info(FieldId::thermistor_stale_cycles).default_value) - 1);
  ASSERT_EQ(flags(), 0U);
  run_cycles(1);
  EXPECT_EQ(flags(), fault_mask(FaultBit::ThermistorStale));
}

// The silence is counted in 64 bits, so neither 2^32 cycles of running
// nor 2^32 cycles of silence (49.7 days at 1 kHz) look like a fresh write.
TEST_F(FaultManagerTest, StillSeesAnEncoderSilentFor2To32Cycles) {
  run_cycles(1);
  sensors.stop(FieldId::motor_position);
  // Late wake-ups of 2^20 periods each (free-running), past 2^32 cycles of silence.
  for (int jump = 1; jump <= 4096 + 2; ++jump) {
    clear_faults();
    cycle += 1U << 20;
    scheduler.run_cycle(cycle);
    ASSERT_TRUE(flags() & fault_mask(FaultBit::MotorEncoderStale)) << "after " << jump << " x 2^20 silent cycles";
  }
}

TEST_F(FaultManagerTest, LatchesAStaleEncoderOnTimeAcross2To32CyclesSinceStart) {
  ASSERT_EQ(bus.write(FieldId::encoder_stale_cycles, 20.0F), core::SetResult::Ok);
  run_cycles(1);
  for (int jump = 1; jump < 4096; ++jump) {  // healthy for 2^32 - 2^20 cycles
    cycle += 1U << 20;
    scheduler.run_cycle(cycle);
  }
  cycle = 0xFFFFFFF6U;  // 10 cycles before 2^32 cycles since the manager's first
  scheduler.run_cycle(cycle);
  ASSERT_EQ(flags(), 0U);
  sensors.stop(FieldId::motor_position);
  for (int silent = 1; silent < 20; ++silent) {
    run_cycles(1);
    ASSERT_EQ(flags(), 0U) << silent << " silent cycles";
  }
  run_cycles(1);
  EXPECT_EQ(flags(), fault_mask(FaultBit::MotorEncoderStale)) << "20 silent cycles, at cycle " << cycle;
}

}  // namespace
}  // namespace joint
