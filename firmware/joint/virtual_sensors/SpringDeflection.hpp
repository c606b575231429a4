// Spring twist between gearbox output and load:
// spring_deflection = motor_position / gear_ratio - output_position.
// Written only when both encoders gave a sample this cycle.
#pragma once

#include "core/MessageBoardUser.hpp"

namespace joint {

constexpr float spring_deflection_rad(float motor_position_rad, float output_position_rad, float gear_ratio) {
  return motor_position_rad / gear_ratio - output_position_rad;
}

class SpringDeflection final : public core::VirtualSensor {
 public:
  explicit SpringDeflection(core::MessageBoard& board);

  void update() override;
};

}  // namespace joint
