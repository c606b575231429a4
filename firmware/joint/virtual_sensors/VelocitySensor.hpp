// A filtered velocity from a position field (VelocityFilter at
// velocity_filter_hz). Used twice: motor_velocity from motor_position and
// output_velocity from output_position. It writes only in cycles where the
// position was written, so a silent encoder leaves the velocity stale too;
// when samples resume, the gap counts as elapsed time.
#pragma once

#include <cstdint>
#include <string_view>

#include "core/MessageBoardUser.hpp"
#include "joint/virtual_sensors/VelocityFilter.hpp"

namespace joint {

class VelocitySensor final : public core::VirtualSensor {
 public:
  // `name` is a string literal; dt_s is the control cycle period.
  VelocitySensor(core::MessageBoard& board, std::string_view name, board::FieldId position_field,
                 board::FieldId velocity_field, float dt_s);

  void update() override;

 private:
  board::FieldId position_field_;
  board::FieldId velocity_field_;
  float dt_s_;
  std::uint32_t previous_sample_cycle_ = 0;
  VelocityFilter filter_;
};

}  // namespace joint
