// The toy lamp's components (board.toml beside this folder): a Sensor that turns the
// photodiode's raw ADC reading into light_level, and an Actuator that turns light_setpoint into
// the lamp's PWM. Both talk to the hardware only through hilfw::HilRegisters, the latest raw
// value of each of the table's [[hil_input]]s and the raw value of each [[hil_output]].
#pragma once

#include <cstdint>

#include "board/fields.hpp"
#include "core/MessageBoardUser.hpp"
#include "core/Scheduler.hpp"
#include "hilfw/HilRegisters.hpp"

namespace lamp {

using board::FieldId;
using board::HilInputId;
using board::HilOutputId;

inline constexpr float kAdcFullScale = 4095.0F;   // the photodiode's 12-bit ADC at full brightness
inline constexpr float kPwmFullScale = 10000.0F;  // lamp_pwm at 100 % duty (the table's 0.01 % unit)

class LightSensor final : public core::Sensor {
 public:
  LightSensor(core::MessageBoard& board, hilfw::HilRegisters& registers)
      : Sensor(board, "light_sensor", {.writes = {FieldId::light_level}}), registers_{registers} {}
  void update() override {
    const float adc = static_cast<float>(registers_.read_input(HilInputId::photodiode_adc).raw);
    boardSet(FieldId::light_level, adc / kAdcFullScale);
  }

 private:
  hilfw::HilRegisters& registers_;
};

// Open loop: the lamp's light in steady state is its duty, so the setpoint is the duty.
class LampDriver final : public core::Actuator {
 public:
  LampDriver(core::MessageBoard& board, hilfw::HilRegisters& registers)
      : Actuator(board, "lamp_driver", {.reads = {FieldId::light_setpoint}}), registers_{registers} {}
  void update() override {
    const float duty = boardGet(FieldId::light_setpoint);
    registers_.write_output(HilOutputId::lamp_pwm, static_cast<std::int32_t>(duty * kPwmFullScale + 0.5F));
  }

 private:
  hilfw::HilRegisters& registers_;
};

// The component set hilfw::run_board builds (and rebuilds on NMT reset node).
class Components {
 public:
  Components(core::MessageBoard& board, hilfw::HilRegisters& registers, float /*dt_s*/)
      : sensor_{board, registers}, driver_{board, registers} {}
  bool add_to(core::Scheduler& scheduler) { return scheduler.add(sensor_) && scheduler.add(driver_); }

 private:
  LightSensor sensor_;
  LampDriver driver_;
};

}  // namespace lamp
