// Position mode's outer loop: a proportional position controller whose output
// is the velocity reference of the velocity loop. The reference is limited to
// the velocity_setpoint range of the field table, the fastest the joint is
// ever commanded to move.
#pragma once

#include <algorithm>

namespace joint {

constexpr float position_velocity_reference(float position_setpoint_rad, float position_rad, float position_kp_per_s,
                                            float max_velocity_rad_s) {
  return std::clamp(position_kp_per_s * (position_setpoint_rad - position_rad), -max_velocity_rad_s,
                    max_velocity_rad_s);
}

}  // namespace joint
