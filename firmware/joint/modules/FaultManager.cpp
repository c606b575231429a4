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
                        FieldId::fault_clear}}) {}

std::uint32_t FaultManager::silent_cycles(FieldId sensor_field) const {
  const core::MessageBoard& b = board();
  const std::uint32_t since_start = b.cycle() - first_cycle_ + 1;
  if (!b.has(sensor_field)) {
    return since_start;
  }
  // Sensors write inside the cycle: a write in this cycle means 0 silent cycles.
  return std::min(since_start, b.cycle() - b.last_write_cycle(sensor_field));
}

std::uint32_t FaultManager::active_causes() {
  const std::uint32_t encoder_limit = count_parameter(boardGet(FieldId::encoder_stale_cycles), 1);
  std::uint32_t causes = 0;
  const auto raise_if = [&causes](bool condition, FaultBit bit) {
    if (condition) {
      causes |= fault_mask(bit);
    }
  };
  raise_if(silent_cycles(FieldId::motor_position) >= encoder_limit, FaultBit::MotorEncoderStale);
  raise_if(silent_cycles(FieldId::output_position) >= encoder_limit, FaultBit::OutputEncoderStale);
  const std::uint32_t thermistor_limit = count_parameter(boardGet(FieldId::thermistor_stale_cycles), 1);
  raise_if(silent_cycles(FieldId::thermistor_resistance) >= thermistor_limit, FaultBit::ThermistorStale);
  raise_if(boardGet(FieldId::thermal_derate) == 0.0F, FaultBit::OverTemperature);
  raise_if(boardGet(FieldId::watchdog_tripped) != 0.0F, FaultBit::CommandWatchdog);

  const std::uint32_t refused = board().total_refused_writes();
  raise_if(refused != previous_refused_writes_, FaultBit::OwnershipViolation);
  previous_refused_writes_ = refused;
  return causes;
}

bool FaultManager::clear_requested() {
  const core::MessageBoard& b = board();
  if (!b.has(FieldId::fault_clear)) {
    return false;
  }
  const std::uint32_t stamp = b.last_write_cycle(FieldId::fault_clear);
  const bool new_write = !seen_clear_ || stamp != seen_clear_stamp_;
  seen_clear_ = true;
  seen_clear_stamp_ = stamp;
  return new_write && boardGet(FieldId::fault_clear) == 1.0F;
}

void FaultManager::update() {
  if (!started_) {
    first_cycle_ = board().cycle();
    started_ = true;
  }
  const bool clear = clear_requested();
  const std::uint32_t latched = latch_.update(active_causes(), clear);
  boardSet(FieldId::fault_flags, static_cast<float>(latched));
  boardSet(FieldId::safe_state, latched != 0 ? 1.0F : 0.0F);
}

}  // namespace joint
