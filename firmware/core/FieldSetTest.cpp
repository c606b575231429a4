#include "core/FieldSet.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace core {
namespace {

using board::FieldId;

TEST(FieldSetTest, ContainsOnlyInsertedFields) {
  FieldSet set{FieldId::motor_position, FieldId::joint_torque};
  EXPECT_TRUE(set.contains(FieldId::motor_position));
  EXPECT_TRUE(set.contains(FieldId::joint_torque));
  EXPECT_FALSE(set.contains(FieldId::motor_velocity));
  EXPECT_EQ(set.size(), 2u);
  set.erase(FieldId::motor_position);
  EXPECT_FALSE(set.contains(FieldId::motor_position));
  EXPECT_EQ(set.size(), 1u);
}

TEST(FieldSetTest, VisitsMembersInFieldIdOrder) {
  const FieldSet set{FieldId::joint_torque, FieldId::motor_position, FieldId::velocity_kp};
  std::vector<FieldId> visited;
  set.for_each([&](FieldId id) { visited.push_back(id); });
  EXPECT_EQ(visited, (std::vector<FieldId>{FieldId::motor_position, FieldId::joint_torque, FieldId::velocity_kp}));
}

TEST(FieldSetTest, IgnoresIdsOutsideTheTable) {
  FieldSet set;
  set.insert(static_cast<FieldId>(board::kFieldCount));
  EXPECT_TRUE(set.empty());
  EXPECT_FALSE(set.contains(static_cast<FieldId>(board::kFieldCount)));
}

TEST(FieldSetTest, BusWritableFieldsAreExactlyTheReadWriteFields) {
  std::size_t read_write = 0;
  for (std::size_t i = 0; i < board::kFieldCount; ++i) {
    const bool is_rw = board::kFields[i].access == board::Access::ReadWrite;
    read_write += is_rw ? 1 : 0;
    EXPECT_EQ(kBusWritableFields.contains(static_cast<FieldId>(i)), is_rw) << board::kFields[i].name;
  }
  EXPECT_EQ(kBusWritableFields.size(), read_write);
  EXPECT_TRUE(kBusWritableFields.contains(FieldId::velocity_setpoint));
  EXPECT_FALSE(kBusWritableFields.contains(FieldId::motor_velocity));
}

TEST(FieldSetTest, UnionAndIntersection) {
  const FieldSet a{FieldId::motor_position, FieldId::motor_velocity};
  const FieldSet b{FieldId::motor_velocity, FieldId::joint_torque};
  EXPECT_EQ(a | b, (FieldSet{FieldId::motor_position, FieldId::motor_velocity, FieldId::joint_torque}));
  EXPECT_EQ(a & b, FieldSet{FieldId::motor_velocity});
}

}  // namespace
}  // namespace core
