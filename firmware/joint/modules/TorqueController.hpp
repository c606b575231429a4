// The torque loop (ControlMode::Torque): PI on joint_torque (the spring's torque)
// against torque_setpoint, writing torque_controller_output (duty). With a
// voltage-driven motor the duty sets roughly the gearbox speed, i.e. the rate
// of change of spring twist, so the plant is close to an integrator and a PI
// loop suffices (no derivative gain in the table, none used). Output limited
// to max_duty * thermal_derate with anti-windup; outside torque mode or in the
// safe state (but a CiA 402 fault reaction's ramp: FaultBits.hpp) it writes 0 and forgets its
// integrator.
#pragma once

#include "core/MessageBoardUser.hpp"
#include "joint/modules/PidController.hpp"

namespace joint {

class TorqueController final : public core::Module {
 public:
  // dt_s: the control cycle period.
  TorqueController(core::MessageBoard& board, float dt_s);

  void update() override;

 private:
  float dt_s_;
  PidController pi_;
};

}  // namespace joint
