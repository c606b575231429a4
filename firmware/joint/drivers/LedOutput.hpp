// The status LED driver: it renders a pattern number (the blinking is its job).
#pragma once

#include <cstdint>

namespace joint {

enum class LedPattern : std::uint8_t {
  Off = 0,
  On = 1,         // ok, drive enabled
  SlowBlink = 2,  // disabled (control_mode 0)
  FastBlink = 3,  // fault: safe state
};

class LedOutput {
 public:
  virtual ~LedOutput() = default;
  virtual void write(LedPattern pattern) = 0;

 protected:
  LedOutput() = default;
  LedOutput(const LedOutput&) = default;
  LedOutput& operator=(const LedOutput&) = default;
};

}  // namespace joint
