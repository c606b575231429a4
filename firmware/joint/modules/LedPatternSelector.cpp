#include "joint/modules/LedPatternSelector.hpp"

namespace joint {

using board::FieldId;

LedPatternSelector::LedPatternSelector(core::MessageBoard& board)
    : Module(board, "led_pattern",
             {.writes = {FieldId::led_pattern_command}, .reads = {FieldId::safe_state, FieldId::drive_mode}}) {}

void LedPatternSelector::update() {
  const LedPattern pattern = select_led_pattern(boardGet(FieldId::safe_state) != 0.0F,
                                                control_mode_from_field(boardGet(FieldId::drive_mode)));
  boardSet(FieldId::led_pattern_command, board::to_value(pattern));
}

}  // namespace joint
