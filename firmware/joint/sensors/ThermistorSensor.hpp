// Winding thermistor: drains the ADC conversions of the last cycle, averages
// them (in ADC counts, where the noise is) and writes the NTC resistance.
// Without a valid conversion this cycle it writes nothing: the last value
// stays, and its age shows the thermistor is silent (or shorted/open).
#pragma once

#include <array>
#include <cstdint>

#include "core/MessageBoardUser.hpp"
#include "joint/drivers/AdcSampleInput.hpp"

namespace joint {

class ThermistorSensor final : public core::Sensor {
 public:
  // More conversions per cycle than this are averaged over the next cycle.
  static constexpr std::size_t kMaxSamplesPerCycle = 16;

  // `adc` must outlive the sensor.
  ThermistorSensor(core::MessageBoard& board, AdcSampleInput& adc);

  void update() override;

 private:
  AdcSampleInput& adc_;
  std::array<std::uint16_t, kMaxSamplesPerCycle> samples_{};
};

}  // namespace joint
