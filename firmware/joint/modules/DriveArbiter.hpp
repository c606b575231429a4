// The command interface: picks the duty the motor applies from drive_mode (control_mode, or
// what the CiA 402 drive asks for: Cia402Drive)
// (Velocity and Position: the velocity loop, Torque: the torque loop, Disabled or any
// other number: none), forces 0 in the safe state (unless the CiA 402 fault reaction ramps the
// drive down on faults that keep the sensors: FaultBits.hpp), and limits it to
// max_duty * thermal_derate (the derate bounds the drive rather than scaling it, so a
// hot winding caps the current instead of weakening every command). Writes
// motor_duty_command.
#pragma once

#include "core/MessageBoardUser.hpp"
#include "joint/ControlMode.hpp"

namespace joint {

struct DriveInputs {
  ControlMode mode;
  bool safe_state;  // the safe state cuts the drive (safe_state_cuts_the_drive)
  float velocity_controller_output;
  float torque_controller_output;
  float max_duty;
  float thermal_derate;
};

// The duty to command, -max_duty*derate .. max_duty*derate.
float arbitrate_duty(const DriveInputs& inputs);

class DriveArbiter final : public core::Module {
 public:
  explicit DriveArbiter(core::MessageBoard& board);

  void update() override;
};

}  // namespace joint
