#include "head/actuators/HeadActuators.hpp"

#include <cmath>

#include "head/modules/PowerModules.hpp"

namespace head {

using board::FieldId;

namespace {
constexpr float kPwmFullScale = 255.0F;
}  // namespace

std::uint8_t pwm_from_duty(float duty) {
  return static_cast<std::uint8_t>(std::lround(clamp_duty(duty) * kPwmFullScale));
}

LedDriver::LedDriver(core::MessageBoard& board, LedPwmOutput& led)
    : Actuator(board, "led_driver",
               {.reads = {FieldId::led_red_duty, FieldId::led_green_duty, FieldId::led_blue_duty}}),
      led_{led} {}

void LedDriver::update() {
  led_.write(pwm_from_duty(boardGet(FieldId::led_red_duty)), pwm_from_duty(boardGet(FieldId::led_green_duty)),
             pwm_from_duty(boardGet(FieldId::led_blue_duty)));
}

RailSwitchDriver::RailSwitchDriver(core::MessageBoard& board, RailSwitchOutput& rail_switch)
    : Actuator(board, "rail_switch_driver", {.reads = {FieldId::rail_on}}), rail_switch_{rail_switch} {}

void RailSwitchDriver::update() { rail_switch_.write(boardGet(FieldId::rail_on) != 0.0F); }

}  // namespace head
