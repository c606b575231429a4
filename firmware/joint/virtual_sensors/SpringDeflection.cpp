#include "joint/virtual_sensors/SpringDeflection.hpp"

#include "joint/BoardReads.hpp"

namespace joint {

using board::FieldId;

SpringDeflection::SpringDeflection(core::MessageBoard& board)
    : VirtualSensor(board, "spring_deflection",
                    {.writes = {FieldId::spring_deflection},
                     .reads = {FieldId::motor_position, FieldId::output_position, FieldId::gear_ratio}}) {}

void SpringDeflection::update() {
  if (!written_this_cycle(board(), FieldId::motor_position) || !written_this_cycle(board(), FieldId::output_position)) {
    return;
  }
  boardSet(FieldId::spring_deflection,
           spring_deflection_rad(boardGet(FieldId::motor_position), boardGet(FieldId::output_position),
                                 boardGet(FieldId::gear_ratio)));
}

}  // namespace joint
