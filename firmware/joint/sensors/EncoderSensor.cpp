#include "joint/sensors/EncoderSensor.hpp"

namespace joint {

EncoderSensor::EncoderSensor(core::MessageBoard& board, std::string_view name, CounterInput& counter,
                             board::FieldId position_field, board::FieldId raw_counter_field,
                             board::FieldId counts_per_rev_parameter)
    : Sensor(board, name, {.writes = {position_field, raw_counter_field}, .reads = {counts_per_rev_parameter}}),
      counter_{counter},
      position_field_{position_field},
      raw_counter_field_{raw_counter_field},
      counts_per_rev_parameter_{counts_per_rev_parameter} {}

void EncoderSensor::update() {
  const CounterSample sample = counter_.read();
  if (!sample.fresh) {
    return;
  }
  const std::int64_t counts = unwrapper_.update(sample.counts);
  boardSet(raw_counter_field_, static_cast<float>(sample.counts));
  // The table keeps counts per rev >= 1, so the division is safe.
  boardSet(position_field_, counts_to_rad(counts, boardGet(counts_per_rev_parameter_)));
}

}  // namespace joint
