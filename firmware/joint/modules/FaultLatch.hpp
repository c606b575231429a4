// Latching of fault bits, independent of the board: a cause latches its bit;
// only an explicit clear drops latched bits, and a cause still present at the
// clear latches again at once.
#pragma once

#include <cstdint>

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

}  // namespace joint
