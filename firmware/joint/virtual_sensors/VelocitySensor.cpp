#include "joint/virtual_sensors/VelocitySensor.hpp"

#include "joint/BoardReads.hpp"

namespace joint {

using board::FieldId;

VelocitySensor::VelocitySensor(core::MessageBoard& board, std::string_view name, FieldId position_field,
                               FieldId velocity_field, float dt_s)
    : VirtualSensor(board, name,
                    {.writes = {velocity_field}, .reads = {position_field, FieldId::velocity_filter_hz}}),
      position_field_{position_field},
      velocity_field_{velocity_field},
      dt_s_{dt_s} {}

void VelocitySensor::update() {
  if (!written_this_cycle(board(), position_field_)) {
    return;
  }
  const std::uint32_t cycle = board().cycle();
  const float elapsed_s = static_cast<float>(cycle - previous_sample_cycle_) * dt_s_;
  previous_sample_cycle_ = cycle;
  const float velocity = filter_.update(boardGet(position_field_), elapsed_s, boardGet(FieldId::velocity_filter_hz));
  if (filter_.has_velocity()) {
    boardSet(velocity_field_, velocity);
  }
}

}  // namespace joint
