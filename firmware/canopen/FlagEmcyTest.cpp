// Latched fault bits -> EMCY frames, driven by the generated board::kFaultFlagsInfo.
#include "FlagEmcy.hpp"

#include <optional>
#include <string_view>

#include "NodeTestSupport.hpp"

namespace co::test {
namespace {

using board::FieldId;

const board::FlagInfo& fault(std::string_view name) {
  for (const board::FlagInfo& bit : board::kFaultFlagsInfo) {
    if (bit.name == name) return bit;
  }
  ADD_FAILURE() << "no fault bit " << name;
  return board::kFaultFlagsInfo[0];
}

class FlagEmcyTest : public NodeTest {
 protected:
  static std::uint8_t lo(std::uint16_t v) { return static_cast<std::uint8_t>(v); }
  static std::uint8_t hi(std::uint16_t v) { return static_cast<std::uint8_t>(v >> 8); }

  FlagEmcyReporter reporter{node, board::kFaultFlagsInfo};
};

TEST_F(FlagEmcyTest, LatchingABitReportsItsEmcyAboutItsObjectAndClearingResetsIt) {
  for (const board::FlagInfo& bit : board::kFaultFlagsInfo) {
    if (!bit.emcy || !bit.about_index) continue;
    SCOPED_TRACE(std::string(bit.name));
    const board::EmcyInfo& emcy = board::info(*bit.emcy);
    const auto register_bits = static_cast<std::uint8_t>(emcy.register_bit | error_register::kGeneric);
    reporter.update(bit.mask());
    EXPECT_EQ(next_sent(), make_frame(kEmcy, {lo(emcy.code), hi(emcy.code), register_bits, lo(*bit.about_index),
                                              hi(*bit.about_index), 0, 0, 0}));
    reporter.update(0);
    EXPECT_EQ(next_sent(), make_frame(kEmcy, {0, 0, 0, 0, 0, 0, 0, 0}));
    EXPECT_TRUE(all_sent().empty());
  }
}

// The frames the firmware sent before the fault bits came from board.toml: moving a bit in the
// table must not change what its fault looks like on the bus.
TEST_F(FlagEmcyTest, EachFaultKeepsItsCodeRegisterAndObject) {
  struct Expected {
    std::string_view fault;
    std::uint16_t code;
    std::uint8_t error_register;  // including the generic bit
    FieldId about;
  };
  for (const Expected& expected : {Expected{"motor_encoder_stale", 0x5000, 0x01, FieldId::motor_position},
                                   Expected{"output_encoder_stale", 0x5000, 0x01, FieldId::output_position},
                                   Expected{"thermistor_stale", 0x5000, 0x01, FieldId::thermistor_resistance},
                                   Expected{"over_temperature", 0x4210, 0x09, FieldId::winding_temperature},
                                   Expected{"command_watchdog", 0x8100, 0x11, FieldId::velocity_setpoint}}) {
    SCOPED_TRACE(std::string(expected.fault));
    const std::uint16_t index = index_of(expected.about);
    reporter.update(fault(expected.fault).mask());
    EXPECT_EQ(next_sent(), make_frame(kEmcy, {lo(expected.code), hi(expected.code), expected.error_register,
                                              lo(index), hi(index), 0, 0, 0}));
    reporter.update(0);
    all_sent();
  }
}

TEST_F(FlagEmcyTest, ABitWhoseRaiserNamesTheObjectSendsNothingButClearsEveryErrorOfItsCode) {
  const board::FlagInfo& ownership = fault("ownership_violation");
  ASSERT_TRUE(ownership.emcy.has_value());
  ASSERT_FALSE(ownership.about_index.has_value());
  // What the board's fault hook reports when it refuses a write.
  node.report_emcy(emcy::ownership_violation(FieldId::motor_duty_command));
  node.report_emcy(emcy::ownership_violation(FieldId::velocity_setpoint));
  all_sent();
  reporter.update(ownership.mask());
  EXPECT_TRUE(all_sent().empty());
  EXPECT_EQ(node.error_register(), error_register::kManufacturer | error_register::kGeneric);
  reporter.update(0);
  EXPECT_EQ(next_sent(), make_frame(kEmcy, {0, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_TRUE(all_sent().empty());
  EXPECT_EQ(node.error_register(), 0);
}

// The node reports a heartbeat event itself (it alone knows the lost node id); the fault bit the
// application latches for it sends nothing more, and clearing the bit clears the error.
TEST_F(FlagEmcyTest, TheHeartbeatBitLeavesTheReportToTheNodeAndClearsIt) {
  const board::FlagInfo& heartbeat = fault("master_heartbeat_lost");
  ASSERT_EQ(heartbeat.emcy, board::EmcyId::heartbeat_error);
  ASSERT_FALSE(heartbeat.about_index.has_value());
  node.report_emcy(emcy::heartbeat_error(0x01));
  EXPECT_EQ(next_sent(), make_frame(kEmcy, {0x30, 0x81, 0x11, 0x16, 0x10, 0x01, 0, 0}));
  reporter.update(heartbeat.mask());
  EXPECT_TRUE(all_sent().empty()) << "one EMCY per heartbeat event";
  reporter.update(0);
  EXPECT_EQ(next_sent(), make_frame(kEmcy, {0, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(node.error_register(), 0);
}

TEST_F(FlagEmcyTest, ReportsEachChangeOnceAndLeavesOtherBitsAlone) {
  const board::FlagInfo& motor = fault("motor_encoder_stale");
  const board::FlagInfo& output = fault("output_encoder_stale");
  reporter.update(motor.mask());
  EXPECT_EQ(all_sent().size(), 1u);
  reporter.update(motor.mask());
  EXPECT_TRUE(all_sent().empty()) << "still latched: nothing new";
  reporter.update(motor.mask() | output.mask());
  EXPECT_EQ(all_sent().size(), 1u) << "only the newly latched bit";
  reporter.update(output.mask());
  EXPECT_EQ(all_sent().size(), 1u) << "one error reset";
  EXPECT_EQ(node.error_register(), error_register::kGeneric) << "the output encoder error stays active";
}

TEST_F(FlagEmcyTest, ForgetReportsStillLatchedBitsAgainAfterResetNode) {
  const board::FlagInfo& hot = fault("over_temperature");
  reporter.update(hot.mask());
  all_sent();
  node.clear_all_emcy();
  all_sent();
  reporter.forget();
  reporter.update(hot.mask());
  EXPECT_EQ(all_sent().size(), 1u);
}

TEST_F(FlagEmcyTest, UnnamedBitsAreIgnored) {
  reporter.update(~board::kFaultFlagsMask);
  reporter.update(0);
  EXPECT_TRUE(all_sent().empty());
}

}  // namespace
}  // namespace co::test
