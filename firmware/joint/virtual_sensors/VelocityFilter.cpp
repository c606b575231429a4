#include "joint/virtual_sensors/VelocityFilter.hpp"

#include <cmath>
#include <numbers>

namespace joint {

float VelocityFilter::update(float displacement, float elapsed_s, float cutoff_hz) {
  if (elapsed_s > 0.0F) {
    const float raw_velocity = displacement / elapsed_s;
    const float alpha = 1.0F - std::exp(-2.0F * std::numbers::pi_v<float> * cutoff_hz * elapsed_s);
    velocity_ += alpha * (raw_velocity - velocity_);
    has_velocity_ = true;
  }
  return velocity_;
}

}  // namespace joint
