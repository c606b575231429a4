// SocketCanPort's acceptance filter on a real SocketCAN bus: what the kernel lets through after
// accept_only(), and a node wired to it the way main() wires it. Needs a CAN interface (vcan0,
// or $HIL_TEST_CAN_INTERFACE); where the kernel has no CAN support or no such interface (a
// container, a CI runner) every test here is skipped and says why.
#include <gtest/gtest.h>
#include <linux/can.h>
#include <net/if.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "SocketCanPort.hpp"
#include "canopen/NodeTestSupport.hpp"

namespace linuxhw {
namespace {

constexpr int kDeliveryTimeoutMs = 1000;
constexpr std::uint32_t kAnyId = 0x555;  // protocol-literal: an identifier of no service here

std::string test_interface() {
  const char* name = std::getenv("HIL_TEST_CAN_INTERFACE");
  return name != nullptr && *name != '\0' ? name : "vcan0";
}

// A second raw socket on the same bus: the other nodes and the master.
class BusPeer {
 public:
  ~BusPeer() {
    if (fd_ >= 0) ::close(fd_);
  }
  bool open(const std::string& interface) {
    fd_ = ::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
    if (fd_ < 0) return false;
    ifreq request{};
    std::strncpy(request.ifr_name, interface.c_str(), IFNAMSIZ - 1);
    if (::ioctl(fd_, SIOCGIFINDEX, &request) < 0) return false;
    sockaddr_can address{};
    address.can_family = AF_CAN;
    address.can_ifindex = request.ifr_ifindex;
    return ::bind(fd_, reinterpret_cast<sockaddr*>(&address), sizeof(address)) == 0;
  }
  void send(std::uint32_t can_id, std::vector<std::uint8_t> data = {}) {
    can_frame frame{};
    frame.can_id = can_id;
    frame.len = static_cast<std::uint8_t>(data.size());
    std::copy(data.begin(), data.end(), frame.data);
    ASSERT_EQ(::write(fd_, &frame, sizeof(frame)), static_cast<ssize_t>(sizeof(frame)))
        << std::strerror(errno);
  }
  std::optional<can_frame> receive() {
    pollfd ready{fd_, POLLIN, 0};
    if (::poll(&ready, 1, kDeliveryTimeoutMs) <= 0) return std::nullopt;
    can_frame frame{};
    if (::read(fd_, &frame, sizeof(frame)) != static_cast<ssize_t>(sizeof(frame))) return std::nullopt;
    return frame;
  }

 private:
  int fd_ = -1;
};

class SocketCanPortTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    if (!port.open(test_interface(), error)) {
      GTEST_SKIP() << "no SocketCAN bus to test the kernel filter on: " << error;
    }
    ASSERT_TRUE(peer.open(test_interface())) << std::strerror(errno);
  }

  // The next frame the port receives, waiting for the kernel to deliver it (as main() waits:
  // not while the port still holds frames it has read).
  std::optional<co::CanFrame> next() {
    co::CanFrame frame;
    for (int attempt = 0; attempt < 2; ++attempt) {
      if (!port.has_buffered_frames()) {
        pollfd ready{port.fd(), POLLIN, 0};
        if (::poll(&ready, 1, kDeliveryTimeoutMs) <= 0) return std::nullopt;
      }
      // A read that found the socket drained says Empty once; the next one asks the kernel.
      if (port.receive(frame) == co::ReceiveResult::Received) return frame;
    }
    return std::nullopt;
  }
  // The ids the port receives up to and including `marker` (sent last, on an accepted id):
  // frames on one bus arrive in order, so whatever the filter let through came before it.
  std::vector<std::uint32_t> ids_until(std::uint32_t marker) {
    std::vector<std::uint32_t> ids;
    while (const std::optional<co::CanFrame> frame = next()) {
      ids.push_back(frame->id);
      if (frame->id == marker) break;
    }
    return ids;
  }

  SocketCanPort port;
  BusPeer peer;
};

TEST_F(SocketCanPortTest, AnInterfaceThatIsNotCanIsRefusedWithItsCause) {
  // The loopback device exists, so its index is found, and the kernel's CAN_RAW bind refuses a
  // device that is not CAN: the error says which step failed, on which interface, and why.
  SocketCanPort other;
  std::string error;
  EXPECT_FALSE(other.open("lo", error));
  EXPECT_EQ(error, "cannot bind to CAN interface lo: No such device");
  SocketCanPort absent;
  EXPECT_FALSE(absent.open("no-such-can9", error));
  EXPECT_EQ(error, "no such CAN interface no-such-can9: create it with `make vcan` (root), or run through tools/with-vcan");
}

TEST_F(SocketCanPortTest, AcceptOnlyPassesExactlyTheListedStandardDataFrames) {
  constexpr std::uint32_t kMarker = 0x000;
  const std::vector<std::uint32_t> accepted = {kMarker, 0x123};
  ASSERT_TRUE(port.accept_only(accepted));
  peer.send(0x123, {1});
  peer.send(0x124, {2});
  peer.send(0x123 | CAN_RTR_FLAG);
  peer.send(0x123 | CAN_EFF_FLAG, {3});
  peer.send(0x7FF, {4});
  peer.send(kMarker, {0x01, 0x00});
  EXPECT_EQ(ids_until(kMarker), (std::vector<std::uint32_t>{0x123, kMarker}));
  EXPECT_EQ(port.counters().filter_failures, 0u);
}

TEST_F(SocketCanPortTest, FramesQueuedBeforeAFilterChangeStayQueued) {
  ASSERT_TRUE(port.accept_only(std::vector<std::uint32_t>{0x123}));
  peer.send(0x123, {1});  // queued under the old filter
  // Let it reach the socket's queue before the filter changes.
  pollfd ready{port.fd(), POLLIN, 0};
  ASSERT_EQ(::poll(&ready, 1, kDeliveryTimeoutMs), 1);
  ASSERT_TRUE(port.accept_only(std::vector<std::uint32_t>{0x124}));
  peer.send(0x123, {2});
  peer.send(0x124, {3});
  EXPECT_EQ(ids_until(0x124), (std::vector<std::uint32_t>{0x123, 0x124}));
}

TEST_F(SocketCanPortTest, AcceptAllReceivesEveryFrameAgain) {
  ASSERT_TRUE(port.accept_only(std::vector<std::uint32_t>{0x123}));
  ASSERT_TRUE(port.accept_all());
  peer.send(kAnyId, {1});
  peer.send(0x123 | CAN_RTR_FLAG);
  EXPECT_EQ(ids_until(0x123 | CAN_RTR_FLAG), (std::vector<std::uint32_t>{kAnyId, 0x123 | CAN_RTR_FLAG}));
}

TEST_F(SocketCanPortTest, AnEmptySetIsRefusedAndTheSocketTakesEverything) {
  EXPECT_FALSE(port.accept_only({}));
  EXPECT_EQ(port.counters().filter_failures, 1u);
  peer.send(kAnyId, {1});
  EXPECT_EQ(ids_until(kAnyId), (std::vector<std::uint32_t>{kAnyId}));
}

// One recvmmsg() reads up to a batch; what is beyond it comes with the next read, in bus order,
// and a drained socket says Empty.
TEST_F(SocketCanPortTest, FramesBeyondOneBatchArriveInBusOrder) {
  constexpr std::size_t kFrames = 2 * SocketCanPort::kReceiveBatch + 3;
  for (std::size_t i = 0; i < kFrames; ++i) peer.send(kAnyId, {static_cast<std::uint8_t>(i)});
  std::vector<std::uint8_t> seen;
  while (seen.size() < kFrames) {
    const std::optional<co::CanFrame> frame = next();
    if (!frame) break;
    seen.push_back(frame->data[0]);
  }
  ASSERT_EQ(seen.size(), kFrames);
  for (std::size_t i = 0; i < kFrames; ++i) EXPECT_EQ(seen[i], i) << "frame " << i;
  co::CanFrame frame;
  EXPECT_EQ(port.receive(frame), co::ReceiveResult::Empty);
  EXPECT_FALSE(port.has_buffered_frames());
  EXPECT_EQ(port.counters().short_frames + port.counters().receive_errors, 0u);
}

// main()'s wiring: the node's set reaches the kernel at start() and with the SDO answer that
// enables an RPDO, so an RPDO sent right after that answer is not lost.
TEST_F(SocketCanPortTest, TheNodeSetsTheFilterBeforeItAnswers) {
  constexpr std::uint8_t kNodeId = 0x10;
  co::test::FakeBoard fields;
  co::test::FakeHil hil;
  co::test::MemoryStorage storage;
  co::Node node{kNodeId, port, fields, hil, storage};
  node.set_acceptance_listener(&port);
  node.start(0);
  ASSERT_TRUE(peer.receive().has_value());  // the boot-up
  auto serve = [&] {
    while (const std::optional<co::CanFrame> frame = next()) {
      node.process(*frame, 0);
      if (frame->id == cia301::cob_id(cia301::FunctionCode::SdoRequest, kNodeId)) return;
    }
  };
  // Expedited, as long as the object is (the node refuses a length that does not match).
  auto download = [&](std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t bytes) {
    const auto command = static_cast<std::uint8_t>(0x23 | ((4 - bytes) << 2));  // protocol-literal: SDO expedited, size given
    peer.send(cia301::cob_id(cia301::FunctionCode::SdoRequest, kNodeId), {command, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8),
                                 sub, static_cast<std::uint8_t>(value), static_cast<std::uint8_t>(value >> 8),
                                 static_cast<std::uint8_t>(value >> 16), static_cast<std::uint8_t>(value >> 24)});
    serve();
    const std::optional<can_frame> answer = peer.receive();
    ASSERT_TRUE(answer.has_value());
    std::uint32_t abort_code = 0;
    std::memcpy(&abort_code, &answer->data[4], sizeof(abort_code));
    EXPECT_EQ(answer->data[0], 0x60) << "SDO abort 0x" << std::hex << abort_code << " writing 0x" << index
                                     << ":" << static_cast<int>(sub);
  };
  constexpr std::uint32_t kRpdo4 = cia301::cob_id(cia301::FunctionCode::Rpdo4, kNodeId);
  peer.send(kRpdo4, {1, 2, 3, 4});  // RPDO4's id, not enabled yet: filtered out
  download(0x1603, 1, 0x2401'0020u, 4);
  download(0x1603, 0, 1, 1);
  download(0x1403, 1, kRpdo4, 4);
  download(0x1017, 0, 0, 2);
  peer.send(0x000, {0x01, kNodeId});  // start
  peer.send(0x7E0, {1});                 // nobody's id
  peer.send(kRpdo4, {0, 0, 0x80, 0x3F});  // at once after the answer: 1.0f
  const std::uint32_t before = node.counters().frames_received;
  std::vector<std::uint32_t> ids;
  while (const std::optional<co::CanFrame> frame = next()) {
    ids.push_back(frame->id);
    node.process(*frame, 0);
    if (frame->id == kRpdo4) break;
  }
  EXPECT_EQ(ids, (std::vector<std::uint32_t>{0x000, kRpdo4}));
  EXPECT_EQ(node.counters().frames_received, before + 2);
  EXPECT_EQ(node.counters().rpdos_received, 1u);
  EXPECT_EQ(node.counters().frames_ignored, 0u);
}

}  // namespace
}  // namespace linuxhw
