#include "joint/modules/VelocityController.hpp"

#include "joint/ControlMode.hpp"
#include "joint/FaultBits.hpp"
#include "joint/modules/PositionLoop.hpp"

namespace joint {

using board::FieldId;

VelocityController::VelocityController(core::MessageBoard& board, float dt_s)
    : Module(board, "velocity_controller",
             {.writes = {FieldId::velocity_controller_output},
              .reads = {FieldId::drive_mode, FieldId::drive_velocity_reference, FieldId::drive_position_reference,
                        FieldId::motor_position, FieldId::motor_velocity, FieldId::gear_ratio, FieldId::velocity_kp,
                        FieldId::velocity_ki, FieldId::velocity_kd, FieldId::position_kp, FieldId::max_duty,
                        FieldId::thermal_derate, FieldId::safe_state, FieldId::fault_flags, FieldId::drive_fault_ramp}}),
      dt_s_{dt_s} {}

void VelocityController::update() {
  const ControlMode mode = control_mode_from_field(boardGet(FieldId::drive_mode));
  const bool in_control = (mode == ControlMode::Velocity || mode == ControlMode::Position) &&
                          !safe_state_cuts_the_drive(boardGet(FieldId::safe_state), boardGet(FieldId::fault_flags),
                                                     boardGet(FieldId::drive_fault_ramp));
  if (!in_control) {
    pid_.reset();
    boardSet(FieldId::velocity_controller_output, 0.0F);
    return;
  }
  const float gear_ratio = boardGet(FieldId::gear_ratio);
  float reference_rad_s = boardGet(FieldId::drive_velocity_reference);
  if (mode == ControlMode::Position) {
    reference_rad_s = position_velocity_reference(boardGet(FieldId::drive_position_reference),
                                                  boardGet(FieldId::motor_position) / gear_ratio,
                                                  boardGet(FieldId::position_kp),
                                                  board::info(FieldId::velocity_setpoint).max);
  }
  const PidGains gains{boardGet(FieldId::velocity_kp), boardGet(FieldId::velocity_ki), boardGet(FieldId::velocity_kd)};
  const float limit = boardGet(FieldId::max_duty) * boardGet(FieldId::thermal_derate);
  const float gearbox_velocity_rad_s = boardGet(FieldId::motor_velocity) / gear_ratio;
  boardSet(FieldId::velocity_controller_output, pid_.update(reference_rad_s, gearbox_velocity_rad_s, dt_s_, gains, limit));
}

}  // namespace joint
