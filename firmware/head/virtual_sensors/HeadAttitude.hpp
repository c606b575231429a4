// Pitch and roll of the head from the direction of gravity in the accelerometer's reading (valid
// while the head is not accelerating much; no gyro fusion yet). x forward, y left, z up: at rest
// the specific force is (0, 0, +g); nose down gives pitch > 0, left side up gives roll > 0.
#pragma once

#include "core/MessageBoardUser.hpp"

namespace head {

struct Attitude {
  float pitch_rad = 0.0F;
  float roll_rad = 0.0F;
};

// The pure math; all-zero acceleration (free fall, no sample) gives (0, 0).
Attitude attitude_from_gravity(float ax, float ay, float az);

class HeadAttitude final : public core::VirtualSensor {
 public:
  explicit HeadAttitude(core::MessageBoard& board);

  void update() override;
};

}  // namespace head
