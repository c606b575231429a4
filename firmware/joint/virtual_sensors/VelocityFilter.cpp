#include "joint/virtual_sensors/VelocityFilter.hpp"

#include <cmath>
#include <numbers>

namespace joint {

float VelocityFilter::update(float position, float elapsed_s, float cutoff_hz) {
  if (samples_ > 0 && elapsed_s > 0.0F) {
    const float raw_velocity = (position - previous_position_) / elapsed_s;
    const float alpha = 1.0F - std::exp(-2.0F * std::numbers::pi_v<float> * cutoff_hz * elapsed_s);
    velocity_ += alpha * (raw_velocity - velocity_);
  }
  previous_position_ = position;
  if (samples_ < 2) {
    ++samples_;
  }
  return velocity_;
}

}  // namespace joint
