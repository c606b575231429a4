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

void CommandWatchdog::update() {
  const core::MessageBoard& b = board();
  const std::uint32_t elapsed_cycles = cycle_step_.update(b.cycle());
  // Cycles run since the newest write of either setpoint arrived (both counters run every cycle).
  const std::uint64_t silent = std::min(velocity_setpoint_silence_.update(b, FieldId::velocity_setpoint, elapsed_cycles),
                                        torque_setpoint_silence_.update(b, FieldId::torque_setpoint, elapsed_cycles));
  const bool enabled = control_mode_from_field(boardGet(FieldId::control_mode)) != ControlMode::Disabled;
  const std::uint32_t limit_cycles = count_parameter(boardGet(FieldId::watchdog_cycles), 1);
  boardSet(FieldId::watchdog_tripped, enabled && silent >= limit_cycles ? 1.0F : 0.0F);
}

}  // namespace joint
