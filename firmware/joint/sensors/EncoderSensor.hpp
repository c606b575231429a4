// An encoder on a 16-bit wrapping counter -> the board. Used twice: the motor
// encoder (motor_position and motor_encoder_raw, encoder_counts_per_rev per
// motor revolution) and the output encoder (output_position and
// output_encoder_raw, output_encoder_counts_per_rev per load revolution).
//
// Two fields per encoder, because a float angle cannot stay exact: its
// resolution falls with the distance turned (0.25 rad after 3e6 rad, two hours
// of the motor at full speed). The raw counter reading (an integer 0..65535,
// exact in a float) is what velocity and spring deflection are derived from,
// by modular differences that stay exact for as long as the firmware runs;
// the continuous angle is for display and the position loop.
//
// Without a fresh sample it writes nothing, so the fields' last-write cycle
// shows the staleness.
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
                board::FieldId raw_counter_field, board::FieldId counts_per_rev_parameter);

  void update() override;

 private:
  CounterInput& counter_;
  board::FieldId position_field_;
  board::FieldId raw_counter_field_;
  board::FieldId counts_per_rev_parameter_;
  EncoderUnwrapper unwrapper_;
};

}  // namespace joint
