#include "joint/sensors/EncoderUnwrapper.hpp"

#include <numbers>

namespace joint {

float counts_to_rad(std::int64_t counts, float counts_per_rev) {
  // In double: a float loses single counts beyond 2^24 of them.
  return static_cast<float>(static_cast<double>(counts) * 2.0 * std::numbers::pi / static_cast<double>(counts_per_rev));
}

}  // namespace joint
