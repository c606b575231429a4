#include "ProgramDownload.hpp"

#include <algorithm>
#include <cstring>

#include "ParameterImage.hpp"

namespace co {
namespace {

using cia302::FlashError;
using cia302::ProgramControl;
namespace field = cia302::image_field;

std::uint32_t get_u32(std::span<const std::uint8_t> bytes, std::size_t at) {
  return bytes[at] | (bytes[at + 1] << 8) | (bytes[at + 2] << 16) |
         (static_cast<std::uint32_t>(bytes[at + 3]) << 24);
}

std::uint16_t get_u16(std::span<const std::uint8_t> bytes, std::size_t at) {
  return static_cast<std::uint16_t>(bytes[at] | (bytes[at + 1] << 8));
}

std::uint32_t crc32(std::span<const std::uint8_t> bytes, std::uint32_t previous) {
  return parameter_image::crc32(std::as_bytes(bytes), previous);
}

}  // namespace

SdoAbort ProgramDownload::refuse(FlashError error, SdoAbort abort) {
  status_ = cia302::flash_status(error, false);
  if (transferring_ && store_ != nullptr) store_->discard_staging();
  transferring_ = false;
  return abort;
}

SdoAbort ProgramDownload::open(std::size_t announced_size) {
  if (transferring_) cancel();
  // CiA 302-3: the program area must be cleared (which needs the program stopped) first.
  if (store_ == nullptr) return refuse(FlashError::FlashSecured, SdoAbort::DataCannotBeStored);
  if (state_ != ProgramControl::Clear) return refuse(FlashError::FlashNotCleared, SdoAbort::DeviceState);
  if (announced_size != 0 && announced_size < cia302::kImageHeaderBytes) {
    return refuse(FlashError::DataFormatUnknown, SdoAbort::DataCannotBeStored);
  }
  if (!store_->open_staging()) return refuse(FlashError::FlashWriteError, SdoAbort::HardwareError);
  transferring_ = true;
  kept_ = false;
  announced_ = announced_size;
  header_bytes_ = 0;
  payload_length_ = 0;
  payload_crc32_ = 0;
  payload_received_ = 0;
  running_crc32_ = 0;
  status_ = cia302::flash_status(FlashError::NoError, true);
  return SdoAbort::None;
}

FlashError ProgramDownload::check_header() const {
  const std::span<const std::uint8_t> header(header_);
  if (!std::equal(cia302::kImageMagic.begin(), cia302::kImageMagic.end(), header.begin() + field::kMagic)) {
    return FlashError::DataFormatUnknown;
  }
  if (get_u16(header, field::kFormatVersion) != cia302::kImageFormatVersion ||
      get_u16(header, field::kHeaderBytes) != cia302::kImageHeaderBytes) {
    return FlashError::DataFormatUnknown;
  }
  if (crc32(header.first(field::kHeaderCrc32), 0) != get_u32(header, field::kHeaderCrc32)) {
    return FlashError::DataFormatError;
  }
  if (get_u32(header, field::kProductCode) != product_code_) return FlashError::WrongBoard;
  const std::uint32_t length = get_u32(header, field::kPayloadLength);
  if (announced_ != 0 && announced_ != cia302::kImageHeaderBytes + std::size_t{length}) {
    return FlashError::DataFormatError;
  }
  return FlashError::NoError;
}

SdoAbort ProgramDownload::append(std::span<const std::uint8_t> bytes) {
  if (!transferring_) return SdoAbort::GeneralError;
  if (header_bytes_ < header_.size()) {
    const std::size_t take = std::min(bytes.size(), header_.size() - header_bytes_);
    std::copy_n(bytes.begin(), take, header_.begin() + static_cast<long>(header_bytes_));
    header_bytes_ += take;
    bytes = bytes.subspan(take);
    if (header_bytes_ < header_.size()) return SdoAbort::None;
    // The whole header is in: a wrong image goes no further.
    if (const FlashError error = check_header(); error != FlashError::NoError) {
      return refuse(error, SdoAbort::DataCannotBeStored);
    }
    payload_length_ = get_u32(header_, field::kPayloadLength);
    payload_crc32_ = get_u32(header_, field::kPayloadCrc32);
  }
  if (bytes.empty()) return SdoAbort::None;
  if (bytes.size() > payload_length_ - payload_received_) {
    return refuse(FlashError::DataFormatError, SdoAbort::DataCannotBeStored);
  }
  running_crc32_ = crc32(bytes, running_crc32_);
  payload_received_ += bytes.size();
  if (!store_->write_staging(bytes)) return refuse(FlashError::FlashWriteError, SdoAbort::HardwareError);
  return SdoAbort::None;
}

SdoAbort ProgramDownload::close() {
  if (!transferring_) return SdoAbort::GeneralError;
  if (header_bytes_ < header_.size()) return refuse(FlashError::DataFormatUnknown, SdoAbort::DataCannotBeStored);
  if (payload_received_ != payload_length_ || running_crc32_ != payload_crc32_) {
    return refuse(FlashError::DataFormatError, SdoAbort::DataCannotBeStored);
  }
  if (!store_->commit_staging()) return refuse(FlashError::FlashWriteError, SdoAbort::HardwareError);
  transferring_ = false;
  kept_ = true;
  // As CANopenNode's: a complete download leaves the program stopped, waiting for Start.
  state_ = ProgramControl::Stop;
  status_ = cia302::flash_status(FlashError::NoError, false);
  return SdoAbort::None;
}

void ProgramDownload::cancel() {
  if (!transferring_) return;
  (void)refuse(FlashError::TransferBrokenOff, SdoAbort::None);
}

SdoAbort ProgramDownload::control(std::uint32_t value) {
  if (transferring_) return SdoAbort::DeviceState;
  switch (value) {
    case static_cast<std::uint32_t>(ProgramControl::Stop):
      state_ = ProgramControl::Stop;
      return SdoAbort::None;
    case static_cast<std::uint32_t>(ProgramControl::Start):
      if (kept_) start_requested_ = true;
      state_ = ProgramControl::Start;
      return SdoAbort::None;
    case static_cast<std::uint32_t>(ProgramControl::Clear):
      if (state_ == ProgramControl::Start) return SdoAbort::DeviceState;  // stop it first
      if (store_ != nullptr) store_->discard_staging();
      kept_ = false;
      state_ = ProgramControl::Clear;
      status_ = cia302::flash_status(FlashError::NoError, false);
      return SdoAbort::None;
    default: return SdoAbort::ValueRangeExceeded;
  }
}

std::uint32_t ProgramDownload::read(std::uint16_t index, std::uint8_t sub) const {
  if (sub == 0) return cia302::kProgramNumber;
  switch (index) {
    case cia302::kProgramControlIndex: return static_cast<std::uint32_t>(state_);
    case cia302::kSoftwareIdIndex: return store_ != nullptr ? store_->running_image_crc32() : 0;
    case cia302::kFlashStatusIndex: return status_;
    default: return 0;
  }
}

}  // namespace co
