// Heartbeat consumer (CiA 301, 7.2.8.3.2.2; object 0x1016, 7.5.2.31): SDO rules, monitoring,
// heartbeat events with their EMCY, store/restore, and the two clocks.
#include <vector>

#include "NodeTestSupport.hpp"

namespace co::test {
namespace {

constexpr std::uint16_t kConsumerHeartbeat = HeartbeatConsumer::kIndex;
constexpr std::uint16_t kConsumerTimeMs = 150;
constexpr std::uint32_t kConsumerTimeUs = kConsumerTimeMs * 1000u;

constexpr std::uint32_t consumer_entry(std::uint8_t node_id, std::uint16_t time_ms) {
  return (std::uint32_t{node_id} << 16) | time_ms;
}

struct HeardStatus {
  std::uint8_t lost_entries;
  bool event;
  friend bool operator==(const HeardStatus&, const HeardStatus&) = default;
};

class RecordingListener final : public HeartbeatListener {
 public:
  void heartbeat_status(std::uint8_t lost_entries, bool event) override {
    heard.push_back({lost_entries, event});
  }
  std::vector<HeardStatus> heard;
};

class HeartbeatConsumerTest : public NodeTest {
 protected:
  void SetUp() override {
    NodeTest::SetUp();
    node.set_heartbeat_listener(&listener);
  }

  void watch_master(std::uint16_t time_ms = kConsumerTimeMs) {
    ASSERT_EQ(download(kConsumerHeartbeat, 1, consumer_entry(kMasterId, time_ms), 4), SdoAbort::None);
  }
  void master_heartbeat(std::uint8_t state = 0x05) { receive(kMasterHeartbeat, {state}); }
  // NMT reset node / communication, its boot-up dropped and our heartbeat off again.
  void reset(NmtCommand command) {
    nmt(command);
    all_sent();
    ASSERT_EQ(download(0x1017, 0, 0, 2), SdoAbort::None);
  }

  // The EMCY a heartbeat event of the master sends (node pre-operational or operational).
  static CanFrame heartbeat_emcy(std::uint8_t error_register) {
    return make_frame(kEmcy, {0x30, 0x81, error_register, 0x16, 0x10, kMasterId, 0, 0});
  }
  static constexpr std::uint8_t kCommunicationError =
      error_register::kCommunication | error_register::kGeneric;

  RecordingListener listener;
};

TEST_F(HeartbeatConsumerTest, ObjectIsAnArrayOfTheTablesEntriesAllUnused) {
  EXPECT_EQ(upload(kConsumerHeartbeat, 0), board::kHeartbeatConsumers);
  for (std::uint8_t sub = 1; sub <= board::kHeartbeatConsumers; ++sub) {
    EXPECT_EQ(upload(kConsumerHeartbeat, sub), 0u) << int{sub};
  }
  const auto past_the_end = static_cast<std::uint8_t>(board::kHeartbeatConsumers + 1);
  EXPECT_EQ(upload_abort(kConsumerHeartbeat, past_the_end), SdoAbort::SubIndexDoesNotExist);
  EXPECT_EQ(download(kConsumerHeartbeat, 0, 1, 1), SdoAbort::ReadOnly);
  EXPECT_EQ(download(kConsumerHeartbeat, 1, 0x96, 2), SdoAbort::LengthTooLow);
}

TEST_F(HeartbeatConsumerTest, ReservedBitsOrANodeIdAbove127AreOutOfRange) {
  EXPECT_EQ(download(kConsumerHeartbeat, 1, 0x0100'0000u | consumer_entry(kMasterId, 100), 4),
            SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(download(kConsumerHeartbeat, 1, consumer_entry(128, 100), 4), SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(upload(kConsumerHeartbeat, 1), 0u) << "a refused value leaves the entry as it was";
  EXPECT_EQ(download(kConsumerHeartbeat, 1, consumer_entry(127, 100), 4), SdoAbort::None);
}

TEST_F(HeartbeatConsumerTest, NothingHappensBeforeTheFirstHeartbeat) {
  watch_master();
  for (int i = 0; i < 100; ++i) advance_us(100'000);  // 10 s of silence from the master
  EXPECT_TRUE(all_sent().empty());
  EXPECT_EQ(node.lost_heartbeats(), 0u);
  EXPECT_EQ(node.counters().heartbeat_events, 0u);
  EXPECT_TRUE(listener.heard.empty());
}

TEST_F(HeartbeatConsumerTest, SilenceForTheConsumerTimeIsOneEventWithItsEmcy) {
  watch_master();
  master_heartbeat();
  EXPECT_EQ(node.counters().heartbeats_consumed, 1u);
  advance_us(kConsumerTimeUs - 1);
  EXPECT_TRUE(all_sent().empty());
  advance_us(1);
  EXPECT_EQ(next_sent(), heartbeat_emcy(kCommunicationError));
  EXPECT_EQ(node.error_register(), kCommunicationError);
  EXPECT_EQ(node.lost_heartbeats(), 1u);
  EXPECT_EQ(listener.heard, (std::vector<HeardStatus>{{1, true}}));
  for (int i = 0; i < 20; ++i) advance_us(100'000);
  EXPECT_TRUE(all_sent().empty()) << "one event per loss";
  EXPECT_EQ(node.counters().heartbeat_events, 1u);
  EXPECT_EQ(node.state(), NmtState::PreOperational) << "0x1029 = 0 acts in operational only";
}

TEST_F(HeartbeatConsumerTest, InOperationalAnEventEntersPreOperationalByDefault) {
  EXPECT_EQ(upload(cia301::kErrorBehaviourIndex, 1), 0u) << "CiA 301's default";
  watch_master();
  nmt(NmtCommand::Start);
  master_heartbeat();
  advance_us(kConsumerTimeUs);
  EXPECT_EQ(next_sent(), heartbeat_emcy(kCommunicationError)) << "the EMCY first";
  EXPECT_EQ(node.state(), NmtState::PreOperational);
  EXPECT_EQ(listener.heard.back(), (HeardStatus{1, true}));
}

TEST_F(HeartbeatConsumerTest, ErrorBehaviourNoChangeKeepsOperational) {
  ASSERT_EQ(download(cia301::kErrorBehaviourIndex, 1, 1, 1), SdoAbort::None);
  watch_master();
  nmt(NmtCommand::Start);
  master_heartbeat();
  advance_us(kConsumerTimeUs);
  EXPECT_EQ(next_sent(), heartbeat_emcy(kCommunicationError));
  EXPECT_EQ(node.state(), NmtState::Operational);
  EXPECT_EQ(listener.heard.back(), (HeardStatus{1, true})) << "the application still goes safe";
}

TEST_F(HeartbeatConsumerTest, ErrorBehaviourStoppedStopsAfterTheEmcy) {
  ASSERT_EQ(download(cia301::kErrorBehaviourIndex, 1, 2, 1), SdoAbort::None);
  watch_master();
  master_heartbeat();
  advance_us(kConsumerTimeUs);  // from pre-operational too
  EXPECT_EQ(next_sent(), heartbeat_emcy(kCommunicationError));
  EXPECT_EQ(node.state(), NmtState::Stopped);
}

TEST_F(HeartbeatConsumerTest, ErrorBehaviourObjectRangeAndStorage) {
  constexpr std::uint16_t kErrorBehaviour = cia301::kErrorBehaviourIndex;
  EXPECT_EQ(upload(kErrorBehaviour, 0), 1u);
  EXPECT_EQ(download(kErrorBehaviour, 0, 2, 1), SdoAbort::ReadOnly);
  EXPECT_EQ(upload_abort(kErrorBehaviour, 2), SdoAbort::SubIndexDoesNotExist);
  EXPECT_EQ(download(kErrorBehaviour, 1, 3, 1), SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(download(kErrorBehaviour, 1, 1, 1), SdoAbort::None);
  reset(NmtCommand::ResetCommunication);
  EXPECT_EQ(upload(kErrorBehaviour, 1), 0u) << "not stored: back to the default";
  ASSERT_EQ(download(kErrorBehaviour, 1, 1, 1), SdoAbort::None);
  ASSERT_EQ(download(0x1010, 2, Node::kStoreSignature, 4), SdoAbort::None);
  reset(NmtCommand::ResetNode);
  EXPECT_EQ(upload(kErrorBehaviour, 1), 1u);
  ASSERT_EQ(download(0x1011, 2, Node::kRestoreSignature, 4), SdoAbort::None);
  reset(NmtCommand::ResetCommunication);
  EXPECT_EQ(upload(kErrorBehaviour, 1), 0u);
}

// A module of a chain: the master, two neighbours and a spare; each node id at most once.
TEST_F(HeartbeatConsumerTest, FourEntriesWatchFourNodesAndRefuseADuplicate) {
  static_assert(board::kHeartbeatConsumers >= 4);
  ASSERT_EQ(download(kConsumerHeartbeat, 1, consumer_entry(0x7F, kConsumerTimeMs), 4), SdoAbort::None);
  ASSERT_EQ(download(kConsumerHeartbeat, 2, consumer_entry(0x0F, kConsumerTimeMs), 4), SdoAbort::None);
  ASSERT_EQ(download(kConsumerHeartbeat, 3, consumer_entry(0x11, kConsumerTimeMs), 4), SdoAbort::None);
  EXPECT_EQ(download(kConsumerHeartbeat, 4, consumer_entry(0x0F, 2 * kConsumerTimeMs), 4),
            SdoAbort::ParameterIncompatible);
  EXPECT_EQ(upload(kConsumerHeartbeat, 4), 0u);
  ASSERT_EQ(download(kConsumerHeartbeat, 4, consumer_entry(kMasterId, kConsumerTimeMs), 4), SdoAbort::None);
  for (const std::uint8_t id : {std::uint8_t{0x7F}, std::uint8_t{0x0F}, std::uint8_t{0x11}, kMasterId}) {
    receive(cia301::cob_id(cia301::FunctionCode::Heartbeat, id), {0x05});
  }
  EXPECT_EQ(node.counters().heartbeats_consumed, 4u);
  advance_us(kConsumerTimeUs);
  EXPECT_EQ(node.lost_heartbeats(), 4u);
  EXPECT_EQ(node.counters().heartbeat_events, 4u);
}

TEST_F(HeartbeatConsumerTest, EveryHeartbeatRestartsTheTimerWhateverItsState) {
  watch_master();
  // Boot-up, pre-operational, operational, stopped: each counts.
  for (const int state : {0x00, 0x7F, 0x05, 0x04, 0x05, 0x05}) {
    master_heartbeat(static_cast<std::uint8_t>(state));
    advance_us(kConsumerTimeUs - 1);
  }
  EXPECT_TRUE(all_sent().empty());
  EXPECT_EQ(node.counters().heartbeats_consumed, 6u);
}

TEST_F(HeartbeatConsumerTest, ReArmsWhenHeartbeatsComeBack) {
  watch_master();
  master_heartbeat();
  advance_us(kConsumerTimeUs);
  EXPECT_EQ(all_sent().size(), 1u);
  master_heartbeat();
  EXPECT_EQ(node.lost_heartbeats(), 0u);
  EXPECT_EQ(listener.heard.back(), (HeardStatus{0, false}));
  advance_us(kConsumerTimeUs);
  EXPECT_EQ(node.counters().heartbeat_events, 2u);
  EXPECT_EQ(listener.heard.back(), (HeardStatus{1, true}));
  EXPECT_TRUE(all_sent().empty()) << "the first EMCY is still active: the node repeats nothing";
  // Once the application cleared the error (its fault latch), the next loss is sent again.
  node.clear_emcy(board::emcy_code::kHeartbeatError);
  EXPECT_EQ(next_sent(), make_frame(kEmcy, {0, 0, 0, 0, 0, 0, 0, 0}));
  master_heartbeat();
  advance_us(kConsumerTimeUs);
  EXPECT_EQ(next_sent(), heartbeat_emcy(kCommunicationError));
}

TEST_F(HeartbeatConsumerTest, WritingAnEntryRestartsItsMonitoring) {
  watch_master();
  master_heartbeat();
  advance_us(kConsumerTimeUs / 2);
  watch_master(kConsumerTimeMs);  // same value: still a restart
  for (int i = 0; i < 10; ++i) advance_us(kConsumerTimeUs);
  EXPECT_TRUE(all_sent().empty()) << "not monitored again until the next heartbeat";
  master_heartbeat();
  advance_us(kConsumerTimeUs);
  EXPECT_EQ(next_sent(), heartbeat_emcy(kCommunicationError));
  // Rewriting a lost entry ends the loss: it waits afresh.
  watch_master();
  EXPECT_EQ(node.lost_heartbeats(), 0u);
  EXPECT_EQ(listener.heard.back(), (HeardStatus{0, false}));
}

TEST_F(HeartbeatConsumerTest, NodeIdZeroOrTimeZeroLeavesTheEntryUnused) {
  for (const std::uint32_t unused : {consumer_entry(0, kConsumerTimeMs), consumer_entry(kMasterId, 0)}) {
    ASSERT_EQ(download(kConsumerHeartbeat, 1, unused, 4), SdoAbort::None);
    EXPECT_EQ(upload(kConsumerHeartbeat, 1), unused);
    master_heartbeat();
    for (int i = 0; i < 10; ++i) advance_us(kConsumerTimeUs);
    EXPECT_TRUE(all_sent().empty());
  }
  EXPECT_EQ(node.counters().heartbeats_consumed, 0u) << "an unwatched heartbeat is ignored";
}

TEST_F(HeartbeatConsumerTest, AHeartbeatOfTheWrongLengthIsMalformedAndRestartsNothing) {
  watch_master();
  master_heartbeat();
  advance_us(kConsumerTimeUs - 10);
  const std::uint32_t malformed = node.counters().frames_malformed;
  receive(kMasterHeartbeat, {0x05, 0x00});
  receive(kMasterHeartbeat, {});
  EXPECT_EQ(node.counters().frames_malformed, malformed + 2);
  advance_us(10);
  EXPECT_EQ(next_sent(), heartbeat_emcy(kCommunicationError));
}

TEST_F(HeartbeatConsumerTest, WorksInEveryNmtStateTheEmcyFrameOnlyWhereEmcyIsAllowed) {
  watch_master();
  nmt(NmtCommand::Start);
  master_heartbeat();
  advance_us(kConsumerTimeUs);
  EXPECT_EQ(next_sent(), heartbeat_emcy(kCommunicationError));
  node.clear_emcy(board::emcy_code::kHeartbeatError);
  all_sent();
  nmt(NmtCommand::Stop);
  master_heartbeat();
  EXPECT_EQ(node.lost_heartbeats(), 0u) << "heard while stopped";
  advance_us(kConsumerTimeUs);
  EXPECT_EQ(node.lost_heartbeats(), 1u);
  EXPECT_EQ(node.error_register(), kCommunicationError) << "active, though stopped sends no EMCY";
  EXPECT_TRUE(all_sent().empty());
}

TEST_F(HeartbeatConsumerTest, StoredWithTheCommunicationParametersAndRestoredToUnused) {
  watch_master();
  reset(NmtCommand::ResetCommunication);
  EXPECT_EQ(upload(kConsumerHeartbeat, 1), 0u) << "not stored: back to the default";
  watch_master();
  ASSERT_EQ(download(0x1010, 2, Node::kStoreSignature, 4), SdoAbort::None);
  ASSERT_EQ(download(kConsumerHeartbeat, 1, 0, 4), SdoAbort::None);
  reset(NmtCommand::ResetCommunication);
  EXPECT_EQ(upload(kConsumerHeartbeat, 1), consumer_entry(kMasterId, kConsumerTimeMs));
  reset(NmtCommand::ResetNode);
  EXPECT_EQ(upload(kConsumerHeartbeat, 1), consumer_entry(kMasterId, kConsumerTimeMs));
  // A stored entry starts waiting for the master's first heartbeat, like a written one.
  all_sent();
  for (int i = 0; i < 10; ++i) advance_us(kConsumerTimeUs);
  EXPECT_TRUE(all_sent().empty());
  ASSERT_EQ(download(0x1011, 2, Node::kRestoreSignature, 4), SdoAbort::None);
  EXPECT_EQ(upload(kConsumerHeartbeat, 1), consumer_entry(kMasterId, kConsumerTimeMs))
      << "restored communication defaults apply at the next reset";
  reset(NmtCommand::ResetCommunication);
  EXPECT_EQ(upload(kConsumerHeartbeat, 1), 0u);
}

TEST_F(HeartbeatConsumerTest, ResetCommunicationEndsALossAndTellsTheListener) {
  watch_master();
  master_heartbeat();
  advance_us(kConsumerTimeUs);
  ASSERT_EQ(node.lost_heartbeats(), 1u);
  reset(NmtCommand::ResetCommunication);
  EXPECT_EQ(node.lost_heartbeats(), 0u);
  EXPECT_EQ(listener.heard.back(), (HeardStatus{0, false}));
}

// Lockstep: time is control cycles times the period; the wall clock means nothing.
TEST_F(HeartbeatConsumerTest, OnControlCyclesOnlyControlTimeCounts) {
  constexpr std::uint32_t kPeriodUs = 1'000;
  node.set_timeout_clock(TimeoutClock::ControlCycles);
  watch_master();
  master_heartbeat();
  for (int i = 0; i < 100; ++i) advance_us(1'000'000);  // the host stalls for 100 s
  EXPECT_TRUE(all_sent().empty());
  // The master's heartbeat every 100 cycles of simulation time keeps it quiet...
  for (std::uint32_t cycle = 1; cycle <= 1000; ++cycle) {
    node.advance_control_time(kPeriodUs);
    if (cycle % 100 == 0) master_heartbeat();
  }
  EXPECT_TRUE(all_sent().empty());
  // ...and without it the event comes exactly kConsumerTimeMs cycles after the last one.
  for (std::uint32_t cycle = 1; cycle < kConsumerTimeMs; ++cycle) node.advance_control_time(kPeriodUs);
  EXPECT_TRUE(all_sent().empty());
  EXPECT_EQ(node.lost_heartbeats(), 0u);
  node.advance_control_time(kPeriodUs);
  EXPECT_EQ(next_sent(), heartbeat_emcy(kCommunicationError));
  EXPECT_EQ(node.lost_heartbeats(), 1u);
}

TEST_F(HeartbeatConsumerTest, OnWallTimeControlTimeIsIgnored) {
  watch_master();
  master_heartbeat();
  for (int i = 0; i < 1000; ++i) node.advance_control_time(1'000'000);
  EXPECT_TRUE(all_sent().empty());
  advance_us(kConsumerTimeUs);
  EXPECT_EQ(next_sent(), heartbeat_emcy(kCommunicationError));
}

// CiA 301's rule for several entries, on a consumer with three (the node has the table's count).
TEST(BasicHeartbeatConsumer, TwoUsedEntriesForOneNodeAreIncompatible) {
  BasicHeartbeatConsumer<3> consumer;
  ASSERT_EQ(consumer.configure(1, consumer_entry(5, 100)), SdoAbort::None);
  EXPECT_EQ(consumer.configure(2, consumer_entry(5, 200)), SdoAbort::ParameterIncompatible);
  EXPECT_EQ(consumer.entry(2), 0u);
  EXPECT_EQ(consumer.configure(2, consumer_entry(5, 0)), SdoAbort::None) << "time 0: unused";
  EXPECT_EQ(consumer.configure(1, consumer_entry(5, 300)), SdoAbort::None) << "its own entry";
  EXPECT_EQ(consumer.configure(3, consumer_entry(6, 100)), SdoAbort::None);
  EXPECT_EQ(consumer.configure(1, 0), SdoAbort::None);
  EXPECT_EQ(consumer.configure(2, consumer_entry(5, 200)), SdoAbort::None) << "free again";
  EXPECT_EQ(consumer.configure(4, 0), SdoAbort::SubIndexDoesNotExist);
}

TEST(BasicHeartbeatConsumer, EntriesTimeOutIndependently) {
  BasicHeartbeatConsumer<2> consumer;
  ASSERT_EQ(consumer.configure(1, consumer_entry(5, 10)), SdoAbort::None);
  ASSERT_EQ(consumer.configure(2, consumer_entry(6, 20)), SdoAbort::None);
  std::vector<std::uint8_t> lost;
  const auto record = [&lost](std::uint8_t node_id) { lost.push_back(node_id); };
  const std::uint32_t start = 0xFFFF'F000u;  // the clock wraps during the test
  consumer.heartbeat(5, start);
  consumer.heartbeat(6, start);
  EXPECT_TRUE(consumer.monitoring(1) && consumer.monitoring(2));
  consumer.check_timeouts(start + 9'999, record);
  EXPECT_TRUE(lost.empty());
  consumer.check_timeouts(start + 10'000, record);
  EXPECT_EQ(lost, (std::vector<std::uint8_t>{5}));
  consumer.heartbeat(6, start + 15'000);
  consumer.check_timeouts(start + 34'999, record);
  EXPECT_EQ(lost, (std::vector<std::uint8_t>{5}));
  EXPECT_EQ(consumer.lost_entries(), 1u);
  consumer.check_timeouts(start + 35'000, record);
  EXPECT_EQ(lost, (std::vector<std::uint8_t>{5, 6}));
  EXPECT_EQ(consumer.lost_entries(), 2u);
}

}  // namespace
}  // namespace co::test
