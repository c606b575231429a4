// How many cycles a board field has gone without a write, counted by a
// component that runs every cycle, so that the count never wraps.
//
// Why not `board.cycle() - board.last_write_cycle(field)`: that difference of
// 32-bit cycle numbers wraps after 2^32 cycles (49.7 days at 1 kHz), and a
// field silent that long would look freshly written, taking a latched fault's
// cause away; a "cycles since start" made the same way wraps to 0 after 2^32
// cycles of running and hid every silence for a while. Here only the age of a
// write seen for the first time is a difference of cycle numbers (small: it is
// new); otherwise the silence grows by the cycles elapsed, in 64 bits.
//
// A write is new when its stamp differs from the last one seen. A stamp that
// comes back exactly 2^32 cycles later is missed: the silence then grows on,
// the safe direction (a fault raised, never one hidden).
#pragma once

#include <algorithm>
#include <cstdint>

#include "core/MessageBoard.hpp"

namespace joint {

class SilenceCounter {
 public:
  // `stamp_lag`: 0 for a field written inside the cycle (a sensor's: a write
  // in this cycle is 0 cycles of silence); 1 for a field written between
  // cycles (the bus's: a write stamped s arrived before cycle s + 1, which is
  // then 0 cycles of silence).
  explicit SilenceCounter(std::uint32_t stamp_lag) : stamp_lag_{stamp_lag} {}

  // Call once per cycle; `elapsed_cycles` since the previous call (1 at the
  // first: a field never written has been silent for one cycle then).
  // Returns the cycles without a write, counting the current one.
  std::uint64_t update(const core::MessageBoard& board, board::FieldId field, std::uint32_t elapsed_cycles) {
    silent_ += elapsed_cycles;
    if (board.has(field)) {
      const std::uint32_t stamp = board.last_write_cycle(field);
      if (!seen_write_ || stamp != seen_stamp_) {
        seen_write_ = true;
        seen_stamp_ = stamp;
        const std::uint32_t age = board.cycle() - stamp;
        silent_ = std::min<std::uint64_t>(silent_, age > stamp_lag_ ? age - stamp_lag_ : 0);
      }
    }
    return silent_;
  }

  std::uint64_t silent_cycles() const { return silent_; }

 private:
  std::uint32_t stamp_lag_;
  std::uint64_t silent_ = 0;
  std::uint32_t seen_stamp_ = 0;
  bool seen_write_ = false;
};

// Cycles since the previous call, from the board's 32-bit cycle number (the
// modular difference is exact across its wrap); 1 at the first call.
class CycleStep {
 public:
  std::uint32_t update(std::uint32_t cycle) {
    const std::uint32_t step = started_ ? cycle - previous_ : 1;
    previous_ = cycle;
    started_ = true;
    return step;
  }

 private:
  std::uint32_t previous_ = 0;
  bool started_ = false;
};

}  // namespace joint
