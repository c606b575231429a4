#include "joint/virtual_sensors/WindingTemperature.hpp"

#include <algorithm>

#include "joint/BoardReads.hpp"
#include "joint/virtual_sensors/NtcThermistor.hpp"

namespace joint {

using board::FieldId;

WindingTemperature::WindingTemperature(core::MessageBoard& board)
    : VirtualSensor(board, "winding_temperature",
                    {.writes = {FieldId::winding_temperature},
                     .reads = {FieldId::thermistor_resistance, FieldId::ntc_r25_ohm, FieldId::ntc_beta_k}}) {}

void WindingTemperature::update() {
  if (!written_this_cycle(board(), FieldId::thermistor_resistance)) {
    return;
  }
  const float resistance_ohm = boardGet(FieldId::thermistor_resistance);
  if (!(resistance_ohm > 0.0F)) {
    return;  // the sensor never writes this; a guard against log(0), not a case
  }
  const board::FieldInfo& field = board::info(FieldId::winding_temperature);
  const float temperature_c =
      ntc_temperature_c(resistance_ohm, boardGet(FieldId::ntc_r25_ohm), boardGet(FieldId::ntc_beta_k));
  boardSet(FieldId::winding_temperature, std::clamp(temperature_c, field.min, field.max));
}

}  // namespace joint
