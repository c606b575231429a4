#include "joint/sensors/ThermistorSensor.hpp"

#include <algorithm>

#include "joint/sensors/ThermistorDivider.hpp"

namespace joint {

using board::FieldId;

ThermistorSensor::ThermistorSensor(core::MessageBoard& board, AdcSampleInput& adc)
    : Sensor(board, "thermistor", {.writes = {FieldId::thermistor_resistance}}), adc_{adc} {}

void ThermistorSensor::update() {
  const std::size_t count = adc_.drain(samples_);
  const std::optional<float> mean = mean_valid_adc(std::span<const std::uint16_t>(samples_.data(), count));
  if (!mean) {
    return;
  }
  if (const std::optional<float> resistance = thermistor_resistance_ohm(*mean)) {
    boardSet(FieldId::thermistor_resistance, std::min(*resistance, board::info(FieldId::thermistor_resistance).max));
  }
}

}  // namespace joint
