#include "joint/sensors/EncoderUnwrapper.hpp"

#include <cmath>
#include <numbers>

namespace joint {

std::uint16_t counter_from_field(float value) {
  // The encoder sensor writes whole numbers 0..65535; anything else is folded
  // onto the counter's range rather than being undefined behaviour.
  if (!std::isfinite(value)) {
    return 0;
  }
  return static_cast<std::uint16_t>(static_cast<std::int64_t>(std::lround(value)) & 0xFFFF);
}

float counts_to_rad(std::int64_t counts, float counts_per_rev) {
  // In double: a float loses single counts beyond 2^24 of them.
  return static_cast<float>(static_cast<double>(counts) * 2.0 * std::numbers::pi / static_cast<double>(counts_per_rev));
}

}  // namespace joint
