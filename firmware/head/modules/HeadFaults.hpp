// Collects the head's faults into fault_flags (bits: head.toml's [[bitset]] fault_flags) and
// latches them; the node turns each newly latched bit into its EMCY (FlagEmcyReporter).
//
// Causes, evaluated every cycle:
//   ImuStale: accel_z not written for imu_stale_cycles cycles (the IMU sensor writes only on a
//     fresh sample; a field never written counts as silent since the first cycle);
//   RailOverCurrent: rail_current > rail_current_limit for rail_trip_cycles consecutive cycles;
//   BatteryLow: battery_voltage < battery_low_voltage for battery_low_cycles consecutive
//     cycles, once the battery has been measured at all;
//   OwnershipViolation: the board's count of refused writes rose since the previous cycle.
// Clearing: a new write of fault_clear = 1 clears the latch; causes still present latch again
// in the same cycle (the rail's cause is gone once the rail is off).
#pragma once

#include <cstdint>

#include "core/MessageBoardUser.hpp"
#include "head/modules/Debounce.hpp"
#include "joint/modules/FaultLatch.hpp"
#include "joint/modules/SilenceCounter.hpp"

namespace head {

class HeadFaults final : public core::Module {
 public:
  explicit HeadFaults(core::MessageBoard& board);

  void update() override;

 private:
  std::uint32_t active_causes(std::uint32_t elapsed_cycles);

  joint::FaultLatch latch_;
  joint::CycleStep cycle_step_;
  joint::SilenceCounter imu_silence_{0};  // the sensor writes inside the cycle: stamp lag 0
  Debounce over_current_;
  Debounce battery_low_;
  std::uint32_t previous_refused_writes_ = 0;
  joint::ClearRequest clear_;
};

}  // namespace head
