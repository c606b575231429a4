// NMT slave state machine (CiA 301, 7.3.2): boot-up, transitions, what each state serves.
#include "NodeTestSupport.hpp"
#include "TimeLeft.hpp"

namespace co::test {
namespace {

using board::FieldId;

class NmtTest : public NodeTest {};

TEST(NmtStartTest, StartSendsBootUpAndEntersPreOperational) {
  MemoryPort port;
  FakeBoard fields;
  FakeHil hil;
  MemoryStorage storage;
  Node node(0x22, port, fields, hil, storage);
  EXPECT_EQ(node.state(), NmtState::Initialising);
  EXPECT_EQ(port.sent_count(), 0u) << "nothing is sent before start()";
  node.start(0);
  CanFrame frame;
  ASSERT_TRUE(port.pop_sent(frame));
  EXPECT_EQ(frame, make_frame(cia301::cob_id(cia301::FunctionCode::Heartbeat, 0x22), {0x00}));
  EXPECT_EQ(node.state(), NmtState::PreOperational);
}

TEST(NmtStartTest, FramesBeforeStartAreIgnored) {
  MemoryPort port;
  FakeBoard fields;
  FakeHil hil;
  MemoryStorage storage;
  Node node(0x22, port, fields, hil, storage);
  node.process(make_frame(cia301::cob_id(cia301::FunctionCode::SdoRequest, 0x22), {0x40, 0x00, 0x10, 0, 0, 0, 0, 0}), 0);
  node.process(make_frame(0x000, {0x01, 0x22}), 0);
  EXPECT_EQ(port.sent_count(), 0u);
  EXPECT_EQ(node.state(), NmtState::Initialising);
  EXPECT_EQ(node.counters().frames_ignored, 2u);
}

TEST_F(NmtTest, StartStopAndPreOperationalFollowTheCommands) {
  nmt(NmtCommand::Start);
  EXPECT_EQ(node.state(), NmtState::Operational);
  nmt(NmtCommand::Stop);
  EXPECT_EQ(node.state(), NmtState::Stopped);
  nmt(NmtCommand::Start);
  EXPECT_EQ(node.state(), NmtState::Operational);
  nmt(NmtCommand::EnterPreOperational);
  EXPECT_EQ(node.state(), NmtState::PreOperational);
  nmt(NmtCommand::Stop);
  EXPECT_EQ(node.state(), NmtState::Stopped);
  nmt(NmtCommand::EnterPreOperational);
  EXPECT_EQ(node.state(), NmtState::PreOperational);
  EXPECT_TRUE(all_sent().empty()) << "state changes alone send nothing";
  EXPECT_EQ(node.counters().nmt_commands, 6u);
}

TEST_F(NmtTest, BroadcastCommandApplies) {
  nmt(NmtCommand::Start, 0);
  EXPECT_EQ(node.state(), NmtState::Operational);
}

TEST_F(NmtTest, CommandForAnotherNodeIsIgnored) {
  nmt(NmtCommand::Start, kNodeId + 1);
  EXPECT_EQ(node.state(), NmtState::PreOperational);
  nmt(NmtCommand::ResetNode, kNodeId + 1);
  EXPECT_TRUE(all_sent().empty());
}

TEST_F(NmtTest, MalformedNmtFramesAreCountedAndIgnored) {
  receive(0x000, {0x01});                 // too short
  receive(0x000, {0x07, kNodeId});        // unknown command
  EXPECT_EQ(node.state(), NmtState::PreOperational);
  EXPECT_EQ(node.counters().frames_malformed, 2u);
}

TEST_F(NmtTest, StoppedNodeDoesNotServeSdo) {
  nmt(NmtCommand::Stop);
  receive(kSdoRx, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0});
  EXPECT_TRUE(all_sent().empty());
  nmt(NmtCommand::EnterPreOperational);
  EXPECT_EQ(upload(0x1000, 0), board::kNode.device_type);
}

TEST_F(NmtTest, StopDropsATransferInProgress) {
  sdo({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0});  // segmented upload of 0x1008 begins
  nmt(NmtCommand::Stop);
  nmt(NmtCommand::EnterPreOperational);
  EXPECT_EQ(sdo({0x60, 0, 0, 0, 0, 0, 0, 0}),
            abort_data(0x1008, 0, SdoAbort::CommandSpecifierInvalid));
}

TEST_F(NmtTest, SdoIsServedInPreOperationalAndOperational) {
  EXPECT_EQ(upload(0x1000, 0), board::kNode.device_type);
  nmt(NmtCommand::Start);
  EXPECT_EQ(upload(0x1000, 0), board::kNode.device_type);
}

TEST_F(NmtTest, SyncIsReportedInPreOperationalAndOperationalButNotStopped) {
  EXPECT_TRUE(receive(cia301::kSyncCobId, {}).sync);
  nmt(NmtCommand::Start);
  const ProcessResult with_counter = receive(cia301::kSyncCobId, {7});
  EXPECT_TRUE(with_counter.sync);
  EXPECT_TRUE(with_counter.sync_has_counter);
  EXPECT_EQ(with_counter.sync_counter, 7);
  nmt(NmtCommand::Stop);
  EXPECT_FALSE(receive(cia301::kSyncCobId, {}).sync);
  EXPECT_EQ(node.counters().syncs_received, 2u);
}

TEST_F(NmtTest, SyncLongerThanOneByteIsMalformed) {
  EXPECT_FALSE(receive(cia301::kSyncCobId, {1, 2}).sync);
  EXPECT_EQ(node.counters().frames_malformed, 1u);
}

TEST_F(NmtTest, NoPdosUnlessOperational) {
  // Pre-operational: SYNC sends no TPDO, RPDOs are not applied.
  ASSERT_GT(board::kTpdoCount, 0u);
  sync();
  EXPECT_TRUE(all_sent().empty());
  const auto rpdo1 = board::kDefaultRpdos[0];
  ASSERT_TRUE(rpdo1.enabled);
  receive(make_frame(rpdo1.cob_id_base + kNodeId, {1, 2, 3, 4, 5, 6, 7, 8}));
  EXPECT_EQ(hil.input_writes, 0u);
  for (std::uint32_t w : fields.writes) EXPECT_EQ(w, 0u);
  // Operational: the default synchronous TPDOs go out.
  nmt(NmtCommand::Start);
  sync();
  EXPECT_FALSE(all_sent().empty());
  // Stopped: nothing again.
  nmt(NmtCommand::Stop);
  receive(cia301::kSyncCobId, {});
  node.transmit_synchronous_pdos(now_us);
  EXPECT_TRUE(all_sent().empty());
}

TEST_F(NmtTest, ResetCommunicationSendsBootUpAndRestoresCommunicationParameters) {
  ASSERT_EQ(download(0x1005, 0, 0x81, 4), SdoAbort::None);
  nmt(NmtCommand::Start);
  nmt(NmtCommand::ResetCommunication);
  EXPECT_EQ(next_sent(), make_frame(cia301::cob_id(cia301::FunctionCode::Heartbeat, kNodeId), {0x00}));
  EXPECT_EQ(node.state(), NmtState::PreOperational);
  EXPECT_EQ(upload(0x1005, 0), cia301::kSyncCobId);
  EXPECT_EQ(upload(0x1017, 0), board::kNode.heartbeat_ms);
}

TEST_F(NmtTest, ResetCommunicationLeavesBoardFieldsAlone) {
  const FieldId id = FieldId::velocity_setpoint;
  ASSERT_EQ(download_float(index_of(id), 1.25f), SdoAbort::None);
  nmt(NmtCommand::ResetCommunication);
  EXPECT_FLOAT_EQ(fields.values[FakeBoard::index(id)], 1.25f);
}

TEST_F(NmtTest, ResetNodeRestoresBusOwnedFieldsAndReportsIt) {
  const FieldId id = FieldId::velocity_setpoint;
  ASSERT_EQ(download_float(index_of(id), 1.25f), SdoAbort::None);
  nmt(NmtCommand::Start);
  const ProcessResult result = receive(0x000, {0x81, kNodeId});
  EXPECT_TRUE(result.application_reset);
  EXPECT_FLOAT_EQ(fields.values[FakeBoard::index(id)], board::info(id).default_value);
  EXPECT_EQ(next_sent(), make_frame(cia301::cob_id(cia301::FunctionCode::Heartbeat, kNodeId), {0x00}));
  EXPECT_EQ(node.state(), NmtState::PreOperational);
}

TEST_F(NmtTest, ResetNodeReappliesStoredParameters) {
  const FieldId id = FieldId::velocity_kp;
  ASSERT_TRUE(board::info(id).stored);
  const float stored = board::info(id).max;
  ASSERT_NE(stored, board::info(id).default_value);
  ASSERT_EQ(download_float(index_of(id), stored), SdoAbort::None);
  ASSERT_EQ(download(0x1010, 1, Node::kStoreSignature, 4), SdoAbort::None);
  nmt(NmtCommand::ResetNode);
  EXPECT_FLOAT_EQ(fields.values[FakeBoard::index(id)], stored);
  EXPECT_EQ(node.parameter_load(), ParameterLoad::Loaded);
}

TEST_F(NmtTest, ExtendedAndRemoteFramesAreIgnored) {
  receive(make_frame(kSdoRx | CanFrame::kExtendedFlag, {0x40, 0x00, 0x10, 0, 0, 0, 0, 0}));
  receive(make_frame(0x000 | CanFrame::kRemoteFlag, {0x01, kNodeId}));
  EXPECT_TRUE(all_sent().empty());
  EXPECT_EQ(node.state(), NmtState::PreOperational);
  EXPECT_EQ(node.counters().frames_ignored, 2u);
}

// CiA 301, 7.2.8 (NMT reset node): every object the firmware does not store is back at its
// power-on value, the HIL inputs included (the issue found 0x3001 at its last value).
TEST_F(NmtTest, ResetNodeReturnsHilInputsToTheirPowerOnValues) {
  ASSERT_EQ(index_of(board::HilInputId::output_encoder_counts), 0x3001);
  EXPECT_EQ(sdo({0x2B, 0x01, 0x30, 0x00, 0xD2, 0x04, 0, 0}),
            (std::array<std::uint8_t, 8>{0x60, 0x01, 0x30, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(sdo({0x40, 0x01, 0x30, 0x00, 0, 0, 0, 0}),
            (std::array<std::uint8_t, 8>{0x4B, 0x01, 0x30, 0x00, 0xD2, 0x04, 0, 0}));
  nmt(NmtCommand::ResetNode);
  EXPECT_EQ(next_sent(), make_frame(kHeartbeat, {0x00}));
  EXPECT_EQ(sdo({0x40, 0x01, 0x30, 0x00, 0, 0, 0, 0}),
            (std::array<std::uint8_t, 8>{0x4B, 0x01, 0x30, 0x00, 0x00, 0x00, 0, 0}));
}

TEST_F(NmtTest, ResetCommunicationLeavesTheApplicationAlone) {
  const FieldId id = FieldId::velocity_setpoint;
  ASSERT_EQ(download_float(index_of(id), 1.25f), SdoAbort::None);
  ASSERT_EQ(download(0x3001, 0, 1234, 2), SdoAbort::None);
  nmt(NmtCommand::ResetCommunication);
  all_sent();
  EXPECT_FLOAT_EQ(fields.values[FakeBoard::index(id)], 1.25f);
  EXPECT_EQ(upload(0x3001, 0), 1234u);
}

class CountingApplicationReset final : public ApplicationReset {
 public:
  explicit CountingApplicationReset(FakeBoard& board) : board_{board} {}
  void reset_application() override {
    ++resets;
    board_.values.fill(-7.0f);  // whatever a fresh application holds: the node writes after it
  }
  int resets = 0;

 private:
  FakeBoard& board_;
};

TEST_F(NmtTest, ResetNodeResetsTheApplicationThenAppliesDefaultsAndStoredValues) {
  CountingApplicationReset application{fields};
  node.set_application_reset(&application);
  const FieldId stored = FieldId::velocity_kp;
  ASSERT_EQ(download_float(index_of(stored), board::info(stored).max), SdoAbort::None);
  ASSERT_EQ(download(0x1010, 3, Node::kStoreSignature, 4), SdoAbort::None);
  nmt(NmtCommand::ResetCommunication);
  EXPECT_EQ(application.resets, 0);
  nmt(NmtCommand::ResetNode);
  EXPECT_EQ(application.resets, 1);
  EXPECT_FLOAT_EQ(fields.values[FakeBoard::index(stored)], board::info(stored).max);
  const FieldId command = FieldId::control_mode;
  EXPECT_FLOAT_EQ(fields.values[FakeBoard::index(command)], board::info(command).default_value);
}

TEST_F(NmtTest, ResetNodeClearsTheErrorRegisterAndHistory) {
  node.report_emcy(emcy::over_temperature(FieldId::winding_temperature));
  all_sent();  // the EMCY frame
  ASSERT_NE(upload(0x1001, 0), 0u);
  ASSERT_EQ(upload(0x1003, 0), 1u);
  nmt(NmtCommand::ResetNode);
  EXPECT_EQ(next_sent(), make_frame(kHeartbeat, {0x00}));
  EXPECT_TRUE(all_sent().empty()) << "no error reset frame: the boot-up says it all";
  EXPECT_EQ(upload(0x1001, 0), 0u);
  EXPECT_EQ(upload(0x1003, 0), 0u);
  EXPECT_EQ(node.error_register(), 0u);
}

// The boot time (board.toml's [node] boot_ms): after an NMT reset the node is silent for that
// long, then sends its boot-up; on the wall clock, or in lockstep on the control clock.
class NmtBootTimeTest : public NodeTest {
 protected:
  static constexpr std::uint32_t kBootUs = board::kNode.boot_ms * 1000u;
  static constexpr std::uint32_t kPeriodUs = board::kNode.period_us;  // the default control period

  void SetUp() override {
    NodeTest::SetUp();
    node.set_boot_time_us(kBootUs);  // what the node has unless told otherwise
  }

  // A SYNC of a lockstep platform while the node boots: the control clock moves on, no cycle.
  bool lockstep_boot_sync() {
    const ProcessResult result = receive(cia301::kSyncCobId, {});
    EXPECT_FALSE(result.sync) << "no control cycle while booting";
    if (result.boot_sync) node.advance_control_time(kPeriodUs);
    return result.boot_sync;
  }
};

TEST(NmtBootTimeDefaultTest, IsTheTablesAndNotZero) {
  MemoryPort port;
  FakeBoard fields;
  FakeHil hil;
  MemoryStorage storage;
  const Node node(0x22, port, fields, hil, storage);
  EXPECT_EQ(node.boot_time_us(), board::kNode.boot_ms * 1000u);
  EXPECT_GT(node.boot_time_us(), 0u) << "the table's default is a real device's";
}

TEST_F(NmtBootTimeTest, OnTheWallClockTheBootUpComesTheBootTimeAfterResetNode) {
  static_assert(kBootUs > 1);
  nmt(NmtCommand::ResetNode);
  EXPECT_TRUE(all_sent().empty()) << "the boot-up waits for the boot time";
  EXPECT_TRUE(node.booting());
  EXPECT_EQ(node.state(), NmtState::Initialising);
  EXPECT_EQ(node.us_until_next_timer(now_us, kNoTimerUs), kBootUs) << "the idle wait ends with the boot";
  // Booting, the node answers nothing: an SDO request, NMT start and a SYNC are ignored.
  const std::uint32_t ignored = node.counters().frames_ignored;
  receive(kSdoRx, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0});
  nmt(NmtCommand::Start);
  const ProcessResult sync = receive(cia301::kSyncCobId, {});
  EXPECT_FALSE(sync.sync || sync.boot_sync) << "on the wall clock a SYNC clocks nothing";
  EXPECT_EQ(node.counters().frames_ignored, ignored + 3);
  advance_us(kBootUs - 1);
  EXPECT_TRUE(all_sent().empty());
  EXPECT_EQ(node.us_until_next_timer(now_us, kNoTimerUs), 1u);
  advance_us(1);
  EXPECT_EQ(all_sent(), (std::vector<CanFrame>{make_frame(kHeartbeat, {0x00})}));
  EXPECT_FALSE(node.booting());
  EXPECT_EQ(node.state(), NmtState::PreOperational);
  EXPECT_EQ(upload(0x1000, 0), board::kNode.device_type) << "served again once booted";
}

TEST_F(NmtBootTimeTest, ResetCommunicationTakesTheBootTimeToo) {
  nmt(NmtCommand::Start);
  nmt(NmtCommand::ResetCommunication);
  EXPECT_TRUE(all_sent().empty());
  EXPECT_EQ(node.state(), NmtState::Initialising);
  advance_us(kBootUs);
  EXPECT_EQ(all_sent(), (std::vector<CanFrame>{make_frame(kHeartbeat, {0x00})}));
  EXPECT_EQ(node.state(), NmtState::PreOperational);
}

TEST_F(NmtBootTimeTest, TheHeartbeatStartsAtTheBootUp) {
  nmt(NmtCommand::ResetCommunication);  // the producer time is back at the table's
  advance_us(kBootUs);
  EXPECT_EQ(all_sent(), (std::vector<CanFrame>{make_frame(kHeartbeat, {0x00})}));
  const std::uint32_t period_us = std::uint32_t{board::kNode.heartbeat_ms} * 1000u;
  ASSERT_GT(period_us, 1u);
  advance_us(period_us - 1);
  EXPECT_TRUE(all_sent().empty()) << "no heartbeat while booting, the first a period after the boot-up";
  advance_us(1);
  EXPECT_EQ(all_sent(), (std::vector<CanFrame>{make_frame(kHeartbeat, {0x7F})}));
}

TEST_F(NmtBootTimeTest, InLockstepTheBootTimeIsCountedInControlCycles) {
  node.set_timeout_clock(TimeoutClock::ControlCycles);
  nmt(NmtCommand::ResetNode);
  EXPECT_EQ(node.us_until_next_timer(now_us, kNoTimerUs), kNoTimerUs) << "no wall-clock timer";
  advance_us(10 * kBootUs);  // a host that took long: wall time does not count
  EXPECT_TRUE(all_sent().empty());
  EXPECT_TRUE(node.booting());
  const std::uint32_t cycles = kBootUs / kPeriodUs;
  ASSERT_GT(cycles, 1u);
  for (std::uint32_t n = 1; n < cycles; ++n) {
    ASSERT_TRUE(lockstep_boot_sync()) << "a SYNC while booting is the boot time's clock, cycle " << n;
    ASSERT_TRUE(all_sent().empty()) << "cycle " << n;
    receive(kSdoRx, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0});  // still answers nothing
    ASSERT_TRUE(all_sent().empty()) << "cycle " << n;
  }
  EXPECT_TRUE(lockstep_boot_sync());
  EXPECT_EQ(all_sent(), (std::vector<CanFrame>{make_frame(kHeartbeat, {0x00})})) << "in cycle " << cycles;
  EXPECT_EQ(node.state(), NmtState::PreOperational);
  EXPECT_EQ(upload(0x1000, 0), board::kNode.device_type);
}

TEST_F(NmtBootTimeTest, ZeroBootsAtOnceAndStartIsAlwaysAtOnce) {
  node.set_boot_time_us(0);
  nmt(NmtCommand::ResetNode);
  EXPECT_EQ(all_sent(), (std::vector<CanFrame>{make_frame(kHeartbeat, {0x00})}));
  EXPECT_FALSE(node.booting());
  MemoryPort other_port;
  Node other(0x22, other_port, fields, hil, storage);
  ASSERT_GT(other.boot_time_us(), 0u);
  other.start(now_us);  // power-on: the process start is the boot
  CanFrame frame;
  ASSERT_TRUE(other_port.pop_sent(frame));
  EXPECT_EQ(frame, make_frame(cia301::cob_id(cia301::FunctionCode::Heartbeat, 0x22), {0x00}));
}

}  // namespace
}  // namespace co::test
