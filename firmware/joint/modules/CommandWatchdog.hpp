// watchdog_tripped = 1 while a control mode is active (control_mode != 0) and
// the setpoint stream (velocity_setpoint, torque_setpoint: one RPDO) has been
// silent for watchdog_cycles cycles; 0 otherwise. It reads the setpoints'
// last-write cycles from the board, not their values.
//
// Counting: the bus writes between cycles, stamped with the cycle before (the
// board's cycle counter advances at the start of a cycle), so a write stamped
// s arrived before cycle s + 1. Cycle s + 1 + n is the n-th cycle without a new
// write; the watchdog trips at n = watchdog_cycles. A setpoint never written
// counts as silent since the watchdog's first cycle.
#pragma once

#include <cstdint>

#include "core/MessageBoardUser.hpp"
#include "joint/modules/SilenceCounter.hpp"

namespace joint {

class CommandWatchdog final : public core::Module {
 public:
  explicit CommandWatchdog(core::MessageBoard& board);

  void update() override;

 private:
  CycleStep cycle_step_;
  // The bus writes between cycles: stamp lag 1. Counted in 64 bits (SilenceCounter.hpp).
  SilenceCounter velocity_setpoint_silence_{1};
  SilenceCounter torque_setpoint_silence_{1};
};

}  // namespace joint
