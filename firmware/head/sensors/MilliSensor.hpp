// An ADC channel in thousandths of a unit -> a field in the unit: the rail shunt (mA ->
// rail_current in A) and the battery divider (mV -> battery_voltage in V). Without a fresh
// sample it writes nothing.
#pragma once

#include <string_view>

#include "core/MessageBoardUser.hpp"
#include "head/drivers/HeadDrivers.hpp"

namespace head {

class MilliSensor final : public core::Sensor {
 public:
  // `name` a string literal; `input` must outlive the sensor.
  MilliSensor(core::MessageBoard& board, std::string_view name, MilliInput& input, board::FieldId field);

  void update() override;

 private:
  MilliInput& input_;
  board::FieldId field_;
};

}  // namespace head
