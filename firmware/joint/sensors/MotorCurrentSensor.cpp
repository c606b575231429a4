#include "joint/sensors/MotorCurrentSensor.hpp"

namespace joint {

using board::FieldId;

namespace {
constexpr float kAmperesPerCount = 0.001F;
}  // namespace

MotorCurrentSensor::MotorCurrentSensor(core::MessageBoard& board, CurrentInput& current)
    : Sensor(board, "motor_current", {.writes = {FieldId::motor_current}}), current_{current} {}

void MotorCurrentSensor::update() {
  const CurrentSample sample = current_.read();
  if (sample.fresh) {
    boardSet(FieldId::motor_current, static_cast<float>(sample.milliamps) * kAmperesPerCount);
  }
}

}  // namespace joint
