// The control cycle number: the firmware's clock. Components measure time as a difference of
// cycle numbers times the period (a velocity from two positions, a sensor's silence, the
// command watchdog). In lockstep every SYNC is one cycle. Free-running on a timer, a wake-up
// that finds k periods passed (the process was late: k timer expirations) advances the number
// by k and runs one cycle, so time measured in cycles stays wall time instead of slowing down
// with a loaded machine (which made the velocity estimate read high by the share of periods
// missed, and the velocity loop hold the joint that much slower).
#pragma once

#include <cstdint>

namespace core {

class CycleCounter {
 public:
  // `periods` (>= 1) have passed since the last cycle; returns the new cycle number.
  std::uint32_t advance(std::uint64_t periods = 1) {
    if (periods == 0) return cycle_;
    cycle_ += static_cast<std::uint32_t>(periods);  // wraps, as the board's arithmetic expects
    skipped_ += periods - 1;
    ++run_;
    return cycle_;
  }

  std::uint32_t cycle() const { return cycle_; }
  // Cycles run.
  std::uint64_t run() const { return run_; }
  // Periods that passed without a cycle of their own (overruns).
  std::uint64_t skipped() const { return skipped_; }

 private:
  std::uint32_t cycle_ = 0;
  std::uint64_t run_ = 0;
  std::uint64_t skipped_ = 0;
};

}  // namespace core
