// The bits of fault_flags. The numbers are part of the bus protocol (a master
// decodes fault_flags with them, and the platform turns each newly latched
// bit into an EMCY frame): never renumber a shipped bit, only add new ones.
#pragma once

#include <array>
#include <cstdint>
#include <string_view>

namespace joint {

enum class FaultBit : std::uint8_t {
  MotorEncoderStale = 0,   // no motor encoder sample for encoder_stale_cycles cycles
  OutputEncoderStale = 1,  // no output encoder sample for encoder_stale_cycles cycles
  ThermistorStale = 2,     // no valid thermistor conversion for thermistor_stale_cycles (open/shorted NTC too)
  OverTemperature = 3,     // winding reached thermal_limit_c; persists until below limit - hysteresis
  CommandWatchdog = 4,     // watchdog_tripped: the setpoint stream went silent while enabled
  OwnershipViolation = 5,  // the board refused a write (a component wrote a field it does not own)
};

inline constexpr std::array<FaultBit, 6> kFaultBits = {FaultBit::MotorEncoderStale, FaultBit::OutputEncoderStale,
                                                       FaultBit::ThermistorStale,   FaultBit::OverTemperature,
                                                       FaultBit::CommandWatchdog,   FaultBit::OwnershipViolation};

constexpr std::uint32_t fault_mask(FaultBit bit) { return std::uint32_t{1} << static_cast<std::uint8_t>(bit); }

constexpr std::string_view to_string(FaultBit bit) {
  switch (bit) {
    case FaultBit::MotorEncoderStale:
      return "motor encoder stale";
    case FaultBit::OutputEncoderStale:
      return "output encoder stale";
    case FaultBit::ThermistorStale:
      return "thermistor stale";
    case FaultBit::OverTemperature:
      return "over-temperature";
    case FaultBit::CommandWatchdog:
      return "command watchdog";
    case FaultBit::OwnershipViolation:
      return "ownership violation";
  }
  return "unknown fault";
}

}  // namespace joint
