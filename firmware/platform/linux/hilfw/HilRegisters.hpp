// hilfw::HilRegisters: the driver registers of a board on the hardware-in-the-loop rig whose
// drivers need nothing but the latest raw value of each of its table's [[hil_input]]s and a raw
// value per [[hil_output]]: the registers hilfw::run_board gives a board that names none of its
// own. The receive path (the CANopen node's RPDOs and SDO writes) calls write_input() and
// heartbeat_status(), never the board (the interrupt policy); a Sensor drains an input in its
// update(), an Actuator leaves its raw command with write_output(), and the node's TPDOs read it
// back with read_output().
//
// One producer and one consumer per register, lock-free (core::LatestValueRegister, atomics),
// no heap: the same rules as a board's own registers on a microcontroller.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>

#include "board/fields.hpp"
#include "core/LatestValueRegister.hpp"

namespace hilfw {

class HilRegisters {
 public:
  // An input as a Sensor sees it: the newest raw value (0 before the first) and whether it
  // arrived since the Sensor's previous read of it.
  struct Input {
    std::int32_t raw;
    bool fresh;
  };
  // The heartbeat consumer's news (0x1016) as a component sees it: whether a watched heartbeat
  // is lost now, and whether one was lost since the component's previous read.
  struct Heartbeat {
    bool lost;
    bool new_loss;
  };

  HilRegisters() = default;
  HilRegisters(const HilRegisters&) = delete;
  HilRegisters& operator=(const HilRegisters&) = delete;

  // --- receive path ----------------------------------------------------------------------
  void write_input(board::HilInputId id, std::int32_t raw) {
    if (id != board::HilInputId::kCount) inputs_[static_cast<std::size_t>(id)].write(raw);
  }
  void heartbeat_status(std::uint8_t lost_entries, bool event) {
    if (event) ++heartbeat_events_;
    heartbeat_.write(Status{heartbeat_events_, lost_entries});
  }

  // --- transmit path ---------------------------------------------------------------------
  std::int32_t read_output(board::HilOutputId id) const {
    if (id == board::HilOutputId::kCount) return 0;
    return outputs_[static_cast<std::size_t>(id)].load(std::memory_order_acquire);
  }

  // --- the components' side --------------------------------------------------------------
  // Consumes the input's freshness: one reader per input (its Sensor).
  Input read_input(board::HilInputId id) {
    const auto reading = inputs_[static_cast<std::size_t>(id)].read();
    return Input{reading.value, reading.fresh};
  }
  // The newest raw value, freshness untouched.
  std::int32_t input(board::HilInputId id) const { return inputs_[static_cast<std::size_t>(id)].peek(); }
  void write_output(board::HilOutputId id, std::int32_t raw) {
    outputs_[static_cast<std::size_t>(id)].store(raw, std::memory_order_release);
  }
  // One reader (the component that reacts to a lost master).
  Heartbeat read_heartbeat() {
    const Status status = heartbeat_.read().value;
    const bool new_loss = status.events != seen_heartbeat_events_;
    seen_heartbeat_events_ = status.events;
    return Heartbeat{status.lost_entries != 0, new_loss};
  }

 private:
  // 32 bits in all, lock-free on a 32-bit target too; the events counter wraps, never between
  // two reads of one cycle each.
  struct Status {
    std::uint16_t events;
    std::uint16_t lost_entries;
  };

  std::array<core::LatestValueRegister<std::int32_t>, board::kHilInputCount> inputs_{};
  std::array<std::atomic<std::int32_t>, board::kHilOutputCount> outputs_{};
  core::LatestValueRegister<Status> heartbeat_;
  std::uint16_t heartbeat_events_ = 0;       // receive path only
  std::uint16_t seen_heartbeat_events_ = 0;  // components only
};

}  // namespace hilfw
