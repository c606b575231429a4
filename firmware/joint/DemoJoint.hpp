// The demo series-elastic joint: every component of it, built on one board
// and one set of drivers, ready to be added to a core::Scheduler (which
// derives the update order from their declarations).
//
//   core::MessageBoard board;
//   core::Scheduler scheduler{board};
//   joint::HilRegisters registers;
//   joint::DemoJoint demo{board, registers.drivers(), period_s};
//   demo.add_to(scheduler);
//   scheduler.add(canopen_node);            // the ExternalWriter of all rw fields
//   if (auto status = scheduler.start(); !status) { ... status.message() ... }
#pragma once

#include "core/MessageBoard.hpp"
#include "core/Scheduler.hpp"
#include "joint/actuators/Motor.hpp"
#include "joint/actuators/StatusLed.hpp"
#include "joint/drivers/JointDrivers.hpp"
#include "joint/modules/Cia402Drive.hpp"
#include "joint/modules/CommandWatchdog.hpp"
#include "joint/modules/DriveArbiter.hpp"
#include "joint/modules/FaultManager.hpp"
#include "joint/modules/LedPatternSelector.hpp"
#include "joint/modules/SpringConstantEstimator.hpp"
#include "joint/modules/ThermalProtection.hpp"
#include "joint/modules/TorqueController.hpp"
#include "joint/modules/VelocityController.hpp"
#include "joint/sensors/EncoderSensor.hpp"
#include "joint/sensors/HeartbeatSensor.hpp"
#include "joint/sensors/MotorCurrentSensor.hpp"
#include "joint/sensors/ThermistorSensor.hpp"
#include "joint/virtual_sensors/JointTorque.hpp"
#include "joint/virtual_sensors/SpringDeflection.hpp"
#include "joint/virtual_sensors/VelocitySensor.hpp"
#include "joint/virtual_sensors/WindingTemperature.hpp"

namespace joint {

class DemoJoint {
 public:
  // The board and the drivers must outlive the joint; dt_s is the control
  // cycle period (the firmware's --period-us), > 0.
  DemoJoint(core::MessageBoard& board, const JointDrivers& drivers, float dt_s);
  DemoJoint(const DemoJoint&) = delete;
  DemoJoint& operator=(const DemoJoint&) = delete;

  // Adds every component, in no particular order. Returns false (adding
  // nothing more) if the scheduler has already started.
  bool add_to(core::Scheduler& scheduler);

 private:
  // Sensors
  EncoderSensor motor_encoder_;
  EncoderSensor output_encoder_;
  ThermistorSensor thermistor_;
  MotorCurrentSensor motor_current_;
  HeartbeatSensor heartbeat_;
  // Virtual sensors
  VelocitySensor motor_velocity_;
  VelocitySensor output_velocity_;
  SpringDeflection spring_deflection_;
  JointTorque joint_torque_;
  WindingTemperature winding_temperature_;
  // Modules
  ThermalProtection thermal_protection_;
  CommandWatchdog command_watchdog_;
  Cia402Drive cia402_drive_;
  FaultManager fault_manager_;
  VelocityController velocity_controller_;
  TorqueController torque_controller_;
  DriveArbiter drive_arbiter_;
  SpringConstantEstimator spring_constant_estimator_;
  LedPatternSelector led_pattern_;
  // Actuators
  Motor motor_;
  StatusLed status_led_;
};

}  // namespace joint
