// co::CanPort over a raw Linux SocketCAN socket (vcan0, can0, any SocketCAN interface).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "canopen/CanPort.hpp"
#include "canopen/Interfaces.hpp"

namespace linuxhw {

struct SocketCanCounters {
  std::uint32_t error_frames = 0;     // controller error frames reported by the driver
  std::uint32_t receive_errors = 0;   // recv() failures other than "nothing pending"
  std::uint32_t short_frames = 0;     // reads that were not a whole classic CAN frame
  std::uint32_t send_queue_full = 0;  // ENOBUFS/EAGAIN: the frame was dropped
  std::uint32_t send_errors = 0;      // other send failures
  // Frames the kernel dropped because this socket's receive queue was full (SO_RXQ_OVFL): a
  // CAN controller's receive overrun. A flood the loop cannot drain shows up here, not silently.
  std::uint32_t receive_overruns = 0;
  // setsockopt(CAN_RAW_FILTER) refused a new acceptance set: the socket then takes every frame
  // (as without a filter) rather than keep a set that may lack an id the node now needs.
  std::uint32_t filter_failures = 0;
};

// As a co::AcceptanceListener it is the node's hardware acceptance filter: the kernel drops
// every frame outside the node's set before it wakes the firmware.
class SocketCanPort final : public co::CanPort, public co::AcceptanceListener {
 public:
  SocketCanPort() = default;
  SocketCanPort(const SocketCanPort&) = delete;
  SocketCanPort& operator=(const SocketCanPort&) = delete;
  ~SocketCanPort() override;

  // Opens a non-blocking raw socket bound to `interface`. On failure returns false and
  // `error` says what to do about it (e.g. how to create a missing vcan interface).
  bool open(const std::string& interface, std::string& error);

  co::SendResult send(const co::CanFrame& frame) override;
  co::ReceiveResult receive(co::CanFrame& frame) override;

  static constexpr std::size_t kMaxAcceptedIds = 32;  // a node lists a handful (no heap here)

  // From now on only standard data frames on these 11-bit ids are received (error frames as
  // before). Frames already queued in the socket stay queued. false: the kernel refused it;
  // the socket then receives every frame again.
  bool accept_only(std::span<const std::uint32_t> cob_ids);
  // Every frame again (the state after open()).
  bool accept_all();
  void accepted_ids_changed(std::span<const std::uint32_t> cob_ids) override { (void)accept_only(cob_ids); }

  int fd() const { return fd_; }
  const SocketCanCounters& counters() const { return counters_; }

 private:
  int fd_ = -1;
  SocketCanCounters counters_;
};

}  // namespace linuxhw
