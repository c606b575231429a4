// Turns successive readings of a 16-bit wrapping hardware counter into a
// continuous count. The counter starts at 0 at power-up, so the first reading
// is taken as a signed step from 0 (65535 means -1). Readings must come often
// enough that the shaft moves less than half a wrap (32768 counts) between
// them: at 1 kHz and 4096 counts/rev that is 8 revolutions per cycle.
//
// Why integers: the step between two readings is exact for as long as the
// firmware runs, while a float angle loses resolution with the distance
// turned (at 2^24 counts a float no longer holds single counts). Velocity and
// spring deflection are computed from these steps, never from float angles.
#pragma once

#include <cstdint>

namespace joint {

// The signed step of a 16-bit wrapping counter from `before` to `now` (modular
// arithmetic: 2 after 65535 is a step of +3).
constexpr std::int16_t counter_step(std::uint16_t now, std::uint16_t before) {
  return static_cast<std::int16_t>(static_cast<std::uint16_t>(now - before));
}

// A counter reading carried in a board field (an integer 0..65535, exact in a
// float) back as the counter's value.
std::uint16_t counter_from_field(float value);

class EncoderUnwrapper {
 public:
  // Takes one raw reading; returns the continuous count.
  std::int64_t update(std::uint16_t raw_counts) {
    counts_ += counter_step(raw_counts, previous_raw_);
    previous_raw_ = raw_counts;
    return counts_;
  }

  std::int64_t counts() const { return counts_; }

 private:
  std::uint16_t previous_raw_ = 0;
  std::int64_t counts_ = 0;  // 2^63 counts: never overflows at any real speed
};

// The angle of a continuous count [rad].
float counts_to_rad(std::int64_t counts, float counts_per_rev);

}  // namespace joint
