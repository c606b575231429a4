// The robot head module's side of the Linux main (platform/linux/main.cpp, built as
// head-firmware): what --help says, its driver registers, its components and the field the
// rogue-write fault injection aims at. The node's views of it are NodeOnHead.hpp's.
#pragma once

#include <string_view>

#include "NodeOnHead.hpp"
#include "board/fields.hpp"
#include "core/MessageBoard.hpp"
#include "core/Scheduler.hpp"
#include "head/HeadModule.hpp"
#include "head/drivers/HeadRegisters.hpp"

namespace board_app {

inline constexpr std::string_view kDescription =
    "Firmware of the robot head module (IMU, RGB LED, current-limited power rail, battery)";
inline constexpr board::FieldId kRogueTarget = board::FieldId::led_red_duty;
inline constexpr float kRogueValue = 0.875F;  // a duty the LED mixer never writes with the LED off

using Registers = head::HeadRegisters;

class Components {
 public:
  // The head's components keep no time constant: dt_s is not used.
  Components(core::MessageBoard& board, Registers& registers, float /*dt_s*/) : head_{board, registers.drivers()} {}
  bool add_to(core::Scheduler& scheduler) { return head_.add_to(scheduler); }

 private:
  head::HeadModule head_;
};

}  // namespace board_app
