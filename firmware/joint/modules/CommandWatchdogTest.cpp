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

}  // namespace
}  // namespace joint
