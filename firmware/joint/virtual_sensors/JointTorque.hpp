// Joint torque from the spring model: joint_torque = spring_constant_nominal *
// spring_deflection. Written only when the deflection was written this cycle.
#pragma once

#include "core/MessageBoardUser.hpp"

namespace joint {

constexpr float spring_torque_nm(float deflection_rad, float spring_constant_nm_per_rad) {
  return spring_constant_nm_per_rad * deflection_rad;
}

class JointTorque final : public core::VirtualSensor {
 public:
  explicit JointTorque(core::MessageBoard& board);

  void update() override;
};

}  // namespace joint
