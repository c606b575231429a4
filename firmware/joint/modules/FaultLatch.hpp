// Latching of fault bits, independent of the board: a cause latches its bit;
// only an explicit clear drops latched bits, and a cause still present at the
// clear latches again at once.
#pragma once

#include <cstdint>

#include "core/MessageBoard.hpp"

namespace joint {

class FaultLatch {
 public:
  // `active_causes`: the fault bits whose cause is present now. Returns the latched bits.
  std::uint32_t update(std::uint32_t active_causes, bool clear_requested) {
    if (clear_requested) {
      latched_ = 0;
    }
    latched_ |= active_causes;
    return latched_;
  }

  std::uint32_t latched() const { return latched_; }

 private:
  std::uint32_t latched_ = 0;
};

// A clear command field (fault_clear) as a latch reads it: each new write of 1 asks once, whether
// or not the value changed (the bus writes between cycles, so the write's cycle stamp tells a new
// write from the old one). Used by every board's fault monitor (the joint's, the head's).
class ClearRequest {
 public:
  bool update(const core::MessageBoard& board, board::FieldId field) {
    if (!board.has(field)) {
      return false;
    }
    const std::uint32_t stamp = board.last_write_cycle(field);
    const bool new_write = !seen_ || stamp != seen_stamp_;
    seen_ = true;
    seen_stamp_ = stamp;
    return new_write && board.get(field) == 1.0F;
  }

 private:
  std::uint32_t seen_stamp_ = 0;
  bool seen_ = false;
};

}  // namespace joint
