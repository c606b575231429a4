// SDO server (CiA 301, 7.2.4): expedited, segmented and block upload and download on one channel.
//
// Block transfer (7.2.4.3.9 to 7.2.4.3.16), with the CRC-16 CiA 301 defines (CCITT polynomial
// 0x1021, initial value 0) whenever the client asks for it:
// - Download: the value is kept whole until the end request, because the object dictionary's
//   write takes it in one call; a value larger than kBufferBytes is refused (OutOfMemory). An
//   object written by stream (a DOMAIN such as CiA 302-3's program data) takes any size: its
//   bytes are handed on as the segments arrive, the server keeps one segment and a running CRC. The
//   server asks for as many segments as the value still needs (blksize 1..10). A segment out of
//   sequence is ignored and the sub-block acknowledged with the last good one, so the client
//   repeats from there.
// - Upload: a value of up to kBufferBytes is copied at the initiate request, so every segment
//   and every repeated one come from the same snapshot. A larger one (a DOMAIN) is read by
//   offset through ObjectAccess::read_at for each segment sent, repeats included: the server
//   keeps offsets and a running CRC, never the value. Segmented uploads stream the same way.
//   A client whose protocol switch threshold admits the value's size gets a normal upload.
// - The segments of an upload sub-block answer no request: after handle() and in every poll the
//   node takes them with peek_segment() and segment_sent().
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "CanPort.hpp"
#include "SdoAbort.hpp"
#include "TimeLeft.hpp"

namespace co {

// What the SDO server needs from the object dictionary: calls on `context`. Plain function
// pointers rather than virtual functions: the engine is built without RTTI, and a polymorphic
// engine class would need typeinfo that RTTI-enabled code (tests and the platform, which also
// run UBSan's vptr checks) cannot find.
struct ObjectAccess {
  void* context = nullptr;
  // Size in bytes of the object's value, or the abort (object/sub-index missing, read-only...)
  // when it cannot be written at all. Checked before a segmented or block download starts.
  SdoAbort (*check_writable)(void* context, std::uint16_t index, std::uint8_t sub,
                             std::size_t& size) = nullptr;
  // Copies the value into `out` and sets `length`, or returns the abort to send.
  SdoAbort (*read)(void* context, std::uint16_t index, std::uint8_t sub,
                   std::span<std::uint8_t> out, std::size_t& length) = nullptr;
  // Writes the value (exactly the bytes the client sent), or returns the abort to send.
  SdoAbort (*write)(void* context, std::uint16_t index, std::uint8_t sub,
                    std::span<const std::uint8_t> data, std::uint32_t now_us) = nullptr;
  // Optional (without it uploads use `read`, up to kBufferBytes): copies the value's bytes from
  // `offset` on into `out`, as many as fit or are left, and sets `length` to that count and
  // `total_size` to the value's size. What lets an upload serve a value larger than the server's
  // buffer. Such a value must not change while it is uploaded: repeated segments are read again.
  SdoAbort (*read_at)(void* context, std::uint16_t index, std::uint8_t sub, std::size_t offset,
                      std::span<std::uint8_t> out, std::size_t& length,
                      std::size_t& total_size) = nullptr;
  // Optional: a DOMAIN written as it arrives, of any size (check_writable reports
  // SdoServer::kStreamedSize for it). Only a block download writes one; each byte is handed over
  // once, in order: stream_open, stream_append for every piece, then stream_close once all
  // arrived and the block CRC matched, or stream_cancel when the transfer ends any other way
  // (either side aborted, the client fell silent, a reset). `announced_size` 0: not indicated.
  SdoAbort (*stream_open)(void* context, std::uint16_t index, std::uint8_t sub,
                          std::size_t announced_size) = nullptr;
  SdoAbort (*stream_append)(void* context, std::span<const std::uint8_t> data) = nullptr;
  SdoAbort (*stream_close)(void* context, std::uint32_t now_us) = nullptr;
  void (*stream_cancel)(void* context) = nullptr;
};

class SdoServer {
 public:
  // A client that lets this long pass between segments (or sub-blocks) gets ProtocolTimedOut.
  static constexpr std::uint32_t kSegmentTimeoutUs = 1'000'000;
  // Largest value a download can carry, and the largest upload copied at its initiate request
  // (the longest string object fits).
  static constexpr std::size_t kBufferBytes = 64;
  // check_writable's size of an object written by stream (ObjectAccess::stream_open).
  static constexpr std::size_t kStreamedSize = SIZE_MAX;
  // CiA 301 bounds of blksize, the segments of one sub-block.
  static constexpr std::uint8_t kMaxBlockSegments = 127;
  // Segments a block download asks for at most: the whole buffer in one sub-block.
  static constexpr std::uint8_t kMaxDownloadBlockSegments = (kBufferBytes + 6) / 7;
  static_assert(kMaxDownloadBlockSegments <= kMaxBlockSegments);

  // `objects.context` must outlive the server.
  explicit SdoServer(const ObjectAccess& objects) : objects_(objects) {}
  SdoServer(const SdoServer&) = delete;
  SdoServer& operator=(const SdoServer&) = delete;

  // Handles one request (data of a frame to 0x600+id). Returns true when `response` (data of a
  // frame to 0x580+id, always 8 bytes) must be sent. Segments of a block upload follow through
  // peek_segment().
  bool handle(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
              std::array<std::uint8_t, 8>& response);

  // Block upload: the next frame of the sub-block being sent (data of a frame to 0x580+id),
  // false when none is due. Peeking does not consume it: call segment_sent() once the port took
  // it, so a segment the CAN queue refused is offered again at the next call. A value that can
  // no longer be read ends the transfer: the frame offered is then the abort.
  bool peek_segment(std::array<std::uint8_t, 8>& frame);
  void segment_sent(std::uint32_t now_us);

  // Aborts a transfer whose client fell silent. Returns true when `response` (the abort) must
  // be sent.
  bool check_timeout(std::uint32_t now_us, std::array<std::uint8_t, 8>& response);
  // Microseconds from `now_us` until check_timeout() would act (0 if it would now); kNoTimerUs
  // while no transfer is open. What an idle loop may sleep.
  std::uint32_t us_until_timeout(std::uint32_t now_us) const {
    if (state_ == State::Idle) return kNoTimerUs;
    return time_left_us(now_us, last_activity_us_, kSegmentTimeoutUs);
  }

  // Forgets any transfer in progress without answering (NMT stop or reset).
  void reset() {
    cancel_stream();
    state_ = State::Idle;
    segment_ready_ = false;
  }

  bool transfer_in_progress() const { return state_ != State::Idle; }
  // A block-upload segment (or the abort replacing it) is waiting for peek_segment().
  bool segments_due() const {
    return segment_ready_ || (state_ == State::BlockUploading && !sub_block_sent());
  }
  std::uint32_t aborts_sent() const { return aborts_sent_; }
  SdoAbort last_abort() const { return last_abort_; }

 private:
  enum class State : std::uint8_t {
    Idle,
    Downloading,          // segmented download: waiting for the next segment
    Uploading,            // segmented upload: waiting for the next segment request
    BlockDownloading,     // block download: receiving the segments of a sub-block
    BlockDownloadEnding,  // block download: all data in, waiting for the end request
    BlockUploadStarting,  // block upload: initiate answered, waiting for the start request
    BlockUploading,       // block upload: sending a sub-block, then waiting for its ack
    BlockUploadEnding,    // block upload: end sent, waiting for the client's end response
    BlockDownloadDraining,  // block download aborted mid sub-block: its remaining segments,
                            // which the client sends before it reads the abort, are dropped
  };

  bool abort(std::uint16_t index, std::uint8_t sub, SdoAbort code,
             std::array<std::uint8_t, 8>& response);
  bool initiate_download(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                         std::array<std::uint8_t, 8>& response);
  bool download_segment(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                        std::array<std::uint8_t, 8>& response);
  bool initiate_upload(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                       std::array<std::uint8_t, 8>& response);
  bool answer_normal_upload(std::uint32_t now_us, std::array<std::uint8_t, 8>& response);
  bool upload_segment(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                      std::array<std::uint8_t, 8>& response);
  bool block_download(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                      std::array<std::uint8_t, 8>& response);
  bool initiate_block_download(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                               std::array<std::uint8_t, 8>& response);
  bool block_download_segment(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                              std::array<std::uint8_t, 8>& response);
  bool end_block_download(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                          std::array<std::uint8_t, 8>& response);
  bool block_upload(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                    std::array<std::uint8_t, 8>& response);
  bool initiate_block_upload(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                             std::array<std::uint8_t, 8>& response);
  bool block_upload_ack(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                        std::array<std::uint8_t, 8>& response);
  std::uint8_t download_block_segments() const;
  // A streamed download that ends without stream_close: the object hears stream_cancel.
  void cancel_stream();
  SdoAbort append_stream(std::span<const std::uint8_t> data);
  bool sub_block_sent() const;
  // Upload source: opens the value (snapshot in buffer_ when it fits) and reads it by offset.
  SdoAbort open_upload(std::uint16_t index, std::uint8_t sub);
  SdoAbort read_upload(std::size_t offset, std::span<std::uint8_t> out);

  ObjectAccess objects_;
  State state_ = State::Idle;
  std::uint16_t index_ = 0;
  std::uint8_t sub_ = 0;
  std::uint8_t toggle_ = 0;              // expected toggle bit of the next segment (0 or 0x10)
  std::uint32_t last_activity_us_ = 0;
  std::size_t announced_size_ = 0;       // download: size from the initiate request, 0 = none
  std::size_t object_size_ = 0;          // download: size of the target object
  std::size_t received_ = 0;             // download: bytes received, whole block segments
                                         // counted as 7 until the end request names the unused
  std::size_t upload_size_ = 0;          // upload: size of the value
  bool upload_streamed_ = false;         // upload: read by offset (read_at), not from buffer_
  std::size_t offset_ = 0;               // upload: offset of the next byte to send
  std::array<std::uint8_t, kBufferBytes> buffer_{};

  // Block transfer.
  bool crc_used_ = false;                // the client asked for CRC (the server always can)
  std::uint16_t crc_ = 0;                // upload: CRC of the first crc_bytes_ bytes
  std::size_t crc_bytes_ = 0;
  std::uint8_t block_segments_ = 0;      // blksize of the sub-block under way
  std::uint8_t sequence_ = 0;            // download: last good seqno; upload: last seqno sent
  std::size_t block_start_ = 0;          // upload: offset of the sub-block's first byte
  bool last_segment_sent_ = false;       // upload: the sub-block ended with the value's end
  std::array<std::uint8_t, 8> segment_{};  // upload: the frame peek_segment() offered
  bool segment_ready_ = false;

  // Streamed block download: the last segment received is held back (in buffer_, which a
  // streamed value does not use) until the next one, or the end request, which says how many of
  // its bytes are padding, shows how much of it is data.
  bool streaming_ = false;
  bool stream_pending_ = false;

  std::uint32_t aborts_sent_ = 0;
  SdoAbort last_abort_ = SdoAbort::None;
};

}  // namespace co
