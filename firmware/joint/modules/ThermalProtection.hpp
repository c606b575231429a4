// Writes thermal_derate from winding_temperature and the thermal parameters
// (ThermalDerate). thermal_derate == 0 is the over-temperature state, which the
// fault manager latches as FaultBit::OverTemperature.
#pragma once

#include "core/MessageBoardUser.hpp"
#include "joint/modules/ThermalDerate.hpp"

namespace joint {

class ThermalProtection final : public core::Module {
 public:
  explicit ThermalProtection(core::MessageBoard& board);

  void update() override;

 private:
  ThermalDerate derate_;
};

}  // namespace joint
