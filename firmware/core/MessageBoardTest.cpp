#include "core/MessageBoard.hpp"

#include <gtest/gtest.h>

#include <vector>

#include "core/MessageBoardUser.hpp"

namespace core {
namespace {

using board::FieldId;

// A component whose writes the test triggers by hand.
class ManualVirtualSensor final : public VirtualSensor {
 public:
  ManualVirtualSensor(MessageBoard& board, std::string_view name, const Declarations& declarations)
      : VirtualSensor(board, name, declarations) {}
  void update() override {}
  SetResult write(FieldId id, float value) { return boardSet(id, value); }
  float read(FieldId id) const { return boardGet(id); }
  bool holds(FieldId id) const { return boardHas(id); }
};

class NodeStandIn final : public ExternalWriter {
 public:
  explicit NodeStandIn(MessageBoard& board) : ExternalWriter(board, "canopen_node", {.writes = kBusWritableFields}) {}
  SetResult write(FieldId id, float value) { return boardSet(id, value); }
};

struct RecordedViolations {
  std::vector<WriteViolation> seen;
  static void record(void* context, const WriteViolation& violation) {
    static_cast<RecordedViolations*>(context)->seen.push_back(violation);
  }
};

class MessageBoardTest : public ::testing::Test {
 protected:
  MessageBoardTest() {
    EXPECT_TRUE(board.claim_writes(velocity));
    EXPECT_TRUE(board.claim_writes(torque));
    board.set_fault_hook({&RecordedViolations::record, &violations});
  }

  MessageBoard board;
  ManualVirtualSensor velocity{board, "motor_velocity_estimator", {.writes = {FieldId::motor_velocity}}};
  ManualVirtualSensor torque{board, "joint_torque_estimator", {.writes = {FieldId::joint_torque}}};
  RecordedViolations violations;
};

TEST_F(MessageBoardTest, StoresValueWrittenByOwner) {
  EXPECT_EQ(velocity.write(FieldId::motor_velocity, 12.5f), SetResult::Ok);
  EXPECT_FLOAT_EQ(board.get(FieldId::motor_velocity), 12.5f);
  EXPECT_FLOAT_EQ(torque.read(FieldId::motor_velocity), 12.5f);
}

TEST_F(MessageBoardTest, HasOnlyFieldsWrittenAtLeastOnce) {
  EXPECT_FALSE(board.has(FieldId::motor_velocity));
  velocity.write(FieldId::motor_velocity, 0.0f);
  EXPECT_TRUE(board.has(FieldId::motor_velocity));
  EXPECT_TRUE(torque.holds(FieldId::motor_velocity));
  EXPECT_FALSE(board.has(FieldId::joint_torque));
}

TEST_F(MessageBoardTest, StartsEveryFieldAtItsTableDefault) {
  for (std::size_t i = 0; i < board::kFieldCount; ++i) {
    EXPECT_EQ(board.get(static_cast<FieldId>(i)), board::kFields[i].default_value) << board::kFields[i].name;
  }
}

TEST_F(MessageBoardTest, RefusesWriteFromNonOwner) {
  velocity.write(FieldId::motor_velocity, 1.0f);
  EXPECT_EQ(torque.write(FieldId::motor_velocity, 99.0f), SetResult::NotOwner);
  EXPECT_FLOAT_EQ(board.get(FieldId::motor_velocity), 1.0f);
  EXPECT_EQ(board.refused_writes(FieldId::motor_velocity), 1u);
  EXPECT_EQ(board.refused_writes(FieldId::joint_torque), 0u);
  EXPECT_EQ(board.total_refused_writes(), 1u);
}

TEST_F(MessageBoardTest, RefusesWriteOfUndeclaredFieldWithoutOwner) {
  EXPECT_EQ(velocity.write(FieldId::output_velocity, 3.0f), SetResult::NotOwner);
  EXPECT_FALSE(board.has(FieldId::output_velocity));
  EXPECT_EQ(board.refused_writes(FieldId::output_velocity), 1u);
}

TEST_F(MessageBoardTest, ReportsRefusedWriteThroughFaultHook) {
  board.begin_cycle(41);
  torque.write(FieldId::motor_velocity, 5.0f);
  ASSERT_EQ(violations.seen.size(), 1u);
  const WriteViolation& violation = violations.seen.front();
  EXPECT_EQ(violation.reason, SetResult::NotOwner);
  EXPECT_EQ(violation.field, FieldId::motor_velocity);
  EXPECT_EQ(violation.offender, &torque);
  EXPECT_EQ(violation.owner, &velocity);
  EXPECT_EQ(violation.cycle, 41u);
}

TEST_F(MessageBoardTest, RefusesFieldIdOutsideTheTable) {
  const auto bogus = static_cast<FieldId>(board::kFieldCount + 3);
  EXPECT_EQ(velocity.write(bogus, 1.0f), SetResult::UnknownField);
  EXPECT_EQ(board.total_refused_writes(), 1u);
  ASSERT_EQ(violations.seen.size(), 1u);
  EXPECT_EQ(violations.seen.front().reason, SetResult::UnknownField);
  EXPECT_EQ(violations.seen.front().owner, nullptr);
  EXPECT_FALSE(board.has(bogus));
  EXPECT_EQ(board.refused_writes(bogus), 0u);
}

TEST_F(MessageBoardTest, CountsRefusalsWithoutFaultHook) {
  board.set_fault_hook({});
  torque.write(FieldId::motor_velocity, 5.0f);
  torque.write(FieldId::motor_velocity, 6.0f);
  EXPECT_EQ(board.refused_writes(FieldId::motor_velocity), 2u);
  EXPECT_TRUE(violations.seen.empty());
}

TEST_F(MessageBoardTest, RejectsSecondClaimOfOwnedFieldNamingBothComponents) {
  ManualVirtualSensor intruder{board, "second_velocity_estimator",
                               {.writes = {FieldId::output_velocity, FieldId::motor_velocity}}};
  const StartupStatus status = board.claim_writes(intruder);
  EXPECT_EQ(status.error(), StartupError::DuplicateWriter);
  EXPECT_NE(status.message().find("'motor_velocity'"), std::string::npos) << status.message();
  EXPECT_NE(status.message().find("motor_velocity_estimator"), std::string::npos) << status.message();
  EXPECT_NE(status.message().find("second_velocity_estimator"), std::string::npos) << status.message();
  // Nothing of a failed claim is registered.
  EXPECT_EQ(board.owner(FieldId::output_velocity), nullptr);
  EXPECT_EQ(board.owner(FieldId::motor_velocity), &velocity);
}

TEST_F(MessageBoardTest, RecordsCycleOfLastWrite) {
  board.begin_cycle(7);
  velocity.write(FieldId::motor_velocity, 1.0f);
  board.begin_cycle(9);
  EXPECT_EQ(board.last_write_cycle(FieldId::motor_velocity), 7u);
  velocity.write(FieldId::motor_velocity, 2.0f);
  EXPECT_EQ(board.last_write_cycle(FieldId::motor_velocity), 9u);
}

TEST_F(MessageBoardTest, FieldIsStaleWhenLastWriteIsOlderThanMaxAge) {
  board.begin_cycle(100);
  velocity.write(FieldId::motor_velocity, 1.0f);
  board.begin_cycle(120);
  EXPECT_FALSE(board.is_stale(FieldId::motor_velocity, 20));
  board.begin_cycle(121);
  EXPECT_TRUE(board.is_stale(FieldId::motor_velocity, 20));
}

TEST_F(MessageBoardTest, NeverWrittenFieldIsStale) {
  EXPECT_TRUE(board.is_stale(FieldId::motor_velocity, 1000));
}

TEST_F(MessageBoardTest, StalenessSurvivesCycleCounterWrapAround) {
  board.begin_cycle(0xFFFF'FFF0u);
  velocity.write(FieldId::motor_velocity, 1.0f);
  board.begin_cycle(0x0000'0004u);  // 20 cycles later
  EXPECT_FALSE(board.is_stale(FieldId::motor_velocity, 20));
  EXPECT_TRUE(board.is_stale(FieldId::motor_velocity, 19));
}

TEST_F(MessageBoardTest, ListsWrittenFieldsInFieldOrder) {
  torque.write(FieldId::joint_torque, 4.0f);
  velocity.write(FieldId::motor_velocity, 2.0f);
  std::vector<std::pair<FieldId, float>> listed;
  board.for_each_written([&](FieldId id, float value) { listed.emplace_back(id, value); });
  const std::vector<std::pair<FieldId, float>> expected{{FieldId::motor_velocity, 2.0f}, {FieldId::joint_torque, 4.0f}};
  EXPECT_EQ(listed, expected);
  EXPECT_EQ(board.written_fields().size(), 2u);
}

TEST_F(MessageBoardTest, ExternalWriterOwnsBusWritableFields) {
  NodeStandIn node{board};
  ASSERT_TRUE(board.claim_writes(node));
  EXPECT_EQ(node.write(FieldId::velocity_setpoint, 3.0f), SetResult::Ok);
  EXPECT_EQ(node.write(FieldId::velocity_kp, 0.5f), SetResult::Ok);
  EXPECT_FLOAT_EQ(board.get(FieldId::velocity_setpoint), 3.0f);
  EXPECT_EQ(node.write(FieldId::motor_velocity, 1.0f), SetResult::NotOwner);
  EXPECT_EQ(velocity.write(FieldId::velocity_setpoint, 1.0f), SetResult::NotOwner);
  EXPECT_FLOAT_EQ(board.get(FieldId::velocity_setpoint), 3.0f);
}

TEST_F(MessageBoardTest, ClaimingOwnFieldsAgainSucceeds) {
  EXPECT_TRUE(board.claim_writes(velocity));
  EXPECT_EQ(board.owner(FieldId::motor_velocity), &velocity);
}

}  // namespace
}  // namespace core
