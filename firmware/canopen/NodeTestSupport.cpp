#include "NodeTestSupport.hpp"

#include <algorithm>
#include <bit>

namespace co::test {

FakeBoard::FakeBoard() {
  for (std::size_t i = 0; i < board::kFieldCount; ++i) values[i] = board::kFields[i].default_value;
}

WriteResult FakeBoard::write(board::FieldId id, float value) {
  if (refuse[index(id)]) return WriteResult::Refused;
  values[index(id)] = value;
  ++writes[index(id)];
  return WriteResult::Accepted;
}

bool MemoryStorage::save(std::span<const std::byte> image) {
  if (fail_saves) return false;
  bytes.assign(image.begin(), image.end());
  ++saves;
  return true;
}

std::size_t MemoryStorage::load(std::span<std::byte> buffer) {
  if (bytes.size() > buffer.size()) return 0;
  std::copy(bytes.begin(), bytes.end(), buffer.begin());
  return bytes.size();
}

CanFrame make_frame(std::uint32_t id, std::initializer_list<std::uint8_t> data) {
  CanFrame frame;
  frame.id = id;
  frame.len = static_cast<std::uint8_t>(data.size());
  std::copy(data.begin(), data.end(), frame.data.begin());
  return frame;
}

std::array<std::uint8_t, 4> le32(std::uint32_t v) {
  return {static_cast<std::uint8_t>(v), static_cast<std::uint8_t>(v >> 8),
          static_cast<std::uint8_t>(v >> 16), static_cast<std::uint8_t>(v >> 24)};
}

std::uint32_t float_bits(float v) { return std::bit_cast<std::uint32_t>(v); }

std::array<std::uint8_t, 8> abort_data(std::uint16_t index, std::uint8_t sub, SdoAbort code) {
  const auto c = le32(to_code(code));
  return {0x80, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub,
          c[0], c[1], c[2], c[3]};
}

std::uint16_t index_of(board::FieldId id) { return board::info(id).index; }
std::uint16_t index_of(board::HilInputId id) {
  return board::kHilInputs[static_cast<std::size_t>(id)].index;
}
std::uint16_t index_of(board::HilOutputId id) {
  return board::kHilOutputs[static_cast<std::size_t>(id)].index;
}

void NodeTest::SetUp() {
  node.set_recorder(&recorder);
  // The frames a test scripts follow an NMT reset's boot-up at once; BootTimeTest times it.
  node.set_boot_time_us(0);
  node.start(now_us);
  port.clear_sent();  // the boot-up message has its own test
  // Heartbeats would interleave with the frames a test scripts; HeartbeatTest turns them on.
  ASSERT_EQ(download(0x1017, 0, 0, 2), SdoAbort::None);
}

ProcessResult NodeTest::receive(std::uint32_t id, std::initializer_list<std::uint8_t> data) {
  return node.process(make_frame(id, data), now_us);
}

ProcessResult NodeTest::receive(const CanFrame& frame) { return node.process(frame, now_us); }

void NodeTest::nmt(NmtCommand command, std::uint8_t target) {
  receive(0x000, {static_cast<std::uint8_t>(command), target});
}

void NodeTest::sync() {
  const ProcessResult result = receive(cia301::kSyncCobId, {});
  EXPECT_TRUE(result.sync);
  node.transmit_synchronous_pdos(now_us);
}

void NodeTest::advance_us(std::uint32_t us) {
  now_us += us;
  node.poll(now_us);
}

CanFrame NodeTest::next_sent() {
  CanFrame frame;
  EXPECT_TRUE(port.pop_sent(frame)) << "expected the node to have sent a frame";
  return frame;
}

std::vector<CanFrame> NodeTest::all_sent() {
  std::vector<CanFrame> frames;
  CanFrame frame;
  while (port.pop_sent(frame)) frames.push_back(frame);
  return frames;
}

std::array<std::uint8_t, 8> NodeTest::sdo(std::array<std::uint8_t, 8> request) {
  CanFrame frame;
  frame.id = kSdoRx;
  frame.len = 8;
  frame.data = request;
  node.process(frame, now_us);
  const std::vector<CanFrame> sent = all_sent();
  EXPECT_EQ(sent.size(), 1u) << "expected exactly one SDO response";
  if (sent.empty()) return {};
  EXPECT_EQ(sent.front().id, kSdoTx);
  EXPECT_EQ(sent.front().len, 8);
  return sent.front().data;
}

SdoAbort NodeTest::download(std::uint16_t index, std::uint8_t sub, std::uint32_t value,
                            std::uint8_t size) {
  const auto v = le32(value);
  const auto command = static_cast<std::uint8_t>(0x23 | ((4 - size) << 2));
  const auto response = sdo({command, static_cast<std::uint8_t>(index),
                             static_cast<std::uint8_t>(index >> 8), sub, v[0], v[1], v[2], v[3]});
  if (response[0] == 0x80) {
    return static_cast<SdoAbort>(response[4] | (response[5] << 8) | (response[6] << 16) |
                                 (std::uint32_t{response[7]} << 24));
  }
  EXPECT_EQ(response[0], 0x60);
  EXPECT_EQ(response[1], static_cast<std::uint8_t>(index));
  EXPECT_EQ(response[2], static_cast<std::uint8_t>(index >> 8));
  EXPECT_EQ(response[3], sub);
  return SdoAbort::None;
}

SdoAbort NodeTest::download_float(std::uint16_t index, float value) {
  return download(index, 0, float_bits(value), 4);
}

std::uint32_t NodeTest::upload(std::uint16_t index, std::uint8_t sub) {
  const auto response = sdo({0x40, static_cast<std::uint8_t>(index),
                             static_cast<std::uint8_t>(index >> 8), sub, 0, 0, 0, 0});
  EXPECT_EQ(response[0] & 0xE3, 0x43) << "expected an expedited upload response, got 0x"
                                      << std::hex << int{response[0]};
  return response[4] | (response[5] << 8) | (response[6] << 16) |
         (std::uint32_t{response[7]} << 24);
}

SdoAbort NodeTest::upload_abort(std::uint16_t index, std::uint8_t sub) {
  const auto response = sdo({0x40, static_cast<std::uint8_t>(index),
                             static_cast<std::uint8_t>(index >> 8), sub, 0, 0, 0, 0});
  if (response[0] != 0x80) return SdoAbort::None;
  return static_cast<SdoAbort>(response[4] | (response[5] << 8) | (response[6] << 16) |
                               (std::uint32_t{response[7]} << 24));
}

}  // namespace co::test
