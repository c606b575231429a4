#include "joint/virtual_sensors/VelocitySensor.hpp"

#include <numbers>

#include "joint/BoardReads.hpp"
#include "joint/sensors/EncoderUnwrapper.hpp"

namespace joint {

using board::FieldId;

VelocitySensor::VelocitySensor(core::MessageBoard& board, std::string_view name, FieldId raw_counter_field,
                               FieldId counts_per_rev_parameter, FieldId velocity_field, float dt_s)
    : VirtualSensor(board, name,
                    {.writes = {velocity_field},
                     .reads = {raw_counter_field, counts_per_rev_parameter, FieldId::velocity_filter_hz}}),
      raw_counter_field_{raw_counter_field},
      counts_per_rev_parameter_{counts_per_rev_parameter},
      velocity_field_{velocity_field},
      dt_s_{dt_s} {}

void VelocitySensor::update() {
  if (!written_this_cycle(board(), raw_counter_field_)) {
    return;
  }
  const std::uint16_t counter = counter_from_field(boardGet(raw_counter_field_));
  const std::uint32_t cycle = board().cycle();
  if (has_previous_sample_) {
    // Both differences are modular and exact: the counter's over 2^16, the cycle's over 2^32.
    const std::uint32_t elapsed_cycles = cycle - previous_sample_cycle_;
    const float elapsed_s = static_cast<float>(elapsed_cycles) * dt_s_;
    // The table keeps counts per rev >= 1.
    const double rad_per_count = 2.0 * std::numbers::pi / static_cast<double>(boardGet(counts_per_rev_parameter_));
    const auto displacement_rad = static_cast<float>(counter_step(counter, previous_counter_) * rad_per_count);
    boardSet(velocity_field_, filter_.update(displacement_rad, elapsed_s, boardGet(FieldId::velocity_filter_hz)));
  }
  has_previous_sample_ = true;
  previous_counter_ = counter;
  previous_sample_cycle_ = cycle;
}

}  // namespace joint
