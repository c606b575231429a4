// control_mode as the components see it. The field is a float on the bus;
// anything that is not exactly one of the modes counts as Disabled, so a
// corrupted command can only stop the drive.
#pragma once

#include <cstdint>

namespace joint {

enum class ControlMode : std::uint8_t { Disabled = 0, Velocity = 1, Torque = 2, Position = 3 };

constexpr ControlMode control_mode_from_field(float value) {
  if (value == 1.0F) {
    return ControlMode::Velocity;
  }
  if (value == 2.0F) {
    return ControlMode::Torque;
  }
  if (value == 3.0F) {
    return ControlMode::Position;
  }
  return ControlMode::Disabled;
}

}  // namespace joint
