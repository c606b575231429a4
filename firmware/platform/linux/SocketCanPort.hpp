// co::CanPort over a raw Linux SocketCAN socket (vcan0, can0, any SocketCAN interface).
#pragma once

#include <linux/can.h>

#include <array>
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
  // The next frame, from what one recvmmsg() took out of the socket (up to kReceiveBatch at a
  // time: a cycle's RPDOs and SYNC in one system call, not one each). Empty once a read found
  // the socket drained; a caller that polls fd() for more first hands out what is buffered.
  co::ReceiveResult receive(co::CanFrame& frame) override;
  // Frames already read from the socket and not yet handed out: fd() does not show them.
  bool has_buffered_frames() const { return next_ < filled_; }

  static constexpr std::size_t kReceiveBatch = 16;

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
  // Reads what the socket holds into batch_ (none: Empty; a failure: PortError).
  co::ReceiveResult read_batch();

  int fd_ = -1;
  SocketCanCounters counters_;
  std::array<can_frame, kReceiveBatch> batch_{};
  std::array<std::size_t, kReceiveBatch> lengths_{};
  std::size_t filled_ = 0;  // frames in batch_
  std::size_t next_ = 0;    // the next one to hand out
  // The last read took fewer than a batch: the socket was empty then, so once batch_ is handed
  // out receive() says Empty without asking the kernel again (and reads on the call after).
  bool drained_ = false;
};

}  // namespace linuxhw
