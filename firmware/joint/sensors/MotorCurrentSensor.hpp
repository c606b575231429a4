// Motor current ADC (1 count = 1 mA) -> motor_current in amperes. Without a
// fresh sample it writes nothing.
#pragma once

#include "core/MessageBoardUser.hpp"
#include "joint/drivers/CurrentInput.hpp"

namespace joint {

class MotorCurrentSensor final : public core::Sensor {
 public:
  // `current` must outlive the sensor.
  MotorCurrentSensor(core::MessageBoard& board, CurrentInput& current);

  void update() override;

 private:
  CurrentInput& current_;
};

}  // namespace joint
