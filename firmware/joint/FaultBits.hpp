// The bits of fault_flags: board.toml's [[bitset]] fault_flags, generated into board/fields.hpp
// (board::FaultFlagsBit, kFaultFlagsBits, and kFaultFlagsInfo with the EMCY each bit raises).
// The numbers are part of the bus protocol: never renumber a shipped bit, only add new ones.
#pragma once

#include <cstdint>

#include "board/fields.hpp"

namespace joint {

using FaultBit = board::FaultFlagsBit;

constexpr std::uint32_t fault_mask(FaultBit bit) { return board::mask(bit); }

}  // namespace joint
