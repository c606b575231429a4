// The status LED driver: it renders a pattern number (the blinking is its job). The patterns
// are board.toml's [[enum]] led_pattern, generated into board/fields.hpp.
#pragma once

#include "board/fields.hpp"

namespace joint {

using LedPattern = board::LedPattern;

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
