// libFuzzer target: a byte stream cut into a sequence of CAN frames fed to one co::Node, the
// way the Linux platform drives it (poll, process, and after a SYNC the synchronous TPDOs).
// Covers NMT, SYNC, the SDO server (expedited, segmented, block, timeouts) and RPDO reception,
// and the TPDOs and EMCYs they cause. Every violated invariant calls abort() so libFuzzer
// reports it.
//
// Input layout (firmware/canopen/fuzz/make_seeds.py writes seeds in it):
//   byte 0           board config: (b % 64) < field count -> the board refuses writes to that
//                    field (the FieldAccess "not owner" path); bit 6 -> storage starts with an
//                    image stored by a previous node; bit 7 -> the heartbeat consumer and the
//                    SDO server timeout run on control time (lockstep: each SYNC's cycle
//                    advances it by kCyclePeriodUs)
//   then records     [head][dt][raw id: 2 bytes, classes 10..15 only][data: min(len, 8) bytes]
//     head & 0x0F    frame length 0..15 (9..15 are invalid lengths the engine must drop)
//     head >> 4      identifier class: 0 NMT, 1 SYNC 0x080, 2 SDO request 0x600+id,
//                    3 SDO request to another node, 4..7 RPDO 1..4 default ids 0x200/0x300/
//                    0x400/0x500+id, 8 LSS request 0x7E5, 9 SDO response id, 10..13 raw 11-bit
//                    id (LE),
//                    14 raw id + RTR flag, 15 raw id + extended flag
//     dt             time step before the frame: < 128 -> dt * 8 us; else (dt-128)^2 * 100 us
//                    (up to 1.6 s: reaches heartbeat, SDO timeout and RPDO deadlines)
//
// Invariants (checked after every step):
//   1. No write through FieldAccess to a ReadOnly (firmware-owned) field; every value written
//      is inside the field's [min, max] and not NaN; HIL inputs stay inside their raw range.
//   2. Every SDO request the node must serve (0x600+id, 8 bytes, pre-operational or
//      operational, not a client abort) gets exactly one response on 0x580+id, a valid server
//      command or an abort with a code from the CiA 301 table; requests it must not serve get
//      none. Block transfer, as a client sees it: a download segment inside a sub-block gets
//      no answer, except the last of the sub-block, which gets the ack naming the last segment
//      in sequence; a block upload start or ack gets a burst of segments numbered 1, 2, ...
//      up to blksize or the last bit, Node::kSdoSegmentsPerCall per process()/poll() until the
//      sub-block is out (or the end frame once all is acknowledged); the client's end gets
//      nothing. A transfer left open by the client is aborted with "SDO protocol timed out" by
//      the first poll() at least SdoServer::kSegmentTimeoutUs later, and only then; on control
//      time, by the first SYNC's control cycle that far on, and never by poll().
//   3. Counters: each frame given to process() lands in exactly one outcome counter; the SDO,
//      heartbeat, TPDO and EMCY counters equal the frames seen on the port; nothing was dropped.
//   4. Error register: non-zero implies the generic bit; every EMCY (not an error reset) carries
//      a register with the generic bit set.
//   5. The field recorder (its objects reachable over SDO, a sample after every SYNC's control
//      cycle as on the platform): a recording that is done reads the same bytes until the
//      recorder leaves done (checked for recordings up to kFrozenCheckBytes).
//   6. Heartbeat consumer (0x1016): no more heartbeat events than heartbeats consumed (an entry
//      times out only after a heartbeat armed it, and once per heartbeat at most).
//   7. Acceptance filter (Node::accepted_ids, the platform's CAN_RAW_FILTER): the set the
//      listener last heard equals accepted_ids() whenever the node sends a frame and after
//      every step (no answer ever leaves while the filter lags), and a frame the filter would
//      drop (outside the set, or remote, or 29-bit) only counts as received and ignored: no
//      other counter, no state change, nothing sent. So the filter changes nothing on the bus.
//   9. Program download (CiA 302-3, a store in memory): the staging area is open exactly while
//      the node reports a download in progress; a download that ends any other way than a
//      completed, checked image (refused header, abort, timeout, reset) leaves nothing staged,
//      and the store keeps an image only while the node says it has one. A block
//      download the server aborts mid sub-block (a refused image header) drops the rest of that
//      sub-block's segments unanswered.
//   8. LSS (CiA 305): an 8-byte LSS request gets at most one answer, with the command specifier
//      CiA 305 pairs with the request; configure node-id succeeds exactly for 1..127 and 0xFF;
//      anything else gets none. A node without a node id (LSS took it away, then a reset
//      communication) accepts LSS only and sends nothing but LSS answers. The ids of the frame
//      classes follow the node's id as LSS changes it.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>
#include <vector>

#include "BlockCrcReference.hpp"
#include "MemoryPort.hpp"
#include "Recorder.hpp"
#include "Node.hpp"

namespace {

constexpr std::uint8_t kNodeId = 0x10;  // at start; LSS and a reset communication may change it
constexpr std::size_t kMaxFrames = 4096;

[[noreturn]] void fail(const char* what, unsigned long a = 0, unsigned long b = 0) {
  std::fprintf(stderr, "INVARIANT VIOLATED: %s (0x%lx, 0x%lx)\n", what, a, b);
  std::abort();
}

void check(bool ok, const char* what, unsigned long a = 0, unsigned long b = 0) {
  if (!ok) fail(what, a, b);
}

// FieldAccess that records writes and enforces invariant 1.
class RecordingBoard final : public co::FieldAccess {
 public:
  RecordingBoard() {
    for (std::size_t i = 0; i < board::kFieldCount; ++i) values[i] = board::kFields[i].default_value;
  }
  float read(board::FieldId id) override { return values[static_cast<std::size_t>(id)]; }
  co::WriteResult write(board::FieldId id, float value) override {
    const auto i = static_cast<std::size_t>(id);
    check(i < board::kFieldCount, "write to a field id outside the table", i);
    const board::FieldInfo& field = board::kFields[i];
    check(field.access != board::Access::ReadOnly, "write to a firmware-owned (ReadOnly) field",
          field.index);
    check(!std::isnan(value) && value >= field.min && value <= field.max,
          "field written outside its range", field.index);
    if (refused == static_cast<int>(i)) return co::WriteResult::Refused;
    values[i] = value;
    ++writes;
    return co::WriteResult::Accepted;
  }
  std::array<float, board::kFieldCount> values{};
  int refused = -1;
  std::uint32_t writes = 0;
};

class RecordingHil final : public co::HilIo {
 public:
  void write_input(board::HilInputId id, std::int32_t raw) override {
    const auto i = static_cast<std::size_t>(id);
    check(i < board::kHilInputCount, "write to a HIL input id outside the table", i);
    const board::IoInfo& io = board::kHilInputs[i];
    check(raw >= io.min && raw <= io.max, "HIL input written outside its range", io.index,
          static_cast<unsigned long>(raw));
  }
  std::int32_t read_output(board::HilOutputId id) override {
    return static_cast<std::int32_t>(static_cast<std::size_t>(id) * 7);
  }
};

class VectorStorage final : public co::ParameterStorage {
 public:
  bool save(std::span<const std::byte> image) override {
    bytes.assign(image.begin(), image.end());
    return true;
  }
  std::size_t load(std::span<std::byte> buffer) override {
    if (bytes.size() > buffer.size()) return 0;
    std::copy(bytes.begin(), bytes.end(), buffer.begin());
    return bytes.size();
  }
  std::vector<std::byte> bytes;
};

// The platform's side of the acceptance filter (invariant 7): a port whose filter is what the
// node's listener last heard, and which checks on every send that it matches the node.
class FilteredPort final : public co::CanPort, public co::AcceptanceListener {
 public:
  void watch(const co::Node& node) { node_ = &node; }
  co::SendResult send(const co::CanFrame& frame) override {
    check(matches_node(), "a frame went out while the filter lagged the accepted set", frame.id);
    return frames.send(frame);
  }
  co::ReceiveResult receive(co::CanFrame& frame) override { return frames.receive(frame); }
  void accepted_ids_changed(std::span<const std::uint32_t> cob_ids) override {
    check(!cob_ids.empty() && std::is_sorted(cob_ids.begin(), cob_ids.end()) &&
              std::adjacent_find(cob_ids.begin(), cob_ids.end()) == cob_ids.end(),
          "accepted set not ascending and unique", cob_ids.size());
    filter_.assign(cob_ids.begin(), cob_ids.end());
  }
  // What CAN_RAW_FILTER with mask CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG lets through.
  bool passes(const co::CanFrame& frame) const {
    return (frame.id & ~0x7FFu) == 0 && std::find(filter_.begin(), filter_.end(), frame.id) != filter_.end();
  }
  bool matches_node() const {
    if (node_ == nullptr) return true;
    std::array<std::uint32_t, co::Node::kMaxAcceptedIds> ids{};
    const std::size_t count = node_->accepted_ids(ids);
    return std::equal(ids.begin(), ids.begin() + static_cast<std::ptrdiff_t>(count), filter_.begin(),
                      filter_.end());
  }

  co::MemoryPort frames;

 private:
  const co::Node* node_ = nullptr;
  std::vector<std::uint32_t> filter_;
};

class Input {
 public:
  Input(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  bool empty() const { return pos_ >= size_; }
  std::uint8_t byte() { return pos_ < size_ ? data_[pos_++] : 0; }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
};

bool known_abort_code(std::uint32_t code) {
  using co::SdoAbort;
  for (SdoAbort a : {SdoAbort::ToggleBitNotAlternated, SdoAbort::ProtocolTimedOut,
                     SdoAbort::CommandSpecifierInvalid, SdoAbort::InvalidBlockSize,
                     SdoAbort::InvalidSequenceNumber, SdoAbort::CrcError, SdoAbort::OutOfMemory,
                     SdoAbort::UnsupportedAccess,
                     SdoAbort::WriteOnly, SdoAbort::ReadOnly, SdoAbort::ObjectDoesNotExist,
                     SdoAbort::ObjectCannotBeMapped, SdoAbort::PdoLengthExceeded,
                     SdoAbort::ParameterIncompatible,
                     SdoAbort::LengthMismatch, SdoAbort::LengthTooHigh, SdoAbort::LengthTooLow,
                     SdoAbort::SubIndexDoesNotExist, SdoAbort::ValueRangeExceeded,
                     SdoAbort::ValueTooHigh, SdoAbort::ValueTooLow, SdoAbort::GeneralError,
                     SdoAbort::DataCannotBeStored, SdoAbort::DeviceState}) {
    if (co::to_code(a) == code) return true;
  }
  return false;
}


std::uint32_t le32(const std::array<std::uint8_t, 8>& d, std::size_t at) {
  return d[at] | (d[at + 1] << 8) | (d[at + 2] << 16) | (std::uint32_t{d[at + 3]} << 24);
}

// The client's view of the SDO channel: which transfer (if any) the server must still have
// open, and since when it has been silent.
struct SdoModel {
  enum class Open : std::uint8_t {
    None,
    Download,          // segmented
    Upload,            // segmented
    BlockDownload,     // inside a sub-block: every frame but 0x80 is a segment
    BlockDownloadEnd,  // the last segment is in: the end request is due
    BlockUploadStart,  // initiate answered: the start request is due
    BlockUpload,       // the server sends a sub-block, the client acknowledges
    BlockUploadEnd,    // the server ended: the client's end is due
    BlockDownloadDrain,  // aborted mid sub-block: its remaining segments go unanswered
  };
  Open open = Open::None;
  std::uint8_t multiplexer[3] = {};
  std::uint32_t last_activity_us = 0;
  std::uint8_t block_size = 0;  // blksize of the sub-block under way
  std::uint8_t sequence = 0;    // download: last segment in sequence; upload: last one sent
  bool last_sent = false;       // upload: the sub-block ended with the last bit
  // Block upload: the value as the segments delivered it, to check the end frame's n and CRC.
  bool crc_requested = false;
  std::uint32_t announced_size = 0;
  std::size_t block_start = 0;  // offset of the sub-block's first byte
  std::vector<std::uint8_t> received;

  bool sub_block_open() const {
    return open == Open::BlockUpload && sequence < block_size && !last_sent;
  }
};

// co::ProgramStore in memory, checking invariant 9 from the store's side.
class MemoryProgramStore final : public co::ProgramStore {
 public:
  bool open_staging() override {
    check(!open, "staging opened twice without an end");
    staging.clear();
    kept.clear();
    open = true;
    return true;
  }
  bool write_staging(std::span<const std::uint8_t> bytes) override {
    check(open, "payload written outside a download");
    staging.insert(staging.end(), bytes.begin(), bytes.end());
    return true;
  }
  bool commit_staging() override {
    check(open, "commit outside a download");
    kept = staging;
    staging.clear();
    open = false;
    return true;
  }
  void discard_staging() override {
    staging.clear();
    kept.clear();
    open = false;
  }
  std::uint32_t running_image_crc32() override { return 0x600D'C0DEu; }

  std::vector<std::uint8_t> staging;
  std::vector<std::uint8_t> kept;
  bool open = false;
};

// Everything the node sent since the last drain, sorted by what it is.
struct Sent {
  std::vector<co::CanFrame> sdo;
  std::uint32_t boot_ups = 0;
  std::uint32_t heartbeats = 0;
  std::uint32_t other = 0;  // EMCY and TPDOs (a TPDO may legally use an EMCY-range id)
  std::uint32_t emcy_frames = 0;
  std::vector<co::CanFrame> lss;  // answers on cia305::kSlaveCobId
};

class Harness {
 public:
  explicit Harness(std::uint8_t config) {
    const std::size_t refuse = config % 64u;
    if (refuse < board::kFieldCount) board_.refused = static_cast<int>(refuse);
    if ((config & 0x40) != 0) {
      // A previous life of the node stored its parameters: start-up must load them.
      co::MemoryPort port;
      RecordingBoard board;
      RecordingHil hil;
      co::Node previous(kNodeId, port, board, hil, storage_);
      previous.start(0);
      (void)previous.store_parameters();
    }
    if ((config & 0x80) != 0) {
      control_clock_ = true;
      node_.set_timeout_clock(co::TimeoutClock::ControlCycles);
    }
    recorder_.reset();  // static: what an earlier input left must not matter
    node_.set_recorder(&recorder_);
    node_.set_program_store(&program_store_);
    port_.watch(node_);
    node_.set_acceptance_listener(&port_);
    node_.start(now_us_);
    Sent sent = drain();
    check(sent.boot_ups == 1 && sent.sdo.empty() && sent.heartbeats == 0,
          "start() must send exactly the boot-up message", sent.boot_ups);
    totals_.boot_ups += sent.boot_ups;
  }

  void step(Input& in) {
    const std::uint8_t head = in.byte();
    const std::uint8_t dt = in.byte();
    co::CanFrame frame;
    frame.len = head & 0x0F;
    frame.id = frame_id(static_cast<std::uint8_t>(head >> 4), in);
    for (std::size_t i = 0; i < frame.len && i < 8; ++i) frame.data[i] = in.byte();

    now_us_ += dt < 128 ? dt * 8u : (dt - 128u) * (dt - 128u) * 100u;
    poll_and_check();
    process_and_check(frame);
  }

  void finish() {
    // One last look after the client fell silent: the server timeout must fire, on its clock.
    if (control_clock_) {
      advance_control_time(co::SdoServer::kSegmentTimeoutUs);
      Sent sent = drain();
      check_sdo_timeout(sent);
      check_counters();
    } else {
      now_us_ += co::SdoServer::kSegmentTimeoutUs;
      poll_and_check();
    }
  }

 private:
  // The node's id now (LSS may give it another, or none: 0xFF).
  std::uint8_t id() const { return node_.node_id(); }

  std::uint32_t frame_id(std::uint8_t cls, Input& in) const {
    switch (cls) {
      case 0: return 0x000;
      case 1: return cia301::kSyncCobId;
      case 2: return cia301::cob_id(cia301::FunctionCode::SdoRequest, id());
      case 3: return cia301::cob_id(cia301::FunctionCode::SdoRequest, 1);
      case 4: return cia301::cob_id(cia301::FunctionCode::Rpdo1, id());
      case 5: return cia301::cob_id(cia301::FunctionCode::Rpdo2, id());
      case 6: return cia301::cob_id(cia301::FunctionCode::Rpdo3, id());
      case 7: return cia301::cob_id(cia301::FunctionCode::Rpdo4, id());
      case 8: return cia305::kMasterCobId;
      case 9: return cia301::cob_id(cia301::FunctionCode::SdoResponse, id());
      default: break;
    }
    const std::uint32_t raw = (in.byte() | (in.byte() << 8)) & 0x7FFu;
    if (cls == 14) return raw | co::CanFrame::kRemoteFlag;
    if (cls == 15) return raw | co::CanFrame::kExtendedFlag;
    return raw;
  }

  Sent drain() {
    Sent sent;
    co::CanFrame f;
    while (port_.frames.pop_sent(f)) {
      check(f.len <= 8, "sent a frame longer than 8 bytes", f.id, f.len);
      check((f.id & ~0x7FFu) == 0, "sent a frame with flags or a non 11-bit id", f.id);
      if (f.id == cia305::kSlaveCobId) {
        check(f.len == 8, "LSS answer not 8 bytes long", f.len);
        sent.lss.push_back(f);
      } else if (f.id == cia301::cob_id(cia301::FunctionCode::SdoResponse, id())) {
        check(f.len == 8, "SDO response not 8 bytes long", f.len);
        sent.sdo.push_back(f);
      } else if (f.id == cia301::cob_id(cia301::FunctionCode::Heartbeat, id())) {
        check(f.len == 1, "boot-up/heartbeat not 1 byte long", f.len);
        if (f.data[0] == 0) {
          ++sent.boot_ups;
        } else {
          check(f.data[0] == static_cast<std::uint8_t>(node_.state()),
                "heartbeat does not carry the NMT state", f.data[0]);
          ++sent.heartbeats;
        }
      } else {
        ++sent.other;
        if (f.id == cia301::cob_id(cia301::FunctionCode::SyncEmcy, id()) && f.len == 8) {
          ++sent.emcy_frames;
          const std::uint16_t code = static_cast<std::uint16_t>(f.data[0] | (f.data[1] << 8));
          if (code != 0) {
            check((f.data[2] & co::error_register::kGeneric) != 0,
                  "EMCY without the generic error bit in its error register", code, f.data[2]);
          }
        }
      }
    }
    totals_.boot_ups += sent.boot_ups;
    totals_.heartbeats += sent.heartbeats;
    totals_.other += sent.other;
    totals_.lss += static_cast<std::uint32_t>(sent.lss.size());
    totals_.sdo += sent.sdo.size();
    for (const co::CanFrame& r : sent.sdo) {
      if (r.data[0] == 0x80) ++totals_.sdo_aborts;
    }
    return sent;
  }

  void check_abort(const co::CanFrame& r) {
    const std::uint32_t code = le32(r.data, 4);
    check(known_abort_code(code), "SDO abort with a code outside the CiA 301 table", code);
  }

  // The clock the node's SDO server times its client out on (Node::set_timeout_clock).
  std::uint32_t timeout_now() const { return control_clock_ ? control_time_us_ : now_us_; }

  bool sdo_timeout_due() const {
    return sdo_.open != SdoModel::Open::None && node_.state() != co::NmtState::Stopped &&
           timeout_now() - sdo_.last_activity_us >= co::SdoServer::kSegmentTimeoutUs;
  }

  void advance_control_time(std::uint32_t elapsed_us) {
    node_.advance_control_time(elapsed_us);
    control_time_us_ += elapsed_us;
  }

  // What the clock's move sent (a poll on wall time, a control cycle on control time): the
  // timeout abort if one was due, else no SDO frame. Takes the abort out of `sent`.
  void check_sdo_timeout(Sent& sent) {
    if (sdo_.open == SdoModel::Open::BlockDownloadDrain) {  // aborted already: nothing more sent
      check(sent.sdo.empty(), "an SDO frame sent while an aborted sub-block drains", sent.sdo.size());
      if (sdo_timeout_due()) sdo_.open = SdoModel::Open::None;
      return;
    }
    if (!sdo_timeout_due()) {
      check(sent.sdo.empty(), "an SDO frame sent with no transfer timing out",
            sent.sdo.empty() ? 0 : sent.sdo.front().data[0]);
      return;
    }
    check(sent.sdo.size() == 1, "open SDO transfer not aborted after the server timeout", sent.sdo.size());
    const co::CanFrame& r = sent.sdo.front();
    check(r.data[0] == 0x80 && le32(r.data, 4) == co::to_code(co::SdoAbort::ProtocolTimedOut),
          "SDO timeout answered with something else than 0x05040000", r.data[0], le32(r.data, 4));
    check(r.data[1] == sdo_.multiplexer[0] && r.data[2] == sdo_.multiplexer[1] &&
              r.data[3] == sdo_.multiplexer[2],
          "SDO timeout abort names another object");
    sdo_.open = SdoModel::Open::None;
    sent.sdo.clear();
  }

  void poll_and_check() {
    node_.poll(now_us_);
    Sent sent = drain();
    const bool due = !control_clock_ && sdo_timeout_due();
    if (!due && sdo_.sub_block_open() && node_.state() != co::NmtState::Stopped) {
      check(!sent.sdo.empty(), "poll() did not go on with the sub-block", sdo_.sequence);
      check_segments(sent.sdo);
    } else if (!due) {
      check(sent.sdo.empty(), "poll() sent an SDO frame with no transfer timing out",
            sent.sdo.empty() ? 0 : sent.sdo.front().data[0]);
    } else {
      check_sdo_timeout(sent);
    }
    // A heartbeat event with 0x1029 = 2 stops the node from poll() too, ending any transfer.
    if (node_.state() == co::NmtState::Stopped) sdo_.open = SdoModel::Open::None;
    check_counters();
  }

  void process_and_check(const co::CanFrame& frame) {
    const co::NmtState before = node_.state();
    const bool served = frame.id == cia301::cob_id(cia301::FunctionCode::SdoRequest, id()) && frame.len == 8 &&
                        (before == co::NmtState::PreOperational ||
                         before == co::NmtState::Operational);
    const std::uint8_t cs = frame.data[0] >> 5;
    if (served) ++sdo_requests_;

    const bool filtered_out = !port_.passes(frame);
    const co::NodeCounters counters_before = node_.counters();

    const co::ProcessResult result = node_.process(frame, now_us_);
    ++frames_;
    check(!result.boot_sync || (control_clock_ && !result.sync), "a boot SYNC off the control clock");
    if (result.boot_sync) advance_control_time(kCyclePeriodUs);  // the boot's clock, no cycle
    if (result.sync) {
      // The control cycle would run here (after the consumer's control time moved on, as on the
      // platform); the recorder samples what it left on the board.
      if (control_clock_) advance_control_time(kCyclePeriodUs);
      recorder_.sample(++cycle_, [this](board::FieldId id) { return board_.read(id); });
      node_.transmit_synchronous_pdos(now_us_);
    }
    Sent sent = drain();
    if (result.sync && control_clock_) check_sdo_timeout(sent);  // the cycle's timeout abort
    if (filtered_out) check_filtered_out(frame, before, counters_before, sent);

    const bool drained = served && sdo_.open == SdoModel::Open::BlockDownloadDrain &&
                         frame.data[0] != 0x80 && (frame.data[0] & 0x7F) == sdo_.sequence + 1;
    if (served && sdo_.open == SdoModel::Open::BlockDownloadDrain && !drained) {
      sdo_.open = SdoModel::Open::None;  // the client's next request
    }
    if (drained) {
      check(sent.sdo.empty(), "segment of an aborted sub-block answered", frame.data[0]);
      sdo_.sequence = frame.data[0] & 0x7F;
      sdo_.last_activity_us = timeout_now();
      if (sdo_.sequence >= sdo_.block_size || (frame.data[0] & 0x80) != 0) {
        sdo_.open = SdoModel::Open::None;
      }
    } else if (served && sdo_.open == SdoModel::Open::BlockDownload && frame.data[0] != 0x80) {
      check_block_download_segment(frame.data, sent.sdo);
    } else if (!served || cs == 4) {  // not for the server, or a client abort: nothing to answer
      check(sent.sdo.empty(), "SDO response to a request that must not be answered",
            frame.id, frame.data[0]);
      if (served) sdo_.open = SdoModel::Open::None;
    } else if (cs == 5) {
      check_block_upload_request(frame.data, sent.sdo);
    } else if (cs == 6) {
      check_block_download_request(frame.data, sent.sdo);
    } else {
      check(sent.sdo.size() == 1, "SDO request not answered with exactly one response",
            frame.data[0], sent.sdo.size());
      check_response(frame, sent.sdo.front());
    }
    check_lss(frame, sent);
    // NMT stop (or a heartbeat event with 0x1029 = 2), both resets (whose boot-up comes the
    // node's boot time later) and losing the node id end any transfer without an answer.
    if (node_.state() == co::NmtState::Stopped || sent.boot_ups != 0 || node_.booting() ||
        !node_.has_node_id()) {
      sdo_.open = SdoModel::Open::None;
    }
    check_counters();
    check_program_store();
  }

  // Invariant 9.
  void check_program_store() const {
    const co::ProgramDownload& program = node_.program();
    check(program_store_.open == program.transfer_in_progress(), "staging open while no download runs",
          program_store_.open, program.transfer_in_progress());
    if (!program.transfer_in_progress()) {
      check(program_store_.staging.empty(), "bytes of an ended download left staged",
            program_store_.staging.size());
    }
    if (!program.image_kept()) {
      check(program_store_.kept.empty(), "an image kept that the node does not know of",
            program_store_.kept.size());
    }
  }

  // Invariant 8: LSS (CiA 305).
  void check_lss(const co::CanFrame& frame, const Sent& sent) {
    const bool lss_request = frame.id == cia305::kMasterCobId && frame.len == 8;
    check(sent.lss.size() <= (lss_request ? 1u : 0u), "LSS answers to a frame that asks for none", frame.id,
          sent.lss.size());
    if (!sent.lss.empty()) {
      using C = co::LssCommand;
      const auto asked = static_cast<C>(frame.data[0]);
      const auto answered = static_cast<C>(sent.lss.front().data[0]);
      C expected = asked;
      if (asked == C::SwitchStateSelectiveSerial) expected = C::SwitchStateSelectiveResponse;
      if (asked == C::IdentifyRemoteSerialHigh || asked == C::Fastscan) expected = C::IdentifySlave;
      if (asked == C::IdentifyNonConfiguredRemote) expected = C::IdentifyNonConfiguredSlave;
      check(answered == expected, "LSS answer with the wrong command specifier", frame.data[0],
            sent.lss.front().data[0]);
      if (asked == C::ConfigureNodeId) {
        const std::uint8_t wanted = frame.data[1];
        const bool valid = cia301::is_node_id(wanted) || wanted == cia305::kNodeIdUnconfigured;
        check((sent.lss.front().data[1] == 0) == valid, "configure node-id answered wrongly", wanted,
              sent.lss.front().data[1]);
      }
    }
    if (!node_.has_node_id()) {
      check(sent.sdo.empty() && sent.boot_ups == 0 && sent.heartbeats == 0 && sent.other == 0,
            "a node without a node id sent something else than an LSS answer", frame.id);
      std::array<std::uint32_t, co::Node::kMaxAcceptedIds> ids{};
      check(node_.accepted_ids(ids) == 1 && ids[0] == cia305::kMasterCobId,
            "a node without a node id accepts more than LSS");
    }
  }

  // Invariant 7: a frame the acceptance filter would have dropped made no difference.
  void check_filtered_out(const co::CanFrame& frame, co::NmtState state_before,
                          const co::NodeCounters& before, const Sent& sent) {
    const co::NodeCounters& after = node_.counters();
    check(after.frames_ignored == before.frames_ignored + 1,
          "a frame outside the accepted set was not just ignored", frame.id, frame.len);
    check(after.lss_requests == before.lss_requests, "the node served LSS outside its accepted set", frame.id);
    check(after.frames_malformed == before.frames_malformed && after.nmt_commands == before.nmt_commands &&
              after.syncs_received == before.syncs_received && after.sdo_requests == before.sdo_requests &&
              after.rpdos_received == before.rpdos_received &&
              after.rpdo_length_errors == before.rpdo_length_errors &&
              after.heartbeats_consumed == before.heartbeats_consumed,
          "the node acted on a frame outside its accepted set", frame.id, frame.len);
    check(node_.state() == state_before, "a frame outside the accepted set changed the NMT state", frame.id);
    check(sent.sdo.empty() && sent.boot_ups == 0 && sent.heartbeats == 0 && sent.other == 0 && sent.lss.empty(),
          "a frame outside the accepted set was answered", frame.id);
  }

  void check_response(const co::CanFrame& request, const co::CanFrame& response) {
    const auto& q = request.data;
    const auto& r = response.data;
    const std::uint8_t cs = q[0] >> 5;
    if (r[0] == 0x80) {
      check_abort(response);
      if (cs == 1 || cs == 2) {
        check(r[1] == q[1] && r[2] == q[2] && r[3] == q[3], "abort names another object");
      }
      sdo_.open = SdoModel::Open::None;
      return;
    }
    const bool echoes = r[1] == q[1] && r[2] == q[2] && r[3] == q[3];
    switch (cs) {
      case 1:  // initiate download
        check(r[0] == 0x60 && echoes, "bad initiate download response", r[0]);
        if ((q[0] & 0x02) != 0) {
          sdo_.open = SdoModel::Open::None;
        } else {
          open(SdoModel::Open::Download, q);
        }
        return;
      case 2:  // initiate upload
        check(echoes, "initiate upload response names another object", r[0]);
        if (r[0] == 0x41) {
          open(SdoModel::Open::Upload, q);
          return;
        }
        check((r[0] & 0xF3) == 0x43, "bad initiate upload response", r[0]);
        sdo_.open = SdoModel::Open::None;
        return;
      case 0:  // download segment
        check(sdo_.open == SdoModel::Open::Download, "download segment answered outside a download",
              r[0]);
        check(r[0] == (0x20 | (q[0] & 0x10)), "bad download segment response", r[0], q[0]);
        if ((q[0] & 0x01) != 0) {
          sdo_.open = SdoModel::Open::None;
        } else {
          sdo_.last_activity_us = timeout_now();
        }
        return;
      case 3:  // upload segment
        check(sdo_.open == SdoModel::Open::Upload, "upload segment answered outside an upload",
              r[0]);
        check((r[0] & 0xE0) == 0 && (r[0] & 0x10) == (q[0] & 0x10), "bad upload segment response",
              r[0], q[0]);
        if ((r[0] & 0x01) != 0) {
          sdo_.open = SdoModel::Open::None;
        } else {
          sdo_.last_activity_us = timeout_now();
        }
        return;
      default: fail("command specifier 7 answered without an abort", r[0]);
    }
  }

  // One frame that must be an abort with `code` (any known code when None); ends the transfer.
  void expect_abort(const std::vector<co::CanFrame>& frames, co::SdoAbort code, const char* what) {
    check(frames.size() == 1 && frames.front().data[0] == 0x80, what,
          frames.empty() ? 0 : frames.front().data[0], frames.size());
    check_abort(frames.front());
    if (code != co::SdoAbort::None) {
      check(le32(frames.front().data, 4) == co::to_code(code), what, le32(frames.front().data, 4));
    }
    sdo_.open = SdoModel::Open::None;
  }

  static bool valid_block_size(std::uint8_t segments) { return segments >= 1 && segments <= 127; }

  void check_block_download_segment(const std::array<std::uint8_t, 8>& q,
                                    const std::vector<co::CanFrame>& frames) {
    const std::uint8_t sequence = q[0] & 0x7F;
    const bool last = (q[0] & 0x80) != 0;
    if (sequence == 0 || sequence > sdo_.block_size) {
      expect_abort(frames, co::SdoAbort::InvalidSequenceNumber, "segment outside blksize not aborted");
      return;
    }
    const bool in_sequence = sequence == sdo_.sequence + 1;
    if (!frames.empty() && frames.front().data[0] == 0x80) {
      // Only new data can be too much for the object, or (a streamed one) refused by it.
      check(in_sequence, "segment out of sequence aborted instead of ignored", sequence, sdo_.sequence);
      const bool streamed = sdo_.multiplexer[0] == (cia302::kProgramDataIndex & 0xFF) &&
                            sdo_.multiplexer[1] == (cia302::kProgramDataIndex >> 8);
      expect_abort(frames, streamed ? co::SdoAbort::None : co::SdoAbort::LengthTooHigh,
                   "segment abort other than length too high");
      if (streamed && sequence < sdo_.block_size && !last) {
        sdo_.open = SdoModel::Open::BlockDownloadDrain;
        sdo_.sequence = sequence;
        sdo_.last_activity_us = timeout_now();
      }
      return;
    }
    if (in_sequence) sdo_.sequence = sequence;
    sdo_.last_activity_us = timeout_now();
    if (sequence < sdo_.block_size && !last) {
      check(frames.empty(), "segment inside a sub-block answered", q[0], frames.size());
      return;
    }
    check(frames.size() == 1, "end of sub-block not acknowledged once", q[0], frames.size());
    const auto& r = frames.front().data;
    check(r[0] == 0xA2 && r[1] == sdo_.sequence && valid_block_size(r[2]),
          "bad block download ack (must name the last segment in sequence)", le32(r, 0), sdo_.sequence);
    if (in_sequence && last) {
      sdo_.open = SdoModel::Open::BlockDownloadEnd;
    } else {
      sdo_.sequence = 0;
      sdo_.block_size = r[2];
    }
  }

  void check_block_download_request(const std::array<std::uint8_t, 8>& q,
                                    const std::vector<co::CanFrame>& frames) {
    check(frames.size() == 1, "block download request not answered once", q[0], frames.size());
    const auto& r = frames.front().data;
    if ((q[0] & 0x01) == 0) {  // initiate: a new transfer whatever was open
      if (r[0] == 0x80) {
        check(r[1] == q[1] && r[2] == q[2] && r[3] == q[3], "abort names another object");
        expect_abort(frames, co::SdoAbort::None, "");
        return;
      }
      check(r[0] == 0xA4 && r[1] == q[1] && r[2] == q[2] && r[3] == q[3] && valid_block_size(r[4]),
            "bad block download initiate response", le32(r, 0), r[4]);
      open(SdoModel::Open::BlockDownload, q);
      sdo_.block_size = r[4];
      sdo_.sequence = 0;
      return;
    }
    if (sdo_.open != SdoModel::Open::BlockDownloadEnd) {
      expect_abort(frames, co::SdoAbort::CommandSpecifierInvalid, "block download end out of turn");
      return;
    }
    check(r[0] == 0xA1 || r[0] == 0x80, "bad block download end response", r[0]);
    if (r[0] == 0x80) check_abort(frames.front());
    sdo_.open = SdoModel::Open::None;
  }

  void check_block_upload_request(const std::array<std::uint8_t, 8>& q,
                                  const std::vector<co::CanFrame>& frames) {
    const std::uint8_t subcommand = q[0] & 0x03;
    if (subcommand == 0) {  // initiate: a new transfer whatever was open
      check(frames.size() == 1, "block upload initiate not answered once", frames.size());
      const auto& r = frames.front().data;
      const bool echoes = r[1] == q[1] && r[2] == q[2] && r[3] == q[3];
      check(echoes, "block upload initiate answer names another object", r[0]);
      if (r[0] == 0x80) {
        expect_abort(frames,
                     valid_block_size(q[4]) ? co::SdoAbort::None : co::SdoAbort::InvalidBlockSize,
                     "blksize 0 or > 127 not refused as such");
        return;
      }
      check(valid_block_size(q[4]), "block upload accepted blksize 0 or > 127", q[4]);
      if (r[0] == 0xC6) {
        open(SdoModel::Open::BlockUploadStart, q);
        sdo_.block_size = q[4];
        sdo_.crc_requested = (q[0] & 0x04) != 0;
        sdo_.announced_size = le32(r, 4);
        sdo_.block_start = 0;
        sdo_.received.clear();
        return;
      }
      // The protocol switch: a normal upload, only for a value no larger than pst.
      const std::uint32_t size = r[0] == 0x41 ? le32(r, 4) : 4u - ((r[0] >> 2) & 0x3u);
      check(r[0] == 0x41 || (r[0] & 0xF3) == 0x43, "bad block upload initiate response", r[0]);
      check(q[5] != 0 && size <= q[5], "normal upload answer to a block upload above pst", size, q[5]);
      if (r[0] == 0x41) {
        open(SdoModel::Open::Upload, q);
      } else {
        sdo_.open = SdoModel::Open::None;
      }
      return;
    }
    const SdoModel::Open expected = subcommand == 3   ? SdoModel::Open::BlockUploadStart
                                    : subcommand == 2 ? SdoModel::Open::BlockUpload
                                                      : SdoModel::Open::BlockUploadEnd;
    if (sdo_.open != expected) {
      expect_abort(frames, co::SdoAbort::CommandSpecifierInvalid, "block upload command out of turn");
      return;
    }
    sdo_.last_activity_us = timeout_now();
    switch (subcommand) {
      case 3:  // start: the first sub-block
        sdo_.open = SdoModel::Open::BlockUpload;
        sdo_.sequence = 0;
        sdo_.last_sent = false;
        check(!frames.empty(), "block upload start sent no segment");
        check_segments(frames);
        return;
      case 2: {  // ack
        if (q[1] > sdo_.sequence) {
          expect_abort(frames, co::SdoAbort::InvalidSequenceNumber, "ack of segments never sent");
          return;
        }
        if (!valid_block_size(q[2])) {
          expect_abort(frames, co::SdoAbort::InvalidBlockSize, "ack with blksize 0 or > 127");
          return;
        }
        if (sdo_.last_sent && q[1] == sdo_.sequence) {
          check(frames.size() == 1 && (frames.front().data[0] & 0xE3) == 0xC1,
                "all acknowledged but no block upload end", frames.size());
          check_upload_end(frames.front().data);
          sdo_.open = SdoModel::Open::BlockUploadEnd;
          return;
        }
        sdo_.block_start += std::size_t{q[1]} * 7u;  // repeated from the segment after ackseq
        sdo_.block_size = q[2];
        sdo_.sequence = 0;
        sdo_.last_sent = false;
        check(!frames.empty(), "block upload ack sent no segment");
        check_segments(frames);
        return;
      }
      default:  // the client's end
        check(frames.empty(), "client's block upload end answered", frames.size());
        sdo_.open = SdoModel::Open::None;
        return;
    }
  }

  // The server's end: n leaves exactly the announced size, the CRC is that of the bytes the
  // segments carried (0 when the client did not ask for one).
  void check_upload_end(const std::array<std::uint8_t, 8>& r) {
    const std::size_t unused = (r[0] >> 2) & 0x7u;
    check(sdo_.received.size() >= 7 && sdo_.received.size() % 7 == 0, "segments not 7 bytes each",
          sdo_.received.size());
    const std::size_t size = sdo_.received.size() - unused;
    check(size == sdo_.announced_size, "block upload delivered another size than announced", size,
          sdo_.announced_size);
    const std::uint16_t crc =
        sdo_.crc_requested ? co::test::reference_crc(std::span(sdo_.received).first(size)) : 0;
    check((r[1] | (r[2] << 8)) == crc, "block upload end CRC does not match the data", r[1] | (r[2] << 8),
          crc);
  }

  // A burst of block upload segments: numbered on from the last one sent, within blksize,
  // nothing after the last bit, and as many as the node may send per call unless the
  // sub-block ended.
  void check_segments(const std::vector<co::CanFrame>& frames) {
    check(frames.size() <= co::Node::kSdoSegmentsPerCall, "more segments than allowed per call",
          frames.size());
    for (const co::CanFrame& f : frames) {
      check(f.data[0] != 0x80, "block upload segment replaced by an abort", le32(f.data, 4));
      const std::uint8_t sequence = f.data[0] & 0x7F;
      check(sdo_.sub_block_open() && sequence == sdo_.sequence + 1,
            "block upload segment out of sequence or past the sub-block", f.data[0], sdo_.sequence);
      sdo_.sequence = sequence;
      sdo_.last_sent = (f.data[0] & 0x80) != 0;
      // A repeated segment must carry the same bytes as the first time.
      const std::size_t offset = sdo_.block_start + (sequence - 1u) * 7u;
      check(offset <= sdo_.received.size(), "block upload segment skipped data", offset);
      for (std::size_t i = 0; i < 7; ++i) {
        if (offset + i < sdo_.received.size()) {
          check(sdo_.received[offset + i] == f.data[1 + i], "repeated segment differs", offset + i);
        } else {
          sdo_.received.push_back(f.data[1 + i]);
        }
      }
    }
    sdo_.last_activity_us = timeout_now();
    check(!sdo_.sub_block_open() || frames.size() == co::Node::kSdoSegmentsPerCall,
          "sub-block stalled: fewer segments than allowed per call", frames.size());
  }

  void open(SdoModel::Open kind, const std::array<std::uint8_t, 8>& q) {
    sdo_.open = kind;
    sdo_.multiplexer[0] = q[1];
    sdo_.multiplexer[1] = q[2];
    sdo_.multiplexer[2] = q[3];
    sdo_.last_activity_us = timeout_now();
  }

  void check_recorder() {
    if (recorder_.state() != board::RecorderState::Done) {
      frozen_.known = false;
      return;
    }
    std::array<std::uint8_t, 64> chunk{};
    std::size_t length = 0;
    std::size_t total = 0;
    std::uint32_t sum = 0;
    for (std::size_t offset = 0; offset < kFrozenCheckBytes; offset += chunk.size()) {
      check(recorder_.read_data(offset, chunk, length, total) == co::SdoAbort::None,
            "a done recording refused a read", offset);
      if (total > kFrozenCheckBytes) return;
      for (std::size_t i = 0; i < length; ++i) sum = sum * 31u + chunk[i];
      if (offset + length >= total) break;
    }
    if (!frozen_.known) frozen_ = {true, sum};
    check(sum == frozen_.sum, "a done recording changed", sum, frozen_.sum);
  }

  void check_counters() {
    check_recorder();
    check(port_.matches_node(), "the acceptance filter lags the node's accepted set");
    const co::NodeCounters& c = node_.counters();
    check(c.frames_received == frames_, "frames_received", c.frames_received, frames_);
    const std::uint32_t outcomes = c.frames_ignored + c.frames_malformed + c.nmt_commands +
                                   c.syncs_received + c.sdo_requests + c.rpdos_received +
                                   c.rpdo_length_errors + c.heartbeats_consumed + c.lss_requests;
    check(outcomes == c.frames_received, "a frame counted in no or in two outcome counters",
          outcomes, c.frames_received);
    check(c.sdo_requests == sdo_requests_, "sdo_requests", c.sdo_requests, sdo_requests_);
    check(c.sdo_aborts_sent == totals_.sdo_aborts, "sdo_aborts_sent", c.sdo_aborts_sent,
          totals_.sdo_aborts);
    check(c.heartbeats_sent == totals_.heartbeats, "heartbeats_sent", c.heartbeats_sent,
          totals_.heartbeats);
    check(c.tpdos_sent + c.emcy_sent == totals_.other, "tpdos_sent + emcy_sent",
          c.tpdos_sent + c.emcy_sent, totals_.other);
    check(c.send_failures == 0, "send failures on a port that never refuses", c.send_failures);
    check(node_.lss().counters().answers == totals_.lss, "LSS answers", node_.lss().counters().answers,
          totals_.lss);
    check(c.heartbeat_events <= c.heartbeats_consumed, "a heartbeat event no heartbeat armed",
          c.heartbeat_events, c.heartbeats_consumed);
    const std::uint8_t reg = node_.error_register();
    check(reg == 0 || (reg & co::error_register::kGeneric) != 0,
          "error register without the generic bit", reg);
  }

  FilteredPort port_;
  RecordingBoard board_;
  RecordingHil hil_;
  VectorStorage storage_;
  co::Node node_{kNodeId, port_, board_, hil_, storage_, 0x1234'5678};
  MemoryProgramStore program_store_;
  // Static, as on the platform (64 KiB of samples; not zeroed per input, reset() is enough).
  static inline co::Recorder recorder_;
  static constexpr std::size_t kFrozenCheckBytes = 4096;
  struct {
    bool known = false;
    std::uint32_t sum = 0;
  } frozen_;
  std::uint32_t cycle_ = 0;
  static constexpr std::uint32_t kCyclePeriodUs = 1'000;
  bool control_clock_ = false;
  std::uint32_t control_time_us_ = 0;  // the node's, on control_clock_
  std::uint32_t now_us_ = 0xFFF0'0000u;  // wraps early: the engine must handle it
  std::uint32_t frames_ = 0;
  std::uint32_t sdo_requests_ = 0;
  struct {
    std::uint32_t boot_ups = 0, heartbeats = 0, other = 0, sdo = 0, sdo_aborts = 0, lss = 0;
  } totals_;
  SdoModel sdo_;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  Input in(data, size);
  Harness harness(in.byte());
  for (std::size_t n = 0; n < kMaxFrames && !in.empty(); ++n) harness.step(in);
  harness.finish();
  return 0;
}
