// The hardware the robot head module needs, one small driver interface per device. A platform
// fills HeadDrivers from its own driver objects (HeadRegisters::drivers() on the HIL rig); the
// components see only these interfaces.
#pragma once

#include <array>
#include <cstdint>

namespace head {

// One reading of the 6-axis IMU's output registers, in counts (the scales are parameters).
struct ImuSample {
  std::array<std::int16_t, 3> accel_counts{};  // x, y, z
  std::array<std::int16_t, 3> gyro_counts{};   // x, y, z
  bool fresh = false;  // a new sample arrived since the previous read
};

class ImuInput {
 public:
  virtual ~ImuInput() = default;
  virtual ImuSample read() = 0;

 protected:
  ImuInput() = default;
  ImuInput(const ImuInput&) = default;
  ImuInput& operator=(const ImuInput&) = default;
};

// An ADC channel that reads in thousandths of its unit (mA of the rail shunt, mV of the battery
// divider).
struct MilliSample {
  std::uint16_t milli = 0;
  bool fresh = false;
};

class MilliInput {
 public:
  virtual ~MilliInput() = default;
  virtual MilliSample read() = 0;

 protected:
  MilliInput() = default;
  MilliInput(const MilliInput&) = default;
  MilliInput& operator=(const MilliInput&) = default;
};

// The RGB LED's three PWM compare values, 0 (off) .. 255 (full on).
class LedPwmOutput {
 public:
  virtual ~LedPwmOutput() = default;
  virtual void write(std::uint8_t red, std::uint8_t green, std::uint8_t blue) = 0;

 protected:
  LedPwmOutput() = default;
  LedPwmOutput(const LedPwmOutput&) = default;
  LedPwmOutput& operator=(const LedPwmOutput&) = default;
};

// The rail's high-side switch gate.
class RailSwitchOutput {
 public:
  virtual ~RailSwitchOutput() = default;
  virtual void write(bool closed) = 0;

 protected:
  RailSwitchOutput() = default;
  RailSwitchOutput(const RailSwitchOutput&) = default;
  RailSwitchOutput& operator=(const RailSwitchOutput&) = default;
};

// References only: the drivers must outlive every component built from them.
struct HeadDrivers {
  ImuInput& imu;
  MilliInput& rail_current;
  MilliInput& battery;
  LedPwmOutput& led;
  RailSwitchOutput& rail_switch;
};

}  // namespace head
