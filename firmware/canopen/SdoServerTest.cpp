// SDO server: exact request/response frames, like canopen's test_sdo.py.
#include <cmath>
#include <limits>
#include <string>

#include "NodeTestSupport.hpp"
#include "ObjectTables.hpp"

namespace co::test {
namespace {

using board::FieldId;

class SdoServerTest : public NodeTest {};

std::array<std::uint8_t, 8> request(std::uint8_t command, std::uint16_t index, std::uint8_t sub,
                                    std::uint32_t data = 0) {
  const auto d = le32(data);
  return {command, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub,
          d[0], d[1], d[2], d[3]};
}

TEST_F(SdoServerTest, ExpeditedUploadOfDeviceTypeReturnsFourBytes) {
  EXPECT_EQ(sdo(request(0x40, 0x1000, 0)), request(0x43, 0x1000, 0, board::kNode.device_type));
}

TEST_F(SdoServerTest, ExpeditedUploadOfOneByteObjectIndicatesItsSize) {
  // 0x4F: expedited, size indicated, n = 3 unused bytes.
  EXPECT_EQ(sdo(request(0x40, 0x1001, 0)), request(0x4F, 0x1001, 0, 0));
}

TEST_F(SdoServerTest, IdentityObjectHoldsTableValuesAndSerialNumber) {
  EXPECT_EQ(upload(0x1018, 0), 4u);
  EXPECT_EQ(upload(0x1018, 1), board::kNode.vendor_id);
  EXPECT_EQ(upload(0x1018, 2), board::kNode.product_code);
  EXPECT_EQ(upload(0x1018, 3), board::kNode.revision);
  EXPECT_EQ(upload(0x1018, 4), kSerial);
}

TEST_F(SdoServerTest, SegmentedUploadOfDeviceNameAlternatesToggleAndEndsWithLastBit) {
  const std::string_view name = board::kNode.device_name;
  ASSERT_GT(name.size(), 4u) << "0x1008 must need a segmented upload for this test";
  EXPECT_EQ(sdo(request(0x40, 0x1008, 0)),
            request(0x41, 0x1008, 0, static_cast<std::uint32_t>(name.size())));
  std::string received;
  std::uint8_t toggle = 0;
  for (int segment = 0; segment < 20; ++segment) {
    const auto response = sdo({static_cast<std::uint8_t>(0x60 | toggle), 0, 0, 0, 0, 0, 0, 0});
    ASSERT_EQ(response[0] & 0xE0, 0x00) << "expected an upload segment response";
    ASSERT_EQ(response[0] & 0x10, toggle) << "server must echo the toggle bit";
    const std::size_t unused = (response[0] >> 1) & 0x7;
    received.append(response.begin() + 1, response.begin() + 1 + static_cast<long>(7 - unused));
    if (response[0] & 0x01) break;
    toggle ^= 0x10;
  }
  EXPECT_EQ(received, name);
  // The transfer is over: a further segment request is a protocol error.
  EXPECT_EQ(sdo({0x60, 0, 0, 0, 0, 0, 0, 0}),
            abort_data(0x1008, 0, SdoAbort::CommandSpecifierInvalid));
}

TEST_F(SdoServerTest, UploadSegmentWithToggleNotAlternatedAborts) {
  sdo(request(0x40, 0x1008, 0));
  ASSERT_EQ(sdo({0x60, 0, 0, 0, 0, 0, 0, 0})[0] & 0x10, 0);
  // Second segment must carry toggle 1; sending 0 again is an error.
  EXPECT_EQ(sdo({0x60, 0, 0, 0, 0, 0, 0, 0}),
            abort_data(0x1008, 0, SdoAbort::ToggleBitNotAlternated));
}

TEST_F(SdoServerTest, SegmentedDownloadInTwoSegmentsWritesTheField) {
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  const auto value = le32(float_bits(1.5f));
  EXPECT_EQ(sdo(request(0x21, index, 0, 4)), request(0x60, index, 0));
  // Segment 1: toggle 0, 3 data bytes (n = 4 unused), not last.
  EXPECT_EQ(sdo({0x08, value[0], value[1], value[2], 0, 0, 0, 0}),
            (std::array<std::uint8_t, 8>{0x20}));
  EXPECT_FLOAT_EQ(fields.values[FakeBoard::index(FieldId::velocity_setpoint)], 0.0f);
  // Segment 2: toggle 1, 1 data byte (n = 6 unused), last.
  EXPECT_EQ(sdo({0x1D, value[3], 0, 0, 0, 0, 0, 0}), (std::array<std::uint8_t, 8>{0x30}));
  EXPECT_FLOAT_EQ(fields.values[FakeBoard::index(FieldId::velocity_setpoint)], 1.5f);
}

TEST_F(SdoServerTest, DownloadSegmentWithToggleNotAlternatedAborts) {
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  sdo(request(0x21, index, 0, 4));
  EXPECT_EQ(sdo({0x08, 0, 0, 0, 0, 0, 0, 0})[0], 0x20);
  EXPECT_EQ(sdo({0x08, 0, 0, 0, 0, 0, 0, 0}), abort_data(index, 0, SdoAbort::ToggleBitNotAlternated));
}

TEST_F(SdoServerTest, SegmentedDownloadAnnouncingTooManyBytesAborts) {
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  EXPECT_EQ(sdo(request(0x21, index, 0, 5)), abort_data(index, 0, SdoAbort::LengthTooHigh));
}

TEST_F(SdoServerTest, SegmentedDownloadAnnouncingTooFewBytesAborts) {
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  EXPECT_EQ(sdo(request(0x21, index, 0, 2)), abort_data(index, 0, SdoAbort::LengthTooLow));
}

TEST_F(SdoServerTest, SegmentedDownloadSendingMoreThanTheObjectAborts) {
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  sdo(request(0x20, index, 0));  // size not indicated
  EXPECT_EQ(sdo({0x01, 1, 2, 3, 4, 5, 6, 7}), abort_data(index, 0, SdoAbort::LengthTooHigh));
}

TEST_F(SdoServerTest, SegmentedDownloadEndingShortOfAnnouncedSizeAbortsWithLengthMismatch) {
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  sdo(request(0x21, index, 0, 4));
  // Last segment after only 3 bytes (n = 4 unused).
  EXPECT_EQ(sdo({0x09, 1, 2, 3, 0, 0, 0, 0}), abort_data(index, 0, SdoAbort::LengthMismatch));
}

TEST_F(SdoServerTest, ExpeditedDownloadShorterThanObjectAbortsLengthTooLow) {
  EXPECT_EQ(download(index_of(FieldId::velocity_setpoint), 0, 0, 2), SdoAbort::LengthTooLow);
}

TEST_F(SdoServerTest, ExpeditedDownloadLongerThanObjectAbortsLengthTooHigh) {
  EXPECT_EQ(download(0x1017, 0, 100, 4), SdoAbort::LengthTooHigh);
}

TEST_F(SdoServerTest, ExpeditedDownloadWithoutSizeTakesTheObjectSize) {
  EXPECT_EQ(sdo(request(0x22, 0x1017, 0, 0xFFFF'0000u | 250u)), request(0x60, 0x1017, 0));
  EXPECT_EQ(upload(0x1017, 0), 250u);
}

TEST_F(SdoServerTest, ServerTimesOutWhenTheNextSegmentDoesNotCome) {
  sdo(request(0x40, 0x1008, 0));
  advance_us(SdoServer::kSegmentTimeoutUs - 1);
  EXPECT_TRUE(all_sent().empty());
  advance_us(1);
  const CanFrame frame = next_sent();
  EXPECT_EQ(frame.id, kSdoTx);
  EXPECT_EQ(frame.data, abort_data(0x1008, 0, SdoAbort::ProtocolTimedOut));
  EXPECT_EQ(sdo({0x60, 0, 0, 0, 0, 0, 0, 0}),
            abort_data(0x1008, 0, SdoAbort::CommandSpecifierInvalid));
}

TEST_F(SdoServerTest, SegmentsKeepTheTransferAliveAndTimeoutSurvivesClockWrap) {
  now_us = 0xFFFF'FF00u;
  sdo(request(0x40, 0x1008, 0));
  advance_us(SdoServer::kSegmentTimeoutUs / 2);  // wraps past zero
  EXPECT_EQ(sdo({0x60, 0, 0, 0, 0, 0, 0, 0})[0] & 0xE0, 0x00);
  advance_us(SdoServer::kSegmentTimeoutUs / 2 + 10);
  EXPECT_TRUE(all_sent().empty()) << "the segment restarted the timeout";
  advance_us(SdoServer::kSegmentTimeoutUs);
  EXPECT_EQ(next_sent().data, abort_data(0x1008, 0, SdoAbort::ProtocolTimedOut));
}

TEST_F(SdoServerTest, ClientAbortEndsTransferWithoutAnswer) {
  sdo(request(0x40, 0x1008, 0));
  receive(kSdoRx, {0x80, 0x08, 0x10, 0, 0, 0, 4, 5});
  EXPECT_TRUE(all_sent().empty());
  advance_us(2 * SdoServer::kSegmentTimeoutUs);
  EXPECT_TRUE(all_sent().empty()) << "no timeout for a transfer the client aborted";
}

TEST_F(SdoServerTest, MissingObjectAbortsObjectDoesNotExist) {
  EXPECT_EQ(upload_abort(0x1234, 0), SdoAbort::ObjectDoesNotExist);
  EXPECT_EQ(download(0x1234, 0, 1, 4), SdoAbort::ObjectDoesNotExist);
}

TEST_F(SdoServerTest, MissingSubIndexAbortsSubIndexDoesNotExist) {
  EXPECT_EQ(upload_abort(index_of(FieldId::velocity_setpoint), 1), SdoAbort::SubIndexDoesNotExist);
  EXPECT_EQ(upload_abort(0x1018, 5), SdoAbort::SubIndexDoesNotExist);
  EXPECT_EQ(upload_abort(0x1800, 4), SdoAbort::SubIndexDoesNotExist);
  EXPECT_EQ(upload_abort(0x1400, 4), SdoAbort::SubIndexDoesNotExist);
}

TEST_F(SdoServerTest, WriteToReadOnlyObjectAbortsReadOnly) {
  EXPECT_EQ(download(0x1000, 0, 0, 4), SdoAbort::ReadOnly);
  EXPECT_EQ(download_float(index_of(FieldId::motor_velocity), 1.0f), SdoAbort::ReadOnly);
  EXPECT_EQ(download(index_of(board::HilOutputId::motor_duty), 0, 0, 2), SdoAbort::ReadOnly);
  EXPECT_EQ(sdo(request(0x21, 0x1008, 0, 4)), abort_data(0x1008, 0, SdoAbort::ReadOnly));
}

TEST_F(SdoServerTest, FieldAboveMaximumAbortsValueTooHighAndIsNotClamped) {
  const FieldId id = FieldId::velocity_setpoint;
  const float above = std::nextafter(board::info(id).max, std::numeric_limits<float>::infinity());
  EXPECT_EQ(download_float(index_of(id), above), SdoAbort::ValueTooHigh);
  EXPECT_EQ(fields.writes[FakeBoard::index(id)], 0u);
}

TEST_F(SdoServerTest, FieldBelowMinimumAbortsValueTooLow) {
  const FieldId id = FieldId::velocity_setpoint;
  const float below = std::nextafter(board::info(id).min, -std::numeric_limits<float>::infinity());
  EXPECT_EQ(download_float(index_of(id), below), SdoAbort::ValueTooLow);
  EXPECT_EQ(fields.writes[FakeBoard::index(id)], 0u);
}

TEST_F(SdoServerTest, FieldAtItsLimitsIsAccepted) {
  const FieldId id = FieldId::velocity_setpoint;
  EXPECT_EQ(download_float(index_of(id), board::info(id).max), SdoAbort::None);
  EXPECT_EQ(download_float(index_of(id), board::info(id).min), SdoAbort::None);
  EXPECT_FLOAT_EQ(fields.values[FakeBoard::index(id)], board::info(id).min);
}

TEST_F(SdoServerTest, FaultReactionOptionTakesZeroToTwoAndRefusesTheRest) {
  const FieldId id = FieldId::fault_reaction_option_code;
  ASSERT_EQ(board::info(id).type, board::DataType::Integer16);
  for (const std::uint32_t option : {0u, 1u, 2u}) {
    EXPECT_EQ(download(index_of(id), 0, option, 2), SdoAbort::None) << option;
  }
  EXPECT_EQ(download(index_of(id), 0, 3, 2), SdoAbort::ValueTooHigh);
  EXPECT_EQ(download(index_of(id), 0, 0xFFFF, 2), SdoAbort::ValueTooLow);  // -1
  EXPECT_FLOAT_EQ(fields.values[FakeBoard::index(id)], 2.0f);
}

TEST_F(SdoServerTest, NotANumberAbortsValueRangeExceeded) {
  EXPECT_EQ(download_float(index_of(FieldId::velocity_setpoint),
                           std::numeric_limits<float>::quiet_NaN()),
            SdoAbort::ValueRangeExceeded);
}

TEST_F(SdoServerTest, WriteRefusedByTheBoardAbortsDataCannotBeStored) {
  const FieldId id = FieldId::velocity_setpoint;
  fields.refuse[FakeBoard::index(id)] = true;
  EXPECT_EQ(download_float(index_of(id), 1.0f), SdoAbort::DataCannotBeStored);
  EXPECT_EQ(node.counters().field_writes_refused, 1u);
}

TEST_F(SdoServerTest, FieldReadReturnsTheBoardValue) {
  fields.values[FakeBoard::index(FieldId::motor_velocity)] = -2.25f;
  EXPECT_EQ(upload(index_of(FieldId::motor_velocity), 0), float_bits(-2.25f));
}

TEST_F(SdoServerTest, HilInputWriteReachesTheDriverAndReadsBack) {
  const auto id = board::HilInputId::motor_current_adc;
  ASSERT_EQ(board::kHilInputs[static_cast<std::size_t>(id)].type, board::DataType::Integer16);
  EXPECT_EQ(download(index_of(id), 0, 0xFC18, 2), SdoAbort::None);  // -1000 mA
  EXPECT_EQ(hil.inputs[static_cast<std::size_t>(id)], -1000);
  EXPECT_EQ(upload(index_of(id), 0), 0xFC18u);
}

TEST_F(SdoServerTest, HilInputAboveItsRangeAbortsValueTooHigh) {
  const auto id = board::HilInputId::thermistor_adc;
  const board::IoInfo& io = board::kHilInputs[static_cast<std::size_t>(id)];
  ASSERT_LT(io.max, 0xFFFF) << "a 12-bit ADC in a U16 object";
  EXPECT_EQ(download(index_of(id), 0, static_cast<std::uint32_t>(io.max + 1), 2),
            SdoAbort::ValueTooHigh);
  EXPECT_EQ(hil.input_writes, 0u);
}

TEST_F(SdoServerTest, HilOutputIsReadWithItsOwnSize) {
  const auto id = board::HilOutputId::motor_duty;
  hil.outputs[static_cast<std::size_t>(id)] = -1234;
  // I16: 0x4B = expedited, size indicated, 2 unused bytes.
  EXPECT_EQ(sdo(request(0x40, index_of(id), 0)), request(0x4B, index_of(id), 0, 0xFB2E));
}

TEST_F(SdoServerTest, UnknownCommandSpecifierAborts) {
  EXPECT_EQ(sdo(request(0xE0, 0x1000, 0)), abort_data(0x1000, 0, SdoAbort::CommandSpecifierInvalid));
  EXPECT_EQ(sdo(request(0xFF, 0x1008, 0)), abort_data(0x1008, 0, SdoAbort::CommandSpecifierInvalid));
  EXPECT_EQ(node.counters().sdo_aborts_sent, 2u);
}

TEST_F(SdoServerTest, BlockTransferRequestsAreServed) {
  // Frame by frame in SdoBlockTest.cpp; here only that they are no longer refused.
  EXPECT_EQ(sdo(request(0xC6, 0x1000, 0, 4)),  // block download initiate: 0x1000 is read-only
            abort_data(0x1000, 0, SdoAbort::ReadOnly));
  EXPECT_EQ(sdo(request(0xA4, 0x1008, 0, 0x7F)),  // block upload initiate, blksize 127
            request(0xC6, 0x1008, 0, static_cast<std::uint32_t>(board::kNode.device_name.size())));
}

TEST_F(SdoServerTest, SegmentRequestWithoutTransferAborts) {
  EXPECT_EQ(sdo({0x00, 1, 2, 3, 4, 5, 6, 7})[0], 0x80);
  EXPECT_EQ(sdo({0x60, 0, 0, 0, 0, 0, 0, 0})[0], 0x80);
}

TEST_F(SdoServerTest, RequestShorterThanEightBytesIsIgnoredAsMalformed) {
  receive(kSdoRx, {0x40, 0x00, 0x10, 0x00});
  EXPECT_TRUE(all_sent().empty());
  EXPECT_EQ(node.counters().frames_malformed, 1u);
}

TEST_F(SdoServerTest, RequestsToOtherNodesAreNotAnswered) {
  receive(cia301::cob_id(cia301::FunctionCode::SdoRequest, kNodeId) + 1, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0});
  EXPECT_TRUE(all_sent().empty());
}

TEST_F(SdoServerTest, SyncCobIdRejectsProducerAndExtendedBits) {
  EXPECT_EQ(download(0x1005, 0, 0x4000'0080u, 4), SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(download(0x1005, 0, 0x2000'0080u, 4), SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(download(0x1005, 0, 0x81, 4), SdoAbort::None);
  EXPECT_EQ(upload(0x1005, 0), 0x81u);
}

TEST_F(SdoServerTest, SyncCobIdRefusesRestrictedIdsSoSdoStaysReachable) {
  // Regression (fuzz_canopen_frames): 0x1005 = 0x600+id made every later SDO request a SYNC.
  for (const std::uint32_t id : std::initializer_list<std::uint32_t>{kSdoRx, 0x000u, 0x07Fu, 0x101u, kSdoTx, 0x6E0u, cia301::cob_id(cia301::FunctionCode::Heartbeat, kNodeId)}) {
    EXPECT_EQ(download(0x1005, 0, id, 4), SdoAbort::ValueRangeExceeded)
        << "COB-ID 0x" << std::hex << id;
  }
  EXPECT_EQ(upload(0x1005, 0), 0x80u);  // unchanged, and the server still answers
  EXPECT_EQ(download(0x1005, 0, 0x80000080u, 4), SdoAbort::None);  // bit 31 is don't-care
  EXPECT_EQ(upload(0x1005, 0), 0x80000080u);
}

TEST_F(SdoServerTest, StringObjectsHoldTheTableStrings) {
  // Short strings come back expedited; check the size bits of whichever fits.
  const std::string_view sw = board::kNode.software_version;
  const auto response = sdo(request(0x40, 0x100A, 0));
  if (sw.size() <= 4) {
    EXPECT_EQ(response[0], 0x43 | ((4 - sw.size()) << 2));
    EXPECT_EQ(std::string(response.begin() + 4, response.begin() + 4 + static_cast<long>(sw.size())), sw);
  } else {
    EXPECT_EQ(response, request(0x41, 0x100A, 0, static_cast<std::uint32_t>(sw.size())));
  }
}

}  // namespace
}  // namespace co::test
