// The IMU's output registers -> accel_x/y/z (m/s^2) and gyro_x/y/z (rad/s), scaled by the
// accel_scale and gyro_scale parameters. Without a fresh sample it writes nothing, so the fault
// monitor sees the IMU go silent.
#pragma once

#include "core/MessageBoardUser.hpp"
#include "head/drivers/HeadDrivers.hpp"

namespace head {

class ImuSensor final : public core::Sensor {
 public:
  // `imu` must outlive the sensor.
  ImuSensor(core::MessageBoard& board, ImuInput& imu);

  void update() override;

 private:
  ImuInput& imu_;
};

}  // namespace head
