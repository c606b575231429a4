#include "head/sensors/MilliSensor.hpp"

namespace head {

namespace {
constexpr float kUnitsPerMilli = 0.001F;
}  // namespace

MilliSensor::MilliSensor(core::MessageBoard& board, std::string_view name, MilliInput& input, board::FieldId field)
    : Sensor(board, name, {.writes = {field}}), input_{input}, field_{field} {}

void MilliSensor::update() {
  const MilliSample sample = input_.read();
  if (sample.fresh) boardSet(field_, static_cast<float>(sample.milli) * kUnitsPerMilli);
}

}  // namespace head
