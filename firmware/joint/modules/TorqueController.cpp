#include "joint/modules/TorqueController.hpp"

#include "joint/ControlMode.hpp"
#include "joint/FaultBits.hpp"

namespace joint {

using board::FieldId;

TorqueController::TorqueController(core::MessageBoard& board, float dt_s)
    : Module(board, "torque_controller",
             {.writes = {FieldId::torque_controller_output},
              .reads = {FieldId::drive_mode, FieldId::drive_torque_reference, FieldId::joint_torque, FieldId::torque_kp,
                        FieldId::torque_ki, FieldId::max_duty, FieldId::thermal_derate, FieldId::safe_state,
                        FieldId::fault_flags, FieldId::drive_fault_ramp}}),
      dt_s_{dt_s} {}

void TorqueController::update() {
  const bool in_control = control_mode_from_field(boardGet(FieldId::drive_mode)) == ControlMode::Torque &&
                          !safe_state_cuts_the_drive(boardGet(FieldId::safe_state), boardGet(FieldId::fault_flags),
                                                     boardGet(FieldId::drive_fault_ramp));
  if (!in_control) {
    pi_.reset();
    boardSet(FieldId::torque_controller_output, 0.0F);
    return;
  }
  const PidGains gains{boardGet(FieldId::torque_kp), boardGet(FieldId::torque_ki), 0.0F};
  const float limit = boardGet(FieldId::max_duty) * boardGet(FieldId::thermal_derate);
  boardSet(FieldId::torque_controller_output,
           pi_.update(boardGet(FieldId::drive_torque_reference), boardGet(FieldId::joint_torque), dt_s_, gains, limit));
}

}  // namespace joint
