// A condition that must hold for a number of consecutive cycles before it counts (a fuse's delay
// for the rail current, load transients for the battery voltage). Independent of the board.
#pragma once

#include <cstdint>

namespace head {

class Debounce {
 public:
  // Call once per cycle. True once `condition` held for `cycles` consecutive calls (this one
  // included); a false resets the count. `cycles` 0 counts as 1.
  bool update(bool condition, std::uint32_t cycles) {
    run_ = condition ? (run_ < UINT32_MAX ? run_ + 1 : run_) : 0;
    return condition && run_ >= (cycles == 0 ? 1 : cycles);
  }

  std::uint32_t run() const { return run_; }

 private:
  std::uint32_t run_ = 0;
};

}  // namespace head
