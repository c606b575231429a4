// The velocity loop (ControlMode::Velocity) and, with PositionLoop in front of it, the
// position loop (ControlMode::Position). Writes velocity_controller_output (duty).
//
// What it regulates: the gearbox-side output velocity, motor_velocity /
// gear_ratio, against velocity_setpoint. That measurement is collocated with
// the motor (no spring between actuator and sensor), so the loop stays stable
// whatever the spring and load do; in steady state the spring carries no
// changing twist, so the load turns at the same speed. Position mode closes
// its outer loop on the gearbox-side angle, motor_position / gear_ratio, for
// the same reason: a loop on output_position through the lightly damped spring
// would put its resonance inside the loop. The price is that a static load
// torque leaves the load off target by the spring's deflection (torque / k).
//
// Gains (velocity_kp/ki/kd) are duty per rad/s of gearbox-side velocity error;
// the output is limited to max_duty * thermal_derate, the most the drive
// arbiter passes on, so the anti-windup sees the real saturation. Outside its
// modes, or in the safe state (but a CiA 402 fault reaction's ramp: FaultBits.hpp), it writes
// 0 and forgets its integrator.
#pragma once

#include "core/MessageBoardUser.hpp"
#include "joint/modules/PidController.hpp"

namespace joint {

class VelocityController final : public core::Module {
 public:
  // dt_s: the control cycle period.
  VelocityController(core::MessageBoard& board, float dt_s);

  void update() override;

 private:
  float dt_s_;
  PidController pid_;
};

}  // namespace joint
