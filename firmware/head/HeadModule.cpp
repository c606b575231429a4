#include "head/HeadModule.hpp"

#include <initializer_list>

namespace head {

using board::FieldId;

HeadModule::HeadModule(core::MessageBoard& board, const HeadDrivers& drivers)
    : imu_{board, drivers.imu},
      rail_current_{board, "rail_current", drivers.rail_current, FieldId::rail_current},
      battery_{board, "battery", drivers.battery, FieldId::battery_voltage},
      attitude_{board},
      faults_{board},
      rail_switch_{board},
      led_mixer_{board},
      led_driver_{board, drivers.led},
      rail_switch_driver_{board, drivers.rail_switch} {}

bool HeadModule::add_to(core::Scheduler& scheduler) {
  for (core::MessageBoardUser* component : std::initializer_list<core::MessageBoardUser*>{
           &imu_, &rail_current_, &battery_, &attitude_, &faults_, &rail_switch_, &led_mixer_, &led_driver_,
           &rail_switch_driver_}) {
    if (!scheduler.add(*component)) return false;
  }
  return true;
}

}  // namespace head
