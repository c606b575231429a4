// A CTU CAN FD controller driver behind co::CanPort (through InterruptCanPort's rings): classic
// frames only for now, the core's CAN FD side left at its reset settings. Registers as the
// core's datasheet (the CTU CAN FD IP core's "System architecture" and register map) documents
// them: 32-bit little-endian words at `Registers`, which is the MMIO window of one core on the
// target and a register model in the host's unit test (CtuCanFdTest.cpp).
//
// Receive: the interrupt (RX buffer not empty) moves every frame out of the core's RX FIFO into
// the port's receive ring, through the node's accepted set (the core's filter A holds the
// accepted ids' common bits, a superset; the set itself is checked here). Transmit: one TXT
// buffer in flight at a time, the four in rotation, so frames leave in the order the node sent
// them (the core picks among ready buffers by priority, not by age). Errors: the fault
// confinement state (error active, passive, bus-off) and the error counters are read on the
// state-change interrupt; the main loop turns a change into EMCY (FirmwareMain.cpp).
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "InterruptCanPort.hpp"
#include "canopen/CanPort.hpp"
#include "canopen/Interfaces.hpp"

namespace virt::ctucan {

// Register offsets (bytes) of one core.
namespace reg {
inline constexpr std::uint32_t kDeviceId = 0x00;  // 0xCAFD in bits 0..15, version above
inline constexpr std::uint32_t kMode = 0x04;      // MODE (bits 0..15) and SETTINGS (16..31)
inline constexpr std::uint32_t kStatus = 0x08;
inline constexpr std::uint32_t kCommand = 0x0C;
inline constexpr std::uint32_t kIntStat = 0x10;  // write 1 to clear
inline constexpr std::uint32_t kIntEnaSet = 0x14;
inline constexpr std::uint32_t kIntEnaClr = 0x18;
inline constexpr std::uint32_t kBtr = 0x24;
inline constexpr std::uint32_t kFaultState = 0x2C;  // EWL, ERP, FAULT_STATE (bits 16..18)
inline constexpr std::uint32_t kRecTec = 0x30;      // REC bits 0..8, TEC bits 16..24
inline constexpr std::uint32_t kFilterAMask = 0x3C;
inline constexpr std::uint32_t kFilterAVal = 0x40;
inline constexpr std::uint32_t kFilterControl = 0x5C;
inline constexpr std::uint32_t kRxStatus = 0x68;  // RX_STATUS: frame count in bits 4..14
inline constexpr std::uint32_t kRxData = 0x6C;
inline constexpr std::uint32_t kTxStatus = 0x70;  // 4 bits per TXT buffer
inline constexpr std::uint32_t kTxCommand = 0x74;
inline constexpr std::uint32_t kTxPriority = 0x78;
inline constexpr std::uint32_t kTxtBuffer1 = 0x100;  // protocol-literal: a register offset of the core (TXT buffer n at kTxtBuffer1 + 0x100 * n)
inline constexpr std::uint32_t kTxtBufferSpan = 0x100;  // protocol-literal: a register offset of the core
}  // namespace reg

inline constexpr std::uint32_t kDeviceIdValue = 0xCAFD;
inline constexpr std::uint32_t kTxPriorityEqual = 0x1111;  // priority 1 for each of the four buffers
inline constexpr std::size_t kTxtBuffers = 4;

namespace bits {
inline constexpr std::uint32_t kModeReset = 1u << 0;
inline constexpr std::uint32_t kModeFdEnable = 1u << 4;
inline constexpr std::uint32_t kSettingsEnable = 1u << (16 + 6);
inline constexpr std::uint32_t kIntRx = 1u << 0;               // RXI: a frame received
inline constexpr std::uint32_t kIntTx = 1u << 1;               // TXI: a frame sent
inline constexpr std::uint32_t kIntErrorWarning = 1u << 2;     // EWLI
inline constexpr std::uint32_t kIntDataOverrun = 1u << 3;      // DOI
inline constexpr std::uint32_t kIntFaultState = 1u << 4;       // FCSI: fault confinement changed
inline constexpr std::uint32_t kIntRxNotEmpty = 1u << 10;      // RBNEI
inline constexpr std::uint32_t kIntTxBufferDone = 1u << 11;    // TXBHCI
inline constexpr std::uint32_t kCommandClearOverrun = 1u << 3;  // CDO
inline constexpr std::uint32_t kTxCommandEmpty = 1u << 0;       // TXCE: buffer to Empty
inline constexpr std::uint32_t kTxCommandReady = 1u << 1;       // TXCR: buffer to Ready
inline constexpr std::uint32_t kFilterAStandard = 1u << 0;      // FANB: filter A, base ids
inline constexpr std::uint32_t kFaultErrorPassive = 1u << 17;
inline constexpr std::uint32_t kFaultBusOff = 1u << 18;
// Frame format word.
inline constexpr std::uint32_t kFrameRtr = 1u << 5;
inline constexpr std::uint32_t kFrameIde = 1u << 6;
inline constexpr std::uint32_t kFrameFdf = 1u << 7;
inline constexpr unsigned kFrameRwcntShift = 11;
inline constexpr unsigned kIdBaseShift = 18;
}  // namespace bits

// TXT buffer states (TX_STATUS, 4 bits each).
enum class TxtState : std::uint32_t { Ready = 1, Transmitting = 2, AbortInProgress = 3, Ok = 4, Error = 6, Aborted = 7, Empty = 8 };

// The fault confinement state, as CAN defines it.
enum class FaultState : std::uint8_t { ErrorActive, ErrorPassive, BusOff };

struct Counters {
  std::uint32_t frames_received = 0;
  std::uint32_t frames_filtered = 0;   // received, outside the accepted set
  std::uint32_t frames_sent = 0;
  std::uint32_t transmit_errors = 0;   // a TXT buffer that ended in Error or Aborted
  std::uint32_t data_overruns = 0;     // the core's RX FIFO overran (DOI)
  std::uint32_t bus_off_events = 0;
  std::uint16_t receive_errors = 0;    // REC, as last read
  std::uint16_t transmit_error_count = 0;  // TEC, as last read
};

// 1 Mbit/s from the core's 100 MHz clock: 10 time quanta a bit at a prescaler of 10
// (sync 1 + prop 5 + phase 1 2 + phase 2 2: the sample point at 80 %), SJW 1.
inline constexpr std::uint32_t kBitTiming1M = (5u << 0) | (2u << 7) | (2u << 13) | (10u << 19) | (1u << 27);

template <class Registers, std::size_t RxCapacity = 32, std::size_t TxCapacity = 32>
class Driver final : public co::AcceptanceListener {
 public:
  using Port = cortexm::InterruptCanPort<RxCapacity, TxCapacity>;

  explicit Driver(Registers& registers) : r_{registers} {}

  // false: no CTU CAN FD core answers at these registers.
  bool start() {
    if ((r_.read(reg::kDeviceId) & 0xFFFFu) != kDeviceIdValue) return false;
    r_.write(reg::kMode, bits::kModeReset);
    r_.write(reg::kBtr, kBitTiming1M);
    // Equal priorities, all non-zero: the core sends no buffer of priority 0 (qemu's model
    // neither), and with one buffer ready at a time their order does not matter.
    r_.write(reg::kTxPriority, kTxPriorityEqual);
    accept_all();
    r_.write(reg::kIntEnaSet, bits::kIntRxNotEmpty | bits::kIntTxBufferDone | bits::kIntDataOverrun |
                                  bits::kIntFaultState | bits::kIntErrorWarning);
    r_.write(reg::kMode, bits::kModeFdEnable | bits::kSettingsEnable);
    return true;
  }

  Port& port() { return port_; }
  const Counters& counters() const { return counters_; }
  FaultState fault_state() const { return fault_state_; }

  // The interrupt: everything the core has for us. Runs with interrupts masked.
  void on_interrupt() {
    const std::uint32_t status = r_.read(reg::kIntStat);
    if ((status & bits::kIntDataOverrun) != 0) {
      ++counters_.data_overruns;
      r_.write(reg::kCommand, bits::kCommandClearOverrun);
    }
    if ((status & (bits::kIntFaultState | bits::kIntErrorWarning)) != 0) read_fault_state();
    r_.write(reg::kIntStat, status);  // cleared before the FIFO is drained: a frame after it raises it again
    drain_receive_fifo();
    service_transmit();
  }

  // Frames the node queued: into a free TXT buffer, from the main loop (with interrupts masked)
  // or from the interrupt.
  void service_transmit() {
    for (;;) {
      const TxtState state = txt_state(in_flight_);
      if (state == TxtState::Ready || state == TxtState::Transmitting || state == TxtState::AbortInProgress) return;
      if (state == TxtState::Ok || state == TxtState::Error || state == TxtState::Aborted) {
        if (state == TxtState::Ok) {
          ++counters_.frames_sent;
        } else {
          ++counters_.transmit_errors;
        }
        r_.write(reg::kTxCommand, bits::kTxCommandEmpty | txt_bit(in_flight_));
        in_flight_ = (in_flight_ + 1) % kTxtBuffers;
        continue;  // the next buffer in the rotation
      }
      co::CanFrame frame;
      if (!port_.pop_to_transmit(frame)) return;
      write_txt(in_flight_, frame);
      r_.write(reg::kTxCommand, bits::kTxCommandReady | txt_bit(in_flight_));
    }
  }

  // The node's accepted set (co::AcceptanceListener): the core's filter A gets the bits all
  // ids share (ids outside the set may pass it; the exact set is checked on reception).
  void accepted_ids_changed(std::span<const std::uint32_t> cob_ids) override {
    accepted_count_ = std::min(cob_ids.size(), accepted_.size());
    std::copy_n(cob_ids.begin(), accepted_count_, accepted_.begin());
    filtering_ = accepted_count_ > 0 && accepted_count_ == cob_ids.size();
    if (!filtering_) {
      accept_all();
      return;
    }
    std::uint32_t same = 0x7FFu;  // bits equal in every accepted id
    for (std::size_t i = 1; i < accepted_count_; ++i) same &= ~(accepted_[i] ^ accepted_[0]);
    r_.write(reg::kFilterAMask, same << bits::kIdBaseShift);
    r_.write(reg::kFilterAVal, (accepted_[0] & same) << bits::kIdBaseShift);
    r_.write(reg::kFilterControl, bits::kFilterAStandard);
  }

  static constexpr std::size_t kMaxAccepted = 32;

 private:
  static std::uint32_t txt_bit(std::size_t buffer) { return 1u << (8 + buffer); }
  TxtState txt_state(std::size_t buffer) const {
    return static_cast<TxtState>((r_.read(reg::kTxStatus) >> (4 * buffer)) & 0xFu);
  }

  void accept_all() {
    // Filter A with an all-don't-care mask passes every base-format frame.
    r_.write(reg::kFilterAMask, 0);
    r_.write(reg::kFilterAVal, 0);
    r_.write(reg::kFilterControl, bits::kFilterAStandard);
  }

  bool accepted(std::uint32_t id) const {
    if (!filtering_) return true;
    return std::binary_search(accepted_.begin(), accepted_.begin() + static_cast<std::ptrdiff_t>(accepted_count_), id);
  }

  void read_fault_state() {
    const std::uint32_t fault = r_.read(reg::kFaultState);
    const FaultState state = (fault & bits::kFaultBusOff) != 0         ? FaultState::BusOff
                             : (fault & bits::kFaultErrorPassive) != 0 ? FaultState::ErrorPassive
                                                                       : FaultState::ErrorActive;
    if (state == FaultState::BusOff && fault_state_ != FaultState::BusOff) ++counters_.bus_off_events;
    fault_state_ = state;
    const std::uint32_t counts = r_.read(reg::kRecTec);
    counters_.receive_errors = static_cast<std::uint16_t>(counts & 0x1FFu);  // protocol-literal: a 9-bit error counter field
    counters_.transmit_error_count = static_cast<std::uint16_t>((counts >> 16) & 0x1FFu);  // protocol-literal: a 9-bit error counter field
  }

  void drain_receive_fifo() {
    while (((r_.read(reg::kRxStatus) >> 4) & 0x7FFu) != 0) {
      const std::uint32_t format = r_.read(reg::kRxData);
      const std::uint32_t words = (format >> bits::kFrameRwcntShift) & 0x1Fu;  // after this one
      const std::uint32_t identifier = r_.read(reg::kRxData);
      std::array<std::uint32_t, 18> rest{};  // two timestamp words, up to 64 data bytes
      const std::uint32_t rest_words = words >= 1 ? std::min<std::uint32_t>(words - 1, rest.size()) : 0;
      for (std::uint32_t i = 0; i < rest_words; ++i) rest[i] = r_.read(reg::kRxData);
      for (std::uint32_t i = rest_words + 1; i < words; ++i) (void)r_.read(reg::kRxData);
      ++counters_.frames_received;
      co::CanFrame frame;
      if ((format & bits::kFrameIde) != 0) {
        frame.id = co::CanFrame::kExtendedFlag | (((identifier >> bits::kIdBaseShift) & 0x7FFu) << 18) |
                   (identifier & 0x3FFFFu);
      } else {
        frame.id = (identifier >> bits::kIdBaseShift) & 0x7FFu;
      }
      if ((format & bits::kFrameRtr) != 0) frame.id |= co::CanFrame::kRemoteFlag;
      const std::uint32_t dlc = format & 0xFu;
      // A CAN FD frame (FDF) carries more than a classic frame holds: the engine ignores it.
      if ((format & bits::kFrameFdf) != 0) frame.id |= co::CanFrame::kErrorFlag;
      frame.len = static_cast<std::uint8_t>(std::min<std::uint32_t>(dlc, 8));
      for (std::size_t i = 0; i < frame.len; ++i) {
        frame.data[i] = static_cast<std::uint8_t>(rest[2 + i / 4] >> (8 * (i % 4)));
      }
      if ((frame.id & (co::CanFrame::kExtendedFlag | co::CanFrame::kRemoteFlag | co::CanFrame::kErrorFlag)) == 0 &&
          !accepted(frame.id)) {
        ++counters_.frames_filtered;
        continue;
      }
      port_.push_received(frame);
    }
  }

  void write_txt(std::size_t buffer, const co::CanFrame& frame) {
    const std::uint32_t base = reg::kTxtBuffer1 + reg::kTxtBufferSpan * static_cast<std::uint32_t>(buffer);
    const std::uint32_t len = std::min<std::uint32_t>(frame.len, 8);
    std::uint32_t format = len;  // classic CAN: DLC = length
    std::uint32_t identifier = 0;
    if ((frame.id & co::CanFrame::kExtendedFlag) != 0) {
      format |= bits::kFrameIde;
      identifier = (((frame.id >> 18) & 0x7FFu) << bits::kIdBaseShift) | (frame.id & 0x3FFFFu);
    } else {
      identifier = (frame.id & 0x7FFu) << bits::kIdBaseShift;
    }
    if ((frame.id & co::CanFrame::kRemoteFlag) != 0) format |= bits::kFrameRtr;
    r_.write(base + 0x0, format);
    r_.write(base + 0x4, identifier);
    r_.write(base + 0x8, 0);  // timestamp: transmit at once
    r_.write(base + 0xC, 0);
    for (std::uint32_t word = 0; word < 2; ++word) {
      std::uint32_t value = 0;
      for (std::uint32_t byte = 0; byte < 4; ++byte) {
        const std::uint32_t i = word * 4 + byte;
        if (i < len) value |= static_cast<std::uint32_t>(frame.data[i]) << (8 * byte);
      }
      r_.write(base + 0x10 + 4 * word, value);
    }
  }

  Registers& r_;
  Port port_;
  Counters counters_{};
  FaultState fault_state_ = FaultState::ErrorActive;
  std::size_t in_flight_ = 0;  // the TXT buffer the next frame goes to (or is in)
  std::array<std::uint32_t, kMaxAccepted> accepted_{};
  std::size_t accepted_count_ = 0;
  bool filtering_ = false;
};

}  // namespace virt::ctucan
