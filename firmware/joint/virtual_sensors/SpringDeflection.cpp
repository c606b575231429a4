#include "joint/virtual_sensors/SpringDeflection.hpp"

#include <numbers>

#include "joint/BoardReads.hpp"

namespace joint {

using board::FieldId;

float spring_deflection_rad(std::int64_t motor_counts, std::int64_t output_counts,
                            const EncoderResolution& resolution) {
  const double gearbox_turns =
      static_cast<double>(motor_counts) / (resolution.motor_counts_per_rev * resolution.gear_ratio);
  const double output_turns = static_cast<double>(output_counts) / resolution.output_counts_per_rev;
  return static_cast<float>((gearbox_turns - output_turns) * 2.0 * std::numbers::pi);
}

SpringDeflection::SpringDeflection(core::MessageBoard& board)
    : VirtualSensor(board, "spring_deflection",
                    {.writes = {FieldId::spring_deflection},
                     .reads = {FieldId::motor_encoder_raw, FieldId::output_encoder_raw, FieldId::gear_ratio,
                               FieldId::encoder_counts_per_rev, FieldId::output_encoder_counts_per_rev}}) {}

void SpringDeflection::update() {
  // Every sample of each encoder is taken, so the unwrapping follows the counter
  // even while the other encoder is silent.
  const bool motor_fresh = written_this_cycle(board(), FieldId::motor_encoder_raw);
  const bool output_fresh = written_this_cycle(board(), FieldId::output_encoder_raw);
  if (motor_fresh) {
    motor_counts_.update(counter_from_field(boardGet(FieldId::motor_encoder_raw)));
  }
  if (output_fresh) {
    output_counts_.update(counter_from_field(boardGet(FieldId::output_encoder_raw)));
  }
  if (!motor_fresh || !output_fresh) {
    return;
  }
  // The table keeps counts per rev and the gear ratio >= 1.
  const EncoderResolution resolution{boardGet(FieldId::encoder_counts_per_rev),
                                     boardGet(FieldId::output_encoder_counts_per_rev), boardGet(FieldId::gear_ratio)};
  boardSet(FieldId::spring_deflection,
           spring_deflection_rad(motor_counts_.counts(), output_counts_.counts(), resolution));
}

}  // namespace joint
