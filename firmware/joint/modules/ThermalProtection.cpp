#include "joint/modules/ThermalProtection.hpp"

namespace joint {

using board::FieldId;

ThermalProtection::ThermalProtection(core::MessageBoard& board)
    : Module(board, "thermal_protection",
             {.writes = {FieldId::thermal_derate},
              .reads = {FieldId::winding_temperature, FieldId::thermal_warning_c, FieldId::thermal_limit_c,
                        FieldId::thermal_hysteresis_c}}) {}

void ThermalProtection::update() {
  // Before the first temperature the field holds its table default (25 degC);
  // a thermistor that never reports is the fault manager's business.
  const ThermalLimits limits{boardGet(FieldId::thermal_warning_c), boardGet(FieldId::thermal_limit_c),
                             boardGet(FieldId::thermal_hysteresis_c)};
  boardSet(FieldId::thermal_derate, derate_.update(boardGet(FieldId::winding_temperature), limits));
}

}  // namespace joint
