#include "joint/modules/ThermalDerate.hpp"

#include <algorithm>

namespace joint {

float ThermalDerate::update(float temperature_c, const ThermalLimits& limits) {
  if (temperature_c >= limits.limit_c) {
    over_temperature_ = true;
  } else if (temperature_c < limits.limit_c - limits.hysteresis_c) {
    over_temperature_ = false;
  }
  if (over_temperature_) {
    return 0.0F;
  }
  if (temperature_c <= limits.warning_c) {
    return 1.0F;
  }
  // Here warning_c < temperature_c < limit_c, so the span is positive.
  return std::clamp((limits.limit_c - temperature_c) / (limits.limit_c - limits.warning_c), 0.0F, 1.0F);
}

}  // namespace joint
