// Small helpers for reading the board the way the joint's components need it.
#pragma once

#include <cmath>
#include <cstdint>

#include "core/MessageBoard.hpp"

namespace joint {

// True if the field was written in the board's current cycle (by a component
// that ran earlier in this cycle). Components that derive values use it to
// pass staleness on instead of recomputing from held inputs.
inline bool written_this_cycle(const core::MessageBoard& board, board::FieldId id) {
  return board.has(id) && board.last_write_cycle(id) == board.cycle();
}

// A count-valued parameter ("cycle", "count" units) as an integer, at least `minimum`.
inline std::uint32_t count_parameter(float value, std::uint32_t minimum) {
  if (!(value >= static_cast<float>(minimum))) {  // also catches NaN
    return minimum;
  }
  return static_cast<std::uint32_t>(std::lround(value));
}

}  // namespace joint
