// The cycle budget check (cm_cycle_budget, run in `make test` and reported by `make bench`): the
// firmware image with a bus master of its own in place of the CAN controller's interrupts. Each
// control cycle it hands the node the frames the rig would (NMT start, the sensor and setpoint
// RPDOs, SYNC), keeps a segmented SDO upload going, and at kFaultCycle stops the setpoint
// stream, so that the command watchdog latches its fault and the node raises the EMCY: every
// TPDO of the default mapping due (TPDO8's every 10th SYNC too), an SDO in progress, a fault
// being latched. The work of each cycle is timed on SysTick; run under `qemu -icount shift=0`
// (one instruction a nanosecond of the emulated clock) its ticks are instructions.
#pragma once

#include <cstddef>
#include <cstdint>

#include "board/cia301.hpp"
#include "board/fields.hpp"
#include "canopen/CanPort.hpp"

namespace cortexm::budget {

inline constexpr std::uint32_t kCycles = 300;      // control cycles measured
inline constexpr std::uint32_t kFaultCycle = 150;  // the setpoint stream stops here
// The budget in core cycles of one control period at the table's clock and share; instructions
// are counted as one cycle each (qemu counts instructions; the share leaves the rest of the
// period for the wait states, interrupts and multi-cycle instructions it does not count).
constexpr std::uint32_t budget_cycles(std::uint32_t period_us) {
  return static_cast<std::uint32_t>(static_cast<std::uint64_t>(board::kMcuClockHz) * period_us *
                                    board::kCycleBudgetPercent / 100'000'000u);
}

class Master {
 public:
  explicit Master(std::uint8_t node_id) : node_id_{node_id} {}

  // The frames of cycle `n` (0-based), handed to `push(frame)` in the order a bus delivers them.
  template <typename Push>
  void frames_of_cycle(std::uint32_t n, Push&& push) {
    using cia301::FunctionCode;
    if (n == 0) push(frame(cia301::kNmtCobId, {static_cast<std::uint8_t>(cia301::NmtCommand::Start), node_id_}));
    if (n == 1) {  // control_mode = velocity by expedited download (REAL32)
      const float mode = static_cast<float>(board::ControlMode::Velocity);
      std::uint8_t bytes[4];
      __builtin_memcpy(bytes, &mode, sizeof bytes);
      const std::uint16_t index = board::info(board::FieldId::control_mode).index;
      push(frame(cia301::cob_id(FunctionCode::SdoRequest, node_id_),
                 {0x23, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), 0x00, bytes[0],
                  bytes[1], bytes[2], bytes[3]}));
    } else if (n >= 2 && !sdo_waiting_) {  // the next step of a segmented upload of 0x1008
      sdo_waiting_ = true;
      if (!uploading_) {
        uploading_ = true;
        toggle_ = 0;
        push(frame(cia301::cob_id(FunctionCode::SdoRequest, node_id_), {0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0}));
      } else {
        push(frame(cia301::cob_id(FunctionCode::SdoRequest, node_id_), {static_cast<std::uint8_t>(0x60 | toggle_), 0, 0, 0, 0, 0, 0, 0}));
      }
    }
    push(frame(cia301::cob_id(FunctionCode::Rpdo1, node_id_), {0, 0, 0, 0, 0, 0, 0, 0}));
    if (n < kFaultCycle) push(frame(cia301::cob_id(FunctionCode::Rpdo2, node_id_), {0, 0, 0, 0, 0, 0, 0, 0}));
    push(frame(cia301::kSyncCobId, {static_cast<std::uint8_t>(n % cia301::kSyncCounterMax + 1)}));
  }

  // A frame the node sent: an SDO answer moves the upload on; EMCYs are counted.
  void sent(const co::CanFrame& frame) {
    if (frame.id == cia301::cob_id(cia301::FunctionCode::SyncEmcy, node_id_)) ++emcy_frames_;
    if (frame.id != cia301::cob_id(cia301::FunctionCode::SdoResponse, node_id_) || frame.len == 0) return;
    const std::uint8_t command = frame.data[0];
    sdo_waiting_ = false;
    if ((command & 0xE0) == 0x00) {  // an upload segment: the last one has bit 0 set
      ++sdo_segments_;
      toggle_ ^= 0x10;
      if (command & 0x01) uploading_ = false;
    } else if ((command & 0xE0) == 0x80) {  // an abort: start over
      uploading_ = false;
    }
  }

  // What the run exercised: the check is void unless the fault's EMCY came and the upload ran.
  std::uint32_t emcy_frames() const { return emcy_frames_; }
  std::uint32_t sdo_segments() const { return sdo_segments_; }

 private:
  static co::CanFrame frame(std::uint32_t id, std::initializer_list<std::uint8_t> bytes) {
    co::CanFrame f;
    f.id = id;
    for (const std::uint8_t b : bytes) f.data[f.len++] = b;
    return f;
  }

  std::uint8_t node_id_;
  bool uploading_ = false;
  bool sdo_waiting_ = false;
  std::uint8_t toggle_ = 0;
  std::uint32_t emcy_frames_ = 0;
  std::uint32_t sdo_segments_ = 0;
};

// Semihosting (qemu: target=native): a line on the emulator's output, and the exit.
inline void write_line(const char* text) {
  register std::uint32_t operation asm("r0") = 0x04;  // SYS_WRITE0
  register const char* argument asm("r1") = text;
  asm volatile("bkpt 0xab" : "+r"(operation) : "r"(argument) : "memory");
}

[[noreturn]] inline void exit_with(bool success) {
  // SYS_EXIT with ADP_Stopped_ApplicationExit (status 0) or ADP_Stopped_RunTimeErrorUnknown (1).
  register std::uint32_t operation asm("r0") = 0x18;
  register std::uint32_t reason asm("r1") = success ? 0x20026 : 0x20023;
  asm volatile("bkpt 0xab" : : "r"(operation), "r"(reason) : "memory");
  for (;;) {
  }
}

// "name=value " appended to `out` (decimal), for the one line the bench parses.
inline char* append(char* out, const char* name, std::uint32_t value) {
  while (*name) *out++ = *name++;
  *out++ = '=';
  char digits[10];
  int count = 0;
  do {
    digits[count++] = static_cast<char>('0' + value % 10);
    value /= 10;
  } while (value != 0);
  while (count) *out++ = digits[--count];
  *out++ = ' ';
  *out = '\0';
  return out;
}

}  // namespace cortexm::budget
