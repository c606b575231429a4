// The bits of fault_flags: board.toml's [[bitset]] fault_flags, generated into board/fields.hpp
// (board::FaultFlagsBit, kFaultFlagsBits, and kFaultFlagsInfo with the EMCY each bit raises).
// The numbers are part of the bus protocol: never renumber a shipped bit, only add new ones.
#pragma once

#include <cstdint>

#include "board/fields.hpp"

namespace joint {

using FaultBit = board::FaultFlagsBit;

constexpr std::uint32_t fault_mask(FaultBit bit) { return board::mask(bit); }

// The faults that leave the joint the sensors a CiA 402 fault reaction ramps on (0x605E = 1, 2):
// the setpoint stream lost, a refused write, the master's heartbeat lost (the encoders keep
// coming; where they stop, in simulation when the node leaves operational, the encoder goes
// stale and ends the ramp). A stale encoder or thermistor leaves nothing to ramp on or to trust,
// and over-temperature is the cut-off, where thermal derate 0 bounds the duty to 0.
constexpr std::uint32_t kFaultsThatKeepTheSensors = fault_mask(FaultBit::CommandWatchdog) |
                                                    fault_mask(FaultBit::OwnershipViolation) |
                                                    fault_mask(FaultBit::MasterHeartbeatLost);

constexpr bool faults_keep_the_sensors(std::uint32_t fault_flags) {
  return (fault_flags & ~kFaultsThatKeepTheSensors) == 0;
}

// Whether the safe state zeroes the duty now: while any fault is latched, unless the CiA 402
// drive ramps it down (drive_fault_ramp) and every latched fault keeps the sensors.
constexpr bool safe_state_cuts_the_drive(float safe_state, float fault_flags, float drive_fault_ramp) {
  if (safe_state == 0.0F) return false;
  return drive_fault_ramp == 0.0F || !faults_keep_the_sensors(static_cast<std::uint32_t>(fault_flags));
}

}  // namespace joint
