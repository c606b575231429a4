// The node's acceptance set (Node::accepted_ids) and its listener: what a receive filter in
// front of the node may let through, in every configuration the bus can give it, and that the
// listener hears a new set before the frame that lets a master use it.
#include <algorithm>
#include <vector>

#include "NodeTestSupport.hpp"

namespace co::test {
namespace {

using Ids = std::vector<std::uint32_t>;

struct Heard {
  Ids ids;
  std::size_t frames_sent_before = 0;  // frames the node had sent (and nobody read) by then
};

class RecordingAcceptance final : public AcceptanceListener {
 public:
  explicit RecordingAcceptance(const MemoryPort& port) : port_(port) {}
  void accepted_ids_changed(std::span<const std::uint32_t> cob_ids) override {
    heard.push_back({Ids(cob_ids.begin(), cob_ids.end()), port_.sent_count()});
  }
  std::vector<Heard> heard;

 private:
  const MemoryPort& port_;
};

class AcceptanceFilterTest : public NodeTest {
 protected:
  static constexpr std::uint32_t kRpdo1 = cia301::cob_id(cia301::FunctionCode::Rpdo1, kNodeId);
  static constexpr std::uint32_t kRpdo2 = cia301::cob_id(cia301::FunctionCode::Rpdo2, kNodeId);
  static constexpr std::uint32_t kRpdo3 = cia301::cob_id(cia301::FunctionCode::Rpdo3, kNodeId);
  static constexpr std::uint32_t kRpdo4 = cia301::cob_id(cia301::FunctionCode::Rpdo4, kNodeId);
  // board.toml's defaults: RPDO1..3 enabled, RPDO4 not; no heartbeat consumed.
  const Ids kDefaultIds = {0x000, cia301::kSyncCobId, kRpdo1, kRpdo2, kRpdo3, kSdoRx, cia305::kMasterCobId};

  void SetUp() override {
    node.set_acceptance_listener(&listener);  // before start(), as the platform does
    NodeTest::SetUp();
  }

  Ids accepted() const {
    std::array<std::uint32_t, Node::kMaxAcceptedIds> ids{};
    const std::size_t count = node.accepted_ids(ids);
    return Ids(ids.begin(), ids.begin() + static_cast<std::ptrdiff_t>(count));
  }
  static Ids with(Ids ids, std::initializer_list<std::uint32_t> more) {
    ids.insert(ids.end(), more);
    std::sort(ids.begin(), ids.end());
    return ids;
  }
  static Ids without(Ids ids, std::uint32_t id) {
    ids.erase(std::remove(ids.begin(), ids.end(), id), ids.end());
    return ids;
  }
  // RPDO4 maps velocity_setpoint, then takes `cob_id` (pre-operational).
  void enable_rpdo4(std::uint32_t cob_id = kRpdo4) {
    ASSERT_EQ(download(0x1603, 1, 0x2401'0020u, 4), SdoAbort::None);
    ASSERT_EQ(download(0x1603, 0, 1, 1), SdoAbort::None);
    ASSERT_EQ(download(0x1403, 1, cob_id, 4), SdoAbort::None);
  }
  // What the last call told, checked to have come before any frame of that call went out.
  Ids last_heard_before_any_frame() {
    if (listener.heard.empty()) return {};
    EXPECT_EQ(listener.heard.back().frames_sent_before, 0u)
        << "the listener heard the new set after the node had sent a frame";
    return listener.heard.back().ids;
  }

  RecordingAcceptance listener{port};
};

TEST_F(AcceptanceFilterTest, StartTellsTheDefaultSetBeforeTheBootUp) {
  EXPECT_EQ(accepted(), kDefaultIds);
  ASSERT_EQ(listener.heard.size(), 1u) << "start() tells the set once (0x1017 changed nothing)";
  EXPECT_EQ(listener.heard[0].ids, kDefaultIds);
  EXPECT_EQ(listener.heard[0].frames_sent_before, 0u) << "the boot-up went out before the filter";
}

TEST_F(AcceptanceFilterTest, SdoRequestsThatChangeNoCobIdTellNothing) {
  EXPECT_EQ(download(0x1017, 0, 100, 2), SdoAbort::None);
  EXPECT_EQ(download(0x1400, 2, 1, 1), SdoAbort::None);  // RPDO1 transmission type
  (void)upload(0x1400, 1);
  EXPECT_EQ(listener.heard.size(), 1u);
}

TEST_F(AcceptanceFilterTest, AnRpdoEnabledOverSdoJoinsTheSetBeforeTheAnswer) {
  enable_rpdo4();
  EXPECT_EQ(accepted(), with(kDefaultIds, {kRpdo4}));
  EXPECT_EQ(last_heard_before_any_frame(), with(kDefaultIds, {kRpdo4}));
  EXPECT_EQ(listener.heard.size(), 2u) << "mapping writes change no COB-ID";
}

TEST_F(AcceptanceFilterTest, AnRpdoMadeInvalidLeavesTheSet) {
  ASSERT_EQ(download(0x1401, 1, kInvalid | kRpdo2, 4), SdoAbort::None);
  EXPECT_EQ(accepted(), without(kDefaultIds, kRpdo2));
  EXPECT_EQ(last_heard_before_any_frame(), without(kDefaultIds, kRpdo2));
}

TEST_F(AcceptanceFilterTest, ARemappedRpdoCobIdIsAcceptedAndServed) {
  constexpr std::uint32_t kRemapped = 0x234;  // protocol-literal: any free identifier
  ASSERT_EQ(download(0x1400, 1, kInvalid | kRpdo1, 4), SdoAbort::None);
  ASSERT_EQ(download(0x1400, 1, kRemapped, 4), SdoAbort::None);
  const Ids expected = with(without(kDefaultIds, kRpdo1), {kRemapped});
  EXPECT_EQ(accepted(), expected);
  EXPECT_EQ(last_heard_before_any_frame(), expected);
  nmt(NmtCommand::Start);
  receive(kRemapped, {1, 0, 2, 0, 3, 0, 4, 0});
  EXPECT_EQ(node.counters().rpdos_received, 1u) << "the remapped id is the one RPDO1 serves";
}

TEST_F(AcceptanceFilterTest, TheSyncCobIdFollows0x1005) {
  ASSERT_EQ(download(0x1005, 0, 0x081, 4), SdoAbort::None);  // protocol-literal: SYNC moved
  const Ids expected = with(without(kDefaultIds, cia301::kSyncCobId), {0x081});  // protocol-literal: SYNC moved
  EXPECT_EQ(accepted(), expected);
  EXPECT_EQ(last_heard_before_any_frame(), expected);
}

TEST_F(AcceptanceFilterTest, UsedHeartbeatConsumerEntriesAddTheWatchedHeartbeat) {
  ASSERT_EQ(download(0x1016, 1, 0x0001'0000u, 4), SdoAbort::None);  // node 1, time 0: unused
  EXPECT_EQ(accepted(), kDefaultIds);
  EXPECT_EQ(listener.heard.size(), 1u);
  ASSERT_EQ(download(0x1016, 1, 0x0001'0096u, 4), SdoAbort::None);  // node 1, 150 ms
  EXPECT_EQ(accepted(), with(kDefaultIds, {kMasterHeartbeat}));
  EXPECT_EQ(last_heard_before_any_frame(), with(kDefaultIds, {kMasterHeartbeat}));
  ASSERT_EQ(download(0x1016, 1, 0, 4), SdoAbort::None);
  EXPECT_EQ(last_heard_before_any_frame(), kDefaultIds);
}

TEST_F(AcceptanceFilterTest, TheNmtStateLeavesTheSetAlone) {
  for (const NmtCommand command : {NmtCommand::Start, NmtCommand::Stop, NmtCommand::EnterPreOperational}) {
    nmt(command);
    EXPECT_EQ(accepted(), kDefaultIds);
  }
  EXPECT_EQ(listener.heard.size(), 1u);
}

TEST_F(AcceptanceFilterTest, ResetCommunicationReloadsTheStoredSetBeforeTheBootUp) {
  enable_rpdo4();
  ASSERT_EQ(download(0x1016, 1, 0x0001'0096u, 4), SdoAbort::None);
  ASSERT_EQ(download(0x1010, 2, Node::kStoreSignature, 4), SdoAbort::None);
  const Ids stored = with(kDefaultIds, {kRpdo4, kMasterHeartbeat});
  ASSERT_EQ(download(0x1402, 1, kInvalid | kRpdo3, 4), SdoAbort::None);  // not stored
  ASSERT_EQ(download(0x1005, 0, 0x081, 4), SdoAbort::None);  // protocol-literal: SYNC moved, not stored
  nmt(NmtCommand::ResetCommunication);
  EXPECT_EQ(accepted(), stored);
  EXPECT_EQ(last_heard_before_any_frame(), stored) << "boot-up before the filter";
  EXPECT_EQ(all_sent().size(), 1u);  // the boot-up
}

TEST_F(AcceptanceFilterTest, ResetNodeReloadsTheStoredSetBeforeTheBootUp) {
  ASSERT_EQ(download(0x1016, 1, 0x0001'0096u, 4), SdoAbort::None);
  ASSERT_EQ(download(0x1010, 1, Node::kStoreSignature, 4), SdoAbort::None);
  ASSERT_EQ(download(0x1016, 1, 0, 4), SdoAbort::None);  // not stored
  ASSERT_EQ(download(0x1400, 1, kInvalid | kRpdo1, 4), SdoAbort::None);  // not stored
  nmt(NmtCommand::ResetNode);
  EXPECT_EQ(accepted(), with(kDefaultIds, {kMasterHeartbeat}));
  EXPECT_EQ(last_heard_before_any_frame(), with(kDefaultIds, {kMasterHeartbeat}));
}

TEST_F(AcceptanceFilterTest, RestoredDefaultsTakeEffectAtTheNextReset) {
  enable_rpdo4();
  ASSERT_EQ(download(0x1010, 1, Node::kStoreSignature, 4), SdoAbort::None);
  const std::size_t told = listener.heard.size();
  ASSERT_EQ(download(0x1011, 1, Node::kRestoreSignature, 4), SdoAbort::None);
  EXPECT_EQ(accepted(), with(kDefaultIds, {kRpdo4})) << "CiA 301: restored values apply after a reset";
  EXPECT_EQ(listener.heard.size(), told);
  nmt(NmtCommand::ResetCommunication);
  EXPECT_EQ(accepted(), kDefaultIds);
  EXPECT_EQ(last_heard_before_any_frame(), kDefaultIds);
}

TEST_F(AcceptanceFilterTest, AListenerSetAfterStartHearsTheSetAtOnce) {
  RecordingAcceptance late{port};
  node.set_acceptance_listener(&late);
  ASSERT_EQ(late.heard.size(), 1u);
  EXPECT_EQ(late.heard[0].ids, kDefaultIds);
  node.set_acceptance_listener(nullptr);
  enable_rpdo4();  // nobody to tell: no crash
  EXPECT_EQ(late.heard.size(), 1u);
}

TEST_F(AcceptanceFilterTest, DuplicateCobIdsAreListedOnce) {
  enable_rpdo4(kRpdo1);  // two RPDOs on one COB-ID: the node allows it
  EXPECT_EQ(accepted(), kDefaultIds);
}

// The set is exhaustive: in every NMT state and configuration, a frame outside it, or any
// remote or 29-bit frame, changes nothing but the received and ignored counters, and the node
// answers nothing. So a filter that drops exactly those frames changes nothing on the bus.
TEST_F(AcceptanceFilterTest, FramesOutsideTheSetAreOnlyEverCountedAsIgnored) {
  enable_rpdo4(0x555);  // protocol-literal: any free identifier
  ASSERT_EQ(download(0x1016, 1, 0x0001'0096u, 4), SdoAbort::None);
  ASSERT_EQ(download(0x1005, 0, 0x0FF, 4), SdoAbort::None);  // protocol-literal: SYNC moved
  const Ids accepted_ids = accepted();
  ASSERT_EQ(accepted_ids, with(without(kDefaultIds, cia301::kSyncCobId), {0x0FF, 0x555, kMasterHeartbeat}));  // protocol-literal: as set above
  for (const NmtCommand state : {NmtCommand::EnterPreOperational, NmtCommand::Start, NmtCommand::Stop}) {
    nmt(state);
    all_sent();
    for (std::uint32_t id = 0; id < 0x800; ++id) {
      const bool in_set = std::find(accepted_ids.begin(), accepted_ids.end(), id) != accepted_ids.end();
      for (const std::uint32_t flags : {std::uint32_t{0}, CanFrame::kRemoteFlag, CanFrame::kExtendedFlag}) {
        if (in_set && flags == 0) continue;
        for (std::uint8_t len = 0; len <= 8; ++len) {
          CanFrame frame;
          frame.id = id | flags;
          frame.len = len;
          frame.data = {0x01, 0x10, 0x2B, 0x17, 0x10, 0x00, 0x64, 0x00};
          const NodeCounters before = node.counters();
          const NmtState state_before = node.state();
          const ProcessResult result = receive(frame);
          const NodeCounters& after = node.counters();
          ASSERT_EQ(after.frames_ignored, before.frames_ignored + 1) << std::hex << frame.id;
          ASSERT_EQ(after.frames_received, before.frames_received + 1);
          ASSERT_EQ(after.frames_malformed + after.nmt_commands + after.syncs_received +
                        after.sdo_requests + after.rpdos_received + after.rpdo_length_errors +
                        after.heartbeats_consumed,
                    before.frames_malformed + before.nmt_commands + before.syncs_received +
                        before.sdo_requests + before.rpdos_received + before.rpdo_length_errors +
                        before.heartbeats_consumed)
              << std::hex << frame.id;
          ASSERT_FALSE(result.sync || result.application_reset);
          ASSERT_EQ(node.state(), state_before);
          ASSERT_EQ(port.sent_count(), 0u) << std::hex << frame.id;
        }
      }
    }
  }
}

}  // namespace
}  // namespace co::test
