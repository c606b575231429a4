// Winding temperature from the thermistor resistance (NTC beta model with
// ntc_r25_ohm, ntc_beta_k). Written only when the resistance was written this
// cycle, so a silent thermistor leaves the temperature stale too.
#pragma once

#include "core/MessageBoardUser.hpp"

namespace joint {

class WindingTemperature final : public core::VirtualSensor {
 public:
  explicit WindingTemperature(core::MessageBoard& board);

  void update() override;
};

}  // namespace joint
