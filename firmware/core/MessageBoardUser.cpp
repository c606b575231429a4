#include "core/MessageBoardUser.hpp"

namespace core {

std::string_view to_string(ComponentKind kind) {
  switch (kind) {
    case ComponentKind::Sensor:
      return "sensor";
    case ComponentKind::VirtualSensor:
      return "virtual sensor";
    case ComponentKind::Module:
      return "module";
    case ComponentKind::Actuator:
      return "actuator";
    case ComponentKind::External:
      return "external writer";
  }
  return "unknown kind";
}

std::string describe(const MessageBoardUser& user) {
  return std::string(to_string(user.kind())) + " '" + std::string(user.name()) + "'";
}

}  // namespace core
