// The status LED: led_pattern_command -> LedOutput. A number that is none of the
// patterns (cannot come from LedPatternSelector) shows as the fault pattern.
#pragma once

#include "core/MessageBoardUser.hpp"
#include "joint/drivers/LedOutput.hpp"

namespace joint {

class StatusLed final : public core::Actuator {
 public:
  // `output` must outlive the actuator.
  StatusLed(core::MessageBoard& board, LedOutput& output);

  void update() override;

 private:
  LedOutput& output_;
};

}  // namespace joint
