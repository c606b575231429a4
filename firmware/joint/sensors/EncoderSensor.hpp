// An encoder on a 16-bit wrapping counter -> a continuous angle on the board.
// Used twice: the motor encoder (motor_position, encoder_counts_per_rev per
// motor revolution) and the output encoder (output_position,
// output_encoder_counts_per_rev per load revolution). Without a fresh sample
// it writes nothing, so the field's last-write cycle shows the staleness.
#pragma once

#include <string_view>

#include "core/MessageBoardUser.hpp"
#include "joint/drivers/CounterInput.hpp"
#include "joint/sensors/EncoderUnwrapper.hpp"

namespace joint {

class EncoderSensor final : public core::Sensor {
 public:
  // `name` is a string literal; `counter` must outlive the sensor.
  EncoderSensor(core::MessageBoard& board, std::string_view name, CounterInput& counter, board::FieldId position_field,
                board::FieldId counts_per_rev_parameter);

  void update() override;

 private:
  CounterInput& counter_;
  board::FieldId position_field_;
  board::FieldId counts_per_rev_parameter_;
  EncoderUnwrapper unwrapper_;
};

}  // namespace joint
