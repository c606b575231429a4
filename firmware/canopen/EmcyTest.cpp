// EMCY producer (CiA 301, 7.2.7): frame content, error register, 0x1003 history, clearing.
#include "NodeTestSupport.hpp"

namespace co::test {
namespace {

using board::FieldId;

class EmcyTest : public NodeTest {
 protected:
  static std::uint8_t lo(std::uint16_t v) { return static_cast<std::uint8_t>(v); }
  static std::uint8_t hi(std::uint16_t v) { return static_cast<std::uint8_t>(v >> 8); }
};

TEST_F(EmcyTest, ReportSendsCodeErrorRegisterAndManufacturerBytes) {
  const std::uint16_t index = index_of(FieldId::winding_temperature);
  EXPECT_TRUE(node.report_emcy(emcy::over_temperature(FieldId::winding_temperature)));
  // 0x4210, register = generic | temperature, manufacturer = the field's index.
  EXPECT_EQ(next_sent(), make_frame(kEmcy, {0x10, 0x42, 0x09, lo(index), hi(index), 0, 0, 0}));
  EXPECT_EQ(upload(0x1001, 0), 0x09u);
  EXPECT_EQ(node.counters().emcy_sent, 1u);
}

TEST_F(EmcyTest, HelpersUseTheDocumentedCodesAndRegisterBits) {
  const auto owner = emcy::ownership_violation(FieldId::velocity_setpoint);
  EXPECT_EQ(owner.code, 0xFF00);
  EXPECT_EQ(owner.register_bits, error_register::kManufacturer);
  EXPECT_EQ(owner.manufacturer[0], lo(index_of(FieldId::velocity_setpoint)));
  EXPECT_EQ(owner.manufacturer[1], hi(index_of(FieldId::velocity_setpoint)));
  EXPECT_EQ(emcy::stale_sensor(FieldId::motor_position).code, 0x5000);
  EXPECT_EQ(emcy::receive_overrun(0x1400).code, 0x8110);
  EXPECT_EQ(emcy::receive_overrun(0x1400).register_bits, error_register::kCommunication);
  EXPECT_EQ(emcy::pdo_length_error(0x1401).code, 0x8210);
  EXPECT_EQ(emcy::pdo_length_error(0x1401).manufacturer[0], 0x01);
}

TEST_F(EmcyTest, RawOverloadBuildsTheSameFrame) {
  EXPECT_TRUE(node.report_emcy(0x1234, error_register::kVoltage, {1, 2, 3, 4, 5}));
  EXPECT_EQ(next_sent(), make_frame(kEmcy, {0x34, 0x12, 0x05, 1, 2, 3, 4, 5}));
}

TEST_F(EmcyTest, ReportingAnActiveErrorAgainSendsNothing) {
  const auto error = emcy::stale_sensor(FieldId::motor_position);
  EXPECT_TRUE(node.report_emcy(error));
  all_sent();
  EXPECT_FALSE(node.report_emcy(error));
  EXPECT_TRUE(all_sent().empty());
  EXPECT_EQ(upload(0x1003, 0), 1u);
  // The same code about another object is a new error.
  EXPECT_TRUE(node.report_emcy(emcy::stale_sensor(FieldId::motor_velocity)));
  EXPECT_EQ(all_sent().size(), 1u);
}

TEST_F(EmcyTest, HistoryIsNewestFirstWithTheObjectIndexInTheUpperHalf) {
  node.report_emcy(emcy::stale_sensor(FieldId::motor_position));
  node.report_emcy(emcy::over_temperature(FieldId::winding_temperature));
  all_sent();
  EXPECT_EQ(upload(0x1003, 0), 2u);
  EXPECT_EQ(upload(0x1003, 1), 0x4210u | (std::uint32_t{index_of(FieldId::winding_temperature)} << 16));
  EXPECT_EQ(upload(0x1003, 2), 0x5000u | (std::uint32_t{index_of(FieldId::motor_position)} << 16));
  EXPECT_EQ(upload(0x1003, 3), 0u);
}

TEST_F(EmcyTest, HistoryKeepsTheNewestEight) {
  for (std::uint16_t code = 1; code <= 10; ++code) {
    node.report_emcy(static_cast<std::uint16_t>(0x1000 + code), 0, {});
  }
  EXPECT_EQ(all_sent().size(), 10u);
  EXPECT_EQ(upload(0x1003, 0), Node::kErrorHistoryDepth);
  EXPECT_EQ(upload(0x1003, 1) & 0xFFFF, 0x100Au);
  EXPECT_EQ(upload(0x1003, 8) & 0xFFFF, 0x1003u);
  EXPECT_EQ(upload_abort(0x1003, 9), SdoAbort::SubIndexDoesNotExist);
}

TEST_F(EmcyTest, WritingZeroToTheCountClearsTheHistoryAndOtherValuesAbort) {
  node.report_emcy(emcy::stale_sensor(FieldId::motor_position));
  all_sent();
  EXPECT_EQ(download(0x1003, 0, 1, 1), SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(download(0x1003, 1, 0, 4), SdoAbort::ReadOnly);
  EXPECT_EQ(download(0x1003, 0, 0, 1), SdoAbort::None);
  EXPECT_EQ(upload(0x1003, 0), 0u);
  EXPECT_EQ(upload(0x1003, 1), 0u);
}

TEST_F(EmcyTest, ClearingSendsErrorResetAndClearsTheRegister) {
  node.report_emcy(emcy::over_temperature(FieldId::winding_temperature));
  all_sent();
  EXPECT_TRUE(node.clear_emcy(board::emcy_code::kOverTemperature));
  EXPECT_EQ(next_sent(), make_frame(kEmcy, {0, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(node.error_register(), 0);
  EXPECT_FALSE(node.clear_emcy(board::emcy_code::kOverTemperature)) << "nothing left to clear";
  EXPECT_TRUE(all_sent().empty());
  EXPECT_EQ(upload(0x1003, 0), 1u) << "clearing keeps the history";
}

TEST_F(EmcyTest, ClearingOneErrorKeepsTheRegisterBitsOfTheOthers) {
  node.report_emcy(emcy::over_temperature(FieldId::winding_temperature));
  node.report_emcy(emcy::ownership_violation(FieldId::velocity_setpoint));
  EXPECT_EQ(node.error_register(), 0x89);
  all_sent();
  EXPECT_TRUE(node.clear_emcy(emcy::over_temperature(FieldId::winding_temperature)));
  EXPECT_EQ(next_sent(), make_frame(kEmcy, {0, 0, 0x81, 0, 0, 0, 0, 0}));
  EXPECT_TRUE(node.clear_all_emcy());
  EXPECT_EQ(next_sent(), make_frame(kEmcy, {0, 0, 0, 0, 0, 0, 0, 0}));
}

TEST_F(EmcyTest, StoppedNodeRecordsButDoesNotSend) {
  nmt(NmtCommand::Stop);
  EXPECT_TRUE(node.report_emcy(emcy::stale_sensor(FieldId::motor_position)));
  EXPECT_TRUE(all_sent().empty());
  EXPECT_EQ(node.error_register(), error_register::kGeneric);
  nmt(NmtCommand::EnterPreOperational);
  EXPECT_EQ(upload(0x1003, 0), 1u);
}

TEST_F(EmcyTest, EmcyCobIdObjectNamesTheProducerId) {
  EXPECT_EQ(upload(0x1014, 0), kEmcy);
}

}  // namespace
}  // namespace co::test
