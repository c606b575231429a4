// control_mode as the components see it: board.toml's [[enum]] control_mode, generated into
// board/fields.hpp. The field is a float on the bus; anything that is not exactly one of the
// modes counts as Disabled, so a corrupted command can only stop the drive.
#pragma once

#include "board/fields.hpp"

namespace joint {

using ControlMode = board::ControlMode;

constexpr ControlMode control_mode_from_field(float value) {
  return board::control_mode_from_value(value).value_or(ControlMode::Disabled);
}

}  // namespace joint
