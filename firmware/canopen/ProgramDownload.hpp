// CiA 302-3 program download: the objects 0x1F50 (program data), 0x1F51 (program control),
// 0x1F56 (software identification) and 0x1F57 (flash status), and the checks an image passes
// before the node will start it. The values, indices and the image header's layout come from
// boardproto.cia302 (board/cia302.hpp).
//
// The sequence is CiA 302-3's, as CANopenNode's program download does it (Zephyr's
// canopen_program.c): write 0x1F51 = Stop, then Clear (drops any staged image), block-download
// the image into 0x1F50, write Start. The image streams through: the header is checked as soon
// as its bytes are in (magic, format, header CRC, this board's product code), the payload goes
// to the platform's staging area piece by piece with a running CRC-32, and only a complete image
// whose length and CRC-32 match its header is kept. Anything else (a refused header, an abort, a
// client that fell silent) discards the staged bytes; the running program is never touched.
// Start with a kept image asks the platform to run it (start_requested()): on the Linux target
// the process re-executes itself from the new image after the SDO answer went out.
//
// Hardware-agnostic; no heap. The platform stores the bytes (ProgramStore).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "SdoAbort.hpp"
#include "board/cia302.hpp"

namespace co {

// Where a downloaded image goes: the platform's staging area (a file next to the running image
// on Linux, a second flash bank on a microcontroller).
class ProgramStore {
 public:
  virtual ~ProgramStore() = default;
  // Starts an empty staging area, dropping whatever it held. false: cannot (the download is
  // refused with a hardware error).
  virtual bool open_staging() = 0;
  // Appends bytes of the payload. false: could not write them.
  virtual bool write_staging(std::span<const std::uint8_t> bytes) = 0;
  // The payload is complete and checked: keep it durably as the image Start will run.
  virtual bool commit_staging() = 0;
  // Drops a partial or kept staged image; the running one stays.
  virtual void discard_staging() = 0;
  // CRC-32 (zlib's) of the image that runs now; 0 when it cannot be read.
  virtual std::uint32_t running_image_crc32() = 0;

 protected:
  ProgramStore() = default;
  ProgramStore(const ProgramStore&) = default;
  ProgramStore& operator=(const ProgramStore&) = default;
};

class ProgramDownload {
 public:
  // `product_code`: 0x1018:02 of this board; an image for another product is refused.
  explicit ProgramDownload(std::uint32_t product_code) : product_code_(product_code) {}
  ProgramDownload(const ProgramDownload&) = delete;
  ProgramDownload& operator=(const ProgramDownload&) = delete;

  // Without a store the objects still exist, but a download is refused: the flash is secured
  // (FlashError::FlashSecured). Must outlive this object.
  void set_store(ProgramStore* store) { store_ = store; }

  // 0x1F50:01 as the SDO server's stream (ObjectAccess::stream_*).
  SdoAbort open(std::size_t announced_size);
  SdoAbort append(std::span<const std::uint8_t> bytes);
  SdoAbort close();
  void cancel();

  // 0x1F51:01 write. Stop and Start without a kept image change only the program's state;
  // Start with one sets start_requested(). Reset (2) and unknown values: ValueRangeExceeded.
  SdoAbort control(std::uint32_t value);
  // Sub 0 of every object reads 1; 0x1F51:01 the program's state, 0x1F56:01 the running
  // image's CRC-32, 0x1F57:01 the flash status.
  std::uint32_t read(std::uint16_t index, std::uint8_t sub) const;

  cia302::ProgramControl state() const { return state_; }
  std::uint32_t flash_status() const { return status_; }
  bool image_kept() const { return kept_; }
  // Start arrived with a kept image: the platform runs it once the answer is sent.
  bool start_requested() const { return start_requested_; }
  bool transfer_in_progress() const { return transferring_; }

 private:
  SdoAbort refuse(cia302::FlashError error, SdoAbort abort);
  cia302::FlashError check_header() const;

  std::uint32_t product_code_;
  ProgramStore* store_ = nullptr;
  cia302::ProgramControl state_ = cia302::ProgramControl::Start;
  std::uint32_t status_ = cia302::flash_status(cia302::FlashError::NoError, false);
  bool kept_ = false;
  bool start_requested_ = false;

  // The transfer under way.
  bool transferring_ = false;
  std::size_t announced_ = 0;
  std::array<std::uint8_t, cia302::kImageHeaderBytes> header_{};
  std::size_t header_bytes_ = 0;
  std::uint32_t payload_length_ = 0;
  std::uint32_t payload_crc32_ = 0;  // from the header
  std::size_t payload_received_ = 0;
  std::uint32_t running_crc32_ = 0;  // of the payload received so far
};

}  // namespace co
