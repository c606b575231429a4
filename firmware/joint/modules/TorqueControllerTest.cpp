#include "joint/modules/TorqueController.hpp"

#include "joint/modules/Cia402Drive.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "core/Scheduler.hpp"
#include "joint/testing/BoardStandIns.hpp"

namespace joint {
namespace {

using board::FieldId;

using joint::testing::kDtS;

class TorqueControllerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    for (core::MessageBoardUser* component : std::initializer_list<core::MessageBoardUser*>{&controller, &drive, &spring, &bus}) {
      ASSERT_TRUE(scheduler.add(*component));
    }
    const core::StartupStatus status = scheduler.start();
    ASSERT_TRUE(status) << status.message();
  }

  core::MessageBoard board;
  core::Scheduler scheduler{board};
  TorqueController controller{board, kDtS};
  Cia402Drive drive{board, kDtS};  // passes control_mode and torque_setpoint on (no 402 mode)
  testing::FieldSource<core::VirtualSensor> spring{board, "spring_model", {FieldId::joint_torque}};
  testing::BusStandIn bus{board};
};

TEST_F(TorqueControllerTest, ReachesTheTorqueSetpointAgainstABlockedLoad) {
  // Voltage-driven motor: duty sets the gearbox speed (24 V / 0.05 V*s/rad / 50 =
  // 9.6 rad/s per unit duty); the load is blocked, so the spring twists by the
  // gearbox angle and the joint torque is 50 N*m/rad times that.
  constexpr float kGearboxSpeedPerDuty = 9.6F;
  constexpr float kStiffness = 50.0F;
  ASSERT_EQ(bus.write(FieldId::control_mode, 2.0F), core::SetResult::Ok);
  ASSERT_EQ(bus.write(FieldId::torque_setpoint, 5.0F), core::SetResult::Ok);
  float gearbox_angle_rad = 0.0F;
  float largest_duty = 0.0F;
  for (std::uint32_t cycle = 1; cycle <= 2000; ++cycle) {
    spring.hold(FieldId::joint_torque, kStiffness * gearbox_angle_rad);
    scheduler.run_cycle(cycle);
    const float duty = board.get(FieldId::torque_controller_output);
    largest_duty = std::max(largest_duty, std::fabs(duty));
    gearbox_angle_rad += kGearboxSpeedPerDuty * duty * kDtS;
  }
  EXPECT_NEAR(kStiffness * gearbox_angle_rad, 5.0F, 0.05F);
  EXPECT_LE(largest_duty, 0.95F);  // max_duty default
}

TEST_F(TorqueControllerTest, WritesZeroOutsideTorqueMode) {
  ASSERT_EQ(bus.write(FieldId::control_mode, 1.0F), core::SetResult::Ok);
  ASSERT_EQ(bus.write(FieldId::torque_setpoint, 5.0F), core::SetResult::Ok);
  scheduler.run_cycle(1);
  EXPECT_EQ(board.get(FieldId::torque_controller_output), 0.0F);
  ASSERT_EQ(bus.write(FieldId::control_mode, 2.0F), core::SetResult::Ok);
  scheduler.run_cycle(2);
  EXPECT_GT(board.get(FieldId::torque_controller_output), 0.0F);
}

}  // namespace
}  // namespace joint
