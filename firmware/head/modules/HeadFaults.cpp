#include "head/modules/HeadFaults.hpp"

#include "joint/BoardReads.hpp"

namespace head {

using board::FieldId;
using Bit = board::FaultFlagsBit;

HeadFaults::HeadFaults(core::MessageBoard& board)
    : Module(board, "head_faults",
             {.writes = {FieldId::fault_flags},
              .reads = {FieldId::accel_z, FieldId::imu_stale_cycles, FieldId::rail_current,
                        FieldId::rail_current_limit, FieldId::rail_trip_cycles, FieldId::battery_voltage,
                        FieldId::battery_low_voltage, FieldId::battery_low_cycles, FieldId::fault_clear}}) {}

std::uint32_t HeadFaults::active_causes(std::uint32_t elapsed_cycles) {
  std::uint32_t causes = 0;
  const auto raise_if = [&causes](bool condition, Bit bit) {
    if (condition) causes |= board::mask(bit);
  };
  const core::MessageBoard& b = board();
  const std::uint32_t imu_limit = joint::count_parameter(boardGet(FieldId::imu_stale_cycles), 1);
  raise_if(imu_silence_.update(b, FieldId::accel_z, elapsed_cycles) >= imu_limit, Bit::ImuStale);
  raise_if(over_current_.update(boardGet(FieldId::rail_current) > boardGet(FieldId::rail_current_limit),
                                joint::count_parameter(boardGet(FieldId::rail_trip_cycles), 1)),
           Bit::RailOverCurrent);
  raise_if(battery_low_.update(b.has(FieldId::battery_voltage) &&
                                   boardGet(FieldId::battery_voltage) < boardGet(FieldId::battery_low_voltage),
                               joint::count_parameter(boardGet(FieldId::battery_low_cycles), 1)),
           Bit::BatteryLow);
  const std::uint32_t refused = b.total_refused_writes();
  raise_if(refused != previous_refused_writes_, Bit::OwnershipViolation);
  previous_refused_writes_ = refused;
  return causes;
}

void HeadFaults::update() {
  const std::uint32_t elapsed_cycles = cycle_step_.update(board().cycle());
  const bool clear = clear_.update(board(), FieldId::fault_clear);
  boardSet(FieldId::fault_flags, static_cast<float>(latch_.update(active_causes(elapsed_cycles), clear)));
}

}  // namespace head
