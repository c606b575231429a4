// The fan board's components (board.toml beside this folder), one of each kind a board
// usually needs. They talk to the hardware only through hilfw::HilRegisters: the latest raw
// value of each [[hil_input]], the raw value of each [[hil_output]]. Each declares the fields it
// writes and reads; the scheduler orders them from that, and refuses two writers of one field.
#pragma once

#include <algorithm>
#include <cstdint>

#include "board/fields.hpp"
#include "core/MessageBoardUser.hpp"
#include "core/Scheduler.hpp"
#include "hilfw/HilRegisters.hpp"

namespace fan {

using board::FieldId;
using board::HilInputId;
using board::HilOutputId;

inline constexpr float kPwmFullScale = 10000.0F;  // fan_pwm at 100 % duty (the table's 0.01 %)
inline constexpr float kDegreesPerCount = 0.05F;  // the thermistor ADC's scale
inline constexpr float kMaxRpm = 3000.0F;         // the fan's speed at full duty
inline constexpr float kSpeedGain = 0.002F;       // duty per rpm of speed error
inline constexpr float kHotC = 70.0F;             // above this, full speed whatever the target

// Sensor: the tach and the thermistor -> speed and temperature.
class FanSensors final : public core::Sensor {
 public:
  FanSensors(core::MessageBoard& board, hilfw::HilRegisters& registers)
      : Sensor(board, "fan_sensors", {.writes = {FieldId::fan_speed_rpm, FieldId::air_temperature_c}}),
        registers_{registers} {}
  void update() override {
    boardSet(FieldId::fan_speed_rpm, static_cast<float>(registers_.read_input(HilInputId::tach_rpm).raw));
    const auto adc = static_cast<float>(registers_.read_input(HilInputId::thermistor_adc).raw);
    boardSet(FieldId::air_temperature_c, adc * kDegreesPerCount);
  }

 private:
  hilfw::HilRegisters& registers_;
};

// Module: feed-forward plus proportional speed control; full speed when the air is hot.
class Controller final : public core::Module {
 public:
  explicit Controller(core::MessageBoard& board)
      : Module(board, "controller",
               {.writes = {FieldId::fan_duty},
                .reads = {FieldId::speed_target_rpm, FieldId::fan_speed_rpm, FieldId::air_temperature_c}}) {}
  void update() override {
    const float target = boardGet(FieldId::speed_target_rpm);
    const float duty = target / kMaxRpm + kSpeedGain * (target - boardGet(FieldId::fan_speed_rpm));
    boardSet(FieldId::fan_duty, boardGet(FieldId::air_temperature_c) > kHotC ? 1.0F : std::clamp(duty, 0.0F, 1.0F));
  }
};

// Actuator: a board field -> the raw hardware command.
class OutputDriver final : public core::Actuator {
 public:
  OutputDriver(core::MessageBoard& board, hilfw::HilRegisters& registers)
      : Actuator(board, "output_driver", {.reads = {FieldId::fan_duty}}), registers_{registers} {}
  void update() override {
    registers_.write_output(HilOutputId::fan_pwm, static_cast<std::int32_t>(boardGet(FieldId::fan_duty) * kPwmFullScale + 0.5F));
  }

 private:
  hilfw::HilRegisters& registers_;
};

// The component set hilfw::run_board builds (and builds again on NMT reset node).
class Components {
 public:
  Components(core::MessageBoard& board, hilfw::HilRegisters& registers, float /*dt_s*/)
      : sensor_{board, registers}, controller_{board}, driver_{board, registers} {}
  bool add_to(core::Scheduler& scheduler) {
    return scheduler.add(sensor_) && scheduler.add(controller_) && scheduler.add(driver_);
  }

 private:
  FanSensors sensor_;
  Controller controller_;
  OutputDriver driver_;
};

}  // namespace fan
