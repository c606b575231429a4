#include "joint/modules/FaultManager.hpp"

#include <algorithm>

#include "joint/BoardReads.hpp"
#include "joint/FaultBits.hpp"

namespace joint {

using board::FieldId;

FaultManager::FaultManager(core::MessageBoard& board)
    : Module(board, "fault_manager",
             {.writes = {FieldId::fault_flags, FieldId::safe_state},
              .reads = {FieldId::motor_position, FieldId::output_position, FieldId::thermistor_resistance,
                        FieldId::encoder_stale_cycles, FieldId::thermistor_stale_cycles, FieldId::thermal_derate, FieldId::watchdog_tripped,
                        FieldId::heartbeat_lost, FieldId::fault_clear, FieldId::drive_fault_reset}}) {}

std::uint32_t FaultManager::active_causes(std::uint32_t elapsed_cycles) {
  const std::uint32_t encoder_limit = count_parameter(boardGet(FieldId::encoder_stale_cycles), 1);
  std::uint32_t causes = 0;
  const auto raise_if = [&causes](bool condition, FaultBit bit) {
    if (condition) {
      causes |= fault_mask(bit);
    }
  };
  const core::MessageBoard& b = board();
  raise_if(motor_encoder_silence_.update(b, FieldId::motor_position, elapsed_cycles) >= encoder_limit,
           FaultBit::MotorEncoderStale);
  raise_if(output_encoder_silence_.update(b, FieldId::output_position, elapsed_cycles) >= encoder_limit,
           FaultBit::OutputEncoderStale);
  const std::uint32_t thermistor_limit = count_parameter(boardGet(FieldId::thermistor_stale_cycles), 1);
  raise_if(thermistor_silence_.update(b, FieldId::thermistor_resistance, elapsed_cycles) >= thermistor_limit,
           FaultBit::ThermistorStale);
  raise_if(boardGet(FieldId::thermal_derate) == 0.0F, FaultBit::OverTemperature);
  raise_if(boardGet(FieldId::watchdog_tripped) != 0.0F, FaultBit::CommandWatchdog);
  raise_if(boardGet(FieldId::heartbeat_lost) != 0.0F, FaultBit::MasterHeartbeatLost);

  const std::uint32_t refused = board().total_refused_writes();
  raise_if(refused != previous_refused_writes_, FaultBit::OwnershipViolation);
  previous_refused_writes_ = refused;
  return causes;
}

void FaultManager::update() {
  const std::uint32_t elapsed_cycles = cycle_step_.update(board().cycle());
  // The CiA 402 drive's fault reset clears by the same rule as a write of fault_clear.
  const bool clear = clear_.update(board(), FieldId::fault_clear) || boardGet(FieldId::drive_fault_reset) != 0.0F;
  const std::uint32_t latched = latch_.update(active_causes(elapsed_cycles), clear);
  boardSet(FieldId::fault_flags, static_cast<float>(latched));
  boardSet(FieldId::safe_state, latched != 0 ? 1.0F : 0.0F);
}

}  // namespace joint
