#include "joint/modules/CommandWatchdog.hpp"

#include <gtest/gtest.h>

#include "core/Scheduler.hpp"
#include "joint/testing/BoardStandIns.hpp"

namespace joint {
namespace {

using board::FieldId;

class CommandWatchdogTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(scheduler.add(watchdog));
    ASSERT_TRUE(scheduler.add(bus));
    const core::StartupStatus status = scheduler.start();
    ASSERT_TRUE(status) << status.message();
    ASSERT_EQ(bus.write(FieldId::watchdog_cycles, 5.0F), core::SetResult::Ok);
  }

  // Runs one cycle, the setpoint frame arriving before it (as the rig's RPDO2 does) if `streaming`.
  void run_cycle(bool streaming) {
    if (streaming) {
      ASSERT_EQ(bus.write(FieldId::velocity_setpoint, 1.0F), core::SetResult::Ok);
      ASSERT_EQ(bus.write(FieldId::torque_setpoint, 0.0F), core::SetResult::Ok);
    }
    scheduler.run_cycle(++cycle);
  }
  bool tripped() const { return board.get(FieldId::watchdog_tripped) == 1.0F; }

  core::MessageBoard board;
  core::Scheduler scheduler{board};
  CommandWatchdog watchdog{board};
  testing::BusStandIn bus{board};
  std::uint32_t cycle = 0;
};

TEST_F(CommandWatchdogTest, TripsAfterExactlyWatchdogCyclesWithoutASetpoint) {
  ASSERT_EQ(bus.write(FieldId::control_mode, 1.0F), core::SetResult::Ok);
  for (int i = 0; i < 10; ++i) {
    run_cycle(true);
    ASSERT_FALSE(tripped()) << "cycle " << cycle;
  }
  for (int silent = 1; silent < 5; ++silent) {
    run_cycle(false);
    ASSERT_FALSE(tripped()) << silent << " cycles without a setpoint";
  }
  run_cycle(false);
  EXPECT_TRUE(tripped()) << "5 cycles without a setpoint";
}

TEST_F(CommandWatchdogTest, StaysQuietWhileDisabled) {
  ASSERT_EQ(bus.write(FieldId::control_mode, 0.0F), core::SetResult::Ok);
  for (int i = 0; i < 20; ++i) {
    run_cycle(false);
  }
  EXPECT_FALSE(tripped());
  EXPECT_TRUE(board.has(FieldId::watchdog_tripped));
}

TEST_F(CommandWatchdogTest, ReleasesWhenTheStreamResumes) {
  ASSERT_EQ(bus.write(FieldId::control_mode, 2.0F), core::SetResult::Ok);
  for (int i = 0; i < 8; ++i) {
    run_cycle(false);
  }
  ASSERT_TRUE(tripped());  // enabled with no stream at all
  run_cycle(true);
  EXPECT_FALSE(tripped());  // latching is the fault manager's job
}

// Counted in 64 bits, the silence survives the 32-bit cycle numbers' wrap.
TEST_F(CommandWatchdogTest, TripsOnTimeAcross2To32CyclesSinceStart) {
  ASSERT_EQ(bus.write(FieldId::control_mode, 1.0F), core::SetResult::Ok);
  run_cycle(true);
  // Late wake-ups of 2^20 periods each (each one trips the watchdog: a period
  // without a setpoint), then streaming again 3 cycles before 2^32 cycles since
  // the watchdog's first.
  for (int jump = 1; jump < 4096; ++jump) {
    cycle += (1U << 20) - 1;
    run_cycle(true);
  }
  cycle = 0xFFFFFFFBU;
  run_cycle(true);
  run_cycle(true);
  ASSERT_EQ(cycle, 0xFFFFFFFDU);
  ASSERT_FALSE(tripped());
  for (int silent = 1; silent < 5; ++silent) {
    run_cycle(false);
    ASSERT_FALSE(tripped()) << silent << " cycles without a setpoint";
  }
  run_cycle(false);
  EXPECT_TRUE(tripped()) << "5 cycles without a setpoint, at cycle " << cycle;
}

TEST_F(CommandWatchdogTest, StaysTrippedThrough2To32SilentCycles) {
  ASSERT_EQ(bus.write(FieldId::control_mode, 1.0F), core::SetResult::Ok);
  run_cycle(true);
  for (int jump = 1; jump <= 4096 + 2; ++jump) {
    cycle += 1U << 20;
    scheduler.run_cycle(cycle);
    ASSERT_TRUE(tripped()) << "after " << jump << " x 2^20 silent cycles";
  }
}

}  // namespace
}  // namespace joint
