#include "core/Scheduler.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace core {
namespace {

using board::FieldId;
using F = board::FieldId;

// Small components of each kind that log their update() calls.
template <typename Kind>
class Probe final : public Kind {
 public:
  Probe(MessageBoard& board, std::string_view name, const Declarations& declarations, std::vector<std::string>& log)
      : Kind(board, name, declarations), log_{log} {}
  void update() override { log_.emplace_back(this->name()); }

 private:
  std::vector<std::string>& log_;
};
using SensorProbe = Probe<Sensor>;
using VirtualSensorProbe = Probe<VirtualSensor>;
using ModuleProbe = Probe<Module>;
using ActuatorProbe = Probe<Actuator>;

class BusNodeStandIn final : public ExternalWriter {
 public:
  explicit BusNodeStandIn(MessageBoard& board) : ExternalWriter(board, "canopen_node", {.writes = kBusWritableFields}) {}
};

class SchedulerTest : public ::testing::Test {
 protected:
  std::vector<std::string> names(std::span<MessageBoardUser* const> components) {
    std::vector<std::string> result;
    for (const MessageBoardUser* component : components) {
      result.emplace_back(component->name());
    }
    return result;
  }

  MessageBoard board;
  Scheduler scheduler{board};
  std::vector<std::string> log;
};

::testing::AssertionResult Mentions(const std::string& text, std::string_view expected) {
  if (text.find(expected) != std::string::npos) {
    return ::testing::AssertionSuccess();
  }
  return ::testing::AssertionFailure() << "expected to find \"" << expected << "\" in:\n" << text;
}

::testing::AssertionResult DoesNotMention(const std::string& text, std::string_view unexpected) {
  if (text.find(unexpected) == std::string::npos) {
    return ::testing::AssertionSuccess();
  }
  return ::testing::AssertionFailure() << "did not expect \"" << unexpected << "\" in:\n" << text;
}

TEST_F(SchedulerTest, OrdersByKindBeforeDependencies) {
  ActuatorProbe motor{board, "motor", {.reads = {F::motor_duty_command}}, log};
  ModuleProbe arbiter{board, "drive_arbiter", {.writes = {F::motor_duty_command}, .reads = {F::motor_velocity}}, log};
  VirtualSensorProbe velocity{board, "motor_velocity",
      {.writes = {F::motor_velocity}, .reads = {F::motor_position}}, log};
  SensorProbe encoder{board, "motor_encoder", {.writes = {F::motor_position}}, log};
  for (MessageBoardUser* component : std::initializer_list<MessageBoardUser*>{&motor, &arbiter, &velocity, &encoder}) {
    ASSERT_TRUE(scheduler.add(*component));
  }
  const StartupStatus status = scheduler.start();
  ASSERT_TRUE(status) << status.message();
  EXPECT_EQ(names(scheduler.order()),
            (std::vector<std::string>{"motor_encoder", "motor_velocity", "drive_arbiter", "motor"}));
}

TEST_F(SchedulerTest, RunsWritersBeforeReadersWithinAKind) {
  // Added reader-first: the topological order must still put the writers first.
  ModuleProbe arbiter{board, "drive_arbiter",
      {.writes = {F::motor_duty_command}, .reads = {F::velocity_controller_output}}, log};
  ModuleProbe pid{board, "velocity_pid",
      {.writes = {F::velocity_controller_output}, .reads = {F::thermal_derate}}, log};
  ModuleProbe thermal{board, "thermal_protection", {.writes = {F::thermal_derate}}, log};
  ModuleProbe estimator{board, "spring_estimator", {.writes = {F::spring_constant_estimate}}, log};
  for (MessageBoardUser* component : std::initializer_list<MessageBoardUser*>{&arbiter, &pid, &thermal, &estimator}) {
    ASSERT_TRUE(scheduler.add(*component));
  }
  const StartupStatus status = scheduler.start();
  ASSERT_TRUE(status) << status.message();
  // spring_estimator has no inputs among the modules: it keeps its place after
  // the first runnable one, thermal_protection.
  EXPECT_EQ(names(scheduler.order()),
            (std::vector<std::string>{"thermal_protection", "velocity_pid", "drive_arbiter", "spring_estimator"}));
}

TEST_F(SchedulerTest, RunCycleStampsCycleThenUpdatesInOrder) {
  class Writer final : public Sensor {
   public:
    explicit Writer(MessageBoard& b) : Sensor(b, "motor_encoder", {.writes = {F::motor_position}}) {}
    void update() override { boardSet(F::motor_position, 1.0f); }
  } encoder{board};
  VirtualSensorProbe velocity{board, "motor_velocity",
      {.writes = {F::motor_velocity}, .reads = {F::motor_position}}, log};
  ASSERT_TRUE(scheduler.add(velocity));
  ASSERT_TRUE(scheduler.add(encoder));
  ASSERT_TRUE(scheduler.start());
  scheduler.run_cycle(5);
  EXPECT_EQ(board.cycle(), 5u);
  EXPECT_EQ(board.last_write_cycle(F::motor_position), 5u);
  EXPECT_EQ(log, std::vector<std::string>{"motor_velocity"});
}

TEST_F(SchedulerTest, RejectsTwoWritersOfOneFieldNamingFieldAndBoth) {
  ModuleProbe first{board, "velocity_pid", {.writes = {F::motor_duty_command}}, log};
  ModuleProbe second{board, "torque_pid", {.writes = {F::motor_duty_command}}, log};
  ASSERT_TRUE(scheduler.add(first));
  ASSERT_TRUE(scheduler.add(second));
  const StartupStatus status = scheduler.start();
  EXPECT_EQ(status.error(), StartupError::DuplicateWriter);
  EXPECT_TRUE(Mentions(status.message(), "'motor_duty_command'"));
  EXPECT_TRUE(Mentions(status.message(), "module 'velocity_pid'"));
  EXPECT_TRUE(Mentions(status.message(), "module 'torque_pid'"));
  // A failed start leaves the board without owners and runs nothing.
  EXPECT_EQ(board.owner(F::motor_duty_command), nullptr);
  EXPECT_TRUE(scheduler.order().empty());
  scheduler.run_cycle(1);
  EXPECT_TRUE(log.empty());
}

TEST_F(SchedulerTest, RejectsComponentWritingABusOwnedField) {
  BusNodeStandIn node{board};
  ModuleProbe sneaky{board, "auto_tuner", {.writes = {F::velocity_kp}}, log};
  ASSERT_TRUE(scheduler.add(node));
  ASSERT_TRUE(scheduler.add(sneaky));
  const StartupStatus status = scheduler.start();
  EXPECT_EQ(status.error(), StartupError::WrongFieldKind);
  EXPECT_TRUE(Mentions(status.message(), "module 'auto_tuner'"));
  EXPECT_TRUE(Mentions(status.message(), "'velocity_kp'"));
}

TEST_F(SchedulerTest, RejectsWriteOfFieldOfAnotherKind) {
  ModuleProbe module{board, "estimator", {.writes = {F::motor_velocity}}, log};
  ASSERT_TRUE(scheduler.add(module));
  const StartupStatus status = scheduler.start();
  EXPECT_EQ(status.error(), StartupError::WrongFieldKind);
  EXPECT_TRUE(Mentions(status.message(), "'motor_velocity', a virtual sensor field"));
}

TEST_F(SchedulerTest, ExternalWriterOwnsBusFieldsButIsNotScheduled) {
  BusNodeStandIn node{board};
  ModuleProbe pid{board, "velocity_pid",
      {.writes = {F::velocity_controller_output}, .reads = {F::velocity_setpoint, F::velocity_kp}}, log};
  ASSERT_TRUE(scheduler.add(node));
  ASSERT_TRUE(scheduler.add(pid));
  ASSERT_TRUE(scheduler.start());
  EXPECT_EQ(board.owner(F::velocity_setpoint), &node);
  EXPECT_EQ(board.owner(F::velocity_controller_output), &pid);
  EXPECT_EQ(names(scheduler.order()), std::vector<std::string>{"velocity_pid"});
  EXPECT_EQ(names(scheduler.external_writers()), std::vector<std::string>{"canopen_node"});
}

TEST_F(SchedulerTest, RejectsSensorReadingBoardField) {
  SensorProbe encoder{board, "motor_encoder", {.writes = {F::motor_position}, .reads = {F::motor_velocity}}, log};
  ASSERT_TRUE(scheduler.add(encoder));
  const StartupStatus status = scheduler.start();
  EXPECT_EQ(status.error(), StartupError::SensorReadsBoard);
  EXPECT_TRUE(Mentions(status.message(), "sensor 'motor_encoder'"));
  EXPECT_TRUE(Mentions(status.message(), "'motor_velocity'"));
}

TEST_F(SchedulerTest, RejectsSensorReadingLastCycleBoardField) {
  SensorProbe encoder{board, "motor_encoder",
      {.writes = {F::motor_position}, .reads_last_cycle = {F::safe_state}}, log};
  ASSERT_TRUE(scheduler.add(encoder));
  EXPECT_EQ(scheduler.start().error(), StartupError::SensorReadsBoard);
}

TEST_F(SchedulerTest, LetsSensorReadParameters) {
  SensorProbe encoder{board, "motor_encoder",
      {.writes = {F::motor_position}, .reads = {F::encoder_counts_per_rev, F::gear_ratio}}, log};
  ASSERT_TRUE(scheduler.add(encoder));
  const StartupStatus status = scheduler.start();
  EXPECT_TRUE(status) << status.message();
}

TEST_F(SchedulerTest, RejectsActuatorWriting) {
  ActuatorProbe motor{board, "motor", {.writes = {F::led_pattern_command}, .reads = {F::motor_duty_command}}, log};
  ASSERT_TRUE(scheduler.add(motor));
  const StartupStatus status = scheduler.start();
  EXPECT_EQ(status.error(), StartupError::ActuatorWritesBoard);
  EXPECT_TRUE(Mentions(status.message(), "actuator 'motor' declares a write of 'led_pattern_command'"));
}

TEST_F(SchedulerTest, RejectsReadOfFieldWrittenByLaterKind) {
  VirtualSensorProbe temperature{board, "winding_temperature",
      {.writes = {F::winding_temperature}, .reads = {F::thermal_derate}}, log};
  ModuleProbe thermal{board, "thermal_protection",
      {.writes = {F::thermal_derate}, .reads = {F::winding_temperature}}, log};
  ASSERT_TRUE(scheduler.add(temperature));
  ASSERT_TRUE(scheduler.add(thermal));
  const StartupStatus status = scheduler.start();
  EXPECT_EQ(status.error(), StartupError::ReadOfLaterKind);
  EXPECT_TRUE(Mentions(status.message(), "virtual sensor 'winding_temperature' reads 'thermal_derate'"));
  EXPECT_TRUE(Mentions(status.message(), "module 'thermal_protection'"));
  EXPECT_TRUE(Mentions(status.message(), "reads_last_cycle"));
}

TEST_F(SchedulerTest, AcceptsLastCycleReadOfFieldWrittenByLaterKind) {
  VirtualSensorProbe temperature{board, "winding_temperature",
      {.writes = {F::winding_temperature}, .reads_last_cycle = {F::thermal_derate}}, log};
  ModuleProbe thermal{board, "thermal_protection",
      {.writes = {F::thermal_derate}, .reads = {F::winding_temperature}}, log};
  ASSERT_TRUE(scheduler.add(thermal));
  ASSERT_TRUE(scheduler.add(temperature));
  const StartupStatus status = scheduler.start();
  ASSERT_TRUE(status) << status.message();
  EXPECT_EQ(names(scheduler.order()), (std::vector<std::string>{"winding_temperature", "thermal_protection"}));
}

TEST_F(SchedulerTest, RejectsCycleSpellingOutComponentsAndFields) {
  ModuleProbe pid{board, "velocity_pid",
      {.writes = {F::velocity_controller_output}, .reads = {F::motor_duty_command}}, log};
  ModuleProbe arbiter{board, "drive_arbiter",
      {.writes = {F::motor_duty_command}, .reads = {F::velocity_controller_output}}, log};
  ModuleProbe thermal{board, "thermal_protection", {.writes = {F::thermal_derate}}, log};
  ASSERT_TRUE(scheduler.add(thermal));
  ASSERT_TRUE(scheduler.add(pid));
  ASSERT_TRUE(scheduler.add(arbiter));
  const StartupStatus status = scheduler.start();
  EXPECT_EQ(status.error(), StartupError::UpdateOrderCycle);
  EXPECT_TRUE(Mentions(status.message(), "velocity_pid -> velocity_controller_output -> drive_arbiter -> "
                                         "motor_duty_command -> velocity_pid"));
  EXPECT_TRUE(Mentions(status.message(), "among modules"));
}

TEST_F(SchedulerTest, SpellsOutOnlyTheLoopOfALongerCycle) {
  // a -> b -> c -> a is the loop; feeder runs before it, and reader hangs off
  // it (added first, so the search starts there) without being part of it.
  ModuleProbe feeder{board, "feeder", {.writes = {F::thermal_derate}}, log};
  ModuleProbe reader{board, "reader", {.writes = {F::spring_constant_confidence}, .reads = {F::safe_state}}, log};
  ModuleProbe a{board, "a", {.writes = {F::fault_flags}, .reads = {F::thermal_derate, F::led_pattern_command}}, log};
  ModuleProbe b{board, "b", {.writes = {F::watchdog_tripped}, .reads = {F::fault_flags}}, log};
  ModuleProbe c{board, "c", {.writes = {F::led_pattern_command, F::safe_state}, .reads = {F::watchdog_tripped}}, log};
  for (MessageBoardUser* component : std::initializer_list<MessageBoardUser*>{&feeder, &reader, &a, &b, &c}) {
    ASSERT_TRUE(scheduler.add(*component));
  }
  const StartupStatus status = scheduler.start();
  EXPECT_EQ(status.error(), StartupError::UpdateOrderCycle);
  EXPECT_TRUE(Mentions(status.message(), ": c -> led_pattern_command -> a -> fault_flags -> b -> watchdog_tripped -> c ("));
  EXPECT_TRUE(DoesNotMention(status.message(), "feeder"));
  EXPECT_TRUE(DoesNotMention(status.message(), "reader"));
}

TEST_F(SchedulerTest, LastCycleReadBreaksACycle) {
  ModuleProbe pid{board, "velocity_pid",
      {.writes = {F::velocity_controller_output}, .reads_last_cycle = {F::motor_duty_command}}, log};
  ModuleProbe arbiter{board, "drive_arbiter",
      {.writes = {F::motor_duty_command}, .reads = {F::velocity_controller_output}}, log};
  ASSERT_TRUE(scheduler.add(arbiter));
  ASSERT_TRUE(scheduler.add(pid));
  const StartupStatus status = scheduler.start();
  ASSERT_TRUE(status) << status.message();
  EXPECT_EQ(names(scheduler.order()), (std::vector<std::string>{"velocity_pid", "drive_arbiter"}));
}

TEST_F(SchedulerTest, RejectsFieldDeclaredAsBothReadAndLastCycleRead) {
  ModuleProbe pid{board, "velocity_pid", {.reads = {F::motor_velocity}, .reads_last_cycle = {F::motor_velocity}}, log};
  ASSERT_TRUE(scheduler.add(pid));
  const StartupStatus status = scheduler.start();
  EXPECT_EQ(status.error(), StartupError::ConflictingRead);
  EXPECT_TRUE(Mentions(status.message(), "'motor_velocity'"));
}

TEST_F(SchedulerTest, RejectsDuplicateNames) {
  ModuleProbe first{board, "pid", {}, log};
  ModuleProbe second{board, "pid", {}, log};
  ASSERT_TRUE(scheduler.add(first));
  ASSERT_TRUE(scheduler.add(second));
  EXPECT_EQ(scheduler.start().error(), StartupError::DuplicateName);
}

TEST_F(SchedulerTest, RefusesAddAndSecondStartAfterStart) {
  ModuleProbe pid{board, "pid", {}, log};
  ModuleProbe late{board, "late", {}, log};
  ASSERT_TRUE(scheduler.add(pid));
  ASSERT_TRUE(scheduler.start());
  EXPECT_FALSE(scheduler.add(late));
  EXPECT_EQ(scheduler.start().error(), StartupError::AlreadyStarted);
  EXPECT_EQ(scheduler.order().size(), 1u);
}

TEST_F(SchedulerTest, PrintsScheduleWithWritesAndReads) {
  BusNodeStandIn node{board};
  SensorProbe encoder{board, "motor_encoder", {.writes = {F::motor_position}}, log};
  VirtualSensorProbe velocity{board, "motor_velocity",
      {.writes = {F::motor_velocity}, .reads = {F::motor_position, F::velocity_filter_hz}}, log};
  ModuleProbe pid{board, "velocity_pid",
      {.writes = {F::velocity_controller_output}, .reads = {F::motor_velocity, F::thermal_derate}, .reads_last_cycle = {F::motor_duty_command}}, log};
  for (MessageBoardUser* component : std::initializer_list<MessageBoardUser*>{&node, &pid, &velocity, &encoder}) {
    ASSERT_TRUE(scheduler.add(*component));
  }
  ASSERT_TRUE(scheduler.start());
  std::string printed;
  scheduler.print_schedule([](void* context, std::string_view text) { static_cast<std::string*>(context)->append(text); },
                           &printed);
  EXPECT_EQ(printed, scheduler.schedule_text());
  EXPECT_TRUE(Mentions(printed, "1. sensor 'motor_encoder'\n       writes: motor_position\n       reads:  -\n"));
  EXPECT_TRUE(Mentions(printed, "2. virtual sensor 'motor_velocity'\n       writes: motor_velocity\n"));
  EXPECT_TRUE(Mentions(printed, "3. module 'velocity_pid'\n       writes: velocity_controller_output\n"));
  EXPECT_TRUE(Mentions(printed, "motor_duty_command (last cycle) (no writer)"));
  EXPECT_TRUE(Mentions(printed, "thermal_derate (no writer)"));
  EXPECT_TRUE(DoesNotMention(printed, "motor_position (no writer)"));
  EXPECT_TRUE(Mentions(printed, "Not scheduled (write between cycles): 1\n  - external writer 'canopen_node'\n"));
  EXPECT_TRUE(Mentions(printed, "velocity_setpoint"));
}

}  // namespace
}  // namespace core
