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

constexpr std::uint8_t kToggleBit = 0x10;
constexpr std::uint8_t kExpeditedBit = 0x02;
constexpr std::uint8_t kSizeIndicatedBit = 0x01;
constexpr std::uint8_t kLastSegmentBit = 0x01;

std::uint16_t request_index(std::span<const std::uint8_t, 8> r) {
  return static_cast<std::uint16_t>(r[1] | (r[2] << 8));
}

void put_u32(std::array<std::uint8_t, 8>& out, std::size_t at, std::uint32_t v) {
  for (std::size_t i = 0; i < 4; ++i) out[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
}

void put_multiplexer(std::array<std::uint8_t, 8>& out, std::uint16_t index, std::uint8_t sub) {
  out[1] = static_cast<std::uint8_t>(index & 0xFF);
  out[2] = static_cast<std::uint8_t>(index >> 8);
  out[3] = sub;
}

}  // namespace

bool SdoServer::abort(std::uint16_t index, std::uint8_t sub, SdoAbort code,
                      std::array<std::uint8_t, 8>& response) {
  response = {0x80};
  put_multiplexer(response, index, sub);
  put_u32(response, 4, to_code(code));
  state_ = State::Idle;
  ++aborts_sent_;
  last_abort_ = code;
  return true;
}

bool SdoServer::handle(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                       std::array<std::uint8_t, 8>& response) {
  switch (request[0] >> 5) {
    case kDownloadSegment: return download_segment(request, now_us, response);
    case kInitiateDownload: return initiate_download(request, now_us, response);
    case kInitiateUpload: return initiate_upload(request, now_us, response);
    case kUploadSegment: return upload_segment(request, now_us, response);
    case kAbortTransfer: state_ = State::Idle; return false;  // the client gave up: no answer
    default:  // block upload (5), block download (6), 7: not supported
      return abort(request_index(request), request[3], SdoAbort::CommandSpecifierInvalid, response);
  }
}

bool SdoServer::initiate_download(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                                  std::array<std::uint8_t, 8>& response) {
  // A new initiate request ends any transfer still open: its client has moved on.
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
  std::size_t announced = 0;
  if (size_indicated) {
    announced = static_cast<std::size_t>(request[4] | (request[5] << 8) | (request[6] << 16) |
                                         (static_cast<std::uint32_t>(request[7]) << 24));
    if (announced > object_size) return abort(index, sub, SdoAbort::LengthTooHigh, response);
    if (announced < object_size) return abort(index, sub, SdoAbort::LengthTooLow, response);
  }
  if (object_size > buffer_.size()) return abort(index, sub, SdoAbort::LengthTooHigh, response);

  state_ = State::Downloading;
  index_ = index;
  sub_ = sub;
  toggle_ = 0;
  announced_size_ = announced;
  object_size_ = object_size;
  length_ = 0;
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
  if (length_ + data_bytes > object_size_) {
    return abort(index_, sub_, SdoAbort::LengthTooHigh, response);
  }
  std::copy_n(request.begin() + 1, data_bytes, buffer_.begin() + static_cast<long>(length_));
  length_ += data_bytes;
  last_activity_us_ = now_us;

  if ((request[0] & kLastSegmentBit) != 0) {
    if (announced_size_ != 0 && length_ != announced_size_) {
      return abort(index_, sub_, SdoAbort::LengthMismatch, response);
    }
    const SdoAbort result =
        objects_.write(objects_.context, index_, sub_, std::span<const std::uint8_t>(buffer_.data(), length_), now_us);
    if (result != SdoAbort::None) return abort(index_, sub_, result, response);
    state_ = State::Idle;
  }
  response = {static_cast<std::uint8_t>(0x20 | toggle)};
  toggle_ ^= kToggleBit;
  return true;
}

bool SdoServer::initiate_upload(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                                std::array<std::uint8_t, 8>& response) {
  state_ = State::Idle;
  const std::uint16_t index = request_index(request);
  const std::uint8_t sub = request[3];
  std::size_t length = 0;
  const SdoAbort result = objects_.read(objects_.context, index, sub, buffer_, length);
  if (result != SdoAbort::None) return abort(index, sub, result, response);

  response = {};
  put_multiplexer(response, index, sub);
  if (length <= 4) {
    // Expedited, size indicated: n = number of unused bytes in 4..7.
    response[0] = static_cast<std::uint8_t>(0x43 | ((4u - length) << 2));
    std::copy_n(buffer_.begin(), length, response.begin() + 4);
    return true;
  }
  response[0] = 0x41;  // segmented, size indicated
  put_u32(response, 4, static_cast<std::uint32_t>(length));
  state_ = State::Uploading;
  index_ = index;
  sub_ = sub;
  toggle_ = 0;
  length_ = length;
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

  const std::size_t chunk = std::min<std::size_t>(7, length_ - offset_);
  response = {};
  std::copy_n(buffer_.begin() + static_cast<long>(offset_), chunk, response.begin() + 1);
  offset_ += chunk;
  const bool last = offset_ == length_;
  response[0] = static_cast<std::uint8_t>(toggle | ((7u - chunk) << 1) | (last ? kLastSegmentBit : 0));
  toggle_ ^= kToggleBit;
  last_activity_us_ = now_us;
  if (last) state_ = State::Idle;
  return true;
}

bool SdoServer::check_timeout(std::uint32_t now_us, std::array<std::uint8_t, 8>& response) {
  if (state_ == State::Idle) return false;
  // Unsigned difference: correct across the 32-bit wrap of now_us.
  if (now_us - last_activity_us_ < kSegmentTimeoutUs) return false;
  return abort(index_, sub_, SdoAbort::ProtocolTimedOut, response);
}

}  // namespace co
