// A filtered velocity from an encoder's raw counter field (VelocityFilter at
// velocity_filter_hz). Used twice: motor_velocity from motor_encoder_raw
// (encoder_counts_per_rev) and output_velocity from output_encoder_raw
// (output_encoder_counts_per_rev).
//
// Why the raw counter and not the angle: the step between two counter
// readings, taken modulo 2^16, is an exact integer however far the shaft has
// turned, and the time between them is a difference of cycle numbers, exact
// across the counter's 2^32 wrap. The float angle field loses resolution with
// the distance turned (the soak saw 3 % velocity error after 1e6 cycles).
//
// It writes only in cycles where the counter was written, so a silent encoder
// leaves the velocity stale too; when samples resume, the gap counts as
// elapsed time (the shaft must still move less than half a counter wrap
// between two samples, as for the encoder sensor's unwrapping).
#pragma once

#include <cstdint>
#include <string_view>

#include "core/MessageBoardUser.hpp"
#include "joint/virtual_sensors/VelocityFilter.hpp"

namespace joint {

class VelocitySensor final : public core::VirtualSensor {
 public:
  // `name` is a string literal; dt_s is the control cycle period.
  VelocitySensor(core::MessageBoard& board, std::string_view name, board::FieldId raw_counter_field,
                 board::FieldId counts_per_rev_parameter, board::FieldId velocity_field, float dt_s);

  void update() override;

 private:
  board::FieldId raw_counter_field_;
  board::FieldId counts_per_rev_parameter_;
  board::FieldId velocity_field_;
  float dt_s_;
  bool has_previous_sample_ = false;
  std::uint16_t previous_counter_ = 0;
  std::uint32_t previous_sample_cycle_ = 0;
  VelocityFilter filter_;
};

}  // namespace joint
