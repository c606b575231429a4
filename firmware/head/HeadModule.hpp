// The robot head module: every component of it, built on one board and one set of drivers,
// ready to be added to a core::Scheduler (which orders them from their declarations). The same
// core as the joint's (firmware/core), compiled against the head's table (protocol/boards/head.toml).
//
//   core::MessageBoard board;
//   core::Scheduler scheduler{board};
//   head::HeadRegisters registers;
//   head::HeadModule module{board, registers.drivers()};
//   module.add_to(scheduler);
//   scheduler.add(canopen_node);            // the ExternalWriter of all rw fields
//   if (auto status = scheduler.start(); !status) { ... status.message() ... }
#pragma once

#include "core/MessageBoard.hpp"
#include "core/Scheduler.hpp"
#include "head/actuators/HeadActuators.hpp"
#include "head/drivers/HeadDrivers.hpp"
#include "head/modules/HeadFaults.hpp"
#include "head/modules/PowerModules.hpp"
#include "head/sensors/ImuSensor.hpp"
#include "head/sensors/MilliSensor.hpp"
#include "head/virtual_sensors/HeadAttitude.hpp"

namespace head {

class HeadModule {
 public:
  // The board and the drivers must outlive the module.
  HeadModule(core::MessageBoard& board, const HeadDrivers& drivers);
  HeadModule(const HeadModule&) = delete;
  HeadModule& operator=(const HeadModule&) = delete;

  // Adds every component, in no particular order. Returns false (adding nothing more) if the
  // scheduler has already started.
  bool add_to(core::Scheduler& scheduler);

 private:
  ImuSensor imu_;
  MilliSensor rail_current_;
  MilliSensor battery_;
  HeadAttitude attitude_;
  HeadFaults faults_;
  RailSwitch rail_switch_;
  LedMixer led_mixer_;
  LedDriver led_driver_;
  RailSwitchDriver rail_switch_driver_;
};

}  // namespace head
