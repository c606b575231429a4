#include "joint/modules/Cia402Drive.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

#include "core/Scheduler.hpp"
#include "joint/FaultBits.hpp"
#include "joint/testing/BoardStandIns.hpp"

namespace joint {
namespace {

using board::FieldId;
using cia402::State;
using joint::testing::kDtS;

constexpr std::uint16_t kShutdown = 0x06;
constexpr std::uint16_t kSwitchOn = 0x07;
constexpr std::uint16_t kEnableOperation = 0x0F;
constexpr std::uint16_t kQuickStop = 0x02;
constexpr std::uint16_t kFaultReset = 0x80;
constexpr std::uint16_t kHalt = cia402::bit(cia402::ControlBit::Halt);
constexpr std::uint16_t kStart = cia402::bit(cia402::ControlBit::NewSetPoint);

class Cia402DriveTest : public ::testing::Test {
 protected:
  void SetUp() override {
    for (core::MessageBoardUser* component :
         std::initializer_list<core::MessageBoardUser*>{&drive, &sensors, &derived, &protection, &bus}) {
      ASSERT_TRUE(scheduler.add(*component));
    }
    const core::StartupStatus status = scheduler.start();
    ASSERT_TRUE(status) << status.message();
    sensors.hold(FieldId::motor_position, 0.0F);
    derived.hold(FieldId::motor_velocity, 0.0F);
    derived.hold(FieldId::joint_torque, 0.0F);
    protection.hold(FieldId::safe_state, 0.0F);
    protection.hold(FieldId::fault_flags, 0.0F);
    step();
  }

  void step() { scheduler.run_cycle(++cycle); }
  void command(std::uint16_t controlword) {
    ASSERT_EQ(bus.write(FieldId::controlword, controlword), core::SetResult::Ok);
    step();
  }
  State state() const {
    const auto status = static_cast<std::uint16_t>(board.get(FieldId::statusword));
    for (const State s : {State::NotReadyToSwitchOn, State::SwitchOnDisabled, State::ReadyToSwitchOn, State::SwitchedOn,
                          State::OperationEnabled, State::QuickStopActive, State::FaultReactionActive, State::Fault}) {
      if ((status & cia402::mask(s)) == static_cast<std::uint16_t>(s)) return s;
    }
    return State::NotReadyToSwitchOn;
  }
  std::uint16_t status() const { return static_cast<std::uint16_t>(board.get(FieldId::statusword)); }
  void enable(float mode) {
    ASSERT_EQ(bus.write(FieldId::modes_of_operation, mode), core::SetResult::Ok);
    command(kShutdown);
    command(kSwitchOn);
    command(kEnableOperation);
    ASSERT_EQ(state(), State::OperationEnabled);
  }

  core::MessageBoard board;
  core::Scheduler scheduler{board};
  Cia402Drive drive{board, kDtS};
  testing::FieldSource<core::Sensor> sensors{board, "sensors", {FieldId::motor_position}};
  testing::FieldSource<core::VirtualSensor> derived{board, "derived", {FieldId::motor_velocity, FieldId::joint_torque}};
  testing::FieldSource<core::Module> protection{board, "protection", {FieldId::safe_state, FieldId::fault_flags}};
  testing::BusStandIn bus{board};
  std::uint32_t cycle = 0;
};

// The fault reaction's ramp: a joint turning at 1 rad/s (gearbox side) in cyclic synchronous
// velocity whose velocity follows the drive's demand a cycle late, and a latched fault.
class Cia402FaultReactionTest : public Cia402DriveTest {
 protected:
  static constexpr float kGearRatio = 50.0F;

  void SetUp() override {
    Cia402DriveTest::SetUp();
    ASSERT_EQ(bus.write(FieldId::target_velocity, 1000.0F), core::SetResult::Ok);
    derived.hold(FieldId::motor_velocity, 1.0F * kGearRatio);
    enable(9.0F);
    ASSERT_EQ(board.get(FieldId::drive_velocity_reference), 1.0F);
  }
  void option(float value) { ASSERT_EQ(bus.write(FieldId::fault_reaction_option_code, value), core::SetResult::Ok); }
  void latch(FaultBit bit) {
    protection.hold(FieldId::safe_state, 1.0F);
    protection.hold(FieldId::fault_flags, static_cast<float>(fault_mask(bit)));
  }
  void follow() {
    derived.hold(FieldId::motor_velocity, board.get(FieldId::drive_velocity_reference) * kGearRatio);
    step();
  }
  // Cycles in fault reaction active, the demand checked against the ramp at `step_rad_s` a cycle.
  int ramp_cycles(float step_rad_s) {
    int cycles = 0;
    while (state() == State::FaultReactionActive && cycles < 10000) {
      ++cycles;
      const float demand = std::max(1.0F - step_rad_s * static_cast<float>(cycles), 0.0F);
      EXPECT_NEAR(board.get(FieldId::drive_velocity_reference), demand, 1.0e-4F) << "cycle " << cycles << " of the ramp";
      EXPECT_EQ(board.get(FieldId::drive_fault_ramp), 1.0F);
      follow();
    }
    return cycles;
  }
};

// CiA 402's command coding (controlword bits 3..0) for every one of the 16 values.
TEST(Cia402Controlword, EveryLowNibbleDecodesAsTheProfilesTableSays) {
  using enum DriveCommand;
  constexpr std::array<DriveCommand, 16> kExpected{
      DisableVoltage, DisableVoltage, QuickStop, QuickStop,  // 0000 0001 0010 0011
      DisableVoltage, DisableVoltage, Shutdown,  SwitchOn,   // 0100 0101 0110 0111
      DisableVoltage, DisableVoltage, QuickStop, QuickStop,  // 1000 1001 1010 1011
      DisableVoltage, DisableVoltage, Shutdown,  EnableOperation};
  for (std::uint16_t low = 0; low < 16; ++low) {
    EXPECT_EQ(decode_controlword(low), kExpected[low]) << "controlword 0x" << std::hex << low;
    EXPECT_EQ(decode_controlword(static_cast<std::uint16_t>(low | 0xFF70u)), kExpected[low]) << "bits 4.. ignored";
  }
}

TEST_F(Cia402DriveTest, OffersItsModesAndStartsSwitchOnDisabled) {
  // Modes 1, 3, 4, 6, 8, 9, 10: bit n-1 each.
  constexpr unsigned kOffered = (1u << 0) | (1u << 2) | (1u << 3) | (1u << 5) | (1u << 7) | (1u << 8) | (1u << 9);
  EXPECT_EQ(board.get(FieldId::supported_drive_modes), static_cast<float>(kOffered));
  EXPECT_EQ(state(), State::SwitchOnDisabled);
  EXPECT_NE(status() & cia402::bit(cia402::StatusBit::Remote), 0);
}

TEST_F(Cia402DriveTest, WalksTheStatesAndQuickStopsToSwitchOnDisabled) {
  command(kShutdown);
  EXPECT_EQ(state(), State::ReadyToSwitchOn);
  command(kSwitchOn);
  EXPECT_EQ(state(), State::SwitchedOn);
  command(kEnableOperation);
  EXPECT_EQ(state(), State::OperationEnabled);
  command(kSwitchOn);  // disable operation
  EXPECT_EQ(state(), State::SwitchedOn);
  command(kEnableOperation);
  command(kQuickStop);
  EXPECT_EQ(state(), State::QuickStopActive);
  step();  // at rest: option 2 ends in switch on disabled
  EXPECT_EQ(state(), State::SwitchOnDisabled);
}

TEST_F(Cia402DriveTest, QuickStopOptionSixStaysAndEnablesAgain) {
  ASSERT_EQ(bus.write(FieldId::quick_stop_option_code, 6.0F), core::SetResult::Ok);
  enable(3.0F);
  command(kQuickStop);
  step();
  EXPECT_EQ(state(), State::QuickStopActive);
  command(kEnableOperation);
  EXPECT_EQ(state(), State::OperationEnabled);
}

TEST_F(Cia402DriveTest, ACommandThatSkipsStatesIsNotTaken) {
  command(kEnableOperation);
  EXPECT_EQ(state(), State::SwitchOnDisabled);
  command(kSwitchOn);
  EXPECT_EQ(state(), State::SwitchOnDisabled);
}

TEST_F(Cia402DriveTest, AModeItDoesNotOfferIsNotTaken) {
  enable(9.0F);
  ASSERT_EQ(bus.write(FieldId::modes_of_operation, 2.0F), core::SetResult::Ok);  // velocity mode
  step();
  EXPECT_EQ(board.get(FieldId::modes_of_operation_display), 9.0F);
}

TEST_F(Cia402DriveTest, WithoutAModeTheJointsOwnCommandsPassThrough) {
  ASSERT_EQ(bus.write(FieldId::control_mode, 1.0F), core::SetResult::Ok);
  ASSERT_EQ(bus.write(FieldId::velocity_setpoint, 2.0F), core::SetResult::Ok);
  step();
  EXPECT_EQ(board.get(FieldId::drive_mode), 1.0F);
  EXPECT_EQ(board.get(FieldId::drive_velocity_reference), 2.0F);
}

TEST_F(Cia402DriveTest, AModeMovesOnlyInOperationEnabled) {
  ASSERT_EQ(bus.write(FieldId::modes_of_operation, 9.0F), core::SetResult::Ok);
  ASSERT_EQ(bus.write(FieldId::target_velocity, 1000.0F), core::SetResult::Ok);  // before enabled
  command(kShutdown);
  command(kSwitchOn);
  EXPECT_EQ(board.get(FieldId::drive_mode), 0.0F);
  command(kEnableOperation);
  EXPECT_EQ(board.get(FieldId::drive_mode), 1.0F);
  EXPECT_FLOAT_EQ(board.get(FieldId::drive_velocity_reference), 1.0F);
}

TEST_F(Cia402DriveTest, MaxMotorSpeedLimitsTheVelocityDemandAndSaysSo) {
  constexpr std::uint16_t kInternalLimit = cia402::bit(cia402::StatusBit::InternalLimitActive);
  ASSERT_EQ(bus.write(FieldId::max_motor_speed, 1500.0F), core::SetResult::Ok);
  ASSERT_EQ(bus.write(FieldId::target_velocity, 1000.0F), core::SetResult::Ok);
  enable(9.0F);
  EXPECT_FLOAT_EQ(board.get(FieldId::drive_velocity_reference), 1.0F);
  EXPECT_EQ(status() & kInternalLimit, 0);
  ASSERT_EQ(bus.write(FieldId::target_velocity, -4000.0F), core::SetResult::Ok);
  step();
  EXPECT_FLOAT_EQ(board.get(FieldId::drive_velocity_reference), -1.5F);
  EXPECT_NE(status() & kInternalLimit, 0);
}

TEST_F(Cia402DriveTest, ProfileVelocityRampsAndAModeSwitchWithHaltStaysHalted) {
  enable(4.0F);
  ASSERT_EQ(bus.write(FieldId::target_velocity, 2000.0F), core::SetResult::Ok);
  ASSERT_EQ(bus.write(FieldId::modes_of_operation, 3.0F), core::SetResult::Ok);
  command(kEnableOperation | kHalt);
  for (int i = 0; i < 50; ++i) step();
  EXPECT_EQ(board.get(FieldId::modes_of_operation_display), 3.0F);
  EXPECT_EQ(board.get(FieldId::drive_velocity_reference), 0.0F);
  command(kEnableOperation);
  for (int i = 0; i < 49; ++i) step();
  // 20 rad/s^2 (profile_acceleration) for 50 cycles of 1 ms.
  EXPECT_NEAR(board.get(FieldId::drive_velocity_reference), 1.0F, 1.0e-3F);
}

// Profile velocity's target reached (statusword bit 10): the velocity within the window of the
// target from either side, below it while accelerating as much as above it.
TEST_F(Cia402DriveTest, ProfileVelocityTargetReachedOnlyWithinTheWindowOnEitherSide) {
  constexpr std::uint16_t kTargetReached = cia402::bit(cia402::StatusBit::TargetReached);
  enable(3.0F);
  ASSERT_EQ(bus.write(FieldId::target_velocity, 2000.0F), core::SetResult::Ok);  // 2 rad/s
  const float window_rad_s = board.get(FieldId::velocity_window) * 1.0e-3F;
  ASSERT_LT(window_rad_s, 1.0F);
  for (const float rad_s : {0.0F, 2.0F - 2.0F * window_rad_s, 2.0F, 2.0F + 0.5F * window_rad_s, 4.0F, -2.0F}) {
    derived.hold(FieldId::motor_velocity, rad_s * kGearRatio);
    step();
    const bool within = std::abs(rad_s - 2.0F) <= window_rad_s;
    EXPECT_EQ((status() & kTargetReached) != 0, within) << rad_s << " rad/s against 2 rad/s";
  }
}

TEST_F(Cia402DriveTest, AFaultIsReactedToThenResetByTheFaultManagersRules) {
  enable(9.0F);
  protection.hold(FieldId::safe_state, 1.0F);
  step();
  step();  // safe_state is read as last cycle's
  EXPECT_EQ(state(), State::FaultReactionActive);
  step();
  EXPECT_EQ(state(), State::Fault);
  command(kFaultReset);
  EXPECT_EQ(board.get(FieldId::drive_fault_reset), 1.0F);
  step();  // the cause is still there: still in fault
  EXPECT_EQ(state(), State::Fault);
  protection.hold(FieldId::safe_state, 0.0F);
  command(0);
  command(kFaultReset);
  step();
  step();
  EXPECT_EQ(state(), State::SwitchOnDisabled);
}

TEST_F(Cia402DriveTest, HomingOnTheCurrentPositionSetsTheHomeOffset) {
  sensors.hold(FieldId::motor_position, 50.0F);  // 1 rad at the gearbox (gear ratio 50)
  ASSERT_EQ(bus.write(FieldId::home_offset, 250.0F), core::SetResult::Ok);
  enable(6.0F);
  EXPECT_EQ(status() & 0x3400, 0);  // in progress until started
  command(kEnableOperation | kStart);
  EXPECT_EQ(status() & 0x3400, 0x1400);  // attained, target reached
  EXPECT_EQ(board.get(FieldId::position_actual_value), 250.0F);
}

TEST_F(Cia402DriveTest, HomingOnAHardStopEndsWhereTheJointStopsFollowing) {
  ASSERT_EQ(bus.write(FieldId::homing_method, -3.0F), core::SetResult::Ok);
  enable(6.0F);
  command(kEnableOperation | kStart);
  EXPECT_LT(board.get(FieldId::drive_velocity_reference), 0.0F);  // moving negative
  // The joint stays put (a stop): the demand runs away until following_error_window (0.2 rad).
  int cycles = 0;
  while ((status() & 0x1000) == 0 && cycles < 10000) {
    step();
    ++cycles;
  }
  EXPECT_EQ(status() & 0x3400, 0x1400);
  EXPECT_GT(cycles, 100);
  EXPECT_EQ(board.get(FieldId::position_actual_value), 0.0F);
}


TEST_F(Cia402DriveTest, AProfilePositionTargetBeyondTheMaxLimitStopsAtIt) {
  constexpr std::uint16_t kInternalLimit = cia402::bit(cia402::StatusBit::InternalLimitActive);
  constexpr std::uint16_t kTargetReached = cia402::bit(cia402::StatusBit::TargetReached);
  ASSERT_EQ(bus.write(FieldId::max_position_limit, 100.0F), core::SetResult::Ok);
  ASSERT_EQ(bus.write(FieldId::target_position, 500.0F), core::SetResult::Ok);
  enable(1.0F);
  command(kEnableOperation | kStart);
  int cycles = 0;
  while (board.get(FieldId::drive_position_reference) < 0.1F && cycles < 10000) {
    step();
    ++cycles;
  }
  for (int i = 0; i < 100; ++i) step();
  EXPECT_FLOAT_EQ(board.get(FieldId::drive_position_reference), 0.1F);  // 100 mrad, not 500
  EXPECT_NE(status() & kInternalLimit, 0);
  // A relative move on from the limit stays at it; one back inside clears the bit.
  command(kEnableOperation | cia402::bit(cia402::ControlBit::Relative));
  command(kEnableOperation | cia402::bit(cia402::ControlBit::Relative) | kStart);
  for (int i = 0; i < 200; ++i) step();
  EXPECT_FLOAT_EQ(board.get(FieldId::drive_position_reference), 0.1F);
  ASSERT_EQ(bus.write(FieldId::target_position, 50.0F), core::SetResult::Ok);
  command(kEnableOperation);
  command(kEnableOperation | kStart);
  for (int i = 0; i < 500; ++i) step();
  EXPECT_NEAR(board.get(FieldId::drive_position_reference), 0.05F, 1.0e-6F);
  EXPECT_EQ(status() & kInternalLimit, 0);
  sensors.hold(FieldId::motor_position, 0.05F * 50.0F);  // the joint follows (gear ratio 50)
  step();
  EXPECT_NE(status() & kTargetReached, 0);
}

TEST_F(Cia402DriveTest, ACyclicSynchronousPositionTargetIsClampedToTheMinLimit) {
  constexpr std::uint16_t kInternalLimit = cia402::bit(cia402::StatusBit::InternalLimitActive);
  ASSERT_EQ(bus.write(FieldId::min_position_limit, -50.0F), core::SetResult::Ok);
  ASSERT_EQ(bus.write(FieldId::target_position, -300.0F), core::SetResult::Ok);
  enable(8.0F);
  EXPECT_FLOAT_EQ(board.get(FieldId::drive_position_reference), -0.05F);
  EXPECT_NE(status() & kInternalLimit, 0);
  ASSERT_EQ(bus.write(FieldId::target_position, -20.0F), core::SetResult::Ok);
  step();
  EXPECT_FLOAT_EQ(board.get(FieldId::drive_position_reference), -0.02F);
  EXPECT_EQ(status() & kInternalLimit, 0);
}

TEST_F(Cia402DriveTest, AMinLimitAboveTheMaxLeavesPositionTargetsUnlimited) {
  ASSERT_EQ(bus.write(FieldId::min_position_limit, 100.0F), core::SetResult::Ok);
  ASSERT_EQ(bus.write(FieldId::max_position_limit, -100.0F), core::SetResult::Ok);
  ASSERT_EQ(bus.write(FieldId::target_position, -300.0F), core::SetResult::Ok);
  enable(8.0F);
  EXPECT_FLOAT_EQ(board.get(FieldId::drive_position_reference), -0.3F);
  EXPECT_EQ(status() & cia402::bit(cia402::StatusBit::InternalLimitActive), 0);
}

TEST_F(Cia402DriveTest, HomingOnAHardStopSearchesAtTheSpeedForTheSwitch) {
  ASSERT_EQ(bus.write(FieldId::homing_method, -3.0F), core::SetResult::Ok);
  ASSERT_EQ(bus.write(FieldId::speed_during_search_for_switch, 300.0F), core::SetResult::Ok);
  ASSERT_EQ(bus.write(FieldId::profile_velocity, 4000.0F), core::SetResult::Ok);  // not homing's
  enable(6.0F);
  command(kEnableOperation | kStart);
  for (int i = 0; i < 100; ++i) step();
  EXPECT_FLOAT_EQ(board.get(FieldId::drive_velocity_reference), -0.3F);
  EXPECT_EQ(status() & 0x1000, 0);  // still searching
}

TEST_F(Cia402FaultReactionTest, OptionTwoRampsOnTheQuickStopDecelerationThenFaults) {
  option(2.0F);
  ASSERT_EQ(bus.write(FieldId::quick_stop_deceleration, 20000.0F), core::SetResult::Ok);  // 20 rad/s^2
  EXPECT_EQ(board.get(FieldId::drive_fault_ramp), 0.0F) << "armed from the next cycle on";
  step();
  EXPECT_EQ(board.get(FieldId::drive_fault_ramp), 1.0F) << "armed while the mode moves the joint";
  latch(FaultBit::CommandWatchdog);
  step();  // the fault's first cycle: the drive reads it a cycle late and still runs the mode
  EXPECT_EQ(state(), State::OperationEnabled);
  EXPECT_EQ(board.get(FieldId::drive_velocity_reference), 1.0F);
  step();
  // 0.02 rad/s a cycle from 1 rad/s: 50 cycles in fault reaction active (the 50th step leaves a
  // float residue, the 51st reaches 0), then fault with the drive disabled.
  EXPECT_EQ(ramp_cycles(0.02F), 50);
  EXPECT_EQ(state(), State::Fault);
  EXPECT_EQ(board.get(FieldId::drive_fault_ramp), 0.0F);
  EXPECT_EQ(board.get(FieldId::drive_mode), board::to_value(ControlMode::Disabled));
}

TEST_F(Cia402FaultReactionTest, OptionOneRampsOnTheProfileDeceleration) {
  option(1.0F);
  ASSERT_EQ(bus.write(FieldId::profile_deceleration, 10000.0F), core::SetResult::Ok);    // 10 rad/s^2
  ASSERT_EQ(bus.write(FieldId::quick_stop_deceleration, 50000.0F), core::SetResult::Ok);  // not this one
  latch(FaultBit::MasterHeartbeatLost);
  step();
  step();
  EXPECT_EQ(ramp_cycles(0.01F), 100);
  EXPECT_EQ(state(), State::Fault);
}

TEST_F(Cia402FaultReactionTest, OptionZeroDisablesAtOnce) {
  option(0.0F);
  step();
  EXPECT_EQ(board.get(FieldId::drive_fault_ramp), 0.0F) << "the safe state cuts the duty in the fault's cycle";
  latch(FaultBit::CommandWatchdog);
  step();
  step();
  EXPECT_EQ(state(), State::FaultReactionActive);
  EXPECT_EQ(board.get(FieldId::drive_mode), board::to_value(ControlMode::Disabled));
  step();
  EXPECT_EQ(state(), State::Fault);
}

TEST_F(Cia402FaultReactionTest, AFaultThatLeavesNoSensorDisablesAtOnceWhateverTheOption) {
  option(2.0F);
  for (const FaultBit bit : {FaultBit::MotorEncoderStale, FaultBit::OutputEncoderStale, FaultBit::ThermistorStale,
                             FaultBit::OverTemperature}) {
    EXPECT_TRUE(safe_state_cuts_the_drive(1.0F, static_cast<float>(fault_mask(bit)), 1.0F));
  }
  latch(FaultBit::MotorEncoderStale);
  step();
  step();
  EXPECT_EQ(state(), State::FaultReactionActive);
  EXPECT_EQ(board.get(FieldId::drive_fault_ramp), 0.0F);
  EXPECT_EQ(board.get(FieldId::drive_mode), board::to_value(ControlMode::Disabled));
  step();
  EXPECT_EQ(state(), State::Fault);
}

TEST_F(Cia402FaultReactionTest, AStaleEncoderDuringTheRampEndsIt) {
  option(2.0F);
  latch(FaultBit::CommandWatchdog);
  step();
  step();
  follow();
  EXPECT_EQ(state(), State::FaultReactionActive);
  EXPECT_FALSE(safe_state_cuts_the_drive(1.0F, board.get(FieldId::fault_flags), board.get(FieldId::drive_fault_ramp)));
  protection.hold(FieldId::fault_flags, static_cast<float>(fault_mask(FaultBit::CommandWatchdog) |
                                                           fault_mask(FaultBit::MotorEncoderStale)));
  step();
  EXPECT_TRUE(safe_state_cuts_the_drive(1.0F, board.get(FieldId::fault_flags), board.get(FieldId::drive_fault_ramp)))
      << "the controllers, the arbiter and the motor cut in the cycle the encoder goes stale";
  step();
  EXPECT_EQ(state(), State::Fault);
  EXPECT_EQ(board.get(FieldId::drive_fault_ramp), 0.0F);
}

TEST_F(Cia402FaultReactionTest, WithoutA402ModeAFaultDisablesAtOnce) {
  option(2.0F);
  ASSERT_EQ(bus.write(FieldId::modes_of_operation, 0.0F), core::SetResult::Ok);
  step();
  EXPECT_EQ(board.get(FieldId::drive_fault_ramp), 0.0F);
}

}  // namespace
}  // namespace joint
