// The head's outputs: the RGB LED's PWM from led_*_duty, the rail switch gate from rail_on.
#pragma once

#include <cstdint>

#include "core/MessageBoardUser.hpp"
#include "head/drivers/HeadDrivers.hpp"

namespace head {

// Duty 0..1 -> PWM compare value 0..255, rounded to nearest; out of range and NaN clamp.
std::uint8_t pwm_from_duty(float duty);

class LedDriver final : public core::Actuator {
 public:
  // `led` must outlive the actuator.
  LedDriver(core::MessageBoard& board, LedPwmOutput& led);
  void update() override;

 private:
  LedPwmOutput& led_;
};

class RailSwitchDriver final : public core::Actuator {
 public:
  // `rail_switch` must outlive the actuator.
  RailSwitchDriver(core::MessageBoard& board, RailSwitchOutput& rail_switch);
  void update() override;

 private:
  RailSwitchOutput& rail_switch_;
};

}  // namespace head
