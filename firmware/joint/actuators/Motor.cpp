#include "joint/actuators/Motor.hpp"

#include <algorithm>
#include <cmath>

#include "joint/FaultBits.hpp"

namespace joint {

using board::FieldId;

std::int16_t duty_to_raw(float duty, float max_duty) {
  if (!std::isfinite(duty) || !(max_duty > 0.0F)) {
    return 0;
  }
  const float limit = std::min(max_duty, 1.0F);
  const float limited = std::clamp(duty, -limit, limit);
  return static_cast<std::int16_t>(std::lround(limited * static_cast<float>(kDutyRawFullScale)));
}

Motor::Motor(core::MessageBoard& board, DutyOutput& output)
    : Actuator(board, "motor", {.reads = {FieldId::motor_duty_command, FieldId::safe_state, FieldId::fault_flags,
                                         FieldId::drive_fault_ramp, FieldId::max_duty}}),
      output_{output} {}

void Motor::update() {
  if (safe_state_cuts_the_drive(boardGet(FieldId::safe_state), boardGet(FieldId::fault_flags),
                                 boardGet(FieldId::drive_fault_ramp))) {
    output_.write(0);
    return;
  }
  output_.write(duty_to_raw(boardGet(FieldId::motor_duty_command), boardGet(FieldId::max_duty)));
}

}  // namespace joint
