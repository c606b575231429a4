#include "SocketCanPort.hpp"

#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>

namespace linuxhw {

SocketCanPort::~SocketCanPort() {
  if (fd_ >= 0) {
    ::close(fd_);
  }
}

bool SocketCanPort::open(const std::string& interface, std::string& error) {
  if (interface.empty() || interface.size() >= IFNAMSIZ) {
    error = "invalid CAN interface name '" + interface + "'";
    return false;
  }
  fd_ = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd_ < 0) {
    error = std::string("cannot open a SocketCAN socket: ") + std::strerror(errno) +
            (errno == EAFNOSUPPORT ? " (this kernel has no CAN support: run through tools/with-vcan)" : "");
    return false;
  }
  ifreq request{};
  std::copy(interface.begin(), interface.end(), request.ifr_name);
  if (::ioctl(fd_, SIOCGIFINDEX, &request) < 0) {
    error = errno == ENODEV
                ? "no such CAN interface " + interface + ": create it with `make vcan` (root), or run through tools/with-vcan"
                : "cannot look up CAN interface " + interface + ": " + std::strerror(errno);
    return false;
  }
  // Error frames are counted, not acted on: a HIL rig wants to see bus trouble in the stats.
  const can_err_mask_t error_mask = CAN_ERR_MASK;
  ::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &error_mask, sizeof(error_mask));
  // The kernel then tells, with each frame, how many it dropped on this socket so far.
  const int report_drops = 1;
  ::setsockopt(fd_, SOL_SOCKET, SO_RXQ_OVFL, &report_drops, sizeof(report_drops));
  sockaddr_can address{};
  address.can_family = AF_CAN;
  address.can_ifindex = request.ifr_ifindex;
  if (::bind(fd_, reinterpret_cast<sockaddr*>(&address), sizeof(address)) < 0) {
    error = "cannot bind to CAN interface " + interface + ": " + std::strerror(errno);
    return false;
  }
  return true;
}

bool SocketCanPort::accept_only(std::span<const std::uint32_t> cob_ids) {
  // Exact 11-bit matches; the flag bits in the mask make remote and 29-bit frames on those ids
  // miss too (the node ignores them anyway).
  std::array<can_filter, kMaxAcceptedIds> filters{};
  if (cob_ids.empty() || cob_ids.size() > filters.size()) {
    ++counters_.filter_failures;
    (void)accept_all();
    return false;
  }
  for (std::size_t i = 0; i < cob_ids.size(); ++i) {
    filters[i].can_id = cob_ids[i] & CAN_SFF_MASK;
    filters[i].can_mask = CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG;
  }
  // The kernel registers the new filters before it drops the old ones, so an id in both sets
  // never misses a frame.
  if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FILTER, filters.data(),
                   static_cast<socklen_t>(cob_ids.size() * sizeof(can_filter))) == 0) {
    return true;
  }
  ++counters_.filter_failures;
  (void)accept_all();
  return false;
}

bool SocketCanPort::accept_all() {
  const can_filter everything{.can_id = 0, .can_mask = 0};
  return ::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FILTER, &everything, sizeof(everything)) == 0;
}

co::SendResult SocketCanPort::send(const co::CanFrame& frame) {
  can_frame raw{};
  raw.can_id = frame.id;
  raw.len = std::min<std::uint8_t>(frame.len, CAN_MAX_DLEN);
  std::copy_n(frame.data.begin(), raw.len, raw.data);
  const ssize_t written = ::write(fd_, &raw, sizeof(raw));
  if (written == static_cast<ssize_t>(sizeof(raw))) {
    return co::SendResult::Sent;
  }
  if (written < 0 && (errno == ENOBUFS || errno == EAGAIN)) {
    ++counters_.send_queue_full;
    return co::SendResult::QueueFull;
  }
  ++counters_.send_errors;
  return co::SendResult::PortError;
}

co::ReceiveResult SocketCanPort::read_batch() {
  std::array<mmsghdr, kReceiveBatch> messages{};
  std::array<iovec, kReceiveBatch> payloads{};
  struct Control {
    alignas(cmsghdr) char bytes[CMSG_SPACE(sizeof(std::uint32_t))];
  };
  std::array<Control, kReceiveBatch> controls{};
  for (std::size_t i = 0; i < kReceiveBatch; ++i) {
    payloads[i] = {&batch_[i], sizeof(can_frame)};
    messages[i].msg_hdr.msg_iov = &payloads[i];
    messages[i].msg_hdr.msg_iovlen = 1;
    messages[i].msg_hdr.msg_control = controls[i].bytes;
    messages[i].msg_hdr.msg_controllen = sizeof(controls[i].bytes);
  }
  filled_ = next_ = 0;
  int got = -1;
  do got = ::recvmmsg(fd_, messages.data(), kReceiveBatch, MSG_DONTWAIT, nullptr);
  while (got < 0 && errno == EINTR);
  if (got < 0) {
    if (errno == EAGAIN || errno == EWOULDBLOCK) {
      return co::ReceiveResult::Empty;
    }
    ++counters_.receive_errors;
    return co::ReceiveResult::PortError;
  }
  for (std::size_t i = 0; i < static_cast<std::size_t>(got); ++i) {
    msghdr& message = messages[i].msg_hdr;
    for (cmsghdr* c = CMSG_FIRSTHDR(&message); c != nullptr; c = CMSG_NXTHDR(&message, c)) {
      if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL) {
        std::memcpy(&counters_.receive_overruns, CMSG_DATA(c), sizeof(counters_.receive_overruns));
      }
    }
    lengths_[i] = messages[i].msg_len;
  }
  filled_ = static_cast<std::size_t>(got);
  drained_ = filled_ < kReceiveBatch;
  return filled_ > 0 ? co::ReceiveResult::Received : co::ReceiveResult::Empty;
}

co::ReceiveResult SocketCanPort::receive(co::CanFrame& frame) {
  for (;;) {
    if (next_ == filled_) {
      if (drained_) {
        drained_ = false;
        return co::ReceiveResult::Empty;
      }
      const co::ReceiveResult read = read_batch();
      if (read != co::ReceiveResult::Received) {
        return read;
      }
    }
    const can_frame& raw = batch_[next_];
    const std::size_t length = lengths_[next_];
    ++next_;
    if (length != sizeof(raw)) {
      ++counters_.short_frames;
      continue;
    }
    if ((raw.can_id & CAN_ERR_FLAG) != 0) {
      ++counters_.error_frames;
      continue;
    }
    frame.id = raw.can_id;
    frame.len = std::min<std::uint8_t>(raw.len, CAN_MAX_DLEN);
    frame.data = {};
    std::copy_n(raw.data, frame.len, frame.data.begin());
    return co::ReceiveResult::Received;
  }
}

}  // namespace linuxhw
