// hilfw's board application without a bus: the generic registers, and run_board's start-up
// (command line, schedule) on the demo joint's table.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "CommandLine.hpp"
#include "hilfw/Board.hpp"
#include "hilfw/HilRegisters.hpp"

namespace {

using board::FieldId;
using board::HilInputId;
using board::HilOutputId;

TEST(HilRegisters, AnInputIsFreshOnceAndKeepsItsValue) {
  hilfw::HilRegisters registers;
  EXPECT_EQ(registers.read_input(HilInputId::thermistor_adc).raw, 0);
  registers.write_input(HilInputId::thermistor_adc, 1234);
  const hilfw::HilRegisters::Input first = registers.read_input(HilInputId::thermistor_adc);
  EXPECT_EQ(first.raw, 1234);
  EXPECT_TRUE(first.fresh);
  const hilfw::HilRegisters::Input second = registers.read_input(HilInputId::thermistor_adc);
  EXPECT_EQ(second.raw, 1234);
  EXPECT_FALSE(second.fresh);
  EXPECT_EQ(registers.input(HilInputId::thermistor_adc), 1234);
  EXPECT_EQ(registers.input(HilInputId::motor_encoder_counts), 0);  // the others untouched
}

TEST(HilRegisters, AnOutputReadsBackWhatTheActuatorLeft) {
  hilfw::HilRegisters registers;
  EXPECT_EQ(registers.read_output(HilOutputId::motor_duty), 0);
  registers.write_output(HilOutputId::motor_duty, -2500);
  EXPECT_EQ(registers.read_output(HilOutputId::motor_duty), -2500);
  EXPECT_EQ(registers.read_output(HilOutputId::led_pattern), 0);
}

TEST(HilRegisters, AHeartbeatLossIsNewOnceAndLostWhileItLasts) {
  hilfw::HilRegisters registers;
  EXPECT_FALSE(registers.read_heartbeat().lost);
  registers.heartbeat_status(1, true);
  const hilfw::HilRegisters::Heartbeat lost = registers.read_heartbeat();
  EXPECT_TRUE(lost.lost);
  EXPECT_TRUE(lost.new_loss);
  EXPECT_FALSE(registers.read_heartbeat().new_loss);
  // Lost and back before the component looked: the loss is still news.
  registers.heartbeat_status(0, false);
  registers.heartbeat_status(1, true);
  registers.heartbeat_status(0, false);
  const hilfw::HilRegisters::Heartbeat back = registers.read_heartbeat();
  EXPECT_FALSE(back.lost);
  EXPECT_TRUE(back.new_loss);
}

// A Sensor on the generic registers: the raw thermistor reading as motor_current (any sensor
// field of the joint's table does).
class RawSensor final : public core::Sensor {
 public:
  RawSensor(core::MessageBoard& board, hilfw::HilRegisters& registers)
      : Sensor(board, "raw_sensor", {.writes = {FieldId::motor_current}}), registers_{registers} {}
  void update() override {
    boardSet(FieldId::motor_current, static_cast<float>(registers_.read_input(HilInputId::thermistor_adc).raw));
  }

 private:
  hilfw::HilRegisters& registers_;
};

struct OneSensor {
  OneSensor(core::MessageBoard& board, hilfw::HilRegisters& registers, float) : sensor{board, registers} {}
  bool add_to(core::Scheduler& scheduler) { return scheduler.add(sensor); }
  RawSensor sensor;
};

// A Sensor that declares a write of a module's field: the schedule refuses it at start-up.
class MisfitSensor final : public core::Sensor {
 public:
  explicit MisfitSensor(core::MessageBoard& board)
      : Sensor(board, "misfit_sensor", {.writes = {FieldId::velocity_controller_output}}) {}
  void update() override {}
};

struct Misfit {
  Misfit(core::MessageBoard& board, hilfw::HilRegisters&, float) : sensor{board} {}
  bool add_to(core::Scheduler& scheduler) { return scheduler.add(sensor); }
  MisfitSensor sensor;
};

template <class Components>
int run(std::vector<std::string> arguments, const hilfw::BoardInfo& info) {
  arguments.insert(arguments.begin(), "board-test");
  std::vector<char*> argv;
  for (std::string& argument : arguments) argv.push_back(argument.data());
  argv.push_back(nullptr);
  return hilfw::run_board<Components>(static_cast<int>(arguments.size()), argv.data(), info);
}

TEST(RunBoard, PrintsTheScheduleOfTheBoardsComponents) {
  testing::internal::CaptureStdout();
  EXPECT_EQ(run<OneSensor>({"--print-schedule"}, {.description = "test board"}), 0);
  const std::string schedule = testing::internal::GetCapturedStdout();
  EXPECT_NE(schedule.find("raw_sensor"), std::string::npos) << schedule;
}

TEST(RunBoard, AScheduleErrorIsAStartUpFailure) {
  testing::internal::CaptureStderr();
  EXPECT_EQ(run<Misfit>({"--print-schedule"}, {.description = "test board"}), 1);
  const std::string error = testing::internal::GetCapturedStderr();
  EXPECT_NE(error.find("board-test: start-up error:"), std::string::npos) << error;
  EXPECT_NE(error.find("misfit_sensor"), std::string::npos) << error;
}

TEST(RunBoard, ARogueWriteWithoutATargetIsRefusedWithTheFix) {
  testing::internal::CaptureStderr();
  EXPECT_EQ(run<OneSensor>({"--inject-rogue-write-at-cycle", "3", "--print-schedule"}, {.description = "x"}), 2);
  const std::string error = testing::internal::GetCapturedStderr();
  EXPECT_NE(error.find("BoardInfo::rogue_target"), std::string::npos) << error;
}

TEST(RunBoard, TheRogueWriterJoinsTheScheduleWhenTheBoardNamesATarget) {
  testing::internal::CaptureStdout();
  EXPECT_EQ(run<OneSensor>({"--inject-rogue-write-at-cycle", "3", "--print-schedule"},
                           {.description = "x", .rogue_target = FieldId::motor_current}),
            0);
  const std::string schedule = testing::internal::GetCapturedStdout();
  EXPECT_NE(schedule.find("rogue_writer"), std::string::npos) << schedule;
}

// CiA 301's node ids 1..127 at both ends, and CiA 305's 0xFF (none yet, LSS only); 0 is not one.
TEST(RunBoard, TheNodeIdIsOneTo127OrTheUnconfiguredOne) {
  for (const char* id : {"1", "127", "0x7F", "0xFF"}) {
    testing::internal::CaptureStdout();
    EXPECT_EQ(run<OneSensor>({"--node-id", id, "--print-schedule"}, {.description = "x"}), 0) << id;
    testing::internal::GetCapturedStdout();
  }
  for (const char* id : {"0", "128", "-1", "0xFE", "1x"}) {
    testing::internal::CaptureStderr();
    EXPECT_EQ(run<OneSensor>({"--node-id", id, "--print-schedule"}, {.description = "x"}), linuxhw::kExitUsage)
        << id;
    EXPECT_NE(testing::internal::GetCapturedStderr().find("is not 1..127 or 0xFF"), std::string::npos) << id;
  }
}

TEST(RunBoard, TheProgramNameIsBoardInfosElseArgvZeros) {
  testing::internal::CaptureStdout();
  EXPECT_EQ(run<OneSensor>({"--help"}, {.description = "Firmware of the test board", .program = "named-firmware"}), 0);
  const std::string help = testing::internal::GetCapturedStdout();
  EXPECT_NE(help.find("named-firmware"), std::string::npos) << help;
  EXPECT_NE(help.find("Firmware of the test board"), std::string::npos) << help;
  testing::internal::CaptureStdout();
  EXPECT_EQ(run<OneSensor>({"--help"}, {.description = "x"}), 0);
  EXPECT_NE(testing::internal::GetCapturedStdout().find("board-test"), std::string::npos);
}

}  // namespace
