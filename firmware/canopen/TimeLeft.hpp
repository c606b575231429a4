// How long until a timer runs out, for the idle wait (Node::us_until_next_timer): one rule for
// every timer of the node (heartbeat, consumer and SDO timeouts, PDO timers and deadlines).
#pragma once

#include <cstdint>

namespace co {

// "No timer is running": longer than any wait a caller asks for.
inline constexpr std::uint32_t kNoTimerUs = UINT32_MAX;

// Time left of a period that started at `since_us`, 0 once it has run out. Unsigned differences:
// right across the 32-bit wrap of the microsecond clock.
constexpr std::uint32_t time_left_us(std::uint32_t now_us, std::uint32_t since_us, std::uint32_t period_us) {
  const std::uint32_t elapsed_us = now_us - since_us;
  return elapsed_us >= period_us ? 0u : period_us - elapsed_us;
}

}  // namespace co
