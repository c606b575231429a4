// Online estimate of the series spring's stiffness, independent of the
// nominal value that joint_torque is computed with (that would be circular).
//
// The torque comes from the motor side instead: in quasi-static motion the
// rotor's torque balance reduces to spring torque = gear_ratio * kt *
// motor_current (rotor inertia and the small motor-side friction neglected).
// SpringConstantRls fits that torque against spring_deflection and writes
// spring_constant_estimate and spring_constant_confidence.
//
// Quasi-static gate: a sample is used only when current, deflection and motor
// velocity were all measured this cycle and the motor's acceleration is below
// kQuasiStaticMotorAccelerationRadPerS2, where the rotor inertia's share of
// the torque is small. Limits: the gearbox efficiency and its friction are
// folded into the offset/slope (a lossy gearbox biases k low); the estimate
// needs the deflection to vary (confidence says how much it did); kt is a
// constant until the table has it.
#pragma once

#include <cstdint>

#include "core/MessageBoardUser.hpp"
#include "joint/modules/SpringConstantRls.hpp"

namespace joint {

// Motor-side acceleration below which a sample counts as quasi-static. With the
// rig's rotor (1e-5 kg*m^2) and gear ratio 50 the neglected inertia torque is
// then at most 0.05 N*m at the joint.
inline constexpr float kQuasiStaticMotorAccelerationRadPerS2 = 100.0F;

class SpringConstantEstimator final : public core::Module {
 public:
  // dt_s: the control cycle period.
  SpringConstantEstimator(core::MessageBoard& board, float dt_s);

  void update() override;

 private:
  bool quasi_static_sample();

  float dt_s_;
  SpringConstantRls rls_;
  bool initialised_ = false;
  bool has_previous_velocity_ = false;
  float previous_motor_velocity_rad_s_ = 0.0F;
  std::uint32_t previous_velocity_cycle_ = 0;
};

}  // namespace joint
