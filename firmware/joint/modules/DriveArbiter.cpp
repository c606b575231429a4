#include "joint/modules/DriveArbiter.hpp"

#include <algorithm>

#include "joint/FaultBits.hpp"

namespace joint {

using board::FieldId;

float arbitrate_duty(const DriveInputs& inputs) {
  if (inputs.safe_state) {
    return 0.0F;
  }
  float duty = 0.0F;
  switch (inputs.mode) {
    case ControlMode::Velocity:
    case ControlMode::Position:
      duty = inputs.velocity_controller_output;
      break;
    case ControlMode::Torque:
      duty = inputs.torque_controller_output;
      break;
    case ControlMode::Disabled:
      return 0.0F;
  }
  const float limit = std::clamp(inputs.max_duty * inputs.thermal_derate, 0.0F, 1.0F);
  return std::clamp(duty, -limit, limit);
}

DriveArbiter::DriveArbiter(core::MessageBoard& board)
    : Module(board, "drive_arbiter",
             {.writes = {FieldId::motor_duty_command},
              .reads = {FieldId::drive_mode, FieldId::velocity_controller_output, FieldId::torque_controller_output,
                        FieldId::thermal_derate, FieldId::safe_state, FieldId::fault_flags,
                        FieldId::drive_fault_ramp, FieldId::max_duty}}) {}

void DriveArbiter::update() {
  boardSet(FieldId::motor_duty_command,
           arbitrate_duty({.mode = control_mode_from_field(boardGet(FieldId::drive_mode)),
                           .safe_state = safe_state_cuts_the_drive(boardGet(FieldId::safe_state),
                                                                   boardGet(FieldId::fault_flags),
                                                                   boardGet(FieldId::drive_fault_ramp)),
                           .velocity_controller_output = boardGet(FieldId::velocity_controller_output),
                           .torque_controller_output = boardGet(FieldId::torque_controller_output),
                           .max_duty = boardGet(FieldId::max_duty),
                           .thermal_derate = boardGet(FieldId::thermal_derate)}));
}

}  // namespace joint
