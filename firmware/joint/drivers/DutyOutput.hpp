// The motor H-bridge: a signed duty, -10000..10000 = -100 %..+100 % of the bus voltage.
#pragma once

#include <cstdint>

namespace joint {

inline constexpr std::int16_t kDutyRawFullScale = 10000;

class DutyOutput {
 public:
  virtual ~DutyOutput() = default;
  // `duty_raw` is within -kDutyRawFullScale..kDutyRawFullScale (the caller clamps).
  virtual void write(std::int16_t duty_raw) = 0;

 protected:
  DutyOutput() = default;
  DutyOutput(const DutyOutput&) = default;
  DutyOutput& operator=(const DutyOutput&) = default;
};

}  // namespace joint
