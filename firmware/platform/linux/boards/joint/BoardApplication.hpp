// The demo joint's side of the Linux main (platform/linux/main.cpp, built as joint-firmware):
// what --help says, its driver registers, its components and the field the rogue-write fault
// injection aims at. The node's views of it are NodeOnJoint.hpp's.
#pragma once

#include <string_view>

#include "NodeOnJoint.hpp"
#include "board/fields.hpp"
#include "core/MessageBoard.hpp"
#include "core/Scheduler.hpp"
#include "joint/DemoJoint.hpp"
#include "joint/drivers/HilRegisters.hpp"

namespace board_app {

inline constexpr std::string_view kDescription = "Firmware of the demo series-elastic joint";
inline constexpr board::FieldId kRogueTarget = board::FieldId::motor_duty_command;
inline constexpr float kRogueValue = 0.875F;  // a duty the joint's owner never commands at rest

using Registers = joint::HilRegisters;

class Components {
 public:
  Components(core::MessageBoard& board, Registers& registers, float dt_s)
      : joint_{board, registers.drivers(), dt_s} {}
  bool add_to(core::Scheduler& scheduler) { return joint_.add_to(scheduler); }

 private:
  joint::DemoJoint joint_;
};

}  // namespace board_app
