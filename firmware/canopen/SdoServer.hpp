// SDO server (CiA 301, 7.2.4): expedited and segmented upload and download on one channel.
// Block transfer is not supported; its requests are answered with CommandSpecifierInvalid.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "CanPort.hpp"
#include "SdoAbort.hpp"

namespace co {

// What the SDO server needs from the object dictionary: three calls on `context`. Plain
// function pointers rather than virtual functions: the engine is built without RTTI, and a
// polymorphic engine class would need typeinfo that RTTI-enabled code (tests and the platform,
// which also run UBSan's vptr checks) cannot find.
struct ObjectAccess {
  void* context = nullptr;
  // Size in bytes of the object's value, or the abort (object/sub-index missing, read-only...)
  // when it cannot be written at all. Checked before a segmented download starts.
  SdoAbort (*check_writable)(void* context, std::uint16_t index, std::uint8_t sub,
                             std::size_t& size) = nullptr;
  // Copies the value into `out` and sets `length`, or returns the abort to send.
  SdoAbort (*read)(void* context, std::uint16_t index, std::uint8_t sub,
                   std::span<std::uint8_t> out, std::size_t& length) = nullptr;
  // Writes the value (exactly the bytes the client sent), or returns the abort to send.
  SdoAbort (*write)(void* context, std::uint16_t index, std::uint8_t sub,
                    std::span<const std::uint8_t> data, std::uint32_t now_us) = nullptr;
};

class SdoServer {
 public:
  // A client that lets this long pass between segments gets ProtocolTimedOut.
  static constexpr std::uint32_t kSegmentTimeoutUs = 1'000'000;
  // Largest value moved by segmented transfer (the longest string object fits).
  static constexpr std::size_t kBufferBytes = 64;

  // `objects.context` must outlive the server.
  explicit SdoServer(const ObjectAccess& objects) : objects_(objects) {}
  SdoServer(const SdoServer&) = delete;
  SdoServer& operator=(const SdoServer&) = delete;

  // Handles one request (data of a frame to 0x600+id). Returns true when `response` (data of a
  // frame to 0x580+id, always 8 bytes) must be sent.
  bool handle(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
              std::array<std::uint8_t, 8>& response);

  // Aborts a segmented transfer whose client fell silent. Returns true when `response` (the
  // abort) must be sent.
  bool check_timeout(std::uint32_t now_us, std::array<std::uint8_t, 8>& response);

  // Forgets any transfer in progress without answering (NMT stop or reset).
  void reset() { state_ = State::Idle; }

  bool transfer_in_progress() const { return state_ != State::Idle; }
  std::uint32_t aborts_sent() const { return aborts_sent_; }
  SdoAbort last_abort() const { return last_abort_; }

 private:
  enum class State : std::uint8_t { Idle, Downloading, Uploading };

  bool abort(std::uint16_t index, std::uint8_t sub, SdoAbort code,
             std::array<std::uint8_t, 8>& response);
  bool initiate_download(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                         std::array<std::uint8_t, 8>& response);
  bool download_segment(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                        std::array<std::uint8_t, 8>& response);
  bool initiate_upload(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                       std::array<std::uint8_t, 8>& response);
  bool upload_segment(std::span<const std::uint8_t, 8> request, std::uint32_t now_us,
                      std::array<std::uint8_t, 8>& response);

  ObjectAccess objects_;
  State state_ = State::Idle;
  std::uint16_t index_ = 0;
  std::uint8_t sub_ = 0;
  std::uint8_t toggle_ = 0;              // expected toggle bit of the next segment (0 or 0x10)
  std::uint32_t last_activity_us_ = 0;
  std::size_t announced_size_ = 0;       // download: size from the initiate request, 0 = none
  std::size_t object_size_ = 0;          // download: size of the target object
  std::size_t length_ = 0;               // bytes in buffer_ (download: received; upload: total)
  std::size_t offset_ = 0;               // upload: bytes already sent
  std::array<std::uint8_t, kBufferBytes> buffer_{};
  std::uint32_t aborts_sent_ = 0;
  SdoAbort last_abort_ = SdoAbort::None;
};

}  // namespace co
