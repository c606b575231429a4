#include "joint/actuators/StatusLed.hpp"

namespace joint {

using board::FieldId;

StatusLed::StatusLed(core::MessageBoard& board, LedOutput& output)
    : Actuator(board, "status_led", {.reads = {FieldId::led_pattern_command}}), output_{output} {}

void StatusLed::update() {
  const float command = boardGet(FieldId::led_pattern_command);
  output_.write(board::led_pattern_from_value(command).value_or(LedPattern::FastBlink));
}

}  // namespace joint
