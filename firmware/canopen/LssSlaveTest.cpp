// The LSS slave (CiA 305) alone, frame by frame, and inside the Node: a start without a node id,
// the id a master configures taking effect with a boot-up, and the id kept across a restart.
#include "LssSlave.hpp"

#include <vector>

#include "NodeTestSupport.hpp"

namespace co::test {
namespace {

using Frame = std::array<std::uint8_t, 8>;
using cia305::kFastscanConfirm;
using cia305::kNodeIdUnconfigured;

constexpr LssIdentity kIdentity{board::kNode.vendor_id, board::kNode.product_code, board::kNode.revision,
                                0x0000'0013};

Frame command(LssCommand cs, std::initializer_list<std::uint8_t> data = {}) {
  Frame frame{};
  frame[0] = static_cast<std::uint8_t>(cs);
  std::size_t i = 1;
  for (std::uint8_t byte : data) frame[i++] = byte;
  return frame;
}

Frame with_u32(LssCommand cs, std::uint32_t value) {
  return command(cs, {static_cast<std::uint8_t>(value), static_cast<std::uint8_t>(value >> 8),
                      static_cast<std::uint8_t>(value >> 16), static_cast<std::uint8_t>(value >> 24)});
}

Frame fastscan(std::uint32_t id, std::uint8_t bit, std::uint8_t sub, std::uint8_t next) {
  Frame frame = with_u32(LssCommand::Fastscan, id);
  frame[5] = bit;
  frame[6] = sub;
  frame[7] = next;
  return frame;
}

class LssSlaveTest : public ::testing::Test {
 protected:
  LssOutcome send(const Frame& frame) { return slave.process(frame); }
  // The command specifier of the answer; 0 when there is none.
  std::uint8_t answered(const Frame& frame) {
    const LssOutcome outcome = send(frame);
    return outcome.answer ? outcome.answer_data[0] : 0;
  }
  void to_configuration() { send(command(LssCommand::SwitchStateGlobal, {1})); }
  // A fastscan of every part and bit, as a master does it: true when the slave answered the
  // last confirmation; `found` gets the identity the answers spelled.
  bool scan(LssIdentity& found) {
    if (answered(fastscan(0, kFastscanConfirm, 0, 0)) == 0) return false;
    std::array<std::uint32_t, 4> parts{};
    for (std::uint8_t sub = 0; sub < 4; ++sub) {
      for (int bit = 31; bit >= 0; --bit) {
        if (answered(fastscan(parts[sub], static_cast<std::uint8_t>(bit), sub, sub)) == 0) {
          parts[sub] |= 1u << bit;
        }
      }
      const auto next = static_cast<std::uint8_t>((sub + 1) % 4);
      if (answered(fastscan(parts[sub], 0, sub, next)) == 0) return false;
    }
    found = {parts[0], parts[1], parts[2], parts[3]};
    return true;
  }

  MemoryStorage storage;
  LssSlave slave{kIdentity, kNodeIdUnconfigured};
};

TEST_F(LssSlaveTest, StartsWaitingWithoutANodeId) {
  EXPECT_EQ(slave.state(), LssState::Waiting);
  EXPECT_FALSE(slave.configured());
  EXPECT_EQ(slave.active_node_id(), kNodeIdUnconfigured);
}

TEST_F(LssSlaveTest, ConfigurationServicesNeedTheConfigurationState) {
  EXPECT_EQ(answered(command(LssCommand::ConfigureNodeId, {5})), 0);
  EXPECT_EQ(answered(command(LssCommand::InquireNodeId)), 0);
  EXPECT_EQ(slave.pending_node_id(), kNodeIdUnconfigured);
  EXPECT_EQ(slave.counters().ignored, 2u);
}

TEST_F(LssSlaveTest, ConfiguresANodeIdAndRefusesOneOutOfRange) {
  to_configuration();
  LssOutcome outcome = send(command(LssCommand::ConfigureNodeId, {5}));
  ASSERT_TRUE(outcome.answer);
  EXPECT_EQ(outcome.answer_data, command(LssCommand::ConfigureNodeId, {0}));
  EXPECT_EQ(slave.pending_node_id(), 5);
  EXPECT_EQ(slave.active_node_id(), kNodeIdUnconfigured) << "pending until activated";
  for (const int bad : {0, 128, 254}) {
    outcome = send(command(LssCommand::ConfigureNodeId, {static_cast<std::uint8_t>(bad)}));
    EXPECT_EQ(outcome.answer_data, command(LssCommand::ConfigureNodeId, {1})) << bad;
  }
  EXPECT_EQ(slave.pending_node_id(), 5);
  EXPECT_EQ(send(command(LssCommand::ConfigureNodeId, {kNodeIdUnconfigured})).answer_data[1], 0)
      << "0xFF takes a node id away (allowed)";
}

TEST_F(LssSlaveTest, SwitchingBackToWaitingActivatesTheIdOfANodeThatHadNone) {
  to_configuration();
  send(command(LssCommand::ConfigureNodeId, {7}));
  const LssOutcome outcome = send(command(LssCommand::SwitchStateGlobal, {0}));
  EXPECT_FALSE(outcome.answer) << "switch state global has no answer";
  EXPECT_EQ(outcome.action, LssAction::ActivateNodeId);
  EXPECT_EQ(slave.activate_pending_node_id(), 7);
  EXPECT_TRUE(slave.configured());
  // A configured node's new id waits for reset communication.
  to_configuration();
  send(command(LssCommand::ConfigureNodeId, {9}));
  EXPECT_EQ(send(command(LssCommand::SwitchStateGlobal, {0})).action, LssAction::None);
  EXPECT_EQ(slave.active_node_id(), 7);
  EXPECT_EQ(slave.pending_node_id(), 9);
}

TEST_F(LssSlaveTest, BitTimingFromTheStandardTableOnly) {
  to_configuration();
  EXPECT_EQ(send(command(LssCommand::ConfigureBitTiming, {0, 2})).answer_data,
            command(LssCommand::ConfigureBitTiming, {0}));
  EXPECT_EQ(slave.pending_bit_timing(), 2);
  for (const Frame& refused : {command(LssCommand::ConfigureBitTiming, {0, 5}),   // reserved
                               command(LssCommand::ConfigureBitTiming, {0, 9}),   // auto: not done
                               command(LssCommand::ConfigureBitTiming, {1, 0})}) {  // other table
    EXPECT_EQ(send(refused).answer_data[1], 1);
  }
  EXPECT_EQ(slave.pending_bit_timing(), 2);
  const LssOutcome activate = send(command(LssCommand::ActivateBitTiming, {0x34, 0x12}));
  EXPECT_FALSE(activate.answer);
  EXPECT_EQ(activate.action, LssAction::ActivateBitTiming);
  EXPECT_EQ(activate.switch_delay_ms, 0x1234);
}

TEST_F(LssSlaveTest, StoreKeepsTheIdForTheNextStart) {
  to_configuration();
  EXPECT_EQ(send(command(LssCommand::StoreConfiguration)).answer_data[1], 1) << "no storage: not supported";
  slave.set_storage(&storage);
  send(command(LssCommand::ConfigureNodeId, {0x21}));
  send(command(LssCommand::ConfigureBitTiming, {0, 3}));
  EXPECT_EQ(send(command(LssCommand::StoreConfiguration)).answer_data, command(LssCommand::StoreConfiguration, {0}));
  ASSERT_EQ(storage.bytes.size(), LssSlave::kStoredBytes);

  LssSlave restarted{kIdentity, kNodeIdUnconfigured};
  restarted.set_storage(&storage);
  ASSERT_TRUE(restarted.load());
  EXPECT_EQ(restarted.active_node_id(), 0x21);
  EXPECT_EQ(restarted.pending_bit_timing(), 3);

  storage.fail_saves = true;
  EXPECT_EQ(send(command(LssCommand::StoreConfiguration)).answer_data[1], 2) << "storage failed";
}

TEST_F(LssSlaveTest, ACorruptStoredConfigurationIsNotLoaded) {
  slave.set_storage(&storage);
  to_configuration();
  send(command(LssCommand::ConfigureNodeId, {0x21}));
  send(command(LssCommand::StoreConfiguration));
  storage.bytes[4] = std::byte{0x22};  // the id changed, the CRC did not
  LssSlave restarted{kIdentity, 3};
  restarted.set_storage(&storage);
  EXPECT_FALSE(restarted.load());
  EXPECT_EQ(restarted.active_node_id(), 3);
}

TEST_F(LssSlaveTest, InquiresTheIdentityAndNodeId) {
  to_configuration();
  EXPECT_EQ(send(command(LssCommand::InquireVendorId)).answer_data, with_u32(LssCommand::InquireVendorId, kIdentity.vendor_id));
  EXPECT_EQ(send(command(LssCommand::InquireProductCode)).answer_data,
            with_u32(LssCommand::InquireProductCode, kIdentity.product_code));
  EXPECT_EQ(send(command(LssCommand::InquireRevision)).answer_data, with_u32(LssCommand::InquireRevision, kIdentity.revision));
  EXPECT_EQ(send(command(LssCommand::InquireSerial)).answer_data, with_u32(LssCommand::InquireSerial, kIdentity.serial_number));
  EXPECT_EQ(send(command(LssCommand::InquireNodeId)).answer_data, command(LssCommand::InquireNodeId, {kNodeIdUnconfigured}));
}

TEST_F(LssSlaveTest, SwitchStateSelectiveNeedsTheWholeAddressInOrder) {
  const auto select = [&](std::uint32_t serial) {
    send(with_u32(LssCommand::SwitchStateSelectiveVendorId, kIdentity.vendor_id));
    send(with_u32(LssCommand::SwitchStateSelectiveProductCode, kIdentity.product_code));
    send(with_u32(LssCommand::SwitchStateSelectiveRevision, kIdentity.revision));
    return send(with_u32(LssCommand::SwitchStateSelectiveSerial, serial));
  };
  EXPECT_FALSE(select(kIdentity.serial_number + 1).answer);
  EXPECT_EQ(slave.state(), LssState::Waiting);
  // The serial alone, without the parts before it, selects nothing.
  EXPECT_FALSE(send(with_u32(LssCommand::SwitchStateSelectiveSerial, kIdentity.serial_number)).answer);
  const LssOutcome outcome = select(kIdentity.serial_number);
  ASSERT_TRUE(outcome.answer);
  EXPECT_EQ(outcome.answer_data, command(LssCommand::SwitchStateSelectiveResponse));
  EXPECT_EQ(slave.state(), LssState::Configuration);
}

TEST_F(LssSlaveTest, IdentifyRemoteSlaveAnswersInsideTheRanges) {
  const auto identify = [&](std::uint32_t serial_low, std::uint32_t serial_high) {
    send(with_u32(LssCommand::IdentifyRemoteVendorId, kIdentity.vendor_id));
    send(with_u32(LssCommand::IdentifyRemoteProductCode, kIdentity.product_code));
    send(with_u32(LssCommand::IdentifyRemoteRevisionLow, 0));
    send(with_u32(LssCommand::IdentifyRemoteRevisionHigh, 0xFFFF'FFFFu));
    send(with_u32(LssCommand::IdentifyRemoteSerialLow, serial_low));
    return answered(with_u32(LssCommand::IdentifyRemoteSerialHigh, serial_high));
  };
  EXPECT_EQ(identify(0x10, 0x13), static_cast<std::uint8_t>(LssCommand::IdentifySlave));
  EXPECT_EQ(identify(0x13, 0x13), static_cast<std::uint8_t>(LssCommand::IdentifySlave));
  EXPECT_EQ(identify(0x14, 0xFF), 0);
  EXPECT_EQ(identify(0x00, 0x12), 0);
}

TEST_F(LssSlaveTest, OnlyANodeWithoutIdAnswersIdentifyNonConfigured) {
  EXPECT_EQ(answered(command(LssCommand::IdentifyNonConfiguredRemote)),
            static_cast<std::uint8_t>(LssCommand::IdentifyNonConfiguredSlave));
  LssSlave configured{kIdentity, 4};
  EXPECT_FALSE(configured.process(command(LssCommand::IdentifyNonConfiguredRemote)).answer);
}

TEST_F(LssSlaveTest, FastscanFindsTheWholeAddressAndEntersConfiguration) {
  LssIdentity found;
  ASSERT_TRUE(scan(found));
  EXPECT_EQ(found.vendor_id, kIdentity.vendor_id);
  EXPECT_EQ(found.product_code, kIdentity.product_code);
  EXPECT_EQ(found.revision, kIdentity.revision);
  EXPECT_EQ(found.serial_number, kIdentity.serial_number);
  EXPECT_EQ(slave.state(), LssState::Configuration);
}

TEST_F(LssSlaveTest, FastscanSkipsKnownPartsWithOneConfirmationEach) {
  ASSERT_NE(answered(fastscan(0, kFastscanConfirm, 0, 0)), 0);
  EXPECT_NE(answered(fastscan(kIdentity.vendor_id, 0, 0, 1)), 0);
  EXPECT_NE(answered(fastscan(kIdentity.product_code, 0, 1, 2)), 0);
  EXPECT_EQ(answered(fastscan(kIdentity.revision + 1, 0, 2, 3)), 0) << "a wrong part: no answer";
  EXPECT_EQ(answered(fastscan(kIdentity.serial_number, 0, 3, 0)), 0) << "the slave still waits at part 2";
  EXPECT_EQ(slave.state(), LssState::Waiting);
  EXPECT_NE(answered(fastscan(kIdentity.revision, 0, 2, 3)), 0);
  EXPECT_NE(answered(fastscan(kIdentity.serial_number, 0, 3, 0)), 0) << "the last part, back to 0: found";
  EXPECT_EQ(slave.state(), LssState::Configuration);
}

TEST_F(LssSlaveTest, FastscanIgnoresInvalidRequestsAndConfiguredNodes) {
  EXPECT_EQ(answered(fastscan(0, 32, 0, 0)), 0);
  EXPECT_EQ(answered(fastscan(0, kFastscanConfirm, 4, 0)), 0);
  EXPECT_EQ(answered(fastscan(0, kFastscanConfirm, 0, 4)), 0);
  LssSlave configured{kIdentity, 4};
  EXPECT_FALSE(configured.process(fastscan(0, kFastscanConfirm, 0, 0)).answer);
}

TEST_F(LssSlaveTest, AChainInputThatIsLowSilencesEveryService) {
  slave.set_enabled(false);
  LssIdentity found;
  EXPECT_FALSE(scan(found));
  EXPECT_EQ(answered(command(LssCommand::IdentifyNonConfiguredRemote)), 0);
  to_configuration();
  EXPECT_EQ(slave.state(), LssState::Waiting);
  slave.set_enabled(true);
  EXPECT_TRUE(scan(found));
}

TEST_F(LssSlaveTest, AShortFrameIsDropped) {
  const Frame frame = command(LssCommand::IdentifyNonConfiguredRemote);
  EXPECT_FALSE(slave.process(std::span<const std::uint8_t>(frame.data(), 7)).answer);
  EXPECT_EQ(slave.counters().malformed, 1u);
}

// --- Inside the Node --------------------------------------------------------------------------

class NodeLssTest : public ::testing::Test {
 protected:
  void start() { node.start(now_us); }
  void lss(const Frame& frame) {
    CanFrame can;
    can.id = cia305::kMasterCobId;
    can.len = 8;
    can.data = frame;
    node.process(can, now_us);
  }
  std::vector<CanFrame> sent() {
    std::vector<CanFrame> frames;
    CanFrame frame;
    while (port.pop_sent(frame)) frames.push_back(frame);
    return frames;
  }
  void assign(std::uint8_t node_id, bool store) {
    lss(command(LssCommand::SwitchStateGlobal, {1}));
    lss(command(LssCommand::ConfigureNodeId, {node_id}));
    if (store) lss(command(LssCommand::StoreConfiguration));
    lss(command(LssCommand::SwitchStateGlobal, {0}));
  }

  MemoryPort port;
  FakeBoard fields;
  FakeHil hil;
  MemoryStorage storage;
  MemoryStorage lss_storage;
  std::uint32_t now_us = 1'000;
  Node node{kNodeIdUnconfigured, port, fields, hil, storage, 0x13};
};

TEST_F(NodeLssTest, WithoutANodeIdOnlyLssIsServedAndNothingIsSent) {
  start();
  EXPECT_TRUE(sent().empty()) << "no boot-up without a node id";
  EXPECT_FALSE(node.has_node_id());
  EXPECT_EQ(node.state(), NmtState::Initialising);
  std::array<std::uint32_t, Node::kMaxAcceptedIds> ids{};
  ASSERT_EQ(node.accepted_ids(ids), 1u);
  EXPECT_EQ(ids[0], cia305::kMasterCobId);
  node.process(make_frame(cia301::kNmtCobId, {static_cast<std::uint8_t>(NmtCommand::Start), 0}), now_us);
  node.poll(now_us + 10'000'000u);
  EXPECT_TRUE(sent().empty()) << "no NMT, no heartbeat";
  EXPECT_EQ(node.state(), NmtState::Initialising);
}

TEST_F(NodeLssTest, AConfiguredIdTakesEffectWithABootUp) {
  start();
  lss(command(LssCommand::SwitchStateGlobal, {1}));
  lss(command(LssCommand::ConfigureNodeId, {5}));
  const std::vector<CanFrame> answer = sent();
  ASSERT_EQ(answer.size(), 1u);
  EXPECT_EQ(answer[0].id, cia305::kSlaveCobId);
  lss(command(LssCommand::SwitchStateGlobal, {0}));
  const std::vector<CanFrame> boot = sent();
  ASSERT_EQ(boot.size(), 1u);
  EXPECT_EQ(boot[0], make_frame(cia301::cob_id(cia301::FunctionCode::Heartbeat, 5), {0}));
  EXPECT_EQ(node.node_id(), 5);
  EXPECT_EQ(node.state(), NmtState::PreOperational);
  EXPECT_TRUE(node.has_node_id());
}

TEST_F(NodeLssTest, AStoredIdIsKeptAcrossARestart) {
  node.set_lss_storage(&lss_storage);
  start();
  assign(0x22, true);
  (void)sent();
  MemoryPort port2;
  Node restarted{kNodeIdUnconfigured, port2, fields, hil, storage, 0x13};
  restarted.set_lss_storage(&lss_storage);
  restarted.start(now_us);
  EXPECT_EQ(restarted.node_id(), 0x22);
  CanFrame boot;
  ASSERT_TRUE(port2.pop_sent(boot));
  EXPECT_EQ(boot, make_frame(cia301::cob_id(cia301::FunctionCode::Heartbeat, 0x22), {0}));
}

TEST_F(NodeLssTest, AConfiguredNodesNewIdWaitsForResetCommunication) {
  Node configured{3, port, fields, hil, storage, 0x13};
  configured.set_boot_time_us(0);  // the reset's boot-up at once (NmtBootTimeTest times it)
  configured.start(now_us);
  (void)sent();
  CanFrame frame;
  frame.id = cia305::kMasterCobId;
  frame.len = 8;
  for (const Frame& data : {command(LssCommand::SwitchStateGlobal, {1}), command(LssCommand::ConfigureNodeId, {9}),
                            command(LssCommand::SwitchStateGlobal, {0})}) {
    frame.data = data;
    configured.process(frame, now_us);
  }
  EXPECT_EQ(configured.node_id(), 3);
  (void)sent();
  configured.process(make_frame(cia301::kNmtCobId, {static_cast<std::uint8_t>(NmtCommand::ResetCommunication), 3}),
                     now_us);
  EXPECT_EQ(configured.node_id(), 9);
  const std::vector<CanFrame> boot = sent();
  ASSERT_EQ(boot.size(), 1u);
  EXPECT_EQ(boot[0].id, cia301::cob_id(cia301::FunctionCode::Heartbeat, 9));
}

TEST_F(NodeLssTest, AShortLssFrameIsCountedMalformed) {
  start();
  node.process(make_frame(cia305::kMasterCobId, {static_cast<std::uint8_t>(LssCommand::IdentifyNonConfiguredRemote)}),
               now_us);
  EXPECT_EQ(node.counters().frames_malformed, 1u);
  EXPECT_TRUE(sent().empty());
}

}  // namespace
}  // namespace co::test
