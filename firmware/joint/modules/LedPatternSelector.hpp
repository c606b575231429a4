// Chooses the status LED pattern: fast blink in the safe state, slow blink
// while ControlMode::Disabled, on while a control mode runs. Writes
// led_pattern_command; the StatusLed actuator drives the LED from it.
#pragma once

#include "core/MessageBoardUser.hpp"
#include "joint/ControlMode.hpp"
#include "joint/drivers/LedOutput.hpp"

namespace joint {

constexpr LedPattern select_led_pattern(bool safe_state, ControlMode mode) {
  if (safe_state) {
    return LedPattern::FastBlink;
  }
  return mode == ControlMode::Disabled ? LedPattern::SlowBlink : LedPattern::On;
}

class LedPatternSelector final : public core::Module {
 public:
  explicit LedPatternSelector(core::MessageBoard& board);

  void update() override;
};

}  // namespace joint
