// The motor bridge: motor_duty_command (-1..1) -> DutyOutput raw
// (-10000..10000), limited to max_duty, and 0 in the safe state (the drive
// arbiter zeroes it already; the actuator does it again because it is the last
// step before the hardware; the CiA 402 fault reaction's ramp passes both: FaultBits.hpp).
#pragma once

#include <cstdint>

#include "core/MessageBoardUser.hpp"
#include "joint/drivers/DutyOutput.hpp"

namespace joint {

// The raw bridge duty for a duty command, limited to +-max_duty (and +-1). NaN gives 0.
std::int16_t duty_to_raw(float duty, float max_duty);

class Motor final : public core::Actuator {
 public:
  // `output` must outlive the actuator.
  Motor(core::MessageBoard& board, DutyOutput& output);

  void update() override;

 private:
  DutyOutput& output_;
};

}  // namespace joint
