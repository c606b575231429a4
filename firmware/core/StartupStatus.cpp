#include "core/StartupStatus.hpp"

namespace core {

std::string_view to_string(StartupError error) {
  switch (error) {
    case StartupError::None:
      return "none";
    case StartupError::DuplicateWriter:
      return "duplicate writer";
    case StartupError::DuplicateName:
      return "duplicate component name";
    case StartupError::ConflictingRead:
      return "conflicting read declaration";
    case StartupError::WrongFieldKind:
      return "write of a field of another kind";
    case StartupError::SensorReadsBoard:
      return "sensor reads the board";
    case StartupError::ActuatorWritesBoard:
      return "actuator writes the board";
    case StartupError::ReadOfLaterKind:
      return "read of a field written by a later kind";
    case StartupError::UpdateOrderCycle:
      return "update-order cycle";
    case StartupError::AlreadyStarted:
      return "already started";
  }
  return "unknown error";
}

}  // namespace core
