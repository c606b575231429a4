#include "joint/actuators/StatusLed.hpp"

namespace joint {

using board::FieldId;

StatusLed::StatusLed(core::MessageBoard& board, LedOutput& output)
    : Actuator(board, "status_led", {.reads = {FieldId::led_pattern_command}}), output_{output} {}

void StatusLed::update() {
  const float command = boardGet(FieldId::led_pattern_command);
  LedPattern pattern = LedPattern::FastBlink;
  if (command == 0.0F) {
    pattern = LedPattern::Off;
  } else if (command == 1.0F) {
    pattern = LedPattern::On;
  } else if (command == 2.0F) {
    pattern = LedPattern::SlowBlink;
  }
  output_.write(pattern);
}

}  // namespace joint
