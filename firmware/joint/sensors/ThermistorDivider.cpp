#include "joint/sensors/ThermistorDivider.hpp"

namespace joint {

std::optional<float> thermistor_resistance_ohm(float adc_counts, float pullup_ohm) {
  constexpr auto full_scale = static_cast<float>(kThermistorAdcFullScale);
  if (!(adc_counts > 0.0F && adc_counts < full_scale)) {
    return std::nullopt;
  }
  return pullup_ohm * adc_counts / (full_scale - adc_counts);
}

std::optional<float> mean_valid_adc(std::span<const std::uint16_t> samples) {
  std::uint32_t sum = 0;
  std::uint32_t count = 0;
  for (const std::uint16_t sample : samples) {
    // Rail readings are faults; averaging them in would fake a temperature.
    if (sample > 0 && sample < kThermistorAdcFullScale) {
      sum += sample;
      ++count;
    }
  }
  if (count == 0) {
    return std::nullopt;
  }
  return static_cast<float>(sum) / static_cast<float>(count);
}

}  // namespace joint
