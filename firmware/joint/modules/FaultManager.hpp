// Collects the joint's faults into fault_flags (bits: board.toml's [[bitset]] fault_flags), latches
// them, and holds safe_state = 1 while any is latched.
//
// Causes, evaluated every cycle:
//   MotorEncoderStale / OutputEncoderStale: motor_position / output_position
//     not written for encoder_stale_cycles cycles (the encoder sensors write
//     only on a fresh sample);
//   ThermistorStale: thermistor_resistance not written for
//     thermistor_stale_cycles cycles (the sensor also drops shorted/open readings);
//   OverTemperature: thermal_derate == 0, the thermal protection's
//     over-temperature state (with its hysteresis);
//   CommandWatchdog: watchdog_tripped == 1;
//   MasterHeartbeatLost: heartbeat_lost == 1 (a heartbeat the CANopen node consumes, 0x1016,
//     timed out; the node reported its EMCY, naming the lost node);
//   OwnershipViolation: the board's count of refused writes rose since the
//     previous cycle (a one-cycle event: it stays latched until cleared).
// A sensor field never written counts as silent since the manager's first
// cycle, which gives the sensors encoder_stale_cycles to start up.
//
// Clearing: a CiA 402 fault reset (drive_fault_reset = 1, Cia402Drive) or a write of fault_clear = 1 (each new write counts, whether or not
// the value changed) clears the latch; causes still present latch again in
// the same cycle.
#pragma once

#include <cstdint>

#include "core/MessageBoardUser.hpp"
#include "joint/modules/FaultLatch.hpp"
#include "joint/modules/SilenceCounter.hpp"

namespace joint {

class FaultManager final : public core::Module {
 public:
  explicit FaultManager(core::MessageBoard& board);

  void update() override;

 private:
  std::uint32_t active_causes(std::uint32_t elapsed_cycles);

  FaultLatch latch_;
  CycleStep cycle_step_;
  // Sensors write inside the cycle: stamp lag 0. Counted in 64 bits (SilenceCounter.hpp).
  SilenceCounter motor_encoder_silence_{0};
  SilenceCounter output_encoder_silence_{0};
  SilenceCounter thermistor_silence_{0};
  std::uint32_t previous_refused_writes_ = 0;  // 0: a refusal before the first cycle latches too
  ClearRequest clear_;
};

}  // namespace joint
