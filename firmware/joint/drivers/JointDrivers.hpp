// The hardware the demo joint needs, one driver per device. A platform fills
// this from its own driver objects (HilRegisters::drivers() on the HIL rig).
#pragma once

#include "joint/drivers/AdcSampleInput.hpp"
#include "joint/drivers/CounterInput.hpp"
#include "joint/drivers/CurrentInput.hpp"
#include "joint/drivers/DutyOutput.hpp"
#include "joint/drivers/HeartbeatInput.hpp"
#include "joint/drivers/LedOutput.hpp"

namespace joint {

// References only: the drivers must outlive every component built from them.
struct JointDrivers {
  CounterInput& motor_encoder;
  CounterInput& output_encoder;
  AdcSampleInput& thermistor_adc;
  CurrentInput& motor_current;
  DutyOutput& motor_duty;
  LedOutput& status_led;
  HeartbeatInput& heartbeat;
};

}  // namespace joint
