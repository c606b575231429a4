#include "joint/modules/PidController.hpp"

#include <algorithm>

namespace joint {

float PidController::update(float setpoint, float measurement, float dt_s, const PidGains& gains, float output_limit) {
  const float limit = std::max(output_limit, 0.0F);
  const float error = setpoint - measurement;
  const float proportional = gains.kp * error;
  float derivative = 0.0F;
  if (has_previous_measurement_ && dt_s > 0.0F) {
    derivative = -gains.kd * (measurement - previous_measurement_) / dt_s;
  }
  previous_measurement_ = measurement;
  has_previous_measurement_ = true;

  const float candidate_integral = std::clamp(integral_ + gains.ki * error * dt_s, -limit, limit);
  const float unsaturated = proportional + candidate_integral + derivative;
  const bool pushes_past_upper = unsaturated > limit && candidate_integral > integral_;
  const bool pushes_past_lower = unsaturated < -limit && candidate_integral < integral_;
  if (!pushes_past_upper && !pushes_past_lower) {
    integral_ = candidate_integral;
  }
  // A lowered limit also bounds what was integrated before.
  integral_ = std::clamp(integral_, -limit, limit);
  return std::clamp(proportional + integral_ + derivative, -limit, limit);
}

void PidController::reset() {
  integral_ = 0.0F;
  previous_measurement_ = 0.0F;
  has_previous_measurement_ = false;
}

}  // namespace joint
