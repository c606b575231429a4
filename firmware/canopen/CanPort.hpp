// The one hardware boundary of the CANopen engine: classic CAN frames in and out.
#pragma once

#include <array>
#include <cstdint>

namespace co {

// A classic CAN frame. `id` uses the SocketCAN `can_id` layout so a Linux port copies it as is:
// bits 0..10 hold a standard identifier; the flag bits below mark frames the engine ignores.
struct CanFrame {
  static constexpr std::uint32_t kExtendedFlag = 0x8000'0000u;  // 29-bit identifier
  static constexpr std::uint32_t kRemoteFlag = 0x4000'0000u;    // remote transmission request
  static constexpr std::uint32_t kErrorFlag = 0x2000'0000u;     // controller error frame

  std::uint32_t id = 0;
  std::uint8_t len = 0;  // 0..8 data bytes
  std::array<std::uint8_t, 8> data{};

  friend bool operator==(const CanFrame&, const CanFrame&) = default;
};

enum class SendResult : std::uint8_t {
  Sent,        // queued for transmission
  QueueFull,   // transmit queue full right now; the frame was NOT queued (caller decides to drop)
  PortError,   // the interface is down or failed; the frame was NOT queued
};

enum class ReceiveResult : std::uint8_t {
  Received,   // `frame` holds the next received frame
  Empty,      // nothing pending; `frame` untouched
  PortError,  // the interface failed; `frame` untouched
};

// Non-blocking CAN interface. Implementations: SocketCAN (platform/linux) and MemoryPort (tests).
class CanPort {
 public:
  virtual ~CanPort() = default;
  virtual SendResult send(const CanFrame& frame) = 0;
  virtual ReceiveResult receive(CanFrame& frame) = 0;

 protected:
  CanPort() = default;
  CanPort(const CanPort&) = default;
  CanPort& operator=(const CanPort&) = default;
};

}  // namespace co
