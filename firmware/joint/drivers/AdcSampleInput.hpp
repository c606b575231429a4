// An ADC channel sampled by hardware at its own rate: every conversion is kept
// until the control cycle drains it, so the sensor can filter them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace joint {

class AdcSampleInput {
 public:
  virtual ~AdcSampleInput() = default;
  // Moves up to out.size() samples that arrived since the previous drain,
  // oldest first, into `out`; returns how many. Zero means no new conversion.
  virtual std::size_t drain(std::span<std::uint16_t> out) = 0;

 protected:
  AdcSampleInput() = default;
  AdcSampleInput(const AdcSampleInput&) = default;
  AdcSampleInput& operator=(const AdcSampleInput&) = default;
};

}  // namespace joint
