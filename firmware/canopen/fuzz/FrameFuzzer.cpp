// libFuzzer target: a byte stream cut into a sequence of CAN frames fed to one co::Node, the
// way the Linux platform drives it (poll, process, and after a SYNC the synchronous TPDOs).
// Covers NMT, SYNC, the SDO server (expedited, segmented, timeouts) and RPDO reception, and the
// TPDOs and EMCYs they cause. Every violated invariant calls abort() so libFuzzer reports it.
//
// Input layout (firmware/canopen/fuzz/make_seeds.py writes seeds in it):
//   byte 0           board config: (b % 64) < field count -> the board refuses writes to that
//                    field (the FieldAccess "not owner" path); bit 6 -> storage starts with an
//                    image stored by a previous node
//   then records     [head][dt][raw id: 2 bytes, classes 10..15 only][data: min(len, 8) bytes]
//     head & 0x0F    frame length 0..15 (9..15 are invalid lengths the engine must drop)
//     head >> 4      identifier class: 0 NMT, 1 SYNC 0x080, 2 SDO request 0x600+id,
//                    3 SDO request to another node, 4..7 RPDO 1..4 default ids 0x200/0x300/
//                    0x400/0x500+id, 8 TPDO1 id, 9 SDO response id, 10..13 raw 11-bit id (LE),
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
//      none. A segmented transfer left open by the client is aborted with "SDO protocol timed
//      out" by the first poll() at least SdoServer::kSegmentTimeoutUs later, and only then.
//   3. Counters: each frame given to process() lands in exactly one outcome counter; the SDO,
//      heartbeat, TPDO and EMCY counters equal the frames seen on the port; nothing was dropped.
//   4. Error register: non-zero implies the generic bit; every EMCY (not an error reset) carries
//      a register with the generic bit set.
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>
#include <vector>

#include "MemoryPort.hpp"
#include "Node.hpp"

namespace {

constexpr std::uint8_t kNodeId = 0x10;
constexpr std::uint32_t kSdoRx = 0x600 + kNodeId;
constexpr std::uint32_t kSdoTx = 0x580 + kNodeId;
constexpr std::uint32_t kEmcy = 0x080 + kNodeId;
constexpr std::uint32_t kErrorControl = 0x700 + kNodeId;
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
                     SdoAbort::CommandSpecifierInvalid, SdoAbort::UnsupportedAccess,
                     SdoAbort::WriteOnly, SdoAbort::ReadOnly, SdoAbort::ObjectDoesNotExist,
                     SdoAbort::ObjectCannotBeMapped, SdoAbort::PdoLengthExceeded,
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

// The client's view of the SDO channel: which segmented transfer (if any) the server must
// still have open, and since when it has been silent.
struct SdoModel {
  enum class Open : std::uint8_t { None, Download, Upload };
  Open open = Open::None;
  std::uint8_t multiplexer[3] = {};
  std::uint32_t last_activity_us = 0;
};

// Everything the node sent since the last drain, sorted by what it is.
struct Sent {
  std::vector<co::CanFrame> sdo;
  std::uint32_t boot_ups = 0;
  std::uint32_t heartbeats = 0;
  std::uint32_t other = 0;  // EMCY and TPDOs (a TPDO may legally use an EMCY-range id)
  std::uint32_t emcy_frames = 0;
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
    // One last look after the client fell silent: the server timeout must fire.
    now_us_ += co::SdoServer::kSegmentTimeoutUs;
    poll_and_check();
  }

 private:
  static std::uint32_t frame_id(std::uint8_t cls, Input& in) {
    switch (cls) {
      case 0: return 0x000;
      case 1: return 0x080;
      case 2: return kSdoRx;
      case 3: return 0x601;
      case 4: return 0x200 + kNodeId;
      case 5: return 0x300 + kNodeId;
      case 6: return 0x400 + kNodeId;
      case 7: return 0x500 + kNodeId;
      case 8: return 0x180 + kNodeId;
      case 9: return kSdoTx;
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
    while (port_.pop_sent(f)) {
      check(f.len <= 8, "sent a frame longer than 8 bytes", f.id, f.len);
      check((f.id & ~0x7FFu) == 0, "sent a frame with flags or a non 11-bit id", f.id);
      if (f.id == kSdoTx) {
        check(f.len == 8, "SDO response not 8 bytes long", f.len);
        sent.sdo.push_back(f);
      } else if (f.id == kErrorControl) {
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
        if (f.id == kEmcy && f.len == 8) {
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

  void poll_and_check() {
    node_.poll(now_us_);
    Sent sent = drain();
    const bool due = sdo_.open != SdoModel::Open::None && node_.state() != co::NmtState::Stopped &&
                     now_us_ - sdo_.last_activity_us >= co::SdoServer::kSegmentTimeoutUs;
    if (!due) {
      check(sent.sdo.empty(), "poll() sent an SDO frame with no transfer timing out",
            sent.sdo.empty() ? 0 : sent.sdo.front().data[0]);
    } else {
      check(sent.sdo.size() == 1, "open SDO transfer not aborted after the server timeout",
            sent.sdo.size());
      const co::CanFrame& r = sent.sdo.front();
      check(r.data[0] == 0x80 && le32(r.data, 4) == co::to_code(co::SdoAbort::ProtocolTimedOut),
            "SDO timeout answered with something else than 0x05040000", r.data[0], le32(r.data, 4));
      check(r.data[1] == sdo_.multiplexer[0] && r.data[2] == sdo_.multiplexer[1] &&
                r.data[3] == sdo_.multiplexer[2],
            "SDO timeout abort names another object");
      sdo_.open = SdoModel::Open::None;
    }
    check_counters();
  }

  void process_and_check(const co::CanFrame& frame) {
    const co::NmtState before = node_.state();
    const bool served = frame.id == kSdoRx && frame.len == 8 &&
                        (before == co::NmtState::PreOperational ||
                         before == co::NmtState::Operational);
    const std::uint8_t cs = frame.data[0] >> 5;
    if (served) ++sdo_requests_;

    const co::ProcessResult result = node_.process(frame, now_us_);
    ++frames_;
    if (result.sync) node_.transmit_synchronous_pdos(now_us_);
    Sent sent = drain();

    if (!served || cs == 4) {  // not for the server, or a client abort: nothing to answer
      check(sent.sdo.empty(), "SDO response to a request that must not be answered",
            frame.id, frame.data[0]);
      if (served) sdo_.open = SdoModel::Open::None;
    } else {
      check(sent.sdo.size() == 1, "SDO request not answered with exactly one response",
            frame.data[0], sent.sdo.size());
      check_response(frame, sent.sdo.front());
    }
    // NMT stop and both resets end any transfer without an answer.
    if (node_.state() == co::NmtState::Stopped || sent.boot_ups != 0) {
      sdo_.open = SdoModel::Open::None;
    }
    check_counters();
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
          sdo_.last_activity_us = now_us_;
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
          sdo_.last_activity_us = now_us_;
        }
        return;
      default: fail("block transfer (unsupported) answered without an abort", r[0]);
    }
  }

  void open(SdoModel::Open kind, const std::array<std::uint8_t, 8>& q) {
    sdo_.open = kind;
    sdo_.multiplexer[0] = q[1];
    sdo_.multiplexer[1] = q[2];
    sdo_.multiplexer[2] = q[3];
    sdo_.last_activity_us = now_us_;
  }

  void check_counters() {
    const co::NodeCounters& c = node_.counters();
    check(c.frames_received == frames_, "frames_received", c.frames_received, frames_);
    const std::uint32_t outcomes = c.frames_ignored + c.frames_malformed + c.nmt_commands +
                                   c.syncs_received + c.sdo_requests + c.rpdos_received +
                                   c.rpdo_length_errors;
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
    const std::uint8_t reg = node_.error_register();
    check(reg == 0 || (reg & co::error_register::kGeneric) != 0,
          "error register without the generic bit", reg);
  }

  co::MemoryPort port_;
  RecordingBoard board_;
  RecordingHil hil_;
  VectorStorage storage_;
  co::Node node_{kNodeId, port_, board_, hil_, storage_, 0x1234'5678};
  std::uint32_t now_us_ = 0xFFF0'0000u;  // wraps early: the engine must handle it
  std::uint32_t frames_ = 0;
  std::uint32_t sdo_requests_ = 0;
  struct {
    std::uint32_t boot_ups = 0, heartbeats = 0, other = 0, sdo = 0, sdo_aborts = 0;
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
