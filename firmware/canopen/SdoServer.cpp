#include "SdoServer.hpp"

#include <algorithm>

namespace co {
namespace {

// Client command specifiers (top three bits of byte 0).
constexpr std::uint8_t kDownloadSegment = 0;
constexpr std::uint8_t kInitiateDownload = 1;
constexpr std::uint8_t kInitiateUpload = 2;
constexpr std::uint8_t kUploadSegment = 3;
constexpr std::uint8_t kAbortTransfer = 4;
constexpr std::uint8_t kBlockUpload = 5;
constexpr std::uint8_t kBlockDownload = 6;

// Block upload client subcommands (bits 0..1), block download ones (bit 0).
constexpr std::uint8_t kBlockInitiate = 0;
constexpr std::uint8_t kBlockEnd = 1;
constexpr std::uint8_t kBlockAck = 2;
constexpr std::uint8_t kBlockStart = 3;

constexpr std::uint8_t kToggleBit = 0x10;
constexpr std::uint8_t kExpeditedBit = 0x02;
constexpr std::uint8_t kSizeIndicatedBit = 0x01;
constexpr std::uint8_t kLastSegmentBit = 0x01;
constexpr std::uint8_t kCrcBit = 0x04;               // block initiate: CRC supported
constexpr std::uint8_t kBlockSizeIndicatedBit = 0x02;  // block initiate: size indicated
constexpr std::uint8_t kNoMoreSegmentsBit = 0x80;    // block segment: the value ends here
constexpr std::uint8_t kSequenceMask = 0x7F;
constexpr std::uint8_t kClientAbort = 0x80;
constexpr std::size_t kSegmentBytes = 7;

std::uint16_t request_index(std::span<const std::uint8_t, 8> r) {
  return static_cast<std::uint16_t>(r[1] | (r[2] << 8));
}

std::uint32_t get_u32(std::span<const std::uint8_t, 8> r, std::size_t at) {
  return r[at] | (r[at + 1] << 8) | (r[at + 2] << 16) | (static_cast<std::uint32_t>(r[at + 3]) << 24);
}

void put_u32(std::array<std::uint8_t, 8>& out, std::size_t at, std::uint32_t v) {
  for (std::size_t i = 0; i < 4; ++i) out[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
}

void put_multiplexer(std::array<std::uint8_t, 8>& out, std::uint16_t index, std::uint8_t sub) {
  out[1] = static_cast<std::uint8_t>(index & 0xFF);
  out[2] = static_cast<std::uint8_t>(index >> 8);
  out[3] = sub;
}

// CRC-16 of block transfers (CiA 301, 7.2.4.3.16): polynomial x^16 + x^12 + x^5 + 1 (0x1021),
// initial value 0, most significant bit first, no final XOR. Bitwise rather than a 512-byte
// table: at most 7 bytes per CAN frame.
std::uint16_t crc16_ccitt(std::uint16_t crc, std::span<const std::uint8_t> bytes) {
  for (const std::uint8_t byte : bytes) {
    crc = static_cast<std::uint16_t>(crc ^ (byte << 8));
    for (int bit = 0; bit < 8; ++bit) {
      const bool carry = (crc & 0x8000) != 0;
      crc = static_cast<std::uint16_t>(crc << 1);
      if (carry) crc ^= 0x1021;
    }
  }
  return crc;
}

bool valid_block_size(std::uint8_t segments) {
  return segments >= 1 && segments <= SdoServer::kMaxBlockSegments;
}

}  // namespace

bool SdoServer::abort(std::uint16_t index, std::uint8_t sub, SdoAbort code,
                      std::array<std::uint8_t, 8>& response) {
  response = {0x80};
  put_multiplexer(response, index, sub);
  put_u32(response, 4, to_code(code));
  cancel_stream();
  state_ = State::Idle;
  ++aborts_sent_;
  last_abort_ = code;
  return true;
}

bool SdoServer::handle(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                       std::array<std::uint8_t, 8>& response) {
  // A request may change what comes next: a segment peeked but not sent is built again.
  segment_ready_ = false;
  // Inside a download sub-block every frame is a segment (byte 0 = last bit and seqno); only
  // 0x80, which seqno 0 cannot be, is the client's abort.
  if (state_ == State::BlockDownloading && request[0] != kClientAbort) {
    return block_download_segment(request, now_us, response);
  }
  if (state_ == State::BlockDownloadDraining) {
    // The next segment of the aborted sub-block is dropped, not read as a request: seqnos 32..63
    // would otherwise look like expedited downloads to whatever index the data spells. (A client
    // that reads the abort early and whose next request's first byte happens to equal the next
    // seqno loses that request; it times out and repeats it.)
    const std::uint8_t sequence = request[0] & kSequenceMask;
    if (request[0] != kClientAbort && sequence == sequence_ + 1) {
      sequence_ = sequence;
      last_activity_us_ = now_us;
      if (sequence >= block_segments_ || (request[0] & kNoMoreSegmentsBit) != 0) state_ = State::Idle;
      return false;
    }
    state_ = State::Idle;  // anything else is the client's next request
  }
  switch (request[0] >> 5) {
    case kDownloadSegment: return download_segment(request, now_us, response);
    case kInitiateDownload: return initiate_download(request, now_us, response);
    case kInitiateUpload: return initiate_upload(request, now_us, response);
    case kUploadSegment: return upload_segment(request, now_us, response);
    case kAbortTransfer:  // the client gave up: no answer
      cancel_stream();
      state_ = State::Idle;
      return false;
    case kBlockUpload: return block_upload(request, now_us, response);
    case kBlockDownload: return block_download(request, now_us, response);
    default:  // 7 is not defined
      return abort(request_index(request), request[3], SdoAbort::CommandSpecifierInvalid, response);
  }
}

// --- Expedited and segmented download ------------------------------------------------------

bool SdoServer::initiate_download(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                                  std::array<std::uint8_t, 8>& response) {
  // A new initiate request ends any transfer still open: its client has moved on.
  cancel_stream();
  state_ = State::Idle;
  const std::uint16_t index = request_index(request);
  const std::uint8_t sub = request[3];
  const bool size_indicated = (request[0] & kSizeIndicatedBit) != 0;

  if ((request[0] & kExpeditedBit) != 0) {
    std::size_t size = 4;
    if (size_indicated) {
      size = 4u - ((request[0] >> 2) & 0x3u);
    } else {
      // Size not indicated: the value is as long as the object (at most the 4 bytes carried).
      std::size_t object_size = 0;
      const SdoAbort writable = objects_.check_writable(objects_.context, index, sub, object_size);
      if (writable != SdoAbort::None) return abort(index, sub, writable, response);
      size = std::min<std::size_t>(object_size, 4);
    }
    const SdoAbort result = objects_.write(objects_.context, index, sub, request.subspan(4, size), now_us);
    if (result != SdoAbort::None) return abort(index, sub, result, response);
    response = {0x60};
    put_multiplexer(response, index, sub);
    return true;
  }

  std::size_t object_size = 0;
  const SdoAbort writable = objects_.check_writable(objects_.context, index, sub, object_size);
  if (writable != SdoAbort::None) return abort(index, sub, writable, response);
  // A streamed object takes block downloads only (python-canopen, CANopenNode and Lely all
  // send large domains by block).
  if (object_size == kStreamedSize) return abort(index, sub, SdoAbort::UnsupportedAccess, response);
  std::size_t announced = 0;
  if (size_indicated) {
    announced = get_u32(request, 4);
    if (announced > object_size) return abort(index, sub, SdoAbort::LengthTooHigh, response);
    if (announced < object_size) return abort(index, sub, SdoAbort::LengthTooLow, response);
  }
  // The client's data would fit the object; the server just cannot hold it until the end.
  if (object_size > buffer_.size()) return abort(index, sub, SdoAbort::OutOfMemory, response);

  state_ = State::Downloading;
  index_ = index;
  sub_ = sub;
  toggle_ = 0;
  announced_size_ = announced;
  object_size_ = object_size;
  received_ = 0;
  last_activity_us_ = now_us;
  response = {0x60};
  put_multiplexer(response, index, sub);
  return true;
}

bool SdoServer::download_segment(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                                 std::array<std::uint8_t, 8>& response) {
  if (state_ != State::Downloading) {
    return abort(index_, sub_, SdoAbort::CommandSpecifierInvalid, response);
  }
  const std::uint8_t toggle = request[0] & kToggleBit;
  if (toggle != toggle_) return abort(index_, sub_, SdoAbort::ToggleBitNotAlternated, response);

  const std::size_t data_bytes = 7u - ((request[0] >> 1) & 0x7u);
  if (received_ + data_bytes > object_size_) {
    return abort(index_, sub_, SdoAbort::LengthTooHigh, response);
  }
  std::copy_n(request.begin() + 1, data_bytes, buffer_.begin() + static_cast<long>(received_));
  received_ += data_bytes;
  last_activity_us_ = now_us;

  if ((request[0] & kLastSegmentBit) != 0) {
    if (announced_size_ != 0 && received_ != announced_size_) {
      return abort(index_, sub_, SdoAbort::LengthMismatch, response);
    }
    const SdoAbort result = objects_.write(
        objects_.context, index_, sub_, std::span<const std::uint8_t>(buffer_.data(), received_), now_us);
    if (result != SdoAbort::None) return abort(index_, sub_, result, response);
    state_ = State::Idle;
  }
  response = {static_cast<std::uint8_t>(0x20 | toggle)};
  toggle_ ^= kToggleBit;
  return true;
}

// --- Expedited and segmented upload --------------------------------------------------------

SdoAbort SdoServer::open_upload(std::uint16_t index, std::uint8_t sub) {
  std::size_t length = 0;
  std::size_t size = 0;
  if (objects_.read_at != nullptr) {
    const SdoAbort result = objects_.read_at(objects_.context, index, sub, 0, buffer_, length, size);
    if (result != SdoAbort::None) return result;
  } else {
    const SdoAbort result = objects_.read(objects_.context, index, sub, buffer_, length);
    if (result != SdoAbort::None) return result;
    size = length;
  }
  index_ = index;
  sub_ = sub;
  upload_size_ = size;
  // What did not fit the buffer is read by offset, segment by segment.
  upload_streamed_ = length < size;
  return SdoAbort::None;
}

SdoAbort SdoServer::read_upload(std::size_t offset, std::span<std::uint8_t> out) {
  if (!upload_streamed_) {
    std::copy_n(buffer_.begin() + static_cast<long>(offset), out.size(), out.begin());
    return SdoAbort::None;
  }
  std::size_t length = 0;
  std::size_t size = 0;
  const SdoAbort result = objects_.read_at(objects_.context, index_, sub_, offset, out, length, size);
  if (result != SdoAbort::None) return result;
  // The value changed size under the transfer: what was announced cannot be delivered.
  if (length != out.size() || size != upload_size_) return SdoAbort::GeneralError;
  return SdoAbort::None;
}

bool SdoServer::initiate_upload(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                                std::array<std::uint8_t, 8>& response) {
  cancel_stream();
  state_ = State::Idle;
  const std::uint16_t index = request_index(request);
  const std::uint8_t sub = request[3];
  const SdoAbort opened = open_upload(index, sub);
  if (opened != SdoAbort::None) return abort(index, sub, opened, response);
  return answer_normal_upload(now_us, response);
}

bool SdoServer::answer_normal_upload(std::uint32_t now_us, std::array<std::uint8_t, 8>& response) {
  response = {};
  put_multiplexer(response, index_, sub_);
  if (upload_size_ >= 1 && upload_size_ <= 4) {
    // Expedited, size indicated: n = number of unused bytes in 4..7 (an empty value cannot
    // say so in two bits: it goes segmented, one segment with no data).
    response[0] = static_cast<std::uint8_t>(0x43 | ((4u - upload_size_) << 2));
    std::copy_n(buffer_.begin(), upload_size_, response.begin() + 4);
    return true;
  }
  response[0] = 0x41;  // segmented, size indicated
  put_u32(response, 4, static_cast<std::uint32_t>(upload_size_));
  state_ = State::Uploading;
  toggle_ = 0;
  offset_ = 0;
  last_activity_us_ = now_us;
  return true;
}

bool SdoServer::upload_segment(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                               std::array<std::uint8_t, 8>& response) {
  if (state_ != State::Uploading) {
    return abort(index_, sub_, SdoAbort::CommandSpecifierInvalid, response);
  }
  const std::uint8_t toggle = request[0] & kToggleBit;
  if (toggle != toggle_) return abort(index_, sub_, SdoAbort::ToggleBitNotAlternated, response);

  const std::size_t chunk = std::min(kSegmentBytes, upload_size_ - offset_);
  std::array<std::uint8_t, 8> segment{};
  const SdoAbort read = read_upload(offset_, std::span(segment).subspan(1, chunk));
  if (read != SdoAbort::None) return abort(index_, sub_, read, response);
  offset_ += chunk;
  const bool last = offset_ == upload_size_;
  segment[0] = static_cast<std::uint8_t>(toggle | ((7u - chunk) << 1) | (last ? kLastSegmentBit : 0));
  response = segment;
  toggle_ ^= kToggleBit;
  last_activity_us_ = now_us;
  if (last) state_ = State::Idle;
  return true;
}

// --- Block download ------------------------------------------------------------------------

bool SdoServer::block_download(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                               std::array<std::uint8_t, 8>& response) {
  if ((request[0] & 0x01) == kBlockInitiate) return initiate_block_download(request, now_us, response);
  return end_block_download(request, now_us, response);
}

void SdoServer::cancel_stream() {
  if (!streaming_) return;
  streaming_ = false;
  stream_pending_ = false;
  objects_.stream_cancel(objects_.context);
}

SdoAbort SdoServer::append_stream(std::span<const std::uint8_t> data) {
  if (data.empty()) return SdoAbort::None;
  crc_ = crc16_ccitt(crc_, data);
  return objects_.stream_append(objects_.context, data);
}

std::uint8_t SdoServer::download_block_segments() const {
  if (streaming_) return kMaxBlockSegments;  // no end in sight: as many as CiA 301 allows
  // As many segments as the value still needs: the whole of it fits one sub-block (the buffer
  // holds any object a download accepts), and a client never sends a segment it cannot hold.
  const std::size_t left = object_size_ - std::min(received_, object_size_);
  const std::size_t segments = (left + kSegmentBytes - 1) / kSegmentBytes;
  return static_cast<std::uint8_t>(std::clamp<std::size_t>(segments, 1, kMaxDownloadBlockSegments));
}

bool SdoServer::initiate_block_download(std::span<const std::uint8_t, 8> request,
                                        std::uint32_t now_us,
                                        std::array<std::uint8_t, 8>& response) {
  cancel_stream();
  state_ = State::Idle;
  const std::uint16_t index = request_index(request);
  const std::uint8_t sub = request[3];
  std::size_t object_size = 0;
  const SdoAbort writable = objects_.check_writable(objects_.context, index, sub, object_size);
  if (writable != SdoAbort::None) return abort(index, sub, writable, response);
  const bool size_indicated = (request[0] & kBlockSizeIndicatedBit) != 0;
  std::size_t announced = 0;
  if (object_size == kStreamedSize) {
    if (objects_.stream_open == nullptr) return abort(index, sub, SdoAbort::UnsupportedAccess, response);
    announced = size_indicated ? get_u32(request, 4) : 0;
    const SdoAbort opened = objects_.stream_open(objects_.context, index, sub, announced);
    if (opened != SdoAbort::None) return abort(index, sub, opened, response);
    streaming_ = true;
    stream_pending_ = false;
    crc_ = 0;
  } else {
    if (size_indicated) {
      announced = get_u32(request, 4);
      if (announced > object_size) return abort(index, sub, SdoAbort::LengthTooHigh, response);
      if (announced < object_size) return abort(index, sub, SdoAbort::LengthTooLow, response);
    }
    if (object_size > buffer_.size()) return abort(index, sub, SdoAbort::OutOfMemory, response);
  }

  state_ = State::BlockDownloading;
  index_ = index;
  sub_ = sub;
  announced_size_ = announced;
  object_size_ = object_size;
  received_ = 0;
  sequence_ = 0;
  crc_used_ = (request[0] & kCrcBit) != 0;
  block_segments_ = download_block_segments();
  last_activity_us_ = now_us;
  // scs 5, sc: the server checks a CRC whenever the client sends one.
  response = {static_cast<std::uint8_t>(0xA0 | kCrcBit)};
  put_multiplexer(response, index, sub);
  response[4] = block_segments_;
  return true;
}

bool SdoServer::block_download_segment(std::span<const std::uint8_t, 8> request,
                                       std::uint32_t now_us,
                                       std::array<std::uint8_t, 8>& response) {
  const std::uint8_t sequence = request[0] & kSequenceMask;
  const bool last = (request[0] & kNoMoreSegmentsBit) != 0;
  if (sequence == 0 || sequence > block_segments_) {
    return abort(index_, sub_, SdoAbort::InvalidSequenceNumber, response);
  }
  last_activity_us_ = now_us;
  bool value_complete = false;
  if (sequence == sequence_ + 1 && streaming_) {
    // The segment before this one was all data: hand it on, keep this one until we know.
    if (stream_pending_) {
      const SdoAbort appended = append_stream(std::span<const std::uint8_t>(buffer_).first(kSegmentBytes));
      if (appended != SdoAbort::None) {
        abort(index_, sub_, appended, response);
        if (sequence < block_segments_ && !last) {
          state_ = State::BlockDownloadDraining;
          sequence_ = sequence;
        }
        return true;
      }
    }
    std::copy_n(request.begin() + 1, kSegmentBytes, buffer_.begin());
    stream_pending_ = true;
    received_ += kSegmentBytes;
    sequence_ = sequence;
    value_complete = last;
  } else if (sequence == sequence_ + 1) {
    if (received_ >= object_size_) return abort(index_, sub_, SdoAbort::LengthTooHigh, response);
    // Bytes past the object can only be the last segment's padding: not kept.
    const std::size_t kept = std::min(kSegmentBytes, object_size_ - received_);
    std::copy_n(request.begin() + 1, kept, buffer_.begin() + static_cast<long>(received_));
    received_ += kSegmentBytes;
    sequence_ = sequence;
    value_complete = last;
  }
  // Anything else was lost or repeated: ignored, and the ack below names the last good one,
  // so the client repeats the rest (CiA 301, 7.2.4.3.11).
  if (sequence < block_segments_ && !last) return false;  // the sub-block goes on: no answer

  response = {static_cast<std::uint8_t>(0xA0 | kBlockAck), sequence_, download_block_segments()};
  if (value_complete) {
    state_ = State::BlockDownloadEnding;
  } else {
    block_segments_ = response[2];
    sequence_ = 0;
  }
  return true;
}

bool SdoServer::end_block_download(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                                   std::array<std::uint8_t, 8>& response) {
  if (state_ != State::BlockDownloadEnding) {
    return abort(index_, sub_, SdoAbort::CommandSpecifierInvalid, response);
  }
  const std::size_t unused = (request[0] >> 2) & 0x7u;
  const std::size_t size = received_ - unused;  // received_ >= 7: one segment at least
  if (streaming_) {
    const SdoAbort appended =
        append_stream(std::span<const std::uint8_t>(buffer_).first(kSegmentBytes - unused));
    if (appended != SdoAbort::None) return abort(index_, sub_, appended, response);
    stream_pending_ = false;
    if (announced_size_ != 0 && size != announced_size_) {
      return abort(index_, sub_, SdoAbort::LengthMismatch, response);
    }
    if (crc_used_) {
      const auto client_crc = static_cast<std::uint16_t>(request[1] | (request[2] << 8));
      if (crc_ != client_crc) return abort(index_, sub_, SdoAbort::CrcError, response);
    }
    streaming_ = false;  // closed: no cancel after this, whatever close answers
    const SdoAbort closed = objects_.stream_close(objects_.context, now_us);
    if (closed != SdoAbort::None) return abort(index_, sub_, closed, response);
    state_ = State::Idle;
    response = {static_cast<std::uint8_t>(0xA0 | kBlockEnd)};
    return true;
  }
  if (size > object_size_) return abort(index_, sub_, SdoAbort::LengthTooHigh, response);
  if (announced_size_ != 0 && size != announced_size_) {
    return abort(index_, sub_, SdoAbort::LengthMismatch, response);
  }
  const std::span<const std::uint8_t> value(buffer_.data(), size);
  if (crc_used_) {
    const auto client_crc = static_cast<std::uint16_t>(request[1] | (request[2] << 8));
    if (crc16_ccitt(0, value) != client_crc) return abort(index_, sub_, SdoAbort::CrcError, response);
  }
  const SdoAbort result = objects_.write(objects_.context, index_, sub_, value, now_us);
  if (result != SdoAbort::None) return abort(index_, sub_, result, response);
  state_ = State::Idle;
  response = {static_cast<std::uint8_t>(0xA0 | kBlockEnd)};
  return true;
}

// --- Block upload --------------------------------------------------------------------------

bool SdoServer::block_upload(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                             std::array<std::uint8_t, 8>& response) {
  switch (request[0] & 0x03) {
    case kBlockInitiate: return initiate_block_upload(request, now_us, response);
    case kBlockStart:
      if (state_ != State::BlockUploadStarting) break;
      state_ = State::BlockUploading;  // the segments follow through peek_segment()
      last_activity_us_ = now_us;
      return false;
    case kBlockAck:
      if (state_ != State::BlockUploading) break;
      return block_upload_ack(request, now_us, response);
    case kBlockEnd:
      if (state_ != State::BlockUploadEnding) break;
      state_ = State::Idle;  // the client has the value and its CRC checked: done
      return false;
    default: break;
  }
  return abort(index_, sub_, SdoAbort::CommandSpecifierInvalid, response);
}

bool SdoServer::initiate_block_upload(std::span<const std::uint8_t, 8> request,
                                      std::uint32_t now_us,
                                      std::array<std::uint8_t, 8>& response) {
  cancel_stream();
  state_ = State::Idle;
  const std::uint16_t index = request_index(request);
  const std::uint8_t sub = request[3];
  const std::uint8_t segments = request[4];
  const std::uint8_t protocol_switch_threshold = request[5];
  if (!valid_block_size(segments)) return abort(index, sub, SdoAbort::InvalidBlockSize, response);
  const SdoAbort opened = open_upload(index, sub);
  if (opened != SdoAbort::None) return abort(index, sub, opened, response);
  // The client prefers the normal protocol for values this small (CiA 301 lets the server
  // switch): fewer frames than initiate, start, one sub-block, ack and end.
  if (protocol_switch_threshold != 0 && upload_size_ <= protocol_switch_threshold) {
    return answer_normal_upload(now_us, response);
  }

  state_ = State::BlockUploadStarting;
  crc_used_ = (request[0] & kCrcBit) != 0;
  crc_ = 0;
  crc_bytes_ = 0;
  block_segments_ = segments;
  sequence_ = 0;
  block_start_ = 0;
  offset_ = 0;
  last_segment_sent_ = false;
  last_activity_us_ = now_us;
  // scs 6, sc (CRC supported), s (size indicated).
  response = {static_cast<std::uint8_t>(0xC0 | kCrcBit | kBlockSizeIndicatedBit)};
  put_multiplexer(response, index, sub);
  put_u32(response, 4, static_cast<std::uint32_t>(upload_size_));
  return true;
}

bool SdoServer::sub_block_sent() const {
  return sequence_ == block_segments_ || last_segment_sent_;
}

bool SdoServer::peek_segment(std::array<std::uint8_t, 8>& frame) {
  if (segment_ready_) {
    frame = segment_;
    return true;
  }
  if (state_ != State::BlockUploading || sub_block_sent()) return false;
  const std::size_t chunk = std::min(kSegmentBytes, upload_size_ - offset_);
  std::array<std::uint8_t, 8> segment{};
  const SdoAbort read = read_upload(offset_, std::span(segment).subspan(1, chunk));
  if (read != SdoAbort::None) {
    abort(index_, sub_, read, segment_);
  } else {
    const bool last = offset_ + chunk == upload_size_;
    segment[0] = static_cast<std::uint8_t>((sequence_ + 1) | (last ? kNoMoreSegmentsBit : 0));
    segment_ = segment;
  }
  segment_ready_ = true;
  frame = segment_;
  return true;
}

void SdoServer::segment_sent(std::uint32_t now_us) {
  if (!segment_ready_) return;
  segment_ready_ = false;
  if (state_ != State::BlockUploading) return;  // it was the abort
  const std::size_t chunk = std::min(kSegmentBytes, upload_size_ - offset_);
  // The CRC covers each byte once: a repeated segment carries bytes it has already seen.
  if (offset_ + chunk > crc_bytes_) {
    const std::size_t seen = crc_bytes_ - offset_;
    crc_ = crc16_ccitt(crc_, std::span<const std::uint8_t>(segment_).subspan(1 + seen, chunk - seen));
    crc_bytes_ = offset_ + chunk;
  }
  offset_ += chunk;
  ++sequence_;
  last_segment_sent_ = (segment_[0] & kNoMoreSegmentsBit) != 0;
  last_activity_us_ = now_us;
}

bool SdoServer::block_upload_ack(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                                 std::array<std::uint8_t, 8>& response) {
  const std::uint8_t acknowledged = request[1];
  const std::uint8_t next_segments = request[2];
  // An ack may come before the sub-block is out (a client that saw a gap says so at once), but
  // never for segments not sent.
  if (acknowledged > sequence_) {
    return abort(index_, sub_, SdoAbort::InvalidSequenceNumber, response);
  }
  if (!valid_block_size(next_segments)) {
    return abort(index_, sub_, SdoAbort::InvalidBlockSize, response);
  }
  last_activity_us_ = now_us;
  if (last_segment_sent_ && acknowledged == sequence_) {
    // Everything arrived: end with the unused bytes of the last segment and the CRC.
    const std::size_t last_start = upload_size_ == 0 ? 0 : (upload_size_ - 1) / kSegmentBytes * kSegmentBytes;
    const std::size_t unused = kSegmentBytes - (upload_size_ - last_start);
    state_ = State::BlockUploadEnding;
    const std::uint16_t crc = crc_used_ ? crc_ : 0;
    response = {static_cast<std::uint8_t>(0xC0 | (unused << 2) | kBlockEnd),
                static_cast<std::uint8_t>(crc & 0xFF), static_cast<std::uint8_t>(crc >> 8)};
    return true;
  }
  // Go on after the last segment the client has: the rest of this sub-block is sent again,
  // read again from the value (only offsets are kept).
  block_start_ += acknowledged * kSegmentBytes;
  offset_ = block_start_;
  sequence_ = 0;
  last_segment_sent_ = false;
  block_segments_ = next_segments;
  return false;
}

bool SdoServer::check_timeout(std::uint32_t now_us, std::array<std::uint8_t, 8>& response) {
  if (state_ == State::BlockDownloadDraining) {
    // Aborted already: no second abort. A client silent this long sends no more of the sub-block.
    if (now_us - last_activity_us_ >= kSegmentTimeoutUs) state_ = State::Idle;
    return false;
  }
  if (state_ == State::Idle) return false;
  // Unsigned difference: correct across the 32-bit wrap of now_us.
  if (now_us - last_activity_us_ < kSegmentTimeoutUs) return false;
  segment_ready_ = false;
  return abort(index_, sub_, SdoAbort::ProtocolTimedOut, response);
}

}  // namespace co
