// SDO block upload and download (CiA 301, 7.2.4.3.9 to 7.2.4.3.16): exact frames, first
// through a Node and its object dictionary, then against the server alone with a test-only
// object dictionary that holds values larger than the server's buffer.
#include <cstring>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "BlockCrcReference.hpp"
#include "NodeTestSupport.hpp"
#include "ObjectTables.hpp"

namespace co::test {
namespace {

using board::FieldId;
using Frame = std::array<std::uint8_t, 8>;

using co::test::reference_crc;  // BlockCrcReference.hpp; the overload below takes text

std::uint16_t reference_crc(std::string_view text) {
  return reference_crc(std::span(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
}

std::uint16_t crc_of(const Frame& frame) {
  return static_cast<std::uint16_t>(frame[1] | (frame[2] << 8));
}

std::uint32_t size_of(const Frame& frame) {
  return frame[4] | (frame[5] << 8) | (frame[6] << 16) | (std::uint32_t{frame[7]} << 24);
}

Frame with_multiplexer(std::uint8_t command, std::uint16_t index, std::uint8_t sub,
                       std::uint8_t b4 = 0, std::uint8_t b5 = 0, std::uint8_t b6 = 0,
                       std::uint8_t b7 = 0) {
  return {command, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub,
          b4, b5, b6, b7};
}

Frame initiate_block_upload(std::uint16_t index, std::uint8_t sub, std::uint8_t blksize,
                            std::uint8_t pst = 0, bool crc = true) {
  return with_multiplexer(static_cast<std::uint8_t>(0xA0 | (crc ? 0x04 : 0)), index, sub, blksize,
                          pst);
}

Frame initiate_block_download(std::uint16_t index, std::uint8_t sub, std::uint32_t size,
                              bool crc = true, bool size_indicated = true) {
  const auto s = le32(size);
  return with_multiplexer(
      static_cast<std::uint8_t>(0xC0 | (crc ? 0x04 : 0) | (size_indicated ? 0x02 : 0)), index, sub,
      size_indicated ? s[0] : 0, size_indicated ? s[1] : 0, size_indicated ? s[2] : 0,
      size_indicated ? s[3] : 0);
}

// A block download segment: sequence number, last bit, up to 7 data bytes.
Frame segment(std::uint8_t sequence, bool last, std::span<const std::uint8_t> data) {
  Frame frame{static_cast<std::uint8_t>(sequence | (last ? 0x80 : 0))};
  std::copy(data.begin(), data.end(), frame.begin() + 1);
  return frame;
}

Frame end_block_download(std::size_t unused, std::uint16_t crc) {
  return {static_cast<std::uint8_t>(0xC1 | (unused << 2)), static_cast<std::uint8_t>(crc),
          static_cast<std::uint8_t>(crc >> 8)};
}

Frame block_ack(std::uint8_t ackseq, std::uint8_t blksize) { return {0xA2, ackseq, blksize}; }

constexpr Frame kStartUpload{0xA3};
constexpr Frame kEndUpload{0xA1};
constexpr Frame kClientAbort{0x80, 0, 0, 0, 0, 0, 0, 0};

TEST(SdoBlockCrc, ReferenceCrcHasTheCheckValueOfCrc16Ccitt) {
  // The published check value of CRC-16/XMODEM, the CRC CiA 301 uses, and python-canopen's
  // binascii.crc_hqx of the same bytes.
  EXPECT_EQ(reference_crc("123456789"), 0x31C3);
  EXPECT_EQ(reference_crc("hil-joint-firmware"), 0xF6EB);
}

// --- Through the node and its object dictionary ----------------------------------------------

class SdoBlockTest : public NodeTest {
 protected:
  // One request and everything the node sends for it: the answer, if any, and every segment
  // that follows, polling as the platform loop does (no time passes).
  std::vector<Frame> exchange(const Frame& request) {
    CanFrame frame;
    frame.id = kSdoRx;
    frame.len = 8;
    frame.data = request;
    node.process(frame, now_us);
    std::vector<Frame> out;
    for (int polls = 0; polls < 100; ++polls) {
      const std::vector<CanFrame> sent = all_sent();
      if (sent.empty()) break;
      for (const CanFrame& f : sent) {
        EXPECT_EQ(f.id, kSdoTx);
        EXPECT_EQ(f.len, 8);
        out.push_back(f.data);
      }
      node.poll(now_us);
    }
    return out;
  }

  // A request the server must not answer (a segment inside a sub-block, a client abort...).
  void silent(const Frame& request) {
    EXPECT_TRUE(exchange(request).empty()) << "expected no answer to 0x" << std::hex
                                           << int{request[0]};
  }

  // Block upload of `index`/`sub` with `blksize` segments per sub-block; returns the value
  // and checks every frame on the way, the CRC against the reference.
  std::string block_upload(std::uint16_t index, std::uint8_t sub, std::uint8_t blksize) {
    const Frame initiate = sdo(initiate_block_upload(index, sub, blksize));
    EXPECT_EQ(initiate[0], 0xC6) << "block upload response with CRC support and size";
    const std::size_t size = size_of(initiate);
    std::string value;
    std::vector<Frame> segments = exchange(kStartUpload);
    for (int sub_blocks = 0; sub_blocks < 50; ++sub_blocks) {
      EXPECT_FALSE(segments.empty());
      std::uint8_t expected_sequence = 1;
      bool last = false;
      for (const Frame& s : segments) {
        EXPECT_EQ(s[0] & 0x7F, expected_sequence++);
        last = (s[0] & 0x80) != 0;
        value.append(s.begin() + 1, s.end());
      }
      EXPECT_TRUE(last || segments.size() == blksize) << "a sub-block stops at blksize or the end";
      const std::vector<Frame> next =
          exchange(block_ack(static_cast<std::uint8_t>(segments.size()), blksize));
      if (last) {
        EXPECT_EQ(next.size(), 1u);
        if (next.empty()) return {};
        const Frame end = next.front();
        EXPECT_EQ(end[0] & 0xE3, 0xC1) << "end block upload";
        value.resize(value.size() - ((end[0] >> 2) & 0x7));
        EXPECT_EQ(value.size(), size);
        EXPECT_EQ(crc_of(end), reference_crc(value));
        silent(kEndUpload);
        return value;
      }
      segments = next;
    }
    ADD_FAILURE() << "block upload did not end";
    return value;
  }
};

TEST_F(SdoBlockTest, UploadOfDeviceNameIsOneSubBlockWithCrc) {
  const std::string_view name = board::kNode.device_name;
  ASSERT_EQ(name, "hil-joint-firmware") << "frames below are spelled out for this name";
  EXPECT_EQ(sdo(initiate_block_upload(0x1008, 0, 127)),
            with_multiplexer(0xC6, 0x1008, 0, static_cast<std::uint8_t>(name.size())));
  const std::vector<Frame> segments = exchange(kStartUpload);
  ASSERT_EQ(segments.size(), 3u);
  EXPECT_EQ(segments[0], (Frame{0x01, 'h', 'i', 'l', '-', 'j', 'o', 'i'}));
  EXPECT_EQ(segments[1], (Frame{0x02, 'n', 't', '-', 'f', 'i', 'r', 'm'}));
  EXPECT_EQ(segments[2], (Frame{0x83, 'w', 'a', 'r', 'e', 0, 0, 0}));
  // n = 3 unused bytes in the last segment, CRC little-endian.
  EXPECT_EQ(sdo(block_ack(3, 127)), (Frame{0xCD, 0xEB, 0xF6}));
  silent(kEndUpload);
  EXPECT_EQ(node.counters().sdo_aborts_sent, 0u);
  advance_us(2 * SdoServer::kSegmentTimeoutUs);
  EXPECT_TRUE(all_sent().empty()) << "the transfer is over: nothing to time out";
}

TEST_F(SdoBlockTest, UploadWithoutClientCrcSendsZeroCrc) {
  // The server still says it supports CRC (sc); only both together use it.
  EXPECT_EQ(sdo(initiate_block_upload(0x1008, 0, 127, 0, false))[0], 0xC6);
  EXPECT_EQ(exchange(kStartUpload).size(), 3u);
  EXPECT_EQ(sdo(block_ack(3, 127)), (Frame{0xCD, 0, 0}));
  silent(kEndUpload);
}

TEST_F(SdoBlockTest, UploadInSubBlocksOfOneAndTwoSegments) {
  EXPECT_EQ(block_upload(0x1008, 0, 1), board::kNode.device_name);
  EXPECT_EQ(block_upload(0x1008, 0, 2), board::kNode.device_name);
  EXPECT_EQ(block_upload(0x1009, 0, 127), board::kNode.hardware_version);
}

TEST_F(SdoBlockTest, UploadOfFourByteObjectIsABlockOfOneSegment) {
  const std::string value = block_upload(0x1018, 1, 127);
  ASSERT_EQ(value.size(), 4u);
  std::uint32_t vendor = 0;
  std::memcpy(&vendor, value.data(), 4);
  EXPECT_EQ(vendor, board::kNode.vendor_id);
}

TEST_F(SdoBlockTest, UploadRepeatsTheSegmentsAfterTheLastOneAcknowledged) {
  sdo(initiate_block_upload(0x1008, 0, 127));
  ASSERT_EQ(exchange(kStartUpload).size(), 3u);
  // Segment 2 was lost: the client acknowledges 1, the server repeats from byte 7 as 1, 2.
  const std::vector<Frame> repeated = exchange(block_ack(1, 127));
  ASSERT_EQ(repeated.size(), 2u);
  EXPECT_EQ(repeated[0], (Frame{0x01, 'n', 't', '-', 'f', 'i', 'r', 'm'}));
  EXPECT_EQ(repeated[1], (Frame{0x82, 'w', 'a', 'r', 'e', 0, 0, 0}));
  // The CRC still covers each byte once.
  EXPECT_EQ(sdo(block_ack(2, 127)), (Frame{0xCD, 0xEB, 0xF6}));
  silent(kEndUpload);
}

TEST_F(SdoBlockTest, UploadAckOfNothingRepeatsTheWholeSubBlock) {
  sdo(initiate_block_upload(0x1008, 0, 2));
  ASSERT_EQ(exchange(kStartUpload).size(), 2u);
  const std::vector<Frame> repeated = exchange(block_ack(0, 127));
  ASSERT_EQ(repeated.size(), 3u) << "the new blksize applies to the repeat";
  EXPECT_EQ(repeated[0][1], 'h');
  EXPECT_EQ(sdo(block_ack(3, 127))[0], 0xCD);
}

TEST_F(SdoBlockTest, ProtocolSwitchThresholdAtOrAboveTheSizeFallsBackToSegmentedUpload) {
  const auto size = static_cast<std::uint8_t>(board::kNode.device_name.size());
  EXPECT_EQ(sdo(initiate_block_upload(0x1008, 0, 127, size)), with_multiplexer(0x41, 0x1008, 0, size));
  // Then the normal segmented protocol.
  const Frame first = sdo({0x60});
  EXPECT_EQ(first, (Frame{0x00, 'h', 'i', 'l', '-', 'j', 'o', 'i'}));
  EXPECT_EQ(sdo({0x70})[0], 0x10);
  EXPECT_EQ(sdo({0x60}), (Frame{0x07, 'w', 'a', 'r', 'e', 0, 0, 0}));  // n = 3, last
  // One byte below the size: block upload after all.
  EXPECT_EQ(sdo(initiate_block_upload(0x1008, 0, 127, static_cast<std::uint8_t>(size - 1)))[0], 0xC6);
}

TEST_F(SdoBlockTest, ProtocolSwitchToExpeditedUploadForSmallValues) {
  const auto type = le32(board::kNode.device_type);
  EXPECT_EQ(sdo(initiate_block_upload(0x1000, 0, 127, 4)),
            with_multiplexer(0x43, 0x1000, 0, type[0], type[1], type[2], type[3]));
  EXPECT_EQ(sdo({0x60}), abort_data(0x1000, 0, SdoAbort::CommandSpecifierInvalid))
      << "an expedited upload leaves nothing open";
}

TEST_F(SdoBlockTest, UploadBlockSizeZeroOrAbove127Aborts) {
  EXPECT_EQ(sdo(initiate_block_upload(0x1008, 0, 0)), abort_data(0x1008, 0, SdoAbort::InvalidBlockSize));
  EXPECT_EQ(sdo(initiate_block_upload(0x1008, 0, 128)), abort_data(0x1008, 0, SdoAbort::InvalidBlockSize));
  sdo(initiate_block_upload(0x1008, 0, 1));
  ASSERT_EQ(exchange(kStartUpload).size(), 1u);
  EXPECT_EQ(sdo(block_ack(1, 0)), abort_data(0x1008, 0, SdoAbort::InvalidBlockSize));
  sdo(initiate_block_upload(0x1008, 0, 1));
  ASSERT_EQ(exchange(kStartUpload).size(), 1u);
  EXPECT_EQ(sdo(block_ack(1, 200)), abort_data(0x1008, 0, SdoAbort::InvalidBlockSize));
}

TEST_F(SdoBlockTest, UploadAckOfSegmentsNotSentAbortsInvalidSequenceNumber) {
  sdo(initiate_block_upload(0x1008, 0, 2));
  ASSERT_EQ(exchange(kStartUpload).size(), 2u);
  EXPECT_EQ(sdo(block_ack(3, 127)), abort_data(0x1008, 0, SdoAbort::InvalidSequenceNumber));
  EXPECT_EQ(node.counters().sdo_aborts_sent, 1u);
}

TEST_F(SdoBlockTest, UploadOfMissingOrWriteOnlyObjectAbortsWithTheObjectsCode) {
  EXPECT_EQ(sdo(initiate_block_upload(0x1234, 0, 127)), abort_data(0x1234, 0, SdoAbort::ObjectDoesNotExist));
  EXPECT_EQ(sdo(initiate_block_upload(0x1018, 9, 127)), abort_data(0x1018, 9, SdoAbort::SubIndexDoesNotExist));
}

TEST_F(SdoBlockTest, UploadCommandsOutOfTurnAbortCommandSpecifierInvalid) {
  EXPECT_EQ(sdo(kStartUpload), abort_data(0, 0, SdoAbort::CommandSpecifierInvalid)) << "no transfer";
  sdo(initiate_block_upload(0x1008, 0, 127));
  EXPECT_EQ(sdo(block_ack(0, 127)), abort_data(0x1008, 0, SdoAbort::CommandSpecifierInvalid))
      << "ack before start";
  sdo(initiate_block_upload(0x1008, 0, 127));
  exchange(kStartUpload);
  EXPECT_EQ(sdo({0x60}), abort_data(0x1008, 0, SdoAbort::CommandSpecifierInvalid))
      << "segmented upload request inside a block upload";
  sdo(initiate_block_upload(0x1008, 0, 127));
  exchange(kStartUpload);
  EXPECT_EQ(sdo(kEndUpload), abort_data(0x1008, 0, SdoAbort::CommandSpecifierInvalid))
      << "end before the server ended";
  sdo(initiate_block_upload(0x1008, 0, 127));
  exchange(kStartUpload);
  EXPECT_EQ(sdo(kStartUpload), abort_data(0x1008, 0, SdoAbort::CommandSpecifierInvalid))
      << "a second start";
}

TEST_F(SdoBlockTest, NewInitiateRequestRestartsAsForSegmentedTransfers) {
  sdo(initiate_block_upload(0x1008, 0, 127));
  exchange(kStartUpload);
  EXPECT_EQ(upload(0x1000, 0), board::kNode.device_type);
  EXPECT_EQ(block_upload(0x1009, 0, 127), board::kNode.hardware_version);
}

TEST_F(SdoBlockTest, ClientAbortEndsBlockUploadWithoutAnswer) {
  sdo(initiate_block_upload(0x1008, 0, 1));
  exchange(kStartUpload);
  silent(kClientAbort);
  advance_us(2 * SdoServer::kSegmentTimeoutUs);
  EXPECT_TRUE(all_sent().empty()) << "no timeout, no further segment";
  EXPECT_EQ(sdo(block_ack(1, 127)), abort_data(0x1008, 0, SdoAbort::CommandSpecifierInvalid));
}

TEST_F(SdoBlockTest, BlockUploadWaitingForAckTimesOut) {
  sdo(initiate_block_upload(0x1008, 0, 127));
  exchange(kStartUpload);
  advance_us(SdoServer::kSegmentTimeoutUs - 1);
  EXPECT_TRUE(all_sent().empty());
  advance_us(1);
  EXPECT_EQ(next_sent().data, abort_data(0x1008, 0, SdoAbort::ProtocolTimedOut));
}

// Lockstep: the server waits on simulation time. A client as slow as a loaded emulator (a
// sub-block read over seconds) keeps its transfer; one silent for the timeout's worth of
// control cycles is aborted in the cycle that reaches it.
TEST_F(SdoBlockTest, OnControlCyclesOnlyControlTimeTimesOutATransfer) {
  constexpr std::uint32_t kPeriodUs = 1'000;
  node.set_timeout_clock(TimeoutClock::ControlCycles);
  sdo(initiate_block_upload(0x1008, 0, 127));
  exchange(kStartUpload);
  for (int i = 0; i < 100; ++i) advance_us(SdoServer::kSegmentTimeoutUs);  // the host stalls
  EXPECT_TRUE(all_sent().empty());
  for (std::uint32_t cycle = 1; cycle < SdoServer::kSegmentTimeoutUs / kPeriodUs; ++cycle) {
    node.advance_control_time(kPeriodUs);
  }
  EXPECT_TRUE(all_sent().empty());
  node.advance_control_time(kPeriodUs);
  EXPECT_EQ(next_sent().data, abort_data(0x1008, 0, SdoAbort::ProtocolTimedOut));
  // A client that answers within the timeout of simulation time goes on, however late.
  sdo(initiate_block_upload(0x1008, 0, 127));
  exchange(kStartUpload);
  node.advance_control_time(SdoServer::kSegmentTimeoutUs - 1);
  EXPECT_FALSE(exchange(block_ack(3, 127)).empty()) << "the end frame or the next sub-block";
}

TEST_F(SdoBlockTest, BlockUploadWaitingForStartOrEndTimesOut) {
  sdo(initiate_block_upload(0x1008, 0, 127));
  advance_us(SdoServer::kSegmentTimeoutUs);
  EXPECT_EQ(next_sent().data, abort_data(0x1008, 0, SdoAbort::ProtocolTimedOut));
  sdo(initiate_block_upload(0x1008, 0, 127));
  exchange(kStartUpload);
  sdo(block_ack(3, 127));
  advance_us(SdoServer::kSegmentTimeoutUs);
  EXPECT_EQ(next_sent().data, abort_data(0x1008, 0, SdoAbort::ProtocolTimedOut));
}

TEST_F(SdoBlockTest, SegmentRefusedByAFullQueueIsSentAtTheNextPoll) {
  sdo(initiate_block_upload(0x1008, 0, 127));
  port.set_fail_sends(true);
  silent(kStartUpload);
  EXPECT_EQ(node.counters().send_failures, 1u) << "one refusal, then the burst waits";
  port.set_fail_sends(false);
  advance_us(1000);
  const std::vector<CanFrame> sent = all_sent();
  ASSERT_EQ(sent.size(), 3u) << "nothing lost, nothing skipped";
  EXPECT_EQ(sent[0].data[0], 0x01);
  EXPECT_EQ(sent[1].data[0], 0x02);
  EXPECT_EQ(sent[2].data[0], 0x83);
  EXPECT_EQ(sdo(block_ack(3, 127)), (Frame{0xCD, 0xEB, 0xF6}));
}

TEST_F(SdoBlockTest, NmtResetForgetsABlockUpload) {
  sdo(initiate_block_upload(0x1008, 0, 1));
  exchange(kStartUpload);
  nmt(NmtCommand::ResetCommunication);
  advance_us(2 * SdoServer::kSegmentTimeoutUs);
  for (const CanFrame& frame : all_sent()) {  // boot-up and heartbeats only
    EXPECT_NE(frame.id, kSdoTx) << "no segment, no timeout";
  }
  EXPECT_EQ(sdo(block_ack(1, 1)), abort_data(0x1008, 0, SdoAbort::CommandSpecifierInvalid));
}

TEST_F(SdoBlockTest, DownloadOfFloatWithCrcWritesTheFieldAtTheEnd) {
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  const auto value = le32(float_bits(1.5f));
  // blksize 1: the value needs one segment.
  EXPECT_EQ(sdo(initiate_block_download(index, 0, 4)), with_multiplexer(0xA4, index, 0, 1));
  EXPECT_EQ(sdo(segment(1, true, value)), block_ack(1, 1));
  EXPECT_FLOAT_EQ(fields.values[FakeBoard::index(FieldId::velocity_setpoint)], 0.0f);
  EXPECT_EQ(reference_crc(value), 0xD1E8) << "binascii.crc_hqx of the same bytes";
  EXPECT_EQ(sdo(end_block_download(3, reference_crc(value))), (Frame{0xA1}));
  EXPECT_FLOAT_EQ(fields.values[FakeBoard::index(FieldId::velocity_setpoint)], 1.5f);
  EXPECT_EQ(node.counters().sdo_aborts_sent, 0u);
}

TEST_F(SdoBlockTest, DownloadWithoutClientCrcIgnoresTheCrcField) {
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  const auto value = le32(float_bits(-2.0f));
  EXPECT_EQ(sdo(initiate_block_download(index, 0, 4, false))[0], 0xA4);
  EXPECT_EQ(sdo(segment(1, true, value)), block_ack(1, 1));
  EXPECT_EQ(sdo(end_block_download(3, 0x1234)), (Frame{0xA1}));
  EXPECT_FLOAT_EQ(fields.values[FakeBoard::index(FieldId::velocity_setpoint)], -2.0f);
}

TEST_F(SdoBlockTest, DownloadWithoutSizeTakesTheObjectSize) {
  const auto value = le32(250);
  EXPECT_EQ(sdo(initiate_block_download(0x1017, 0, 0, true, false)), with_multiplexer(0xA4, 0x1017, 0, 1));
  EXPECT_EQ(sdo(segment(1, true, std::span(value).first(2))), block_ack(1, 1));
  EXPECT_EQ(sdo(end_block_download(5, reference_crc(std::span(value).first(2)))), (Frame{0xA1}));
  EXPECT_EQ(upload(0x1017, 0), 250u);
}

TEST_F(SdoBlockTest, DownloadWithWrongCrcAbortsAndWritesNothing) {
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  const auto value = le32(float_bits(1.5f));
  sdo(initiate_block_download(index, 0, 4));
  sdo(segment(1, true, value));
  EXPECT_EQ(sdo(end_block_download(3, reference_crc(value) ^ 0x0100)),
            abort_data(index, 0, SdoAbort::CrcError));
  EXPECT_EQ(fields.writes[FakeBoard::index(FieldId::velocity_setpoint)], 0u);
}

TEST_F(SdoBlockTest, DownloadEndingShortOfTheAnnouncedSizeAbortsLengthMismatch) {
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  const std::array<std::uint8_t, 3> three = {1, 2, 3};
  sdo(initiate_block_download(index, 0, 4));
  sdo(segment(1, true, three));
  EXPECT_EQ(sdo(end_block_download(4, reference_crc(three))), abort_data(index, 0, SdoAbort::LengthMismatch));
}

TEST_F(SdoBlockTest, DownloadAnnouncingAnotherSizeThanTheObjectAborts) {
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  EXPECT_EQ(sdo(initiate_block_download(index, 0, 5)), abort_data(index, 0, SdoAbort::LengthTooHigh));
  EXPECT_EQ(sdo(initiate_block_download(index, 0, 2)), abort_data(index, 0, SdoAbort::LengthTooLow));
}

TEST_F(SdoBlockTest, DownloadWithoutSizeEndingShortIsRefusedByTheObject) {
  const std::array<std::uint8_t, 3> three = {1, 2, 3};
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  sdo(initiate_block_download(index, 0, 0, true, false));
  sdo(segment(1, true, three));
  EXPECT_EQ(sdo(end_block_download(4, reference_crc(three))), abort_data(index, 0, SdoAbort::LengthTooLow));
}

TEST_F(SdoBlockTest, DownloadSegmentPastTheObjectAbortsLengthTooHigh) {
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  const std::array<std::uint8_t, 7> seven = {1, 2, 3, 4, 5, 6, 7};
  sdo(initiate_block_download(index, 0, 0, true, false));
  // Seven bytes, and the client says more follow: the server asks for one more segment...
  EXPECT_EQ(sdo(segment(1, false, seven)), block_ack(1, 1));
  // ...which cannot fit a 4-byte object.
  EXPECT_EQ(sdo(segment(1, true, seven)), abort_data(index, 0, SdoAbort::LengthTooHigh));
}

TEST_F(SdoBlockTest, DownloadSequenceNumberZeroOrPastBlksizeAborts) {
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  const auto value = le32(float_bits(1.5f));
  sdo(initiate_block_download(index, 0, 4));
  EXPECT_EQ(sdo(segment(0, false, value)), abort_data(index, 0, SdoAbort::InvalidSequenceNumber));
  sdo(initiate_block_download(index, 0, 4));
  EXPECT_EQ(sdo(segment(2, true, value)), abort_data(index, 0, SdoAbort::InvalidSequenceNumber))
      << "blksize is 1";
}

TEST_F(SdoBlockTest, DownloadEndBeforeTheLastSegmentAbortsOrIsASegment) {
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  EXPECT_EQ(sdo(end_block_download(0, 0)), abort_data(0, 0, SdoAbort::CommandSpecifierInvalid))
      << "no transfer";
  sdo(initiate_block_download(index, 0, 4));
  // Inside the sub-block 0xC1 is segment 0x41 with the last bit: past blksize 1.
  EXPECT_EQ(sdo(end_block_download(0, 0)), abort_data(index, 0, SdoAbort::InvalidSequenceNumber));
}

TEST_F(SdoBlockTest, DownloadCommandsOutOfTurnAbortCommandSpecifierInvalid) {
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  const auto value = le32(float_bits(1.5f));
  sdo(initiate_block_download(index, 0, 4));
  sdo(segment(1, true, value));
  EXPECT_EQ(sdo({0x00, 1, 2, 3, 4, 5, 6, 7}), abort_data(index, 0, SdoAbort::CommandSpecifierInvalid))
      << "segmented download segment where the end request belongs";
  EXPECT_EQ(fields.writes[FakeBoard::index(FieldId::velocity_setpoint)], 0u);
}

TEST_F(SdoBlockTest, DownloadToReadOnlyOrMissingObjectAborts) {
  EXPECT_EQ(sdo(initiate_block_download(0x1000, 0, 4)), abort_data(0x1000, 0, SdoAbort::ReadOnly));
  EXPECT_EQ(sdo(initiate_block_download(0x1234, 0, 4)), abort_data(0x1234, 0, SdoAbort::ObjectDoesNotExist));
}

TEST_F(SdoBlockTest, ClientAbortInsideASubBlockEndsTheDownload) {
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  sdo(initiate_block_download(index, 0, 4));
  silent(kClientAbort);
  advance_us(2 * SdoServer::kSegmentTimeoutUs);
  EXPECT_TRUE(all_sent().empty());
  EXPECT_EQ(sdo(end_block_download(3, 0)), abort_data(index, 0, SdoAbort::CommandSpecifierInvalid));
}

TEST_F(SdoBlockTest, BlockDownloadWaitingForSegmentsOrEndTimesOut) {
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  sdo(initiate_block_download(index, 0, 4));
  advance_us(SdoServer::kSegmentTimeoutUs - 1);
  EXPECT_TRUE(all_sent().empty());
  advance_us(1);
  EXPECT_EQ(next_sent().data, abort_data(index, 0, SdoAbort::ProtocolTimedOut));
  sdo(initiate_block_download(index, 0, 4));
  sdo(segment(1, true, le32(float_bits(1.5f))));
  advance_us(SdoServer::kSegmentTimeoutUs);
  EXPECT_EQ(next_sent().data, abort_data(index, 0, SdoAbort::ProtocolTimedOut));
  EXPECT_EQ(fields.writes[FakeBoard::index(FieldId::velocity_setpoint)], 0u);
}

TEST_F(SdoBlockTest, NmtResetForgetsABlockDownload) {
  const std::uint16_t index = index_of(FieldId::velocity_setpoint);
  const auto value = le32(float_bits(1.5f));
  sdo(initiate_block_download(index, 0, 4));
  sdo(segment(1, true, value));
  nmt(NmtCommand::ResetCommunication);
  all_sent();  // boot-up
  EXPECT_EQ(sdo(end_block_download(3, reference_crc(value))),
            abort_data(index, 0, SdoAbort::CommandSpecifierInvalid));
  EXPECT_EQ(fields.writes[FakeBoard::index(FieldId::velocity_setpoint)], 0u);
}

// --- The server alone, with values larger than its buffer ---------------------------------------

// A test-only object dictionary: 0x5000 holds `pattern_size` bytes of pattern data served only
// by offset (a stand-in for the recorder's DOMAIN); 0x5001 is writable, `writable_size` bytes.
class LargeObjects {
 public:
  static constexpr std::uint16_t kPattern = 0x5000;
  static constexpr std::uint16_t kWritable = 0x5001;

  static std::uint8_t pattern(std::size_t offset) {
    return static_cast<std::uint8_t>(offset * 31 + (offset >> 8));
  }
  std::string pattern_string(std::size_t from, std::size_t count) const {
    std::string s;
    for (std::size_t i = from; i < from + count; ++i) s.push_back(static_cast<char>(pattern(i)));
    return s;
  }

  ObjectAccess access() {
    ObjectAccess a;
    a.context = this;
    a.check_writable = [](void* self, std::uint16_t index, std::uint8_t, std::size_t& size) {
      auto& objects = *static_cast<LargeObjects*>(self);
      if (index == kPattern) return SdoAbort::ReadOnly;
      if (index != kWritable) return SdoAbort::ObjectDoesNotExist;
      size = objects.writable_size;
      return SdoAbort::None;
    };
    a.read = [](void*, std::uint16_t, std::uint8_t, std::span<std::uint8_t>, std::size_t&) {
      ADD_FAILURE() << "with read_at the server never reads a value whole";
      return SdoAbort::GeneralError;
    };
    a.write = [](void* self, std::uint16_t index, std::uint8_t, std::span<const std::uint8_t> data,
                 std::uint32_t) {
      auto& objects = *static_cast<LargeObjects*>(self);
      if (index != kWritable) return SdoAbort::ObjectDoesNotExist;
      if (data.size() != objects.writable_size) return SdoAbort::LengthMismatch;
      objects.written.assign(data.begin(), data.end());
      return SdoAbort::None;
    };
    a.read_at = [](void* self, std::uint16_t index, std::uint8_t, std::size_t offset,
                   std::span<std::uint8_t> out, std::size_t& length, std::size_t& total_size) {
      auto& objects = *static_cast<LargeObjects*>(self);
      if (index != kPattern) return SdoAbort::ObjectDoesNotExist;
      objects.reads.push_back({offset, out.size()});
      total_size = objects.pattern_size;
      length = std::min(out.size(), objects.pattern_size - std::min(offset, objects.pattern_size));
      for (std::size_t i = 0; i < length; ++i) out[i] = pattern(offset + i);
      return SdoAbort::None;
    };
    return a;
  }

  struct Read {
    std::size_t offset;
    std::size_t length;
  };
  std::size_t pattern_size = 2000;
  std::size_t writable_size = 64;
  std::vector<Read> reads;
  std::vector<std::uint8_t> written;
};

class SdoServerBlockTest : public ::testing::Test {
 protected:
  // The answer to one request, if any.
  std::optional<Frame> handle(const Frame& request) {
    Frame response{};
    if (!server.handle(request, now_us, response)) return std::nullopt;
    return response;
  }
  Frame answer(const Frame& request) {
    const std::optional<Frame> response = handle(request);
    EXPECT_TRUE(response.has_value()) << "expected an answer to 0x" << std::hex << int{request[0]};
    return response.value_or(Frame{});
  }
  // Every segment due now, as the node sends them.
  std::vector<Frame> segments() {
    std::vector<Frame> out;
    Frame frame{};
    while (out.size() < 200 && server.peek_segment(frame)) {
      out.push_back(frame);
      server.segment_sent(now_us);
    }
    return out;
  }
  static std::string data_of(const std::vector<Frame>& frames) {
    std::string s;
    for (const Frame& f : frames) s.append(f.begin() + 1, f.end());
    return s;
  }

  LargeObjects objects;
  SdoServer server{objects.access()};
  std::uint32_t now_us = 5'000;
};

TEST_F(SdoServerBlockTest, ServerHoldsNoCopyOfTheValue) {
  // A 64 kB upload must not need 64 kB here, nor a sub-block (127 * 7 bytes): the 64-byte
  // buffer, one frame and bookkeeping.
  EXPECT_LE(sizeof(SdoServer), 256u);
}

TEST_F(SdoServerBlockTest, UploadLargerThanAnyObjectStreamsThroughReadAt) {
  EXPECT_EQ(answer(initiate_block_upload(LargeObjects::kPattern, 0, 127)),
            with_multiplexer(0xC6, LargeObjects::kPattern, 0, 0xD0, 0x07));  // 2000 bytes
  EXPECT_FALSE(handle(kStartUpload).has_value());
  std::string value;
  std::vector<std::size_t> sub_blocks;
  std::vector<Frame> sub_block = segments();
  for (int n = 0; n < 10 && !sub_block.empty(); ++n) {
    sub_blocks.push_back(sub_block.size());
    for (std::size_t i = 0; i < sub_block.size(); ++i) {
      EXPECT_EQ(static_cast<std::size_t>(sub_block[i][0] & 0x7F), i + 1);
    }
    value += data_of(sub_block);
    const bool last = (sub_block.back()[0] & 0x80) != 0;
    const std::optional<Frame> next = handle(block_ack(static_cast<std::uint8_t>(sub_block.size()), 127));
    if (last) {
      ASSERT_TRUE(next.has_value());
      value.resize(value.size() - ((*next)[0] >> 2 & 0x7));
      EXPECT_EQ((*next)[0] & 0xE3, 0xC1);
      EXPECT_EQ(crc_of(*next), reference_crc(value));
      break;
    }
    EXPECT_FALSE(next.has_value()) << "the next sub-block comes as segments";
    sub_block = segments();
  }
  // 2000 bytes = 286 segments: 127 + 127 + 32.
  EXPECT_EQ(sub_blocks, (std::vector<std::size_t>{127, 127, 32}));
  EXPECT_EQ(value, objects.pattern_string(0, 2000));
  EXPECT_FALSE(handle(kEndUpload).has_value());
  EXPECT_FALSE(server.transfer_in_progress());
  // One look at the start, then one read per segment of at most 7 bytes.
  ASSERT_EQ(objects.reads.size(), 1u + 286u);
  for (std::size_t i = 1; i < objects.reads.size(); ++i) {
    EXPECT_EQ(objects.reads[i].offset, (i - 1) * 7);
    EXPECT_LE(objects.reads[i].length, 7u);
  }
}

TEST_F(SdoServerBlockTest, RepeatedSegmentsAreReadAgainFromTheObject) {
  answer(initiate_block_upload(LargeObjects::kPattern, 0, 127));
  handle(kStartUpload);
  ASSERT_EQ(segments().size(), 127u);
  objects.reads.clear();
  // Segment 51 was lost: 50 arrived.
  EXPECT_FALSE(handle(block_ack(50, 100)).has_value());
  const std::vector<Frame> repeated = segments();
  ASSERT_EQ(repeated.size(), 100u) << "the client's new blksize";
  EXPECT_EQ(objects.reads.front().offset, 50u * 7u);
  EXPECT_EQ(repeated.front()[0], 0x01);
  EXPECT_EQ(data_of(repeated), objects.pattern_string(350, 700));
  // The rest, 950 bytes in 127 + 9 segments, then the end: the CRC counts the repeated bytes
  // once.
  EXPECT_FALSE(handle(block_ack(100, 127)).has_value());
  EXPECT_EQ(segments().size(), 127u);
  EXPECT_FALSE(handle(block_ack(127, 127)).has_value());
  const std::vector<Frame> rest = segments();
  ASSERT_EQ(rest.size(), 9u);
  EXPECT_EQ(rest.back()[0], 0x89);
  const Frame end = answer(block_ack(9, 127));
  EXPECT_EQ(end[0], 0xC1 | (2 << 2)) << "2000 = 285 * 7 + 5: 2 bytes unused";
  EXPECT_EQ(crc_of(end), reference_crc(objects.pattern_string(0, 2000)));
}

TEST_F(SdoServerBlockTest, AckBeforeTheSubBlockIsOutRestartsFromIt) {
  // python-canopen acknowledges as soon as it sees a gap, while segments are still coming.
  answer(initiate_block_upload(LargeObjects::kPattern, 0, 127));
  handle(kStartUpload);
  Frame frame{};
  for (int i = 0; i < 5; ++i) {
    ASSERT_TRUE(server.peek_segment(frame));
    server.segment_sent(now_us);
  }
  EXPECT_EQ(answer(block_ack(6, 127)),
            abort_data(LargeObjects::kPattern, 0, SdoAbort::InvalidSequenceNumber))
      << "6 were never sent";
  answer(initiate_block_upload(LargeObjects::kPattern, 0, 127));
  handle(kStartUpload);
  for (int i = 0; i < 5; ++i) {
    ASSERT_TRUE(server.peek_segment(frame));
    server.segment_sent(now_us);
  }
  EXPECT_FALSE(handle(block_ack(3, 127)).has_value());
  const std::vector<Frame> after = segments();
  ASSERT_EQ(after.size(), 127u);
  EXPECT_EQ(data_of({after.front()}), objects.pattern_string(21, 7));
  EXPECT_EQ(after.front()[0], 0x01);
}

TEST_F(SdoServerBlockTest, PeekingTwiceOffersTheSameSegmentUntilItIsSent) {
  answer(initiate_block_upload(LargeObjects::kPattern, 0, 127));
  handle(kStartUpload);
  Frame first{};
  Frame again{};
  ASSERT_TRUE(server.peek_segment(first));
  ASSERT_TRUE(server.peek_segment(again));
  EXPECT_EQ(first, again);
  EXPECT_EQ(objects.reads.size(), 2u) << "kept, not read again";
  server.segment_sent(now_us);
  ASSERT_TRUE(server.peek_segment(again));
  EXPECT_EQ(again[0], 0x02);
}

TEST_F(SdoServerBlockTest, SegmentedUploadAlsoStreamsLargeValues) {
  EXPECT_EQ(answer(with_multiplexer(0x40, LargeObjects::kPattern, 0)),
            with_multiplexer(0x41, LargeObjects::kPattern, 0, 0xD0, 0x07));
  std::string value;
  std::uint8_t toggle = 0;
  for (int n = 0; n < 400; ++n) {
    const Frame s = answer({static_cast<std::uint8_t>(0x60 | toggle)});
    ASSERT_EQ(s[0] & 0x10, toggle);
    value.append(s.begin() + 1, s.begin() + 8 - ((s[0] >> 1) & 0x7));
    if (s[0] & 0x01) break;
    toggle ^= 0x10;
  }
  EXPECT_EQ(value, objects.pattern_string(0, 2000));
}

TEST_F(SdoServerBlockTest, EmptyValueUploadsAsOneSegmentWithoutData) {
  // A recorder that recorded nothing yet.
  objects.pattern_size = 0;
  EXPECT_EQ(answer(initiate_block_upload(LargeObjects::kPattern, 0, 127)),
            with_multiplexer(0xC6, LargeObjects::kPattern, 0));
  handle(kStartUpload);
  EXPECT_EQ(segments(), (std::vector<Frame>{{0x81}}));
  EXPECT_EQ(answer(block_ack(1, 127)), (Frame{0xDD})) << "n = 7, CRC of nothing = 0";
  EXPECT_FALSE(handle(kEndUpload).has_value());
  // Segmented: size 0, then one last segment with n = 7.
  EXPECT_EQ(answer(with_multiplexer(0x40, LargeObjects::kPattern, 0)),
            with_multiplexer(0x41, LargeObjects::kPattern, 0));
  EXPECT_EQ(answer({0x60}), (Frame{0x0F}));
  EXPECT_FALSE(server.transfer_in_progress());
}

TEST_F(SdoServerBlockTest, ValueThatChangesSizeMidUploadAbortsGeneralError) {
  answer(initiate_block_upload(LargeObjects::kPattern, 0, 127));
  handle(kStartUpload);
  segments();
  handle(block_ack(127, 127));
  objects.pattern_size = 1000;
  const std::vector<Frame> frames = segments();
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(frames.front(), abort_data(LargeObjects::kPattern, 0, SdoAbort::GeneralError));
  EXPECT_FALSE(server.transfer_in_progress());
  EXPECT_EQ(server.aborts_sent(), 1u);
}

TEST_F(SdoServerBlockTest, DownloadOfBufferSizedValueWithALostSegment) {
  std::array<std::uint8_t, 70> data{};  // 64 bytes of value, 6 of padding in the last segment
  for (std::size_t i = 0; i < 64; ++i) data[i] = static_cast<std::uint8_t>(0xA0 + i);
  const auto part = [&](std::size_t segment_index) { return std::span(data).subspan(segment_index * 7, 7); };
  // blksize 10: the whole value in one sub-block.
  EXPECT_EQ(answer(initiate_block_download(LargeObjects::kWritable, 0, 64)),
            with_multiplexer(0xA4, LargeObjects::kWritable, 0, 10));
  for (std::uint8_t s = 1; s <= 9; ++s) {
    if (s == 4) continue;  // lost
    EXPECT_FALSE(handle(segment(s, false, part(s - 1u))).has_value()) << int{s};
  }
  // End of the sub-block: the last good one was 3; 43 bytes are missing, 7 segments.
  EXPECT_EQ(answer(segment(10, true, part(9))), block_ack(3, 7));
  for (std::uint8_t s = 1; s <= 6; ++s) EXPECT_FALSE(handle(segment(s, false, part(s + 2u))).has_value());
  EXPECT_EQ(answer(segment(7, true, part(9))), block_ack(7, 1));
  EXPECT_TRUE(objects.written.empty()) << "written at the end request only";
  EXPECT_EQ(answer(end_block_download(6, reference_crc(std::span(data).first(64)))), (Frame{0xA1}));
  EXPECT_EQ(objects.written, std::vector<std::uint8_t>(data.begin(), data.begin() + 64));
}

TEST_F(SdoServerBlockTest, DownloadIgnoresRepeatedAndOutOfOrderSegments) {
  objects.writable_size = 14;
  const std::array<std::uint8_t, 14> data = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14};
  EXPECT_EQ(answer(initiate_block_download(LargeObjects::kWritable, 0, 14)),
            with_multiplexer(0xA4, LargeObjects::kWritable, 0, 2));
  EXPECT_FALSE(handle(segment(1, false, std::span(data).first(7))).has_value());
  EXPECT_FALSE(handle(segment(1, false, std::span(data).first(7))).has_value()) << "repeated";
  EXPECT_EQ(answer(segment(2, true, std::span(data).subspan(7))), block_ack(2, 1));
  EXPECT_EQ(answer(end_block_download(0, reference_crc(data))), (Frame{0xA1}));
  EXPECT_EQ(objects.written, std::vector<std::uint8_t>(data.begin(), data.end()));
}

TEST_F(SdoServerBlockTest, DownloadLargerThanTheBufferAbortsOutOfMemory) {
  objects.writable_size = SdoServer::kBufferBytes + 1;
  EXPECT_EQ(answer(initiate_block_download(LargeObjects::kWritable, 0, 65)),
            abort_data(LargeObjects::kWritable, 0, SdoAbort::OutOfMemory));
  EXPECT_EQ(answer(initiate_block_download(LargeObjects::kWritable, 0, 0, true, false)),
            abort_data(LargeObjects::kWritable, 0, SdoAbort::OutOfMemory));
  // Segmented download the same: the client's data would fit the object, not the server.
  EXPECT_EQ(answer(with_multiplexer(0x21, LargeObjects::kWritable, 0, 65)),
            abort_data(LargeObjects::kWritable, 0, SdoAbort::OutOfMemory));
  // More than the object holds is still the client's error.
  EXPECT_EQ(answer(initiate_block_download(LargeObjects::kWritable, 0, 66)),
            abort_data(LargeObjects::kWritable, 0, SdoAbort::LengthTooHigh));
}

}  // namespace
}  // namespace co::test
