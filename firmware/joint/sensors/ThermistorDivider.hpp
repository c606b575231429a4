// The thermistor's voltage divider: 3.3 V -- pull-up -- node -- NTC -- GND,
// read by a 12-bit ADC: adc = 4095 * R_ntc / (R_ntc + R_pullup).
#pragma once

#include <cstdint>
#include <optional>
#include <span>

namespace joint {

inline constexpr std::uint16_t kThermistorAdcFullScale = 4095;
// A property of the board's circuit, not of the NTC, hence not a board parameter.
inline constexpr float kThermistorPullupOhm = 10000.0F;

// The NTC resistance for a (possibly averaged) ADC reading. Empty for a reading
// with no finite, positive resistance: 0 (shorted NTC) or full scale and above
// (open NTC): a wiring fault, not a temperature.
std::optional<float> thermistor_resistance_ohm(float adc_counts, float pullup_ohm = kThermistorPullupOhm);

// The mean of the valid (1..4094) ADC samples; empty if there is none.
std::optional<float> mean_valid_adc(std::span<const std::uint16_t> samples);

}  // namespace joint
