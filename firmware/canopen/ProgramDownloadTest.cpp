// CiA 302-3 program download through a Node: 0x1F51 control, a streamed SDO block download into
// 0x1F50 (exact frames), the image header checks, and what an abort or a silent client leaves.
// The store is in memory; the Linux one (a staging file) is exercised by the bus scenarios.
#include <vector>

#include "BlockCrcReference.hpp"
#include "NodeTestSupport.hpp"
#include "ParameterImage.hpp"

namespace co::test {
namespace {

using Frame = std::array<std::uint8_t, 8>;
using cia302::FlashError;
using cia302::ProgramControl;

void put_u32(std::vector<std::uint8_t>& out, std::size_t at, std::uint32_t v) {
  for (std::size_t i = 0; i < 4; ++i) out[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
}

std::uint32_t crc32(std::span<const std::uint8_t> bytes) {
  return parameter_image::crc32(std::as_bytes(bytes));
}

// An image as boardproto.cia302.ImageHeader.pack() writes it, then `payload`.
std::vector<std::uint8_t> make_image(std::span<const std::uint8_t> payload,
                                     std::uint32_t product_code = board::kNode.product_code) {
  namespace field = cia302::image_field;
  std::vector<std::uint8_t> image(cia302::kImageHeaderBytes, 0);
  std::copy(cia302::kImageMagic.begin(), cia302::kImageMagic.end(), image.begin());
  image[field::kFormatVersion] = cia302::kImageFormatVersion;
  image[field::kHeaderBytes] = cia302::kImageHeaderBytes;
  put_u32(image, field::kProductCode, product_code);
  put_u32(image, field::kPayloadLength, static_cast<std::uint32_t>(payload.size()));
  put_u32(image, field::kPayloadCrc32, crc32(payload));
  const char version[] = "9.9.9";
  std::copy(version, version + 5, image.begin() + field::kSoftwareVersion);
  put_u32(image, field::kHeaderCrc32, crc32(std::span(image).first(field::kHeaderCrc32)));
  image.insert(image.end(), payload.begin(), payload.end());
  return image;
}

std::vector<std::uint8_t> pattern(std::size_t size) {
  std::vector<std::uint8_t> bytes(size);
  for (std::size_t i = 0; i < size; ++i) bytes[i] = static_cast<std::uint8_t>(i * 7 + (i >> 8));
  return bytes;
}

class ProgramDownloadTest : public NodeTest {
 protected:
  void SetUp() override {
    node.set_program_store(&store);
    NodeTest::SetUp();
  }

  SdoAbort control(ProgramControl value) {
    return download(cia302::kProgramControlIndex, 1, static_cast<std::uint32_t>(value), 1);
  }
  void stop_and_clear() {
    ASSERT_EQ(control(ProgramControl::Stop), SdoAbort::None);
    ASSERT_EQ(control(ProgramControl::Clear), SdoAbort::None);
  }

  // Block download of `data` into 0x1F50:01 with CRC; stops after `segments_limit` segments
  // (0: all) without the end request. Returns the abort the server sent (None: it acked all).
  SdoAbort block_download(std::span<const std::uint8_t> data, std::size_t segments_limit = 0) {
    const std::uint32_t size = static_cast<std::uint32_t>(data.size());
    Frame initiate{0xC6, 0x50, 0x1F, 1, static_cast<std::uint8_t>(size), static_cast<std::uint8_t>(size >> 8),
                   static_cast<std::uint8_t>(size >> 16), static_cast<std::uint8_t>(size >> 24)};
    Frame answer = sdo(initiate);
    if (answer[0] == 0x80) return abort_of(answer);
    EXPECT_EQ(answer[0], 0xA4);
    std::uint8_t blksize = answer[4];
    std::size_t offset = 0;
    std::size_t sent = 0;
    while (offset < data.size()) {
      for (std::uint8_t seq = 1; seq <= blksize && offset < data.size(); ++seq) {
        const std::size_t chunk = std::min<std::size_t>(7, data.size() - offset);
        const bool last = offset + chunk == data.size();
        Frame frame{static_cast<std::uint8_t>(seq | (last ? 0x80 : 0))};
        std::copy_n(data.begin() + static_cast<long>(offset), chunk, frame.begin() + 1);
        offset += chunk;
        receive(make_frame(kSdoRx, {frame[0], frame[1], frame[2], frame[3], frame[4], frame[5], frame[6], frame[7]}));
        if (segments_limit != 0 && ++sent == segments_limit) {
          const auto frames = all_sent();
          return frames.empty() || frames.back().data[0] != 0x80 ? SdoAbort::None : abort_of(frames.back().data);
        }
        if (seq == blksize || last) {
          const CanFrame ack = next_sent();
          if (ack.data[0] == 0x80) return abort_of(ack.data);
          EXPECT_EQ(ack.data[0], 0xA2);
          blksize = ack.data[2];
        }
      }
    }
    const std::size_t unused = (7 - data.size() % 7) % 7;
    const std::uint16_t crc = reference_crc(data);
    answer = sdo({static_cast<std::uint8_t>(0xC1 | (unused << 2)), static_cast<std::uint8_t>(crc),
                  static_cast<std::uint8_t>(crc >> 8)});
    if (answer[0] == 0x80) return abort_of(answer);
    EXPECT_EQ(answer[0], 0xA1);
    return SdoAbort::None;
  }

  static SdoAbort abort_of(std::span<const std::uint8_t, 8> frame) {
    return static_cast<SdoAbort>(frame[4] | (frame[5] << 8) | (frame[6] << 16) |
                                 (std::uint32_t{frame[7]} << 24));
  }

  std::uint32_t flash_status() { return upload(cia302::kFlashStatusIndex, 1); }

  MemoryProgramStore store;
};

TEST_F(ProgramDownloadTest, ObjectsReadAsCia302Says) {
  EXPECT_EQ(upload(cia302::kProgramControlIndex, 0), 1u);
  EXPECT_EQ(upload(cia302::kProgramControlIndex, 1), static_cast<std::uint32_t>(ProgramControl::Start));
  EXPECT_EQ(upload(cia302::kSoftwareIdIndex, 1), 0xC0FF'EE00u);
  EXPECT_EQ(flash_status(), 0u);
  EXPECT_EQ(upload_abort(cia302::kProgramDataIndex, 1), SdoAbort::WriteOnly);
  EXPECT_EQ(download(cia302::kFlashStatusIndex, 1, 0, 4), SdoAbort::ReadOnly);
}

TEST_F(ProgramDownloadTest, StreamsAnImageMuchLargerThanTheServerBufferAndKeepsIt) {
  const auto payload = pattern(5000);  // ~80 sub-block segments past the 64-byte buffer
  const auto image = make_image(payload);
  stop_and_clear();
  ASSERT_EQ(block_download(image), SdoAbort::None);
  EXPECT_EQ(store.kept, payload);  // the header is the node's, the store gets the payload
  EXPECT_EQ(flash_status(), 0u);
  EXPECT_FALSE(node.program_start_requested());
  EXPECT_EQ(control(ProgramControl::Start), SdoAbort::None);
  EXPECT_TRUE(node.program_start_requested());
}

TEST_F(ProgramDownloadTest, RefusesADownloadBeforeClear) {
  const auto image = make_image(pattern(100));
  EXPECT_EQ(block_download(image), SdoAbort::DeviceState);
  EXPECT_EQ(flash_status(), cia302::flash_status(FlashError::FlashNotCleared, false));
  EXPECT_EQ(control(ProgramControl::Clear), SdoAbort::DeviceState);  // running: stop first
}

TEST_F(ProgramDownloadTest, RefusesAnImageForAnotherBoardAsSoonAsItsHeaderArrived) {
  const auto image = make_image(pattern(3000), board::kNode.product_code + 1);
  stop_and_clear();
  // The header's 60 bytes end in segment 9, which the server holds back until segment 10 shows
  // it was all data: the abort answers segment 10, mid sub-block.
  EXPECT_EQ(block_download(image, 10), SdoAbort::DataCannotBeStored);
  // The rest of that sub-block, sent before the client reads the abort, is dropped unanswered
  // (seqno 0x22 would otherwise read as an expedited download request).
  for (std::uint8_t seq = 11; seq <= 0x30; ++seq) receive(make_frame(kSdoRx, {seq, 0x00, 0x20, 0, 1, 2, 3, 4}));
  EXPECT_TRUE(all_sent().empty());
  EXPECT_EQ(flash_status(), cia302::flash_status(FlashError::WrongBoard, false));
  EXPECT_TRUE(store.staging.empty());
  EXPECT_FALSE(store.open);
}

TEST_F(ProgramDownloadTest, RefusesAFileWithoutImageHeader) {
  stop_and_clear();
  EXPECT_EQ(block_download(pattern(200)), SdoAbort::DataCannotBeStored);
  EXPECT_EQ(flash_status(), cia302::flash_status(FlashError::DataFormatUnknown, false));
}

TEST_F(ProgramDownloadTest, RefusesAPayloadWhoseCrcDoesNotMatchItsHeader) {
  auto image = make_image(pattern(300));
  image.back() ^= 0x01;
  stop_and_clear();
  EXPECT_EQ(block_download(image), SdoAbort::DataCannotBeStored);
  EXPECT_EQ(flash_status(), cia302::flash_status(FlashError::DataFormatError, false));
  EXPECT_TRUE(store.kept.empty());
  EXPECT_EQ(control(ProgramControl::Start), SdoAbort::None);
  EXPECT_FALSE(node.program_start_requested());  // nothing kept: the old program runs on
}

TEST_F(ProgramDownloadTest, AClientAbortMidTransferDiscardsTheStagedBytes) {
  stop_and_clear();
  EXPECT_EQ(block_download(make_image(pattern(3000)), 40), SdoAbort::None);
  // Read locally: an SDO request now would end the transfer (CiA 301: a new request ends it).
  EXPECT_TRUE(node.program().transfer_in_progress());
  EXPECT_EQ(node.program().flash_status(), cia302::flash_status(FlashError::NoError, true));
  receive(make_frame(kSdoRx, {0x80, 0x50, 0x1F, 1, 0, 0, 0, 0x08}));
  EXPECT_FALSE(store.open);
  EXPECT_TRUE(store.staging.empty());
  EXPECT_EQ(flash_status(), cia302::flash_status(FlashError::TransferBrokenOff, false));
  EXPECT_EQ(control(ProgramControl::Start), SdoAbort::None);
  EXPECT_FALSE(node.program_start_requested());
}

TEST_F(ProgramDownloadTest, ASilentClientTimesOutAndTheStagedBytesAreDiscarded) {
  stop_and_clear();
  EXPECT_EQ(block_download(make_image(pattern(3000)), 20), SdoAbort::None);
  advance_us(SdoServer::kSegmentTimeoutUs + 1000);
  const auto frames = all_sent();
  ASSERT_FALSE(frames.empty());
  EXPECT_EQ(abort_of(frames.back().data), SdoAbort::ProtocolTimedOut);
  EXPECT_TRUE(store.staging.empty());
  EXPECT_EQ(flash_status(), cia302::flash_status(FlashError::TransferBrokenOff, false));
}

TEST_F(ProgramDownloadTest, AWriteFailureAbortsWithAHardwareError) {
  stop_and_clear();
  store.fail_writes = true;
  EXPECT_EQ(block_download(make_image(pattern(500))), SdoAbort::HardwareError);
  EXPECT_EQ(flash_status(), cia302::flash_status(FlashError::FlashWriteError, false));
}

// A write that fails on the segment handed on when the transfer's last one arrives: the abort ends
// the transfer there (no segments follow a last one), so the client's next request is served.
// Ending on seqno 63 makes that request's first byte (0x40, an upload) look like the next seqno.
TEST_F(ProgramDownloadTest, AWriteFailureAtTheLastSegmentLeavesTheServerReadyForTheNextRequest) {
  stop_and_clear();
  constexpr std::size_t kSegments = 63;
  const std::size_t header_bytes = make_image({}).size();
  const auto image = make_image(pattern(kSegments * 7 - header_bytes));
  ASSERT_EQ(block_download(image, kSegments - 1), SdoAbort::None);
  store.fail_writes = true;
  Frame last{static_cast<std::uint8_t>(kSegments | 0x80)};
  std::copy_n(image.end() - 7, 7, last.begin() + 1);
  receive(make_frame(kSdoRx, {last[0], last[1], last[2], last[3], last[4], last[5], last[6], last[7]}));
  EXPECT_EQ(abort_of(next_sent().data), SdoAbort::HardwareError);
  EXPECT_EQ(flash_status(), cia302::flash_status(FlashError::FlashWriteError, false)) << "answered";
}

TEST(ProgramDownloadWithoutStore, RefusesEveryDownloadAsFlashSecured) {
  ProgramDownload program{board::kNode.product_code};
  EXPECT_EQ(program.control(static_cast<std::uint32_t>(ProgramControl::Stop)), SdoAbort::None);
  EXPECT_EQ(program.control(static_cast<std::uint32_t>(ProgramControl::Clear)), SdoAbort::None);
  EXPECT_EQ(program.open(1000), SdoAbort::DataCannotBeStored);
  EXPECT_EQ(program.flash_status(), cia302::flash_status(FlashError::FlashSecured, false));
  EXPECT_EQ(program.read(cia302::kSoftwareIdIndex, 1), 0u);
}

TEST_F(ProgramDownloadTest, OnlyBlockDownloadWritesProgramData) {
  // Segmented initiate, size 100.
  const Frame answer = sdo({0x21, 0x50, 0x1F, 1, 100, 0, 0, 0});
  EXPECT_EQ(abort_of(answer), SdoAbort::UnsupportedAccess);
}

TEST_F(ProgramDownloadTest, StopLeavesOperationalForPreOperationalAndResetIsRefused) {
  nmt(NmtCommand::Start);
  all_sent();
  EXPECT_EQ(control(ProgramControl::Stop), SdoAbort::None);
  EXPECT_EQ(node.state(), NmtState::PreOperational);
  EXPECT_EQ(download(cia302::kProgramControlIndex, 1, 2, 1), SdoAbort::ValueRangeExceeded);
}

}  // namespace
}  // namespace co::test
