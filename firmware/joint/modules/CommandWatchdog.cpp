#include "joint/modules/CommandWatchdog.hpp"

#include <algorithm>

#include "joint/BoardReads.hpp"
#include "joint/ControlMode.hpp"

namespace joint {

using board::FieldId;

CommandWatchdog::CommandWatchdog(core::MessageBoard& board)
    : Module(board, "command_watchdog",
             {.writes = {FieldId::watchdog_tripped},
              .reads = {FieldId::control_mode, FieldId::velocity_setpoint, FieldId::torque_setpoint,
                        FieldId::watchdog_cycles}}) {}

std::uint32_t CommandWatchdog::silent_cycles() const {
  const core::MessageBoard& b = board();
  const std::uint32_t since_start = b.cycle() - first_cycle_ + 1;
  std::uint32_t silent = since_start;
  for (const FieldId setpoint : {FieldId::velocity_setpoint, FieldId::torque_setpoint}) {
    if (b.has(setpoint)) {
      // Written before cycle stamp + 1: that cycle is the first that saw it.
      const std::uint32_t age = b.cycle() - b.last_write_cycle(setpoint);
      silent = std::min(silent, age == 0 ? 0 : age - 1);
    }
  }
  return std::min(silent, since_start);
}

void CommandWatchdog::update() {
  if (!started_) {
    first_cycle_ = board().cycle();
    started_ = true;
  }
  const bool enabled = control_mode_from_field(boardGet(FieldId::control_mode)) != ControlMode::Disabled;
  const std::uint32_t limit_cycles = count_parameter(boardGet(FieldId::watchdog_cycles), 1);
  boardSet(FieldId::watchdog_tripped, enabled && silent_cycles() >= limit_cycles ? 1.0F : 0.0F);
}

}  // namespace joint
