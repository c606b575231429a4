#include "head/virtual_sensors/HeadAttitude.hpp"

#include <cmath>

namespace head {

using board::FieldId;

Attitude attitude_from_gravity(float ax, float ay, float az) {
  if (ax == 0.0F && ay == 0.0F && az == 0.0F) return {};
  return Attitude{std::atan2(-ax, std::hypot(ay, az)), std::atan2(ay, az)};
}

HeadAttitude::HeadAttitude(core::MessageBoard& board)
    : VirtualSensor(board, "head_attitude",
                    {.writes = {FieldId::head_pitch, FieldId::head_roll},
                     .reads = {FieldId::accel_x, FieldId::accel_y, FieldId::accel_z}}) {}

void HeadAttitude::update() {
  const Attitude attitude =
      attitude_from_gravity(boardGet(FieldId::accel_x), boardGet(FieldId::accel_y), boardGet(FieldId::accel_z));
  boardSet(FieldId::head_pitch, attitude.pitch_rad);
  boardSet(FieldId::head_roll, attitude.roll_rad);
}

}  // namespace head
