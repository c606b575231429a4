#include "head/sensors/ImuSensor.hpp"

#include <array>
#include <cstddef>

namespace head {

using board::FieldId;

namespace {
constexpr std::array<FieldId, 3> kAccel{FieldId::accel_x, FieldId::accel_y, FieldId::accel_z};
constexpr std::array<FieldId, 3> kGyro{FieldId::gyro_x, FieldId::gyro_y, FieldId::gyro_z};
}  // namespace

ImuSensor::ImuSensor(core::MessageBoard& board, ImuInput& imu)
    : Sensor(board, "imu",
             {.writes = {FieldId::accel_x, FieldId::accel_y, FieldId::accel_z, FieldId::gyro_x, FieldId::gyro_y,
                         FieldId::gyro_z},
              .reads = {FieldId::accel_scale, FieldId::gyro_scale}}),
      imu_{imu} {}

void ImuSensor::update() {
  const ImuSample sample = imu_.read();
  if (!sample.fresh) return;
  const float accel_scale = boardGet(FieldId::accel_scale);
  const float gyro_scale = boardGet(FieldId::gyro_scale);
  for (std::size_t axis = 0; axis < 3; ++axis) {
    boardSet(kAccel[axis], static_cast<float>(sample.accel_counts[axis]) * accel_scale);
    boardSet(kGyro[axis], static_cast<float>(sample.gyro_counts[axis]) * gyro_scale);
  }
}

}  // namespace head
